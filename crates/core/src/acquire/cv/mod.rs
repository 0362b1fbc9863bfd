//! Acquisition cross-validation (SPEC 10): folds as in SPEC 8; per fold the basis is chosen
//! on the training materials (a selection method and k), the plan on the training
//! materials (basis and training targets); each held-out material is measured at the plan's
//! first n samples (noise model `y = f (1 + sigma_rel N(0, 1))`, one draw per sample and
//! channel, seeded per material and noise level, so that the n'-measurement is a prefix of
//! the n-measurement), fitted from them and scored on the whole fit mask: rho (SPEC 8, from
//! the full-mask Gram form), MAE on the grid (SPEC 5) and the normalised image error of
//! renders (SPEC 7: light (45, 45)). The dense rho of the same basis (fit on the whole mask)
//! is its limit.

use super::fit::{function_shape, solve_rows_toward, Toward, RIDGE_STRENGTHS};
use super::nielsen::{nielsen_per_step, NielsenModel, ETA};
use super::plan::{cell_candidates, plan_given_dense, plan_with_progress, values_at, Dense};
use super::AcquireError;
use super::{Candidate, Criterion, PlanParams, PlannedSample};
use crate::backend::cpu::CpuBackend;
use crate::backend::weighted::TargetWeight;
use crate::backend::Backend;
use crate::collection::Collection;
use crate::distance::{distance_matrix, DistanceParams};
use crate::eval::appearance::{Appearance, LogSums};
use crate::eval::image_error::{normalized_image_error, DisplayParams};
use crate::eval::render::{render_sphere, Image, RenderParams};
use crate::eval::shade::{combination_brdf, PixelBrdfs};
use crate::fit::{fit_cells, FitParams};
use crate::nnls::{lawson_hanson, GramProblem};
use crate::select::cv::evaluate::{means_of, GridEval, LightRenders, MaeJob};
use crate::select::cv::folds::fold_bases;
use crate::select::cv::AppearanceMeans;
use crate::select::cv::{CvMethod, CvParams};
use crate::select::{make_folds, Objective, ObjectiveParams};
use crate::stats::{mean, median};
use rand::SeedableRng;
use rayon::prelude::*;
use std::f64::consts::FRAC_1_PI;
use std::sync::atomic::{AtomicU64, Ordering};

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
    /// mean material, measured on the whole grid under the shared weights
    /// (the basis's shared-weight Gram matrix), its strength chosen per fold, plan and n on the training
    /// materials, each left out of the prior it is judged with ([`RIDGE_STRENGTHS`]);
    /// `false`: plain NNLS.
    pub ridge: bool,
    /// A fixed split: the names of the held-out materials, scored as one fold (seed
    /// `seed`, as fold 0 of a cross-validation) with the basis, the plans and the
    /// `nielsen` model trained on the others; empty: `folds` folds.
    pub test: Vec<String>,
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
            test: Vec::new(),
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
    /// The strength of the energy penalty of the fits from samples per fold
    /// ([`ENERGY_STRENGTHS`], chosen with `ridge`; empty where `ridge` is).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub energy_ridge: Vec<f64>,
    /// The largest rho over the held-out materials (above 1: a reconstruction further
    /// from its material than black is; NaN in files written before it).
    #[serde(default = "nan")]
    pub max_rho: f64,
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
    /// The size of the renders of `mean_image_error` (pixels), for the Markdown's headers
    /// (audit 3, U5: the appearance table's image error is at 256 px); not in the JSON,
    /// whose fields stay as they were (`None` when read back).
    #[serde(skip)]
    pub render_size: Option<u32>,
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

/// The value of a field missing from a file written before it.
fn nan() -> f64 {
    f64::NAN
}

/// Held-out rows and fold plans of one (plan, n, noise), accumulated over folds.
type Cell = (Vec<AcqHeldOut>, Vec<Vec<PlannedSample>>);

mod fold;
mod prior;
mod showcase;
mod split;

pub use prior::{ENERGY_STRENGTHS, HIGHLIGHT_DEG, WILD_RHO};

use fold::{FoldRows, Shared};
use showcase::Showcase;

/// Runs the acquisition cross-validation (module docs): the collection's shared state
/// (`Shared::new`: checks, fold bases, renders, candidates), then per method each fold
/// (`Shared::fold`) merged in fold order, one row per plan, n and noise
/// (`summarize`), and the showcase.
pub fn acquisition_cv(
    backend: &dyn Backend,
    coll: &Collection,
    p: &AcqCvParams,
) -> Result<AcqCv, AcquireError> {
    acquisition_cv_with_progress(backend, coll, p, &|_, _| {})
}

/// The progress of an acquisition cross-validation, in steps: the shared state, then per
/// method and fold each plan of ours with its fits, the scores, each `nielsen` plan with
/// its scores, and the showcase. Work inside a step calls [`Ticker::pulse`], which reports
/// the same position again: a caller that cancels from its progress callback (Python's
/// Ctrl-C) is heard within one render or one plan candidate, not one step.
pub(super) struct Ticker<'a> {
    progress: crate::backend::Progress<'a>,
    done: AtomicU64,
    total: AtomicU64,
}

impl<'a> Ticker<'a> {
    fn new(progress: crate::backend::Progress<'a>, p: &AcqCvParams) -> Self {
        let t = Self {
            progress,
            done: AtomicU64::new(0),
            total: AtomicU64::new(0),
        };
        t.set_folds(p, p.folds);
        t.pulse();
        t
    }

    /// The number of steps once the folds are made.
    fn set_folds(&self, p: &AcqCvParams, folds: usize) {
        let per_fold = p.plans.len() as u64 + 1;
        let total = 2 + (p.methods.len() * folds) as u64 * per_fold;
        self.total.store(total, Ordering::Relaxed);
    }

    /// Reports the current position again (work is going on inside a step).
    pub(super) fn pulse(&self) {
        let total = self.total.load(Ordering::Relaxed);
        (self.progress)(self.done.load(Ordering::Relaxed).min(total), total);
    }

    /// One step done.
    pub(super) fn step(&self) {
        self.done.fetch_add(1, Ordering::Relaxed);
        self.pulse();
    }
}

/// [`acquisition_cv`], reporting `progress(steps done, steps)` (see the CLI's bar); the
/// callback is also called while a step runs, with the same position, so that a caller
/// can cancel from it (it may unwind; the work holds no state outside its stack).
pub fn acquisition_cv_with_progress(
    backend: &dyn Backend,
    coll: &Collection,
    p: &AcqCvParams,
    progress: crate::backend::Progress<'_>,
) -> Result<AcqCv, AcquireError> {
    let tick = Ticker::new(progress, p);
    let s = Shared::new(backend, coll, p, &tick)?;
    tick.set_folds(p, s.folds.len());
    tick.step();
    let names = &s.names;
    let mut show_chosen: Vec<Vec<Candidate>> = vec![Vec::new(); s.folds.len()];
    let mut show_prior: Vec<Option<prior::Prior>> = (0..s.folds.len()).map(|_| None).collect();
    let mut results = Vec::new();
    for (mi, m) in p.methods.iter().enumerate() {
        // Each fold returns its rows, merged in fold order.
        let per_fold: Vec<FoldRows> = s
            .folds
            .iter()
            .enumerate()
            .map(|(f, held)| s.fold(mi, f, held, &tick))
            .collect::<Result<_, _>>()?;
        // rows[plan][n][noise] accumulated over folds.
        let mut acc = s.empty_cells();
        let mut fold_bases_named = Vec::new();
        let mut ridge_folds: Vec<Vec<Vec<prior::Strength>>> =
            vec![vec![Vec::new(); p.ns.len()]; p.plans.len()];
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
        results.extend(summarize(m, p, acc, &fold_bases_named, &ridge_folds));
    }
    let show = Showcase {
        backend,
        coll,
        p,
        folds: &s.folds,
        bases: &s.bases[0][0],
        chosen: &show_chosen,
        prior: &show_prior,
        cellset: &s.cellset,
        cands: &s.cands,
        rp: &s.rp,
        display: &s.display,
        originals: &s.originals,
    };
    let showcase = show.build(&results)?;
    tick.step();
    Ok(AcqCv {
        showcase,
        render_size: Some(p.render_size),
        folds: s
            .folds
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
        objective: s.weight.kind().name().to_string(),
        results,
        collection_fingerprint: coll.fingerprint(),
    })
}

/// One row per plan, n and noise of method `m` from its rows accumulated over the folds
/// (`acc[plan][n][noise]`, taken).
fn summarize(
    m: &CvMethod,
    p: &AcqCvParams,
    mut acc: Vec<Vec<Vec<Cell>>>,
    fold_bases_named: &[Vec<String>],
    ridge_folds: &[Vec<Vec<prior::Strength>>],
) -> Vec<AcqResult> {
    let mut results = Vec::new();
    for (pi, &crit) in p.plans.iter().enumerate() {
        for (ni, &ns) in p.ns.iter().enumerate() {
            for (si, &sigma) in p.noises.iter().enumerate() {
                let (held_out, plans) = std::mem::take(&mut acc[pi][ni][si]);
                let col = |g: fn(&AcqHeldOut) -> f64| held_out.iter().map(g).collect::<Vec<f64>>();
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
                    fold_bases: fold_bases_named.to_vec(),
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
                    ridge: ridge_folds[pi][ni].iter().map(|s| s.toward).collect(),
                    energy_ridge: ridge_folds[pi][ni].iter().map(|s| s.energy).collect(),
                    max_rho: rho.iter().copied().fold(f64::NAN, f64::max),
                    mean_log_rmse: looks_mean(&held_out, |h| h.appearance.as_ref()).map(|(l, _)| l),
                    appearance: looks_mean(&held_out, |h| h.appearance.as_ref()).map(|(_, a)| a),
                    mean_dense_log_rmse: looks_mean(&held_out, |h| h.dense_appearance.as_ref())
                        .map(|(l, _)| l),
                    dense_appearance: looks_mean(&held_out, |h| h.dense_appearance.as_ref())
                        .map(|(_, a)| a),
                    held_out,
                });
            }
        }
    }
    results
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

impl AcqCv {
    /// The results as a Markdown table: one row per method, plan, n and noise (mean and
    /// median over the held-out materials), and per method the dense fit's row.
    pub fn markdown(&self) -> String {
        use crate::stats::num;
        let mut s = format!(
            "| method | plan | n | noise | mean rho | median rho | max rho | dense rho | ratio | mean MAE | median MAE | {} | {} |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
            crate::select::cv::report::image_error_header("mean", self.render_size),
            crate::select::cv::report::image_error_header("median", self.render_size)
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
                    "| {m} | dense fit (the limit) | all | 0 | {} | {} | {} | {} | 1 | {} | {} | {} | {} |\n",
                    num(mean(&rho)),
                    num(median(&rho)),
                    num(rho.iter().copied().fold(f64::NAN, f64::max)),
                    num(mean(&rho)),
                    num(mean(&mae)),
                    num(median(&mae)),
                    num(mean(&img)),
                    num(median(&img))
                ));
            }
            for r in self.results.iter().filter(|r| r.method == m) {
                s.push_str(&format!(
                    "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                    r.method,
                    r.plan.as_str(),
                    r.n,
                    r.noise, // as given (0.02, not 0.02000): a setting, not a result
                    num(r.mean_rho),
                    num(r.median_rho),
                    num(r.max_rho),
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
            "Appearance (objective `{}`; SPEC 11: renders 256 px, four lights):\n\n| method | plan | n | noise | log-RMSE | image error (45, 45; 256 px) | image error (4 lights; 256 px) | CIEDE2000 (4 lights) | ΔE_ITP (4 lights) | FLIP (45, 45) | FLIP (4 lights) | median FLIP |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
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
                "| {m} | {plan} | {n} | {noise} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                num(l),
                num(a.image_error_paper_light),
                num(a.image_error),
                num(a.ciede2000),
                num(a.delta_e_itp),
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
                let (n, noise) = (r.n.to_string(), r.noise.to_string());
                row(&mut s, &r.method, r.plan.as_str(), &n, &noise, l, a);
            }
        }
        Some(s)
    }
}
