//! Clustering of materials from a distance matrix: k-medoids (PAM), GCUK and the medoid
//! Davies-Bouldin validity index (SPEC section 6, paper section V-B).
//!
//! Every algorithm takes anything that implements [`Distances`](crate::distance::Distances)
//! (a symmetric matrix with a zero diagonal), a parameter builder with documented defaults
//! that is validated by `check()`, and returns a named result struct. Stochastic steps are
//! driven by a [`rand_chacha::ChaCha8Rng`] seeded from the parameters, so the same seed
//! always gives the same result.
//!
//! * [`medoid_of`], [`assign`], [`loss`], [`davies_bouldin`]: medoid of a cluster, nearest-medoid assignment, k-medoids loss and the
//!   medoid Davies-Bouldin index (Davies & Bouldin 1979, doi:10.1109/TPAMI.1979.4766909).
//! * [`KMedoids`]: FasterPAM (Schubert & Rousseeuw 2021, doi:10.1016/j.is.2021.101804,
//!   the default) and PAM, BUILD + SWAP (Kaufman & Rousseeuw 1990,
//!   doi:10.1002/9780470316801.ch2), with seeded random restarts.
//! * [`Gcuk`]: Genetic Clustering for Unknown K (Bandyopadhyay & Maulik 2002,
//!   doi:10.1016/S0031-3203(01)00108-X) as modified by the paper (no mutation, medoids).

mod gcuk;
pub mod indices;
mod kmedoids;
mod validity;

pub use gcuk::*;
pub use kmedoids::*;

/// Default relative margin of the loss and fitness comparisons of the clustering
/// algorithms: two values `a < b` with `b - a <= TIE_TOLERANCE x |b|` count as a tie,
/// broken by index (earlier swap, slot, run). The back-ends' distances agree far more
/// closely than this (bit for bit between the CPU and lavapipe; the f32 sums behind them
/// are accurate to about 1e-7 relative), so no decision hinges on how a back-end rounds.
pub const TIE_TOLERANCE: f64 = 1e-6;

/// Whether `a` is lower than `b` by more than `tolerance x |b|` (the comparison behind
/// every best-of choice; an infinite `b` is beaten by any lower `a`).
pub(crate) fn clearly_lower(a: f64, b: f64, tolerance: f64) -> bool {
    if b.is_finite() {
        a < b - tolerance * b.abs()
    } else {
        a < b
    }
}
pub use validity::*;

/// Errors of the clustering algorithms and validity indices.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ClusterError {
    /// The distance values changed while they were clustered (a memory-mapped matrix file
    /// truncated or written, [`crate::distance::Distances::intact`]).
    #[error("the distances changed while they were read: {0}")]
    SourceChanged(String),
    /// The number of clusters `k` must satisfy `2 <= k <= n` (the Davies-Bouldin index
    /// needs two clusters, and every cluster needs a distinct medoid).
    #[error("number of clusters k = {k} is out of range: need 2 <= k <= n = {n}")]
    KOutOfRange {
        /// Requested number of clusters.
        k: usize,
        /// Number of items.
        n: usize,
    },
    /// The number of clusters must be at least 2 (the Davies-Bouldin index needs two).
    #[error("number of clusters k = {k} is too small: need k >= 2")]
    KTooSmall {
        /// Requested number of clusters.
        k: usize,
    },
    /// The range of cluster counts is empty.
    #[error("--k-min {k_min} is larger than --k-max {k_max}")]
    EmptyKRange {
        /// Requested minimum number of clusters.
        k_min: usize,
        /// Requested maximum number of clusters.
        k_max: usize,
    },
    /// The minimum number of clusters must be at least 2.
    #[error("--k-min {k_min} is too small: the Davies-Bouldin index needs --k-min >= 2")]
    KMinTooSmall {
        /// Requested minimum number of clusters.
        k_min: usize,
    },
    /// The maximum number of clusters (GCUK slots) exceeds the number of items.
    #[error("--k-max {k_max} exceeds the number of items ({n})")]
    KMaxTooLarge {
        /// Requested maximum number of clusters.
        k_max: usize,
        /// Number of items.
        n: usize,
    },
    /// A genetic population needs at least two individuals to cross over.
    #[error("population size {population} is too small: need at least 2")]
    PopulationTooSmall {
        /// Requested population size.
        population: usize,
    },
    /// There are too few items to cluster.
    #[error("too few items to cluster: found {n}, need at least {needed}")]
    TooFewItems {
        /// Number of items found.
        n: usize,
        /// Minimum number of items needed.
        needed: usize,
    },
    /// A distance is NaN or infinite.
    #[error("distance between items {i} and {j} is not finite ({value})")]
    NonFiniteDistance {
        /// First item.
        i: usize,
        /// Second item.
        j: usize,
        /// The offending value.
        value: f64,
    },
    /// A distance is negative.
    #[error("distance between items {i} and {j} is negative ({value})")]
    NegativeDistance {
        /// First item.
        i: usize,
        /// Second item.
        j: usize,
        /// The offending value.
        value: f64,
    },
    /// Every item falls in one cluster, so the silhouette and Dunn index are undefined.
    #[error(
        "all {n} materials fall in one cluster (the other medoids attract none: the distances are all zero or tied), so the silhouette and Dunn index are undefined"
    )]
    OneNonEmptyCluster {
        /// Number of items.
        n: usize,
    },
    /// No run has a defined Davies-Bouldin index.
    #[error(
        "the Davies-Bouldin index is undefined in all {runs} runs (two medoids at distance 0 in each: the matrix holds identical materials or is zero); no best run can be chosen"
    )]
    UndefinedDbIndex {
        /// Number of runs.
        runs: usize,
    },
    /// No run has a defined Davies-Bouldin index because the distances are too large to
    /// add up: the runs' losses overflow `f64`.
    #[error(
        "the Davies-Bouldin index is undefined in all {runs} runs: the distances are too large to add up in 64-bit floating point (the k-medoids loss, a sum of distances, overflows to infinity in {overflowed} of them; the largest distance is near the f64 limit of 1.8e308); rescale the matrix; no best run can be chosen"
    )]
    DistanceSumOverflow {
        /// Number of runs.
        runs: usize,
        /// Runs whose loss is infinite.
        overflowed: usize,
    },
    /// At least one run (start) is needed.
    #[error("the number of runs (restarts) must be at least 1")]
    ZeroRuns,
    /// A probability parameter is outside `[0, 1]` or not finite.
    #[error("{name} {value} is not in [0, 1]")]
    ProbabilityOutOfRange {
        /// Parameter name.
        name: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A function that needs at least one medoid was given none.
    #[error("at least one medoid is needed")]
    NoMedoids,
    /// A function that needs at least one cluster member was given none.
    #[error("the cluster has no members")]
    EmptyCluster,
    /// A label vector does not have one entry per item.
    #[error("expected {expected} labels (one per item), found {found}")]
    LabelCountMismatch {
        /// Number of items.
        expected: usize,
        /// Number of labels given.
        found: usize,
    },
    /// A label points past the list of medoids.
    #[error("item {item} has label {label} but there are only {k} clusters")]
    LabelOutOfRange {
        /// Item whose label is invalid.
        item: usize,
        /// The invalid label.
        label: usize,
        /// Number of clusters (medoids).
        k: usize,
    },
    /// An item index (medoid or member) is not below the number of items.
    #[error("item index {index} is out of range for {n} items")]
    IndexOutOfRange {
        /// The invalid index.
        index: usize,
        /// Number of items.
        n: usize,
    },
    /// An unknown k-medoids algorithm name.
    #[error("unknown k-medoids algorithm `{0}` (expected fasterpam or pam)")]
    UnknownAlgorithm(String),
    /// The tie tolerance is not in `[0, 1)`.
    #[error("tolerance = {0} is not in [0, 1)")]
    BadTolerance(f64),
    /// The initial medoids repeat an item.
    #[error("item {0} appears twice among the initial medoids")]
    DuplicateMedoid(usize),
    /// The number of initial medoids is not `k`.
    #[error("expected {expected} initial medoids (k), found {found}")]
    MedoidCount {
        /// `k`.
        expected: usize,
        /// Medoids given.
        found: usize,
    },
    /// GCUK could not draw a valid initial individual (every draw had fewer than `k_min`
    /// non-empty clusters, which needs many items at distance 0 from each other).
    #[error("no valid initial individual after {attempts} draws (--k-min {k_min}): too many items at distance 0?")]
    NoValidIndividual {
        /// Number of draws made.
        attempts: usize,
        /// Minimum number of non-empty clusters required.
        k_min: usize,
    },
}
