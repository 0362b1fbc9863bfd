//! Per-target weighted normal equations on the GPU (`weighted.wgsl`; the CPU twin
//! and f64 reference is [`brdf_basis_core::backend::weighted::reference`]).
//!
//! Per chunk of cells, every row (basis lobes, then targets) is tabulated on the device
//! into one packed texture: analytic rows by the tabulation kernel, neural rows by the
//! neural kernel, measured rows packed by the host; each kind starts on a whole texel
//! ([`KindLayout`]). The kernel then sums each target's system over runs of 1,024 cells in
//! f32, and the runs are added in f64 on the device where it has f64
//! ([`super::pairwise`]'s reduction), else on the host; one readback at the end.

use super::neural::{lobe_rows, NeuralCells, NeuralKernel, NeuralTarget};
use super::pairwise::DeviceSums;
use super::tabulate::{PackTarget, TabulateKernel};
use super::{dispatch, GpuContext, PipelineCache, TEX_W};
use brdf_basis_core::backend::weighted::{cos_theta_i, reference, TargetWeight, WeightedSystems};
use brdf_basis_core::backend::{Lobe, Progress};
use brdf_basis_core::brdf::LobeParams;
use brdf_basis_core::error::GpuError;
use brdf_basis_core::merl::CellSet;

/// WGSL template of the kernel (see [`kernel_source`]).
pub const SOURCE: &str = include_str!("weighted.wgsl");
/// Cells per run (one invocation's loop); keep below lavapipe's 65,535 iterations.
pub const RUN_LEN: usize = 1024;
/// Invocations (targets) per workgroup; keep in sync with the shader.
const WORKGROUP: u32 = 64;
/// Most bytes of a chunk's packed texture on a software adapter / a hardware GPU.
const TEXTURE_BUDGET: [usize; 2] = [16 << 20, 1 << 30];

/// Uniform parameters; keep in sync with `WeightedParams` in `weighted.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct WeightedParams {
    /// Cells in this chunk.
    pub n_cells: u32,
    /// Targets.
    pub n_targets: u32,
    /// Cells per run.
    pub run_len: u32,
    /// Runs in this chunk.
    pub n_runs: u32,
    /// Texels between row blocks of the packed texture.
    pub chunk: u32,
    /// The objective: 0 = l2, 1 = relative, 2 = log.
    pub weight: u32,
    /// The relative objective's eps.
    pub eps: f32,
    /// The Lambertian column's value, `1 / pi` in f32.
    pub lambert: f32,
}

/// Values the kernel adds after each target's system: the count of cells whose weight
/// left f32's range (0, subnormal or infinite where the f64 reference forms a positive
/// normal weight, e.g. a value above about 1e18 under `relative`, or an eps outside f32's
/// range). The host hands such targets, and those whose sums overflowed f32, to the f64
/// reference: the GPU then gives the CPU back-end's systems bit for bit (or the same
/// refusal), not a system that silently lost cells.
pub const FLAG: usize = 1;

/// The factor (a power of two, exact) by which the kernel scales each term `W y^2` of
/// `yy` under `relative` and `log`, where each term is at most the cell weight times 1
/// and a value far below `eps` (1e-20 under eps 0.01) would otherwise underflow f32; the
/// host divides it out in f64.
pub const YY_SCALE: f64 = 18446744073709551616.0; // 2^64

/// The kernel for `k` basis lobes: the template with `K` and `STRIDE` defined and its
/// `//@` lines expanded (one f32 accumulator per value of the system, and the count of
/// [`FLAG`]).
pub fn kernel_source(k: usize) -> String {
    let m = k + 1;
    let stride = WeightedSystems::stride_for(m);
    let mut out = format!(
        "const K: u32 = {k}u;\nconst STRIDE: u32 = {}u;\n",
        stride + FLAG
    );
    let upper = || (0..m).flat_map(move |i| (i..m).map(move |j| (i, j)));
    for line in SOURCE.lines() {
        let indent = &line[..line.len() - line.trim_start().len()];
        let mut emit = |s: String| {
            out.push_str(indent);
            out.push_str(&s);
            out.push('\n');
        };
        match line.trim() {
            "//@BASIS" => (1..m).for_each(|j| emit(format!("let br{j} = row_of[{}u];", j - 1))),
            "//@DECLARE" => {
                upper().for_each(|(i, j)| emit(format!("var g_{i}_{j}: f32 = 0.0;")));
                (0..m).for_each(|i| emit(format!("var r_{i}: f32 = 0.0;")));
                emit("var yy: f32 = 0.0;".into());
            }
            "//@FETCH" => (1..m).for_each(|j| emit(format!("let f{j} = fetch(br{j}, c);"))),
            "//@ACCUMULATE" => {
                for i in 0..m {
                    emit(format!("let wf{i} = wgt * f{i};"));
                    for j in i..m {
                        emit(format!("g_{i}_{j} = g_{i}_{j} + wf{i} * f{j};"));
                    }
                    emit(format!("r_{i} = r_{i} + wf{i} * y;"));
                }
                emit("yy = yy + (wgt * y) * (y * yscale);".into());
            }
            "//@STORE" => {
                let mut q = 0;
                for (i, j) in upper() {
                    emit(format!("partial[o + {q}u] = g_{i}_{j};"));
                    q += 1;
                }
                for i in 0..m {
                    emit(format!("partial[o + {}u] = r_{i};", q + i));
                }
                emit(format!("partial[o + {}u] = yy;", q + m));
                emit(format!("partial[o + {}u] = lost;", q + m + 1));
            }
            _ => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    out
}

/// `systems` with the targets `redo` (whose weights or sums left f32's range, [`FLAG`])
/// replaced by the f64 reference's ([`brdf_basis_core::backend::weighted::reference`] on
/// the CPU back-end): their systems are then the CPU back-end's, bit for bit.
fn f64_reference(
    mut systems: WeightedSystems,
    basis: &[Lobe],
    targets: &[Lobe],
    cells: &CellSet,
    weight: TargetWeight,
    redo: &[usize],
) -> Result<WeightedSystems, GpuError> {
    if redo.is_empty() {
        return Ok(systems);
    }
    let cpu = brdf_basis_core::backend::cpu::CpuBackend::new();
    let lobes: Vec<Lobe> = redo.iter().map(|&t| targets[t].clone()).collect();
    let exact = reference(&cpu, basis, &lobes, cells, weight, &|_, _| {})
        .map_err(|e| GpuError::Limits(e.to_string()))?;
    let stride = systems.stride();
    for (q, &t) in redo.iter().enumerate() {
        systems.values[t * stride..(t + 1) * stride]
            .copy_from_slice(&exact.values[q * stride..(q + 1) * stride]);
    }
    Ok(systems)
}

/// Where each row sits in the packed texture: analytic rows first, then measured, then
/// neural, each kind from a whole texel (block of four rows) on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KindLayout {
    /// Packed row of each input row.
    pub row: Vec<u32>,
    /// Input rows of each kind, in order.
    pub analytic: Vec<usize>,
    /// Measured rows.
    pub measured: Vec<usize>,
    /// Neural rows.
    pub neural: Vec<usize>,
    /// First block of the measured and of the neural rows, and blocks in all.
    pub blocks: [usize; 3],
}

impl KindLayout {
    /// The layout of `rows`.
    pub fn new(rows: &[&Lobe]) -> Self {
        let of = |k: u8| -> Vec<usize> {
            (0..rows.len())
                .filter(|&i| {
                    k == match rows[i] {
                        Lobe::Analytic(_) => 0,
                        Lobe::Measured { .. } => 1,
                        Lobe::Neural { .. } => 2,
                    }
                })
                .collect()
        };
        let (analytic, measured, neural) = (of(0), of(1), of(2));
        let mb = analytic.len().div_ceil(4);
        let nb = mb + measured.len().div_ceil(4);
        let total = nb + neural.len().div_ceil(4);
        let mut row = vec![0u32; rows.len()];
        for (k, &i) in analytic.iter().enumerate() {
            row[i] = k as u32;
        }
        for (k, &i) in measured.iter().enumerate() {
            row[i] = (4 * mb + k) as u32;
        }
        for (k, &i) in neural.iter().enumerate() {
            row[i] = (4 * nb + k) as u32;
        }
        Self {
            row,
            analytic,
            measured,
            neural,
            blocks: [mb, nb, total],
        }
    }
}

/// The weighted-systems kernel: pipelines per basis size, compiled on first use.
#[derive(Debug, Default)]
pub struct WeightedKernel {
    pipelines: PipelineCache<usize>,
    reduce: PipelineCache<()>,
}

impl WeightedKernel {
    /// An empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// Every target's system (see [`brdf_basis_core::backend::weighted`]) on the device.
    ///
    /// Long function: the chunked driver of the kernel: per chunk of cells the upload
    /// of rows and weights, one dispatch per batch of targets, the f64 reduction and
    /// the readback, with the buffers living across the loop.
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        &self,
        ctx: &GpuContext,
        tab: &TabulateKernel,
        neural: impl Fn() -> Result<std::sync::Arc<NeuralKernel>, GpuError>,
        basis: &[Lobe],
        targets: &[Lobe],
        cells: &CellSet,
        weight: TargetWeight,
        progress: Progress<'_>,
    ) -> Result<WeightedSystems, GpuError> {
        let (k, t_count) = (basis.len(), targets.len());
        let m = k + 1;
        let system = WeightedSystems::stride_for(m);
        if t_count == 0 || cells.is_empty() {
            let values = vec![0f64; t_count * system];
            return Ok(WeightedSystems { columns: m, values });
        }
        // The kernel's values per target: the system and the flag.
        let stride = system + FLAG;
        let mut values = vec![0f64; t_count * stride];
        let pipeline = self.pipelines.get(k, || {
            ctx.pipeline(&format!("weighted (K = {k})"), &kernel_source(k))
        })?;
        let rows: Vec<&Lobe> = basis.iter().chain(targets).collect();
        let layout = KindLayout::new(&rows);
        let blocks = layout.blocks[2].max(1);
        let max_dim = ctx.limits.max_texture_dimension_2d as usize;
        let budget = TEXTURE_BUDGET[usize::from(!ctx.is_software())];
        let chunk = ((budget / (16 * blocks)).min(max_dim / blocks * TEX_W) / TEX_W * TEX_W)
            .clamp(TEX_W, cells.len().next_multiple_of(TEX_W));
        if blocks * chunk / TEX_W > max_dim {
            return Err(GpuError::Limits(format!(
                "{} rows do not fit a packed texture of side {max_dim}",
                rows.len()
            )));
        }
        let n_runs = chunk.div_ceil(RUN_LEN);
        let target = PackTarget::new(
            ctx,
            blocks,
            chunk,
            wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        );
        let view = target
            .texture
            .create_view(&wgpu::TextureViewDescriptor::default());
        // Analytic tables (blocks from 0), neural weights (blocks from the layout's second).
        let mut analytic: Vec<Option<LobeParams>> = layout
            .analytic
            .iter()
            .map(|&i| match rows[i] {
                Lobe::Analytic(p) => Some(*p),
                Lobe::Measured { .. } | Lobe::Neural { .. } => None,
            })
            .collect();
        analytic.resize(analytic.len().div_ceil(4) * 4, None);
        let prepared = tab.prepare_packed(ctx, &analytic);
        let mut neural_pass = match layout.neural.is_empty() {
            true => None,
            false => {
                let kernel = neural()?;
                let (nets, nrows) = lobe_rows(layout.neural.iter().map(|&i| rows[i]));
                let nets: Vec<&[f32]> = nets.iter().map(|n| n.weights()).collect();
                let mut padded: Vec<Option<_>> = nrows.into_iter().map(Some).collect();
                padded.resize(padded.len().div_ceil(4) * 4, None);
                let prepared = kernel.prepare(ctx, &nets, &padded)?;
                Some((kernel, prepared, NeuralCells::new(ctx, chunk)))
            }
        };
        let row_buf = ctx.storage_init(
            "weighted rows",
            bytemuck::cast_slice(&layout.row),
            wgpu::BufferUsages::empty(),
        );
        let cell_buf = ctx.storage("weighted cells", (chunk * 8) as u64);
        let partial = ctx.storage("weighted partials", (t_count * n_runs * stride * 4) as u64);
        let reduce = match ctx.has_f64() {
            true => Some(self.reduce.get((), || {
                ctx.pipeline("reduce (f64)", super::pairwise::REDUCE_SOURCE)
            })?),
            false => None,
        };
        let sums = DeviceSums::new(ctx, reduce, t_count * stride);
        let (code, eps) = weight.code();
        let mut in_flight = None;
        let mut done = 0usize;
        for (cc, cw) in cells.cells.chunks(chunk).zip(cells.weights.chunks(chunk)) {
            let len = cc.len();
            // Encoded, not yet summed: the position of the chunks handed to the device.
            done += len;
            progress(done as u64, cells.cells.len() as u64);
            let mut enc = tab.encode_pack(ctx, &prepared, &target, cc);
            self.pack_measured(ctx, &target, &layout, &rows, cc, chunk)?;
            if let Some((kernel, prepared, ncells)) = neural_pass.as_mut() {
                ncells.write(ctx, cc, None);
                let at = NeuralTarget {
                    view: &view,
                    base: layout.blocks[1] * chunk,
                    row_stride: chunk,
                };
                kernel.encode(ctx, &mut enc, prepared, ncells, at);
            }
            let per_cell: Vec<[f32; 2]> = cc
                .iter()
                .zip(cw)
                .map(|(&c, &w)| [w as f32, cos_theta_i(c as usize) as f32])
                .collect();
            ctx.queue
                .write_buffer(&cell_buf, 0, bytemuck::cast_slice(&per_cell));
            let runs = len.div_ceil(RUN_LEN);
            let params = WeightedParams {
                n_cells: len as u32,
                n_targets: t_count as u32,
                run_len: RUN_LEN as u32,
                n_runs: runs as u32,
                chunk: chunk as u32,
                weight: code,
                eps,
                lambert: std::f32::consts::FRAC_1_PI,
            };
            let pbuf = ctx.uniform("weighted params", &params);
            let bind = ctx.bind_at(
                &pipeline,
                vec![
                    (0, pbuf.as_entire_binding()),
                    (1, wgpu::BindingResource::TextureView(&view)),
                    (2, row_buf.as_entire_binding()),
                    (3, cell_buf.as_entire_binding()),
                    (4, partial.as_entire_binding()),
                ],
            );
            dispatch(
                &mut enc,
                &pipeline,
                &bind,
                ((t_count as u32).div_ceil(WORKGROUP), runs as u32),
            );
            if let Some(ix) = in_flight.take() {
                ctx.wait_for(ix)?;
            }
            match &sums {
                Some(d) => {
                    d.encode(ctx, &mut enc, &partial, (0, t_count, stride, runs));
                    in_flight = Some(ctx.submit(enc)?);
                }
                None => {
                    let used = (t_count * runs * stride * 4) as u64;
                    let bytes = ctx.submit_and_read(enc, &partial, used)?;
                    let part: &[f32] = bytemuck::cast_slice(&bytes[..used as usize]);
                    for (v, p) in values.chunks_mut(stride).zip(part.chunks(runs * stride)) {
                        for run in p.chunks(stride) {
                            for (a, &x) in v.iter_mut().zip(run) {
                                *a += x as f64;
                            }
                        }
                    }
                }
            }
        }
        if let Some(d) = &sums {
            values = d.read(ctx, ctx.encoder())?;
        }
        let yscale = match weight {
            TargetWeight::L2 => 1.0,
            TargetWeight::Relative { .. } | TargetWeight::Log => YY_SCALE,
        };
        let systems = WeightedSystems {
            columns: m,
            values: values
                .chunks(stride)
                .flat_map(|v| {
                    let (sys, yy) = v[..system].split_at(system - 1);
                    sys.iter().copied().chain([yy[0] / yscale])
                })
                .collect(),
        };
        let out_of_f32: Vec<usize> = values
            .chunks(stride)
            .enumerate()
            .filter(|(_, v)| v[system] != 0.0 || v[..system].iter().any(|x| !x.is_finite()))
            .map(|(t, _)| t)
            .collect();
        f64_reference(systems, basis, targets, cells, weight, &out_of_f32)
    }

    /// Packs the measured rows of a chunk (host tabulation, four rows to a texel) into
    /// their blocks of the texture.
    fn pack_measured(
        &self,
        ctx: &GpuContext,
        target: &PackTarget,
        layout: &KindLayout,
        rows: &[&Lobe],
        cc: &[u32],
        chunk: usize,
    ) -> Result<(), GpuError> {
        if layout.measured.is_empty() {
            return Ok(());
        }
        let len = cc.len();
        let mut vals = vec![0f32; layout.measured.len() * len];
        brdf_basis_core::backend::cpu::fill_rows(
            layout
                .measured
                .iter()
                .map(|&i| rows[i])
                .zip(vals.chunks_mut(len))
                .collect(),
            cc,
            None,
        )
        .map_err(|e| GpuError::Limits(e.to_string()))?;
        let mut texels = vec![0f32; chunk * 4];
        for (b, group) in vals.chunks(4 * len).enumerate() {
            texels.fill(0.0);
            for (q, row) in group.chunks(len).enumerate() {
                for (c, &v) in row.iter().enumerate() {
                    texels[4 * c + q] = v;
                }
            }
            ctx.write_texel_rows(
                &target.texture,
                (layout.blocks[0] + b) * chunk / TEX_W,
                &texels,
            );
        }
        Ok(())
    }
}
