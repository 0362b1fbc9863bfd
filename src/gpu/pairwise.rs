//! Pairwise weighted L1 kernel (`shaders/pairwise.wgsl`) and its chunked driver.
//!
//! The grid is streamed in chunks of cells: per chunk, the lobes are tabulated on the GPU
//! straight into the value buffer (weights pre-multiplied, so `w |a - b| = |w a - w b|`),
//! measured rows are uploaded, and one dispatch reduces every block pair over every run
//! of cells. Per-lane partial sums (f32 over at most `MAX_RUN_ITERS` cells) are read back per
//! chunk and accumulated in f64 on the host.

use super::tabulate::TabulateKernel;
use super::{dispatch, GpuContext};
use crate::backend::blocks::{add_block, PairOp};
use crate::backend::{Lobe, LobeParams, Progress};
use crate::error::GpuError;
use crate::merl::{CellSet, GridTables};

/// WGSL source of the kernel.
pub const SOURCE: &str = include_str!("../../shaders/pairwise.wgsl");
pub use crate::backend::blocks::BLOCK;
/// Lanes per workgroup; keep in sync with `WG` in common.wgsl.
pub const WG: usize = 8;
/// Most loop iterations of one invocation (lavapipe silently ends loops after 65,535).
pub const MAX_RUN_ITERS: u32 = 1024;
/// Most cells per streamed chunk.
pub const MAX_CHUNK: usize = 1 << 18;
const _: () = assert!(MAX_RUN_ITERS < 65_535 && (WG as u32) < 65_535);

/// Uniform parameters; keep in sync with `PairParams` in `shaders/pairwise.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PairParams {
    /// Cells in this chunk.
    pub n_cells: u32,
    /// Distance in f32 between rows of the value buffer.
    pub row_stride: u32,
    /// Loop iterations per lane.
    pub run_iters: u32,
    /// Runs per chunk.
    pub n_runs: u32,
    /// First block pair of this dispatch.
    pub block_offset: u32,
    /// Block pairs in total.
    pub n_blocks: u32,
    /// Padding.
    pub _pad0: u32,
    /// Padding.
    pub _pad1: u32,
}

/// How a pairwise reduction is cut into chunks, runs and dispatches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairPlan {
    /// Materials padded to a multiple of BLOCK.
    pub n_pad: usize,
    /// Block pairs `(bi <= bj)`.
    pub n_blocks: usize,
    /// Cells per chunk (a multiple of `64 x run_iters` unless the whole set is smaller).
    pub chunk: usize,
    /// Loop iterations per lane.
    pub run_iters: u32,
    /// Runs per chunk.
    pub n_runs: usize,
}

impl PairPlan {
    /// Plans `n` materials over `cells` cells within `max_binding` bytes per binding.
    /// `software`: few large workgroups (lavapipe); otherwise enough workgroups to fill a
    /// large GPU.
    pub fn new(n: usize, cells: usize, max_binding: u64, software: bool) -> Result<Self, GpuError> {
        let n_pad = n.div_ceil(BLOCK) * BLOCK;
        let nb = n_pad / BLOCK;
        let n_blocks = nb * (nb + 1) / 2;
        let by_binding = (max_binding / 4) as usize / n_pad.max(1);
        if by_binding < WG {
            return Err(GpuError::Limits(format!(
                "{n} materials do not fit one storage binding of {max_binding} bytes even 64 cells at a time"
            )));
        }
        let mut chunk = by_binding.min(MAX_CHUNK).min(cells.max(1));
        let run_iters = if software {
            MAX_RUN_ITERS
        } else {
            let want_runs = 16_384usize.div_ceil(n_blocks).max(1);
            ((chunk / WG / want_runs) as u32).clamp(8, MAX_RUN_ITERS)
        };
        let run = WG * run_iters as usize;
        if chunk > run {
            chunk = chunk / run * run;
        }
        let n_runs = chunk.div_ceil(run);
        Ok(Self {
            n_pad,
            n_blocks,
            chunk,
            run_iters,
            n_runs,
        })
    }
}

/// The compiled pairwise kernel, one pipeline per operation.
#[derive(Debug)]
pub struct PairwiseKernel {
    l1: wgpu::ComputePipeline,
    dot: wgpu::ComputePipeline,
}

impl PairwiseKernel {
    /// Compiles the kernel for both operations.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        Ok(Self {
            l1: ctx.pipeline_with("pairwise (L1)", SOURCE, &[("OP", 0.0)])?,
            dot: ctx.pipeline_with("pairwise (dot)", SOURCE, &[("OP", 1.0)])?,
        })
    }

    /// Reduces `op` of `lobes` over `cells` for the listed block pairs: full `n x n`, f64.
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        &self,
        ctx: &GpuContext,
        tab: &TabulateKernel,
        lobes: &[Lobe],
        cells: &CellSet,
        blocks: &[[u32; 2]],
        op: PairOp,
        plan: &PairPlan,
        progress: Progress<'_>,
    ) -> Result<Vec<f64>, GpuError> {
        let n = lobes.len();
        let mut out = vec![0f64; n * n];
        let pipeline = match op {
            PairOp::L1 => &self.l1,
            PairOp::Dot => &self.dot,
        };
        let mut sums = vec![0f64; blocks.len() * 16];
        let n_blocks = blocks.len();
        let block_buf = ctx.storage_init(
            "block pairs",
            bytemuck::cast_slice(blocks),
            wgpu::BufferUsages::empty(),
        );
        let vals = ctx.storage("values", (plan.n_pad * plan.chunk * 4) as u64);
        // Bytes of per-lane partials of one block; blocks per pass so that they fit one
        // binding and one dispatch dimension.
        let per_block = plan.n_runs * WG * 16 * 4;
        let max_dim = ctx.limits.max_compute_workgroups_per_dimension as usize;
        let per_pass = ((ctx.max_binding() as usize / per_block).max(1))
            .min(max_dim)
            .min(n_blocks);
        let partial_bytes = (per_pass * per_block) as u64;
        let partial = ctx.storage("partial sums", partial_bytes);
        let cell_buf = ctx.storage("cells", (plan.chunk * 4) as u64);
        let weight_buf = ctx.storage("weights", (plan.chunk * 4) as u64);
        let (analytic, rows): (Vec<LobeParams>, Vec<u32>) = lobes
            .iter()
            .enumerate()
            .filter_map(|(i, l)| match l {
                Lobe::Analytic(p) => Some((*p, i as u32)),
                Lobe::Measured { .. } => None,
            })
            .unzip();
        let measured: Vec<usize> = (0..n)
            .filter(|&i| matches!(lobes[i], Lobe::Measured { .. }))
            .collect();
        let tables = GridTables::new();
        if plan.n_runs > max_dim {
            return Err(GpuError::Limits(format!(
                "{} runs per chunk exceed the dispatch limit {max_dim}",
                plan.n_runs
            )));
        }
        let prepared = tab.prepare(ctx, &analytic, &rows);
        let total = cells.len() as u64;
        let mut done = 0u64;
        for (cc, cw) in cells
            .cells
            .chunks(plan.chunk)
            .zip(cells.weights.chunks(plan.chunk))
        {
            let len = cc.len();
            let w32: Vec<f32> = cw.iter().map(|&w| op.row_scale(w) as f32).collect();
            ctx.queue
                .write_buffer(&cell_buf, 0, bytemuck::cast_slice(cc));
            ctx.queue
                .write_buffer(&weight_buf, 0, bytemuck::cast_slice(&w32));
            for &m in &measured {
                let row: Vec<f32> = cc
                    .iter()
                    .zip(cw)
                    .map(|(&c, &w)| {
                        (op.row_scale(w) * lobes[m].eval_f64(&tables, c as usize)) as f32
                    })
                    .collect();
                ctx.queue.write_buffer(
                    &vals,
                    (m * plan.chunk * 4) as u64,
                    bytemuck::cast_slice(&row),
                );
            }
            let mut enc = ctx.encoder();
            if !analytic.is_empty() {
                tab.record(
                    ctx,
                    &mut enc,
                    &prepared,
                    &cell_buf,
                    Some(&weight_buf),
                    &vals,
                    len as u32,
                    plan.chunk as u32,
                );
            }
            // Block groups whose per-lane partials fit one binding; one readback each.
            for off in (0..n_blocks).step_by(per_pass) {
                let count = (n_blocks - off).min(per_pass);
                let params = PairParams {
                    n_cells: len as u32,
                    row_stride: plan.chunk as u32,
                    run_iters: plan.run_iters,
                    n_runs: plan.n_runs as u32,
                    block_offset: off as u32,
                    n_blocks: (off + count) as u32,
                    _pad0: 0,
                    _pad1: 0,
                };
                let pbuf = ctx.uniform("pairwise params", &params);
                let bind = ctx.bind(pipeline, &[&pbuf, &vals, &block_buf, &partial]);
                dispatch(
                    &mut enc,
                    pipeline,
                    &bind,
                    (plan.n_runs as u32, count as u32),
                );
                let used = (count * per_block) as u64;
                let bytes = ctx.submit_and_read(
                    std::mem::replace(&mut enc, ctx.encoder()),
                    &partial,
                    used,
                )?;
                let part: &[f32] = bytemuck::cast_slice(&bytes[..used as usize]);
                for (k, s) in sums[off * 16..(off + count) * 16]
                    .chunks_mut(16)
                    .enumerate()
                {
                    for lane_run in part[k * per_block / 4..(k + 1) * per_block / 4].chunks(16) {
                        for (v, &x) in s.iter_mut().zip(lane_run) {
                            *v += x as f64;
                        }
                    }
                }
            }
            done += len as u64;
            progress(done, total);
        }
        for (s, &b) in sums.chunks(16).zip(blocks) {
            add_block(&mut out, n, b, |r, q| s[r * BLOCK + q]);
        }
        Ok(out)
    }
}
