//! The weighted systems of one chunk of cells as matrix products (issue 48): with `P` the
//! cell-major products `f_i f_j` of the columns (`i <= j`, the upper triangle's order), `F`
//! the cell-major columns, and per target `W_t(s)` and `W_t(s) y_t(s)`,
//! `G = W P`, `r = (W o Y) F` and `yy_t = sum_s (W_t y_t)(s) y_t(s)`.
//!
//! Every value is one f64 fused multiply-add chain over the cells in their order
//! (`acc = fma(left, right, acc)`, starting from the running value of the previous
//! chunks), whatever the tile, the block or the thread that computes it: the result does
//! not depend on the number of threads, the chunking or the processor (the AVX2 and
//! portable kernels give the same bits; a unit test holds them to it). Against the
//! scalar loop it replaced (`W f_i` times `f_j`, added, with no fusing) each term rounds
//! once or twice differently: the systems differ by a few units in the last place of the
//! sums, far inside [`super::WEIGHTED_TOLERANCE`] (the unit tests bound it at 1e-12,
//! relative to the sum of the terms' magnitudes).
//!
//! Work is cache-blocked: per task of a few targets, blocks of [`BLOCK`] cells whose `P`
//! rows (and the task's `W` rows) stay in L2, tiles of four targets by eight (`G` and
//! `r`) columns held in registers, so that the loop is one broadcast per target
//! and one load per four columns for every four-by-four fused multiply-adds: the products
//! run near the machine's FMA peak, where the scalar form stored every sum to memory after
//! each cell.

#[cfg(test)]
use super::cos_theta_i;
use super::{TargetWeight, WeightedSystems};

/// Cells per cache block.
const BLOCK: usize = 128;
/// Targets per register tile.
const TT: usize = 4;
/// Columns per `G` tile and per `r` tile: two vectors of four f64 (with four targets,
/// eight accumulators, two row vectors and a broadcast: eleven of AVX2's sixteen
/// registers; three vectors, sixteen with nothing left, ran 1.3x slower).
const G_COLS: usize = 8;
/// Columns per `r` tile.
const R_COLS: usize = 8;
/// Cells per task of the chunk's F and P rows.
const PREP_CELLS: usize = 1024;

/// `n` rounded up to a multiple of `k`.
fn round_up(n: usize, k: usize) -> usize {
    n.div_ceil(k) * k
}

/// One chunk of cells `cc` (weights `cw`) added to every target's sums `values`
/// ([`WeightedSystems`] layout, `m` columns): `b` the basis rows and `y` the target rows at
/// the chunk's cells (lobe-major, f32).
pub(super) fn accumulate_chunk(
    values: &mut [f64],
    m: usize,
    b: &[f32],
    y: &[f32],
    cc: &[u32],
    cw: &[f64],
    weight: TargetWeight,
) {
    let n = cc.len();
    if n == 0 || values.is_empty() {
        return;
    }
    let nq = m * (m + 1) / 2;
    let (qpad, fpad) = (round_up(nq, G_COLS), round_up(m, R_COLS));
    let lambert = std::f32::consts::FRAC_1_PI as f64;
    // Only the log objective's weights depend on the incoming cosine.
    let cos_i: Vec<f64> = if weight == TargetWeight::Log {
        cc.iter().map(|&c| cos_theta_i_fast(c as usize)).collect()
    } else {
        Vec::new()
    };
    // Cell-major columns F (the Lambertian column first) and their products P, zero-padded,
    // in buffers kept by the calling thread from chunk to chunk (P is megabytes a chunk: a
    // fresh one cost a page fault and a clearing per page, about 5 % of a cross-validation
    // of networks). Every value, padding included, is written below, by tasks of
    // [`PREP_CELLS`] cells (each product is exact: two f32 in f64).
    let (mut f, mut p) = SCRATCH.with(|s| std::mem::take(&mut *s.borrow_mut()));
    f.resize(n * fpad, 0.0);
    p.resize(n * qpad, 0.0);
    {
        use rayon::prelude::*;
        f.par_chunks_mut(PREP_CELLS * fpad)
            .zip(p.par_chunks_mut(PREP_CELLS * qpad))
            .enumerate()
            .for_each(|(task, (ft, pt))| {
                for (i, (fr, pr)) in ft
                    .chunks_exact_mut(fpad)
                    .zip(pt.chunks_exact_mut(qpad))
                    .enumerate()
                {
                    let c = task * PREP_CELLS + i;
                    fr[0] = lambert;
                    for j in 1..m {
                        fr[j] = b[(j - 1) * n + c] as f64;
                    }
                    fr[m..].fill(0.0);
                    let mut q = 0;
                    for i in 0..m {
                        let (a, row) = (fr[i], &fr[i..m]);
                        for (o, &v) in pr[q..q + row.len()].iter_mut().zip(row) {
                            *o = a * v;
                        }
                        q += row.len();
                    }
                    pr[q..].fill(0.0);
                }
            });
    }
    accumulate_targets(values, m, y, cc, cw, weight, (&f, &p, &cos_i));
    SCRATCH.with(|s| *s.borrow_mut() = (f, p));
}

thread_local! {
    /// [`accumulate_chunk`]'s F and P buffers.
    static SCRATCH: std::cell::RefCell<(Vec<f64>, Vec<f64>)> = const {
        std::cell::RefCell::new((Vec::new(), Vec::new()))
    };
}

/// [`accumulate_chunk`] given the chunk's F, P and cosines.
fn accumulate_targets(
    values: &mut [f64],
    m: usize,
    y: &[f32],
    cc: &[u32],
    cw: &[f64],
    weight: TargetWeight,
    (f, p, cos_i): (&[f64], &[f64], &[f64]),
) {
    use rayon::prelude::*;
    let n = cc.len();
    let stride = WeightedSystems::stride_for(m);
    let targets = values.len() / stride;
    let nq = m * (m + 1) / 2;
    let (qpad, fpad) = (round_up(nq, G_COLS), round_up(m, R_COLS));
    // Tasks of whole tiles: enough of them for the threads, the same result for any size.
    let threads = rayon::current_num_threads().max(1);
    let per_task = round_up(targets.div_ceil(2 * threads), TT).clamp(TT, 8 * TT);
    values
        .par_chunks_mut(stride * per_task)
        .zip(y.par_chunks(n * per_task))
        .for_each(|(v, yt)| {
            let count = v.len() / stride;
            let tiles = count.div_ceil(TT);
            let padded = tiles * TT;
            let width = qpad + fpad;
            // The task's running sums: G (qpad), r (fpad) and yy, per target.
            let mut acc = vec![0f64; padded * width];
            let mut yy = vec![0f64; count];
            for t in 0..count {
                let src = &v[t * stride..(t + 1) * stride];
                acc[t * width..t * width + nq].copy_from_slice(&src[..nq]);
                acc[t * width + qpad..t * width + qpad + m].copy_from_slice(&src[nq..nq + m]);
                yy[t] = src[nq + m];
            }
            let cos_at = |start: usize, len: usize| -> &[f64] {
                if cos_i.is_empty() {
                    &[]
                } else {
                    &cos_i[start..start + len]
                }
            };
            let mut wb = vec![0f64; padded * BLOCK];
            let mut wyb = vec![0f64; padded * BLOCK];
            let mut start = 0;
            while start < n {
                let len = BLOCK.min(n - start);
                for t in 0..count {
                    let yr = &yt[t * n + start..t * n + start + len];
                    let (wr, wyr) = (&mut wb[t * BLOCK..], &mut wyb[t * BLOCK..]);
                    block_weights(
                        weight,
                        yr,
                        &cw[start..start + len],
                        cos_at(start, len),
                        wr,
                        wyr,
                    );
                }
                // `yy` per target, one fused chain over the cells in order; the tile's
                // targets interleaved (independent chains).
                for t0 in (0..count).step_by(TT) {
                    let ts = t0..(t0 + TT).min(count);
                    for c in 0..len {
                        for t in ts.clone() {
                            let yc = yt[t * n + start + c] as f64;
                            yy[t] = wyb[t * BLOCK + c].mul_add(yc, yy[t]);
                        }
                    }
                }
                let pb = &p[start * qpad..(start + len) * qpad];
                let fb = &f[start * fpad..(start + len) * fpad];
                for tile in 0..tiles {
                    let t0 = tile * TT;
                    let tile_acc = &mut acc[t0 * width..(t0 + TT) * width];
                    let (w_rows, wy_rows) = (tile_rows(&wb, t0, len), tile_rows(&wyb, t0, len));
                    for col in (0..qpad).step_by(G_COLS) {
                        tile_kernel::<2>(w_rows, pb, qpad, col, col, tile_acc, width);
                    }
                    for col in (0..fpad).step_by(R_COLS) {
                        tile_kernel::<2>(wy_rows, fb, fpad, col, qpad + col, tile_acc, width);
                    }
                }
                start += len;
            }
            for t in 0..count {
                let dst = &mut v[t * stride..(t + 1) * stride];
                dst[..nq].copy_from_slice(&acc[t * width..t * width + nq]);
                dst[nq..nq + m].copy_from_slice(&acc[t * width + qpad..t * width + qpad + m]);
                dst[nq + m] = yy[t];
            }
        });
}

/// One target's weights at a block of cells: `w = cw phi(y)` and `wy = w y`
/// ([`TargetWeight::phi`]'s operations in its order, so its bits), the loop specialised per
/// objective so that it vectorises; `cos_i` is read by the log objective only.
fn block_weights(
    weight: TargetWeight,
    y: &[f32],
    cw: &[f64],
    cos_i: &[f64],
    w: &mut [f64],
    wy: &mut [f64],
) {
    let out = w.iter_mut().zip(wy.iter_mut());
    match weight {
        TargetWeight::L2 => {
            for ((w, wy), (&yc, &cw)) in out.zip(y.iter().zip(cw)) {
                let yc = yc as f64;
                *w = cw;
                *wy = cw * yc;
            }
        }
        TargetWeight::Relative { eps } => {
            for ((w, wy), (&yc, &cw)) in out.zip(y.iter().zip(cw)) {
                let yc = yc as f64;
                let ym = yc.max(0.0);
                let v = cw * (1.0 / ((ym + eps) * (ym + eps)));
                *w = v;
                *wy = v * yc;
            }
        }
        TargetWeight::Log => {
            for (((w, wy), (&yc, &cw)), &ci) in out.zip(y.iter().zip(cw)).zip(cos_i) {
                let yc = yc as f64;
                let v = cw * weight.phi(yc, ci);
                *w = v;
                *wy = v * yc;
            }
        }
    }
}

/// [`cos_theta_i`] from per-axis tables of the angles' cosines and sines: the same
/// operations on the same values, so the same bits, without five trigonometric calls a
/// cell.
fn cos_theta_i_fast(cell: usize) -> f64 {
    use crate::merl::{phi_d, theta_d, theta_h, N_PD, N_TD, N_TH};
    struct Axes {
        th: Vec<(f64, f64)>,
        td: Vec<(f64, f64)>,
        pd: Vec<f64>,
    }
    static AXES: std::sync::OnceLock<Axes> = std::sync::OnceLock::new();
    let a = AXES.get_or_init(|| Axes {
        th: (0..N_TH)
            .map(|i| (theta_h(i).cos(), theta_h(i).sin()))
            .collect(),
        td: (0..N_TD)
            .map(|j| (theta_d(j).cos(), theta_d(j).sin()))
            .collect(),
        pd: (0..N_PD).map(|k| phi_d(k).cos()).collect(),
    });
    let (i, j, k) = (cell / (N_TD * N_PD), (cell / N_PD) % N_TD, cell % N_PD);
    let ((cth, sth), (ctd, std_), cpd) = (a.th[i], a.td[j], a.pd[k]);
    cth * ctd - sth * std_ * cpd
}

/// The first `len` values of the [`BLOCK`]-long rows of the tile's targets `t0..t0 + TT`.
fn tile_rows(buf: &[f64], t0: usize, len: usize) -> [&[f64]; TT] {
    std::array::from_fn(|i| &buf[(t0 + i) * BLOCK..(t0 + i) * BLOCK + len])
}

/// `acc[t][at + j] = fma(left[t][c], right[c][col + j], acc[t][at + j])` over the cells
/// `c` in order, for the four targets `t` and `4 NV` columns `j`: `right` is cell-major
/// with `rs` values per cell, `acc` four rows of `width` values. The AVX2 kernel where the processor has it, else the portable one:
/// the same bits.
fn tile_kernel<const NV: usize>(
    left: [&[f64]; TT],
    right: &[f64],
    rs: usize,
    col: usize,
    at: usize,
    acc: &mut [f64],
    width: usize,
) {
    let len = left[0].len();
    assert!(
        left.iter().all(|l| l.len() == len)
            && right.len() >= len * rs
            && col + 4 * NV <= rs
            && acc.len() >= (TT - 1) * width + at + 4 * NV,
        "tile_kernel: operands out of shape"
    );
    #[cfg(target_arch = "x86_64")]
    {
        if use_avx2() {
            // SAFETY: AVX2 and FMA are present (checked); the shapes were checked above.
            unsafe { tile_avx2::<NV>(left, right, rs, col, at, acc, width) };
            return;
        }
    }
    tile_portable::<NV>(left, right, rs, col, at, acc, width);
}

/// Whether the AVX2 kernel runs (the processor has AVX2 and FMA, and no test asked this
/// thread for the portable one).
fn use_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        !PORTABLE_ONLY.with(|c| c.get())
            && std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

thread_local! {
    /// Set by tests: this thread runs the portable kernel.
    pub(super) static PORTABLE_ONLY: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// The portable kernel ([`tile_kernel`]): `f64::mul_add` is the same correctly rounded
/// fused multiply-add as the AVX2 instruction.
fn tile_portable<const NV: usize>(
    left: [&[f64]; TT],
    right: &[f64],
    rs: usize,
    col: usize,
    at: usize,
    acc: &mut [f64],
    width: usize,
) {
    let len = left[0].len();
    let mut a = [[[0f64; 4]; NV]; TT];
    for (t, at_t) in a.iter_mut().enumerate() {
        for (v, lane) in at_t.iter_mut().enumerate() {
            lane.copy_from_slice(&acc[t * width + at + 4 * v..t * width + at + 4 * v + 4]);
        }
    }
    for c in 0..len {
        let r = &right[c * rs + col..c * rs + col + 4 * NV];
        for (t, at_t) in a.iter_mut().enumerate() {
            let l = left[t][c];
            for (v, lane) in at_t.iter_mut().enumerate() {
                for (k, x) in lane.iter_mut().enumerate() {
                    *x = l.mul_add(r[4 * v + k], *x);
                }
            }
        }
    }
    for (t, at_t) in a.iter().enumerate() {
        for (v, lane) in at_t.iter().enumerate() {
            acc[t * width + at + 4 * v..t * width + at + 4 * v + 4].copy_from_slice(lane);
        }
    }
}

/// The AVX2 kernel ([`tile_kernel`]): the four targets' `4 NV` running sums in registers.
///
/// # Safety
/// The processor has AVX2 and FMA; the shapes are [`tile_kernel`]'s (checked there).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn tile_avx2<const NV: usize>(
    left: [&[f64]; TT],
    right: &[f64],
    rs: usize,
    col: usize,
    at: usize,
    acc: &mut [f64],
    width: usize,
) {
    use std::arch::x86_64::*;
    let len = left[0].len();
    let ap = acc.as_mut_ptr();
    let mut a = [[_mm256_setzero_pd(); NV]; TT];
    for (t, at_t) in a.iter_mut().enumerate() {
        for (v, x) in at_t.iter_mut().enumerate() {
            *x = _mm256_loadu_pd(ap.add(t * width + at + 4 * v));
        }
    }
    let rp = right.as_ptr().add(col);
    let lp: [*const f64; TT] = std::array::from_fn(|t| left[t].as_ptr());
    for c in 0..len {
        let row = rp.add(c * rs);
        let r: [__m256d; NV] = std::array::from_fn(|v| _mm256_loadu_pd(row.add(4 * v)));
        for (t, at_t) in a.iter_mut().enumerate() {
            let l = _mm256_broadcast_sd(&*lp[t].add(c));
            for (v, x) in at_t.iter_mut().enumerate() {
                *x = _mm256_fmadd_pd(l, r[v], *x);
            }
        }
    }
    for (t, at_t) in a.iter().enumerate() {
        for (v, x) in at_t.iter().enumerate() {
            _mm256_storeu_pd(ap.add(t * width + at + 4 * v), *x);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reproducible stream of values in `[lo, lo + span)`.
    fn values(seed: u64, count: usize, lo: f64, span: f64) -> Vec<f64> {
        let mut s = seed;
        (0..count)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                lo + span * ((s >> 11) as f64 / (1u64 << 53) as f64)
            })
            .collect()
    }

    /// The AVX2 and portable kernels give the same bits (where the processor has AVX2;
    /// elsewhere both calls run the portable one), for both tile widths.
    #[test]
    fn avx2_and_portable_kernels_give_the_same_bits() {
        let (len, rs, width) = (97, 40, 52);
        let left_v: Vec<Vec<f64>> = (0..TT)
            .map(|t| values(t as u64 + 1, len, -2.0, 5.0))
            .collect();
        let left: [&[f64]; TT] = std::array::from_fn(|t| &left_v[t][..]);
        let right = values(99, len * rs, -1.0, 3.0);
        let start = values(7, TT * width, -10.0, 20.0);
        for (col, at) in [(0, 0), (24, 36), (28, 40)] {
            let run = |portable: bool| {
                PORTABLE_ONLY.with(|c| c.set(portable));
                let mut a3 = start.clone();
                let mut a2 = start.clone();
                tile_kernel::<3>(left, &right, rs, col, at, &mut a3, width);
                tile_kernel::<2>(left, &right, rs, col, at, &mut a2, width);
                PORTABLE_ONLY.with(|c| c.set(false));
                (a3, a2)
            };
            let (fast, slow) = (run(false), run(true));
            assert_eq!(fast, slow, "col {col}, at {at}");
            assert_ne!(fast.0, start);
            // And the portable kernel is the plain fused chain.
            let mut want = start.clone();
            for c in 0..len {
                for t in 0..TT {
                    for j in 0..12 {
                        let x = &mut want[t * width + at + j];
                        *x = left[t][c].mul_add(right[c * rs + col + j], *x);
                    }
                }
            }
            assert_eq!(slow.0, want);
        }
    }

    /// The tabulated incoming cosine is `cos_theta_i`'s bits on every cell of the grid.
    #[test]
    fn the_tabulated_incoming_cosine_is_the_direct_one_on_every_cell() {
        let cells = crate::merl::N_TH * crate::merl::N_TD * crate::merl::N_PD;
        for c in 0..cells {
            assert_eq!(
                cos_theta_i_fast(c).to_bits(),
                cos_theta_i(c).to_bits(),
                "cell {c}"
            );
        }
    }

    /// The block's weights are `cw * phi(y)` to the bit for every objective, NaN-free
    /// values and zeros and negatives included.
    #[test]
    fn block_weights_are_phi_to_the_bit() {
        let n = 301;
        let y: Vec<f32> = values(11, n, -0.5, 40.0)
            .iter()
            .enumerate()
            .map(|(i, &v)| if i % 17 == 0 { 0.0 } else { v as f32 })
            .collect();
        let cw = values(12, n, 1e-7, 1e-3);
        let cos_i: Vec<f64> = (0..n).map(|c| cos_theta_i(1_000 + 4_099 * c)).collect();
        for weight in [
            TargetWeight::L2,
            TargetWeight::Relative { eps: 0.01 },
            TargetWeight::Relative { eps: 3e-4 },
            TargetWeight::Log,
        ] {
            let (mut w, mut wy) = (vec![0f64; n], vec![0f64; n]);
            block_weights(weight, &y, &cw, &cos_i, &mut w, &mut wy);
            for c in 0..n {
                let yc = y[c] as f64;
                let want = cw[c] * weight.phi(yc, cos_i[c]);
                assert_eq!(w[c].to_bits(), want.to_bits(), "{weight:?} cell {c}");
                assert_eq!(
                    wy[c].to_bits(),
                    (want * yc).to_bits(),
                    "{weight:?} cell {c}"
                );
            }
        }
    }

    /// The sums do not depend on how many threads (hence tasks and tiles) compute them.
    #[test]
    fn the_sums_are_the_same_bits_on_one_thread_and_on_many() {
        let (m, n, targets) = (6, 3 * BLOCK + 17, 11);
        let b: Vec<f32> = values(3, (m - 1) * n, 0.0, 2.0)
            .iter()
            .map(|&v| v as f32)
            .collect();
        let y: Vec<f32> = values(5, targets * n, 0.0, 4.0)
            .iter()
            .map(|&v| v as f32)
            .collect();
        let cc: Vec<u32> = (0..n as u32).map(|c| 37 * c + 1000).collect();
        let cw = values(9, n, 0.1, 1.0);
        let stride = WeightedSystems::stride_for(m);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut v = vec![0.5f64; targets * stride];
            pool.install(|| {
                for part in [0..n / 2, n / 2..n] {
                    let bs: Vec<f32> = (0..m - 1)
                        .flat_map(|j| b[j * n + part.start..j * n + part.end].to_vec())
                        .collect();
                    let ys: Vec<f32> = (0..targets)
                        .flat_map(|t| y[t * n + part.start..t * n + part.end].to_vec())
                        .collect();
                    let w = TargetWeight::Relative { eps: 0.01 };
                    accumulate_chunk(&mut v, m, &bs, &ys, &cc[part.clone()], &cw[part], w);
                }
            });
            v
        };
        let one = run(1);
        assert_eq!(one, run(2));
        assert_eq!(one, run(7));
        assert!(one.iter().all(|v| v.is_finite() && *v > 0.5));
    }
}
#[cfg(test)]
mod rate {
    use super::*;
    #[test]
    #[ignore]
    fn gemm_rate() {
        let (m, n, targets) = (13usize, 1usize << 14, 20usize);
        let b: Vec<f32> = (0..(m - 1) * n)
            .map(|i| ((i * 7919) % 1000) as f32 * 0.001 + 0.01)
            .collect();
        let y: Vec<f32> = (0..targets * n)
            .map(|i| ((i * 104729) % 1000) as f32 * 0.002 + 0.01)
            .collect();
        let cc: Vec<u32> = (0..n as u32).map(|c| 37 * c + 1000).collect();
        let cw = vec![1e-6; n];
        let stride = WeightedSystems::stride_for(m);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let mut v = vec![0f64; targets * stride];
        let w = TargetWeight::Relative { eps: 0.01 };
        pool.install(|| {
            for _ in 0..3 {
                accumulate_chunk(&mut v, m, &b, &y, &cc, &cw, w);
            }
            let s = (0..40)
                .map(|_| {
                    let t = std::time::Instant::now();
                    accumulate_chunk(&mut v, m, &b, &y, &cc, &cw, w);
                    t.elapsed().as_secs_f64()
                })
                .fold(f64::INFINITY, f64::min);
            let nq = m * (m + 1) / 2;
            let lanes = (targets * n * (round_up(nq, G_COLS) + round_up(m, R_COLS))) as f64;
            eprintln!(
                "RATE {:.2} ms per chunk, {:.2} G FMA lanes/s ({:.2} G useful)",
                s * 1e3,
                lanes / s / 1e9,
                (targets * n * (nq + m)) as f64 / s / 1e9
            );
        });
    }
}
