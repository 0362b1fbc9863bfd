//! The MERL grid (Matusik et al. 2003, doi:10.1145/882262.882343) and its `.binary` format.

mod binary;
mod grid;

pub use binary::*;
pub use grid::*;
