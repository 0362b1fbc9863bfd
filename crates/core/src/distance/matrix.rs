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
    /// Whether the values can still be trusted, checked cheaply (no re-read): values read
    /// in place from a memory-mapped file that was truncated or written since it was
    /// checked are not ([`crate::io::mmap`]). Clustering asks between runs and every few
    /// swaps and candidates, and stops with the reason. Always `Ok` by default.
    fn intact(&self) -> Result<(), String> {
        Ok(())
    }
}

/// Values that live outside the matrix, in an owner it shares (a memory-mapped file,
/// [`crate::io::mmap`]).
///
/// # Safety
///
/// [`values`](SharedValues::values) must return the same slice (address and length) on
/// every call, valid for as long as the owner lives: the matrix reads it through a copy
/// of that address, not through the owner.
pub(crate) unsafe trait SharedValues: Send + Sync + std::fmt::Debug {
    /// The values, row-major.
    fn values(&self) -> &[f64];

    /// Whether the source of the values is as it was when they were checked (a mapped
    /// file: not written or truncated since, [`crate::io::mmap`]); the error says what
    /// changed.
    fn unchanged(&self) -> Result<(), String> {
        Ok(())
    }

    /// [`Self::unchanged`] without reading the values again (size, times, truncation).
    fn unchanged_quick(&self) -> Result<(), String> {
        Ok(())
    }
}

/// Where a matrix's values are: its own vector, or a shared owner's stable slice.
#[derive(Clone, Debug)]
enum Values {
    Owned(Vec<f64>),
    Shared {
        // Kept alive for `ptr..ptr + len` (SharedValues' contract).
        _owner: std::sync::Arc<dyn SharedValues>,
        ptr: *const f64,
        len: usize,
    },
}

// SAFETY: the shared slice is read-only and its owner is Send + Sync.
unsafe impl Send for Values {}
// SAFETY: as above; nothing mutates the values through `&Values`.
unsafe impl Sync for Values {}

impl Values {
    #[inline]
    fn as_slice(&self) -> &[f64] {
        match self {
            Values::Owned(v) => v,
            // SAFETY: `ptr..ptr + len` is the owner's stable slice, alive while `_owner`
            // is (SharedValues' contract), and never written through.
            Values::Shared { ptr, len, .. } => unsafe { std::slice::from_raw_parts(*ptr, *len) },
        }
    }
}

/// A full, symmetric, zero-diagonal distance matrix over named materials (row-major).
/// Its values are its own, or, for a saved matrix read with
/// [`load_saved_matrix`](crate::io::saved::load_saved_matrix), read in place from the
/// memory-mapped file ([`is_mapped`](Self::is_mapped)); either way they read the same.
#[derive(Clone, Debug)]
pub struct DistanceMatrix {
    names: Vec<String>,
    data: Values,
}

impl PartialEq for DistanceMatrix {
    fn eq(&self, other: &Self) -> bool {
        self.names == other.names && self.as_full() == other.as_full()
    }
}

impl DistanceMatrix {
    /// Builds a matrix from a full row-major `N x N` array. Rejects a wrong size, a
    /// non-finite or negative entry, a non-zero diagonal or an asymmetric pair
    /// (`check_entries` with tolerance 0).
    pub fn from_full(names: Vec<String>, data: Vec<f64>) -> Result<Self, DistanceError> {
        let n = names.len();
        if data.len() != n * n {
            return Err(DistanceError::Shape {
                expected: n * n,
                found: data.len(),
            });
        }
        match check_entries(n, &data, 0.0) {
            Ok(()) => Ok(Self {
                names,
                data: Values::Owned(data),
            }),
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
        Self {
            names,
            data: Values::Owned(data),
        }
    }

    /// A matrix whose values, already checked by [`check_entries`] with tolerance 0, stay
    /// in `owner` (a memory-mapped file) and are read in place.
    pub(crate) fn from_checked_shared(
        names: Vec<String>,
        owner: std::sync::Arc<dyn SharedValues>,
    ) -> Self {
        let v = owner.values();
        let (ptr, len) = (v.as_ptr(), v.len());
        assert_eq!(len, names.len() * names.len(), "shared matrix values");
        Self {
            names,
            data: Values::Shared {
                _owner: owner,
                ptr,
                len,
            },
        }
    }

    /// For values read in place from a memory-mapped file: whether the file is still as
    /// it was when it was checked (same size, times and checksum, never truncated under
    /// the mapping); the error says what changed. Always `Ok` for values of its own.
    pub fn source_unchanged(&self) -> Result<(), String> {
        match &self.data {
            Values::Owned(_) => Ok(()),
            Values::Shared { _owner, .. } => _owner.unchanged(),
        }
    }

    /// Whether the values are read in place from a memory-mapped file rather than held in
    /// memory of the matrix's own.
    pub fn is_mapped(&self) -> bool {
        matches!(self.data, Values::Shared { .. })
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
    #[inline]
    pub fn as_full(&self) -> &[f64] {
        self.data.as_slice()
    }

    /// The condensed upper triangle (row-major over `i < j`).
    pub fn condensed(&self) -> Vec<f64> {
        let n = self.names.len();
        let data = self.as_full();
        let mut out = Vec::with_capacity(n * n.saturating_sub(1) / 2);
        for i in 0..n {
            for j in i + 1..n {
                out.push(data[i * n + j]);
            }
        }
        out
    }

    /// Row `i` of the matrix.
    pub fn row(&self, i: usize) -> &[f64] {
        let n = self.names.len();
        &self.as_full()[i * n..(i + 1) * n]
    }

    /// A sub-matrix over the given item indices (in the given order).
    pub fn subset(&self, idx: &[usize]) -> Self {
        let n = self.names.len();
        let names = idx.iter().map(|&i| self.names[i].clone()).collect();
        let full = self.as_full();
        let mut data = Vec::with_capacity(idx.len() * idx.len());
        for &i in idx {
            for &j in idx {
                data.push(full[i * n + j]);
            }
        }
        Self::from_checked(names, data)
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
pub(crate) fn entry_fault(i: usize, j: usize, v: f64) -> Option<EntryFault> {
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
pub(crate) fn check_entries(n: usize, data: &[f64], tol: f64) -> Result<(), BadEntry> {
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
    #[inline]
    fn dist(&self, i: usize, j: usize) -> f64 {
        self.as_full()[i * self.names.len() + j]
    }
    fn intact(&self) -> Result<(), String> {
        match &self.data {
            Values::Owned(_) => Ok(()),
            Values::Shared { _owner, .. } => _owner.unchanged_quick(),
        }
    }
}
