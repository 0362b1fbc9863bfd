//! Pairwise reduction kernel (`shaders/pairwise.wgsl`) and its chunked driver.
//!
//! Rows live four to a texel ("row block") of one rgba32float value texture. Analytic
//! lobes are never stored per cell: their row blocks hold the separable form's tables
//! (8,100 betas and the alphas, uploaded once), and the kernel tabulates them in registers
//! at each cell from a per-cell texel `(e, g, w)` the host computes in f64. Measured lobes
//! are packed per chunk of cells by the host. One dispatch per chunk reduces every
//! requested register block of `4R x 4R` lobe pairs over every run of cells. Per-lane
//! partial sums (f32 over at most `MAX_RUN_ITERS` cells) are read back and accumulated in
//! f64 on the host.
//!
//! The kernel body is unrolled here ([`kernel_source`]) for a [`KernelShape`]: on lavapipe
//! large blocks (R = 4 to 6: up to 24 x 24 pairs from 12 texel fetches per cell) amortise
//! the fetches, and [`KernelShape::choose`] picks the one that pads the collection least;
//! on a hardware GPU R = 2 keeps the 64 accumulators in registers.
//!
//! Rows are laid out by [`RowLayout`] (analytic lobes first, then measured ones, so that
//! no row block mixes tables and per-cell values); [`covering_blocks`] maps the caller's
//! `BLOCK x BLOCK` block pairs onto the register blocks that hold them.

use super::tabulate::{separable_texels, NIJ};
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
/// Workgroups per dispatch the hardware plan aims at.
pub const HARDWARE_WORKGROUPS: usize = 4096;
/// Most bytes of measured rows in the value texture (bounds the chunk for large measured
/// collections).
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

/// lavapipe shapes and their rates (G evaluated pair-cells/s, best of three, measured by
/// `BENCH_SHAPES=1 cargo bench --bench distance` on 2 cores of an AMD EPYC with lavapipe
/// 22.3 at N = 100 and 240; one 8-wide SIMD row per workgroup). Smaller blocks re-fetch
/// too often (4 x 4 pairs per invocation ran at 4.7, 8 x 8 at 10.7 in a first probe);
/// 24 x 24 spills.
const SOFTWARE_SHAPES: [(KernelShape, f64); 3] = [
    (KernelShape { r: 4, lanes: 8 }, 15.4),
    (KernelShape { r: 5, lanes: 8 }, 17.3),
    (KernelShape { r: 6, lanes: 8 }, 14.6),
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
        let cost = |(s, rate): &(KernelShape, f64)| s.evaluated_pairs(n_rows) / rate;
        SOFTWARE_SHAPES
            .iter()
            .min_by(|a, b| cost(a).total_cmp(&cost(b)))
            .map(|s| s.0)
            .unwrap_or(Self::HARDWARE)
    }

    /// Lobe pairs the kernel evaluates per cell for `n_rows` rows (padding included; a
    /// diagonal register block evaluates its texel pairs `i <= j`).
    pub fn evaluated_pairs(&self, n_rows: usize) -> f64 {
        let nb = n_rows.max(1).div_ceil(self.side()) as f64;
        let block = (self.side() * self.side()) as f64;
        let diagonal = block * (self.r + 1) as f64 / (2 * self.r) as f64;
        nb * (nb - 1.0) / 2.0 * block + nb * diagonal
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
/// expanded into the unrolled register block. `diagonal`: the variant for register blocks
/// on the diagonal (`I = J`), which fetches the `R` texels once and accumulates only the
/// texel pairs `(i <= j)` (the rest mirror them).
pub fn kernel_source(shape: KernelShape, diagonal: bool) -> String {
    let (r, side) = (shape.r, shape.side());
    const XYZW: [char; 4] = ['x', 'y', 'z', 'w'];
    // Accumulator (row i of the block, texel j of the columns) is computed?
    let live = |i: usize, j: usize| !diagonal || i / 4 <= j;
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
        let pairs = || (0..side).flat_map(|i| (0..r).map(move |j| (i, j)));
        match line.trim() {
            "//@DECLARE" => pairs()
                .filter(|&(i, j)| live(i, j))
                .for_each(|(i, j)| emit(format!("var acc_{i}_{j} = vec4<f32>(0.0);"))),
            "//@SOURCES" => {
                (0..r).for_each(|i| emit(format!("let sa{i} = source(ra + {i}u);")));
                if !diagonal {
                    (0..r).for_each(|j| emit(format!("let sb{j} = source(rb + {j}u);")));
                }
            }
            "//@FETCH" => {
                (0..r).for_each(|i| emit(format!("let a{i} = rows(sa{i}, c, e, info.y, info.z);")));
                (0..r).for_each(|j| {
                    emit(if diagonal {
                        format!("let b{j} = a{j};")
                    } else {
                        format!("let b{j} = rows(sb{j}, c, e, info.y, info.z);")
                    })
                });
            }
            "//@ACCUMULATE" => pairs().filter(|&(i, j)| live(i, j)).for_each(|(i, j)| {
                emit(format!(
                    "acc_{i}_{j} = step(acc_{i}_{j}, a{}.{}, b{j});",
                    i / 4,
                    XYZW[i % 4]
                ))
            }),
            "//@STORE" => pairs().filter(|&(i, j)| live(i, j)).for_each(|(i, j)| {
                (0..4).for_each(|q| {
                    emit(format!(
                        "partial[o + {}u] = acc_{i}_{j}.{};",
                        i * side + 4 * j + q,
                        XYZW[q]
                    ))
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

/// Where each lobe sits in the value texture: analytic lobes first (tabulated in
/// registers from their tables), padded to a whole texel, then measured lobes (packed per
/// cell by the host), so
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

/// f32 per row block of an analytic table: 8,100 betas and the alphas, four rows each.
const TABLE_TEXELS: usize = NIJ + 1;

/// How a pairwise reduction is cut into chunks, runs and dispatches, and where its rows
/// sit in the value texture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairPlan {
    /// Register block and workgroup.
    pub shape: KernelShape,
    /// Packed rows padded to a multiple of the block side `4R`.
    pub n_pad: usize,
    /// Analytic row blocks (4 rows each; the last one may be part padding).
    pub analytic_blocks: usize,
    /// Measured row blocks.
    pub measured_blocks: usize,
    /// Cells per chunk (a multiple of `lanes x run_iters` unless the whole set is smaller).
    pub chunk: usize,
    /// Texels between measured row blocks: `chunk` rounded up to whole texture rows.
    pub row_stride: usize,
    /// Loop iterations per lane.
    pub run_iters: u32,
    /// Runs per chunk.
    pub n_runs: usize,
}

impl PairPlan {
    /// Plans `n_analytic` analytic and `n_measured` measured lobes over `cells` cells.
    pub fn new(
        n_analytic: usize,
        n_measured: usize,
        cells: usize,
        limits: &PlanLimits,
        shape: KernelShape,
    ) -> Result<Self, GpuError> {
        let n_rows = RowLayout::rows_for(n_analytic, n_measured);
        let side = shape.side();
        let n_pad = n_rows.max(1).div_ceil(side) * side;
        let n_super = n_pad / side;
        let analytic_blocks = n_analytic.div_ceil(4);
        let measured_blocks = n_measured.div_ceil(4);
        let max_dim = limits.max_texture_dim as usize;
        let table_rows = table_rows(analytic_blocks);
        if table_rows > max_dim {
            return Err(GpuError::Limits(format!(
                "{n_analytic} analytic lobes need {table_rows} texture rows of tables; the \
                 adapter allows {max_dim}"
            )));
        }
        let by_texture = if measured_blocks == 0 {
            MAX_CHUNK
        } else {
            (MAX_PACKED_BYTES / (16 * measured_blocks))
                .min((max_dim - table_rows) * TEX_W / measured_blocks)
                / TEX_W
                * TEX_W
        };
        let mut chunk = by_texture.min(MAX_CHUNK).min(cells.max(1));
        if chunk < shape.lanes.min(cells.max(1)) {
            return Err(GpuError::Limits(format!(
                "{n_measured} measured lobes do not fit a texture of {MAX_PACKED_BYTES} bytes \
                 and side {max_dim} even {TEX_W} cells at a time"
            )));
        }
        let run_iters = if shape.is_software() {
            MAX_RUN_ITERS
        } else {
            // About HARDWARE_WORKGROUPS workgroups per dispatch: enough to fill a large GPU
            // (4,096 x 64 lanes is ~30 warps per SM of an H100), while the per-lane
            // partials the host sums in f64 stay few (they scale with the run count).
            let pairs = n_super * (n_super + 1) / 2;
            let want_runs = HARDWARE_WORKGROUPS.div_ceil(pairs).max(1);
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
            analytic_blocks,
            measured_blocks,
            chunk,
            row_stride: chunk.next_multiple_of(TEX_W),
            run_iters,
            n_runs,
        })
    }

    /// Texel of the all-zero table (after the analytic tables).
    pub fn zero_base(&self) -> usize {
        self.analytic_blocks * TABLE_TEXELS
    }

    /// Texel of the first measured block's cell 0 (after the tables, on a whole row).
    pub fn measured_base(&self) -> usize {
        table_rows(self.analytic_blocks) * TEX_W
    }

    /// Height of the value texture (width [`TEX_W`]).
    pub fn texture_height(&self) -> u32 {
        (table_rows(self.analytic_blocks) + self.measured_blocks * self.row_stride / TEX_W) as u32
    }

    /// f32 of per-lane partial sums one register block writes per chunk.
    pub fn partials_per_block(&self) -> usize {
        self.n_runs * self.shape.lanes * self.shape.side() * self.shape.side()
    }
}

/// Texture rows of `blocks` analytic tables and the zero table.
fn table_rows(blocks: usize) -> usize {
    ((blocks + 1) * TABLE_TEXELS).div_ceil(TEX_W)
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
            Lobe::Measured { .. } => None,
        })
        .collect();
    rows.resize(4 * (blocks + 1), None);
    let mut texels = separable_texels(&GridTables::new(), &rows);
    texels.resize(table_rows(blocks) * TEX_W * 4, 0.0);
    texels
}

/// Writes `texels` (rgba) into whole rows of `texture` from row `first_row`.
fn write_rows(ctx: &GpuContext, texture: &wgpu::Texture, first_row: usize, texels: &[f32]) {
    let rows = texels.len() / (4 * TEX_W);
    ctx.queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d {
                x: 0,
                y: first_row as u32,
                z: 0,
            },
            aspect: wgpu::TextureAspect::All,
        },
        bytemuck::cast_slice(texels),
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some((TEX_W * 16) as u32),
            rows_per_image: None,
        },
        wgpu::Extent3d {
            width: TEX_W as u32,
            height: rows as u32,
            depth_or_array_layers: 1,
        },
    );
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
/// A compiled variant: shape, operation, diagonal or not.
type PipelineKey = (KernelShape, PairOp, bool);

/// The pairwise kernel: pipelines compiled on first use per shape and operation, and the
/// value texture kept between calls (a fresh texture would be cleared by wgpu first).
#[derive(Debug, Default)]
pub struct PairwiseKernel {
    pipelines: std::sync::Mutex<Vec<(PipelineKey, wgpu::ComputePipeline)>>,
    texture: std::sync::Mutex<Option<(u32, wgpu::Texture)>>,
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
        let key = (shape, op, diagonal);
        let mut cache = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, p)) = cache.iter().find(|(k, _)| *k == key) {
            return Ok(p.clone());
        }
        let label = format!(
            "pairwise ({op:?}, {0}x{0}{1})",
            shape.side(),
            if diagonal { ", diagonal" } else { "" }
        );
        let code = match op {
            PairOp::L1 => 0.0,
            PairOp::Dot => 1.0,
        };
        let src = kernel_source(shape, diagonal);
        let p = ctx.pipeline_with(&label, &src, &[("OP", code)])?;
        cache.push((key, p.clone()));
        Ok(p)
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
                wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
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
                layout.measured.len().div_ceil(4)
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
        let (height, texture) = self.value_texture(ctx, plan.texture_height());
        write_rows(
            ctx,
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
        let tables = GridTables::new();
        let total = cells.len() as u64;
        let mut done = 0u64;
        for (cc, cw) in cells
            .cells
            .chunks(plan.chunk)
            .zip(cells.weights.chunks(plan.chunk))
        {
            let len = cc.len();
            // Per cell (e, g, w, 0): table index, separable factor times the row scale,
            // row scale; f64 rounded once.
            let mut texels = vec![0f32; plan.row_stride * 4];
            for ((t, &c), &w) in texels.chunks_exact_mut(4).zip(cc).zip(cw) {
                let (e, g) = tables.cell_factor(c as usize);
                let w = op.row_scale(w);
                t.copy_from_slice(&[e as f32, (g * w) as f32, w as f32, 0.0]);
            }
            write_rows(ctx, &info, 0, &texels);
            // Measured rows: scaled and packed on the host, four rows to a texel.
            for (m, group) in layout.measured.chunks(4).enumerate() {
                texels.fill(0.0);
                for (q, &i) in group.iter().enumerate() {
                    for (c, (&cell, &w)) in cc.iter().zip(cw).enumerate() {
                        texels[4 * c + q] =
                            (op.row_scale(w) * lobes[i].eval_f64(&tables, cell as usize)) as f32;
                    }
                }
                write_rows(
                    ctx,
                    &texture,
                    plan.measured_base() / TEX_W + m * info_rows,
                    &texels,
                );
            }
            let mut enc = ctx.encoder();
            // Register-block groups whose per-lane partials fit one binding; one readback
            // each.
            let groups = [(0, n_diagonal), (n_diagonal, n_blocks)]
                .into_iter()
                .zip(&pipelines)
                .flat_map(|((lo, hi), p)| {
                    (lo..hi)
                        .step_by(per_pass)
                        .map(move |off| (off, (hi - off).min(per_pass), p))
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
                        (1, wgpu::BindingResource::TextureView(&view)),
                        (2, block_buf.as_entire_binding()),
                        (3, partial.as_entire_binding()),
                        (4, wgpu::BindingResource::TextureView(&info_view)),
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
