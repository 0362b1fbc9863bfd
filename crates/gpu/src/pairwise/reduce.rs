//! The f64 totals of a pairwise reduction, added on the device (`pairwise/reduce_f64.wgsl`)
//! where the adapter computes in f64, in the order the host's [`super::accumulate`] adds
//! them: the per-lane partials then stay on the device and only `8` bytes per pair of a
//! register block come back, once, at the end (on an H200 at N = 1,000 the host path read
//! 1.75 GB of partials back).

use crate::{dispatch, GpuContext};
use brdf_basis_core::error::GpuError;

/// WGSL source of the kernel.
pub const SOURCE: &str = include_str!("reduce_f64.wgsl");
/// Invocations per workgroup; keep in sync with the shader.
const WORKGROUP: u32 = 64;

/// Uniform parameters; keep in sync with `ReduceParams` in `pairwise/reduce_f64.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ReduceParams {
    /// Values per register block.
    pub ss: u32,
    /// Lane-runs per register block in the partials.
    pub lane_runs: u32,
    /// Register blocks in this dispatch.
    pub count: u32,
    /// Index in the totals of the dispatch's first value.
    pub sum_base: u32,
    /// Invocations per row of the 2D dispatch.
    pub row: u32,
    /// Padding.
    pub _pad: [u32; 3],
}

/// The device's f64 totals of every register block of one reduction (zeroed at creation).
pub(crate) struct DeviceSums {
    pipeline: wgpu::ComputePipeline,
    sums: wgpu::Buffer,
    values: usize,
}

impl DeviceSums {
    /// Totals for `values` f64 on `ctx`, or `None` where the device has no f64 in shaders
    /// or they would not fit one binding (the host then adds the partials).
    pub(crate) fn new(
        ctx: &GpuContext,
        pipeline: Option<wgpu::ComputePipeline>,
        values: usize,
    ) -> Option<Self> {
        let bytes = (values as u64 * 8).max(16);
        if !ctx.has_f64() || bytes > ctx.max_binding() || values > u32::MAX as usize {
            return None;
        }
        // wgpu zero-initialises new buffers.
        let sums = ctx.storage("f64 totals", bytes);
        Some(Self {
            pipeline: pipeline?,
            sums,
            values,
        })
    }

    /// Records the addition of `count` register blocks' partials (`partial`, `lane_runs`
    /// lane-runs of `ss` values each per block) into the totals from block `first` on.
    pub(crate) fn encode(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        partial: &wgpu::Buffer,
        (first, count, ss, lane_runs): (usize, usize, usize, usize),
    ) {
        let total = (count * ss) as u32;
        let groups = total.div_ceil(WORKGROUP).max(1);
        let max_dim = ctx.limits.max_compute_workgroups_per_dimension.max(1);
        let x = groups.min(max_dim);
        let y = groups.div_ceil(x);
        let params = ReduceParams {
            ss: ss as u32,
            lane_runs: lane_runs as u32,
            count: count as u32,
            sum_base: (first * ss) as u32,
            row: x * WORKGROUP,
            _pad: [0; 3],
        };
        let pbuf = ctx.uniform("reduce params", &params);
        let bind = ctx.bind(&self.pipeline, &[&pbuf, partial, &self.sums]);
        dispatch(enc, &self.pipeline, &bind, (x, y));
    }

    /// Submits `enc`, waits and reads the totals back.
    pub(crate) fn read(
        &self,
        ctx: &GpuContext,
        enc: wgpu::CommandEncoder,
    ) -> Result<Vec<f64>, GpuError> {
        let bytes = ctx.submit_and_read(enc, &self.sums, (self.values * 8) as u64)?;
        Ok(bytes[..self.values * 8]
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect())
    }
}
