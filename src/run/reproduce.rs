//! `reproduce`: the paper's section VI end to end ([`crate::experiment`]), then the
//! acquisition cross-validation of the report with its settings policy.

use super::{refuse, Ctx, Refusal, Request};
use crate::acquire::AcqSelect;
use crate::acquire::{acquisition_cv, AcqCv, AcqCvParams, Criterion};
use crate::backend::Backend;
use crate::collection::Collection;
use crate::experiment::appearance::{self, AppearanceParams};
use crate::experiment::bases::read_paper_bases;
use crate::experiment::report::{AcquisitionReport, AppearanceReport};
use crate::experiment::{
    run as run_experiment, Experiment, ExperimentParams, Stage, ValidExperimentParams,
};
use crate::select::ObjectiveParams;
use crate::Result;
use std::path::PathBuf;
use std::time::Instant;

/// `brdf-basis reproduce`: its settings, with the defaults of `reproduce --help`
/// ([`ExperimentParams::default`]).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct ReproduceRequest {
    /// `--runs`: runs per clustering configuration (paper: 30).
    pub runs: usize,
    /// `--stride`: grid stride for distances and fits.
    pub stride: usize,
    /// `--k-min`: smallest k of k-medoids and GCUK (paper: 5).
    pub k_min: usize,
    /// `--k-max`: largest k of k-medoids (paper: 12).
    pub k_max: usize,
    /// `--gcuk-k-max` (paper: 20).
    pub gcuk_k_max: usize,
    /// `--render-size`: pixels of the renders of the image errors.
    pub render_size: u32,
    /// `--showcase`: the material of the full-size renders, heatmaps and lobe plots.
    pub showcase: Option<String>,
    /// `--paper-bases`: a CSV `basis,material` of the paper's bases, fitted on the same
    /// targets.
    pub paper_bases: Option<PathBuf>,
    /// `--cv-folds`: folds of the cross-validations (0: none).
    pub cv_folds: usize,
    /// `--cv-runs`: k-medoids restarts and GCUK runs per fold of the selection methods'
    /// cross-validation (`None`: [`ExperimentParams::default`]'s); refused with
    /// `--cv-folds 0`, which leaves that cross-validation out.
    pub cv_runs: Option<usize>,
    /// Bases chosen by fitting error (`--no-selection` clears it).
    pub selection: bool,
    /// The acquisition cross-validation (`--no-acquisition` clears it).
    pub acquisition: bool,
    /// The Appearance section (held-out fits under each objective of SPEC 11) and the
    /// appearance metrics of the Acquisition section's reconstructions
    /// (`--no-appearance` clears both).
    pub appearance: bool,
    /// `--seed`.
    pub seed: u64,
}

impl Default for ReproduceRequest {
    fn default() -> Self {
        let d = ExperimentParams::default();
        Self {
            runs: d.runs,
            stride: d.stride,
            k_min: d.k_min,
            k_max: d.k_max,
            gcuk_k_max: d.gcuk_k_max,
            render_size: d.render_size,
            showcase: d.showcase,
            paper_bases: None,
            cv_folds: d.cv_folds,
            cv_runs: None,
            selection: d.error_driven,
            acquisition: true,
            appearance: true,
            seed: d.seed,
        }
    }
}

/// What `reproduce` computes: the experiment's stages and the acquisition report (the
/// command writes them, with the figures, into its directory).
#[derive(Debug)]
#[non_exhaustive]
pub struct Reproduction {
    /// The paper's pipeline, stage by stage.
    pub experiment: Experiment,
    /// The acquisition cross-validation (`None` when not asked for).
    pub acquisition: Option<AcquisitionReport>,
    /// Seconds the acquisition cross-validation took.
    pub acquisition_seconds: f64,
    /// The Appearance section's study (`None` when not asked for).
    pub appearance: Option<AppearanceReport>,
    /// Seconds the appearance study took.
    pub appearance_seconds: f64,
}

impl ReproduceRequest {
    /// The experiment's parameters for `coll`, checked (the paper bases read): the
    /// rules that need the collection, which [`Request::run`] makes before any work.
    ///
    /// # Errors
    /// The request's [`Refusal`]; [`crate::experiment::ExperimentError`] for settings
    /// that do not fit the collection or an unreadable paper-bases file.
    pub fn params(&self, coll: &Collection) -> Result<ValidExperimentParams> {
        self.check()?;
        let paper_bases = match &self.paper_bases {
            Some(p) => read_paper_bases(p, coll)?,
            None => vec![],
        };
        Ok(self.experiment_params(paper_bases).check(coll)?)
    }

    fn experiment_params(
        &self,
        paper_bases: Vec<crate::experiment::bases::Basis>,
    ) -> ExperimentParams {
        ExperimentParams {
            runs: self.runs,
            stride: self.stride,
            k_min: self.k_min,
            k_max: self.k_max,
            gcuk_k_max: self.gcuk_k_max,
            render_size: self.render_size,
            showcase: self.showcase.clone(),
            seed: self.seed,
            paper_bases,
            error_driven: self.selection,
            cv_folds: self.cv_folds,
            cv_runs: self.cv_runs.unwrap_or(ExperimentParams::default().cv_runs),
            ..Default::default()
        }
    }
}

impl Request for ReproduceRequest {
    type Output = Reproduction;

    /// The rules of the settings that need no collection: no setting of a part the
    /// others leave out, so that none is ignored without a word (`--cv-runs` with
    /// `--cv-folds 0`).
    fn check(&self) -> std::result::Result<(), Refusal> {
        if let (Some(runs), 0) = (self.cv_runs, self.cv_folds) {
            refuse!(Refusal::LeftOut {
                setting: "--cv-runs",
                value: runs.to_string(),
                part: "the cross-validation of the selection methods".into(),
                left_out_by: "--cv-folds 0".into(),
                hint: "give --cv-folds 2 or more, or leave --cv-runs out".into(),
            });
        }
        Ok(())
    }

    /// The checks of [`ReproduceRequest::params`] that need only the number of
    /// materials `n` ([`ExperimentParams::check_count`]), for a caller that has not
    /// loaded the collection yet ([`Collection::count_many`]).
    fn check_count(&self, n: usize) -> Result<()> {
        self.check()?;
        Ok(self.experiment_params(vec![]).check_count(n)?)
    }

    /// Runs the experiment on the collection with the parameters of
    /// [`ReproduceRequest::params`], then the appearance study and the acquisition
    /// cross-validation; the stages are reported to [`Ctx::stages`] (else each stage's
    /// `(done, total)` to [`Ctx::progress`]).
    fn run(&self, ctx: &Ctx<'_>) -> Result<Reproduction> {
        let (backend, coll) = (ctx.need_backend()?, ctx.need_collection()?);
        let params = self.params(coll)?;
        let each = ctx.progress;
        let by_stage = move |_: Stage, d: u64, t: u64| each(d, t);
        let progress = ctx.stages.unwrap_or(&by_stage);
        let experiment = run_experiment(backend, coll, &params, progress)?;
        let t = Instant::now();
        let appearance = if self.appearance {
            Some(match AppearanceParams::of(params.params(), coll.len()) {
                Ok(ap) => AppearanceReport {
                    study: Some(appearance::run(backend, coll, &ap, &|d, t| {
                        progress(Stage::Appearance, d, t)
                    })?),
                    skipped: None,
                },
                Err(why) => AppearanceReport {
                    study: None,
                    skipped: Some(why),
                },
            })
        } else {
            None
        };
        let appearance_seconds = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let acquisition = if self.acquisition {
            Some(acquisition(
                backend,
                coll,
                params.params(),
                self.appearance,
            )?)
        } else {
            None
        };
        Ok(Reproduction {
            experiment,
            acquisition,
            acquisition_seconds: t.elapsed().as_secs_f64(),
            appearance,
            appearance_seconds,
        })
    }
}

/// The acquisition cross-validation of the report (SPEC 10) under the default objective
/// (with `appearance`, every reconstruction's SPEC 11 metrics), with settings kept modest:
/// `--cv-folds` folds, greedy bases of k = 12 (fewer when the training folds are small),
/// plans error, condition, random and nielsen, n = 5, 10, 20, noise 0 and 2%, the run's
/// grid stride, renders of at most 64 px; on collections of more than 40 materials 2,000
/// candidates per plan step (10,000 otherwise), a grid stride of at least 2 and noise 0
/// only.
fn acquisition(
    backend: &dyn Backend,
    coll: &Collection,
    p: &ExperimentParams,
    appearance: bool,
) -> Result<AcquisitionReport> {
    let n = coll.len();
    let skip = |why: String| AcquisitionReport {
        cv: AcqCv {
            folds: vec![],
            seed: p.seed,
            select: AcqSelect {
                method: String::new(),
                k: 0,
            },
            k: 0,
            candidates_per_step: 0,
            restarts: 1,
            objective: "l2".into(),
            results: vec![],
            collection_fingerprint: coll.fingerprint(),
            showcase: None,
            render_size: None,
        },
        settings: String::new(),
        skipped: Some(why),
    };
    if p.cv_folds < 2 {
        return Ok(skip("no cross-validation folds (--cv-folds 0)".into()));
    }
    let train = n - n.div_ceil(p.cv_folds);
    let k = 12.min(train.saturating_sub(1));
    if k == 0 {
        return Ok(skip(format!(
            "{n} materials in {} folds leave no training material outside a basis",
            p.cv_folds
        )));
    }
    // Big collections: fewer candidates per step, every other cell on each axis, no
    // noisy repeat (the noise-free table is the comparison).
    let big = n > 40;
    let per_step = if big { 2_000 } else { 10_000 };
    let stride = if big { p.stride.max(2) } else { p.stride };
    let ap = AcqCvParams {
        k,
        plans: vec![
            Criterion::Error,
            Criterion::Condition,
            Criterion::Random,
            Criterion::Nielsen,
        ],
        folds: p.cv_folds,
        seed: p.seed,
        candidates_per_step: per_step,
        render_size: p.render_size.min(64),
        // Beyond the paper: under the default objective, scored on every metric of SPEC 11.
        objective: ObjectiveParams::default()
            .stride(stride)
            .objective(super::DEFAULT_OBJECTIVE),
        noises: if big { vec![0.0] } else { vec![0.0, 0.02] },
        appearance,
        ..AcqCvParams::default()
    };
    let settings = format!(
        "{} folds, greedy k = {k}, objective {}, plans error, condition, random, nielsen; n = {}; noise {}; {} candidates per plan step (nielsen: 500, as published); grid stride {}; {} px renders",
        ap.folds,
        super::DEFAULT_OBJECTIVE.kind().name(),
        ap.ns.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(", "),
        ap.noises.iter().map(|v| format!("{}%", v * 100.0)).collect::<Vec<_>>().join(", "),
        per_step,
        stride,
        ap.render_size
    );
    let cv = acquisition_cv(backend, coll, &ap)?;
    Ok(AcquisitionReport {
        cv,
        settings,
        skipped: None,
    })
}
