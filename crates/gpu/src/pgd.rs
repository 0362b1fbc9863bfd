//! Batched projected-gradient NNLS kernel (`pgd.wgsl`): one target per invocation,
//! f32, the same FISTA iteration as [`brdf_basis_core::nnls::pgd`] (its CPU twin) on the same scaled
//! problem. Each dispatch advances every unfinished target by [`STEPS`] steps; every
//! [`DISPATCHES_PER_CHECK`] dispatches the state is read back and the loop ends when every
//! target has converged or reached `max_iter`. Objective and KKT are then recomputed in
//! f64 on the host.

use super::{dispatch, GpuContext, PipelineCache};
use brdf_basis_core::error::GpuError;
use brdf_basis_core::nnls::pgd::{PgdParams, Prepared, PGD_KERNEL_COLUMNS};
use brdf_basis_core::nnls::{GramBatch, NnlsSolution};

/// WGSL template (see [`kernel_source`]).
pub const SOURCE: &str = include_str!("pgd.wgsl");

/// The kernel for `m` columns: the template with `const M` defined, so that every loop
/// has a constant trip count (unrolled, arrays in registers, constant Gram indices).
pub fn kernel_source(m: usize) -> String {
    format!("const M: u32 = {m}u;\n{SOURCE}")
}
/// Steps per dispatch: at most `STEPS x (32^2 + 4 x 32)` loop iterations per invocation.
pub const STEPS: u32 = 16;
/// Dispatches between two convergence checks.
pub const DISPATCHES_PER_CHECK: u32 = 16;
/// f32 per target of the state buffer; keep in sync with `S_LEN` in the shader.
pub const STATE_LEN: usize = 132;
/// The kernel's scaled-KKT tolerance floor: f32 arithmetic cannot certify less.
pub const F32_TOL: f64 = 2e-6;
const _: () = assert!((STEPS as usize) * (32 * 32 + 4 * 32) < 65_535);

/// Uniforms; keep in sync with `PgdUniforms` in the shader.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PgdUniforms {
    /// Columns.
    pub m: u32,
    /// Targets.
    pub n_targets: u32,
    /// Steps per dispatch.
    pub steps: u32,
    /// Step cap.
    pub max_iter: u32,
    /// 1 / L.
    pub inv_l: f32,
    /// Scaled-KKT tolerance.
    pub tol: f32,
    /// Padding.
    pub _pad0: u32,
    /// Padding.
    pub _pad1: u32,
}

/// The kernel, compiled on first use per number of columns.
#[derive(Debug, Default)]
pub struct PgdKernel {
    pipelines: PipelineCache<usize>,
}

impl PgdKernel {
    /// An empty cache (`ctx` is kept in the signature for callers that compile eagerly).
    pub fn new(_ctx: &GpuContext) -> Result<Self, GpuError> {
        Ok(Self::default())
    }

    /// The pipeline for `m` columns.
    fn pipeline(&self, ctx: &GpuContext, m: usize) -> Result<wgpu::ComputePipeline, GpuError> {
        self.pipelines.get(m, || {
            ctx.pipeline(&format!("pgd ({m} columns)"), &kernel_source(m))
        })
    }

    /// Solves every target of `batch` (at most 32 columns) on the GPU.
    pub fn solve_batch(
        &self,
        ctx: &GpuContext,
        batch: &GramBatch<'_>,
        params: &PgdParams,
    ) -> Result<Vec<NnlsSolution>, GpuError> {
        let m = batch.m();
        if m > PGD_KERNEL_COLUMNS {
            return Err(GpuError::Limits(format!(
                "the GPU solver takes at most {PGD_KERNEL_COLUMNS} columns, not {m}"
            )));
        }
        let prep =
            Prepared::new(m, batch.g(), params).map_err(|e| GpuError::Limits(e.to_string()))?;
        let n = batch.len();
        if n == 0 {
            return Ok(Vec::new());
        }
        let gs: Vec<f32> = prep.scaled_gram().iter().map(|&v| v as f32).collect();
        let mut hs = Vec::with_capacity(n * m);
        for t in 0..n {
            let p = batch
                .problem(t)
                .ok_or_else(|| GpuError::Limits("target out of range".into()))?;
            hs.extend(prep.scaled_h(p.h()).into_iter().map(|v| v as f32));
        }
        let mut state = vec![0f32; n * STATE_LEN];
        for s in state.chunks_mut(STATE_LEN) {
            s[128] = 1.0;
        }
        let bytes = (state.len() * 4) as u64;
        if bytes > ctx.max_binding() {
            return Err(GpuError::Limits(format!(
                "{n} targets need {bytes} bytes of solver state, over the binding limit"
            )));
        }
        let mut gs = gs;
        gs.resize(32 * 32, 0.0);
        let gbuf = ctx.uniform_slice("pgd gram", &gs);
        let pipeline = &self.pipeline(ctx, m)?;
        let hbuf = ctx.storage_init(
            "pgd h",
            bytemuck::cast_slice(&hs),
            wgpu::BufferUsages::empty(),
        );
        let sbuf = ctx.storage_init(
            "pgd state",
            bytemuck::cast_slice(&state),
            wgpu::BufferUsages::COPY_SRC,
        );
        let u = PgdUniforms {
            m: m as u32,
            n_targets: n as u32,
            steps: STEPS,
            max_iter: params.max_iter as u32,
            inv_l: prep.inv_l() as f32,
            tol: params.tol.max(F32_TOL) as f32,
            _pad0: 0,
            _pad1: 0,
        };
        let ubuf = ctx.uniform("pgd params", &u);
        let bind = ctx.bind(pipeline, &[&ubuf, &gbuf, &hbuf, &sbuf]);
        let groups = n.div_ceil(64);
        let (gx, gy) = (groups.min(65_535) as u32, groups.div_ceil(65_535) as u32);
        let max_dispatches = (params.max_iter as u32).div_ceil(STEPS);
        let mut dispatched = 0;
        loop {
            let mut enc = ctx.encoder();
            for _ in 0..DISPATCHES_PER_CHECK.min(max_dispatches - dispatched) {
                dispatch(&mut enc, pipeline, &bind, (gx, gy));
                dispatched += 1;
            }
            let data = ctx.submit_and_read(enc, &sbuf, bytes)?;
            state.copy_from_slice(bytemuck::cast_slice(&data[..bytes as usize]));
            if dispatched >= max_dispatches || state.chunks(STATE_LEN).all(|s| s[130] != 0.0) {
                break;
            }
        }
        Ok((0..n)
            .filter_map(|t| batch.problem(t).map(|p| (t, p)))
            .map(|(t, p)| {
                let s = &state[t * STATE_LEN..(t + 1) * STATE_LEN];
                let y: Vec<f64> = s[..m].iter().map(|&v| v as f64).collect();
                prep.finish(&p, &y, s[129] as usize)
            })
            .collect())
    }
}
