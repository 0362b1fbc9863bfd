//! Tabulation kernel (`shaders/tabulate.wgsl`): analytic lobes over a list of grid cells,
//! optionally multiplied by cell weights, written as rows of an output buffer.

use super::{dispatch, GpuContext};
use crate::backend::LobeParams;
use crate::error::GpuError;

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

/// The compiled kernel and its grid tables.
#[derive(Debug)]
pub struct TabulateKernel {
    pipeline: wgpu::ComputePipeline,
    tables: wgpu::Buffer,
}

impl TabulateKernel {
    /// Compiles the kernel and uploads the grid tables.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let pipeline = ctx.pipeline("tabulate", SOURCE)?;
        let t = super::grid_table_f32(&crate::merl::GridTables::new());
        let tables = ctx.storage_init(
            "grid tables",
            bytemuck::cast_slice(&t),
            wgpu::BufferUsages::empty(),
        );
        Ok(Self { pipeline, tables })
    }

    /// Records the tabulation of `lobes` (lobe `l` into row `rows[l]`) over the `n_cells`
    /// cells of `cells`, into `out[row * row_stride + c]`, times `weights[c]` if given.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        lobes: &[LobeParams],
        rows: &[u32],
        cells: &wgpu::Buffer,
        weights: Option<&wgpu::Buffer>,
        out: &wgpu::Buffer,
        n_cells: u32,
        row_stride: u32,
    ) {
        assert_eq!(lobes.len(), rows.len());
        let max_dim = ctx.limits.max_compute_workgroups_per_dimension.max(1) as usize;
        for (lb, rb) in lobes.chunks(max_dim).zip(rows.chunks(max_dim)) {
            let params = TabParams {
                n_cells,
                n_lobes: lb.len() as u32,
                weighted: u32::from(weights.is_some()),
                row_stride,
            };
            let pbuf = ctx.uniform("tabulate params", &params);
            let lbuf = ctx.storage_init(
                "lobes",
                bytemuck::cast_slice(lb),
                wgpu::BufferUsages::empty(),
            );
            let rbuf = ctx.storage_init(
                "rows",
                bytemuck::cast_slice(rb),
                wgpu::BufferUsages::empty(),
            );
            let wbuf = weights.unwrap_or(cells);
            let bind = ctx.bind(
                &self.pipeline,
                &[&pbuf, &self.tables, &lbuf, &rbuf, cells, wbuf, out],
            );
            dispatch(
                encoder,
                &self.pipeline,
                &bind,
                (n_cells.div_ceil(WORKGROUP), lb.len() as u32),
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
                    lb,
                    &rows,
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

/// CPU twin of `lobe_value` in `shaders/tabulate.wgsl`: the same f32 operations on the
/// same f32 tables (used by tests to separate kernel bugs from rounding).
pub fn lobe_value_twin(table: &[f32], l: &LobeParams, cell: u32) -> f32 {
    use super::*;
    let (i, j, k) = (
        (cell / 16200) as usize,
        ((cell / 180) % 90) as usize,
        (cell % 180) as usize,
    );
    let cos_d = table[TABLE_COS_D + j];
    let max_cos = table[TABLE_COS_H + i] * cos_d
        + table[TABLE_SIN_H + i] * table[TABLE_SIN_D + j] * table[TABLE_ABS_COS_P + k];
    let fresnel = l.f0 + (1.0 - l.f0) * table[TABLE_SCHLICK_D + j];
    let peak = (l.n * table[TABLE_LOG2_COS_H + i]).exp2();
    let spec =
        (l.n + 1.0) * peak * fresnel * (1.0 / (8.0 * std::f32::consts::PI)) / (cos_d * max_cos);
    l.kd * std::f32::consts::FRAC_1_PI + l.ks * spec
}
