//! The MERL grid (Matusik et al. 2003, doi:10.1145/882262.882343) and its `.binary` format.

pub mod binary;
pub mod grid;

pub use binary::{parse_binary, read_binary, write_binary, write_binary_to, MerlTable};
pub use grid::{CellSet, GridTables, Mask, Weighting};
