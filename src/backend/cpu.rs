//! The CPU back-end: rayon over materials and block pairs, blocked loops that vectorise
//! (AVX2 when the processor has it, chosen at run time). It is also the reference twin of
//! every GPU kernel in the tests.

use super::{condensed_index, condensed_len, Backend, Lobe, Progress};
use crate::error::BackendError;
use crate::merl::grid::unflat;
use crate::merl::{CellSet, GridTables};
use rayon::prelude::*;

/// Cells per streamed chunk: a row of a chunk is 32 KiB, so a 4 x 4 block's 8 rows stay
/// in L2.
pub const CHUNK_CELLS: usize = 8192;
/// Cells accumulated in f32 before the partial sum is added to f64.
pub const F32_RUN: usize = 1024;
/// Block size (rows and columns of material pairs per task).
pub const BLOCK: usize = 4;

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

    /// Tabulates one lobe over `cells` into `out`, multiplying by `weights` when given.
    /// Analytic lobes are evaluated in f64 and rounded once to f32.
    pub fn tabulate_into(
        &self,
        lobe: &Lobe,
        cells: &[u32],
        weights: Option<&[f64]>,
        out: &mut [f32],
    ) {
        let t = &self.tables;
        match lobe {
            Lobe::Analytic(p) => {
                let (kd, ks, f0, n) = (p.kd as f64, p.ks as f64, p.f0 as f64, p.n as f64);
                for (c, (&cell, o)) in cells.iter().zip(out.iter_mut()).enumerate() {
                    let (i, j, k) = unflat(cell as usize);
                    let v = kd * std::f64::consts::FRAC_1_PI + ks * t.rho_s(i, j, k, f0, n);
                    *o = (weights.map_or(1.0, |w| w[c]) * v) as f32;
                }
            }
            Lobe::Measured { .. } => {
                for (c, (&cell, o)) in cells.iter().zip(out.iter_mut()).enumerate() {
                    *o = (weights.map_or(1.0, |w| w[c]) * lobe.eval_f64(t, cell as usize)) as f32;
                }
            }
        }
    }
}

/// Sum over a block of rows `a` x rows `b` of `|a - b|` over `len` cells, added into `acc`
/// (f64) after f32 runs of [`F32_RUN`] cells.
#[inline(always)]
fn block_l1_generic(a: [&[f32]; BLOCK], b: [&[f32]; BLOCK], acc: &mut [[f64; BLOCK]; BLOCK]) {
    const L: usize = 8;
    let len = a[0].len();
    let mut start = 0;
    while start < len {
        let end = (start + F32_RUN).min(len);
        let mut s = [[[0f32; L]; BLOCK]; BLOCK];
        let vec_end = start + (end - start) / L * L;
        let mut c = start;
        while c < vec_end {
            let mut av = [[0f32; L]; BLOCK];
            for r in 0..BLOCK {
                av[r].copy_from_slice(&a[r][c..c + L]);
            }
            for q in 0..BLOCK {
                let bv: &[f32] = &b[q][c..c + L];
                for r in 0..BLOCK {
                    for l in 0..L {
                        s[r][q][l] += (av[r][l] - bv[l]).abs();
                    }
                }
            }
            c += L;
        }
        for r in 0..BLOCK {
            for q in 0..BLOCK {
                let mut t: f32 = s[r][q].iter().sum();
                for cc in vec_end..end {
                    t += (a[r][cc] - b[q][cc]).abs();
                }
                acc[r][q] += t as f64;
            }
        }
        start = end;
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn block_l1_avx2(a: [&[f32]; BLOCK], b: [&[f32]; BLOCK], acc: &mut [[f64; BLOCK]; BLOCK]) {
    block_l1_generic(a, b, acc)
}

/// `acc[r][q] += sum_c |a_r(c) - b_q(c)|` with the fastest code path of this processor.
pub fn block_l1(a: [&[f32]; BLOCK], b: [&[f32]; BLOCK], acc: &mut [[f64; BLOCK]; BLOCK]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the features were detected on this processor just above.
            unsafe { block_l1_avx2(a, b, acc) };
            return;
        }
    }
    block_l1_generic(a, b, acc)
}

/// Pairwise L1 over one chunk of tabulated rows (`rows[m]`, all of one length; rows
/// beyond the materials are zero padding), accumulated into the condensed `out`.
pub fn pairwise_chunk(rows: &[&[f32]], n: usize, out: &mut [f64]) {
    let nb = rows.len() / BLOCK;
    let pairs: Vec<(usize, usize)> = (0..nb)
        .flat_map(|bi| (bi..nb).map(move |bj| (bi, bj)))
        .collect();
    let partials: Vec<[[f64; BLOCK]; BLOCK]> = pairs
        .par_iter()
        .map(|&(bi, bj)| {
            let a = std::array::from_fn(|r| rows[bi * BLOCK + r]);
            let b = std::array::from_fn(|q| rows[bj * BLOCK + q]);
            let mut acc = [[0f64; BLOCK]; BLOCK];
            block_l1(a, b, &mut acc);
            acc
        })
        .collect();
    for (&(bi, bj), acc) in pairs.iter().zip(&partials) {
        for r in 0..BLOCK {
            for q in 0..BLOCK {
                let (i, j) = (bi * BLOCK + r, bj * BLOCK + q);
                if i < j && j < n {
                    out[condensed_index(n, i, j)] += acc[r][q];
                }
            }
        }
    }
}

impl Backend for CpuBackend {
    fn name(&self) -> String {
        let simd = if cfg!(target_arch = "x86_64") && is_avx2() {
            "avx2"
        } else {
            "portable"
        };
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
                    row.par_chunks_mut(CHUNK_CELLS)
                        .zip(cells.par_chunks(CHUNK_CELLS))
                        .for_each(|(o, c)| self.tabulate_into(lobe, c, None, o));
                })
        });
        Ok(out)
    }

    fn pairwise_l1(
        &self,
        lobes: &[Lobe],
        cells: &CellSet,
        progress: Progress<'_>,
    ) -> Result<Vec<f64>, BackendError> {
        let n = lobes.len();
        let mut out = vec![0f64; condensed_len(n)];
        let n_pad = n.div_ceil(BLOCK) * BLOCK;
        let mut buf = vec![0f32; n_pad * CHUNK_CELLS];
        let total = cells.len() as u64;
        let mut done = 0u64;
        for (cc, cw) in cells
            .cells
            .chunks(CHUNK_CELLS)
            .zip(cells.weights.chunks(CHUNK_CELLS))
        {
            let len = cc.len();
            self.install(|| {
                buf[..n * len]
                    .par_chunks_mut(len)
                    .zip(lobes.par_iter())
                    .for_each(|(row, lobe)| {
                        self.tabulate_into(lobe, cc, Some(cw), row);
                    });
                buf[n * len..n_pad * len].fill(0.0);
                let rows: Vec<&[f32]> = buf[..n_pad * len].chunks(len).collect();
                pairwise_chunk(&rows, n, &mut out);
            });
            done += len as u64;
            progress(done, total);
        }
        Ok(out)
    }
}

fn is_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
