//! Basis selection by fitting error (SPEC 8; the paper's future work, VII) and the
//! cross-validated comparison of every selection method.
//!
//! The objective: for a basis `B` and targets `T`, the relative residual of a target
//!
//! ```text
//! rho(t; B) = sum_c r_c^2 / sum_c sum_s w_s b_c(s)^2      (r_c: the SPEC 5 fit by B + Lambertian)
//! S(B; T)   = mean of rho(t; B) over t in T \ B
//! ```
//!
//! * [`objective`]: one Gram matrix of all N materials per channel ([`Objective`]); every
//!   candidate basis is then a small NNLS on a sub-matrix of it, never a pass over the
//!   grid. The incremental evaluation of "basis + one candidate" for every target keeps
//!   the previous basis' active set and Cholesky factor and borders it by one column.
//! * [`search`]: greedy forward selection, swap refinement and a genetic algorithm over
//!   k-subsets (the paper's proposal of "genetic optimisation techniques").
//! * [`cv`]: K-fold cross-validation over materials of any set of methods (greedy, swap,
//!   ga, kmedoids, gcuk, empirical, random), with paired Wilcoxon tests and a Markdown
//!   summary.
//!
//! ```no_run
//! use brdf_basis::backend::cpu::CpuBackend;
//! use brdf_basis::collection::Collection;
//! use brdf_basis::selection::*;
//! let coll = Collection::embedded_default();
//! let cpu = CpuBackend::new();
//! let op = ObjectiveParams::default().check()?;
//! let obj = Objective::new(&cpu, &coll, &op, &|_, _| {})?;
//! let best = swap(&obj, &SearchParams::new(5).check(obj.names())?, &|_, _| {});
//! println!("{:?}: S = {:.4}", best.basis, best.score);
//! let cv = cross_validate(&cpu, &coll, &CvParams::default().check(coll.len())?, &|_, _| {})?;
//! println!("{}", cv.markdown());
//! # Ok::<(), SelectionError>(())
//! ```

pub mod cv;
pub mod objective;
pub mod search;

pub use cv::{
    cross_validate, cross_validate_with, make_folds, CvMethod, CvMethodResult, CvParams, CvResult,
    CvTest, HeldOut, ValidCvParams,
};
pub use objective::{Objective, ObjectiveParams};
pub use search::{
    error_driven_bases, ga, greedy, swap, GaParams, SearchParams, Selection, ValidGaParams,
    ValidSearchParams,
};

/// Errors of error-driven selection and cross-validation.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SelectionError {
    /// A parameter is out of range.
    #[error("{name} = {value}: {expected}")]
    InvalidParam {
        /// Parameter name.
        name: &'static str,
        /// The value given.
        value: String,
        /// What is accepted.
        expected: &'static str,
    },
    /// More basis materials asked for than there are candidates.
    #[error("k = {k} basis materials asked for, but only {candidates} candidates are allowed")]
    TooFewCandidates {
        /// Requested basis size.
        k: usize,
        /// Number of candidates.
        candidates: usize,
    },
    /// A material index is out of range (library callers only; names are checked by the
    /// collection).
    #[error("{what}: material index {index} is out of range for a collection of {n}")]
    IndexOutOfRange {
        /// Which list.
        what: &'static str,
        /// The index.
        index: usize,
        /// Collection size.
        n: usize,
    },
    /// A material appears twice in a list.
    #[error("{what}: material `{}` is listed twice", crate::error::short_name(.material))]
    Duplicate {
        /// Which list.
        what: &'static str,
        /// The material.
        material: String,
    },
    /// A starting basis holds a material that is not a candidate.
    #[error("the starting basis holds `{}`, which is not among the candidates", crate::error::short_name(.0))]
    InitNotCandidate(String),
    /// The Gram matrices given do not fit the collection.
    #[error(
        "Gram matrix of channel {channel}: expected {expected} entries ((N + 1)^2), found {found}"
    )]
    GramShape {
        /// Channel.
        channel: usize,
        /// Expected length.
        expected: usize,
        /// Found length.
        found: usize,
    },
    /// A Gram entry is not finite.
    #[error("non-finite Gram entry for `{}` (channel {channel}): the data holds NaN or infinite values", crate::error::short_name(.material))]
    NonFinite {
        /// Material.
        material: String,
        /// Channel.
        channel: usize,
    },
    /// Fitting failed.
    #[error(transparent)]
    Fit(#[from] crate::fit::FitError),
    /// A distance matrix could not be built.
    #[error(transparent)]
    Distance(#[from] crate::error::DistanceError),
    /// Clustering failed.
    #[error(transparent)]
    Cluster(#[from] crate::cluster::ClusterError),
    /// Rendering failed.
    #[error(transparent)]
    Render(#[from] crate::eval::render::RenderError),
    /// An NNLS solve was rejected.
    #[error(transparent)]
    Nnls(#[from] crate::nnls::NnlsError),
}
