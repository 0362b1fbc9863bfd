//! The CPU back-end: rayon over materials and block pairs, blocked loops with AVX2 (chosen
//! at run time, portable code otherwise). It is also the reference twin of every GPU
//! kernel in the tests.
//!
//! Analytic lobes are tabulated from factors: on the grid
//! `rho_s = (n + 1) / (8 pi) * P[i] * F[j] / (cos theta_d max(N.wi, N.wo))` with
//! `P[i] = (cos theta_h)^n` and `F[j]` the Fresnel term, so each lobe needs 180
//! exponentials and powers, not one per cell; everything is f64, rounded once to f32.

use super::blocks::{add_block, PairOp, BLOCK};
use super::{Backend, Lobe, LobeParams, Progress};
use crate::error::BackendError;
use crate::merl::grid::{unflat, N_TD, N_TH};
use crate::merl::{CellSet, GridTables};
use crate::separable::SeparableLobe;
use rayon::prelude::*;

/// Cells per streamed chunk: a row of a chunk is 16 KiB, so the 6 rows a 4 x 2 sub-block
/// streams stay in L2 while the block pairs of the chunk reuse them.
pub const CHUNK_CELLS: usize = 4096;
/// Cells accumulated in f32 before the partial sum is added to f64.
pub const F32_RUN: usize = 1024;

/// The CPU back-end.
#[derive(Debug)]
pub struct CpuBackend {
    tables: GridTables,
    pool: Option<rayon::ThreadPool>,
}

impl Default for CpuBackend {
    fn default() -> Self {
        Self::new()
    }
}

/// Per-lobe factors of an analytic lobe on the grid.
struct Factors {
    kd: f64,
    coef: f64,
    p: [f64; N_TH],
    f: [f64; N_TD],
}

impl Factors {
    fn new(t: &GridTables, l: &LobeParams) -> Self {
        let (f0, n) = (l.f0 as f64, l.n as f64);
        let mut p = [0.0; N_TH];
        let mut f = [0.0; N_TD];
        for (p, &ln) in p.iter_mut().zip(&t.ln_cos_h) {
            *p = (n * ln).exp();
        }
        for (f, &s) in f.iter_mut().zip(&t.schlick_d) {
            *f = f0 + (1.0 - f0) * s;
        }
        let coef = l.ks as f64 * (n + 1.0) / (8.0 * std::f64::consts::PI);
        Self {
            kd: l.kd as f64 * std::f64::consts::FRAC_1_PI,
            coef,
            p,
            f,
        }
    }
}

impl CpuBackend {
    /// A back-end on rayon's global pool.
    pub fn new() -> Self {
        Self {
            tables: GridTables::new(),
            pool: None,
        }
    }

    /// A back-end on its own pool of `threads` threads.
    pub fn with_threads(threads: usize) -> Result<Self, BackendError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .build()
            .map_err(|e| BackendError::Invalid(format!("cannot start {threads} threads: {e}")))?;
        Ok(Self {
            tables: GridTables::new(),
            pool: Some(pool),
        })
    }

    fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.pool {
            Some(p) => p.install(f),
            None => f(),
        }
    }

    /// Threads used.
    pub fn threads(&self) -> usize {
        self.pool
            .as_ref()
            .map_or_else(rayon::current_num_threads, |p| p.current_num_threads())
    }

    /// Tabulates one lobe over `cells` in f64 (the reference values of every reduction).
    pub fn values_f64(&self, lobe: &Lobe, cells: &[u32]) -> Vec<f64> {
        let t = &self.tables;
        match lobe {
            Lobe::Analytic(p) => {
                let fa = Factors::new(t, p);
                cells
                    .iter()
                    .map(|&cell| {
                        let (i, j, k) = unflat(cell as usize);
                        fa.kd + fa.coef * fa.p[i] * fa.f[j] / (t.cos_d[j] * t.max_cos(i, j, k))
                    })
                    .collect()
            }
            Lobe::Measured { .. } => cells
                .iter()
                .map(|&c| lobe.eval_f64(t, c as usize))
                .collect(),
        }
    }

    /// Tabulates one lobe over `cells` into `out`, each value times `scale[c]` if given.
    pub fn tabulate_into(
        &self,
        lobe: &Lobe,
        cells: &[u32],
        scale: Option<&[f64]>,
        out: &mut [f32],
    ) {
        let t = &self.tables;
        match lobe {
            Lobe::Analytic(p) => {
                let fa = Factors::new(t, p);
                for (c, (&cell, o)) in cells.iter().zip(out.iter_mut()).enumerate() {
                    let (i, j, k) = unflat(cell as usize);
                    let g = 1.0 / (t.cos_d[j] * t.max_cos(i, j, k));
                    let v = fa.kd + fa.coef * fa.p[i] * fa.f[j] * g;
                    *o = (scale.map_or(1.0, |s| s[c]) * v) as f32;
                }
            }
            Lobe::Measured { .. } => {
                for (c, (&cell, o)) in cells.iter().zip(out.iter_mut()).enumerate() {
                    *o = (scale.map_or(1.0, |s| s[c]) * lobe.eval_f64(t, cell as usize)) as f32;
                }
            }
        }
    }
}

/// Portable kernel: `acc[r][q] += sum_c op(a_r(c), b_q(c))`, f32 runs of [`F32_RUN`] cells
/// added into f64.
fn block_portable<const DOT: bool>(
    a: [&[f32]; BLOCK],
    b: [&[f32]; BLOCK],
    acc: &mut [[f64; BLOCK]; BLOCK],
) {
    let len = a[0].len();
    for start in (0..len).step_by(F32_RUN) {
        let end = (start + F32_RUN).min(len);
        for r in 0..BLOCK {
            for q in 0..BLOCK {
                let mut s = [0f32; 8];
                let (ar, bq) = (&a[r][start..end], &b[q][start..end]);
                let (ac, bc) = (ar.chunks_exact(8), bq.chunks_exact(8));
                let (at, bt) = (ac.remainder(), bc.remainder());
                for (x, y) in ac.zip(bc) {
                    for l in 0..8 {
                        s[l] += if DOT {
                            x[l] * y[l]
                        } else {
                            (x[l] - y[l]).abs()
                        };
                    }
                }
                let mut t: f32 = s.iter().sum();
                for (x, y) in at.iter().zip(bt) {
                    t += if DOT { x * y } else { (x - y).abs() };
                }
                acc[r][q] += t as f64;
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{BLOCK, F32_RUN};
    use std::arch::x86_64::*;

    /// Sum of the 8 lanes.
    #[inline(always)]
    unsafe fn hsum(v: __m256) -> f32 {
        let mut o = [0f32; 8];
        _mm256_storeu_ps(o.as_mut_ptr(), v);
        o.iter().sum()
    }

    /// AVX2 kernel over a 4 x 4 block as two 4 x 2 passes (8 accumulators, 4 + 1 row
    /// registers and the sign mask: no spills).
    ///
    /// # Safety
    /// The processor must support AVX2 and FMA; all rows must have one length.
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn block<const DOT: bool>(
        a: [&[f32]; BLOCK],
        b: [&[f32]; BLOCK],
        acc: &mut [[f64; BLOCK]; BLOCK],
    ) {
        let len = a[0].len();
        let vec_len = len / 8 * 8;
        let sign = _mm256_set1_ps(-0.0);
        for half in 0..2 {
            let (q0, q1) = (2 * half, 2 * half + 1);
            let mut start = 0;
            while start < vec_len {
                let end = (start + F32_RUN).min(vec_len);
                let mut s = [_mm256_setzero_ps(); 8];
                let mut c = start;
                while c < end {
                    let a0 = _mm256_loadu_ps(a[0].as_ptr().add(c));
                    let a1 = _mm256_loadu_ps(a[1].as_ptr().add(c));
                    let a2 = _mm256_loadu_ps(a[2].as_ptr().add(c));
                    let a3 = _mm256_loadu_ps(a[3].as_ptr().add(c));
                    for (k, q) in [q0, q1].into_iter().enumerate() {
                        let bv = _mm256_loadu_ps(b[q].as_ptr().add(c));
                        if DOT {
                            s[4 * k] = _mm256_fmadd_ps(a0, bv, s[4 * k]);
                            s[4 * k + 1] = _mm256_fmadd_ps(a1, bv, s[4 * k + 1]);
                            s[4 * k + 2] = _mm256_fmadd_ps(a2, bv, s[4 * k + 2]);
                            s[4 * k + 3] = _mm256_fmadd_ps(a3, bv, s[4 * k + 3]);
                        } else {
                            s[4 * k] = _mm256_add_ps(
                                s[4 * k],
                                _mm256_andnot_ps(sign, _mm256_sub_ps(a0, bv)),
                            );
                            s[4 * k + 1] = _mm256_add_ps(
                                s[4 * k + 1],
                                _mm256_andnot_ps(sign, _mm256_sub_ps(a1, bv)),
                            );
                            s[4 * k + 2] = _mm256_add_ps(
                                s[4 * k + 2],
                                _mm256_andnot_ps(sign, _mm256_sub_ps(a2, bv)),
                            );
                            s[4 * k + 3] = _mm256_add_ps(
                                s[4 * k + 3],
                                _mm256_andnot_ps(sign, _mm256_sub_ps(a3, bv)),
                            );
                        }
                    }
                    c += 8;
                }
                for k in 0..2 {
                    for r in 0..4 {
                        acc[r][[q0, q1][k]] += hsum(s[4 * k + r]) as f64;
                    }
                }
                start = end;
            }
        }
        for r in 0..BLOCK {
            for q in 0..BLOCK {
                let mut t = 0f32;
                for c in vec_len..len {
                    t += if DOT {
                        a[r][c] * b[q][c]
                    } else {
                        (a[r][c] - b[q][c]).abs()
                    };
                }
                acc[r][q] += t as f64;
            }
        }
    }
}

/// `acc[r][q] += sum_c op(a_r(c), b_q(c))` with the fastest code path of this processor.
///
/// Every row of `a` and `b` must have the same length; otherwise nothing is added and an
/// error names the lengths (the vector kernel reads every row up to the first row's
/// length).
pub fn block_reduce(
    op: PairOp,
    a: [&[f32]; BLOCK],
    b: [&[f32]; BLOCK],
    acc: &mut [[f64; BLOCK]; BLOCK],
) -> Result<(), BackendError> {
    let len = a[0].len();
    if a.iter().chain(&b).any(|r| r.len() != len) {
        let lens = |rows: &[&[f32]; BLOCK]| rows.map(|r| r.len());
        return Err(BackendError::Invalid(format!(
            "block_reduce: rows of one length needed, found a: {:?}, b: {:?}",
            lens(&a),
            lens(&b)
        )));
    }
    block_reduce_same_len(op, a, b, acc);
    Ok(())
}

/// [`block_reduce`] for rows already known to share one length.
fn block_reduce_same_len(
    op: PairOp,
    a: [&[f32]; BLOCK],
    b: [&[f32]; BLOCK],
    acc: &mut [[f64; BLOCK]; BLOCK],
) {
    debug_assert!(a.iter().chain(&b).all(|r| r.len() == a[0].len()));
    #[cfg(target_arch = "x86_64")]
    {
        if is_avx2() {
            // SAFETY: AVX2 and FMA were detected on this processor; the callers
            // (`block_reduce` checks, `reduce_pairs` slices one buffer into rows of one
            // length) pass rows of one length.
            unsafe {
                match op {
                    PairOp::L1 => avx2::block::<false>(a, b, acc),
                    PairOp::Dot => avx2::block::<true>(a, b, acc),
                }
            }
            return;
        }
    }
    match op {
        PairOp::L1 => block_portable::<false>(a, b, acc),
        PairOp::Dot => block_portable::<true>(a, b, acc),
    }
}

impl Backend for CpuBackend {
    fn name(&self) -> String {
        let simd = if is_avx2() { "avx2" } else { "portable" };
        format!("cpu ({} threads, {simd})", self.threads())
    }

    fn tabulate(&self, lobes: &[Lobe], cells: &[u32]) -> Result<Vec<f32>, BackendError> {
        let mut out = vec![0f32; lobes.len() * cells.len()];
        if cells.is_empty() {
            return Ok(out);
        }
        self.install(|| {
            out.par_chunks_mut(cells.len())
                .zip(lobes.par_iter())
                .for_each(|(row, lobe)| {
                    row.par_chunks_mut(1 << 16)
                        .zip(cells.par_chunks(1 << 16))
                        .for_each(|(o, c)| self.tabulate_into(lobe, c, None, o));
                })
        });
        Ok(out)
    }

    fn reduce_pairs(
        &self,
        lobes: &[Lobe],
        cells: &CellSet,
        blocks: &[[u32; 2]],
        op: PairOp,
        progress: Progress<'_>,
    ) -> Result<Vec<f64>, BackendError> {
        let n = lobes.len();
        let n_pad = n.div_ceil(BLOCK) * BLOCK;
        let mut out = vec![0f64; n * n];
        let mut sums = vec![[[0f64; BLOCK]; BLOCK]; blocks.len()];
        let mut buf = vec![0f32; n_pad * CHUNK_CELLS];
        // Analytic lobes in separable form (alpha + G(c) beta[i][j], f64), built once: a
        // value is then one multiply-add per cell.
        let seps: Vec<Option<SeparableLobe>> = self.install(|| {
            lobes
                .par_iter()
                .map(|l| match l {
                    Lobe::Analytic(p) => Some(SeparableLobe::new(&self.tables, p)),
                    Lobe::Measured { .. } => None,
                })
                .collect()
        });
        let total = cells.len() as u64;
        let mut done = 0u64;
        for (cc, cw) in cells
            .cells
            .chunks(CHUNK_CELLS)
            .zip(cells.weights.chunks(CHUNK_CELLS))
        {
            let len = cc.len();
            let scale: Vec<f64> = cw.iter().map(|&w| op.row_scale(w)).collect();
            // Per cell: (i * 90 + j, G(c) x row scale).
            let factors: Vec<(usize, f64)> = cc
                .iter()
                .zip(&scale)
                .map(|(&c, &s)| {
                    let (e, g) = self.tables.cell_factor(c as usize);
                    (e, g * s)
                })
                .collect();
            self.install(|| {
                buf[..n * len]
                    .par_chunks_mut(len)
                    .zip(lobes.par_iter().zip(&seps))
                    .for_each(|(row, (lobe, sep))| match sep {
                        Some(sp) => {
                            for ((o, &(e, g)), &s) in row.iter_mut().zip(&factors).zip(&scale) {
                                *o = (sp.alpha * s + sp.beta[e] * g) as f32;
                            }
                        }
                        None => self.tabulate_into(lobe, cc, Some(&scale), row),
                    });
                buf[n * len..n_pad * len].fill(0.0);
                let rows: Vec<&[f32]> = buf[..n_pad * len].chunks(len).collect();
                sums.par_iter_mut()
                    .zip(blocks.par_iter())
                    .for_each(|(acc, &[bi, bj])| {
                        let a = std::array::from_fn(|r| rows[bi as usize * BLOCK + r]);
                        let b = std::array::from_fn(|q| rows[bj as usize * BLOCK + q]);
                        block_reduce_same_len(op, a, b, acc);
                    });
            });
            done += len as u64;
            progress(done, total);
        }
        for (acc, &b) in sums.iter().zip(blocks) {
            add_block(&mut out, n, b, |r, q| acc[r][q]);
        }
        Ok(out)
    }
}

fn is_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn avx2_and_portable_kernels_agree_with_a_hand_sum() {
        let rows: Vec<Vec<f32>> = (0..8)
            .map(|r| {
                (0..1037)
                    .map(|c| ((r * 31 + c * 7) % 13) as f32 - 6.0)
                    .collect()
            })
            .collect();
        let a: [&[f32]; BLOCK] = std::array::from_fn(|r| rows[r].as_slice());
        let b: [&[f32]; BLOCK] = std::array::from_fn(|q| rows[4 + q].as_slice());
        for op in [PairOp::L1, PairOp::Dot] {
            let mut fast = [[0f64; BLOCK]; BLOCK];
            block_reduce(op, a, b, &mut fast).expect("same lengths");
            let mut port = [[0f64; BLOCK]; BLOCK];
            match op {
                PairOp::L1 => block_portable::<false>(a, b, &mut port),
                PairOp::Dot => block_portable::<true>(a, b, &mut port),
            }
            for r in 0..BLOCK {
                for q in 0..BLOCK {
                    let want: f64 = a[r]
                        .iter()
                        .zip(b[q])
                        .map(|(&x, &y)| {
                            if op == PairOp::Dot {
                                x as f64 * y as f64
                            } else {
                                (x as f64 - y as f64).abs()
                            }
                        })
                        .sum();
                    // Small integers: every partial sum is exact in f32.
                    assert_eq!(fast[r][q], want, "{op:?} {r} {q}");
                    assert_eq!(port[r][q], want, "{op:?} {r} {q}");
                }
            }
        }
    }

    #[test]
    fn rows_of_different_lengths_are_an_error_not_a_read_past_the_end() {
        let long = vec![1f32; 4096];
        let short = vec![2f32; 8];
        for op in [PairOp::L1, PairOp::Dot] {
            for bad in 0..2 * BLOCK {
                let rows: [&[f32]; 2 * BLOCK] =
                    std::array::from_fn(|i| if i == bad { &short[..] } else { &long[..] });
                let (a, b) = (
                    std::array::from_fn(|r| rows[r]),
                    std::array::from_fn(|q| rows[BLOCK + q]),
                );
                let mut acc = [[0f64; BLOCK]; BLOCK];
                let err = block_reduce(op, a, b, &mut acc).unwrap_err();
                assert!(err.to_string().contains("4096") && err.to_string().contains('8'));
                assert_eq!(acc, [[0f64; BLOCK]; BLOCK], "nothing added");
            }
        }
        // Rows of one length, even empty ones, are fine.
        let mut acc = [[0f64; BLOCK]; BLOCK];
        block_reduce(PairOp::L1, [&[][..]; BLOCK], [&[][..]; BLOCK], &mut acc).expect("empty");
    }
}
