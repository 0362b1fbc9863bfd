//! # brdf-basis-core
//!
//! The numerics of [brdf-basis](https://github.com/brdf-basis/brdf-basis) and its CPU
//! back-end, without wgpu, clap, plotters or pyo3: BRDF models and formats (`brdf`,
//! `merl`, `rgl`, `collection`), the [`backend::Backend`] trait with the CPU back-end
//! ([`backend::cpu::CpuBackend`]), distances, NNLS, k-medoids and GCUK, basis selection,
//! fits, acquisition, appearance metrics, statistics, the experiment of `reproduce`, and
//! the one output layer ([`atomic`]).
//!
//! A program that wants only the CPU back-end depends on this crate and compiles no wgpu;
//! the crate `brdf-basis` re-exports every module of this one under the same path and adds
//! the GPU back-end (`brdf-basis-gpu`), the command requests (`brdf_basis::run`) and the
//! embedding facade.
//!
//! ```
//! use brdf_basis_core::backend::cpu::CpuBackend;
//! use brdf_basis_core::collection::Collection;
//! use brdf_basis_core::distance::{distance_matrix, DistanceParams};
//!
//! let coll = Collection::embedded_default();
//! let p = DistanceParams::default().stride(8).check(&coll).unwrap();
//! let d = distance_matrix(&CpuBackend::new(), &coll, &p, &|_, _| {}).unwrap();
//! assert_eq!(d.names().len(), coll.len());
//! ```
//!
//! The back-end contract the GPU crate implements is [`backend::Backend`] (tabulate lobes
//! over cells; reduce 4 x 4 blocks of lobe pairs by a [`backend::PairOp`]; weighted
//! systems; batched NNLS), with the canonical summation order of
//! [`backend::cpu::CANONICAL_LANES`] and [`backend::cpu::CANONICAL_RUN`] that both follow.
#![warn(missing_docs)]
// Errors carry the file, line, column and material they name; they are cold paths, so
// their size is not worth boxing.
#![allow(clippy::result_large_err)]

pub mod acquire;
pub mod atomic;
pub mod backend;
pub mod brdf;
pub mod cluster;
pub mod collection;
pub mod distance;
pub mod error;
pub mod eval;
pub mod experiment;
pub mod fit;
pub mod hash;
pub mod io;
pub mod merl;
pub mod nnls;
pub mod npy_format;
pub mod rgl;
pub mod select;
pub mod separable;
pub mod stats;
