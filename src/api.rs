//! The embedding facade: the few types and functions a host program needs, re-exported at
//! the crate root ([`crate`] has the example).
//!
//! * Collections: [`Collection::load`] (a CSV of analytic materials, a `.binary`, or a
//!   directory of them), [`Collection::embedded_default`].
//! * Back-ends: [`gpu_backend`] wraps the host's own wgpu device and queue (use
//!   [`crate::wgpu`], the version this crate is built against), [`CpuBackend`], or
//!   [`open_backend`] by [`BackendChoice`].
//! * Stages: [`distances`], [`KMedoidsParams::fit`], [`objective`] with
//!   [`select_greedy`], [`select_swap`], [`select_ga`], [`empirical`], [`fit()`] and
//!   [`cross_validate`].
//! * One error type, [`Error`], with `From` for each module's error, and [`Result`].
//!
//! Each function checks its parameters against the collection (or the objective) before
//! any work, and reports no progress. The module functions they call
//! ([`crate::distance::distance_matrix`], [`crate::select::greedy`], [`crate::fit::fit`],
//! ...) take a progress callback `(done, total)` for hosts that want one.
//!
//! * Acquisition (SPEC 10): [`plan_samples`] (where to measure), [`fit_from_arrays`] (a
//!   material from samples given as arrays) and [`acquisition_cv`].

use std::sync::Arc;

pub use crate::acquire::{
    acquisition_cv, plan as plan_samples, AcqCv, AcqCvParams, AcquireError, Candidate, Criterion,
    Plan, PlanParams, Sample, SampleFit,
};
pub use crate::backend::cpu::CpuBackend;
pub use crate::backend::gpu::GpuBackend;
pub use crate::backend::{open as open_backend, Backend, BackendChoice};
pub use crate::cluster::{KMedoids, KMedoidsAlgorithm, KMedoidsInit, KMedoidsParams};
pub use crate::collection::Collection;
pub use crate::distance::{DistanceMatrix, DistanceParams, Distances, Metric};
pub use crate::fit::{FitParams, GramMode, Solver, TargetFit};
pub use crate::merl::{Mask, Weighting};
pub use crate::select::{
    CvMethod, CvParams, CvResult, Empirical, EmpiricalParams, GaParams, Objective, ObjectiveParams,
    SearchParams, Selection,
};

/// Any error of the library: the error of the module that failed, unchanged (its message
/// names the file, material or parameter).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Reading or parsing a collection.
    #[error(transparent)]
    Collection(#[from] crate::error::CollectionError),
    /// Reading or parsing a MERL `.binary`.
    #[error(transparent)]
    Merl(#[from] crate::error::MerlError),
    /// Opening the GPU or running a kernel.
    #[error(transparent)]
    Gpu(#[from] crate::error::GpuError),
    /// A back-end reduction.
    #[error(transparent)]
    Backend(#[from] crate::error::BackendError),
    /// Distance parameters or computation.
    #[error(transparent)]
    Distance(#[from] crate::error::DistanceError),
    /// Writing an output file.
    #[error(transparent)]
    Output(#[from] crate::error::OutputError),
    /// A saved distance matrix (`.npy` and sidecar).
    #[error(transparent)]
    MatrixFile(#[from] crate::io::MatrixFileError),
    /// Clustering (k-medoids, GCUK, validity indices).
    #[error(transparent)]
    Cluster(#[from] crate::cluster::ClusterError),
    /// Basis selection (objective, greedy, swap, GA, cross-validation).
    #[error(transparent)]
    Selection(#[from] crate::select::SelectionError),
    /// A selection result file.
    #[error(transparent)]
    SelectFile(#[from] crate::select::output::SelectFileError),
    /// Fitting materials by a basis.
    #[error(transparent)]
    Fit(#[from] crate::fit::FitError),
    /// A fit result file.
    #[error(transparent)]
    FitFile(#[from] crate::fit::file::FitFileError),
    /// An NNLS solve.
    #[error(transparent)]
    Nnls(#[from] crate::nnls::NnlsError),
    /// Rendering.
    #[error(transparent)]
    Render(#[from] crate::eval::render::RenderError),
    /// Acquisition: samples, plans, acquisition cross-validation.
    #[error(transparent)]
    Acquire(#[from] crate::acquire::AcquireError),
    /// A statistical test.
    #[error(transparent)]
    Stats(#[from] crate::stats::StatsError),
    /// The paper's experiment.
    #[error(transparent)]
    Experiment(#[from] crate::experiment::ExperimentError),
    /// The experiment's report tree (feature `plot`).
    #[cfg(feature = "plot")]
    #[error(transparent)]
    Layout(#[from] crate::experiment::layout::LayoutError),
    /// A figure (feature `plot`).
    #[cfg(feature = "plot")]
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
}

/// `Result` with the crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// The GPU back-end on a host's own device and queue (from [`crate::wgpu`]), compiling
/// the kernels on it. The device should have been opened with the adapter's limits
/// (`required_limits: adapter.limits()`): the kernels size their work by them.
///
/// # Errors
/// [`Error::Gpu`] when a kernel does not compile or validate on the device.
pub fn gpu_backend(
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
) -> Result<GpuBackend> {
    let ctx = crate::backend::gpu::GpuContext::from_device(Arc::new(device), Arc::new(queue), info);
    Ok(GpuBackend::with_context(ctx)?)
}

/// The distance matrix of `coll` by `p` (metric, mask, weighting, stride) on `backend`.
///
/// # Errors
/// [`Error::Distance`] for parameters that do not fit the collection (e.g. a stride that
/// leaves no cell, the euclidean metric on measured materials) or a failed reduction.
pub fn distances(
    backend: &dyn Backend,
    coll: &Collection,
    p: &DistanceParams,
) -> Result<DistanceMatrix> {
    let valid = p.check(coll)?;
    Ok(crate::distance::distance_matrix(
        backend,
        coll,
        &valid,
        &|_, _| {},
    )?)
}

/// The selection objective `S(B; T)` of `coll` (SPEC 8): one Gram matrix per channel,
/// shared by [`select_greedy`], [`select_swap`] and [`select_ga`].
///
/// # Errors
/// [`Error::Selection`] for invalid parameters, an empty collection or a failed Gram pass.
pub fn objective(
    backend: &dyn Backend,
    coll: &Collection,
    p: &ObjectiveParams,
) -> Result<Objective> {
    Ok(Objective::new(backend, coll, &p.check()?, &|_, _| {})?)
}

/// Greedy forward selection of `p.k` materials on `obj`.
///
/// # Errors
/// [`Error::Selection`] for parameters that do not fit the objective's materials or a
/// failed solve.
pub fn select_greedy(obj: &Objective, p: &SearchParams) -> Result<Selection> {
    Ok(crate::select::greedy(
        obj,
        &p.check(obj.names())?,
        &|_, _| {},
    )?)
}

/// Swap refinement (from `p.init`, or the greedy basis) on `obj`.
///
/// # Errors
/// As [`select_greedy`].
pub fn select_swap(obj: &Objective, p: &SearchParams) -> Result<Selection> {
    Ok(crate::select::swap(
        obj,
        &p.check(obj.names())?,
        &|_, _| {},
    )?)
}

/// The genetic algorithm on `obj` (seeded by `g.seed`).
///
/// # Errors
/// As [`select_greedy`], and for invalid GA settings.
pub fn select_ga(obj: &Objective, p: &SearchParams, g: &GaParams) -> Result<Selection> {
    Ok(crate::select::ga(
        obj,
        &p.check(obj.names())?,
        &g.check()?,
        &|_, _| {},
    )?)
}

/// The paper's empirical basis (Algorithm 1): materials that contribute to more than
/// `p.more_than` leave-one-out fits.
///
/// # Errors
/// [`Error::Fit`] for fewer than two materials, no common cells, or a failed solve.
pub fn empirical(
    backend: &dyn Backend,
    coll: &Collection,
    p: &EmpiricalParams,
) -> Result<Empirical> {
    Ok(crate::select::empirical(backend, coll, p, &|_, _| {})?)
}

/// Fits each of `targets` (collection indices) as a non-negative combination of a
/// Lambertian term and the `basis` materials.
///
/// # Errors
/// [`Error::Fit`] for an empty basis or target list, indices out of range, no common
/// cells, or a failed solve.
pub fn fit(
    backend: &dyn Backend,
    coll: &Collection,
    basis: &[usize],
    targets: &[usize],
    p: &FitParams,
) -> Result<Vec<TargetFit>> {
    Ok(crate::fit::fit(
        backend,
        coll,
        basis,
        targets,
        p,
        &|_, _| {},
    )?)
}

/// K-fold cross-validation of the selection methods `p.methods` at the sizes `p.ks`.
///
/// # Errors
/// [`Error::Selection`] for parameters that do not fit the collection or a failed stage.
pub fn cross_validate(backend: &dyn Backend, coll: &Collection, p: &CvParams) -> Result<CvResult> {
    let valid = p.check(coll.len())?;
    Ok(crate::select::cross_validate(
        backend,
        coll,
        &valid,
        &|_, _| {},
    )?)
}

/// Fits a new material from samples given as arrays (SPEC 10): per sample the angles
/// `[theta_i, phi_i, theta_o, phi_o]` in degrees and the RGB reflectance, optional
/// per-channel standard deviations; `basis` names materials of `coll`. Samples are
/// validated like a samples file (row `i` is reported as line `i + 1`).
pub fn fit_from_arrays(
    coll: &Collection,
    basis: &[&str],
    angles: &[[f64; 4]],
    rgb: &[[f64; 3]],
    sigma: Option<&[[f64; 3]]>,
) -> Result<SampleFit> {
    let b: Vec<usize> = basis
        .iter()
        .map(|n| coll.index_of(n))
        .collect::<std::result::Result<_, _>>()?;
    if angles.len() != rgb.len() || sigma.is_some_and(|s| s.len() != rgb.len()) {
        return Err(crate::acquire::AcquireError::InvalidParam {
            name: "sample arrays",
            value: format!("{} angles, {} values", angles.len(), rgb.len()),
            expected: "one row of angles, values (and sigmas) per sample",
        }
        .into());
    }
    let samples: Vec<Sample> = angles
        .iter()
        .zip(rgb)
        .enumerate()
        .map(|(i, (a, v))| {
            crate::acquire::samples::sample_from_degrees(
                std::path::Path::new("<arrays>"),
                i + 1,
                *a,
                *v,
                sigma.map(|s| s[i]),
                ["theta_i", "phi_i", "theta_o", "phi_o"],
            )
        })
        .collect::<std::result::Result<_, _>>()?;
    Ok(crate::acquire::fit_samples(coll, &b, &samples)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The facade is the module functions with checked parameters and no progress: the
    /// same numbers, bit for bit.
    #[test]
    fn facade_results_are_the_module_results() {
        let cpu = CpuBackend::new();
        let coll = Collection::embedded_default();
        let dp = DistanceParams::default().stride(8);
        let d = distances(&cpu, &coll, &dp).unwrap();
        let m =
            crate::distance::distance_matrix(&cpu, &coll, &dp.check(&coll).unwrap(), &|_, _| {})
                .unwrap();
        assert_eq!(d.names(), m.names());
        for i in 0..coll.len() {
            for j in 0..coll.len() {
                assert_eq!(d.dist(i, j).to_bits(), m.dist(i, j).to_bits());
            }
        }
        let op = ObjectiveParams::default().stride(8);
        let obj = objective(&cpu, &coll, &op).unwrap();
        let sp = SearchParams::new(3);
        let g = select_greedy(&obj, &sp).unwrap();
        let vp = sp.check(obj.names()).unwrap();
        assert_eq!(g, crate::select::greedy(&obj, &vp, &|_, _| {}).unwrap());
        let targets: Vec<usize> = (0..coll.len()).filter(|t| !g.indices.contains(t)).collect();
        let fp = FitParams {
            stride: 8,
            ..Default::default()
        };
        let f = fit(&cpu, &coll, &g.indices, &targets, &fp).unwrap();
        let m = crate::fit::fit(&cpu, &coll, &g.indices, &targets, &fp, &|_, _| {}).unwrap();
        // serde_json writes f64 by the shortest round-trip form: equal text, equal bits.
        assert_eq!(
            serde_json::to_string(&f).unwrap(),
            serde_json::to_string(&m).unwrap()
        );
    }

    /// A module's error passes through [`Error`] with its message unchanged.
    #[test]
    fn module_errors_keep_their_message() {
        let cpu = CpuBackend::new();
        let coll = Collection::embedded_default();
        let p = DistanceParams::default().stride(0);
        let direct = p.check(&coll).unwrap_err().to_string();
        let e = distances(&cpu, &coll, &p).unwrap_err();
        assert!(matches!(e, Error::Distance(_)), "{e:?}");
        assert_eq!(e.to_string(), direct);
        let e = fit(&cpu, &coll, &[], &[1], &FitParams::default()).unwrap_err();
        assert!(
            matches!(e, Error::Fit(crate::fit::FitError::EmptyBasis)),
            "{e:?}"
        );
    }
}
