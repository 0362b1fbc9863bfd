//! Pairwise reduction kernel (`pairwise/pairwise.wgsl`) and its chunked driver.
//!
//! Rows live four to a texel ("row block") of one rgba32float value texture. Analytic
//! lobes are never stored per cell: their row blocks hold the separable form's tables
//! (8,100 betas and the alphas, uploaded once), and the kernel tabulates them in registers
//! at each cell from a per-cell texel `(e, g, w)` the host computes in f64. Measured lobes
//! are packed per chunk of cells by the host; neural lobes are evaluated per chunk on the
//! device by the neural kernel ([`crate::neural`]), which writes their row
//! blocks into the value texture before the chunk's reductions. One dispatch per chunk reduces every
//! requested register block of `4R x 4R` lobe pairs over every run of cells. Per-lane
//! partial sums (f32 over at most `MAX_RUN_ITERS` cells) are read back and accumulated in
//! f64 on the host, in the canonical order of [`brdf_basis_core::backend::cpu`] (lane `l` of a run of
//! 8,192 cells sums cells `l, l + 8, ...`; runs and lanes added in order), so that the
//! sums equal the CPU back-end's bit for bit (neural lobes aside: the two back-ends'
//! network evaluations agree to SPEC 9's accuracy, not bit for bit) wherever the adapter computes f32 `*`, `+`,
//! `-` and `abs` as IEEE 754 does and does not contract `a * b + c` into a fused
//! multiply-add (lavapipe).
//!
//! The kernel body is unrolled here ([`kernel_source`]) for a [`KernelShape`]: on lavapipe
//! large blocks (R = 4 to 6: up to 24 x 24 pairs from 12 texel fetches per cell) amortise
//! the fetches, and [`KernelShape::choose`] picks the one that pads the collection least;
//! on a hardware GPU R = 2 keeps the 64 accumulators in registers.
//!
//! Rows are laid out by [`RowLayout`] (analytic lobes first, then measured tables, then
//! neural lobes, each kind from a whole texel on, so that no row block mixes kinds); `covering_blocks` maps the caller's
//! `BLOCK x BLOCK` block pairs onto the register blocks that hold them.

mod neural_rows;
mod plan;
mod reduce;
mod shape;

pub(crate) use plan::covering_blocks;
pub use plan::{PairPlan, PlanLimits, RowLayout};
pub use reduce::{ReduceParams, SOURCE as REDUCE_SOURCE};
pub use shape::{kernel_source, KernelShape, TILED_SOURCE};

use super::neural::NeuralKernel;
use super::tabulate::separable_texels;
use super::{dispatch, GpuContext, PipelineCache};
use brdf_basis_core::backend::{add_block, PairOp};
use brdf_basis_core::backend::{Lobe, Progress};
use brdf_basis_core::brdf::LobeParams;
use brdf_basis_core::error::GpuError;
use brdf_basis_core::merl::{CellSet, GridTables};
use neural_rows::NeuralPass;
use plan::table_rows;
pub(crate) use reduce::DeviceSums;

/// WGSL template of the kernel (see [`kernel_source`]).
pub const SOURCE: &str = include_str!("pairwise.wgsl");
use super::TEX_W;
use brdf_basis_core::backend::BLOCK;
/// Most loop iterations of one invocation (lavapipe silently ends loops after 65,535).
pub const MAX_RUN_ITERS: u32 = 1024;
/// Most cells per streamed chunk on a software adapter.
pub const MAX_CHUNK: usize = 1 << 18;
/// Most cells per streamed chunk on a hardware GPU: the evaluation mask (894,396 cells)
/// in one chunk, so that even N = 100 fills the device (the reduce kernel's loop then
/// runs 8 x 128 = 1,024 lane-runs per value).
pub const MAX_CHUNK_HARDWARE: usize = 1 << 20;
/// Most bytes of measured rows in the value texture (bounds the chunk for large measured
/// collections).
pub const MAX_PACKED_BYTES: usize = 256 << 20;
const _: () = assert!(MAX_RUN_ITERS < 65_535);
// One invocation sums one lane of one canonical run (the CPU back-end's summation order).
const _: () = assert!(
    MAX_RUN_ITERS as usize * brdf_basis_core::backend::cpu::CANONICAL_LANES
        == brdf_basis_core::backend::cpu::CANONICAL_RUN
);

/// Uniform parameters; keep in sync with `PairParams` in `pairwise/pairwise.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PairParams {
    /// Cells in this chunk.
    pub n_cells: u32,
    /// Texels between consecutive measured row blocks (cells per chunk, whole rows).
    pub row_stride: u32,
    /// Loop iterations per lane.
    pub run_iters: u32,
    /// Runs per chunk.
    pub n_runs: u32,
    /// First block pair of this dispatch.
    pub block_offset: u32,
    /// Block pairs in total.
    pub n_blocks: u32,
    /// Analytic row blocks (tables at `b * (NIJ + 1)`).
    pub analytic_blocks: u32,
    /// Measured row blocks after them.
    pub measured_blocks: u32,
    /// Texel of the first measured block's cell 0.
    pub measured_base: u32,
    /// Texel of the all-zero table read by padding blocks.
    pub zero_base: u32,
    /// Padding.
    pub _pad0: u32,
    /// Padding.
    pub _pad1: u32,
}

/// The value texture's table region: per analytic row block, 8,100 texels of four betas
/// then one of four alphas (f32 of the f64 separable form), then an all-zero table.
fn table_texels(lobes: &[Lobe], layout: &RowLayout, blocks: usize) -> Vec<f32> {
    // The analytic rows padded to whole blocks, then one block of padding: the zero table.
    let mut rows: Vec<Option<LobeParams>> = layout
        .analytic
        .iter()
        .map(|&i| match &lobes[i] {
            Lobe::Analytic(l) => Some(*l),
            Lobe::Measured { .. } | Lobe::Neural { .. } => None,
        })
        .collect();
    rows.resize(4 * (blocks + 1), None);
    let mut texels = separable_texels(&GridTables::new(), &rows);
    texels.resize(table_rows(blocks) * TEX_W * 4, 0.0);
    texels
}

/// A compiled variant: shape, operation, diagonal or not.
type PipelineKey = (KernelShape, PairOp, bool);

/// The pairwise kernel: pipelines compiled on first use per shape and operation, and the
/// value texture kept between calls (a fresh texture would be cleared by wgpu first).
#[derive(Debug, Default)]
pub struct PairwiseKernel {
    pipelines: PipelineCache<PipelineKey>,
    reduce: PipelineCache<()>,
    texture: std::sync::Mutex<Option<(u32, wgpu::Texture)>>,
    neural: std::sync::Mutex<Option<std::sync::Arc<NeuralKernel>>>,
}

impl PairwiseKernel {
    /// An empty cache; kernels compile on first use.
    pub fn new() -> Self {
        Self::default()
    }

    /// The pipeline for `shape`, `op` and diagonal or not, compiled on first use.
    pub fn pipeline(
        &self,
        ctx: &GpuContext,
        shape: KernelShape,
        op: PairOp,
        diagonal: bool,
    ) -> Result<wgpu::ComputePipeline, GpuError> {
        self.pipelines.get((shape, op, diagonal), || {
            let label = format!(
                "pairwise ({op:?}, {0}x{0}{1})",
                shape.side(),
                if diagonal { ", diagonal" } else { "" }
            );
            let code = match op {
                PairOp::L1 => 0.0,
                PairOp::Dot => 1.0,
            };
            ctx.pipeline_with(&label, &kernel_source(shape, diagonal), &[("OP", code)])
        })
    }

    /// The f64 reduction's pipeline, compiled on first use where the device has f64.
    fn reduce_pipeline(&self, ctx: &GpuContext) -> Option<wgpu::ComputePipeline> {
        if !ctx.has_f64() {
            return None;
        }
        self.reduce
            .get((), || ctx.pipeline("reduce (f64)", reduce::SOURCE))
            .ok()
    }

    /// The neural kernel, compiled on first use (on `ctx`, the context of every call).
    pub fn neural_kernel(
        &self,
        ctx: &GpuContext,
    ) -> Result<std::sync::Arc<NeuralKernel>, GpuError> {
        let mut slot = self.neural.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(k) = slot.as_ref() {
            return Ok(k.clone());
        }
        let k = std::sync::Arc::new(NeuralKernel::new(ctx)?);
        *slot = Some(k.clone());
        Ok(k)
    }

    /// A value texture of at least `height` rows: the cached one when it is as tall, taken
    /// out of the cache so that concurrent calls never share it (see `put_back`).
    fn value_texture(&self, ctx: &GpuContext, height: u32) -> (u32, wgpu::Texture) {
        let cached = self
            .texture
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take_if(|(h, _)| *h >= height);
        cached.unwrap_or_else(|| {
            let t = ctx.packed_texture(
                "values",
                height,
                // Storage: the neural kernel writes its rows in place.
                wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_DST
                    | wgpu::TextureUsages::STORAGE_BINDING,
            );
            (height, t)
        })
    }

    /// Returns a value texture to the cache, keeping the taller one.
    fn put_back(&self, texture: (u32, wgpu::Texture)) {
        let mut slot = self.texture.lock().unwrap_or_else(|e| e.into_inner());
        if slot.as_ref().is_none_or(|(h, _)| *h < texture.0) {
            *slot = Some(texture);
        }
    }

    /// Drops the cached value texture (tables and up to [`MAX_PACKED_BYTES`] of measured
    /// rows).
    pub fn release_memory(&self) {
        *self.texture.lock().unwrap_or_else(|e| e.into_inner()) = None;
    }

    /// Reduces `op` of `lobes` over `cells` for the listed `BLOCK x BLOCK` block pairs:
    /// full `n x n`, f64. `plan` must be made for these lobes and cells.
    ///
    /// Long function: the chunked driver of the kernel: per chunk of cells the upload,
    /// a dispatch per block shape and the f64 reduction, with the staging buffers and
    /// readback living across the loop.
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        &self,
        ctx: &GpuContext,
        lobes: &[Lobe],
        cells: &CellSet,
        blocks: &[[u32; 2]],
        op: PairOp,
        plan: &PairPlan,
        progress: Progress<'_>,
    ) -> Result<Vec<f64>, GpuError> {
        let n = lobes.len();
        let shape = plan.shape;
        let side = shape.side();
        let mut out = vec![0f64; n * n];
        let pipelines = [
            self.pipeline(ctx, shape, op, true)?,
            self.pipeline(ctx, shape, op, false)?,
        ];
        let layout = RowLayout::new(lobes);
        assert_eq!(
            (
                layout.analytic.len().div_ceil(4),
                layout.packed_rows().div_ceil(4)
            ),
            (plan.analytic_blocks, plan.measured_blocks),
            "plan made for other lobes"
        );
        // Diagonal register blocks first (their own kernel variant), then the others.
        let mut supers = covering_blocks(blocks, &layout, shape);
        let key = |b: &[u32; 2]| (b[0] != b[1], b[0], b[1]);
        supers.sort_by_key(key);
        let n_diagonal = supers.iter().filter(|b| b[0] == b[1]).count();
        let n_blocks = supers.len();
        let mut sums = vec![0f64; n_blocks * side * side];
        let block_buf = ctx.storage_init(
            "register blocks",
            bytemuck::cast_slice(&supers),
            wgpu::BufferUsages::empty(),
        );
        // Per-lane partials of one register block; blocks per pass so that they fit one
        // binding and one dispatch dimension.
        let per_block = plan.partials_per_block() * 4;
        let max_dim = ctx.limits.max_compute_workgroups_per_dimension as usize;
        let per_pass = ((ctx.max_binding() as usize / per_block).max(1))
            .min(max_dim)
            .min(n_blocks.max(1));
        let partial = ctx.storage("partial sums", (per_pass * per_block) as u64);
        // The totals on the device where it has f64 (one readback at the end), else on
        // the host after each dispatch.
        let device_sums = DeviceSums::new(ctx, self.reduce_pipeline(ctx), n_blocks * side * side);
        let (height, texture) = self.value_texture(ctx, plan.texture_height());
        ctx.write_texel_rows(
            &texture,
            0,
            &table_texels(lobes, &layout, plan.analytic_blocks),
        );
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let info_rows = plan.row_stride / TEX_W;
        let info = ctx.packed_texture(
            "cell info",
            info_rows as u32,
            wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        );
        let info_view = info.create_view(&wgpu::TextureViewDescriptor::default());
        let neural_kernel = match layout.neural.is_empty() {
            true => None,
            false => Some(self.neural_kernel(ctx)?),
        };
        let mut neural = match &neural_kernel {
            Some(k) => NeuralPass::new(ctx, k, lobes, &layout, plan, &texture)?,
            None => None,
        };
        let tables = GridTables::new();
        let total = cells.len() as u64;
        let mut done = 0u64;
        let mut in_flight = None;
        let pass = Pass {
            plan,
            pipelines: &pipelines,
            view: &view,
            info_view: &info_view,
            block_buf: &block_buf,
            partial: &partial,
            per_block,
            per_pass,
            n_diagonal,
            n_blocks,
            side,
            device_sums: device_sums.as_ref(),
        };
        for (cc, cw) in cells
            .cells
            .chunks(plan.chunk)
            .zip(cells.weights.chunks(plan.chunk))
        {
            pack_chunk(
                ctx, &info, &texture, lobes, &layout, plan, op, &tables, cc, cw,
            );
            if let Some(n) = neural.as_mut() {
                n.chunk(ctx, op, cc, cw)?;
            }
            // At most two chunks in flight: this one's uploads were staged while the
            // device worked on the last one.
            if let Some(ix) = in_flight.take() {
                ctx.wait_for(ix)?;
            }
            in_flight = dispatch_groups(ctx, &pass, cc.len(), &mut sums)?;
            done += cc.len() as u64;
            progress(done, total);
        }
        if let Some(d) = &device_sums {
            sums = d.read(ctx, ctx.encoder())?;
        }
        self.put_back((height, texture));
        let value = |i: usize, j: usize| {
            // a <= b: the entry a diagonal block's kernel computes.
            let (a, b) = (
                layout.row[i].min(layout.row[j]),
                layout.row[i].max(layout.row[j]),
            );
            let s = supers
                .binary_search_by_key(&key(&[(a / side) as u32, (b / side) as u32]), key)
                .expect("covering block");
            sums[s * side * side + (a % side) * side + b % side]
        };
        for &b in blocks {
            add_block(&mut out, n, b, |r, q| {
                value(b[0] as usize * BLOCK + r, b[1] as usize * BLOCK + q)
            });
        }
        Ok(out)
    }
}

/// What every cell chunk of one [`PairwiseKernel::run`] shares: the plan, the two
/// pipelines (diagonal register blocks, others), the bound resources and the register-block
/// grouping (`per_pass` blocks of `per_block` bytes of partials each per readback).
struct Pass<'a> {
    plan: &'a PairPlan,
    pipelines: &'a [wgpu::ComputePipeline; 2],
    view: &'a wgpu::TextureView,
    info_view: &'a wgpu::TextureView,
    block_buf: &'a wgpu::Buffer,
    partial: &'a wgpu::Buffer,
    per_block: usize,
    per_pass: usize,
    n_diagonal: usize,
    n_blocks: usize,
    side: usize,
    /// The totals on the device, if it has f64.
    device_sums: Option<&'a DeviceSums>,
}

/// Uploads one chunk of cells (`cc`, weights `cw`): per cell (e, g, w, 0) into `info`
/// (table index, separable factor times the row scale, row scale; f64 rounded once), and
/// the measured rows, scaled and packed on the host four rows to a texel, into `texture`.
#[allow(clippy::too_many_arguments)]
fn pack_chunk(
    ctx: &GpuContext,
    info: &wgpu::Texture,
    texture: &wgpu::Texture,
    lobes: &[Lobe],
    layout: &RowLayout,
    plan: &PairPlan,
    op: PairOp,
    tables: &GridTables,
    cc: &[u32],
    cw: &[f64],
) {
    use rayon::prelude::*;
    let info_rows = plan.row_stride / TEX_W;
    let mut texels = vec![0f32; plan.row_stride * 4];
    texels
        .par_chunks_mut(4 << 12)
        .zip(cc.par_chunks(1 << 12))
        .zip(cw.par_chunks(1 << 12))
        .for_each(|((ts, cs), ws)| {
            for ((t, &c), &w) in ts.chunks_exact_mut(4).zip(cs).zip(ws) {
                let (e, g) = tables.cell_factor(c as usize);
                let w = op.row_scale(w);
                t.copy_from_slice(&[e as f32, (g * w) as f32, w as f32, 0.0]);
            }
        });
    ctx.write_texel_rows(info, 0, &texels);
    // Measured tables, filled as the CPU back-end fills them (bit for bit); neural rows are
    // written on the device (NeuralPass).
    let scale: Vec<f64> = cw.iter().map(|&w| op.row_scale(w)).collect();
    let len = cc.len();
    let mut rows = vec![0f32; layout.measured.len() * len];
    brdf_basis_core::backend::cpu::fill_rows(
        layout
            .measured
            .iter()
            .map(|&i| &lobes[i])
            .zip(rows.chunks_mut(len.max(1)))
            .collect(),
        cc,
        Some(&scale),
    )
    .expect("rows of the chunk's length, of non-analytic lobes only (RowLayout)");
    for (m, group) in rows.chunks(4 * len.max(1)).enumerate() {
        texels.fill(0.0);
        for (q, row) in group.chunks(len.max(1)).enumerate() {
            for (c, &v) in row.iter().enumerate() {
                texels[4 * c + q] = v;
            }
        }
        ctx.write_texel_rows(
            texture,
            plan.measured_base() / TEX_W + m * info_rows,
            &texels,
        );
    }
}

/// Runs the kernel on the uploaded chunk of `len` cells: register-block groups whose
/// per-lane partials fit one binding (diagonal blocks first, their own pipeline), one
/// dispatch each, added into the totals: on the device where it has f64 (one submission
/// per group, no wait: the queue orders the reuse of the partials and of the value
/// texture), else by one blocking readback each, [`accumulate`]d into `sums` on the host.
fn dispatch_groups(
    ctx: &GpuContext,
    pass: &Pass<'_>,
    len: usize,
    sums: &mut [f64],
) -> Result<Option<wgpu::SubmissionIndex>, GpuError> {
    let plan = pass.plan;
    let mut enc = ctx.encoder();
    let mut last = None;
    let groups = [(0, pass.n_diagonal), (pass.n_diagonal, pass.n_blocks)]
        .into_iter()
        .zip(pass.pipelines)
        .flat_map(|((lo, hi), p)| {
            (lo..hi)
                .step_by(pass.per_pass)
                .map(move |off| (off, (hi - off).min(pass.per_pass), p))
        });
    for (off, count, pipeline) in groups {
        let params = PairParams {
            n_cells: len as u32,
            row_stride: plan.row_stride as u32,
            run_iters: plan.run_iters,
            n_runs: plan.n_runs as u32,
            block_offset: off as u32,
            n_blocks: (off + count) as u32,
            analytic_blocks: plan.analytic_blocks as u32,
            measured_blocks: plan.measured_blocks as u32,
            measured_base: plan.measured_base() as u32,
            zero_base: plan.zero_base() as u32,
            _pad0: 0,
            _pad1: 0,
        };
        let pbuf = ctx.uniform("pairwise params", &params);
        let bind = ctx.bind_at(
            pipeline,
            vec![
                (0, pbuf.as_entire_binding()),
                (1, wgpu::BindingResource::TextureView(pass.view)),
                (2, pass.block_buf.as_entire_binding()),
                (3, pass.partial.as_entire_binding()),
                (4, wgpu::BindingResource::TextureView(pass.info_view)),
            ],
        );
        dispatch(
            &mut enc,
            pipeline,
            &bind,
            (plan.n_runs as u32, count as u32),
        );
        if let Some(d) = pass.device_sums {
            let ss = pass.side * pass.side;
            d.encode(
                ctx,
                &mut enc,
                pass.partial,
                (off, count, ss, pass.per_block / 4 / ss),
            );
            last = Some(ctx.submit(std::mem::replace(&mut enc, ctx.encoder()))?);
            continue;
        }
        let used = (count * pass.per_block) as u64;
        let bytes = ctx.submit_and_read(
            std::mem::replace(&mut enc, ctx.encoder()),
            pass.partial,
            used,
        )?;
        let ss = pass.side * pass.side;
        accumulate(
            &mut sums[off * ss..(off + count) * ss],
            bytemuck::cast_slice(&bytes[..used as usize]),
            ss,
            pass.per_block / 4,
        );
    }
    Ok(last)
}

/// Adds the f32 per-lane, per-run partials `part` (`per_block` values per register block)
/// to the f64 sums of the same blocks (`ss` values each), in lane-run order.
fn accumulate(sums: &mut [f64], part: &[f32], ss: usize, per_block: usize) {
    for (s, blk) in sums.chunks_mut(ss).zip(part.chunks(per_block)) {
        for lane_run in blk.chunks(ss) {
            for (v, &x) in s.iter_mut().zip(lane_run) {
                *v += x as f64;
            }
        }
    }
}
