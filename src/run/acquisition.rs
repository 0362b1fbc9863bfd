//! `cv --acquisition`: acquisition cross-validation (SPEC 10).

use super::{check_restarts, refuse, Ctx, ObjectiveSetting, Refusal, Request};
use crate::acquire::{acquisition_cv_with_progress, AcqCv, AcqCvParams, Criterion};
use crate::merl::GridSpec;
use crate::select::cv::CvMethod;
use crate::select::ObjectiveParams;
use crate::Result;

/// `brdf-basis cv --acquisition`: its settings, with the defaults of `cv --help`
/// ([`AcqCvParams::default`]).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct AcquisitionRequest {
    /// `--methods`: selection methods of the bases.
    pub methods: Vec<CvMethod>,
    /// `-k`: the basis size.
    pub k: usize,
    /// `--plans`: plan criteria (`nielsen`: the peer baseline with its own reconstruction).
    pub plans: Vec<Criterion>,
    /// `-n`: sample counts.
    pub ns: Vec<usize>,
    /// `--noise`: relative noise levels of the simulated measurements.
    pub noises: Vec<f64>,
    /// `--folds` (default: [`AcqCvParams::default`]'s; not with `test`, a fixed split).
    pub folds: Option<usize>,
    /// `--candidates-per-step`: of the error, condition and nielsen plans (0: all;
    /// default: [`AcqCvParams::default`]'s).
    pub candidates_per_step: Option<usize>,
    /// `--shortlist`: exact fits per step of the error plans (0: every examined one;
    /// default: [`AcqCvParams::default`]'s).
    pub shortlist: Option<usize>,
    /// `--restarts`: seeded greedy paths of the error plans, 1 to 64 (default:
    /// [`AcqCvParams::default`]'s).
    pub restarts: Option<usize>,
    /// `--render-size`.
    pub render_size: u32,
    /// `--mask`, `--weighting`, `--stride`.
    pub grid: GridSpec,
    /// `--seed`.
    pub seed: u64,
    /// `--objective` and `--eps` (SPEC 11): the fold bases' shared weights, the plans'
    /// row weights and every fit's weights, as given.
    pub objective: ObjectiveSetting,
    /// Appearance metrics of every reconstruction (`--no-appearance` turns them off).
    pub appearance: bool,
    /// The ridge of the fits from samples (`--no-ridge` turns it off).
    pub ridge: bool,
    /// `--test`: a fixed split, the held-out materials by name (empty: `folds` folds).
    pub test: Vec<String>,
}

impl Default for AcquisitionRequest {
    fn default() -> Self {
        let d = AcqCvParams::default();
        Self {
            methods: d.methods,
            k: d.k,
            plans: d.plans,
            ns: d.ns,
            noises: d.noises,
            folds: None,
            candidates_per_step: None,
            shortlist: None,
            restarts: None,
            render_size: d.render_size,
            grid: GridSpec::default(),
            seed: d.seed,
            objective: ObjectiveSetting::default(),
            appearance: d.appearance,
            ridge: d.ridge,
            test: d.test,
        }
    }
}

impl AcquisitionRequest {
    /// `--folds` with its default.
    pub fn folds(&self) -> usize {
        self.folds.unwrap_or(AcqCvParams::default().folds)
    }

    /// The library's parameters, the defaults applied.
    fn params(&self) -> Result<AcqCvParams> {
        let d = AcqCvParams::default();
        Ok(AcqCvParams {
            methods: self.methods.clone(),
            k: self.k,
            plans: self.plans.clone(),
            ns: self.ns.clone(),
            noises: self.noises.clone(),
            folds: self.folds(),
            seed: self.seed,
            candidates_per_step: self.candidates_per_step.unwrap_or(d.candidates_per_step),
            shortlist: self.shortlist.unwrap_or(d.shortlist),
            restarts: self.restarts.unwrap_or(d.restarts),
            render_size: self.render_size,
            objective: ObjectiveParams::default()
                .grid(self.grid)
                .objective(self.objective.weight()?),
            appearance: self.appearance,
            ridge: self.ridge,
            test: self.test.clone(),
        })
    }
}

impl Request for AcquisitionRequest {
    type Output = AcqCv;

    /// The rules of the settings that need no collection (the objective's,
    /// [`ObjectiveSetting::weight`]; no plan setting that no plan of `--plans` uses; 1 to
    /// 64 restarts; noise levels from 0 to 1000; no plan,
    /// sample count or noise level listed twice, as `--methods` refuses a method listed
    /// twice: each would give a duplicate row); the others (folds, k, plans, n, noise) are
    /// checked by [`Request::run`] before any work.
    ///
    /// # Errors
    /// The [`Refusal`] naming the setting.
    fn check(&self) -> std::result::Result<(), Refusal> {
        self.objective.weight()?;
        if let (false, Some(f)) = (self.test.is_empty(), self.folds) {
            refuse!(Refusal::DoesNotApply {
                settings: vec!["--folds"],
                shown: format!("--folds {f}"),
                context: "with --test".into(),
                why: " (a fixed split is one fold); leave one out".into(),
            });
        }
        let given = [
            self.candidates_per_step.is_some(),
            self.shortlist.is_some(),
            self.restarts.is_some(),
        ];
        super::plan::criterion_settings("--plans", &self.plans, given)?;
        check_restarts(self.restarts.unwrap_or(AcqCvParams::default().restarts))?;
        let plans: Vec<&str> = self.plans.iter().map(|c| c.as_str()).collect();
        once("--plans", "plan", &plans, |c| format!("`{c}`"))?;
        once("-n", "sample count", &self.ns, |n| n.to_string())?;
        once("--noise", "noise level", &self.noises, |x| x.to_string())?;
        // Audit 3, T3: a noise level of 1e300 overflowed the fits' sums ("bb: non-finite
        // entry inf"); refused here, before any work, with the range.
        if let Some(s) = self.noises.iter().find(|s| !(0.0..=MAX_NOISE).contains(*s)) {
            refuse!(Refusal::OutOfRange {
                setting: "--noise",
                value: None,
                rule: format!(
                    "noise level {s} is outside 0 to {MAX_NOISE} (relative noise levels: \
                     0.02 is 2 % of the value)"
                ),
            });
        }
        // Audit 2, U3: in the flags' words, not "plans / methods / n = 3 / 1 / [0]".
        if self.plans.is_empty() {
            refuse!(Refusal::Missing {
                setting: "--plans",
                message: "--plans: give at least one plan (error, condition, random, nielsen)"
                    .into(),
            });
        }
        if self.methods.is_empty() {
            refuse!(Refusal::Missing {
                setting: "--methods",
                message: "--methods: give at least one selection method".into(),
            });
        }
        if self.ns.is_empty() || self.ns.contains(&0) {
            refuse!(Refusal::OutOfRange {
                setting: "-n",
                value: None,
                rule: format!(
                    "give sample counts of at least 1 (got {})",
                    if self.ns.is_empty() {
                        "none".to_string()
                    } else {
                        self.ns
                            .iter()
                            .map(|n| n.to_string())
                            .collect::<Vec<_>>()
                            .join(",")
                    }
                ),
            });
        }
        Ok(())
    }

    /// Runs the acquisition cross-validation on the collection and returns what
    /// `cv --acquisition --json` writes (its [`AcqCv::markdown`] is `--markdown`). The
    /// progress callback gets `(steps done, steps)`: the shared state, each plan of each
    /// method and fold, each fold's scores, the showcase; it is also called, with the
    /// same position, while a step runs (a caller may cancel from it: the command line's
    /// bar, Python's Ctrl-C).
    fn run(&self, ctx: &Ctx<'_>) -> Result<AcqCv> {
        let (backend, coll) = (ctx.need_backend()?, ctx.need_collection()?);
        self.check()?;
        Ok(acquisition_cv_with_progress(
            backend,
            coll,
            &self.params()?,
            ctx.progress,
        )?)
    }
}

/// The largest relative noise level `--noise` takes: the measured values `f (1 + noise z)`
/// and their squared sums stay finite for any finite material value a fit can take.
const MAX_NOISE: f64 = 1e3;

/// Refuses a value of `flag`'s list that appears twice (`show`: the value in words).
fn once<T: PartialEq>(
    flag: &'static str,
    what: &'static str,
    values: &[T],
    show: impl Fn(&T) -> String,
) -> std::result::Result<(), Refusal> {
    for (j, v) in values.iter().enumerate() {
        if values[..j].contains(v) {
            refuse!(Refusal::Duplicate {
                setting: flag,
                what,
                value: show(v),
            });
        }
    }
    Ok(())
}
