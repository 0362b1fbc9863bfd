//! Pairwise reduction kernel (`shaders/pairwise.wgsl`) and its chunked driver.
//!
//! The grid is streamed in chunks of cells. Per chunk, `pack` (tabulate.wgsl) fills an
//! rgba32float texture with every row's weighted values, four rows to a texel: analytic
//! lobes are tabulated on the GPU straight into it, measured rows are uploaded once per
//! chunk. One dispatch then reduces every requested register block of `4R x 4R` lobe pairs
//! over every run of cells. Per-lane partial sums (f32 over at most `MAX_RUN_ITERS` cells)
//! are read back and accumulated in f64 on the host.
//!
//! The kernel body is unrolled here ([`kernel_source`]) for a [`KernelShape`]: on lavapipe
//! large blocks (R = 4 to 6: up to 24 x 24 pairs from 12 texel fetches per cell) amortise
//! the fetches, and [`KernelShape::choose`] picks the one that pads the collection least;
//! on a hardware GPU R = 2 keeps the 64 accumulators in registers.
//!
//! Rows are laid out by [`RowLayout`] (analytic lobes first, then measured ones, so that
//! no texel mixes GPU-tabulated and host-packed rows); [`covering_blocks`] maps the
//! caller's `BLOCK x BLOCK` block pairs onto the register blocks that hold them.

use super::tabulate::TabulateKernel;
use super::{dispatch, GpuContext};
use crate::backend::blocks::{add_block, PairOp};
use crate::backend::{Lobe, LobeParams, Progress};
use crate::error::GpuError;
use crate::merl::{CellSet, GridTables};

/// WGSL template of the kernel (see [`kernel_source`]).
pub const SOURCE: &str = include_str!("../../shaders/pairwise.wgsl");
pub use crate::backend::blocks::BLOCK;
/// Width in texels of the packed value texture; keep in sync with `TEX_W` in common.wgsl.
pub const TEX_W: usize = 4096;
/// Most loop iterations of one invocation (lavapipe silently ends loops after 65,535).
pub const MAX_RUN_ITERS: u32 = 1024;
/// Most cells per streamed chunk.
pub const MAX_CHUNK: usize = 1 << 18;
/// Most bytes of the packed value texture (bounds the chunk for large collections).
pub const MAX_PACKED_BYTES: usize = 256 << 20;
const _: () = assert!(MAX_RUN_ITERS < 65_535);

/// Register block and workgroup of the pairwise kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KernelShape {
    /// Texels (of 4 rows) per side of an invocation's register block: `4R x 4R` pairs.
    pub r: usize,
    /// Lanes per workgroup.
    pub lanes: usize,
}

/// lavapipe shapes and their kernel-only rates (G pair-cells/s, measured on 2 cores of an
/// AMD EPYC with lavapipe 22.3: 4 x 4 pairs per invocation ran at 4.7, 8 x 8 at 10.7,
/// 12 x 12 at 15.5): one 8-wide SIMD row per workgroup.
const SOFTWARE_SHAPES: [(KernelShape, f64); 3] = [
    (KernelShape { r: 4, lanes: 8 }, 16.4),
    (KernelShape { r: 5, lanes: 8 }, 20.1),
    (KernelShape { r: 6, lanes: 8 }, 20.9),
];

impl KernelShape {
    /// Hardware GPUs: 8 x 8 pairs (64 f32 accumulators), 64 lanes.
    pub const HARDWARE: Self = Self { r: 2, lanes: 64 };

    /// The shape for `n_rows` packed rows: on a software adapter, the one with the least
    /// modelled time (padded pairs / rate), so that e.g. 100 rows use 20 x 20 blocks
    /// without padding.
    pub fn choose(n_rows: usize, software: bool) -> Self {
        if !software {
            return Self::HARDWARE;
        }
        let cost = |(s, rate): &(KernelShape, f64)| {
            let nb = n_rows.max(1).div_ceil(s.side());
            (nb * (nb + 1) / 2 * s.side() * s.side()) as f64 / rate
        };
        SOFTWARE_SHAPES
            .iter()
            .min_by(|a, b| cost(a).total_cmp(&cost(b)))
            .map(|s| s.0)
            .unwrap_or(Self::HARDWARE)
    }

    /// Every shape [`Self::choose`] can return.
    pub fn all() -> impl Iterator<Item = Self> {
        SOFTWARE_SHAPES
            .iter()
            .map(|s| s.0)
            .chain(std::iter::once(Self::HARDWARE))
    }

    /// Whether this shape is tuned for a software adapter (longest runs).
    pub fn is_software(&self) -> bool {
        SOFTWARE_SHAPES.iter().any(|s| s.0 == *self)
    }

    /// Lobes per side of a register block (`4R`).
    pub fn side(&self) -> usize {
        4 * self.r
    }
}

/// The kernel for `shape`: the template with `R` and `LANES` defined and its `//@` lines
/// expanded into the unrolled register block.
pub fn kernel_source(shape: KernelShape) -> String {
    let (r, side) = (shape.r, shape.side());
    const XYZW: [char; 4] = ['x', 'y', 'z', 'w'];
    let mut out = format!(
        "const R: u32 = {r}u;\nconst LANES: u32 = {}u;\n",
        shape.lanes
    );
    for line in SOURCE.lines() {
        let indent = &line[..line.len() - line.trim_start().len()];
        let mut emit = |s: String| {
            out.push_str(indent);
            out.push_str(&s);
            out.push('\n');
        };
        match line.trim() {
            "//@DECLARE" => (0..side).for_each(|i| {
                (0..r).for_each(|j| emit(format!("var acc_{i}_{j} = vec4<f32>(0.0);")))
            }),
            "//@FETCH" => {
                (0..r).for_each(|j| emit(format!("let b{j} = fetch(rb + {j}u, c);")));
                (0..r).for_each(|i| emit(format!("let a{i} = fetch(ra + {i}u, c);")));
            }
            "//@ACCUMULATE" => (0..side).for_each(|i| {
                (0..r).for_each(|j| {
                    emit(format!(
                        "acc_{i}_{j} = step(acc_{i}_{j}, a{}.{}, b{j});",
                        i / 4,
                        XYZW[i % 4]
                    ))
                })
            }),
            "//@STORE" => (0..side).for_each(|i| {
                (0..r).for_each(|j| {
                    (0..4).for_each(|q| {
                        emit(format!(
                            "partial[o + {}u] = acc_{i}_{j}.{};",
                            i * side + 4 * j + q,
                            XYZW[q]
                        ))
                    })
                })
            }),
            _ => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    out
}

/// Uniform parameters; keep in sync with `PairParams` in `shaders/pairwise.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PairParams {
    /// Cells in this chunk.
    pub n_cells: u32,
    /// Texels between consecutive row blocks of the packed texture (cells per chunk).
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

/// The device limits a plan must respect.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlanLimits {
    /// Largest storage binding in bytes.
    pub max_binding: u64,
    /// Largest 2D texture side.
    pub max_texture_dim: u32,
    /// Largest dispatch dimension.
    pub max_dispatch: u32,
}

impl PlanLimits {
    /// The limits of a context.
    pub fn of(ctx: &GpuContext) -> Self {
        Self {
            max_binding: ctx.max_binding(),
            max_texture_dim: ctx.limits.max_texture_dimension_2d,
            max_dispatch: ctx.limits.max_compute_workgroups_per_dimension,
        }
    }
}

/// Where each lobe sits in the packed texture: analytic lobes first (tabulated on the
/// GPU by `pack`), padded to a whole texel, then measured lobes (packed on the host), so
/// that no texel mixes the two.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RowLayout {
    /// Packed row of each lobe.
    pub row: Vec<usize>,
    /// Analytic lobes, in order.
    pub analytic: Vec<usize>,
    /// Measured lobes, in order; they start at row `measured_start`.
    pub measured: Vec<usize>,
    /// First measured row (a multiple of 4).
    pub measured_start: usize,
    /// Rows in use.
    pub n_rows: usize,
}

impl RowLayout {
    /// The layout of `lobes`.
    pub fn new(lobes: &[Lobe]) -> Self {
        let measured: Vec<usize> = (0..lobes.len())
            .filter(|&i| matches!(lobes[i], Lobe::Measured { .. }))
            .collect();
        let analytic: Vec<usize> = (0..lobes.len())
            .filter(|&i| matches!(lobes[i], Lobe::Analytic(_)))
            .collect();
        Self::of_counts(analytic, measured, lobes.len())
    }

    fn of_counts(analytic: Vec<usize>, measured: Vec<usize>, n: usize) -> Self {
        let measured_start = analytic.len().div_ceil(4) * 4;
        let mut row = vec![0; n];
        for (k, &i) in analytic.iter().enumerate() {
            row[i] = k;
        }
        for (k, &i) in measured.iter().enumerate() {
            row[i] = measured_start + k;
        }
        Self {
            row,
            n_rows: measured_start + measured.len(),
            analytic,
            measured,
            measured_start,
        }
    }

    /// Rows of `n_analytic` analytic then `n_measured` measured lobes.
    pub fn rows_for(n_analytic: usize, n_measured: usize) -> usize {
        n_analytic.div_ceil(4) * 4 + n_measured
    }
}

/// How a pairwise reduction is cut into chunks, runs and dispatches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairPlan {
    /// Register block and workgroup.
    pub shape: KernelShape,
    /// Packed rows padded to a multiple of the block side `4R`.
    pub n_pad: usize,
    /// Cells per chunk (a multiple of `lanes x run_iters` unless the whole set is smaller).
    pub chunk: usize,
    /// Texels between row blocks of the packed texture: `chunk` rounded up to whole
    /// texture rows.
    pub row_stride: usize,
    /// Loop iterations per lane.
    pub run_iters: u32,
    /// Runs per chunk.
    pub n_runs: usize,
}

impl PairPlan {
    /// Plans `n_rows` packed rows (see [`RowLayout::rows_for`]) over `cells` cells.
    pub fn new(
        n_rows: usize,
        cells: usize,
        limits: &PlanLimits,
        shape: KernelShape,
    ) -> Result<Self, GpuError> {
        let side = shape.side();
        let n_pad = n_rows.max(1).div_ceil(side) * side;
        let n_super = n_pad / side;
        let texel_blocks = n_pad / 4;
        let by_texture = (MAX_PACKED_BYTES / (16 * texel_blocks))
            .min(TEX_W * limits.max_texture_dim as usize / texel_blocks)
            / TEX_W
            * TEX_W;
        let mut chunk = by_texture.min(MAX_CHUNK).min(cells.max(1));
        if chunk < shape.lanes.min(cells.max(1)) {
            return Err(GpuError::Limits(format!(
                "{n_rows} rows do not fit a packed texture of {MAX_PACKED_BYTES} bytes and \
                 side {} even {TEX_W} cells at a time",
                limits.max_texture_dim
            )));
        }
        let run_iters = if shape.is_software() {
            MAX_RUN_ITERS
        } else {
            let pairs = n_super * (n_super + 1) / 2;
            let want_runs = 16_384usize.div_ceil(pairs).max(1);
            ((chunk / shape.lanes / want_runs) as u32).clamp(8, MAX_RUN_ITERS)
        };
        let run = shape.lanes * run_iters as usize;
        if chunk > run {
            chunk = chunk / run * run;
        }
        let n_runs = chunk.div_ceil(run);
        if n_runs > limits.max_dispatch as usize {
            return Err(GpuError::Limits(format!(
                "{n_runs} runs per chunk exceed the dispatch limit {}",
                limits.max_dispatch
            )));
        }
        Ok(Self {
            shape,
            n_pad,
            chunk,
            row_stride: chunk.next_multiple_of(TEX_W),
            run_iters,
            n_runs,
        })
    }

    /// Height of the packed texture (width [`TEX_W`]).
    pub fn texture_height(&self) -> u32 {
        (self.n_pad / 4 * self.row_stride / TEX_W) as u32
    }

    /// f32 of per-lane partial sums one register block writes per chunk.
    pub fn partials_per_block(&self) -> usize {
        self.n_runs * self.shape.lanes * self.shape.side() * self.shape.side()
    }
}

/// The register blocks `(I <= J)` (in units of `4R` packed rows) that hold every lobe pair
/// of the requested `BLOCK x BLOCK` block pairs, sorted.
pub fn covering_blocks(
    blocks: &[[u32; 2]],
    layout: &RowLayout,
    shape: KernelShape,
) -> Vec<[u32; 2]> {
    let side = shape.side();
    let n = layout.row.len();
    let mut v = Vec::new();
    for &[bi, bj] in blocks {
        for r in 0..BLOCK {
            for q in 0..BLOCK {
                let (i, j) = (bi as usize * BLOCK + r, bj as usize * BLOCK + q);
                if i < n && j < n {
                    let (a, b) = (layout.row[i] / side, layout.row[j] / side);
                    v.push([a.min(b) as u32, a.max(b) as u32]);
                }
            }
        }
    }
    v.sort_unstable();
    v.dedup();
    v
}
/// The pairwise kernel: pipelines compiled on first use per shape and operation, and the
/// packed texture kept between calls (a fresh texture would be cleared by wgpu first).
#[derive(Debug, Default)]
pub struct PairwiseKernel {
    pipelines: std::sync::Mutex<Vec<((KernelShape, PairOp), wgpu::ComputePipeline)>>,
    texture: std::sync::Mutex<Option<(u32, wgpu::Texture)>>,
}

impl PairwiseKernel {
    /// An empty cache; kernels compile on first use.
    pub fn new() -> Self {
        Self::default()
    }

    /// The pipeline for `shape` and `op`, compiled on first use.
    pub fn pipeline(
        &self,
        ctx: &GpuContext,
        shape: KernelShape,
        op: PairOp,
    ) -> Result<wgpu::ComputePipeline, GpuError> {
        let mut cache = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, p)) = cache.iter().find(|(k, _)| *k == (shape, op)) {
            return Ok(p.clone());
        }
        let label = format!("pairwise ({op:?}, {0}x{0})", shape.side());
        let code = match op {
            PairOp::L1 => 0.0,
            PairOp::Dot => 1.0,
        };
        let p = ctx.pipeline_with(&label, &kernel_source(shape), &[("OP", code)])?;
        cache.push(((shape, op), p.clone()));
        Ok(p)
    }

    /// A packed texture of at least `height` rows (reused when the last one is as tall).
    fn packed_texture(&self, ctx: &GpuContext, height: u32) -> wgpu::Texture {
        let mut slot = self.texture.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((h, t)) = slot.as_ref() {
            if *h >= height {
                return t.clone();
            }
        }
        let t = ctx.packed_texture(
            "packed values",
            height,
            wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        );
        *slot = Some((height, t.clone()));
        t
    }

    /// Drops the cached packed texture (up to [`MAX_PACKED_BYTES`]).
    pub fn release_memory(&self) {
        *self.texture.lock().unwrap_or_else(|e| e.into_inner()) = None;
    }

    /// Reduces `op` of `lobes` over `cells` for the listed `BLOCK x BLOCK` block pairs:
    /// full `n x n`, f64.
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
        let shape = plan.shape;
        let side = shape.side();
        let mut out = vec![0f64; n * n];
        let pipeline = &self.pipeline(ctx, shape, op)?;
        let layout = RowLayout::new(lobes);
        let supers = covering_blocks(blocks, &layout, shape);
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
        let cell_buf = ctx.storage("cells", (plan.chunk * 4) as u64);
        let weight_buf = ctx.storage("row scales", (plan.chunk * 4) as u64);
        let analytic_rows: Vec<Option<LobeParams>> = (0..layout.measured_start)
            .map(|k| match layout.analytic.get(k).map(|&i| &lobes[i]) {
                Some(Lobe::Analytic(p)) => Some(*p),
                _ => None,
            })
            .collect();
        let packed_rows = tab.prepare_packed(ctx, &analytic_rows);
        let texture = self.packed_texture(ctx, plan.texture_height());
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let tables = GridTables::new();
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
            // Measured rows: packed on the host, four rows to a texel, whole texture rows.
            let texture_rows = plan.row_stride / TEX_W;
            for (tb, group) in layout.measured.chunks(4).enumerate() {
                let mut texels = vec![0f32; plan.row_stride * 4];
                for (q, &m) in group.iter().enumerate() {
                    for (c, (&cell, &w)) in cc.iter().zip(cw).enumerate() {
                        texels[4 * c + q] =
                            (op.row_scale(w) * lobes[m].eval_f64(&tables, cell as usize)) as f32;
                    }
                }
                let block = layout.measured_start / 4 + tb;
                ctx.queue.write_texture(
                    wgpu::TexelCopyTextureInfo {
                        texture: &texture,
                        mip_level: 0,
                        origin: wgpu::Origin3d {
                            x: 0,
                            y: (block * texture_rows) as u32,
                            z: 0,
                        },
                        aspect: wgpu::TextureAspect::All,
                    },
                    bytemuck::cast_slice(&texels),
                    wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some((TEX_W * 16) as u32),
                        rows_per_image: None,
                    },
                    wgpu::Extent3d {
                        width: TEX_W as u32,
                        height: texture_rows as u32,
                        depth_or_array_layers: 1,
                    },
                );
            }
            let mut enc = ctx.encoder();
            if !layout.analytic.is_empty() {
                tab.record_pack(
                    ctx,
                    &mut enc,
                    &packed_rows,
                    &cell_buf,
                    &weight_buf,
                    &view,
                    len as u32,
                    plan.row_stride as u32,
                );
            }
            // Register-block groups whose per-lane partials fit one binding; one readback
            // each.
            for off in (0..n_blocks).step_by(per_pass) {
                let count = (n_blocks - off).min(per_pass);
                let params = PairParams {
                    n_cells: len as u32,
                    row_stride: plan.row_stride as u32,
                    run_iters: plan.run_iters,
                    n_runs: plan.n_runs as u32,
                    block_offset: off as u32,
                    n_blocks: (off + count) as u32,
                    _pad0: 0,
                    _pad1: 0,
                };
                let pbuf = ctx.uniform("pairwise params", &params);
                let bind = ctx.bind_at(
                    pipeline,
                    vec![
                        (0, pbuf.as_entire_binding()),
                        (1, wgpu::BindingResource::TextureView(&view)),
                        (2, block_buf.as_entire_binding()),
                        (3, partial.as_entire_binding()),
                    ],
                );
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
                let ss = side * side;
                for (s, blk) in sums[off * ss..(off + count) * ss]
                    .chunks_mut(ss)
                    .zip(part.chunks(per_block / 4))
                {
                    for lane_run in blk.chunks(ss) {
                        for (v, &x) in s.iter_mut().zip(lane_run) {
                            *v += x as f64;
                        }
                    }
                }
            }
            done += len as u64;
            progress(done, total);
        }
        let value = |i: usize, j: usize| {
            let (mut a, mut b) = (layout.row[i], layout.row[j]);
            if a / side > b / side {
                std::mem::swap(&mut a, &mut b);
            }
            let s = supers
                .binary_search(&[(a / side) as u32, (b / side) as u32])
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
