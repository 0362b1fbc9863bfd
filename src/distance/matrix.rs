//! Distance matrices: a full symmetric `N x N` matrix with names, its condensed form, and
//! the small [`Distances`] trait that the clustering code takes.

use crate::error::DistanceError;

/// Anything that can report the distance between items `i` and `j` of a set of `len()`
/// items. Implementations must be symmetric with a zero diagonal.
pub trait Distances {
    /// Number of items.
    fn len(&self) -> usize;
    /// Distance between items `i` and `j` (`0 <= i, j < len()`).
    fn dist(&self, i: usize, j: usize) -> f64;
    /// True when there are no items.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A full, symmetric, zero-diagonal distance matrix over named materials (row-major).
#[derive(Clone, Debug, PartialEq)]
pub struct DistanceMatrix {
    names: Vec<String>,
    data: Vec<f64>,
}

impl DistanceMatrix {
    /// Builds a matrix from a full row-major `N x N` array. Rejects a wrong size, a
    /// non-finite or negative entry, a non-zero diagonal or an asymmetric pair
    /// ([`check_entries`] with tolerance 0).
    pub fn from_full(names: Vec<String>, data: Vec<f64>) -> Result<Self, DistanceError> {
        let n = names.len();
        if data.len() != n * n {
            return Err(DistanceError::Shape {
                expected: n * n,
                found: data.len(),
            });
        }
        match check_entries(n, &data, 0.0) {
            Ok(()) => Ok(Self { names, data }),
            Err(e) => {
                let (row, col) = (names[e.row].clone(), names[e.col].clone());
                Err(match e.fault {
                    EntryFault::Asymmetric { .. } => DistanceError::Asymmetric { row, col },
                    _ => DistanceError::BadEntry {
                        row,
                        col,
                        value: e.value,
                    },
                })
            }
        }
    }

    /// A matrix from data already checked by [`check_entries`] with tolerance 0.
    pub(crate) fn from_checked(names: Vec<String>, data: Vec<f64>) -> Self {
        debug_assert_eq!(data.len(), names.len() * names.len());
        Self { names, data }
    }

    /// Builds a matrix from the condensed upper triangle (row-major over `i < j`, the
    /// SciPy `pdist` order).
    pub fn from_condensed(names: Vec<String>, condensed: &[f64]) -> Result<Self, DistanceError> {
        let n = names.len();
        let expected = n * n.saturating_sub(1) / 2;
        if condensed.len() != expected {
            return Err(DistanceError::Shape {
                expected,
                found: condensed.len(),
            });
        }
        let mut data = vec![0.0; n * n];
        let mut k = 0;
        for i in 0..n {
            for j in i + 1..n {
                data[i * n + j] = condensed[k];
                data[j * n + i] = condensed[k];
                k += 1;
            }
        }
        Self::from_full(names, data)
    }

    /// Material names, in row order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The full row-major `N x N` data.
    pub fn as_full(&self) -> &[f64] {
        &self.data
    }

    /// The condensed upper triangle (row-major over `i < j`).
    pub fn condensed(&self) -> Vec<f64> {
        let n = self.names.len();
        let mut out = Vec::with_capacity(n * n.saturating_sub(1) / 2);
        for i in 0..n {
            for j in i + 1..n {
                out.push(self.data[i * n + j]);
            }
        }
        out
    }

    /// Row `i` of the matrix.
    pub fn row(&self, i: usize) -> &[f64] {
        let n = self.names.len();
        &self.data[i * n..(i + 1) * n]
    }

    /// A sub-matrix over the given item indices (in the given order).
    pub fn subset(&self, idx: &[usize]) -> Self {
        let n = self.names.len();
        let names = idx.iter().map(|&i| self.names[i].clone()).collect();
        let mut data = Vec::with_capacity(idx.len() * idx.len());
        for &i in idx {
            for &j in idx {
                data.push(self.data[i * n + j]);
            }
        }
        Self { names, data }
    }
}

/// What is wrong with a distance-matrix entry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EntryFault {
    /// NaN or infinite.
    NotFinite,
    /// Below 0.
    Negative,
    /// A diagonal entry other than 0.
    Diagonal,
    /// `D[i][j]` and `D[j][i]` differ by more than the tolerance; `other` is `D[j][i]`.
    Asymmetric {
        /// The mirrored entry.
        other: f64,
    },
}

impl EntryFault {
    /// Why the entry is refused, in words (for messages); `tol` is the relative
    /// symmetry tolerance used.
    pub fn reason(&self, row: usize, col: usize, tol: f64) -> String {
        match self {
            EntryFault::NotFinite => "not a finite number".into(),
            EntryFault::Negative => "a distance cannot be negative".into(),
            EntryFault::Diagonal => "the diagonal must be 0".into(),
            EntryFault::Asymmetric { other } => format!(
                "the matrix is not symmetric: the entry at row {col}, column {row} is {other} (relative tolerance {tol:e})"
            ),
        }
    }
}

/// The first bad entry of a matrix, by row and column index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BadEntry {
    /// Row (0-based).
    pub row: usize,
    /// Column (0-based).
    pub col: usize,
    /// The entry.
    pub value: f64,
    /// What is wrong.
    pub fault: EntryFault,
}

/// What is wrong with entry `(i, j)` of value `v` taken alone (finite, non-negative,
/// zero on the diagonal), if anything.
pub fn entry_fault(i: usize, j: usize, v: f64) -> Option<EntryFault> {
    if !v.is_finite() {
        Some(EntryFault::NotFinite)
    } else if v < 0.0 {
        Some(EntryFault::Negative)
    } else if i == j && v != 0.0 {
        Some(EntryFault::Diagonal)
    } else {
        None
    }
}

/// The one check of a distance matrix (row-major `n x n`): every entry finite and
/// non-negative, row by row, the diagonal 0, then every pair `i < j` symmetric within
/// the relative tolerance `tol` (`|D_ij - D_ji| <= tol * max(|D_ij|, |D_ji|)`; 0 asks
/// for exact symmetry). Returns the first bad entry.
pub fn check_entries(n: usize, data: &[f64], tol: f64) -> Result<(), BadEntry> {
    assert_eq!(data.len(), n * n, "check_entries: {n} x {n} matrix");
    for i in 0..n {
        for j in 0..n {
            let value = data[i * n + j];
            if let Some(fault) = entry_fault(i, j, value) {
                return Err(BadEntry {
                    row: i,
                    col: j,
                    value,
                    fault,
                });
            }
        }
    }
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (data[i * n + j], data[j * n + i]);
            if a != b && (a - b).abs() > tol * a.abs().max(b.abs()) {
                return Err(BadEntry {
                    row: i,
                    col: j,
                    value: a,
                    fault: EntryFault::Asymmetric { other: b },
                });
            }
        }
    }
    Ok(())
}

impl Distances for DistanceMatrix {
    fn len(&self) -> usize {
        self.names.len()
    }
    fn dist(&self, i: usize, j: usize) -> f64 {
        self.data[i * self.names.len() + j]
    }
}
