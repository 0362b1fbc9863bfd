//! Acquisition cross-validation (SPEC 10): folds as in SPEC 8; per fold the basis is chosen
//! on the training materials (a selection method and k), the plan on the training
//! materials (basis and training targets); each held-out material is measured at the plan's
//! first n samples (noise model `y = f (1 + sigma_rel N(0, 1))`, one draw per sample and
//! channel, seeded per material and noise level, so that the n'-measurement is a prefix of
//! the n-measurement), fitted from them and scored on the whole fit mask: rho (SPEC 8, from
//! the full-mask Gram form), MAE on the grid (SPEC 5) and the normalised image error of
//! renders (SPEC 7: light (45, 45)). The dense rho of the same basis (fit on the whole mask)
//! is its limit.

use super::fit::{solve_rows_toward, RIDGE_STRENGTHS};
use super::nielsen::{nielsen_per_step, NielsenModel, ETA};
use super::plan::{
    cell_candidates, plan, values_at, Candidate, Criterion, Dense, PlanParams, PlannedSample,
};
use super::AcquireError;
use crate::backend::cpu::CpuBackend;
use crate::backend::Backend;
use crate::collection::Collection;
use crate::distance::{distance_matrix, DistanceParams};
use crate::eval::appearance::{Appearance, LogSums};
use crate::eval::image_error::{normalized_image_error, DisplayParams};
use crate::eval::render::{render_sphere, Image, RenderParams};
use crate::eval::shade::{combination_brdf, PixelBrdfs};
use crate::fit::{fit_cells, FitParams, TargetWeight};
use crate::nnls::{lawson_hanson, GramProblem};
use crate::select::cv::evaluate::{means_of, GridEval, LightRenders, MaeJob};
use crate::select::cv::folds::fold_bases;
use crate::select::cv::AppearanceMeans;
use crate::select::{make_folds, CvMethod, CvParams, Objective, ObjectiveParams};
use crate::stats::{mean, median};
use rand::SeedableRng;
use rayon::prelude::*;
use std::f64::consts::FRAC_1_PI;

/// Parameters of [`acquisition_cv`]. Defaults: greedy, k = 12, plans error, condition,
/// random; n = 5, 10, 20; noise 0 and 2%; 5 folds; 10,000 candidates per step.
#[derive(Clone, Debug)]
pub struct AcqCvParams {
    /// Selection methods.
    pub methods: Vec<CvMethod>,
    /// Basis size.
    pub k: usize,
    /// Plan criteria.
    pub plans: Vec<Criterion>,
    /// Sample counts (each plan is planned once for the largest; smaller n are prefixes).
    pub ns: Vec<usize>,
    /// Relative noise levels.
    pub noises: Vec<f64>,
    /// Folds.
    pub folds: usize,
    /// Seed.
    pub seed: u64,
    /// Candidates examined per plan step (0: all).
    pub candidates_per_step: usize,
    /// Exact shortlist of the error criterion.
    pub shortlist: usize,
    /// Seeded greedy paths of each error plan sharing the candidates of a step
    /// ([`super::plan::plan`]; 1: one path).
    pub restarts: usize,
    /// Render size of the image errors.
    pub render_size: u32,
    /// Fit mask, weighting, stride and the objective (SPEC 11): the fold bases are
    /// chosen under its shared weights, plans weigh their rows by them, every fit (from
    /// samples and dense) minimises it.
    pub objective: ObjectiveParams,
    /// Appearance metrics (SPEC 11: log-RMSE, and image error, CIEDE2000 and FLIP under
    /// the four lights) of every reconstruction, the `nielsen` baseline's included.
    pub appearance: bool,
    /// Fits from fewer samples than unknowns with a ridge toward the training materials'
    /// mean coefficients, its strength chosen per fold, plan and n on the training
    /// materials ([`RIDGE_STRENGTHS`]); `false`: plain NNLS.
    pub ridge: bool,
}

impl Default for AcqCvParams {
    fn default() -> Self {
        Self {
            methods: vec![CvMethod::Greedy],
            k: 12,
            plans: vec![Criterion::Error, Criterion::Condition, Criterion::Random],
            ns: vec![5, 10, 20],
            noises: vec![0.0, 0.02],
            folds: 5,
            seed: 1,
            candidates_per_step: 10_000,
            shortlist: 32,
            restarts: 1,
            render_size: 64,
            objective: ObjectiveParams::default(),
            appearance: true,
            ridge: true,
        }
    }
}

/// One held-out material reconstructed from its samples.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AcqHeldOut {
    /// Material.
    pub material: String,
    /// Its fold.
    pub fold: usize,
    /// rho of the reconstruction from the samples.
    pub rho: f64,
    /// rho of the dense fit by the same basis (the limit).
    pub dense_rho: f64,
    /// Grid MAE of the reconstruction.
    pub mae: f64,
    /// Normalised image error of the reconstruction's render.
    pub image_error: f64,
    /// Grid MAE of the dense fit.
    pub dense_mae: f64,
    /// Image error of the dense fit's render.
    pub dense_image_error: f64,
    /// Appearance metrics of the reconstruction (SPEC 11), when computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub appearance: Option<Appearance>,
    /// Appearance metrics of the dense fit, when computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dense_appearance: Option<Appearance>,
}

/// One (method, plan, n, noise).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AcqResult {
    /// Selection method.
    pub method: String,
    /// Plan criterion.
    pub plan: Criterion,
    /// Samples.
    pub n: usize,
    /// Relative noise.
    pub noise: f64,
    /// Basis of each fold.
    pub fold_bases: Vec<Vec<String>>,
    /// Plan of each fold (its first n samples).
    pub fold_plans: Vec<Vec<PlannedSample>>,
    /// Held-out materials.
    pub held_out: Vec<AcqHeldOut>,
    /// Mean rho.
    pub mean_rho: f64,
    /// Median rho.
    pub median_rho: f64,
    /// Mean dense rho.
    pub mean_dense_rho: f64,
    /// `mean_rho / mean_dense_rho`.
    pub ratio: f64,
    /// Mean MAE.
    pub mean_mae: f64,
    /// Median MAE.
    pub median_mae: f64,
    /// Mean image error.
    pub mean_image_error: f64,
    /// Median image error.
    pub median_image_error: f64,
    /// Mean MAE of the dense fits.
    pub mean_dense_mae: f64,
    /// Mean image error of the dense fits.
    pub mean_dense_image_error: f64,
    /// The ridge strength of the fits from samples per fold ([`RIDGE_STRENGTHS`]; 0 with
    /// at least as many samples as unknowns; empty for `nielsen` and without a ridge).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ridge: Vec<f64>,
    /// Mean log-RMSE (SPEC 11), when the appearance metrics were computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_log_rmse: Option<f64>,
    /// Means of the image metrics under the four lights, when computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub appearance: Option<AppearanceMeans>,
    /// Mean log-RMSE of the dense fits, when computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_dense_log_rmse: Option<f64>,
    /// Means of the dense fits' image metrics, when computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dense_appearance: Option<AppearanceMeans>,
}

/// The selection of the fold bases.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AcqSelect {
    /// Selection methods, comma-separated (each result names its own).
    pub method: String,
    /// Basis size.
    pub k: usize,
}

/// The `cv --acquisition` JSON.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AcqCv {
    /// Folds, by name.
    pub folds: Vec<Vec<String>>,
    /// Seed.
    pub seed: u64,
    /// The selection of the fold bases (SPEC-cli `select: {method, k}`).
    pub select: AcqSelect,
    /// Basis size.
    pub k: usize,
    /// Candidates examined per plan step.
    pub candidates_per_step: usize,
    /// Greedy paths of each error plan.
    #[serde(default = "super::plan_types::one")]
    pub restarts: usize,
    /// The objective of the fits and plans (SPEC 11; `l2` in files written before).
    #[serde(default = "super::plan_types::l2_name")]
    pub objective: String,
    /// Per method, plan, n and noise.
    pub results: Vec<AcqResult>,
    /// Collection fingerprint.
    pub collection_fingerprint: String,
    /// Renders of one held-out material (not written to the JSON).
    #[serde(skip)]
    pub showcase: Option<AcqShowcase>,
}

/// Renders of one showcase held-out material: the material, the dense fit of its fold's
/// basis and its reconstructions from each n of one plan (first method, first plan, the
/// noise-free level when there is one). The material is the one of median rho at the
/// largest n by that plan.
#[derive(Clone, Debug, PartialEq)]
pub struct AcqShowcase {
    /// Material.
    pub material: String,
    /// Its fold.
    pub fold: usize,
    /// Selection method of the basis.
    pub method: String,
    /// The plan of the reconstructions.
    pub plan: Criterion,
    /// Relative noise of the measurements.
    pub noise: f64,
    /// Render of the material.
    pub original: Image,
    /// `(label, render, image error, rho)`: the dense fit, then n = each sample count.
    pub tiles: Vec<(String, Image, f64, f64)>,
}

/// Held-out rows and fold plans of one (plan, n, noise), accumulated over folds.
type Cell = (Vec<AcqHeldOut>, Vec<Vec<PlannedSample>>);

/// One reconstruction of a fold: plan, n and noise indices, the held-out material's index
/// in the fold and its coefficients per channel.
type Rec = (usize, usize, usize, usize, [Vec<f64>; 3]);

/// One fold's basis (names), the samples of the showcase's plan (empty unless it is
/// the first method's first plan, not nielsen), its rows per plan, n and noise, the
/// ridge strength per plan and n and the ridge's prior mean.
type FoldRows = (
    Vec<String>,
    Vec<Candidate>,
    Vec<Vec<Vec<Cell>>>,
    Vec<Vec<Option<f64>>>,
    Option<[Vec<f64>; 3]>,
);

/// Runs the acquisition cross-validation (module docs).
///
/// Over 100 lines: one loop nest (method, fold, plan, noise, n) whose levels share the
/// fold's basis, dense Gram quantities, plan and measured values; splitting it would pass
/// all of them around.
#[allow(clippy::needless_range_loop)]
pub fn acquisition_cv(
    backend: &dyn Backend,
    coll: &Collection,
    p: &AcqCvParams,
) -> Result<AcqCv, AcquireError> {
    let n = coll.len();
    let nmax = p.ns.iter().copied().max().unwrap_or(0);
    if nmax == 0 || p.plans.is_empty() || p.methods.is_empty() {
        return Err(AcquireError::InvalidParam {
            name: "plans / methods / n",
            value: format!("{} / {} / {:?}", p.plans.len(), p.methods.len(), p.ns),
            expected: "at least one plan, one method and one n >= 1",
        });
    }
    if let Some(s) = p.noises.iter().find(|s| !s.is_finite() || **s < 0.0) {
        return Err(AcquireError::InvalidParam {
            name: "noise",
            value: s.to_string(),
            expected: "finite relative noise levels >= 0",
        });
    }
    let vp = CvParams {
        methods: p.methods.clone(),
        ks: vec![p.k],
        folds: p.folds,
        seed: p.seed,
        objective: p.objective.clone(),
        ..CvParams::default()
    }
    .check(n)?;
    // The objective's fits and plans; the scores (rho, MAE: SPEC 10) are l2's.
    let fp_obj = p.objective.fit_params();
    let weight = fp_obj
        .objective
        .check()
        .map_err(crate::fit::FitError::from)?;
    let fp = FitParams {
        objective: TargetWeight::L2,
        ..fp_obj.clone()
    };
    let obj = Objective::new(backend, coll, &p.objective.check()?, &|_, _| {})?;
    let dist = if p.methods.iter().any(|m| m.clustering()) {
        let dp = DistanceParams::default()
            .metric(vp.params().metric)
            .mask(fp.mask)
            .weighting(fp.weighting)
            .stride(fp.stride)
            .check(coll)
            .map_err(crate::select::SelectionError::from)?;
        Some(
            distance_matrix(backend, coll, &dp, &|_, _| {})
                .map_err(crate::select::SelectionError::from)?,
        )
    } else {
        None
    };
    let folds = make_folds(n, p.folds, p.seed);
    let bases = fold_bases(&obj, dist.as_ref(), &folds, &vp, &|_, _| {})?;
    let grid = GridEval::new(coll, &fp);
    let rp = RenderParams::default()
        .with_size(p.render_size)
        .with_light(45.0, 45.0);
    let display = DisplayParams::default();
    let pixels = PixelBrdfs::new(coll, &rp).map_err(|e| AcquireError::Render(e.to_string()))?;
    let originals: Vec<_> = (0..n)
        .map(|t| render_sphere(&rp, &pixels.material(t)))
        .collect::<Result<_, _>>()
        .map_err(|e| AcquireError::Render(e.to_string()))?;
    let names = coll.names();
    let all: Vec<usize> = (0..n).collect();
    let cands = cell_candidates(coll, &all, &fp)?;
    let cellset = fit_cells(coll, &all, &fp)?;
    let lights = if p.appearance {
        LightRenders::all(coll).map_err(|e| AcquireError::Render(e.to_string()))?
    } else {
        Vec::new()
    };
    let mut show_chosen: Vec<Vec<Candidate>> = vec![Vec::new(); folds.len()];
    let mut show_prior: Vec<Option<[Vec<f64>; 3]>> = vec![None; folds.len()];
    let mut results = Vec::new();
    for (mi, m) in p.methods.iter().enumerate() {
        // rows[plan][n][noise] accumulated over folds.
        let mut acc: Vec<Vec<Vec<Cell>>> =
            vec![vec![vec![(Vec::new(), Vec::new()); p.noises.len()]; p.ns.len()]; p.plans.len()];
        let mut fold_bases_named = Vec::new();
        // Each fold returns its rows, merged in fold order.
        let per_fold: Vec<FoldRows> = folds
            .iter()
            .enumerate()
            .map(|(f, held)| -> Result<FoldRows, AcquireError> {
                let mut acc: Vec<Vec<Vec<Cell>>> =
                    vec![
                        vec![vec![(Vec::new(), Vec::new()); p.noises.len()]; p.ns.len()];
                        p.plans.len()
                    ];
                let mut show = Vec::new();
                let basis = &bases[mi][0][f];
                let named: Vec<String> = basis.iter().map(|&b| names[b].clone()).collect();
                let train: Vec<usize> = (0..n)
                    .filter(|i| held.binary_search(i).is_err() && !basis.contains(i))
                    .collect();
                let dense = Dense::new(backend, coll, basis, held, &fp)?;
                let mm = basis.len() + 1;
                let prior = if p.ridge && !train.is_empty() {
                    // On the CPU twin, as the limits below: the same ridge on every
                    // back-end.
                    Some(Prior::new(
                        &CpuBackend::new(),
                        coll,
                        basis,
                        &train,
                        &fp_obj,
                    )?)
                } else {
                    None
                };
                let mut ridges: Vec<Vec<Option<f64>>> = vec![vec![None; p.ns.len()]; p.plans.len()];
                // The dense fit of each held-out material (the limit). Under an objective
                // the per-target weighted systems come from the CPU twin: they agree
                // between back-ends only within `WEIGHTED_TOLERANCE`, which an
                // ill-conditioned fit amplifies, and the limit is a small pass beside the
                // plans; so the JSON is the same on every back-end.
                let dense_x: Vec<[Vec<f64>; 3]> = if weight != TargetWeight::L2 {
                    crate::fit::fit(&CpuBackend::new(), coll, basis, held, &fp_obj, &|_, _| {})?
                        .into_iter()
                        .map(|tf| [0, 1, 2].map(|c| tf.coefficients.iter().map(|a| a[c]).collect()))
                        .collect()
                } else {
                    (0..held.len())
                        .into_par_iter()
                        .map(|t| -> Result<[Vec<f64>; 3], AcquireError> {
                            let x = [0, 1, 2].map(|c| {
                                let g = &dense.g[c];
                                GramProblem::new(mm, &g.gram, &g.h[t * mm..(t + 1) * mm], g.bb[t])
                                    .and_then(|pr| {
                                        lawson_hanson::solve(
                                            &pr,
                                            &lawson_hanson::LhParams::default(),
                                        )
                                    })
                                    .map(|s| s.x)
                            });
                            let [a, b, c] = x;
                            Ok([a?, b?, c?])
                        })
                        .collect::<Result<_, _>>()?
                };
                // Every reconstruction of the fold by a plan of ours: (plan, n, noise, held-out
                // index, coefficients per channel); scored together below (one pass over the
                // grid for every MAE, renders from the pixel table).
                let mut recs: Vec<Rec> = Vec::new();
                let seed_f = p.seed.wrapping_add(1000 * f as u64);
                for (pi, &crit) in p.plans.iter().enumerate() {
                    if crit == Criterion::Nielsen {
                        continue;
                    }
                    let pp = PlanParams {
                        n: nmax,
                        criterion: crit,
                        candidates_per_step: p.candidates_per_step,
                        shortlist: p.shortlist,
                        seed: seed_f,
                        fit: fp_obj.clone(),
                        restarts: p.restarts,
                    };
                    // Condition and random plans need no training materials (but for the
                    // shared weights of an objective): without them `plan` skips the
                    // training-score history the results never use.
                    let train_of = if crit == Criterion::Error
                        || (crit == Criterion::Condition && weight != TargetWeight::L2)
                    {
                        &train[..]
                    } else {
                        &[]
                    };
                    let chosen = plan(backend, coll, basis, train_of, &cands, &pp)?.chosen;
                    let samples: Vec<PlannedSample> =
                        chosen.iter().map(PlannedSample::from).collect();
                    if mi == 0 && pi == 0 {
                        show = chosen.clone();
                    }
                    let mut mats = basis.clone();
                    mats.extend_from_slice(held);
                    let vals = values_at(coll, &mats, &chosen)?;
                    let cos: Vec<f64> = chosen.iter().map(|c| c.wi[2]).collect();
                    let lambdas: Vec<f64> = match &prior {
                        Some(pr) => {
                            let tv = values_at(coll, &train, &chosen)?;
                            // With at least as many samples as unknowns the samples
                            // determine the fit: no prior.
                            p.ns.iter()
                                .map(|&ns| {
                                    if ns.min(nmax) >= mm {
                                        Ok(0.0)
                                    } else {
                                        pr.choose(&vals, &tv, ns.min(nmax), weight, &cos)
                                    }
                                })
                                .collect::<Result<_, AcquireError>>()?
                        }
                        None => vec![0.0; p.ns.len()],
                    };
                    if prior.is_some() {
                        for (ni, &l) in lambdas.iter().enumerate() {
                            ridges[pi][ni] = Some(l);
                        }
                    }
                    let toward = |ni: usize| prior.as_ref().map(|pr| (&pr.mean, lambdas[ni]));
                    for si in 0..p.noises.len() {
                        let sigma = p.noises[si];
                        // Noisy measurements of every held-out material at the nmax samples.
                        let ys: Vec<[Vec<f64>; 3]> = held
                            .iter()
                            .enumerate()
                            .map(|(t, &ti)| {
                                measure(p.seed, ti, si, sigma, nmax, |c, s| {
                                    vals[c][basis.len() + t][s]
                                })
                            })
                            .collect();
                        for (ni, &ns) in p.ns.iter().enumerate() {
                            let xs: Vec<[Vec<f64>; 3]> = (0..held.len())
                                .into_par_iter()
                                .map(|t| {
                                    sample_coefficients(
                                        basis.len(),
                                        &vals,
                                        &ys[t],
                                        ns,
                                        weight,
                                        &cos,
                                        toward(ni),
                                    )
                                })
                                .collect::<Result<_, _>>()?;
                            recs.extend(
                                xs.into_iter().enumerate().map(|(t, x)| (pi, ni, si, t, x)),
                            );
                            acc[pi][ni][si].1.push(samples[..ns].to_vec());
                        }
                    }
                }
                // Scores: the dense fits first, then every reconstruction.
                let coefs: Vec<Vec<[f64; 3]>> = dense_x
                    .iter()
                    .chain(recs.iter().map(|r| &r.4))
                    .map(|x| (0..mm).map(|j| [x[0][j], x[1][j], x[2][j]]).collect())
                    .collect();
                let target = |i: usize| {
                    held[if i < held.len() {
                        i
                    } else {
                        recs[i - held.len()].3
                    }]
                };
                let jobs: Vec<MaeJob<'_>> = coefs
                    .iter()
                    .enumerate()
                    .map(|(i, coef)| MaeJob {
                        basis,
                        target: target(i),
                        coef,
                    })
                    .collect();
                let (maes, logs): (Vec<f64>, Vec<f64>) = if p.appearance {
                    grid.sums(&jobs).into_iter().unzip()
                } else {
                    (grid.maes(&jobs), Vec::new())
                };
                let looks: Vec<Option<Appearance>> = if p.appearance {
                    coefs
                        .par_iter()
                        .enumerate()
                        .map(|(i, coef)| {
                            let mut a = LightRenders::scores(&lights, target(i), basis, coef)
                                .map_err(|e| AcquireError::Render(e.to_string()))?;
                            a.log_rmse = logs[i];
                            Ok(Some(a))
                        })
                        .collect::<Result<_, AcquireError>>()?
                } else {
                    vec![None; coefs.len()]
                };
                let ies: Vec<f64> = coefs
                    .par_iter()
                    .enumerate()
                    .map(|(i, coef)| {
                        render_error(&pixels, &rp, &display, &originals[target(i)], basis, coef)
                            .map(|r| r.1)
                    })
                    .collect::<Result<_, _>>()?;
                let dense_rho: Vec<f64> =
                    (0..held.len()).map(|t| dense.rho(t, &dense_x[t])).collect();
                for (r, (pi, ni, si, t, x)) in recs.iter().enumerate() {
                    let i = held.len() + r;
                    acc[*pi][*ni][*si].0.push(AcqHeldOut {
                        material: names[held[*t]].clone(),
                        fold: f,
                        rho: dense.rho(*t, x),
                        dense_rho: dense_rho[*t],
                        mae: maes[i],
                        image_error: ies[i],
                        dense_mae: maes[*t],
                        dense_image_error: ies[*t],
                        appearance: looks[i].clone(),
                        dense_appearance: looks[*t].clone(),
                    });
                }
                for (pi, &crit) in p.plans.iter().enumerate() {
                    if crit != Criterion::Nielsen {
                        continue;
                    }
                    // The peer baseline: its own model of every training material of the
                    // fold (no basis), plan and reconstruction.
                    let train_all: Vec<usize> =
                        (0..n).filter(|i| held.binary_search(i).is_err()).collect();
                    let model = NielsenModel::train(coll, &train_all, &cellset.cells, nmax)?;
                    let chosen = model.plan(nmax, nielsen_per_step(p.candidates_per_step), seed_f);
                    let samples: Vec<PlannedSample> = chosen
                        .iter()
                        .map(|&j| PlannedSample::from(&cands[j]))
                        .collect();
                    let nf = NielsenFold {
                        coll,
                        model: &model,
                        chosen: &chosen,
                        weights: &cellset.weights,
                        rp: &rp,
                        display: &display,
                        lights: &lights,
                    };
                    let per: Vec<Vec<Vec<Scores>>> = held
                        .par_iter()
                        .map(|&ti| nielsen_rows(&nf, p, ti, &originals[ti]))
                        .collect::<Result<_, _>>()?;
                    for (ni, &ns) in p.ns.iter().enumerate() {
                        for si in 0..p.noises.len() {
                            let rows = held.iter().enumerate().map(|(t, &ti)| {
                                let (rho, mae, image_error, appearance) = per[t][ni][si].clone();
                                AcqHeldOut {
                                    material: names[ti].clone(),
                                    fold: f,
                                    rho,
                                    dense_rho: dense_rho[t],
                                    mae,
                                    image_error,
                                    dense_mae: maes[t],
                                    dense_image_error: ies[t],
                                    appearance,
                                    dense_appearance: looks[t].clone(),
                                }
                            });
                            acc[pi][ni][si].0.extend(rows);
                            acc[pi][ni][si]
                                .1
                                .push(samples[..ns.min(samples.len())].to_vec());
                        }
                    }
                }
                Ok((named, show, acc, ridges, prior.map(|p| p.mean)))
            })
            .collect::<Result<_, _>>()?;
        let mut ridge_folds: Vec<Vec<Vec<f64>>> = vec![vec![Vec::new(); p.ns.len()]; p.plans.len()];
        for (f, (named, show, facc, fridge, fprior)) in per_fold.into_iter().enumerate() {
            fold_bases_named.push(named);
            if mi == 0 && !show.is_empty() {
                show_chosen[f] = show;
            }
            if mi == 0 {
                show_prior[f] = fprior;
            }
            for (pi, per_n) in fridge.into_iter().enumerate() {
                for (ni, l) in per_n.into_iter().enumerate() {
                    ridge_folds[pi][ni].extend(l);
                }
            }
            for (pi, per_n) in facc.into_iter().enumerate() {
                for (ni, per_noise) in per_n.into_iter().enumerate() {
                    for (si, (rows, plans)) in per_noise.into_iter().enumerate() {
                        acc[pi][ni][si].0.extend(rows);
                        acc[pi][ni][si].1.extend(plans);
                    }
                }
            }
        }
        for (pi, &crit) in p.plans.iter().enumerate() {
            for (ni, &ns) in p.ns.iter().enumerate() {
                for (si, &sigma) in p.noises.iter().enumerate() {
                    let (held_out, plans) = std::mem::take(&mut acc[pi][ni][si]);
                    let col =
                        |g: fn(&AcqHeldOut) -> f64| held_out.iter().map(g).collect::<Vec<f64>>();
                    let (rho, dr, mae, img) = (
                        col(|h| h.rho),
                        col(|h| h.dense_rho),
                        col(|h| h.mae),
                        col(|h| h.image_error),
                    );
                    results.push(AcqResult {
                        method: m.name().to_string(),
                        plan: crit,
                        n: ns,
                        noise: sigma,
                        fold_bases: fold_bases_named.clone(),
                        fold_plans: plans,
                        mean_rho: mean(&rho),
                        median_rho: median(&rho),
                        mean_dense_rho: mean(&dr),
                        ratio: mean(&rho) / mean(&dr),
                        mean_mae: mean(&mae),
                        median_mae: median(&mae),
                        mean_image_error: mean(&img),
                        median_image_error: median(&img),
                        mean_dense_mae: mean(&col(|h| h.dense_mae)),
                        mean_dense_image_error: mean(&col(|h| h.dense_image_error)),
                        ridge: ridge_folds[pi][ni].clone(),
                        mean_log_rmse: looks_mean(&held_out, |h| h.appearance.as_ref())
                            .map(|(l, _)| l),
                        appearance: looks_mean(&held_out, |h| h.appearance.as_ref())
                            .map(|(_, a)| a),
                        mean_dense_log_rmse: looks_mean(&held_out, |h| h.dense_appearance.as_ref())
                            .map(|(l, _)| l),
                        dense_appearance: looks_mean(&held_out, |h| h.dense_appearance.as_ref())
                            .map(|(_, a)| a),
                        held_out,
                    });
                }
            }
        }
    }
    let show = Showcase {
        backend,
        coll,
        p,
        folds: &folds,
        bases: &bases[0][0],
        chosen: &show_chosen,
        prior: &show_prior,
        cellset: &cellset,
        cands: &cands,
        rp: &rp,
        display: &display,
        originals: &originals,
    };
    let showcase = show.build(&results)?;
    Ok(AcqCv {
        showcase,
        folds: folds
            .iter()
            .map(|f| f.iter().map(|&i| names[i].clone()).collect())
            .collect(),
        seed: p.seed,
        select: AcqSelect {
            method: p
                .methods
                .iter()
                .map(|m| m.name())
                .collect::<Vec<_>>()
                .join(","),
            k: p.k,
        },
        k: p.k,
        candidates_per_step: p.candidates_per_step,
        restarts: p.restarts,
        objective: weight.kind().name().to_string(),
        results,
        collection_fingerprint: coll.fingerprint(),
    })
}

/// Noisy measurements `f (1 + sigma N(0, 1))` of held-out material `ti` (collection index)
/// at `nmax` samples, `f(c, s)` its noise-free value: one draw per sample and channel,
/// seeded per material and noise level (the same draws for every plan).
fn measure(
    seed: u64,
    ti: usize,
    si: usize,
    sigma: f64,
    nmax: usize,
    f: impl Fn(usize, usize) -> f64,
) -> [Vec<f64>; 3] {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(
        seed ^ ((ti as u64 + 1) << 20) ^ ((si as u64 + 1) << 8),
    );
    let mut y: [Vec<f64>; 3] = Default::default();
    for s in 0..nmax {
        for (c, yc) in y.iter_mut().enumerate() {
            let z = standard_normal(&mut rng);
            yc.push(f(c, s) * (1.0 + sigma * z));
        }
    }
    y
}

/// Per-channel sample fit (Lambertian + basis, SPEC 10) of the first `ns` samples:
/// `vals[c][b][s]` the basis values, `y[c]` the measurements, each sample weighted by the
/// objective's weight at its measured value and `cos[s]`, its `cos theta_i` (SPEC 11).
#[allow(clippy::needless_range_loop)]
fn sample_coefficients(
    nb: usize,
    vals: &[Vec<Vec<f64>>; 3],
    y: &[Vec<f64>; 3],
    ns: usize,
    weight: TargetWeight,
    cos: &[f64],
    toward: Option<(&[Vec<f64>; 3], f64)>,
) -> Result<[Vec<f64>; 3], AcquireError> {
    let mm = nb + 1;
    let mut x: [Vec<f64>; 3] = Default::default();
    for c in 0..3 {
        let mut r = Vec::with_capacity(ns * mm);
        for s in 0..ns {
            r.push(FRAC_1_PI);
            r.extend((0..nb).map(|b| vals[c][b][s]));
        }
        let w: Vec<f64> = (0..ns).map(|s| weight.phi(y[c][s], cos[s])).collect();
        let pr = toward.map(|(mean, l)| (&mean[c][..], l));
        x[c] = solve_rows_toward(mm, &r, &y[c][..ns], &w, pr)?.x;
    }
    Ok(x)
}

/// The ridge of the fits from samples (SPEC 10, beside it in `docs/acquisition.md`): the
/// mean over a fold's training materials of their dense fits (under the objective's
/// shared weights), and those materials' dense state to score their fits from samples.
struct Prior {
    /// Per channel, the mean coefficients (Lambertian first).
    mean: [Vec<f64>; 3],
    /// The training materials' full-mask Gram quantities (shared weights).
    dense: Dense,
}

impl Prior {
    fn new(
        backend: &dyn Backend,
        coll: &Collection,
        basis: &[usize],
        train: &[usize],
        fp: &FitParams,
    ) -> Result<Self, AcquireError> {
        let dense = Dense::new(backend, coll, basis, train, fp)?;
        let m = dense.m;
        let mut mean = [vec![0.0; m], vec![0.0; m], vec![0.0; m]];
        for (c, mc) in mean.iter_mut().enumerate() {
            let g = &dense.g[c];
            let xs = crate::nnls::GramBatch::new(
                m,
                &g.gram,
                &g.h[..train.len() * m],
                &g.bb[..train.len()],
            )
            .and_then(|b| lawson_hanson::solve_batch(&b, &lawson_hanson::LhParams::default()))?;
            for s in &xs {
                for (a, x) in mc.iter_mut().zip(&s.x) {
                    *a += x / train.len() as f64;
                }
            }
        }
        Ok(Self { mean, dense })
    }

    /// The ridge strength of [`RIDGE_STRENGTHS`] whose fits of the training materials
    /// from their noise-free values `tv[c][t][s]` at the first `ns` samples (basis values
    /// `vals[c][b][s]`) have the lowest mean score (`rho` under the shared weights on the
    /// whole mask); ties to the weaker ridge.
    #[allow(clippy::needless_range_loop)]
    fn choose(
        &self,
        vals: &[Vec<Vec<f64>>; 3],
        tv: &[Vec<Vec<f64>>; 3],
        ns: usize,
        weight: TargetWeight,
        cos: &[f64],
    ) -> Result<f64, AcquireError> {
        let nb = self.dense.m - 1;
        let nt = tv[0].len();
        let scores: Vec<f64> = RIDGE_STRENGTHS
            .par_iter()
            .map(|&l| -> Result<f64, AcquireError> {
                let mut sum = 0.0;
                for t in 0..nt {
                    let y = [0, 1, 2].map(|c| tv[c][t].clone());
                    let x =
                        sample_coefficients(nb, vals, &y, ns, weight, cos, Some((&self.mean, l)))?;
                    sum += self.dense.rho(t, &x);
                }
                Ok(sum / nt.max(1) as f64)
            })
            .collect::<Result<_, _>>()?;
        let mut best = 0;
        for (i, v) in scores.iter().enumerate() {
            if *v < scores[best] {
                best = i;
            }
        }
        Ok(RIDGE_STRENGTHS[best])
    }
}

/// `(rho, MAE, image error, appearance)` of one reconstruction.
type Scores = (f64, f64, f64, Option<Appearance>);

/// The mean log-RMSE and the means of the image metrics of the rows' `get`, when every
/// row has them.
fn looks_mean(
    rows: &[AcqHeldOut],
    get: impl Fn(&AcqHeldOut) -> Option<&Appearance>,
) -> Option<(f64, AppearanceMeans)> {
    let a: Vec<&Appearance> = rows.iter().filter_map(&get).collect();
    if a.len() != rows.len() {
        return None;
    }
    let logs: Vec<f64> = a.iter().map(|x| x.log_rmse).collect();
    Some((mean(&logs), means_of(&a)?))
}

/// What the `nielsen` rows of one fold share.
struct NielsenFold<'a> {
    coll: &'a Collection,
    model: &'a NielsenModel,
    chosen: &'a [usize],
    weights: &'a [f64],
    rp: &'a RenderParams,
    display: &'a DisplayParams,
    lights: &'a [LightRenders],
}

/// Held-out material `ti` reconstructed by the `nielsen` baseline from its first n samples,
/// per n and noise level (`[n][noise]`): rho and MAE on every model cell (the fit mask),
/// image error of the render.
fn nielsen_rows(
    nf: &NielsenFold<'_>,
    p: &AcqCvParams,
    ti: usize,
    original: &Image,
) -> Result<Vec<Vec<Scores>>, AcquireError> {
    let cpu = CpuBackend::new();
    let data = &nf.coll.materials()[ti].data;
    let tv = super::nielsen::channel_values(&cpu, data, &nf.model.cells);
    let e: f64 = tv
        .iter()
        .map(|t| {
            t.iter()
                .zip(nf.weights)
                .map(|(v, w)| w * v * v)
                .sum::<f64>()
        })
        .sum();
    let nmax = nf.chosen.len();
    let mut out = vec![Vec::with_capacity(p.noises.len()); p.ns.len()];
    for (si, &sigma) in p.noises.iter().enumerate() {
        let y = measure(p.seed, ti, si, sigma, nmax, |c, s| tv[c][nf.chosen[s]]);
        for (ni, &ns) in p.ns.iter().enumerate() {
            let ns = ns.min(nmax);
            let coef: [Vec<f64>; 3] =
                [0, 1, 2].map(|c| nf.model.coefficients(&nf.chosen[..ns], &y[c][..ns], ETA));
            let (mut sq, mut ab) = (0.0, 0.0);
            for c in 0..3 {
                for (j, (&t, &w)) in tv[c].iter().zip(nf.weights).enumerate() {
                    let r = nf.model.value(j, &coef[c]) - t;
                    sq += w * r * r;
                    ab += w * r.abs();
                }
            }
            let img = render_sphere(nf.rp, &nf.model.brdf(&coef))
                .map_err(|e| AcquireError::Render(e.to_string()))?;
            let ie = normalized_image_error(original, &img, nf.display)
                .map_err(|e| AcquireError::Render(e.to_string()))?;
            let looks = if nf.lights.is_empty() {
                None
            } else {
                let brdf = nf.model.brdf(&coef);
                let mut a =
                    LightRenders::scores_of(nf.lights, ti, |l| render_sphere(l.params(), &brdf))
                        .map_err(|e| AcquireError::Render(e.to_string()))?;
                let mut logs = LogSums::default();
                for c in 0..3 {
                    for (j, (&t, &w)) in tv[c].iter().zip(nf.weights).enumerate() {
                        let cos = crate::backend::weighted::cos_theta_i(nf.model.cells[j] as usize);
                        logs.add(nf.model.value(j, &coef[c]), t, w, cos);
                    }
                }
                a.log_rmse = logs.value();
                Some(a)
            };
            out[ni].push((if e > 0.0 { sq / e } else { 0.0 }, ab / 3.0, ie, looks));
        }
    }
    Ok(out)
}

/// What the showcase renders need.
struct Showcase<'a> {
    backend: &'a dyn Backend,
    coll: &'a Collection,
    p: &'a AcqCvParams,
    folds: &'a [Vec<usize>],
    bases: &'a [Vec<usize>],
    chosen: &'a [Vec<Candidate>],
    prior: &'a [Option<[Vec<f64>; 3]>],
    cellset: &'a crate::merl::grid::CellSet,
    cands: &'a [Candidate],
    rp: &'a RenderParams,
    display: &'a DisplayParams,
    originals: &'a [Image],
}

impl Showcase<'_> {
    /// The showcase of [`AcqShowcase`] (none without results).
    fn build(&self, results: &[AcqResult]) -> Result<Option<AcqShowcase>, AcquireError> {
        let (p, coll) = (self.p, self.coll);
        let (Some(&crit), Some(m)) = (p.plans.first(), p.methods.first()) else {
            return Ok(None);
        };
        let si = p.noises.iter().position(|&s| s == 0.0).unwrap_or(0);
        let Some(&sigma) = p.noises.get(si) else {
            return Ok(None);
        };
        let mut ns: Vec<usize> = p.ns.clone();
        ns.sort_unstable();
        ns.dedup();
        let nmax = ns.last().copied().unwrap_or(0);
        let find = |n: usize| {
            results
                .iter()
                .find(|r| r.method == m.name() && r.plan == crit && r.n == n && r.noise == sigma)
        };
        let Some(last) = find(nmax) else {
            return Ok(None);
        };
        let mut order: Vec<&AcqHeldOut> = last.held_out.iter().collect();
        order.sort_by(|a, b| a.rho.total_cmp(&b.rho).then(a.material.cmp(&b.material)));
        let Some(h) = order.get(order.len() / 2) else {
            return Ok(None);
        };
        let names = coll.names();
        let Some(ti) = names.iter().position(|x| *x == h.material) else {
            return Ok(None);
        };
        let f = h.fold;
        let basis = &self.bases[f];
        let render = |b: &(dyn Fn([f64; 3], [f64; 3]) -> [f64; 3] + Sync)| {
            let img = render_sphere(self.rp, b).map_err(|e| AcquireError::Render(e.to_string()))?;
            let ie = normalized_image_error(&self.originals[ti], &img, self.display)
                .map_err(|e| AcquireError::Render(e.to_string()))?;
            Ok::<_, AcquireError>((img, ie))
        };
        // The dense fit of the fold's basis (under the objective; rho is l2's).
        let fp_obj = p.objective.fit_params();
        let weight = fp_obj.objective;
        let fp = FitParams {
            objective: TargetWeight::L2,
            ..fp_obj.clone()
        };
        let dense = Dense::new(self.backend, coll, basis, &[ti], &fp)?;
        let mm = basis.len() + 1;
        let x = if weight == TargetWeight::L2 {
            let x = [0, 1, 2].map(|c| {
                let g = &dense.g[c];
                GramProblem::new(mm, &g.gram, &g.h[..mm], g.bb[0])
                    .and_then(|pr| lawson_hanson::solve(&pr, &lawson_hanson::LhParams::default()))
                    .map(|s| s.x)
            });
            let [a, b, c] = x;
            [a?, b?, c?]
        } else {
            // On the CPU twin, as the held-out limits (acquisition_cv).
            let tf = crate::fit::fit(&CpuBackend::new(), coll, basis, &[ti], &fp_obj, &|_, _| {})?;
            [0, 1, 2].map(|c| tf[0].coefficients.iter().map(|a| a[c]).collect())
        };
        let coef: Vec<[f64; 3]> = (0..mm).map(|j| [x[0][j], x[1][j], x[2][j]]).collect();
        let (img, ie) = render(&combination_brdf(coll, basis, &coef))?;
        let mut tiles = vec![("dense fit".to_string(), img, ie, dense.rho(0, &x))];
        let rho_at = |n: usize| {
            find(n)
                .and_then(|r| r.held_out.iter().find(|x| x.material == h.material))
                .map_or(f64::NAN, |x| x.rho)
        };
        if crit == Criterion::Nielsen {
            let held = &self.folds[f];
            let train_all: Vec<usize> = (0..coll.len())
                .filter(|i| held.binary_search(i).is_err())
                .collect();
            let model = NielsenModel::train(coll, &train_all, &self.cellset.cells, nmax)?;
            let seed_f = p.seed.wrapping_add(1000 * f as u64);
            let chosen = model.plan(nmax, nielsen_per_step(p.candidates_per_step), seed_f);
            let at: Vec<Candidate> = chosen.iter().map(|&j| self.cands[j]).collect();
            let vals = values_at(coll, &[ti], &at)?;
            let y = measure(p.seed, ti, si, sigma, chosen.len(), |c, s| vals[c][0][s]);
            for &n in &ns {
                let k = n.min(chosen.len());
                let coef = [0, 1, 2].map(|c| model.coefficients(&chosen[..k], &y[c][..k], ETA));
                let (img, ie) = render(&model.brdf(&coef))?;
                tiles.push((format!("n = {n}"), img, ie, rho_at(n)));
            }
        } else {
            let chosen = &self.chosen[f];
            let mut mats = basis.clone();
            mats.push(ti);
            let vals = values_at(coll, &mats, chosen)?;
            let nb = basis.len();
            let y = measure(p.seed, ti, si, sigma, chosen.len(), |c, s| vals[c][nb][s]);
            let cos: Vec<f64> = chosen.iter().map(|c| c.wi[2]).collect();
            for &n in &ns {
                let lambda = find(n).and_then(|r| r.ridge.get(f).copied()).unwrap_or(0.0);
                let toward = self.prior[f].as_ref().map(|m| (m, lambda));
                let x =
                    sample_coefficients(nb, &vals, &y, n.min(chosen.len()), weight, &cos, toward)?;
                let coef: Vec<[f64; 3]> = (0..mm).map(|j| [x[0][j], x[1][j], x[2][j]]).collect();
                let (img, ie) = render(&combination_brdf(coll, basis, &coef))?;
                tiles.push((format!("n = {n}"), img, ie, rho_at(n)));
            }
        }
        Ok(Some(AcqShowcase {
            material: h.material.clone(),
            fold: f,
            method: m.name().to_string(),
            plan: crit,
            noise: sigma,
            original: self.originals[ti].clone(),
            tiles,
        }))
    }
}

/// The render of `combination_brdf(coll, basis, coef)` from `pixels` and its image error
/// against `original`.
fn render_error(
    pixels: &PixelBrdfs,
    rp: &RenderParams,
    display: &DisplayParams,
    original: &Image,
    basis: &[usize],
    coef: &[[f64; 3]],
) -> Result<(Image, f64), AcquireError> {
    let img = render_sphere(rp, &pixels.combination(basis, coef))
        .map_err(|e| AcquireError::Render(e.to_string()))?;
    let ie = normalized_image_error(original, &img, display)
        .map_err(|e| AcquireError::Render(e.to_string()))?;
    Ok((img, ie))
}

/// A standard normal draw (Box-Muller on two uniform draws in (0, 1]).
fn standard_normal(rng: &mut rand_chacha::ChaCha8Rng) -> f64 {
    let u1 = 1.0 - rand::Rng::random::<f64>(rng);
    let u2 = rand::Rng::random::<f64>(rng);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

impl AcqCv {
    /// The results as a Markdown table: one row per method, plan, n and noise (mean and
    /// median over the held-out materials), and per method the dense fit's row.
    pub fn markdown(&self) -> String {
        use crate::stats::num;
        let mut s = String::from(
            "| method | plan | n | noise | mean rho | median rho | dense rho | ratio | mean MAE | median MAE | mean image error | median image error |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
        );
        let mut methods: Vec<&str> = Vec::new();
        for r in &self.results {
            if !methods.contains(&r.method.as_str()) {
                methods.push(&r.method);
            }
        }
        for m in methods {
            if let Some(r) = self.results.iter().find(|r| r.method == m) {
                let col = |g: fn(&AcqHeldOut) -> f64| r.held_out.iter().map(g).collect::<Vec<_>>();
                let (rho, mae, img) = (
                    col(|h| h.dense_rho),
                    col(|h| h.dense_mae),
                    col(|h| h.dense_image_error),
                );
                s.push_str(&format!(
                    "| {m} | dense fit (the limit) | all | 0 | {} | {} | {} | 1 | {} | {} | {} | {} |\n",
                    num(mean(&rho)),
                    num(median(&rho)),
                    num(mean(&rho)),
                    num(mean(&mae)),
                    num(median(&mae)),
                    num(mean(&img)),
                    num(median(&img))
                ));
            }
            for r in self.results.iter().filter(|r| r.method == m) {
                s.push_str(&format!(
                    "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                    r.method,
                    r.plan.as_str(),
                    r.n,
                    num(r.noise),
                    num(r.mean_rho),
                    num(r.median_rho),
                    num(r.mean_dense_rho),
                    num(r.ratio),
                    num(r.mean_mae),
                    num(r.median_mae),
                    num(r.mean_image_error),
                    num(r.median_image_error)
                ));
            }
        }
        if let Some(a) = self.appearance_markdown() {
            s.push('\n');
            s.push_str(&a);
        }
        s
    }

    /// The appearance metrics (SPEC 11) of every row as a Markdown table (means over the
    /// held-out materials; image metrics at 256 px under the paper's light and averaged
    /// over the four lights), the dense fits first; `None` when they were not computed.
    pub fn appearance_markdown(&self) -> Option<String> {
        use crate::stats::num;
        if self.results.iter().all(|r| r.appearance.is_none()) {
            return None;
        }
        let mut s = format!(
            "Appearance (objective `{}`; SPEC 11: renders 256 px, four lights):\n\n| method | plan | n | noise | log-RMSE | image error (45, 45) | image error (4 lights) | CIEDE2000 (4 lights) | FLIP (45, 45) | FLIP (4 lights) | median FLIP |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
            self.objective
        );
        let row = |s: &mut String,
                   m: &str,
                   plan: &str,
                   n: &str,
                   noise: &str,
                   l: f64,
                   a: &AppearanceMeans| {
            s.push_str(&format!(
                "| {m} | {plan} | {n} | {noise} | {} | {} | {} | {} | {} | {} | {} |\n",
                num(l),
                num(a.image_error_paper_light),
                num(a.image_error),
                num(a.ciede2000),
                num(a.flip_paper_light),
                num(a.flip),
                num(a.median_flip)
            ));
        };
        let mut seen: Vec<&str> = Vec::new();
        for r in &self.results {
            if !seen.contains(&r.method.as_str()) {
                seen.push(&r.method);
                if let (Some(l), Some(a)) = (r.mean_dense_log_rmse, &r.dense_appearance) {
                    row(&mut s, &r.method, "dense fit (the limit)", "all", "0", l, a);
                }
            }
            if let (Some(l), Some(a)) = (r.mean_log_rmse, &r.appearance) {
                let (n, noise) = (r.n.to_string(), num(r.noise));
                row(&mut s, &r.method, r.plan.as_str(), &n, &noise, l, a);
            }
        }
        Some(s)
    }
}
