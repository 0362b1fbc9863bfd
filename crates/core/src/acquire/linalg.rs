//! Small dense symmetric eigenproblems (cyclic Jacobi) for condition numbers, ranks and
//! the PCA of the `nielsen` baseline. Matrices are row-major `n x n`.

/// Eigenvalues and eigenvectors of the symmetric `a` (`n x n`, row-major) by cyclic Jacobi
/// rotations (Golub & Van Loan, *Matrix Computations*, 4th ed., section 8.5): returns the
/// eigenvalues in decreasing order and the eigenvectors as the columns of a row-major
/// `n x n` matrix in the same order. Accurate to a few ulps of the largest eigenvalue.
pub(crate) fn sym_eigen(n: usize, a: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut m = a[..n * n].to_vec();
    let mut v = vec![0.0; n * n];
    for i in 0..n {
        v[i * n + i] = 1.0;
    }
    jacobi(n, &mut m, Some(&mut v));
    let order = decreasing(n, &m);
    let vals = order.iter().map(|&i| m[i * n + i]).collect();
    let mut vecs = vec![0.0; n * n];
    for (c, &i) in order.iter().enumerate() {
        for r in 0..n {
            vecs[r * n + c] = v[r * n + i];
        }
    }
    (vals, vecs)
}

/// The eigenvalues of [`sym_eigen`] alone, bit for bit (the rotations of the matrix do not
/// depend on the eigenvectors, which are not accumulated: a third less work).
pub(crate) fn sym_eigenvalues(n: usize, a: &[f64]) -> Vec<f64> {
    let mut m = a[..n * n].to_vec();
    jacobi(n, &mut m, None);
    decreasing(n, &m).iter().map(|&i| m[i * n + i]).collect()
}

/// Indices of the diagonal of `m` in decreasing order.
fn decreasing(n: usize, m: &[f64]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| m[j * n + j].total_cmp(&m[i * n + i]));
    order
}

/// Cyclic Jacobi sweeps on `m` (`n x n`) until its off-diagonal part is negligible, the
/// rotations accumulated into `v` when given.
fn jacobi(n: usize, m: &mut [f64], mut v: Option<&mut [f64]>) {
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
                for row in m.chunks_exact_mut(n) {
                    let (mkp, mkq) = (row[p], row[q]);
                    row[p] = c * mkp - s * mkq;
                    row[q] = s * mkp + c * mkq;
                }
                let (rp, rq) = m.split_at_mut(q * n);
                let (rp, rq) = (&mut rp[p * n..(p + 1) * n], &mut rq[..n]);
                for (mpk, mqk) in rp.iter_mut().zip(rq.iter_mut()) {
                    let (a, b) = (*mpk, *mqk);
                    *mpk = c * a - s * b;
                    *mqk = s * a + c * b;
                }
                if let Some(v) = v.as_deref_mut() {
                    for row in v.chunks_exact_mut(n) {
                        let (vkp, vkq) = (row[p], row[q]);
                        row[p] = c * vkp - s * vkq;
                        row[q] = s * vkp + c * vkq;
                    }
                }
            }
        }
    }
}

/// Singular values (decreasing) of the `rows x cols` row-major matrix `d`: square roots of
/// the eigenvalues of the smaller of `d d^T` and `d^T d` (negative rounding clamped to 0).
pub(crate) fn singular_values(rows: usize, cols: usize, d: &[f64]) -> Vec<f64> {
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
    sym_eigenvalues(n, &g)
        .into_iter()
        .map(|l| l.max(0.0).sqrt())
        .collect()
}

/// Condition number `s_max / s_min` of `d` over its `min(rows, cols)` singular values
/// (infinite when the smallest is 0; 1 for an empty matrix).
pub(crate) fn condition_number(rows: usize, cols: usize, d: &[f64]) -> f64 {
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

    /// The eigenvalues alone are those of the full decomposition bit for bit.
    #[test]
    fn eigenvalues_alone_equal_those_of_the_decomposition() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for n in [1, 2, 5, 13, 20] {
            let b: Vec<f64> = (0..n * n).map(|_| rng.random::<f64>() - 0.3).collect();
            let mut a = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    a[i * n + j] = (0..n).map(|k| b[i * n + k] * b[j * n + k]).sum();
                }
            }
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                bits(&sym_eigenvalues(n, &a)),
                bits(&sym_eigen(n, &a).0),
                "n {n}"
            );
        }
    }
}
