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
    /// non-finite or negative entry, a non-zero diagonal or an asymmetric pair.
    pub fn from_full(names: Vec<String>, data: Vec<f64>) -> Result<Self, DistanceError> {
        let n = names.len();
        if data.len() != n * n {
            return Err(DistanceError::Shape {
                expected: n * n,
                found: data.len(),
            });
        }
        for i in 0..n {
            for j in 0..n {
                let v = data[i * n + j];
                if !v.is_finite() || v < 0.0 {
                    return Err(DistanceError::BadEntry {
                        row: names[i].clone(),
                        col: names[j].clone(),
                        value: v,
                    });
                }
                if i == j && v != 0.0 {
                    return Err(DistanceError::BadEntry {
                        row: names[i].clone(),
                        col: names[j].clone(),
                        value: v,
                    });
                }
                if v != data[j * n + i] {
                    return Err(DistanceError::Asymmetric {
                        row: names[i].clone(),
                        col: names[j].clone(),
                    });
                }
            }
        }
        Ok(Self { names, data })
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

impl Distances for DistanceMatrix {
    fn len(&self) -> usize {
        self.names.len()
    }
    fn dist(&self, i: usize, j: usize) -> f64 {
        self.data[i * self.names.len() + j]
    }
}
