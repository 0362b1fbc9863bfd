//! The compute back-ends: everything of [`brdf_basis_core::backend`] (the [`Backend`]
//! trait, the CPU back-end [`cpu`], block-pair reductions, weighted systems), the GPU
//! back-end ([`gpu`], the crate `brdf-basis-gpu`) and the choice between them ([`open`]:
//! `--backend auto|cpu|gpu`).

pub use brdf_basis_core::backend::*;
/// The GPU back-end (the crate `brdf-basis-gpu`): wgpu context, one module per kernel
/// (feature `gpu`, on by default).
#[cfg(feature = "gpu")]
pub use brdf_basis_gpu as gpu;

mod open;
#[cfg(feature = "gpu")]
pub use open::AutoBackend;
pub use open::{open, BackendChoice, AUTO_ROUTES};
