//! # brdf-basis
//!
//! Find small, expressive bases of BRDFs and represent materials as non-negative linear
//! combinations of them (Nascimento, Carvalho & Andrade, "Improving the Selection of Bases
//! of BRDFs for Appearance Preservation", SIBGRAPI 2016, doi:10.1109/SIBGRAPI.2016.024).
//!
//! Data flows `brdf` (models) -> `merl` (grid, `.binary`) -> `backend` / `gpu` (tabulation
//! and reductions over the grid) -> `distance`, `nnls`, `cluster`, `select` -> `eval`.
//!
//! ## Embedding
//!
//! The crate root is the facade for a host program: [`Collection`], the back-ends
//! ([`gpu_backend`] on the host's own wgpu device, [`CpuBackend`], [`open_backend`]),
//! one function per stage ([`distances`], [`objective`], [`select_greedy`],
//! [`select_swap`], [`select_ga`], [`empirical`], [`fit()`], [`cross_validate`];
//! k-medoids is [`KMedoidsParams::fit`]), one [`Error`] and [`Result`]. Each function
//! checks its parameters before any work and reports no progress; the module functions
//! behind them ([`distance::distance_matrix`], [`select::greedy()`], [`fit::fit`], ...)
//! take a `(done, total)` progress callback. [`wgpu`] and [`pollster`] are re-exported,
//! so the host uses the wgpu this crate is built against without pinning it
//! (`examples/embed.rs` opens its own device and hands it over).
//!
//! The commands themselves (`select`, `plan`, `fit`, `cv`, `cv --acquisition`) are typed
//! requests in [`run`]: the one door through which the command line and the Python
//! bindings reach them (their settings, documented defaults, every rule in one wording,
//! and the typed output). Acquisition (SPEC 10: where to measure a new material, fits
//! from samples) is [`acquire`], with [`plan_samples()`], [`fit_from_arrays`] and
//! [`acquisition_cv`] at the root.
//!
//! ```
//! use brdf_basis::{CpuBackend, Collection, DistanceParams, FitParams, KMedoidsParams};
//! use brdf_basis::{ObjectiveParams, SearchParams};
//!
//! # fn main() -> brdf_basis::Result<()> {
//! let cpu = CpuBackend::new(); // or brdf_basis::gpu_backend(device, queue, info)?
//! let coll = Collection::embedded_default();
//! // Every 8th cell per grid axis keeps the example quick; the default is the full grid.
//! let d = brdf_basis::distances(&cpu, &coll, &DistanceParams::default().stride(8))?;
//! let km = KMedoidsParams::new(3).fit(&d)?;
//! let obj = brdf_basis::objective(&cpu, &coll, &ObjectiveParams::default().stride(8))?;
//! let greedy = brdf_basis::select_greedy(&obj, &SearchParams::new(3))?;
//! let targets: Vec<usize> = (0..coll.len()).filter(|t| !greedy.indices.contains(t)).collect();
//! let fp = FitParams { stride: 8, ..Default::default() };
//! let fits = brdf_basis::fit(&cpu, &coll, &greedy.indices, &targets, &fp)?;
//! println!("k-medoids {:?}, greedy {:?}: {} fits", km.medoids, greedy.basis, fits.len());
//! assert_eq!(fits.len(), coll.len() - 3);
//! # Ok(())
//! # }
//! ```
//!
//! The GPU back-end (feature `gpu`, on by default: the crate `brdf-basis-gpu`, wgpu) is
//! optional: `default-features = false` leaves it out, and `--backend gpu` is then
//! refused. The command line and its figures are the crate `brdf-basis-cli`
//! (crates/cli), which a program that embeds the library does not build.
#![warn(missing_docs)]
// Errors carry the file, line, column and material they name; they are cold paths, so
// their size is not worth boxing.
#![allow(clippy::result_large_err)]

mod api;
pub use api::*;
/// The executor the examples block on wgpu's futures with.
#[cfg(feature = "gpu")]
pub use pollster;
/// The wgpu this crate is built against (hand [`gpu_backend`] a device from it).
#[cfg(feature = "gpu")]
pub use wgpu;

pub use brdf_basis_core::{
    acquire, atomic, brdf, cluster, collection, distance, error, eval, fit, hash, io, merl, nnls,
    npy_format, rgl, select, separable, stats,
};
pub mod backend;
pub mod experiment;
pub mod run;

/// Plans where to measure a new material (SPEC 10): [`crate::acquire::plan`] on the basis
/// columns `basis`, scored on `targets`, over `cands`, after the rule of
/// [`crate::run::PlanRequest::check`] on the criterion: `nielsen` (the peer baseline,
/// which reconstructs without a basis) is refused, as `brdf-basis plan` refuses it.
///
/// # Errors
/// [`Error::Request`] for `Criterion::Nielsen`; then the plan's own errors.
pub fn plan_samples(
    backend: &dyn backend::Backend,
    coll: &collection::Collection,
    basis: &[usize],
    targets: &[usize],
    cands: &[acquire::Candidate],
    p: &acquire::PlanParams,
) -> Result<acquire::Plan> {
    run::check_criterion(p.criterion)?;
    Ok(crate::acquire::plan(
        backend, coll, basis, targets, cands, p,
    )?)
}
