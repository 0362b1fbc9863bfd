//! # brdf-basis
//!
//! Find small, expressive bases of BRDFs and represent materials as non-negative linear
//! combinations of them (Nascimento, Carvalho & Andrade, "Improving the Selection of Bases
//! of BRDFs for Appearance Preservation", SIBGRAPI 2016, doi:10.1109/SIBGRAPI.2016.024).
//!
//! Data flows `brdf` (models) -> `merl` (grid, `.binary`) -> `backend` / `gpu` (tabulation
//! and reductions over the grid) -> `distance`, `nnls`, `cluster`, `select` -> `eval`.
//!
//! ```no_run
//! use brdf_basis::{backend::cpu::CpuBackend, collection::Collection, distance::*};
//! let coll = Collection::embedded_default();
//! let params = DistanceParams::default().check(&coll).unwrap();
//! let d = distance_matrix(&CpuBackend::new(), &coll, &params, &|_, _| {}).unwrap();
//! println!("{} x {}", d.names().len(), d.names().len());
//! ```
#![warn(missing_docs)]
// Errors carry the file, line, column and material they name; they are cold paths, so
// their size is not worth boxing.
#![allow(clippy::result_large_err)]

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
pub mod plot;
pub mod select;
pub mod separable;
pub mod stats;
