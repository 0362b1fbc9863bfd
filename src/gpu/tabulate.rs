//! Tabulation kernel (`shaders/tabulate.wgsl`): analytic lobes in separable form over a
//! list of grid cells, optionally multiplied by cell weights, written as rows of an output
//! buffer.

use super::{dispatch, GpuContext};
use crate::backend::LobeParams;
use crate::error::GpuError;
use crate::merl::GridTables;
use crate::separable::SeparableLobe;

/// WGSL source of the kernel.
pub const SOURCE: &str = include_str!("../../shaders/tabulate.wgsl");
/// Workgroup size (cells per workgroup).
pub const WORKGROUP: u32 = 64;

/// Uniform parameters; keep in sync with `TabParams` in `shaders/tabulate.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct TabParams {
    /// Cells in this dispatch.
    pub n_cells: u32,
    /// Lobes in this dispatch.
    pub n_lobes: u32,
    /// 1: multiply by `weights[c]`.
    pub weighted: u32,
    /// Distance in f32 between output rows.
    pub row_stride: u32,
}

/// Uniform parameters of the `pack` entry point; keep in sync with `PackParams` in
/// `shaders/tabulate.wgsl`.
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

/// Lobes per invocation; keep in sync with `LPI` in the shader.
pub const LPI: usize = 16;
/// Row blocks (of 4 rows) per invocation of `pack`; keep in sync with `BPI` in the shader.
pub const BPI: usize = 8;

/// Row descriptors and beta tables uploaded for `pack`, in groups of row blocks that fit
/// one binding and one dispatch dimension.
#[derive(Debug)]
pub struct PackRows {
    groups: Vec<PackGroup>,
    alpha: bool,
}

#[derive(Debug)]
struct PackGroup {
    first_block: u32,
    n_blocks: u32,
    betas: wgpu::TextureView,
}
/// f32 of one lobe's beta table.
pub const NIJ: usize = 8100;

/// The compiled kernel and its grid tables.
#[derive(Debug)]
pub struct TabulateKernel {
    pipeline: wgpu::ComputePipeline,
    pack: wgpu::ComputePipeline,
    pack_specular: wgpu::ComputePipeline,
    tables: wgpu::Buffer,
}

/// Lobes uploaded once in separable form (alpha, beta tables, output rows), in groups that
/// fit one binding and one dispatch dimension.
#[derive(Debug)]
pub struct TabLobes {
    groups: Vec<(wgpu::Buffer, wgpu::Buffer, wgpu::Buffer, u32)>,
}

/// The f32 alpha and beta of a lobe, as uploaded (beta: f64 rounded once).
pub fn separable_f32(t: &GridTables, l: &LobeParams) -> (f32, Vec<f32>) {
    let s = SeparableLobe::new(t, l);
    (s.alpha as f32, s.beta.iter().map(|&b| b as f32).collect())
}

impl TabulateKernel {
    /// Compiles the kernel and uploads the grid tables.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let pipeline = ctx.pipeline("tabulate", SOURCE)?;
        let pack = ctx.pipeline_entry("tabulate (pack)", SOURCE, "pack", &[])?;
        let pack_specular = ctx.pipeline_entry(
            "tabulate (pack, no alpha)",
            SOURCE,
            "pack",
            &[("HAS_ALPHA", 0.0)],
        )?;
        let t = super::grid_table_f32(&GridTables::new());
        let tables = ctx.uniform_slice("grid tables", &t);
        Ok(Self {
            pipeline,
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
        use super::pairwise::TEX_W;
        let by_texture = (TEX_W * ctx.limits.max_texture_dimension_2d as usize / (NIJ + 1)).max(1);
        let by_dim = ctx.limits.max_compute_workgroups_per_dimension.max(1) as usize * BPI;
        let per = by_texture.min(by_dim);
        let groups = rows
            .chunks(4 * per)
            .enumerate()
            .map(|(g, blocks)| {
                // Per row block: NIJ texels of four betas, then one of four alphas; zeros
                // for padding rows.
                let mut texels = vec![0f32; blocks.len() / 4 * (NIJ + 1) * 4];
                for (r, l) in blocks.iter().enumerate() {
                    if let Some(l) = l {
                        let (a, b) = separable_f32(&t, l);
                        let (base, q) = (r / 4 * (NIJ + 1), r % 4);
                        for (e, &beta) in b.iter().enumerate() {
                            texels[4 * (base + e) + q] = beta;
                        }
                        texels[4 * (base + NIJ) + q] = a;
                    }
                }
                PackGroup {
                    first_block: (g * per) as u32,
                    n_blocks: (blocks.len() / 4) as u32,
                    betas: ctx.linear_texture("beta tables", &texels, 4),
                }
            })
            .collect();
        // alpha = kd / pi (src/separable.rs).
        let alpha = rows.iter().flatten().any(|l| l.kd != 0.0);
        PackRows { groups, alpha }
    }

    /// Records the fill of the analytic row blocks of the packed texture `packed` for one
    /// chunk of `n_cells` cells (`weights`: each cell's row scale; `chunk`: texels between
    /// row blocks).
    #[allow(clippy::too_many_arguments)]
    pub fn record_pack(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        rows: &PackRows,
        cells: &wgpu::Buffer,
        weights: &wgpu::Buffer,
        packed: &wgpu::TextureView,
        n_cells: u32,
        chunk: u32,
    ) {
        let pipeline = if rows.alpha {
            &self.pack
        } else {
            &self.pack_specular
        };
        for g in &rows.groups {
            let params = PackParams {
                n_cells,
                chunk,
                first_block: g.first_block,
                n_blocks: g.n_blocks,
            };
            let pbuf = ctx.uniform("pack params", &params);
            let bind = ctx.bind_at(
                pipeline,
                vec![
                    (1, self.tables.as_entire_binding()),
                    (4, cells.as_entire_binding()),
                    (5, weights.as_entire_binding()),
                    (8, pbuf.as_entire_binding()),
                    (11, wgpu::BindingResource::TextureView(packed)),
                    (12, wgpu::BindingResource::TextureView(&g.betas)),
                ],
            );
            dispatch(
                encoder,
                pipeline,
                &bind,
                (n_cells.div_ceil(WORKGROUP), g.n_blocks.div_ceil(BPI as u32)),
            );
        }
    }

    /// Uploads `lobes` (lobe `l` goes to output row `rows[l]`).
    pub fn prepare(&self, ctx: &GpuContext, lobes: &[LobeParams], rows: &[u32]) -> TabLobes {
        assert_eq!(lobes.len(), rows.len());
        let t = GridTables::new();
        let by_binding = (ctx.max_binding() as usize / (NIJ * 4)).max(1);
        let by_dim = ctx.limits.max_compute_workgroups_per_dimension.max(1) as usize * LPI;
        let per = by_binding.min(by_dim);
        let groups = lobes
            .chunks(per)
            .zip(rows.chunks(per))
            .map(|(lb, rb)| {
                let mut alphas = Vec::with_capacity(lb.len());
                let mut betas = Vec::with_capacity(lb.len() * NIJ);
                for l in lb {
                    let (a, b) = separable_f32(&t, l);
                    alphas.push(a);
                    betas.extend(b);
                }
                (
                    ctx.storage_init(
                        "alphas",
                        bytemuck::cast_slice(&alphas),
                        wgpu::BufferUsages::empty(),
                    ),
                    ctx.storage_init(
                        "rows",
                        bytemuck::cast_slice(rb),
                        wgpu::BufferUsages::empty(),
                    ),
                    ctx.storage_init(
                        "betas",
                        bytemuck::cast_slice(&betas),
                        wgpu::BufferUsages::empty(),
                    ),
                    lb.len() as u32,
                )
            })
            .collect();
        TabLobes { groups }
    }

    /// Records the tabulation of the prepared lobes over the `n_cells` cells of `cells`,
    /// into `out[row * row_stride + c]`, times `weights[c]` if given.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        lobes: &TabLobes,
        cells: &wgpu::Buffer,
        weights: Option<&wgpu::Buffer>,
        out: &wgpu::Buffer,
        n_cells: u32,
        row_stride: u32,
    ) {
        for (alphas, rows, betas, count) in &lobes.groups {
            let params = TabParams {
                n_cells,
                n_lobes: *count,
                weighted: u32::from(weights.is_some()),
                row_stride,
            };
            let pbuf = ctx.uniform("tabulate params", &params);
            let wbuf = weights.unwrap_or(cells);
            let bind = ctx.bind(
                &self.pipeline,
                &[&pbuf, &self.tables, alphas, rows, cells, wbuf, out, betas],
            );
            dispatch(
                encoder,
                &self.pipeline,
                &bind,
                (n_cells.div_ceil(WORKGROUP), count.div_ceil(LPI as u32)),
            );
        }
    }

    /// Tabulates `lobes` over `cells` and reads the values back (`out[l * cells.len() + c]`),
    /// in chunks of cells that fit the device's storage-binding limit.
    pub fn tabulate(
        &self,
        ctx: &GpuContext,
        lobes: &[LobeParams],
        cells: &[u32],
    ) -> Result<Vec<f32>, GpuError> {
        let n = cells.len();
        let mut out = vec![0f32; lobes.len() * n];
        if n == 0 || lobes.is_empty() {
            return Ok(out);
        }
        let max_dim = ctx.limits.max_compute_workgroups_per_dimension as usize * WORKGROUP as usize;
        let per_lobe = (ctx.max_binding() / 4) as usize;
        let lobes_per_pass = lobes.len().min(per_lobe / 1024).max(1);
        for (lb_idx, lb) in lobes.chunks(lobes_per_pass).enumerate() {
            let chunk = (per_lobe / lb.len()).min(max_dim).min(n).max(1);
            let rows: Vec<u32> = (0..lb.len() as u32).collect();
            let prepared = self.prepare(ctx, lb, &rows);
            for start in (0..n).step_by(chunk) {
                let cc = &cells[start..(start + chunk).min(n)];
                let cbuf = ctx.storage_init(
                    "cells",
                    bytemuck::cast_slice(cc),
                    wgpu::BufferUsages::empty(),
                );
                let bytes = (lb.len() * cc.len() * 4) as u64;
                let obuf = ctx.storage("tabulated", bytes);
                let mut enc = ctx.encoder();
                self.record(
                    ctx,
                    &mut enc,
                    &prepared,
                    &cbuf,
                    None,
                    &obuf,
                    cc.len() as u32,
                    cc.len() as u32,
                );
                let data = ctx.submit_and_read(enc, &obuf, bytes)?;
                let vals: &[f32] = bytemuck::cast_slice(&data[..bytes as usize]);
                for (r, row) in vals.chunks(cc.len()).enumerate() {
                    let l = lb_idx * lobes_per_pass + r;
                    out[l * n + start..l * n + start + cc.len()].copy_from_slice(row);
                }
            }
        }
        Ok(out)
    }
}

/// CPU twin of the shader: the same f32 operations on the same f32 tables (used by tests
/// to separate kernel bugs from rounding).
pub fn lobe_value_twin(table: &[f32], alpha: f32, beta: &[f32], cell: u32, w: f32) -> f32 {
    use super::*;
    let (i, j, k) = (
        (cell / 16200) as usize,
        ((cell / 180) % 90) as usize,
        (cell % 180) as usize,
    );
    let cos_d = table[TABLE_COS_D + j];
    let max_cos = table[TABLE_COS_H + i] * cos_d
        + table[TABLE_SIN_H + i] * table[TABLE_SIN_D + j] * table[TABLE_ABS_COS_P + k];
    let gw = w / (cos_d * max_cos);
    alpha * w + beta[i * 90 + j] * gw
}
