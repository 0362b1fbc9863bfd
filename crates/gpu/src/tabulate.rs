//! Tabulation kernel (`tabulate.wgsl`): analytic lobes in separable form over a
//! list of grid cells, multiplied by per-cell row scales, packed four rows to a texel of an
//! rgba32float texture ([`TabulateKernel::encode_pack`]; the layout of the pairwise
//! kernel's measured row blocks); [`TabulateKernel::tabulate`] reads it back into planar
//! rows. (The pairwise kernel itself tabulates analytic lobes in registers.)

use super::readback::{PackedStream, Unpack};
use super::{dispatch, GpuContext};
use brdf_basis_core::brdf::LobeParams;
use brdf_basis_core::error::GpuError;
use brdf_basis_core::merl::GridTables;
use brdf_basis_core::separable::SeparableLobe;

/// WGSL source of the kernel.
pub const SOURCE: &str = include_str!("tabulate.wgsl");
/// Workgroup size (cells per workgroup).
pub const WORKGROUP: u32 = 64;

/// Uniform parameters of the kernel; keep in sync with `PackParams` in
/// `tabulate.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PackParams {
    /// Cells in this chunk.
    pub n_cells: u32,
    /// Texels between consecutive row blocks of the packed texture (cells per chunk).
    pub chunk: u32,
    /// First row block of this dispatch.
    pub first_block: u32,
    /// Row blocks in this dispatch.
    pub n_blocks: u32,
}

/// Row blocks (of 4 rows) per invocation of `pack`; keep in sync with `BPI` in the shader.
pub const BPI: usize = 8;

/// Beta and alpha tables uploaded for `pack`, in groups of row blocks that fit one
/// texture and one dispatch dimension.
#[derive(Debug)]
pub struct PackRows {
    groups: Vec<PackGroup>,
    alpha: bool,
}

/// Where `pack` writes: a packed texture of row blocks `chunk` texels apart, and the
/// chunk's cells with unit row scales.
#[derive(Debug)]
pub struct PackTarget {
    /// The texture (storage, plus the caller's usage).
    pub texture: wgpu::Texture,
    view: wgpu::TextureView,
    cells: wgpu::Buffer,
    weights: wgpu::Buffer,
    /// Texels between row blocks (a multiple of `TEX_W`).
    pub chunk: usize,
}

impl PackTarget {
    /// A target for `blocks` row blocks of `chunk` cells (`chunk` a multiple of `TEX_W`).
    pub fn new(ctx: &GpuContext, blocks: usize, chunk: usize, usage: wgpu::TextureUsages) -> Self {
        use super::TEX_W;
        assert_eq!(chunk % TEX_W, 0, "whole texture rows per row block");
        let texture = ctx.packed_texture(
            "packed rows",
            (blocks * chunk / TEX_W) as u32,
            wgpu::TextureUsages::STORAGE_BINDING | usage,
        );
        let ones = vec![1f32; chunk];
        Self {
            view: texture.create_view(&wgpu::TextureViewDescriptor::default()),
            texture,
            cells: ctx.storage("cells", (chunk * 4) as u64),
            weights: ctx.storage_init(
                "unit weights",
                bytemuck::cast_slice(&ones),
                wgpu::BufferUsages::empty(),
            ),
            chunk,
        }
    }
}

#[derive(Debug)]
struct PackGroup {
    first_block: u32,
    n_blocks: u32,
    betas: wgpu::TextureView,
}
/// The separable tables of rows (`rows.len()` a multiple of 4) as rgba texels: per block
/// of four rows, NIJ texels of their four betas, then one of their four alphas (f64
/// rounded once); zeros for padding rows (`None`). The pairwise kernel and `pack` read
/// this layout.
pub(crate) fn separable_texels(t: &GridTables, rows: &[Option<LobeParams>]) -> Vec<f32> {
    use rayon::prelude::*;
    let mut texels = vec![0f32; rows.len() / 4 * (NIJ + 1) * 4];
    // Row blocks in parallel (each lobe's table costs 8,100 exp/pow in f64).
    texels
        .par_chunks_mut((NIJ + 1) * 4)
        .zip(rows.par_chunks(4))
        .for_each(|(block, quad)| {
            for (q, l) in quad.iter().enumerate() {
                if let Some(l) = l {
                    let (a, b) = separable_f32(t, l);
                    for (e, &beta) in b.iter().enumerate() {
                        block[4 * e + q] = beta;
                    }
                    block[4 * NIJ + q] = a;
                }
            }
        });
    texels
}

use super::NIJ;

/// The compiled kernel and its grid tables.
#[derive(Debug)]
pub struct TabulateKernel {
    pack: wgpu::ComputePipeline,
    pack_specular: wgpu::ComputePipeline,
    tables: wgpu::Buffer,
}

/// The f32 alpha and beta of a lobe, as uploaded (beta: f64 rounded once).
pub(crate) fn separable_f32(t: &GridTables, l: &LobeParams) -> (f32, Vec<f32>) {
    let s = SeparableLobe::new(t, l);
    (s.alpha as f32, s.beta.iter().map(|&b| b as f32).collect())
}

impl TabulateKernel {
    /// Compiles the kernel and uploads the grid tables.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let pack = ctx.pipeline("tabulate", SOURCE)?;
        let pack_specular =
            ctx.pipeline_with("tabulate (no alpha)", SOURCE, &[("HAS_ALPHA", 0.0)])?;
        let t = super::grid_table_f32(&GridTables::new());
        let tables = ctx.uniform_slice("grid tables", &t);
        Ok(Self {
            pack,
            pack_specular,
            tables,
        })
    }

    /// Uploads the analytic rows of a packed texture (`rows.len()` a multiple of 4; `None`:
    /// a padding row of zeros).
    pub fn prepare_packed(&self, ctx: &GpuContext, rows: &[Option<LobeParams>]) -> PackRows {
        assert_eq!(rows.len() % 4, 0, "whole row blocks");
        let t = GridTables::new();
        use super::TEX_W;
        let by_texture = (TEX_W * ctx.limits.max_texture_dimension_2d as usize / (NIJ + 1)).max(1);
        let by_dim = ctx.limits.max_compute_workgroups_per_dimension.max(1) as usize * BPI;
        let per = by_texture.min(by_dim);
        let groups = rows
            .chunks(4 * per)
            .enumerate()
            .map(|(g, blocks)| {
                let texels = separable_texels(&t, blocks);
                PackGroup {
                    first_block: (g * per) as u32,
                    n_blocks: (blocks.len() / 4) as u32,
                    betas: ctx.linear_texture("beta tables", &texels),
                }
            })
            .collect();
        // alpha = kd / pi (crates/core/src/separable.rs).
        let alpha = rows.iter().flatten().any(|l| l.kd != 0.0);
        PackRows { groups, alpha }
    }

    /// Uploads `cells` (at most `target.chunk`) and records the fill of the analytic row
    /// blocks of `target`'s texture, with unit row scales.
    pub fn encode_pack(
        &self,
        ctx: &GpuContext,
        rows: &PackRows,
        target: &PackTarget,
        cells: &[u32],
    ) -> wgpu::CommandEncoder {
        ctx.queue
            .write_buffer(&target.cells, 0, bytemuck::cast_slice(cells));
        let mut encoder = ctx.encoder();
        let pipeline = if rows.alpha {
            &self.pack
        } else {
            &self.pack_specular
        };
        let n_cells = cells.len() as u32;
        for g in &rows.groups {
            let params = PackParams {
                n_cells,
                chunk: target.chunk as u32,
                first_block: g.first_block,
                n_blocks: g.n_blocks,
            };
            let pbuf = ctx.uniform("pack params", &params);
            let bind = ctx.bind_at(
                pipeline,
                vec![
                    (0, pbuf.as_entire_binding()),
                    (1, self.tables.as_entire_binding()),
                    (2, target.cells.as_entire_binding()),
                    (3, target.weights.as_entire_binding()),
                    (4, wgpu::BindingResource::TextureView(&target.view)),
                    (5, wgpu::BindingResource::TextureView(&g.betas)),
                ],
            );
            dispatch(
                &mut encoder,
                pipeline,
                &bind,
                (n_cells.div_ceil(WORKGROUP), g.n_blocks.div_ceil(BPI as u32)),
            );
        }
        encoder
    }

    /// Tabulates `lobes` over `cells` and reads the values back (`out[l * cells.len() + c]`):
    /// packed on the GPU in chunks of cells, each copied out while the next is computed
    /// and unpacked on the host in parallel ([`PackedStream`]).
    pub fn tabulate(
        &self,
        ctx: &GpuContext,
        lobes: &[LobeParams],
        cells: &[u32],
    ) -> Result<Vec<f32>, GpuError> {
        let mut out = vec![0f32; lobes.len() * cells.len()];
        self.tabulate_into(ctx, lobes, cells, &mut out)?;
        Ok(out)
    }

    /// [`Self::tabulate`] into `out` (`lobes.len() * cells.len()` values).
    pub fn tabulate_into(
        &self,
        ctx: &GpuContext,
        lobes: &[LobeParams],
        cells: &[u32],
        out: &mut [f32],
    ) -> Result<(), GpuError> {
        let n = cells.len();
        assert_eq!(out.len(), lobes.len() * n, "one row per lobe");
        if n == 0 || lobes.is_empty() {
            return Ok(());
        }
        // Batches of lobes and chunks of cells whose texture fits the budget.
        let max_blocks = ctx.pack_max_blocks();
        let mut stream = PackedStream::new(ctx);
        for (batch, lb) in lobes.chunks(4 * max_blocks).enumerate() {
            let mut rows: Vec<Option<LobeParams>> = lb.iter().map(|&l| Some(l)).collect();
            rows.resize(lb.len().div_ceil(4) * 4, None);
            let blocks = rows.len() / 4;
            let prepared = self.prepare_packed(ctx, &rows);
            let chunk = ctx.pack_chunk(blocks, n, usize::MAX);
            let target = PackTarget::new(ctx, blocks, chunk, wgpu::TextureUsages::COPY_SRC);
            for (k, cc) in cells.chunks(chunk).enumerate() {
                let enc = self.encode_pack(ctx, &prepared, &target, cc);
                let at = Unpack {
                    chunk,
                    rows: lb.len(),
                    row0: batch * 4 * max_blocks,
                    n,
                    start: k * chunk,
                    len: cc.len(),
                };
                stream.push(ctx, enc, &target.texture, at, out)?;
            }
        }
        stream.finish(ctx, out)
    }
}
