//! Small dense symmetric eigenproblems (cyclic Jacobi) for condition numbers, ranks and
//! the PCA of the `nielsen` baseline. Matrices are row-major `n x n`.

/// Eigenvalues and eigenvectors of the symmetric `a` (`n x n`, row-major) by cyclic Jacobi
/// rotations (Golub & Van Loan, *Matrix Computations*, 4th ed., section 8.5): returns the
/// eigenvalues in decreasing order and the eigenvectors as the columns of a row-major
/// `n x n` matrix in the same order. Accurate to a few ulps of the largest eigenvalue.
pub fn sym_eigen(n: usize, a: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut m = a[..n * n].to_vec();
    let mut v = vec![0.0; n * n];
    for i in 0..n {
        v[i * n + i] = 1.0;
    }
    for _sweep in 0..60 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| m[i * n + j] * m[i * n + j])
            .sum();
        let diag: f64 = (0..n).map(|i| m[i * n + i] * m[i * n + i]).sum();
        if off <= 1e-30 * diag || off == 0.0 {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = m[p * n + q];
                if apq == 0.0 {
                    continue;
                }
                let theta = (m[q * n + q] - m[p * n + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let (mkp, mkq) = (m[k * n + p], m[k * n + q]);
                    m[k * n + p] = c * mkp - s * mkq;
                    m[k * n + q] = s * mkp + c * mkq;
                }
                for k in 0..n {
                    let (mpk, mqk) = (m[p * n + k], m[q * n + k]);
                    m[p * n + k] = c * mpk - s * mqk;
                    m[q * n + k] = s * mpk + c * mqk;
                }
                for k in 0..n {
                    let (vkp, vkq) = (v[k * n + p], v[k * n + q]);
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| m[j * n + j].total_cmp(&m[i * n + i]));
    let vals = order.iter().map(|&i| m[i * n + i]).collect();
    let mut vecs = vec![0.0; n * n];
    for (c, &i) in order.iter().enumerate() {
        for r in 0..n {
            vecs[r * n + c] = v[r * n + i];
        }
    }
    (vals, vecs)
}

/// Singular values (decreasing) of the `rows x cols` row-major matrix `d`: square roots of
/// the eigenvalues of the smaller of `d d^T` and `d^T d` (negative rounding clamped to 0).
pub fn singular_values(rows: usize, cols: usize, d: &[f64]) -> Vec<f64> {
    let (n, g) = if rows <= cols {
        let mut g = vec![0.0; rows * rows];
        for i in 0..rows {
            for j in 0..=i {
                let s: f64 = (0..cols).map(|k| d[i * cols + k] * d[j * cols + k]).sum();
                g[i * rows + j] = s;
                g[j * rows + i] = s;
            }
        }
        (rows, g)
    } else {
        let mut g = vec![0.0; cols * cols];
        for r in 0..rows {
            let row = &d[r * cols..(r + 1) * cols];
            for i in 0..cols {
                for j in 0..=i {
                    g[i * cols + j] += row[i] * row[j];
                }
            }
        }
        for i in 0..cols {
            for j in 0..i {
                g[j * cols + i] = g[i * cols + j];
            }
        }
        (cols, g)
    };
    sym_eigen(n, &g)
        .0
        .into_iter()
        .map(|l| l.max(0.0).sqrt())
        .collect()
}

/// Condition number `s_max / s_min` of `d` over its `min(rows, cols)` singular values
/// (infinite when the smallest is 0; 1 for an empty matrix).
pub fn condition_number(rows: usize, cols: usize, d: &[f64]) -> f64 {
    let s = singular_values(rows, cols, d);
    match (s.first(), s.last()) {
        (Some(&hi), Some(&lo)) if lo > 0.0 => hi / lo,
        (Some(_), Some(_)) => f64::INFINITY,
        _ => 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigen_of_a_hand_made_matrix() {
        // [[2, 1], [1, 2]]: eigenvalues 3 and 1, vectors (1, 1)/sqrt2 and (1, -1)/sqrt2.
        let (l, v) = sym_eigen(2, &[2.0, 1.0, 1.0, 2.0]);
        assert!(
            (l[0] - 3.0).abs() < 1e-14 && (l[1] - 1.0).abs() < 1e-14,
            "{l:?}"
        );
        assert!((v[0].abs() - 0.5f64.sqrt()).abs() < 1e-14 && (v[0] - v[2]).abs() < 1e-14);
        // diag(3, 1) rows [[3, 0], [0, 1], [0, 0]]: singular values 3, 1, condition 3.
        let d = [3.0, 0.0, 0.0, 1.0, 0.0, 0.0];
        assert!((condition_number(3, 2, &d) - 3.0).abs() < 1e-12);
        assert!((condition_number(2, 3, &[3.0, 0.0, 0.0, 0.0, 1.0, 0.0]) - 3.0).abs() < 1e-12);
        assert!(condition_number(2, 2, &[1.0, 1.0, 1.0, 1.0]) > 1e12);
    }
}
