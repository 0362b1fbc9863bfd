//! Gram matrices of an all-analytic collection in closed form (the objective's fast path).

use crate::backend::LobeParams;
use crate::collection::Collection;
use crate::merl::grid::{N_TD, N_TH};
use crate::merl::{CellSet, GridTables};
use crate::separable::{CellMoments, SeparableLobe};
use rayon::prelude::*;

/// The Gram matrices of an all-analytic collection in closed form: every channel lobe is
/// `kd / pi + ks beta_unit(F0, n)`, so one product `R R^T` of the unit lobes (rows
/// `beta_unit * sqrt(M_2)`) serves the three channels.
pub(crate) fn analytic_grams(coll: &Collection, cells: &CellSet) -> [Vec<f64>; 3] {
    let t = GridTables::new();
    let mom = CellMoments::new(&t, cells);
    let n = coll.len();
    let mats: Vec<_> = coll
        .materials()
        .iter()
        .map(|m| *m.analytic().expect("all analytic"))
        .collect();
    let unit: Vec<SeparableLobe> = mats
        .par_iter()
        .map(|a| {
            SeparableLobe::new(
                &t,
                &LobeParams {
                    kd: 0.0,
                    ks: 1.0,
                    f0: a.f0 as f32,
                    n: a.n as f32,
                },
            )
        })
        .collect();
    let sq: Vec<f64> = mom.m2.iter().map(|v| v.max(0.0).sqrt()).collect();
    let nij = N_TH * N_TD;
    let rows: Vec<f64> = unit
        .iter()
        .flat_map(|u| u.beta.iter().zip(&sq).map(|(b, s)| b * s))
        .collect();
    let c1: Vec<f64> = unit
        .iter()
        .map(|u| u.beta.iter().zip(&mom.m1).map(|(b, m)| b * m).sum())
        .collect();
    let u = gram_rows(&rows, n, nij);
    // Freed before the three (N + 1)^2 matrices are built (650 MB each at N = 10,000).
    drop(rows);
    drop(unit);
    let total = mom.total;
    [0, 1, 2].map(|c| {
        let m = n + 1;
        // Column 0: alpha = 1/pi, ks = 0. Parameters rounded to f32 as every lobe is.
        let alpha: Vec<f64> = std::iter::once(std::f64::consts::FRAC_1_PI)
            .chain(
                mats.iter()
                    .map(|a| a.d[c] as f32 as f64 * std::f64::consts::FRAC_1_PI),
            )
            .collect();
        let ks: Vec<f64> = std::iter::once(0.0)
            .chain(mats.iter().map(|a| a.s[c] as f32 as f64))
            .collect();
        let c1x: Vec<f64> = std::iter::once(0.0).chain(c1.iter().copied()).collect();
        let mut g = vec![0.0; m * m];
        g.par_chunks_mut(m).enumerate().for_each(|(i, row)| {
            for (j, o) in row.iter_mut().enumerate() {
                let uij = if i > 0 && j > 0 {
                    u[(i - 1) * n + j - 1]
                } else {
                    0.0
                };
                *o = alpha[i] * alpha[j] * total
                    + alpha[i] * ks[j] * c1x[j]
                    + alpha[j] * ks[i] * c1x[i]
                    + ks[i] * ks[j] * uij;
            }
        });
        g
    })
}

/// `R R^T` of `n` rows of length `len` (row-major), symmetric `n x n`, in 4 x 4 register
/// tiles, row tiles in parallel.
fn gram_rows(rows: &[f64], n: usize, len: usize) -> Vec<f64> {
    const T: usize = 4;
    let tiles = n.div_ceil(T);
    let pairs: Vec<(usize, usize)> = (0..tiles)
        .flat_map(|a| (a..tiles).map(move |b| (a, b)))
        .collect();
    let blocks: Vec<[[f64; T]; T]> = pairs
        .par_iter()
        .map(|&(a, b)| {
            let row = |i: usize| {
                let i = i.min(n - 1);
                &rows[i * len..(i + 1) * len]
            };
            let ra = [0, 1, 2, 3].map(|r| row(a * T + r));
            let rb = [0, 1, 2, 3].map(|r| row(b * T + r));
            let mut acc = [[[0.0f64; 4]; T]; T];
            let chunks = len / 4;
            for e in 0..chunks {
                let o = e * 4;
                let xa = ra.map(|r| [r[o], r[o + 1], r[o + 2], r[o + 3]]);
                let xb = rb.map(|r| [r[o], r[o + 1], r[o + 2], r[o + 3]]);
                for i in 0..T {
                    for j in 0..T {
                        for l in 0..4 {
                            acc[i][j][l] += xa[i][l] * xb[j][l];
                        }
                    }
                }
            }
            let mut out = [[0.0; T]; T];
            for i in 0..T {
                for j in 0..T {
                    let mut s = acc[i][j][0] + acc[i][j][1] + acc[i][j][2] + acc[i][j][3];
                    for o in chunks * 4..len {
                        s += ra[i][o] * rb[j][o];
                    }
                    out[i][j] = s;
                }
            }
            out
        })
        .collect();
    let mut g = vec![0.0; n * n];
    for (&(a, b), blk) in pairs.iter().zip(&blocks) {
        for (i, r) in blk.iter().enumerate() {
            for (j, &v) in r.iter().enumerate() {
                let (gi, gj) = (a * T + i, b * T + j);
                if gi < n && gj < n {
                    g[gi * n + gj] = v;
                    g[gj * n + gi] = v;
                }
            }
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gram_rows_matches_naive_products() {
        let (n, len) = (7, 13);
        let rows: Vec<f64> = (0..n * len).map(|i| ((i * 37 % 11) as f64) - 4.0).collect();
        let g = gram_rows(&rows, n, len);
        for i in 0..n {
            for j in 0..n {
                let naive: f64 = (0..len)
                    .map(|e| rows[i * len + e] * rows[j * len + e])
                    .sum();
                assert_eq!(g[i * n + j], naive, "({i}, {j})");
            }
        }
    }
}
