//! The compute back-ends: everything of [`brdf_basis_core::backend`] (the [`Backend`]
//! trait, the CPU back-end [`cpu`], block-pair reductions, weighted systems), the GPU
//! back-end ([`gpu`], the crate `brdf-basis-gpu`) and the choice between them ([`open`]:
//! `--backend auto|cpu|gpu`).

pub use brdf_basis_core::backend::*;
/// The GPU back-end (the crate `brdf-basis-gpu`): wgpu context, one module per kernel.
pub use brdf_basis_gpu as gpu;

mod open;
pub use open::{open, AutoBackend, BackendChoice, AUTO_ROUTES};
