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
use super::plan::{
    cell_candidates, plan, values_at, Candidate, Criterion, Dense, PlanParams, PlannedSample,
};
use super::AcquireError;
use crate::backend::Backend;
use crate::collection::Collection;
use crate::distance::{distance_matrix, DistanceParams};
use crate::eval::image_error::{normalized_image_error, DisplayParams};
use crate::eval::render::{render_sphere, RenderParams};
use crate::eval::shade::{combination_brdf, material_brdf};
use crate::nnls::{lawson_hanson, GramProblem};
use crate::select::cv::evaluate::GridEval;
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
}

/// The `cv --acquisition` JSON.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AcqCv {
    /// Folds, by name.
    pub folds: Vec<Vec<String>>,
    /// Seed.
    pub seed: u64,
    /// Basis size.
    pub k: usize,
    /// Candidates examined per plan step.
    pub candidates_per_step: usize,
    /// Per method, plan, n and noise.
    pub results: Vec<AcqResult>,
    /// Collection fingerprint.
    pub collection_fingerprint: String,
}

/// Runs the acquisition cross-validation (module docs).
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
    let originals: Vec<_> = (0..n)
        .into_par_iter()
        .map(|t| render_sphere(&rp, &material_brdf(&coll.materials()[t].data)))
        .collect::<Result<_, _>>()
        .map_err(|e| AcquireError::Render(e.to_string()))?;
    let names = coll.names();
    let all: Vec<usize> = (0..n).collect();
    let cands = cell_candidates(coll, &all, &fp)?;
    let mut results = Vec::new();
    for (mi, m) in p.methods.iter().enumerate() {
        // rows[plan][n][noise] accumulated over folds.
        let mut acc: Vec<Vec<Vec<(Vec<AcqHeldOut>, Vec<Vec<PlannedSample>>)>>> =
            vec![vec![vec![(Vec::new(), Vec::new()); p.noises.len()]; p.ns.len()]; p.plans.len()];
        let mut fold_bases_named = Vec::new();
        for (f, held) in folds.iter().enumerate() {
            let basis = &bases[mi][0][f];
            fold_bases_named.push(basis.iter().map(|&b| names[b].clone()).collect::<Vec<_>>());
            let train: Vec<usize> = (0..n)
                .filter(|i| held.binary_search(i).is_err() && !basis.contains(i))
                .collect();
            let dense = Dense::new(backend, coll, basis, held, &fp)?;
            let mm = basis.len() + 1;
            let dense_rho: Vec<f64> = (0..held.len())
                .map(|t| {
                    let x = [0, 1, 2].map(|c| {
                        let g = &dense.g[c];
                        GramProblem::new(mm, &g.gram, &g.h[t * mm..(t + 1) * mm], g.bb[t])
                            .and_then(|pr| {
                                lawson_hanson::solve(&pr, &lawson_hanson::LhParams::default())
                            })
                            .map(|s| s.x)
                    });
                    let [a, b, c] = x;
                    Ok(dense.rho(t, &[a?, b?, c?]))
                })
                .collect::<Result<_, crate::nnls::NnlsError>>()?;
            for (pi, &crit) in p.plans.iter().enumerate() {
                let pp = PlanParams {
                    n: nmax,
                    criterion: crit,
                    candidates_per_step: p.candidates_per_step,
                    shortlist: p.shortlist,
                    seed: p.seed.wrapping_add(1000 * f as u64),
                    fit: fp.clone(),
                };
                let pl = plan(backend, coll, basis, &train, &cands, &pp)?;
                let chosen: Vec<Candidate> = pl.chosen.clone();
                let mut mats = basis.clone();
                mats.extend_from_slice(held);
                let vals = values_at(coll, &mats, &chosen)?;
                for (si, &sigma) in p.noises.iter().enumerate() {
                    // Noisy measurements of every held-out material at the nmax samples.
                    let ys: Vec<[Vec<f64>; 3]> = held
                        .iter()
                        .enumerate()
                        .map(|(t, &ti)| {
                            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(
                                p.seed ^ ((ti as u64 + 1) << 20) ^ ((si as u64 + 1) << 8),
                            );
                            let mut y: [Vec<f64>; 3] = Default::default();
                            for s in 0..nmax {
                                for (c, yc) in y.iter_mut().enumerate() {
                                    let z = standard_normal(&mut rng);
                                    yc.push(vals[c][basis.len() + t][s] * (1.0 + sigma * z));
                                }
                            }
                            y
                        })
                        .collect();
                    for (ni, &ns) in p.ns.iter().enumerate() {
                        let rows: Vec<AcqHeldOut> = held
                            .par_iter()
                            .enumerate()
                            .map(|(t, &ti)| -> Result<AcqHeldOut, AcquireError> {
                                let mut x: [Vec<f64>; 3] = Default::default();
                                for c in 0..3 {
                                    let mut r = Vec::with_capacity(ns * mm);
                                    for s in 0..ns {
                                        r.push(FRAC_1_PI);
                                        r.extend((0..basis.len()).map(|b| vals[c][b][s]));
                                    }
                                    x[c] = solve_rows(mm, &r, &ys[t][c][..ns], &vec![1.0; ns])?.x;
                                }
                                let coef: Vec<[f64; 3]> =
                                    (0..mm).map(|j| [x[0][j], x[1][j], x[2][j]]).collect();
                                let img = render_sphere(&rp, &combination_brdf(coll, basis, &coef))
                                    .map_err(|e| AcquireError::Render(e.to_string()))?;
                                Ok(AcqHeldOut {
                                    material: names[ti].clone(),
                                    fold: f,
                                    rho: dense.rho(t, &x),
                                    dense_rho: dense_rho[t],
                                    mae: grid.mae(basis, ti, &coef),
                                    image_error: normalized_image_error(
                                        &originals[ti],
                                        &img,
                                        &display,
                                    )
                                    .map_err(|e| AcquireError::Render(e.to_string()))?,
                                })
                            })
                            .collect::<Result<_, _>>()?;
                        acc[pi][ni][si].0.extend(rows);
                        acc[pi][ni][si].1.push(pl.samples[..ns].to_vec());
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
                        held_out,
                    });
                }
            }
        }
    }
    Ok(AcqCv {
        folds: folds
            .iter()
            .map(|f| f.iter().map(|&i| names[i].clone()).collect())
            .collect(),
        seed: p.seed,
        k: p.k,
        candidates_per_step: p.candidates_per_step,
        results,
        collection_fingerprint: coll.fingerprint(),
    })
}

/// A standard normal draw (Box-Muller on two uniform draws in (0, 1]).
fn standard_normal(rng: &mut rand_chacha::ChaCha8Rng) -> f64 {
    let u1 = 1.0 - rand::Rng::random::<f64>(rng);
    let u2 = rand::Rng::random::<f64>(rng);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

impl AcqCv {
    /// The results as a Markdown table: one row per method, plan, n and noise.
    pub fn markdown(&self) -> String {
        use crate::stats::num;
        let mut s = String::from(
            "| method | plan | n | noise | mean rho | median rho | dense rho | ratio | mean MAE | image error |\n|---|---|---|---|---|---|---|---|---|---|\n",
        );
        for r in &self.results {
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                r.method,
                r.plan.as_str(),
                r.n,
                num(r.noise),
                num(r.mean_rho),
                num(r.median_rho),
                num(r.mean_dense_rho),
                num(r.ratio),
                num(r.mean_mae),
                num(r.mean_image_error)
            ));
        }
        s
    }
}
