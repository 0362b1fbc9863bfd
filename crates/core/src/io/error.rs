//! The error of saved matrices, tiles and merging, shared by the `.npy` reader, the
//! sidecar, saved matrices and the merge (here, below all of them, so that none imports
//! another for it).

use crate::error::OutputError;
use std::path::{Path, PathBuf};

/// Errors of saved matrices, tiles and merging. Each names the file and, for a bad
/// entry, the row and column (index and material).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MatrixFileError {
    /// I/O failure.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// Not a readable `.npy`, CSV or sidecar.
    #[error("{path}: {message}")]
    Format {
        /// File.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A `.npy` without its names sidecar.
    #[error("{npy}: no names sidecar `{sidecar}`: a saved .npy matrix is read together with the JSON sidecar `brdf-basis distance` writes beside it (or give a .csv, whose header holds the names)")]
    NoSidecar {
        /// The matrix.
        npy: PathBuf,
        /// The sidecar looked for.
        sidecar: PathBuf,
    },
    /// The `.npy` is not the one its sidecar describes.
    #[error("{npy} does not match its sidecar {sidecar} ({what}): the pair was not written together (interrupted or mixed copies); compute the matrix again")]
    Mismatch {
        /// The matrix.
        npy: PathBuf,
        /// The sidecar.
        sidecar: PathBuf,
        /// Which check failed.
        what: String,
    },
    /// A file changed while it was read (rewritten or truncated by another program).
    #[error("{path}: changed while it was read ({message}); the result would mix the old and the new matrix, so it is refused: run again once nothing rewrites the file")]
    Changed {
        /// File.
        path: PathBuf,
        /// What changed.
        message: String,
    },
    /// Not square.
    #[error("{path}: the matrix is not square: {message}")]
    NotSquare {
        /// File.
        path: PathBuf,
        /// Shape found.
        message: String,
    },
    /// A bad entry.
    #[error("{path}: entry at row {row} (`{row_name}`), column {col} (`{col_name}`) is {value}: {reason}")]
    Entry {
        /// File.
        path: PathBuf,
        /// Row index (0-based).
        row: usize,
        /// Row material.
        row_name: String,
        /// Column index (0-based).
        col: usize,
        /// Column material.
        col_name: String,
        /// The value.
        value: f64,
        /// Why it is refused.
        reason: String,
    },
    /// Names that do not fit the matrix.
    #[error("{path}: {message}")]
    Names {
        /// File.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Tiles that do not assemble into one matrix.
    #[error("cannot merge tiles: {0}")]
    Merge(String),
    /// Writing failed.
    #[error(transparent)]
    Output(#[from] OutputError),
}

impl MatrixFileError {
    /// A bad entry `(row, col)` of the matrix of `names` in `path`.
    pub(crate) fn entry(
        path: &Path,
        names: &[String],
        e: crate::distance::BadEntry,
        tol: f64,
    ) -> Self {
        MatrixFileError::Entry {
            path: path.to_path_buf(),
            row: e.row,
            row_name: names[e.row].clone(),
            col: e.col,
            col_name: names[e.col].clone(),
            value: e.value,
            reason: e.fault.reason(e.row, e.col, tol),
        }
    }
}
