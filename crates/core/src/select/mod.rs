//! Basis selection, every method in one tree (SPEC 5, 6, 8; the paper's Alg. 1 and VI-C):
//!
//! * [`empirical()`]: the paper's Algorithm 1 (leave-one-out contributions).
//! * [`ClusteringSet`]: seeded multi-run k-medoids and GCUK on a distance matrix (the clustering
//!   algorithms live in [`crate::cluster`]), with the one best-run rule ([`best_run`]:
//!   lowest Davies-Bouldin index, ties within [`crate::cluster::TIE_TOLERANCE`] to the
//!   earliest run) used by `select`, `reproduce` and `cv` alike.
//! * [`Objective`]: the SPEC 8 objective. For a basis `B` and targets `T`, the relative
//!   residual of a target
//!
//!   ```text
//!   rho(t; B) = sum_c r_c^2 / sum_c sum_s w_s b_c(s)^2      (r_c: the SPEC 5 fit by B + Lambertian)
//!   S(B; T)   = mean of rho(t; B) over t in T \ B
//!   ```
//!
//!   from one Gram matrix of all N materials per channel ([`Objective`]); every candidate
//!   basis is then a small NNLS on a sub-matrix of it, never a pass over the grid (the
//!   incremental solver is [`crate::nnls::incremental`]).
//! * [`greedy()`], [`swap()`], [`ga()`]: searches over k-subsets on `S` ([`SearchParams`] holds their
//!   shared parameters and the [`Selection`] result).
//! * [`cv`]: K-fold cross-validation over materials of every method (greedy, swap, ga,
//!   kmedoids, gcuk, empirical, random), with paired Wilcoxon tests and a Markdown summary.
//! * [`SelectOutput`]: the typed result of `brdf-basis select`, written and read
//!   back by the same type, with the fingerprint of the collection or matrix it came from.
//!
//! ```no_run
//! use brdf_basis_core::backend::cpu::CpuBackend;
//! use brdf_basis_core::collection::Collection;
//! use brdf_basis_core::select::cv::{cross_validate, CvParams};
//! use brdf_basis_core::select::*;
//! let coll = Collection::embedded_default();
//! let cpu = CpuBackend::new();
//! let op = ObjectiveParams::default().check()?;
//! let obj = Objective::new(&cpu, &coll, &op, &|_, _| {})?;
//! let best = swap(&obj, &SearchParams::new(5).check(obj.names())?, &|_, _| {})?;
//! println!("{:?}: S = {:.4}", best.basis, best.score);
//! let cv = cross_validate(&cpu, &coll, &CvParams::default().check(coll.len())?, &|_, _| {})?;
//! println!("{}", cv.markdown());
//! # Ok::<(), SelectionError>(())
//! ```

pub mod cv;
mod empirical;
mod ga;
mod greedy;
mod objective;
mod output;
mod runs;
mod search;
mod swap;

pub(crate) use cv::make_folds;
pub use empirical::*;
pub use ga::*;
pub use greedy::*;
pub use objective::*;
pub use output::*;
pub use runs::*;
pub use search::*;
pub use swap::*;

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
    /// The empirical basis is empty.
    #[error(
        "the empirical basis is empty: no material contributes to more than {more_than} fits (the most any material contributes to is {most}); lower --more-than"
    )]
    EmptyEmpiricalBasis {
        /// The threshold.
        more_than: usize,
        /// The highest count.
        most: usize,
    },
    /// A method appears twice in a list.
    #[error("--methods: method `{0}` is listed twice")]
    DuplicateMethod(String),
    /// No target is left outside the basis, so `S` (a mean over them) is undefined.
    #[error(
        "a basis of {} can hold {} and leave none to score: give fewer basis materials (-k) than targets, or a target that is not a candidate", crate::error::plural(*.basis, "material", "materials"), if *.targets == 1 { "the only target".to_string() } else { format!("all {} targets", .targets) }
    )]
    NoTargetLeft {
        /// Basis size.
        basis: usize,
        /// Number of targets.
        targets: usize,
    },
    /// An NNLS solve of the objective was rejected.
    #[error("the fit of `{material}` (channel {channel}) failed: {source}")]
    Solve {
        /// Target material.
        material: String,
        /// Channel.
        channel: usize,
        /// The solver's error.
        source: crate::nnls::NnlsError,
    },
    /// A statistical test failed.
    #[error("the Wilcoxon test {a} vs {b} at k = {k} on {what} failed: {source}")]
    Test {
        /// First method.
        a: String,
        /// Second method.
        b: String,
        /// Basis size.
        k: usize,
        /// Which held-out values.
        what: &'static str,
        /// The test's error.
        source: crate::stats::StatsError,
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
    #[error("the Gram sums of `{}` (channel {channel}) are not finite: its data holds a non-finite value, or reflectances too large for the sums (a value above about 1e18, squared, leaves the back-end's f32 range; the loaders refuse NaN and infinite values, and measured reflectances are far below 1e18): check the material's data and its units", crate::error::short_name(.material))]
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

/// The error-driven bases `reproduce` compares: greedy and swap (from the greedy basis) at
/// each k of `ks` (k larger than the collection is skipped), every material a candidate and
/// a target; in the order greedy k1, swap k1, greedy k2, ...
pub(crate) fn error_driven_bases(
    obj: &Objective,
    ks: &[usize],
) -> Result<Vec<Selection>, SelectionError> {
    let mut out = Vec::new();
    for &k in ks.iter().filter(|&&k| k >= 1 && k <= obj.len()) {
        let p = SearchParams::new(k).check(obj.names())?;
        let g = greedy(obj, &p, &|_, _| {})?;
        let s = swap(
            obj,
            &SearchParams::new(k)
                .init(g.indices.clone())
                .check(obj.names())?,
            &|_, _| {},
        )?;
        out.push(g);
        out.push(s);
    }
    Ok(out)
}
