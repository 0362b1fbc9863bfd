//! `reproduce` as a library: everything of [`brdf_basis_core::experiment`] (the stages,
//! their typed results, the report's Markdown) and, with the `plot` feature, the output
//! directory's [`layout`], which draws the heatmaps' colour bars with plotters.

pub use brdf_basis_core::experiment::*;

#[cfg(feature = "plot")]
pub mod layout;
