//! The embedding facade: the few types and functions a host program needs, re-exported at
//! the crate root ([`crate`] has the example).
//!
//! * Collections: [`Collection::load`] (a CSV of analytic materials, a `.binary`, or a
//!   directory of them), [`Collection::embedded_default`].
//! * Back-ends: [`gpu_backend`] wraps the host's own wgpu device and queue (use
//!   [`crate::wgpu`], the version this crate is built against; feature `gpu`, on by
//!   default), [`CpuBackend`], or [`open_backend`] by [`BackendChoice`].
//! * The commands: one typed request each in [`crate::run`] (the one door of the command
//!   line and Python too: the same defaults, rules and output). Below them, each stage's
//!   module function ([`crate::distance::distance_matrix`], [`crate::select::greedy`],
//!   [`crate::fit::fit`], ...) takes checked parameters and a progress callback
//!   `(done, total)`; k-medoids on a matrix is [`KMedoidsParams::fit`].
//! * One error type, [`Error`], with `From` for each module's error, and [`Result`].
//! * Acquisition (SPEC 10): [`crate::plan_samples`] (where to measure, on given candidates)
//!   and [`fit_from_arrays`] (a material from samples given as arrays).

pub use crate::acquire::{
    acquisition_cv, AcqCv, AcqCvParams, AcquireError, Candidate, Criterion, Plan, PlanParams,
    Sample, SampleFit,
};
pub use crate::backend::cpu::CpuBackend;
#[cfg(feature = "gpu")]
pub use crate::backend::gpu::GpuBackend;
pub use crate::backend::{open as open_backend, Backend, BackendChoice};
pub use crate::cluster::{
    KMedoids, KMedoidsAlgorithm, KMedoidsInit, KMedoidsOrder, KMedoidsParams,
};
pub use crate::collection::Collection;
pub use crate::distance::{DistanceMatrix, DistanceParams, Distances, Metric};
pub use crate::errors::{Error, NotFiniteError, Result};
pub use crate::fit::{FitParams, GramMode, Solver, TargetFit};
pub use crate::merl::{Mask, Weighting};
pub use crate::select::cv::{CvMethod, CvParams, CvResult};
pub use crate::select::{
    Empirical, EmpiricalParams, GaParams, Objective, ObjectiveParams, SearchParams, Selection,
};
pub use crate::table::{material_kind, tabulate};

/// The GPU back-end on a host's own device and queue (from [`crate::wgpu`]), compiling
/// the kernels on it. The device should have been opened with the adapter's limits
/// (`required_limits: adapter.limits()`): the kernels size their work by them.
///
/// # Errors
/// [`Error::Gpu`] when a kernel does not compile or validate on the device.
#[cfg(feature = "gpu")]
pub fn gpu_backend(
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
) -> Result<GpuBackend> {
    use std::sync::Arc;
    let ctx = crate::backend::gpu::GpuContext::from_device(Arc::new(device), Arc::new(queue), info);
    Ok(GpuBackend::with_context(ctx)?)
}

// ---------------------------------------------------------------------------------------
// What a host in another language needs beyond the stages above (the Python bindings in
// `python/`): the command line's `tabulate` as a function, a dense NNLS, and a progress
// callback on the long stages. The commands themselves are requests: [`crate::run`].
// ---------------------------------------------------------------------------------------

pub use crate::backend::Progress;
pub use crate::cluster::GcukParams;
pub use crate::nnls::NnlsSolution;
pub use crate::select::SelectOutput;

/// Non-negative least squares `min |A x - b|` subject to `x >= 0` for a dense row-major
/// `A` (`rows` x `cols`), by the crate's exact Lawson-Hanson solver on the Gram form
/// (`G = A^T A`, `h = A^T b`, summed in f64): [`crate::nnls::solve_dense`].
///
/// # Errors
/// [`Error::Nnls`] for mismatched lengths, non-finite entries or no column.
pub fn nnls_dense(a: &[f64], rows: usize, cols: usize, b: &[f64]) -> Result<NnlsSolution> {
    Ok(crate::nnls::solve_dense(a, rows, cols, b)?)
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
    objective: crate::backend::weighted::TargetWeight,
) -> Result<SampleFit> {
    let b: Vec<usize> = basis
        .iter()
        .map(|n| coll.index_of(n))
        .collect::<std::result::Result<_, _>>()?;
    let samples = crate::acquire::samples_from_arrays(angles, rgb, sigma)?;
    Ok(crate::acquire::fit_samples(coll, &b, &samples, objective)?)
}
