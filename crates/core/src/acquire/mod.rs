//! Acquisition (SPEC 10): a material from a few measured samples, and where to measure.
//!
//! * [`material_at`]: a material at an arbitrary direction pair (SPEC 9): analytic rows exactly,
//!   MERL tables by the cell of the MERL lookup (an invalid cell is an error).
//! * [`read_samples`], [`read_candidates`]: the samples file (CSV of SPEC 10, or ASTM E1392 `.astm`), validated with
//!   errors naming the line and column.
//! * [`fit_samples`]: the per-channel weighted NNLS of SPEC 10 on the samples (section 5's problem
//!   on the samples instead of the grid; the crate's Lawson-Hanson solver), its warnings
//!   (fewer samples than columns, a rank-deficient or ill-conditioned sampled design) and
//!   the score of a reconstruction on the whole fit mask.
//! * [`plan()`]: where to measure: `error` (greedy on the mean training score), `condition`
//!   (greedy on the condition number of the sampled design) and `random`.
//! * [`acquisition_cv`]: acquisition cross-validation (folds of SPEC 8; basis and plan chosen on the
//!   training materials, held-out materials measured at the plan and scored).

mod cv;
mod eval;
mod fit;
pub mod linalg;
pub mod nielsen;
mod peak;
mod plan;
mod plan_types;
mod samples;

pub use cv::*;
pub use eval::*;
pub use fit::*;
pub use peak::{peak_warning, PEAK_RATIO};
pub use plan::*;
pub use plan_types::{Candidate, Criterion, Plan, PlanParams, PlannedSample};
pub use samples::*;

use std::path::PathBuf;

/// Errors of acquisition.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AcquireError {
    /// A direction is not above the horizon.
    #[error("{what} direction {dir:?} is not above the horizon (its z must be positive)")]
    BelowHorizon {
        /// `incoming` or `outgoing`.
        what: &'static str,
        /// The direction.
        dir: [f64; 3],
    },
    /// A direction is not a finite non-zero vector.
    #[error("{what} direction {dir:?} is not a finite non-zero vector")]
    BadDirection {
        /// `incoming` or `outgoing`.
        what: &'static str,
        /// The direction.
        dir: [f64; 3],
    },
    /// A measured table has no value at the cell a direction pair falls in.
    #[error("material `{}` has no measurement in MERL cell {cell} (theta_h index {}, theta_d index {}, phi_d index {}), where a sample falls: its value is undefined there", crate::error::short_name(.material), .cell / 16200, (.cell / 180) % 90, .cell % 180)]
    InvalidCell {
        /// Material.
        material: String,
        /// Flat MERL cell index.
        cell: usize,
    },
    /// A samples file could not be read.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// A samples file is malformed (line 1 is the header; columns count from 1).
    #[error("{path}{}{}: {message}", crate::error::at_line(*.line as u64), .column.as_ref().map(|c| format!(", column `{c}`")).unwrap_or_default())]
    Parse {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// Column name, when one is at fault.
        column: Option<String>,
        /// What is wrong.
        message: String,
    },
    /// A samples or candidates file is unusable as a whole (not a regular file, too large,
    /// not text, not ASTM).
    #[error("{path}: {message}")]
    File {
        /// File.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// No sample to fit from.
    #[error("{what}: no sample: at least one measured direction pair is needed")]
    NoSamples {
        /// The file or the caller's arrays.
        what: String,
    },
    /// An invalid parameter.
    #[error("{name} = {value}: {expected}")]
    InvalidParam {
        /// Parameter.
        name: &'static str,
        /// Value given.
        value: String,
        /// What is expected.
        expected: String,
    },
    /// Every training target of a plan is in its basis: each is fitted exactly by itself,
    /// its score is 0 whatever the samples, and nothing is left to choose samples by.
    #[error(
        "a basis of {} holds {} and leaves none to score (a basis material fits itself exactly, so its score is 0 at any samples): give --targets outside the basis, or leave --targets out to use every material outside the basis",
        crate::error::plural(*.basis, "material", "materials"),
        if *.targets == 1 { "the only target".to_string() } else { format!("all {} targets", .targets) }
    )]
    NoTargetLeft {
        /// Basis size.
        basis: usize,
        /// Number of targets.
        targets: usize,
    },
    /// A material appears twice in a plan's basis or targets.
    #[error("material `{}` appears twice in the {what}", crate::error::short_name(.material))]
    Duplicate {
        /// `basis` or `targets`.
        what: &'static str,
        /// The material.
        material: String,
    },
    /// A fit failed.
    #[error(transparent)]
    Fit(#[from] crate::fit::FitError),
    /// The solver failed.
    #[error(transparent)]
    Nnls(#[from] crate::nnls::NnlsError),
    /// Basis selection (cross-validation) failed.
    #[error(transparent)]
    Selection(#[from] crate::select::SelectionError),
    /// A collection lookup failed.
    #[error(transparent)]
    Collection(#[from] crate::error::CollectionError),
    /// A render failed.
    #[error("render: {0}")]
    Render(String),
}
