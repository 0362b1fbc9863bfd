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
//! one [`Error`] and [`Result`]. The commands (`distance`, `select`, `plan`, `fit`, `cv`,
//! `cv --acquisition`, `reproduce`) are typed requests in [`run`]: the one door through
//! which the command line, the Python bindings and a host reach them (their settings,
//! documented defaults, every rule in one wording, and the typed output). Below them, the
//! module functions ([`distance::distance_matrix`], [`select::greedy()`], [`fit::fit`],
//! ...) take checked parameters and a `(done, total)` progress callback; k-medoids on a
//! matrix is [`KMedoidsParams::fit`]. [`wgpu`] and [`pollster`] are re-exported, so the
//! host uses the wgpu this crate is built against without pinning it (`examples/embed.rs`
//! opens its own device and hands it over). Acquisition (SPEC 10: where to measure a new
//! material, fits from samples) is [`acquire`], with [`plan_samples()`] and
//! [`fit_from_arrays`] at the root.
//!
//! ```
//! use brdf_basis::run::{Ctx, DistanceOutput, DistanceRequest, FitRequest, Request};
//! use brdf_basis::run::{SelectMethod, SelectRequest};
//! use brdf_basis::{Collection, CpuBackend, KMedoidsParams};
//!
//! # fn main() -> brdf_basis::Result<()> {
//! let cpu = CpuBackend::new(); // or brdf_basis::gpu_backend(device, queue, info)?
//! let coll = Collection::embedded_default();
//! // Every 8th cell per grid axis keeps the example quick; the default is the full grid.
//! let grid = brdf_basis::merl::GridSpec::default().with_stride(8)?;
//! let mut dr = DistanceRequest::default();
//! dr.grid = grid;
//! let DistanceOutput::Matrix(d) = dr.run(&Ctx::new(&cpu, &coll))? else {
//!     unreachable!("no --tile")
//! };
//! let km = KMedoidsParams::new(3).fit(&d)?;
//! let mut sr = SelectRequest::new(SelectMethod::Greedy);
//! (sr.k, sr.grid) = (Some(3), grid);
//! let greedy = sr.run(&Ctx::new(&cpu, &coll).progress(&|_done, _total| {}))?;
//! let mut fr = FitRequest::new(greedy.basis().to_vec()); // every other material a target
//! (fr.grid, fr.appearance) = (grid, false);
//! let fits = fr.run(&Ctx::new(&cpu, &coll))?.fits;
//! println!("k-medoids {:?}, greedy {:?}: {} fits", km.medoids, greedy.basis(), fits.len());
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
mod errors;
mod table;
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
/// [`crate::run::PlanRequest`]'s [`check`](crate::run::Request::check) on the criterion: `nielsen` (the peer baseline,
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
