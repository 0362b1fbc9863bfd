//! One typed request per command: the one door through which the command line, the
//! Python bindings and a host program reach `distance`, `select`, `plan`, `fit`, `cv`,
//! `cv --acquisition` and `reproduce`.
//!
//! A request's fields are the command's settings and its [`Default`] the documented
//! defaults (the command line's `--help` shows the same values: its defaults are read from
//! here). Every request is a [`Request`]: `check` makes every rule a combination of
//! settings can break, in one wording, and returns a typed [`Refusal`] (settings are
//! named by their command-line flags; Python's keyword arguments are the same names with
//! underscores); `run` takes a [`Ctx`] (back-end, collection, progress), checks again,
//! makes the rules that need the collection (names, sizes) before any work, does the
//! work and returns the typed output the command writes. Front ends only translate their
//! arguments into a request and write its output.
//!
//! ```
//! use brdf_basis::run::{Ctx, PlanRequest, Refusal, Request, SelectRequest, SelectMethod};
//! use brdf_basis::{Collection, CpuBackend};
//! # fn main() -> brdf_basis::Result<()> {
//! let coll = Collection::embedded_default();
//! let mut req = SelectRequest::new(SelectMethod::Greedy);
//! req.k = Some(3);
//! req.grid = brdf_basis::merl::GridSpec::default().with_stride(8)?;
//! let out = req.run(&Ctx::new(&CpuBackend::new(), &coll))?;
//! assert!(out.to_json().contains("\"method\": \"greedy\""));
//! // A rule every door makes: a `nielsen` plan is not one `fit --samples` can use.
//! let mut plan = PlanRequest::new(vec!["polished-gold".into()]);
//! plan.criterion = brdf_basis::Criterion::Nielsen;
//! assert!(matches!(
//!     plan.check(),
//!     Err(Refusal::NotOffered { setting: "--criterion", .. })
//! ));
//! # Ok(())
//! # }
//! ```

mod acquisition;
mod cv;
mod distance;
mod fit;
mod plan;
mod reproduce;
mod select;

pub use acquisition::AcquisitionRequest;
pub use cv::CvRequest;
pub use distance::{DistanceOutput, DistanceRequest};
pub use fit::{FitOutput, FitRequest, FitSamplesOutput, FitSamplesRequest, FitTargets, Samples};
pub(crate) use plan::check_criterion;
pub use plan::PlanRequest;
pub use reproduce::{ReproduceRequest, Reproduction};
pub use select::{SelectMethod, SelectRequest};

use crate::backend::weighted::{ObjectiveKind, TargetWeight};
use crate::backend::{Backend, Progress};
use crate::collection::Collection;
pub use crate::error::Refusal;
use crate::experiment::StageProgress;

/// The fit objective of `fit`, `select`, `plan` and `cv` when none is given (SPEC 11):
/// the library's one default (`relative`, `eps` 0.01), the same for the core's parameter
/// types. `reproduce` keeps `l2` where it reproduces the paper. Fits from samples (`fit
/// --samples`, `cv --acquisition`) weigh each sample by the objective at its measured
/// value, plans (`plan`) by the objective's shared weights (SPEC 11).
pub use crate::fit::DEFAULT_OBJECTIVE;

/// `--seed` when none is given: the seed of every random step of every command, the
/// same as the core's parameter types' defaults (`crates/cli/tests/requests.rs` holds
/// them equal).
pub const SEED: u64 = 1;

/// `--objective` and `--eps` as a door gave them (`None`: not given), the one home of
/// the fit objective's default and rules for `fit`, `select`, `plan`, `cv` and
/// `cv --acquisition`: [`ObjectiveSetting::weight`] applies [`DEFAULT_OBJECTIVE`] and
/// refuses an `eps` that is not a positive number or that the objective does not use.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ObjectiveSetting {
    /// `--objective` (default: `relative`, [`DEFAULT_OBJECTIVE`]).
    pub objective: Option<ObjectiveKind>,
    /// `--eps`: the offset of `relative` only (default [`TargetWeight::DEFAULT_EPS`]).
    pub eps: Option<f64>,
}

impl ObjectiveSetting {
    /// The flags given (`--objective`, `--eps`), in that order.
    pub fn given(&self) -> impl Iterator<Item = &'static str> {
        [
            (self.objective.is_some(), "--objective"),
            (self.eps.is_some(), "--eps"),
        ]
        .into_iter()
        .filter_map(|(given, flag)| given.then_some(flag))
    }

    /// The objective with the defaults applied, every rule made.
    ///
    /// # Errors
    /// [`Refusal::NotApplicable`]: `--eps` with an objective other than `relative`;
    /// [`Refusal::OutOfRange`]: an `eps` outside its range ([`TargetWeight::relative`],
    /// named `--eps`).
    pub fn weight(&self) -> Result<TargetWeight, Refusal> {
        let kind = self.objective.unwrap_or(DEFAULT_OBJECTIVE.kind());
        match (kind, self.eps) {
            (ObjectiveKind::Relative, eps) => {
                let eps = eps
                    .or(DEFAULT_OBJECTIVE.eps())
                    .unwrap_or(TargetWeight::DEFAULT_EPS);
                match TargetWeight::relative(eps) {
                    Ok(w) => Ok(w),
                    Err(e) => refuse!(Refusal::OutOfRange {
                        setting: "--eps",
                        value: Some(eps.to_string()),
                        rule: e.to_string(),
                    }),
                }
            }
            (k, Some(eps)) => refuse!(Refusal::NotApplicable {
                setting: "--eps",
                value: Some(eps.to_string()),
                applies_to: "--objective relative".into(),
                not_to: format!("--objective {}", k.name()),
                why: Some("only the relative objective has an offset; leave --eps out".into()),
            }),
            (ObjectiveKind::L2, None) => Ok(TargetWeight::L2),
            (ObjectiveKind::Log, None) => Ok(TargetWeight::Log),
        }
    }
}

impl From<TargetWeight> for ObjectiveSetting {
    /// The objective given explicitly (with its `eps` when `relative`).
    fn from(w: TargetWeight) -> Self {
        Self {
            objective: Some(w.kind()),
            eps: w.eps(),
        }
    }
}

/// One command's request: the one contract of the eight requests of this module (the
/// checked-parameters pattern of linfa's `ParamGuard`). [`Request::check`] makes the rules
/// that need nothing else, [`Request::check_count`] those that need only the number of
/// materials (a front end makes them before loading a collection, or before opening a
/// back-end), and [`Request::run`] makes every rule again, then those that need the
/// collection (names, sizes), before any work, does the work and returns the typed output
/// the command writes.
pub trait Request {
    /// What the command computes (its JSON, tables and warnings).
    type Output;

    /// The rules of the settings that need nothing else.
    ///
    /// # Errors
    /// The [`Refusal`] of the first rule broken, naming the setting.
    fn check(&self) -> Result<(), Refusal>;

    /// [`Self::check`], then the rules that need only the number of materials `n`
    /// (k ranges, folds); without such rules, [`Self::check`].
    ///
    /// # Errors
    /// A [`Refusal`] or the parameters' own range errors, naming the setting.
    fn check_count(&self, n: usize) -> crate::Result<()> {
        let _ = n;
        Ok(self.check()?)
    }

    /// Checks the request, then runs it in `ctx`.
    ///
    /// # Errors
    /// A [`Refusal`] (and, for a piece `ctx` lacks, [`Refusal::Missing`]) or the
    /// parameters' errors before any work, then the stages' errors.
    fn run(&self, ctx: &Ctx<'_>) -> crate::Result<Self::Output>;
}

/// What a request runs with: the back-end, the collection and the progress callbacks.
/// Every request but `select --distances` (a saved matrix) needs the collection, and
/// every one but that and `fit --samples` the back-end.
///
/// ```
/// use brdf_basis::run::{Ctx, FitRequest, Request};
/// use brdf_basis::{Collection, CpuBackend};
/// # fn main() -> brdf_basis::Result<()> {
/// let (cpu, coll) = (CpuBackend::new(), Collection::embedded_default());
/// let mut req = FitRequest::new(vec!["polished-gold".into(), "machined-iron".into()]);
/// (req.grid, req.appearance) = (brdf_basis::merl::GridSpec::default().with_stride(10)?, false);
/// let out = req.run(&Ctx::new(&cpu, &coll).progress(&|done, total| assert!(done <= total)))?;
/// assert_eq!(out.fits.len(), coll.len() - 2);
/// # Ok(())
/// # }
/// ```
#[derive(Clone, Copy)]
pub struct Ctx<'a> {
    backend: Option<&'a dyn Backend>,
    collection: Option<&'a Collection>,
    progress: Progress<'a>,
    stages: Option<StageProgress<'a>>,
}

impl<'a> Ctx<'a> {
    /// `backend` and `collection`, with no progress callback.
    pub fn new(backend: &'a dyn Backend, collection: &'a Collection) -> Self {
        Self {
            backend: Some(backend),
            collection: Some(collection),
            progress: &|_, _| {},
            stages: None,
        }
    }

    /// Only `collection`: for the requests that open no back-end (`fit --samples`).
    pub fn collection(collection: &'a Collection) -> Self {
        Self {
            backend: None,
            collection: Some(collection),
            progress: &|_, _| {},
            stages: None,
        }
    }

    /// Neither back-end nor collection: for `select --distances`, which clusters a saved
    /// matrix.
    pub fn saved() -> Self {
        Self {
            backend: None,
            collection: None,
            progress: &|_, _| {},
            stages: None,
        }
    }

    /// This context reporting `progress(done, total)`, called from the working threads.
    pub fn progress(self, progress: Progress<'a>) -> Self {
        Self { progress, ..self }
    }

    /// This context reporting `progress(stage, done, total)` for the staged commands
    /// (`reproduce`); without it they report `(done, total)` of each stage to
    /// [`Self::progress`].
    pub fn stages(self, stages: StageProgress<'a>) -> Self {
        Self {
            stages: Some(stages),
            ..self
        }
    }

    /// Whether a collection is given.
    pub fn has_collection(&self) -> bool {
        self.collection.is_some()
    }

    /// The back-end, or [`Refusal::Missing`].
    fn need_backend(&self) -> crate::Result<&'a dyn Backend> {
        self.backend.ok_or_else(|| {
            Refusal::Missing {
                setting: "--backend",
                message: "this request runs on a back-end: give one (Ctx::new)".into(),
            }
            .into()
        })
    }

    /// The collection, or [`Refusal::Missing`].
    fn need_collection(&self) -> crate::Result<&'a Collection> {
        self.collection.ok_or_else(|| {
            Refusal::Missing {
                setting: "COLLECTION",
                message: "this request runs on a collection: give one (Ctx::new)".into(),
            }
            .into()
        })
    }
}

/// `Err(Refusal::…)`: returns the refusal, converted into the caller's error type.
macro_rules! refuse {
    ($e:expr) => {
        return Err($e.into())
    };
}
pub(crate) use refuse;

/// Collection indices of `names` (surrounding spaces ignored), in order.
///
/// # Errors
/// [`crate::error::CollectionError`] for an empty or unknown name (the message suggests
/// close names).
pub fn indices_of(coll: &Collection, names: &[String]) -> crate::Result<Vec<usize>> {
    Ok(names
        .iter()
        .map(|n| coll.index_of(n.trim()))
        .collect::<Result<_, _>>()?)
}

/// `indices_of` for an optional list (`None` stays `None`).
fn optional_indices(
    coll: &Collection,
    names: Option<&[String]>,
) -> crate::Result<Option<Vec<usize>>> {
    names.map(|n| indices_of(coll, n)).transpose()
}

/// Every material of `coll` outside `basis`, in collection order (the default targets of
/// `fit --all-others` and `plan`).
pub fn all_others(coll: &Collection, basis: &[usize]) -> Vec<usize> {
    (0..coll.len()).filter(|i| !basis.contains(i)).collect()
}

/// `a`, `a and b`, `a, b and c`: the names a refusal lists.
fn list(names: &[&str]) -> String {
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
        _ => names.join(""),
    }
}

/// Restarts of an `error` plan: 1 to 64 (`plan --restarts`, `cv --acquisition --restarts`).
fn check_restarts(restarts: usize) -> Result<(), Refusal> {
    if !(1..=64).contains(&restarts) {
        refuse!(Refusal::OutOfRange {
            setting: "--restarts",
            value: Some(restarts.to_string()),
            rule: "give 1 to 64 seeded greedy paths".into(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests;
