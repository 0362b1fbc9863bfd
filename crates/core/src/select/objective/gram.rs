//! Gram matrices of an all-analytic collection in closed form (the objective's fast path).
//!
//! Every channel lobe of an analytic material is `kd / pi + ks beta_unit(F0, n)` with the
//! unit lobe `beta_unit[i][j] = P_i F_j`, `P_i = (n + 1) / (8 pi) (cos theta_h_i)^n` and
//! `F_j = F0 + (1 - F0) S_j = F0 (1 - S_j) + S_j` (`S_j` the Schlick factor of column `j`),
//! F0 and n shared by the three channels. The specular products over the fit cells
//! therefore separate over `j`:
//!
//! ```text
//! sum_ij beta_a beta_b M_2 = sum_i P_a,i P_b,i (F0_a F0_b A_i + (F0_a + F0_b) B_i + C_i)
//! A_i = sum_j (1 - S_j)^2 M_2,ij,  B_i = sum_j (1 - S_j) S_j M_2,ij,  C_i = sum_j S_j^2 M_2,ij
//! ```
//!
//! so the channel-independent kernel `U_ab` is one product `Z W^T` of `N x 180` matrices
//! (`Z_a = [P_a F0_a, P_a]`, `W_b = [P_b (F0_b A + B), P_b (F0_b B + C)]`) instead of 8,100
//! multiply-adds per pair; every term is non-negative, so the reassociation changes
//! nothing but rounding (tested against the per-pair tables to 1e-12 relative). The
//! cross terms `<beta_a, M_1>` reduce the same way to 90-vectors.

use crate::collection::Collection;
use crate::merl::{CellSet, GridTables};
use crate::merl::{N_TD, N_TH};
use crate::separable::CellMoments;
use rayon::prelude::*;

/// Length of the rows of `Z` and `W`.
const LEN: usize = 2 * N_TH;

/// The Gram matrices of an all-analytic collection in closed form (module docs): per
/// channel `(N + 1)^2`, column 0 the Lambertian `1/pi`, column `j + 1` material `j`.
pub(crate) fn analytic_grams(coll: &Collection, cells: &CellSet) -> [Vec<f64>; 3] {
    analytic_grams_weighted(coll, [cells, cells, cells])
}

/// [`analytic_grams`] with each channel's own weights over the fit cells (`cells[c]`, the
/// same cells: SPEC 11's shared weights of `relative` and `log`, which differ per
/// channel). One specular kernel when the three cell sets are one (`l2`), else one per
/// channel; each is a `Z W^T` product, so a weighted objective costs what `l2` does and
/// no grid pass over the materials.
pub(crate) fn analytic_grams_weighted(coll: &Collection, cells: [&CellSet; 3]) -> [Vec<f64>; 3] {
    let t = GridTables::new();
    let n = coll.len();
    let m = n + 1;
    let mats: Vec<_> = coll
        .materials()
        .iter()
        .map(|mat| *mat.analytic().expect("all analytic"))
        .collect();
    let chan = |c: usize, total: f64, c1: &[f64]| Channel {
        total,
        alpha: std::iter::once(std::f64::consts::FRAC_1_PI)
            .chain(
                mats.iter()
                    .map(|a| a.d[c] as f32 as f64 * std::f64::consts::FRAC_1_PI),
            )
            .collect(),
        ks: std::iter::once(0.0)
            .chain(mats.iter().map(|a| a.s[c] as f32 as f64))
            .collect(),
        c1: std::iter::once(0.0).chain(c1.iter().copied()).collect(),
    };
    // `u` (the specular kernel, row and column 0 zero) becomes channel `c`'s matrix in place.
    let finish = |ch: Channel, mut u: Vec<f64>| {
        u.par_chunks_mut(m).enumerate().for_each(|(i, row)| {
            for (j, o) in row.iter_mut().enumerate() {
                *o = ch.entry(i, j, *o);
            }
        });
        u
    };
    let same = std::ptr::eq(cells[0], cells[1]) && std::ptr::eq(cells[0], cells[2]);
    if !same {
        return std::array::from_fn(|c| {
            let mom = CellMoments::new(&t, cells[c]);
            let (u, c1) = specular_kernel(&t, &mats, &mom);
            finish(chan(c, mom.total, &c1), u)
        });
    }
    let mom = CellMoments::new(&t, cells[0]);
    let (g0, c1) = specular_kernel(&t, &mats, &mom);
    // Channel 0's matrix holds U until the other two channels are built from it; then it
    // becomes channel 0 in place (three (N + 1)^2 matrices at most).
    let from_u = |c: usize, u: &[f64]| {
        let ch = chan(c, mom.total, &c1);
        let mut g = vec![0.0; m * m];
        g.par_chunks_mut(m)
            .zip(u.par_chunks(m))
            .enumerate()
            .for_each(|(i, (row, urow))| {
                for (j, (o, &uij)) in row.iter_mut().zip(urow).enumerate() {
                    *o = ch.entry(i, j, uij);
                }
            });
        g
    };
    let g1 = from_u(1, &g0);
    let g2 = from_u(2, &g0);
    let g0 = finish(chan(0, mom.total, &c1), g0);
    [g0, g1, g2]
}

/// The channel-independent specular kernel `U` of the materials under the moments `mom`
/// (`(N + 1)^2`, row and column 0 zero, symmetric) and `<beta_unit, M_1>` per material.
fn specular_kernel(
    t: &GridTables,
    mats: &[crate::brdf::AshikhminShirley],
    mom: &CellMoments,
) -> (Vec<f64>, Vec<f64>) {
    let n = mats.len();
    let m = n + 1;
    // Per-i reductions of the moment tables over j.
    let (mut a2, mut b2, mut c2) = ([0.0; N_TH], [0.0; N_TH], [0.0; N_TH]);
    let (mut a1, mut b1) = ([0.0; N_TH], [0.0; N_TH]);
    for i in 0..N_TH {
        for j in 0..N_TD {
            let s = t.schlick_d[j];
            let u = 1.0 - s;
            let (m1, m2) = (mom.m1[i * N_TD + j], mom.m2[i * N_TD + j]);
            a2[i] += u * u * m2;
            b2[i] += u * s * m2;
            c2[i] += s * s * m2;
            a1[i] += u * m1;
            b1[i] += s * m1;
        }
    }
    // Rows of Z and W, and <beta_unit, M_1>, per material (parameters rounded to f32 as
    // every lobe is).
    let mut z = vec![0.0; n * LEN];
    let mut w = vec![0.0; n * LEN];
    let mut c1 = vec![0.0; n];
    z.par_chunks_mut(LEN)
        .zip(w.par_chunks_mut(LEN))
        .zip(c1.par_iter_mut())
        .zip(mats.par_iter())
        .for_each(|(((zr, wr), c1r), a)| {
            let (f0, e) = (a.f0 as f32 as f64, a.n as f32 as f64);
            let coef = (e + 1.0) / (8.0 * std::f64::consts::PI);
            let mut s1 = 0.0;
            for i in 0..N_TH {
                let p = coef * (e * t.ln_cos_h[i]).exp();
                zr[i] = p * f0;
                zr[N_TH + i] = p;
                wr[i] = p * (f0 * a2[i] + b2[i]);
                wr[N_TH + i] = p * (f0 * b2[i] + c2[i]);
                s1 += p * (f0 * a1[i] + b1[i]);
            }
            *c1r = s1;
        });
    let mut u = vec![0.0; m * m];
    cross_upper(&z, &w, n, &mut u[m..], m);
    drop(z);
    drop(w);
    mirror_upper(&mut u, m);
    (u, c1)
}

/// One channel's terms of the Gram entries (index 0 the Lambertian column).
struct Channel {
    /// `sum_c w` over the fit cells.
    total: f64,
    /// `kd / pi` per column.
    alpha: Vec<f64>,
    /// `ks` per column.
    ks: Vec<f64>,
    /// `<beta_unit, M_1>` per column.
    c1: Vec<f64>,
}

impl Channel {
    /// `F_ij` from the specular kernel `u = <beta_unit_i beta_unit_j, M_2>`.
    #[inline]
    fn entry(&self, i: usize, j: usize, u: f64) -> f64 {
        let (a, ks, c1) = (&self.alpha, &self.ks, &self.c1);
        a[i] * a[j] * self.total + a[i] * ks[j] * c1[j] + a[j] * ks[i] * c1[i] + ks[i] * ks[j] * u
    }
}

/// Register tile of [`cross_upper`].
const T: usize = 4;

/// The upper triangle (`b >= a`) of `Z W^T` (`n` rows of length [`LEN`] each, row-major)
/// into `out[a * m + b + 1]` (the material block of an `m x m` matrix whose row 0 is left
/// out of `out`), in `T x T` register tiles, row tiles in parallel. Each entry is the sum
/// over `e` in order, so the result does not depend on the tiling or the threads.
fn cross_upper(z: &[f64], w: &[f64], n: usize, out: &mut [f64], m: usize) {
    let np = n.div_ceil(T) * T;
    // W transposed (`LEN x np`, zero padded), so that a tile's four columns are adjacent.
    let mut wt = vec![0.0; LEN * np];
    for (b, row) in w.chunks(LEN).enumerate() {
        for (e, &v) in row.iter().enumerate() {
            wt[e * np + b] = v;
        }
    }
    out.par_chunks_mut(T * m)
        .enumerate()
        .for_each(|(ta, strip)| {
            let a0 = ta * T;
            let za: [&[f64]; T] = std::array::from_fn(|r| {
                let a = (a0 + r).min(n - 1);
                &z[a * LEN..(a + 1) * LEN]
            });
            for b0 in (a0..n).step_by(T) {
                let mut acc = [[0.0f64; T]; T];
                for e in 0..LEN {
                    let wb = &wt[e * np + b0..e * np + b0 + T];
                    for r in 0..T {
                        let x = za[r][e];
                        for s in 0..T {
                            acc[r][s] += x * wb[s];
                        }
                    }
                }
                for (r, acc_r) in acc.iter().enumerate() {
                    let a = a0 + r;
                    if a >= n {
                        break;
                    }
                    for (s, &v) in acc_r.iter().enumerate() {
                        let b = b0 + s;
                        if b >= a && b < n {
                            strip[r * m + b + 1] = v;
                        }
                    }
                }
            }
        });
}

/// Copies the strict upper triangle of the `m x m` matrix `g` onto the lower one, in
/// blocks (cache-friendly transposition).
fn mirror_upper(g: &mut [f64], m: usize) {
    const B: usize = 64;
    for i0 in (0..m).step_by(B) {
        for j0 in (i0..m).step_by(B) {
            for i in i0..(i0 + B).min(m) {
                for j in j0.max(i + 1)..(j0 + B).min(m) {
                    g[j * m + i] = g[i * m + j];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::LobeParams;
    use crate::separable::SeparableLobe;

    /// The Gram of one channel from the per-pair moment tables ([`CellMoments::gram`]:
    /// 8,100 products per pair), the definition the closed form reassociates.
    fn per_pair(coll: &Collection, cells: &CellSet, c: usize) -> Vec<f64> {
        let t = GridTables::new();
        let mom = CellMoments::new(&t, cells);
        let mut lobes = vec![SeparableLobe::new(
            &t,
            &LobeParams {
                kd: std::f32::consts::PI,
                ks: 0.0,
                f0: 0.0,
                n: 0.0,
            },
        )];
        for mat in coll.materials() {
            let a = mat.analytic().expect("analytic");
            lobes.push(SeparableLobe::new(
                &t,
                &LobeParams {
                    kd: a.d[c] as f32,
                    ks: a.s[c] as f32,
                    f0: a.f0 as f32,
                    n: a.n as f32,
                },
            ));
        }
        // Column 0 is exactly 1/pi: alpha = kd / pi with kd = pi rounded to f32 is not,
        // so it is set.
        lobes[0].alpha = std::f64::consts::FRAC_1_PI;
        mom.gram(&lobes, lobes.len())
    }

    #[test]
    fn the_closed_form_equals_the_per_pair_tables() {
        let coll = Collection::embedded_default();
        for stride in [1, 3] {
            let p = crate::fit::FitParams {
                stride,
                ..crate::fit::FitParams::default()
            };
            let all: Vec<usize> = (0..coll.len()).collect();
            let cells = crate::fit::fit_cells(&coll, &all, &p).expect("cells");
            let fast = analytic_grams(&coll, &cells);
            let m = coll.len() + 1;
            for (c, g) in fast.iter().enumerate() {
                let want = per_pair(&coll, &cells, c);
                let mut worst = 0.0f64;
                for i in 0..m {
                    for j in 0..m {
                        let (a, b) = (g[i * m + j], want[i * m + j]);
                        let scale = (g[i * m + i] * g[j * m + j]).sqrt();
                        worst = worst.max((a - b).abs() / scale);
                        // Symmetric to rounding (the cosine matrix averages both halves).
                        let asym = (g[i * m + j] - g[j * m + i]).abs() / scale;
                        assert!(asym <= 1e-14, "({i}, {j}) asymmetric by {asym:e}");
                    }
                }
                assert!(
                    worst <= 1e-12,
                    "stride {stride}, channel {c}: {worst:e} relative"
                );
            }
        }
    }

    #[test]
    fn per_channel_weights_give_each_channel_its_own_closed_form() {
        // Three different weightings of the same cells (as SPEC 11's shared weights are):
        // each channel's matrix equals the per-pair definition under its own weights.
        let coll = Collection::embedded_default();
        let p = crate::fit::FitParams {
            stride: 3,
            ..crate::fit::FitParams::default()
        };
        let all: Vec<usize> = (0..coll.len()).collect();
        let cells = crate::fit::fit_cells(&coll, &all, &p).expect("cells");
        let per: [CellSet; 3] = std::array::from_fn(|c| {
            let mut w = cells.clone();
            for (s, x) in w.weights.iter_mut().enumerate() {
                *x *= 1.0 + ((s * (c + 3)) % 11) as f64 / (c + 1) as f64;
            }
            w
        });
        let fast = analytic_grams_weighted(&coll, [&per[0], &per[1], &per[2]]);
        let m = coll.len() + 1;
        for (c, g) in fast.iter().enumerate() {
            let want = per_pair(&coll, &per[c], c);
            for i in 0..m {
                for j in 0..m {
                    let scale = (want[i * m + i] * want[j * m + j]).sqrt();
                    let d = (g[i * m + j] - want[i * m + j]).abs() / scale;
                    assert!(d <= 1e-12, "channel {c} ({i}, {j}): {d:e} relative");
                }
            }
        }
        // One cell set for all three: the shared-kernel path, the same numbers.
        let one = analytic_grams_weighted(&coll, [&per[1], &per[1], &per[1]]);
        let apart = analytic_grams_weighted(&coll, [&per[1], &per[1].clone(), &per[1].clone()]);
        assert_eq!(one, apart);
    }

    #[test]
    fn cross_upper_matches_naive_products() {
        for n in [1, 5, 8, 11] {
            let m = n + 1;
            let z: Vec<f64> = (0..n * LEN).map(|i| ((i * 37 % 11) as f64) - 4.0).collect();
            let w: Vec<f64> = (0..n * LEN).map(|i| ((i * 13 % 7) as f64) + 0.5).collect();
            let mut g = vec![0.0; m * m];
            cross_upper(&z, &w, n, &mut g[m..], m);
            mirror_upper(&mut g, m);
            for a in 0..n {
                for b in 0..n {
                    let (lo, hi) = (a.min(b), a.max(b));
                    let mut naive = 0.0;
                    for e in 0..LEN {
                        naive += z[lo * LEN + e] * w[hi * LEN + e];
                    }
                    assert_eq!(g[(a + 1) * m + b + 1], naive, "n {n} ({a}, {b})");
                }
            }
            assert!((0..m).all(|k| g[k] == 0.0 && g[k * m] == 0.0));
        }
    }
}
