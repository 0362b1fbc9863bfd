//! The CPU back-end: rayon over materials and block pairs, blocked loops with AVX2 (chosen
//! at run time, portable code otherwise). It is also the reference twin of every GPU
//! kernel in the tests.
//!
//! Analytic lobes are tabulated from factors: on the grid
//! `rho_s = (n + 1) / (8 pi) * P[i] * F[j] / (cos theta_d max(N.wi, N.wo))` with
//! `P[i] = (cos theta_h)^n` and `F[j]` the Fresnel term, so each lobe needs 180
//! exponentials and powers, not one per cell; everything is f64, rounded once to f32.
//!
//! # Canonical summation order (shared with the GPU kernel)
//!
//! Pair reductions ([`Backend::reduce_pairs`]) give the same sums, bit for bit, as the GPU
//! back-end's kernel on lavapipe: both form a lobe's value at a cell as
//! `beta[e] x (g w) + alpha x w` in f32 from the same f32 inputs (the separable form of
//! [`crate::separable`], rounded once; measured rows: the f64 value times the row scale,
//! rounded once), each product and the sum rounded (no fused multiply-add: lavapipe
//! computes WGSL `fma` as a multiply and an add), and both sum in one order. The cells of
//! the set are cut into *canonical runs* of [`CANONICAL_RUN`] = 8 x 1,024 consecutive
//! cells; in a run, lane `l` of [`CANONICAL_LANES`] = 8 sums `op(a, b)` over cells
//! `l, l + 8, l + 16, ...` in f32, in that order (`acc + |a - b|`, or `acc + a b` for dot
//! products); the eight lane sums of each run are then added to the f64 total in lane
//! order, run after run. An f32 lane sum covers at most 1,024 cells (relative error ~1e-7
//! on BRDF_it, well inside SPEC 4's 1e-4). The AVX2 kernel keeps the eight lanes in one
//! register; the GPU gives each lane an invocation. A hardware driver may contract
//! `a x b + c` into a fused multiply-add (SPIR-V allows it): its sums then differ in the
//! last bits of some cells' values (~1e-8 relative on BRDF_it), which the clustering's
//! tie margin (`cluster::TIE_TOLERANCE`, 1e-6) absorbs.
//!
//! # Neural lobes
//!
//! A neural lobe ([`Lobe::Neural`]) is evaluated per chunk of cells by the f32 twin of its
//! network ([`crate::brdf::Nbrdf::eval_cells`]), never stored as a whole table: the
//! lobes of one network (its three channels, or the mean) share one evaluation per chunk
//! ([`fill_rows`]). A row value is the chosen channel (or the f64 mean of the three) times
//! the row scale in f64, rounded once to f32, like a measured row. The GPU back-end runs
//! its own f32 kernel of the networks on the device (`brdf_basis_gpu::neural`): both are
//! within SPEC 9 of the f64 network, not bit for bit the same, so reductions over neural
//! lobes agree between the back-ends to that accuracy (measured and analytic rows still
//! bit for bit).

use super::blocks::{PairOp, BLOCK};
use super::{Backend, Lobe, LobeParams, Progress};
use crate::brdf::Nbrdf;
use crate::error::BackendError;
use crate::merl::{unflat, N_TD, N_TH};
use crate::merl::{CellSet, GridTables};
use rayon::prelude::*;

/// Lanes of the canonical summation order (module docs).
#[doc(hidden)]
pub const CANONICAL_LANES: usize = 8;
/// Cells of a canonical run: [`CANONICAL_LANES`] lanes of 1,024 cells, each summed in f32.
#[doc(hidden)]
pub const CANONICAL_RUN: usize = 8192;
/// Cells per streamed chunk: one canonical run. A row of a chunk is 32 KiB, so the 6 rows
/// a 4 x 2 sub-block streams stay in L2 while the block pairs of the chunk reuse them.
pub const CHUNK_CELLS: usize = CANONICAL_RUN;

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

/// Most threads per available CPU of any pool: the work is CPU-bound.
pub const MAX_THREADS_PER_CPU: usize = 4;

/// CPUs available to this process (1 when unknown).
fn cpus() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Most threads of any pool: [`MAX_THREADS_PER_CPU`] x the available CPUs.
pub fn max_threads() -> usize {
    MAX_THREADS_PER_CPU * cpus()
}

/// Builds rayon's global pool with at most [`max_threads`] threads when
/// `RAYON_NUM_THREADS` asks for more (`RAYON_NUM_THREADS=100000` would otherwise spend
/// minutes starting threads before any work), and returns the warning to print. Call it
/// before anything runs on the global pool; without such a request, or once the global
/// pool exists, it does nothing and returns `None`.
pub fn cap_global_threads() -> Option<String> {
    let asked: usize = std::env::var("RAYON_NUM_THREADS")
        .ok()?
        .trim()
        .parse()
        .ok()?;
    let max = max_threads();
    if asked <= max {
        return None;
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(max)
        .build_global()
        .ok()?;
    Some(format!(
        "RAYON_NUM_THREADS={asked} is more than {MAX_THREADS_PER_CPU} threads per CPU ({} CPUs): using {max} threads",
        cpus()
    ))
}

impl CpuBackend {
    /// A back-end on rayon's global pool (see [`cap_global_threads`]).
    pub fn new() -> Self {
        Self {
            tables: GridTables::new(),
            pool: None,
        }
    }

    /// A back-end on its own pool of `threads` threads (at most [`max_threads`]; more
    /// is an error: the work is CPU-bound, and a pool of thousands of threads only takes
    /// minutes to start).
    pub fn with_threads(threads: usize) -> Result<Self, BackendError> {
        if threads > max_threads() {
            return Err(BackendError::Invalid(format!(
                "{threads} threads requested, more than the {} this machine's {} CPUs use at most ({MAX_THREADS_PER_CPU} per CPU)",
                max_threads(),
                cpus()
            )));
        }
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
            // The tabulated lobe (the f32 twin, within SPEC 9's accuracy of the f64
            // network, `Lobe::eval_f64`): the values every reduction runs over.
            Lobe::Neural { net, channel } => self
                .neural_f32(lobe, net, *channel, cells)
                .iter()
                .map(|&v| f64::from(v))
                .collect(),
        }
    }

    /// A network's channel at `cells` in f32, from the cache or tabulated into it. A
    /// channel's miss tabulates the network's three channels together (one run of the
    /// network per cell instead of one per channel: the passes that ask for one channel ask
    /// for the other two next) and keeps all three.
    fn neural_f32(
        &self,
        lobe: &Lobe,
        net: &std::sync::Arc<Nbrdf>,
        channel: Option<usize>,
        cells: &[u32],
    ) -> std::sync::Arc<Vec<f32>> {
        neural_cache::get(net, channel, cells, || {
            let chunk = 1 << 14;
            let Some(_) = channel else {
                let mut out = vec![0f32; cells.len()];
                self.install(|| {
                    out.par_chunks_mut(chunk)
                        .zip(cells.par_chunks(chunk))
                        .for_each(|(o, c)| self.tabulate_into(lobe, c, None, o))
                });
                return vec![(channel, out)];
            };
            // The three channels in one run of the network per cell: `neural_rows`' values,
            // the same bits as each channel's own tabulation (a unit test holds them equal).
            let [mut r, mut g, mut b] = [0; 3].map(|_| vec![0f32; cells.len()]);
            self.install(|| {
                r.par_chunks_mut(chunk)
                    .zip(g.par_chunks_mut(chunk))
                    .zip(b.par_chunks_mut(chunk))
                    .zip(cells.par_chunks(chunk))
                    .for_each(|(((r, g), b), c)| {
                        neural_rows(
                            net,
                            c,
                            &mut [(Some(0), None, r), (Some(1), None, g), (Some(2), None, b)],
                        );
                    })
            });
            vec![(Some(0), r), (Some(1), g), (Some(2), b)]
        })
    }

    /// `lobe`'s values over `cells` ([`Self::values_f64`]) to be read a block of cells at a
    /// time with [`Self::block_values`]: a network's tabulation of all `cells` is fetched
    /// (or made) once, other lobes are evaluated per block.
    pub(crate) fn block_source<'a>(&self, lobe: &'a Lobe, cells: &[u32]) -> BlockSource<'a> {
        match lobe {
            Lobe::Neural { net, channel } => {
                BlockSource::Tabulated(self.neural_f32(lobe, net, *channel, cells))
            }
            _ => BlockSource::Direct(lobe),
        }
    }

    /// The values of [`Self::values_f64`] at the block `cells`, which starts at `offset`
    /// of the cells `source` was made for: the same bits.
    pub(crate) fn block_values(
        &self,
        source: &BlockSource<'_>,
        cells: &[u32],
        offset: usize,
    ) -> Vec<f64> {
        match source {
            BlockSource::Direct(lobe) => self.values_f64(lobe, cells),
            BlockSource::Tabulated(v) => v[offset..offset + cells.len()]
                .iter()
                .map(|&x| f64::from(x))
                .collect(),
        }
    }

    /// The three channels of a network at `cells` in f64, on the calling thread and past
    /// the cache: the values [`Self::values_f64`] gives each channel's lobe (the f32 twin,
    /// clamped), from one run of the network. For passes that tabulate a block of cells
    /// at a time (the cross-validation's and the evaluation's grid MAE).
    pub fn neural_values_f64(&self, net: &Nbrdf, cells: &[u32]) -> [Vec<f64>; 3] {
        let mut out = [
            vec![0f32; cells.len()],
            vec![0f32; cells.len()],
            vec![0f32; cells.len()],
        ];
        {
            let [r, g, b] = &mut out;
            let mut rows = [
                (Some(0), None, &mut r[..]),
                (Some(1), None, &mut g[..]),
                (Some(2), None, &mut b[..]),
            ];
            neural_rows(net, cells, &mut rows);
        }
        out.map(|v| v.into_iter().map(f64::from).collect())
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
            Lobe::Neural { net, channel } => {
                let mut rows = [(*channel, scale, &mut out[..cells.len()])];
                neural_rows(net, cells, &mut rows);
            }
        }
    }
}

/// The rows of one network's lobes at `cells`: each `(channel, scale, row)` gets the
/// channel (`None`: the f64 mean of R, G, B) times `scale[c]` (if given), rounded once to
/// f32. The network runs once per [`NEURAL_RUN`] cells for all of them.
fn neural_rows(net: &Nbrdf, cells: &[u32], rows: &mut [NeuralRow<'_, '_>]) {
    // The three channels unscaled (a tabulation): straight into the rows (the same
    // values: an f32 times 1 in f64 rounds back to itself).
    if let [(Some(0), None, r), (Some(1), None, g), (Some(2), None, b)] = &mut *rows {
        net.eval_cells(cells, true, [&mut r[..], &mut g[..], &mut b[..]]);
        return;
    }
    let run = NEURAL_RUN.min(cells.len());
    let (mut r, mut g, mut b) = (vec![0f32; run], vec![0f32; run], vec![0f32; run]);
    for (start, cc) in (0..cells.len())
        .step_by(NEURAL_RUN)
        .zip(cells.chunks(NEURAL_RUN))
    {
        let len = cc.len();
        net.eval_cells(cc, true, [&mut r[..len], &mut g[..len], &mut b[..len]]);
        let ch: [&[f32]; 3] = [&r[..len], &g[..len], &b[..len]];
        for (channel, scale, row) in rows.iter_mut() {
            let row = &mut row[start..start + len];
            match *channel {
                Some(c) => {
                    for (k, (o, &v)) in row.iter_mut().zip(ch[c]).enumerate() {
                        *o = (scale.map_or(1.0, |s| s[start + k]) * v as f64) as f32;
                    }
                }
                None => {
                    for (k, o) in row.iter_mut().enumerate() {
                        let v = (ch[0][k] as f64 + ch[1][k] as f64 + ch[2][k] as f64) / 3.0;
                        *o = (scale.map_or(1.0, |s| s[start + k]) * v) as f32;
                    }
                }
            }
        }
    }
}

/// A row of [`fill_rows_each`]: the lobe, the row scale, the row.
type ScaledRow<'l, 's, 'r> = (&'l Lobe, Option<&'s [f64]>, &'r mut [f32]);

/// A row of [`neural_rows`]: the channel (`None`: the mean), the row scale, the row.
type NeuralRow<'s, 'r> = (Option<usize>, Option<&'s [f64]>, &'r mut [f32]);

/// A lobe's values read a block of cells at a time ([`CpuBackend::block_source`]).
pub(crate) enum BlockSource<'a> {
    /// Evaluated per block.
    Direct(&'a Lobe),
    /// A network's f32 tabulation of all the cells.
    Tabulated(std::sync::Arc<Vec<f32>>),
}

mod neural_cache;
pub use neural_cache::NEURAL_CACHE_BYTES;

/// Cells a network is run over at once in [`neural_rows`] (its RGB stays in L1).
const NEURAL_RUN: usize = 1024;

/// Fills the rows of non-analytic lobes at `cells`, each value times `scale[c]` (if
/// given), rounded once to f32: `rows` pairs a lobe with its output row (`cells.len()`
/// values). The lobes of one network share one evaluation; rayon runs the networks (and
/// measured rows) in parallel. Analytic lobes are refused (they have their own paths).
/// The CPU back-end fills measured and neural rows with this, and the GPU back-end's host
/// packing its measured rows (bit for bit the same values).
pub fn fill_rows(
    rows: Vec<(&Lobe, &mut [f32])>,
    cells: &[u32],
    scale: Option<&[f64]>,
) -> Result<(), BackendError> {
    fill_rows_each(
        rows.into_iter().map(|(l, r)| (l, scale, r)).collect(),
        cells,
    )
}

/// [`fill_rows`] with a scale per row (`None`: 1): the rows of one network share one
/// evaluation whatever their scales.
fn fill_rows_each(rows: Vec<ScaledRow<'_, '_, '_>>, cells: &[u32]) -> Result<(), BackendError> {
    let tables = &GridTables::new();
    type NetRows<'a, 's, 'b> = (&'a Nbrdf, Vec<NeuralRow<'s, 'b>>);
    let mut nets: Vec<NetRows> = Vec::new();
    let mut tables_rows: Vec<ScaledRow> = Vec::new();
    for (lobe, scale, row) in rows {
        if row.len() != cells.len() {
            return Err(BackendError::Invalid(format!(
                "fill_rows: a row of {} values for {} cells",
                row.len(),
                cells.len()
            )));
        }
        match lobe {
            Lobe::Analytic(_) => {
                return Err(BackendError::Invalid(
                    "fill_rows: analytic lobes are tabulated from their parameters".into(),
                ))
            }
            Lobe::Measured { .. } => tables_rows.push((lobe, scale, row)),
            Lobe::Neural { net, channel } => {
                match nets
                    .iter_mut()
                    .find(|(n, _)| std::ptr::eq(*n, net.as_ref()))
                {
                    Some((_, v)) => v.push((*channel, scale, row)),
                    None => nets.push((net.as_ref(), vec![(*channel, scale, row)])),
                }
            }
        }
    }
    tables_rows.into_par_iter().for_each(|(lobe, scale, row)| {
        for (c, (&cell, o)) in cells.iter().zip(row.iter_mut()).enumerate() {
            *o = (scale.map_or(1.0, |s| s[c]) * lobe.eval_f64(tables, cell as usize)) as f32;
        }
    });
    nets.into_par_iter()
        .for_each(|(net, mut rows)| neural_rows(net, cells, &mut rows));
    Ok(())
}

/// `op` of one cell into a lane sum, as the GPU kernel does it (products rounded: no fma).
#[inline(always)]
fn lane_step<const DOT: bool>(s: f32, x: f32, y: f32) -> f32 {
    if DOT {
        s + x * y
    } else {
        s + (x - y).abs()
    }
}

/// Portable kernel: `acc[r][q] += sum_c op(a_r(c), b_q(c))` in the canonical order (module
/// docs).
fn block_portable<const DOT: bool>(
    a: [&[f32]; BLOCK],
    b: [&[f32]; BLOCK],
    acc: &mut [[f64; BLOCK]; BLOCK],
) {
    let len = a[0].len();
    for start in (0..len).step_by(CANONICAL_RUN) {
        let end = (start + CANONICAL_RUN).min(len);
        for r in 0..BLOCK {
            for q in 0..BLOCK {
                let mut s = [0f32; CANONICAL_LANES];
                let (ar, bq) = (&a[r][start..end], &b[q][start..end]);
                for (c, (&x, &y)) in ar.iter().zip(bq).enumerate() {
                    let l = c % CANONICAL_LANES;
                    s[l] = lane_step::<DOT>(s[l], x, y);
                }
                for v in s {
                    acc[r][q] += v as f64;
                }
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{lane_step, BLOCK, CANONICAL_LANES, CANONICAL_RUN};
    use std::arch::x86_64::*;

    /// AVX2 kernel over a 4 x 4 block as two 4 x 2 passes (8 accumulators, 4 + 1 row
    /// registers and the sign mask: no spills), in the canonical order: the 8 lanes of a
    /// register are the 8 lanes of a canonical run.
    ///
    /// # Safety
    /// The processor must support AVX2 and FMA; all rows must have one length.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn block<const DOT: bool>(
        a: [&[f32]; BLOCK],
        b: [&[f32]; BLOCK],
        acc: &mut [[f64; BLOCK]; BLOCK],
    ) {
        let len = a[0].len();
        let sign = _mm256_set1_ps(-0.0);
        for start in (0..len).step_by(CANONICAL_RUN) {
            let end = (start + CANONICAL_RUN).min(len);
            let vec_end = start + (end - start) / 8 * 8;
            for half in 0..2 {
                let (q0, q1) = (2 * half, 2 * half + 1);
                let mut s = [_mm256_setzero_ps(); 8];
                let mut c = start;
                while c < vec_end {
                    let a0 = _mm256_loadu_ps(a[0].as_ptr().add(c));
                    let a1 = _mm256_loadu_ps(a[1].as_ptr().add(c));
                    let a2 = _mm256_loadu_ps(a[2].as_ptr().add(c));
                    let a3 = _mm256_loadu_ps(a[3].as_ptr().add(c));
                    for (k, q) in [q0, q1].into_iter().enumerate() {
                        let bv = _mm256_loadu_ps(b[q].as_ptr().add(c));
                        if DOT {
                            s[4 * k] = _mm256_add_ps(s[4 * k], _mm256_mul_ps(a0, bv));
                            s[4 * k + 1] = _mm256_add_ps(s[4 * k + 1], _mm256_mul_ps(a1, bv));
                            s[4 * k + 2] = _mm256_add_ps(s[4 * k + 2], _mm256_mul_ps(a2, bv));
                            s[4 * k + 3] = _mm256_add_ps(s[4 * k + 3], _mm256_mul_ps(a3, bv));
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
                // The lanes, the run's last cells (fewer than 8) into their lanes, then the
                // lanes into f64 in lane order.
                for (k, q) in [q0, q1].into_iter().enumerate() {
                    for (r, ar) in a.iter().enumerate() {
                        let mut lanes = [0f32; CANONICAL_LANES];
                        _mm256_storeu_ps(lanes.as_mut_ptr(), s[4 * k + r]);
                        for c in vec_end..end {
                            let l = c - vec_end;
                            lanes[l] = lane_step::<DOT>(lanes[l], ar[c], b[q][c]);
                        }
                        for v in lanes {
                            acc[r][q] += v as f64;
                        }
                    }
                }
            }
        }
    }

    /// [`super::fill_analytic`] compiled for AVX2 (the same values: no fused multiply-add).
    ///
    /// # Safety
    /// The processor must support AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn fill_analytic(
        beta: &[f32],
        alpha: f32,
        cells: &[(usize, f32, f32)],
        out: &mut [f32],
    ) {
        super::fill_analytic_body(beta, alpha, cells, out)
    }
}

/// An analytic row at a chunk's cells `(e, g w, w)` (f32), as the GPU kernel forms it:
/// `beta[e] (g w) + alpha w`, each product and the sum rounded to f32.
#[inline(always)]
fn fill_analytic_body(beta: &[f32], alpha: f32, cells: &[(usize, f32, f32)], out: &mut [f32]) {
    for (o, &(e, gw, w)) in out.iter_mut().zip(cells) {
        *o = beta[e] * gw + alpha * w;
    }
}

/// [`fill_analytic_body`] with the fastest code path of this processor (the same values).
fn fill_analytic(beta: &[f32], alpha: f32, cells: &[(usize, f32, f32)], out: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    {
        if is_avx2() {
            // SAFETY: AVX2 and FMA were detected on this processor.
            unsafe { avx2::fill_analytic(beta, alpha, cells, out) };
            return;
        }
    }
    fill_analytic_body(beta, alpha, cells, out)
}

/// `acc[r][q] += sum_c op(a_r(c), b_q(c))` with the fastest code path of this processor.
///
/// Every row of `a` and `b` must have the same length; otherwise nothing is added and an
/// error names the lengths (the vector kernel reads every row up to the first row's
/// length).
#[doc(hidden)]
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
        huge_pages(&mut out);
        if cells.is_empty() {
            return Ok(out);
        }
        let n = cells.len();
        self.install(|| {
            let (analytic, other): (Vec<_>, Vec<_>) = out
                .chunks_mut(n)
                .zip(lobes)
                .map(|(row, lobe)| (lobe, row))
                .partition(|(lobe, _)| lobe.is_analytic());
            analytic.into_par_iter().for_each(|(lobe, row)| {
                row.par_chunks_mut(1 << 16)
                    .zip(cells.par_chunks(1 << 16))
                    .for_each(|(o, c)| self.tabulate_into(lobe, c, None, o));
            });
            // Measured and neural rows per run of cells, the lobes of one network sharing
            // its evaluation.
            const RUN: usize = 1 << 14;
            let mut runs: Vec<Vec<(&Lobe, &mut [f32])>> =
                (0..n.div_ceil(RUN)).map(|_| Vec::new()).collect();
            for (lobe, row) in other {
                for (run, part) in runs.iter_mut().zip(row.chunks_mut(RUN)) {
                    run.push((lobe, part));
                }
            }
            runs.into_par_iter()
                .zip(cells.par_chunks(RUN))
                .try_for_each(|(rows, cc)| fill_rows(rows, cc, None))
        })?;
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
        let groups = vec![0; lobes.len()];
        let pass = pairs::Pass {
            lobes,
            group: &groups,
            weights: &[&cells.weights],
            cells: &cells.cells,
            blocks,
            op,
        };
        pairs::reduce(self, &pass, progress)
    }

    fn grams_per_channel(
        &self,
        lobes: [Vec<Lobe>; 3],
        cells: [&CellSet; 3],
        basis: usize,
        progress: Progress<'_>,
    ) -> Result<[Vec<f64>; 3], BackendError> {
        pairs::grams_per_channel(self, lobes, cells, basis, progress)
    }

    fn weighted_systems_per_channel(
        &self,
        basis: [&[Lobe]; 3],
        targets: [&[Lobe]; 3],
        cells: &CellSet,
        weight: super::weighted::TargetWeight,
        progress: Progress<'_>,
    ) -> Result<[super::weighted::WeightedSystems; 3], BackendError> {
        systems::weighted_systems_per_channel(self, basis, targets, cells, weight, progress)
    }
}

/// Asks the kernel for transparent huge pages under a large, freshly allocated (still
/// untouched) buffer: the first writes then fault in 2 MiB pages instead of 4 KiB ones
/// (a 1.75 GB tabulation: ~900 faults instead of ~430,000). Advice only: nothing changes
/// where the kernel has huge pages off, and no value changes anywhere.
fn huge_pages(buf: &mut [f32]) {
    const HUGE: usize = 2 << 20;
    let bytes = std::mem::size_of_val(buf);
    if bytes < 4 * HUGE {
        return;
    }
    #[cfg(target_os = "linux")]
    {
        let start = buf.as_mut_ptr() as usize;
        let lo = start.div_ceil(HUGE) * HUGE;
        let hi = (start + bytes) / HUGE * HUGE;
        if hi > lo {
            // SAFETY: [lo, hi) lies inside `buf`'s allocation; MADV_HUGEPAGE changes no
            // contents and only how the range is backed.
            unsafe {
                libc::madvise(lo as *mut libc::c_void, hi - lo, libc::MADV_HUGEPAGE);
            }
        }
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

mod pairs;
mod systems;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod weighted_tests;
