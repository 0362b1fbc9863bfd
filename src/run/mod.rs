//! One typed request per command: the one door through which the command line, the
//! Python bindings and a host program reach `distance`, `select`, `plan`, `fit`, `cv`,
//! `cv --acquisition` and `reproduce`.
//!
//! A request's fields are the command's settings and its [`Default`] the documented
//! defaults (the command line's `--help` shows the same values: its defaults are read from
//! here). `check` makes every rule a combination of settings can break, in one wording
//! (settings are named by their command-line flags; Python's keyword arguments are the
//! same names with underscores); `run` checks again, makes the rules that need the
//! collection (names, sizes) before any work, does the work and returns the typed output
//! the command writes. Front ends only translate their arguments into a request and
//! write its output.
//!
//! ```
//! use brdf_basis::run::{PlanRequest, SelectRequest, SelectMethod};
//! use brdf_basis::{Collection, CpuBackend};
//! # fn main() -> brdf_basis::Result<()> {
//! let coll = Collection::embedded_default();
//! let mut req = SelectRequest::new(SelectMethod::Greedy);
//! req.k = Some(3);
//! req.grid = brdf_basis::merl::GridSpec::default().with_stride(8)?;
//! let out = req.run(&CpuBackend::new(), &coll, &|_, _| {})?;
//! assert!(out.to_json().contains("\"method\": \"greedy\""));
//! // A rule every door makes: a `nielsen` plan is not one `fit --samples` can use.
//! let mut plan = PlanRequest::new(vec!["polished-gold".into()]);
//! plan.criterion = brdf_basis::Criterion::Nielsen;
//! assert!(plan.check().is_err());
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
use crate::collection::Collection;

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
    /// [`crate::error::RequestError`]: `--eps` with an objective other than `relative`,
    /// or an `eps` outside its range ([`TargetWeight::relative`], named `--eps`).
    pub fn weight(&self) -> crate::Result<TargetWeight> {
        let kind = self.objective.unwrap_or(DEFAULT_OBJECTIVE.kind());
        match (kind, self.eps) {
            (ObjectiveKind::Relative, eps) => {
                let eps = eps.or(DEFAULT_OBJECTIVE.eps()).unwrap_or(TargetWeight::DEFAULT_EPS);
                match TargetWeight::relative(eps) {
                    Ok(w) => Ok(w),
                    Err(e) => refuse!("--eps {eps}: {e}"),
                }
            }
            (k, Some(eps)) => refuse!(
                "--eps {eps} applies to --objective relative, not to --objective {}: only the relative objective has an offset; leave --eps out",
                k.name()
            ),
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

/// `Err(RequestError::Settings(..))` with a formatted message.
macro_rules! refuse {
    ($($arg:tt)*) => {
        return Err(crate::error::RequestError::Settings(format!($($arg)*)).into())
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
fn check_restarts(restarts: usize) -> crate::Result<()> {
    if !(1..=64).contains(&restarts) {
        refuse!("--restarts {restarts}: give 1 to 64 seeded greedy paths");
    }
    Ok(())
}
