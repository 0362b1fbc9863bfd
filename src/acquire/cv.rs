//! Acquisition cross-validation (SPEC 10): folds as in SPEC 8; per fold the basis is chosen
//! on the training materials (a selection method and k), the plan on the training
//! materials (basis and training targets); each held-out material is measured at the plan's
//! first n samples (noise model `y = f (1 + sigma_rel N(0, 1))`, one draw per sample and
//! channel, seeded per material and noise level, so that the n'-measurement is a prefix of
//! the n-measurement), fitted from them and scored on the whole fit mask: rho (SPEC 8, from
//! the full-mask Gram form), MAE on the grid (SPEC 5) and the normalised image error of
//! renders (SPEC 7: light (45, 45)). The dense rho of the same basis (fit on the whole mask)
//! is its limit.

use super::fit::solve_rows;
use super::nielsen::{nielsen_per_step, NielsenModel, ETA};
use super::plan::{
    cell_candidates, plan, values_at, Candidate, Criterion, Dense, PlanParams, PlannedSample,
};
use super::AcquireError;
use crate::backend::cpu::CpuBackend;
use crate::backend::Backend;
use crate::collection::Collection;
use crate::distance::{distance_matrix, DistanceParams};
use crate::eval::image_error::{normalized_image_error, DisplayParams};
use crate::eval::render::{render_sphere, Image, RenderParams};
use crate::eval::shade::{combination_brdf, PixelBrdfs};
use crate::fit::fit_cells;
use crate::nnls::{lawson_hanson, GramProblem};
use crate::select::cv::evaluate::{GridEval, MaeJob};
use crate::select::cv::folds::fold_bases;
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
    /// Fit mask, weighting, stride.
    pub objective: ObjectiveParams,
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
/// the first method's first plan, not nielsen) and its rows per plan, n and noise.
type FoldRows = (Vec<String>, Vec<Candidate>, Vec<Vec<Vec<Cell>>>);

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
    let fp = p.objective.fit_params();
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
    let mut show_chosen: Vec<Vec<Candidate>> = vec![Vec::new(); folds.len()];
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
                // The dense fit of each held-out material (the limit).
                let dense_x: Vec<[Vec<f64>; 3]> = (0..held.len())
                    .into_par_iter()
                    .map(|t| -> Result<[Vec<f64>; 3], AcquireError> {
                        let x = [0, 1, 2].map(|c| {
                            let g = &dense.g[c];
                            GramProblem::new(mm, &g.gram, &g.h[t * mm..(t + 1) * mm], g.bb[t])
                                .and_then(|pr| {
                                    lawson_hanson::solve(&pr, &lawson_hanson::LhParams::default())
                                })
                                .map(|s| s.x)
                        });
                        let [a, b, c] = x;
                        Ok([a?, b?, c?])
                    })
                    .collect::<Result<_, _>>()?;
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
                        fit: fp.clone(),
                        restarts: p.restarts,
                    };
                    // Condition and random plans need no training materials: without
                    // them `plan` skips the training-score history the results never use.
                    let train_of = if crit == Criterion::Error {
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
                                .map(|t| sample_coefficients(basis.len(), &vals, &ys[t], ns))
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
                let maes = grid.maes(&jobs);
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
                    };
                    let per: Vec<Vec<Vec<(f64, f64, f64)>>> = held
                        .par_iter()
                        .map(|&ti| nielsen_rows(&nf, p, ti, &originals[ti]))
                        .collect::<Result<_, _>>()?;
                    for (ni, &ns) in p.ns.iter().enumerate() {
                        for si in 0..p.noises.len() {
                            let rows = held.iter().enumerate().map(|(t, &ti)| {
                                let (rho, mae, image_error) = per[t][ni][si];
                                AcqHeldOut {
                                    material: names[ti].clone(),
                                    fold: f,
                                    rho,
                                    dense_rho: dense_rho[t],
                                    mae,
                                    image_error,
                                    dense_mae: maes[t],
                                    dense_image_error: ies[t],
                                }
                            });
                            acc[pi][ni][si].0.extend(rows);
                            acc[pi][ni][si]
                                .1
                                .push(samples[..ns.min(samples.len())].to_vec());
                        }
                    }
                }
                Ok((named, show, acc))
            })
            .collect::<Result<_, _>>()?;
        for (f, (named, show, facc)) in per_fold.into_iter().enumerate() {
            fold_bases_named.push(named);
            if mi == 0 && !show.is_empty() {
                show_chosen[f] = show;
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
/// `vals[c][b][s]` the basis values, `y[c]` the measurements.
#[allow(clippy::needless_range_loop)]
fn sample_coefficients(
    nb: usize,
    vals: &[Vec<Vec<f64>>; 3],
    y: &[Vec<f64>; 3],
    ns: usize,
) -> Result<[Vec<f64>; 3], AcquireError> {
    let mm = nb + 1;
    let mut x: [Vec<f64>; 3] = Default::default();
    for c in 0..3 {
        let mut r = Vec::with_capacity(ns * mm);
        for s in 0..ns {
            r.push(FRAC_1_PI);
            r.extend((0..nb).map(|b| vals[c][b][s]));
        }
        x[c] = solve_rows(mm, &r, &y[c][..ns], &vec![1.0; ns])?.x;
    }
    Ok(x)
}

/// `(rho, MAE, image error)` of one reconstruction.
type Scores = (f64, f64, f64);

/// What the `nielsen` rows of one fold share.
struct NielsenFold<'a> {
    coll: &'a Collection,
    model: &'a NielsenModel,
    chosen: &'a [usize],
    weights: &'a [f64],
    rp: &'a RenderParams,
    display: &'a DisplayParams,
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
            out[ni].push((if e > 0.0 { sq / e } else { 0.0 }, ab / 3.0, ie));
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
        // The dense fit of the fold's basis.
        let fp = p.objective.fit_params();
        let dense = Dense::new(self.backend, coll, basis, &[ti], &fp)?;
        let mm = basis.len() + 1;
        let x = [0, 1, 2].map(|c| {
            let g = &dense.g[c];
            GramProblem::new(mm, &g.gram, &g.h[..mm], g.bb[0])
                .and_then(|pr| lawson_hanson::solve(&pr, &lawson_hanson::LhParams::default()))
                .map(|s| s.x)
        });
        let [a, b, c] = x;
        let x = [a?, b?, c?];
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
            for &n in &ns {
                let x = sample_coefficients(nb, &vals, &y, n.min(chosen.len()))?;
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
        s
    }
}
