//! Dense NNLS: `min |A x - b|` subject to `x >= 0` for a row-major `A`, on the Gram form
//! by the exact Lawson-Hanson solver (the facade's `nnls_dense`, Python's `nnls`).

use super::{NnlsError, NnlsSolution};

/// Non-negative least squares `min |A x - b|` subject to `x >= 0` for a dense row-major
/// `A` (`rows` x `cols`), by the crate's exact Lawson-Hanson solver on the Gram form
/// (`G = A^T A`, `h = A^T b`, summed in f64).
///
/// # Errors
/// [`NnlsError`] for mismatched lengths, non-finite entries or no column.
pub fn solve_dense(
    a: &[f64],
    rows: usize,
    cols: usize,
    b: &[f64],
) -> Result<NnlsSolution, NnlsError> {
    if a.len() != rows * cols {
        return Err(NnlsError::DimensionMismatch {
            what: "A",
            expected: rows * cols,
            found: a.len(),
        });
    }
    if b.len() != rows {
        return Err(NnlsError::DimensionMismatch {
            what: "b",
            expected: rows,
            found: b.len(),
        });
    }
    for (what, v, width) in [("A", a, cols.max(1)), ("b", b, 1)] {
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(NnlsError::NonFinite {
                what,
                row: i / width,
                col: i % width,
                value: v[i],
            });
        }
    }
    let mut g = vec![0f64; cols * cols];
    let mut h = vec![0f64; cols];
    for r in 0..rows {
        let row = &a[r * cols..(r + 1) * cols];
        for i in 0..cols {
            h[i] += row[i] * b[r];
            for j in 0..cols {
                g[i * cols + j] += row[i] * row[j];
            }
        }
    }
    let bb: f64 = b.iter().map(|x| x * x).sum();
    let problem = super::GramProblem::new(cols, &g, &h, bb)?;
    super::lawson_hanson::solve(&problem, &super::lawson_hanson::LhParams::default())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dense NNLS: hand-solved cases, the dimension checks.
    #[test]
    fn nnls_hand_cases() {
        // min |x - (1, -1)| s.t. x >= 0: (1, 0).
        let s = solve_dense(&[1.0, 0.0, 0.0, 1.0], 2, 2, &[1.0, -1.0]).unwrap();
        assert_eq!(s.x, vec![1.0, 0.0]);
        // A = [[1, 1], [1, 2], [1, 3]], b = A (2, 1): exact and positive.
        let a = [1.0, 1.0, 1.0, 2.0, 1.0, 3.0];
        let s = solve_dense(&a, 3, 2, &[3.0, 4.0, 5.0]).unwrap();
        assert!(
            (s.x[0] - 2.0).abs() < 1e-12 && (s.x[1] - 1.0).abs() < 1e-12,
            "{:?}",
            s.x
        );
        // b = (3, 2, 1): the unconstrained slope is -1; with x >= 0, x = (2, 0).
        let s = solve_dense(&a, 3, 2, &[3.0, 2.0, 1.0]).unwrap();
        assert!((s.x[0] - 2.0).abs() < 1e-12 && s.x[1] == 0.0, "{:?}", s.x);
        assert!(matches!(
            solve_dense(&a, 3, 2, &[1.0]),
            Err(NnlsError::DimensionMismatch { .. })
        ));
        assert!(matches!(
            solve_dense(&a[..5], 3, 2, &[1.0; 3]),
            Err(NnlsError::DimensionMismatch { .. })
        ));
        assert!(matches!(
            solve_dense(&[f64::NAN], 1, 1, &[1.0]),
            Err(NnlsError::NonFinite { .. })
        ));
    }
}
