//! The paper's section VI end to end, as a library: distances, empirical selection,
//! clustering with validity indices, statistics, bases, fits and image errors. Every
//! stage returns typed results (serde types where they are written to files); the
//! command line (`reproduce`) only parses arguments and writes files.
//!
//! ```no_run
//! use brdf_basis_core::{backend::cpu::CpuBackend, collection::Collection, experiment::*};
//! let coll = Collection::embedded_default();
//! let p = ExperimentParams { runs: 5, stride: 4, ..Default::default() }.check(&coll).unwrap();
//! let e = run(&CpuBackend::new(), &coll, &p, &|_, _, _| {}).unwrap();
//! println!("{}", report::markdown(&e, &report::ReportContext::default()));
//! ```
//!
//! Extension points: another basis source is a [`bases::BasisSource`] variant and a
//! push in the `Bases` stage of [`run`]; another report section is one function in
//! [`report::SECTIONS`].

pub mod appearance;
pub mod bases;
pub mod claims;
pub mod evaluation;
pub mod report;
pub mod statistics;

use crate::backend::weighted::TargetWeight;
use crate::backend::Backend;
use crate::cluster::{ClusterError, GcukParams};
use crate::collection::Collection;
use crate::distance::{distance_matrix, DistanceMatrix, DistanceParams, Metric};
use crate::error::{CollectionError, DistanceError};
use crate::eval::image_error::DisplayParams;
use crate::eval::render::{RenderError, RenderParams};
use crate::fit::{CollectionGrams, FitError, FitParams};
use crate::merl::Weighting;
use crate::select as clustering;
use crate::select::cv::{cross_validate_with, CvParams, CvResult};
use crate::select::ClusteringSet;
use crate::select::SelectionError;
use crate::select::{empirical, empirical_from_grams, Empirical, EmpiricalParams};
use crate::select::{error_driven_bases, Selection};
use crate::select::{Objective, ObjectiveParams};
use bases::Basis;
use evaluation::{EvalSettings, Evaluation};
use statistics::Statistics;
use std::path::PathBuf;
use std::time::Instant;

/// Errors of the experiment.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum ExperimentError {
    /// A parameter is out of range.
    #[error("{name} = {value} is invalid: {expected}")]
    InvalidParam {
        /// Parameter (as the command-line flag).
        name: &'static str,
        /// The value given.
        value: String,
        /// What is expected.
        expected: String,
    },
    /// The paper-bases CSV is malformed or names an unknown material.
    #[error("{path}: line {line}: {message}")]
    PaperBases {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// What is wrong.
        message: String,
    },
    /// Every material is in some basis: nothing to evaluate.
    #[error("every material of the collection is in some basis: no material is left to evaluate the bases on (use a larger collection or fewer/smaller bases)")]
    NoTargets,
    /// A material name (e.g. `--showcase`).
    #[error("--showcase: {0}")]
    Showcase(CollectionError),
    /// Collection error.
    #[error(transparent)]
    Collection(#[from] CollectionError),
    /// Distance error.
    #[error(transparent)]
    Distance(#[from] DistanceError),
    /// Clustering error.
    #[error(transparent)]
    Cluster(#[from] ClusterError),
    /// Fit error.
    #[error(transparent)]
    Fit(#[from] FitError),
    /// Render error.
    #[error(transparent)]
    Render(#[from] RenderError),
    /// Error-driven selection or cross-validation error.
    #[error(transparent)]
    Selection(#[from] SelectionError),
}

/// Parameters of [`run`]; the defaults are the paper's settings (VI-C).
#[derive(Clone, Debug)]
pub struct ExperimentParams {
    /// Runs per clustering configuration, seeds `seed..seed + runs` (default 30).
    pub runs: usize,
    /// Grid stride for distances and fits (default 1 = full grid).
    pub stride: usize,
    /// Smallest k of k-medoids and GCUK (default 5).
    pub k_min: usize,
    /// Largest k of k-medoids (default 12).
    pub k_max: usize,
    /// GCUK k_max (default 20).
    pub gcuk_k_max: usize,
    /// GCUK population (default 20).
    pub population: usize,
    /// GCUK generations (default 10).
    pub generations: usize,
    /// Empirical threshold: contributes to more than this many fits (default 5).
    pub more_than: usize,
    /// Render size of the image errors, pixels (default 96).
    pub render_size: u32,
    /// Render size of the showcase (default 256).
    pub showcase_size: u32,
    /// Showcase material (default: `evaluation::default_showcase`: `alum-bronze` when it
    /// is a target, else a moderately glossy target whose render shows its lobe).
    pub showcase: Option<String>,
    /// First seed (default 1).
    pub seed: u64,
    /// The paper's bases (from [`bases::read_paper_bases`]); default none.
    pub paper_bases: Vec<Basis>,
    /// Also compare bases chosen by fitting error (SPEC 8): greedy and swap at `k_min`
    /// and `k_max`, the sizes of the paper's bases (default true).
    pub error_driven: bool,
    /// Folds of the cross-validation of every selection method (SPEC 8; default 5,
    /// 0 = none).
    pub cv_folds: usize,
    /// Clustering runs per fold in the cross-validation (default 10).
    pub cv_runs: usize,
}

impl Default for ExperimentParams {
    fn default() -> Self {
        ExperimentParams {
            runs: 30,
            stride: 1,
            k_min: 5,
            k_max: 12,
            gcuk_k_max: 20,
            population: 20,
            generations: 10,
            more_than: 5,
            render_size: 96,
            showcase_size: 256,
            showcase: None,
            seed: 1,
            paper_bases: vec![],
            error_driven: true,
            cv_folds: 5,
            cv_runs: 10,
        }
    }
}

/// Parameters checked against a collection.
#[derive(Clone, Debug)]
pub struct ValidExperimentParams {
    p: ExperimentParams,
    showcase: Option<usize>,
}

impl ValidExperimentParams {
    /// The parameters.
    pub fn params(&self) -> &ExperimentParams {
        &self.p
    }
}

fn invalid(name: &'static str, value: impl ToString, expected: String) -> ExperimentError {
    ExperimentError::InvalidParam {
        name,
        value: value.to_string(),
        expected,
    }
}

impl ExperimentParams {
    /// Checks every parameter against `coll` before any work.
    pub fn check(&self, coll: &Collection) -> Result<ValidExperimentParams, ExperimentError> {
        self.check_count(coll.len())?;
        let showcase = match &self.showcase {
            Some(s) => Some(coll.index_of(s).map_err(ExperimentError::Showcase)?),
            None => None,
        };
        Ok(ValidExperimentParams {
            p: self.clone(),
            showcase,
        })
    }

    /// The checks of [`Self::check`] that need only the number of materials `n` (all but
    /// the showcase's name): a caller can run them before it loads (and tabulates) the
    /// collection ([`Collection::count_many`]).
    ///
    /// # Errors
    /// The parameter that does not fit `n` materials, named.
    pub fn check_count(&self, n: usize) -> Result<(), ExperimentError> {
        if self.runs == 0 {
            return Err(invalid(
                "--runs",
                0,
                "at least 1 run per configuration".into(),
            ));
        }
        if !crate::merl::GridSpec::stride_ok(self.stride) {
            return Err(invalid(
                "--stride",
                self.stride,
                crate::merl::GridSpec::STRIDE_RULE.into(),
            ));
        }
        if self.k_min < 2 {
            return Err(invalid(
                "--k-min",
                self.k_min,
                "at least 2 (the DB index needs two clusters)".into(),
            ));
        }
        if self.k_min > self.k_max {
            return Err(invalid(
                "--k-max",
                self.k_max,
                format!("at least --k-min = {}", self.k_min),
            ));
        }
        if self.k_max >= n {
            return Err(invalid(
                "--k-max",
                self.k_max,
                format!("it must be below the number of materials ({n})"),
            ));
        }
        if self.gcuk_k_max < self.k_min || self.gcuk_k_max >= n {
            return Err(invalid(
                "--gcuk-k-max",
                self.gcuk_k_max,
                format!(
                    "between --k-min = {} and the number of materials less one ({})",
                    self.k_min,
                    n.saturating_sub(1)
                ),
            ));
        }
        GcukParams::default()
            .k_range(self.k_min, self.gcuk_k_max)
            .population(self.population)
            .generations(self.generations)
            .check()?;
        for size in [self.render_size, self.showcase_size] {
            RenderParams::default().with_size(size).check()?;
        }
        if self.cv_folds == 1 || self.cv_folds > n {
            return Err(invalid(
                "--cv-folds",
                self.cv_folds,
                format!("0 (no cross-validation) or between 2 and the number of materials ({n})"),
            ));
        }
        if self.cv_folds > 0 && self.cv_runs == 0 {
            return Err(invalid("--cv-runs", 0, "at least 1 run per fold".into()));
        }
        Ok(())
    }
}

/// The stages of [`run`], in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stage {
    /// Distance matrices.
    Distances,
    /// Empirical selection (Algorithm 1).
    Empirical,
    /// k-medoids and GCUK on every metric.
    Clustering,
    /// Friedman, Nemenyi, Wilcoxon, Mann-Whitney.
    Statistics,
    /// Bases chosen by fitting error (greedy, swap; SPEC 8).
    Selection,
    /// Cross-validation of every selection method over materials (SPEC 8).
    CrossValidation,
    /// Fits, renders and image errors of every basis.
    Fits,
    /// Held-out fits under each objective of SPEC 11 (`reproduce`'s Appearance section,
    /// [`appearance::run`], after the paper's stages).
    Appearance,
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Stage::Distances => "distances",
            Stage::Empirical => "empirical",
            Stage::Clustering => "clustering",
            Stage::Statistics => "statistics",
            Stage::Selection => "selection",
            Stage::CrossValidation => "cross-validation",
            Stage::Fits => "fits",
            Stage::Appearance => "appearance",
        })
    }
}

/// Wall time of one stage.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StageTiming {
    /// Stage name.
    pub stage: String,
    /// Seconds.
    pub seconds: f64,
}

/// A distance the clustering runs on.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MetricSpec {
    /// Label: `euclidean`, `brdf-it` or `brdf-it-solid-angle`.
    pub label: String,
    /// `euclidean` or `brdf-it`.
    pub metric: String,
    /// `uniform` or `solid-angle`.
    pub weighting: String,
    /// Lobe compared (`specular` or `full`; empty for Euclidean).
    pub lobe: String,
}

/// Settings as run, for the report's text.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Settings {
    /// Number of materials.
    pub materials: usize,
    /// [`Collection::fingerprint`] of the collection the experiment ran on.
    pub collection_fingerprint: String,
    /// Back-end name.
    pub backend: String,
    /// First seed.
    pub seed: u64,
    /// Runs per configuration.
    pub runs: usize,
    /// Grid stride.
    pub stride: usize,
    /// k-medoids range.
    pub k_min: usize,
    /// k-medoids range.
    pub k_max: usize,
    /// GCUK k_max.
    pub gcuk_k_max: usize,
    /// GCUK population.
    pub population: usize,
    /// GCUK generations.
    pub generations: usize,
    /// Empirical threshold.
    pub more_than: usize,
    /// Image-error render size.
    pub render_size: u32,
    /// Metrics clustered on.
    pub metrics: Vec<MetricSpec>,
}

/// Everything [`run`] computes.
#[derive(Clone, Debug)]
pub struct Experiment {
    /// Settings as run.
    pub settings: Settings,
    /// Distance matrices, one per metric (same order as `settings.metrics`).
    pub distances: Vec<DistanceMatrix>,
    /// Empirical selection.
    pub empirical: Empirical,
    /// Every clustering set (metric-major, k-medoids by k, then GCUK).
    pub clustering: Vec<ClusteringSet>,
    /// Statistical tests.
    pub statistics: Statistics,
    /// Bases chosen by fitting error on the whole collection (greedy, swap), in-sample.
    pub selections: Vec<Selection>,
    /// Cross-validation of the selection methods, if run.
    pub cv: Option<CvResult>,
    /// The bases compared (ours, then the paper's), coincident ones named once.
    pub bases: Vec<Basis>,
    /// Fits and errors.
    pub evaluation: Evaluation,
    /// The collection (for plots of materials and fits).
    pub collection: Collection,
    /// Wall time per stage.
    pub timings: Vec<StageTiming>,
}

/// Stage progress: `(stage, done, total)`.
pub type StageProgress<'a> = &'a (dyn Fn(Stage, u64, u64) + Sync);

/// The metrics of the experiment: Euclidean (F0, n), BRDF_it uniform (the paper's) and
/// BRDF_it with solid-angle weights (its future work). Euclidean needs analytic materials.
fn metric_list(coll: &Collection) -> Vec<(String, Metric, Weighting)> {
    let mut m = vec![];
    if coll.all_analytic() {
        m.push((
            "euclidean".to_string(),
            Metric::Euclidean,
            Weighting::Uniform,
        ));
    }
    m.push(("brdf-it".to_string(), Metric::BrdfIt, Weighting::Uniform));
    m.push((
        "brdf-it-solid-angle".to_string(),
        Metric::BrdfIt,
        Weighting::SolidAngle,
    ));
    m
}

/// Runs section VI on `coll`.
///
/// Long function: the seven stages of section VI run in order, each a
/// call to its own function with typed inputs and outputs, timed and reported between
/// calls; splitting the sequence would only hide the order the paper describes.
pub fn run(
    backend: &dyn Backend,
    coll: &Collection,
    vp: &ValidExperimentParams,
    progress: StageProgress<'_>,
) -> Result<Experiment, ExperimentError> {
    let p = &vp.p;
    let mut timings = Vec::new();
    let mut clock = Instant::now();
    let mut lap = |stage: Stage, timings: &mut Vec<StageTiming>| {
        timings.push(StageTiming {
            stage: stage.to_string(),
            seconds: clock.elapsed().as_secs_f64(),
        });
        clock = Instant::now();
    };

    // 1. Distances.
    let list = metric_list(coll);
    let mut distances = Vec::new();
    let mut metrics = Vec::new();
    for (i, (label, metric, weighting)) in list.iter().enumerate() {
        progress(Stage::Distances, i as u64, list.len() as u64);
        let dp = DistanceParams::default()
            .metric(*metric)
            .weighting(*weighting)
            .stride(p.stride)
            .check(coll)?;
        distances.push(distance_matrix(backend, coll, &dp, &|_, _| {})?);
        metrics.push(MetricSpec {
            label: label.clone(),
            metric: metric.to_string(),
            weighting: weighting.to_string(),
            lobe: if *metric == Metric::Euclidean {
                String::new()
            } else {
                dp.lobe().to_string()
            },
        });
    }
    progress(Stage::Distances, list.len() as u64, list.len() as u64);
    lap(Stage::Distances, &mut timings);

    // 2. Empirical selection.
    // The paper's fits: l2 (SPEC 5), not the library's default objective.
    let fit_params = FitParams {
        stride: p.stride,
        objective: TargetWeight::L2,
        ..Default::default()
    };
    let ep = EmpiricalParams {
        fit: fit_params.clone(),
        more_than: p.more_than,
    };
    // A measured or neural collection: one grid pass for the Gram matrices of all its
    // materials in the three channels, shared by the empirical selection, the objective of
    // SPEC 8 and the fits (the same cells: evaluation mask, uniform weights, this stride).
    // (No cell at all: no sharing; each stage reports it as before.)
    let shared = if CollectionGrams::needed(coll, fit_params.gram) && coll.len() >= 2 {
        Some(CollectionGrams::grid(
            backend,
            coll,
            &fit_params,
            &|d, t| progress(Stage::Empirical, d, t),
        )?)
        .filter(|g| !g.cells.cells.is_empty())
    } else {
        None
    };
    let emp = match &shared {
        Some(g) => empirical_from_grams(coll, &ep, &g.grams)?,
        None => empirical(backend, coll, &ep, &|d, t| progress(Stage::Empirical, d, t))?,
    };
    lap(Stage::Empirical, &mut timings);

    // 3. Clustering.
    let ks: Vec<usize> = (p.k_min..=p.k_max).collect();
    let gp = GcukParams::default()
        .k_range(p.k_min, p.gcuk_k_max)
        .population(p.population)
        .generations(p.generations);
    let mut sets = Vec::new();
    let steps = (metrics.len() * 2) as u64;
    for (i, (m, d)) in metrics.iter().zip(&distances).enumerate() {
        progress(Stage::Clustering, 2 * i as u64, steps);
        sets.extend(clustering::kmedoids_sets(d, &m.label, &ks, p.runs, p.seed)?);
        progress(Stage::Clustering, 2 * i as u64 + 1, steps);
        sets.push(clustering::gcuk_set(d, &m.label, &gp, p.runs, p.seed)?);
    }
    progress(Stage::Clustering, steps, steps);
    lap(Stage::Clustering, &mut timings);

    // 4. Statistics.
    progress(Stage::Statistics, 0, 1);
    let labels: Vec<String> = metrics.iter().map(|m| m.label.clone()).collect();
    let statistics = statistics::compare(&labels, &sets, p.runs);
    progress(Stage::Statistics, 1, 1);
    lap(Stage::Statistics, &mut timings);

    // 5. Error-driven bases and the cross-validation of every method (SPEC 8), from one
    // Gram matrix per channel of the whole collection.
    let ks: Vec<usize> = {
        let mut v = vec![p.k_min, p.k_max];
        v.dedup();
        v
    };
    let need_objective = p.error_driven || p.cv_folds > 0;
    let objective = if need_objective {
        let op = ObjectiveParams::default()
            .stride(p.stride)
            .objective(TargetWeight::L2)
            .check()?;
        match &shared {
            // The objective's cells are the fits' (`op.fit_params()` is `fit_params`).
            Some(g) => Some(Objective::from_grams(coll.names(), g.grams.clone())?),
            _ => Some(Objective::new(backend, coll, &op, &|_, _| {})?),
        }
    } else {
        None
    };
    let selections = match (&objective, p.error_driven) {
        (Some(obj), true) => {
            progress(Stage::Selection, 0, 1);
            let s = error_driven_bases(obj, &ks)?;
            progress(Stage::Selection, 1, 1);
            s
        }
        _ => vec![],
    };
    lap(Stage::Selection, &mut timings);
    // A fold trains on n - ceil(n / K) materials: larger bases are left out of the CV.
    let train = coll.len() - coll.len().div_ceil(p.cv_folds.max(1));
    let cv_ks: Vec<usize> = ks.iter().copied().filter(|&k| k <= train).collect();
    let cv = match &objective {
        Some(obj) if p.cv_folds > 0 && !cv_ks.is_empty() => {
            let vp = CvParams::default()
                .ks(cv_ks)
                .folds(p.cv_folds)
                .seed(p.seed)
                .runs(p.cv_runs)
                .objective(
                    ObjectiveParams::default()
                        .stride(p.stride)
                        .objective(TargetWeight::L2),
                )
                // reproduce keeps the paper's l2 and its timing: no appearance renders here.
                .appearance(false)
                .check(coll.len())?;
            // The clustering methods run on the BRDF_it (uniform) matrix, as the paper's.
            let d = metrics
                .iter()
                .position(|m| m.label == "brdf-it")
                .map(|i| &distances[i]);
            Some(cross_validate_with(coll, obj, d, &vp, &|d, t| {
                progress(Stage::CrossValidation, d, t)
            })?)
        }
        _ => None,
    };
    lap(Stage::CrossValidation, &mut timings);

    // 6. Bases: ours from the BRDF_it (uniform) clusterings as the paper, the error-driven
    // ones, then the paper's. Add another source here.
    let brdf_it: Vec<ClusteringSet> = sets
        .iter()
        .filter(|s| s.metric == "brdf-it")
        .cloned()
        .collect();
    let mut all = bases::our_bases(coll, &emp, &brdf_it, p.k_max, p.k_min);
    all.extend(selections.iter().map(bases::error_driven_basis));
    all.extend(p.paper_bases.iter().cloned());
    let bases = bases::dedupe(all);

    // 7. Fits of the materials in no basis.
    let in_any: std::collections::HashSet<&String> =
        bases.iter().flat_map(|b| b.materials.iter()).collect();
    let targets: Vec<usize> = (0..coll.len())
        .filter(|&i| !in_any.contains(&coll.names()[i]))
        .collect();
    if targets.is_empty() {
        return Err(ExperimentError::NoTargets);
    }
    let showcase = vp
        .showcase
        .unwrap_or_else(|| evaluation::default_showcase(coll, &targets));
    let settings = EvalSettings {
        fit: fit_params,
        small: RenderParams::default()
            .with_size(p.render_size)
            .with_light(45.0, 45.0),
        big: RenderParams::default()
            .with_size(p.showcase_size)
            .with_light(45.0, 45.0),
        display: DisplayParams::default(),
    };
    let evaluation = evaluation::evaluate(
        backend,
        coll,
        &bases,
        &targets,
        showcase,
        &settings,
        shared.as_ref(),
        &|d, t| progress(Stage::Fits, d, t),
    )?;
    lap(Stage::Fits, &mut timings);

    Ok(Experiment {
        settings: Settings {
            materials: coll.len(),
            collection_fingerprint: coll.fingerprint(),
            backend: backend.name(),
            seed: p.seed,
            runs: p.runs,
            stride: p.stride,
            k_min: p.k_min,
            k_max: p.k_max,
            gcuk_k_max: p.gcuk_k_max,
            population: p.population,
            generations: p.generations,
            more_than: p.more_than,
            render_size: p.render_size,
            metrics,
        },
        distances,
        empirical: emp,
        clustering: sets,
        statistics,
        selections,
        cv,
        bases,
        evaluation,
        collection: coll.clone(),
        timings,
    })
}
