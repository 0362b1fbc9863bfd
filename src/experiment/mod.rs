//! `reproduce` as a library: everything of [`brdf_basis_core::experiment`] (the stages,
//! their typed results, the report's Markdown). The output directory's layout and the
//! figures are the command line's (`brdf-basis-cli`).

pub use brdf_basis_core::experiment::*;
