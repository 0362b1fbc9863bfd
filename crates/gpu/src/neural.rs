//! Neural BRDF kernel (`nbrdf.wgsl`): the networks of Sztrajman et al. 2021
//! (SPEC 9) evaluated on the GPU at the cells of a chunk, written four rows to a texel of
//! an rgba32float texture in the layout of the pairwise kernel's measured row blocks
//! ([`NeuralKernel::encode`]), so that a pairwise reduction reads its neural rows without
//! a host round trip; [`NeuralKernel::tabulate`] reads them back into planar rows.
//!
//! Weights come as the flat layout of `brdf_basis_core::brdf::Nbrdf` (675 f32 per network: fc1
//! 6 x 21 at 0, b1 at 126, fc2 21 x 21 at 147, b2 at 588, fc3 21 x 3 at 609, b3 at 672,
//! matrices row-major, input-major) and are repacked once per call into the kernel's
//! vec4 layout ([`kernel_weights`]). The inputs of each cell (sin, cos of its angles) are
//! computed on the host in f64 and rounded once ([`grid_features`], with the rounding
//! errors); the kernel runs the network in f32 with an accurate `expm1`, estimates the
//! rounding error of each value, and runs the network again in double-f32 arithmetic where
//! the estimate is not well within SPEC 9 (5e-4 relative of an f64 evaluation wherever the
//! value exceeds 1e-3, 1e-6 absolute below).
//!
//! One invocation evaluates the distinct networks of one row block (at most four) at one
//! cell: rows of one network in one block share its evaluation, and the work of an
//! invocation is bounded whatever the number of cells or networks.

use super::readback::{PackedStream, Unpack};
use super::{GpuContext, TEX_W};
use brdf_basis_core::backend::Lobe;
use brdf_basis_core::brdf::Nbrdf;
use brdf_basis_core::error::GpuError;
use brdf_basis_core::merl::{phi_d, theta_d, theta_h, N_PD, N_TD, N_TH};
use std::sync::Arc;

/// WGSL source of the kernel.
pub const SOURCE: &str = include_str!("nbrdf.wgsl");
/// Workgroup size (cells per workgroup).
pub const WORKGROUP: u32 = 64;
/// Weights of one network in the flat layout (`brdf_basis_core::brdf::NBRDF_WEIGHTS`).
pub const FLAT_WEIGHTS: usize = 675;
/// Hidden units per layer.
pub const HIDDEN: usize = 21;
/// vec4 of one network in the kernel layout; keep in sync with `NET_VEC4` in the shader.
pub const NET_VEC4: usize = 184;
/// Texels of the (theta_d, phi_d) features: one per `(j, k)`; keep in sync with
/// `D_CELLS` in the shader.
pub const D_CELLS: usize = N_TD * N_PD;

// Offsets (vec4) of the kernel layout; keep in sync with the shader.
const W1: usize = 0;
const B1: usize = 30;
const W2T: usize = 36;
const W3B2: usize = 162;
const B3: usize = 183;
const _: () = assert!(B3 + 1 == NET_VEC4);

// Offsets (f32) of the flat layout.
const F_FC1: usize = 0;
const F_B1: usize = 126;
const F_FC2: usize = 147;
const F_B2: usize = 588;
const F_FC3: usize = 609;
const F_B3: usize = 672;
const _: () = assert!(F_B3 + 3 == FLAT_WEIGHTS);

/// The inputs of fc1 that are not identically zero (x[1] = sin theta_h sin phi_h with
/// phi_h = 0), in the order of the kernel layout: sin th, cos th, then the three of d.
const INPUT_ROWS: [usize; 5] = [0, 2, 3, 4, 5];

/// Uniform parameters; keep in sync with `NeuralParams` in `nbrdf.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct NeuralParams {
    /// Cells in this chunk.
    pub n_cells: u32,
    /// Texels between consecutive row blocks of the output texture.
    pub row_stride: u32,
    /// Texel of row block 0's cell 0.
    pub out_base: u32,
    /// `1.0f32.to_bits()`: a 1 the shader compiler cannot see, which keeps the kernel's
    /// exact transformations (double-f32 arithmetic) from being simplified away.
    pub one_bits: u32,
}

/// One row block as the kernel reads it; keep in sync with `BlockDesc` in the shader.
/// Its networks' weights follow it in the block's uniform region ([`REGION_BYTES`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BlockDesc {
    /// Per row, the slot of its network among the block's networks; [`PAD_SLOT`]: a
    /// padding row (0).
    pub slot: [u32; 4],
    /// Per row, its channel (0, 1, 2) or [`MEAN`].
    pub chan: [u32; 4],
    /// Distinct networks of the block (slots `0..count`).
    pub count: u32,
    /// The block's index in the output texture.
    pub block: u32,
    /// Padding.
    pub _pad: [u32; 2],
}

/// Bytes of one block's uniform region: its [`BlockDesc`] and the weights of four
/// networks (`BlockUniform` in the shader).
pub const REGION_BYTES: usize = std::mem::size_of::<BlockDesc>() + 4 * NET_VEC4 * 16;

/// The slot of a padding row in [`BlockDesc::slot`].
pub const PAD_SLOT: u32 = 4;
/// The channel code of the mean of R, G, B in [`BlockDesc::chan`].
pub const MEAN: u32 = 3;

/// One row of a neural row set: the index of its network among the call's networks and
/// its channel (`None`: the mean of R, G, B).
pub type NeuralRow = (usize, Option<usize>);

/// The distinct networks of `lobes` (neural lobes; others are skipped) and one row per
/// neural lobe, in order: rows of one network (the same `Arc`) share its index.
pub(crate) fn lobe_rows<'a>(
    lobes: impl Iterator<Item = &'a Lobe>,
) -> (Vec<Arc<Nbrdf>>, Vec<NeuralRow>) {
    let mut nets: Vec<Arc<Nbrdf>> = Vec::new();
    let mut rows = Vec::new();
    for l in lobes {
        if let Lobe::Neural { net, channel } = l {
            let k = nets
                .iter()
                .position(|n| Arc::ptr_eq(n, net))
                .unwrap_or_else(|| {
                    nets.push(net.clone());
                    nets.len() - 1
                });
            rows.push((k, *channel));
        }
    }
    (nets, rows)
}

/// Submits `encoder`, turning validation errors into an error (not a panic).
pub fn submit(ctx: &GpuContext, encoder: wgpu::CommandEncoder) -> Result<(), GpuError> {
    let scope = ctx.device.push_error_scope(wgpu::ErrorFilter::Validation);
    ctx.queue.submit(Some(encoder.finish()));
    match pollster::block_on(scope.pop()) {
        Some(e) => Err(GpuError::Wgpu {
            context: "evaluating neural BRDFs".into(),
            message: e.to_string(),
        }),
        None => Ok(()),
    }
}

/// The block descriptors of `rows` (`None`: a padding row), four rows per block, each with
/// the networks of its slots (distinct, in order of first use).
pub fn block_descs(rows: &[Option<NeuralRow>]) -> Vec<(BlockDesc, Vec<usize>)> {
    rows.chunks(4)
        .enumerate()
        .map(|(b, block)| {
            let mut d = BlockDesc {
                slot: [PAD_SLOT; 4],
                block: b as u32,
                ..Default::default()
            };
            let mut nets: Vec<usize> = Vec::new();
            for (q, row) in block.iter().enumerate() {
                if let Some((net, channel)) = *row {
                    let slot = nets.iter().position(|&n| n == net).unwrap_or_else(|| {
                        nets.push(net);
                        nets.len() - 1
                    });
                    d.slot[q] = slot as u32;
                    d.chan[q] = channel.map_or(MEAN, |c| c.min(2) as u32);
                }
            }
            d.count = nets.len() as u32;
            (d, nets)
        })
        .collect()
}

/// One network's flat weights (675 f32) in the kernel layout (`NET_VEC4` vec4, as f32).
pub fn kernel_weights(flat: &[f32]) -> Vec<f32> {
    assert_eq!(
        flat.len(),
        FLAT_WEIGHTS,
        "a network has {FLAT_WEIGHTS} weights"
    );
    let mut k = vec![0f32; 4 * NET_VEC4];
    // Hidden unit u of a layer sits in vec4 u / 4, lane u % 4.
    let at = |v: usize, u: usize| 4 * (v + u / 4) + u % 4;
    for (r, &input) in INPUT_ROWS.iter().enumerate() {
        for u in 0..HIDDEN {
            k[at(W1 + 6 * r, u)] = flat[F_FC1 + input * HIDDEN + u];
        }
    }
    for u in 0..HIDDEN {
        k[at(B1, u)] = flat[F_B1 + u];
    }
    for j in 0..HIDDEN {
        for i in 0..HIDDEN {
            k[at(W2T + 6 * j, i)] = flat[F_FC2 + i * HIDDEN + j];
        }
        for c in 0..3 {
            k[4 * (W3B2 + j) + c] = flat[F_FC3 + j * 3 + c];
        }
        k[4 * (W3B2 + j) + 3] = flat[F_B2 + j];
    }
    for c in 0..3 {
        k[4 * B3 + c] = flat[F_B3 + c];
    }
    k
}

/// The features of the MERL grid as the kernel reads them (rgba texels): texel
/// `j * 180 + k` holds `(sin td cos pd, sin td sin pd, cos td, 0)` at the centre of
/// `(j, k)`, texel `D_CELLS + i` holds `(sin th, cos th)` of row `i` and their rounding
/// errors (f64, rounded once; the errors `v - (v as f32)`, rounded), texel `2 D_CELLS +
/// j * 180 + k` the rounding errors of the first.
pub fn grid_features() -> Vec<f32> {
    let mut t = vec![0f32; 4 * 3 * D_CELLS];
    for j in 0..N_TD {
        for k in 0..N_PD {
            set_d(&mut t, j * N_PD + k, theta_d(j), phi_d(k));
        }
    }
    for i in 0..N_TH {
        set_h(&mut t, i, theta_h(i));
    }
    t
}

/// `v` in f32 and its rounding error.
fn hi_lo(v: f64) -> [f32; 2] {
    let hi = v as f32;
    [hi, (v - hi as f64) as f32]
}

/// The theta_d, phi_d features of texel `at` (and their errors at `2 D_CELLS + at`).
fn set_d(t: &mut [f32], at: usize, td: f64, pd: f64) {
    let (sd, cd) = td.sin_cos();
    let (sp, cp) = pd.sin_cos();
    for (q, v) in [sd * cp, sd * sp, cd].into_iter().enumerate() {
        let [hi, lo] = hi_lo(v);
        t[4 * at + q] = hi;
        t[4 * (2 * D_CELLS + at) + q] = lo;
    }
}

/// The theta_h features of texel `D_CELLS + at`, their errors in its `.zw`.
fn set_h(t: &mut [f32], at: usize, th: f64) {
    let (s, c) = th.sin_cos();
    let ([sh, sl], [ch, cl]) = (hi_lo(s), hi_lo(c));
    t[4 * (D_CELLS + at)..4 * (D_CELLS + at) + 4].copy_from_slice(&[sh, ch, sl, cl]);
}

/// Most points of one [`NeuralKernel::eval_points`] batch (each point takes a feature
/// texel of each kind).
pub const MAX_POINTS: usize = D_CELLS;

/// The row blocks of one call, uploaded: one uniform region per block (its descriptor
/// and its networks' weights), `stride` bytes apart.
#[derive(Debug)]
pub struct NeuralRows {
    regions: wgpu::Buffer,
    stride: u64,
    /// Row blocks.
    pub n_blocks: usize,
}

/// A chunk's cells and per-cell row scales, uploaded (reused chunk after chunk).
#[derive(Debug)]
pub struct NeuralCells {
    cells: wgpu::Buffer,
    scales: wgpu::Buffer,
    capacity: usize,
    /// Cells of the chunk uploaded last.
    n: usize,
    /// Whether the scales buffer holds all ones.
    ones: bool,
}

impl NeuralCells {
    /// Buffers for chunks of at most `capacity` cells.
    pub fn new(ctx: &GpuContext, capacity: usize) -> Self {
        Self {
            cells: ctx.storage("neural cells", (capacity * 4) as u64),
            scales: ctx.storage("neural row scales", (capacity * 4) as u64),
            capacity,
            n: 0,
            ones: false,
        }
    }

    /// Uploads a chunk: `cells` and their row scales (`None`: all 1).
    pub fn write(&mut self, ctx: &GpuContext, cells: &[u32], scales: Option<&[f32]>) {
        assert!(
            cells.len() <= self.capacity,
            "chunk larger than the buffers"
        );
        ctx.queue
            .write_buffer(&self.cells, 0, bytemuck::cast_slice(cells));
        match scales {
            Some(s) => {
                assert_eq!(s.len(), cells.len(), "one row scale per cell");
                ctx.queue
                    .write_buffer(&self.scales, 0, bytemuck::cast_slice(s));
                self.ones = false;
            }
            None if !self.ones => {
                let ones = vec![1f32; self.capacity];
                ctx.queue
                    .write_buffer(&self.scales, 0, bytemuck::cast_slice(&ones));
                self.ones = true;
            }
            None => {}
        }
        self.n = cells.len();
    }
}

/// Where [`NeuralKernel::encode`] writes: a storage-bindable rgba32float texture of width
/// [`TEX_W`], row block `b` at cell `c` in texel `base + b * row_stride + c`.
#[derive(Clone, Copy, Debug)]
pub struct NeuralTarget<'a> {
    /// A view of the texture (created with `STORAGE_BINDING`).
    pub view: &'a wgpu::TextureView,
    /// Texel of block 0's cell 0.
    pub base: usize,
    /// Texels between blocks (at least the chunk's cells).
    pub row_stride: usize,
}

/// The compiled kernel and the grid's features.
#[derive(Debug)]
pub struct NeuralKernel {
    pipeline: wgpu::ComputePipeline,
    grid: wgpu::TextureView,
}

impl NeuralKernel {
    /// Compiles the kernel and uploads the grid's features.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let pipeline = ctx.pipeline("neural brdf", SOURCE)?;
        let grid = ctx.linear_texture("grid features", &grid_features());
        Ok(Self { pipeline, grid })
    }

    /// Uploads the row blocks of `rows` (`rows.len()` a multiple of 4; `None`: a padding
    /// row; a row names a network by its index in `nets`, flat weights of 675 each).
    pub fn prepare(
        &self,
        ctx: &GpuContext,
        nets: &[&[f32]],
        rows: &[Option<NeuralRow>],
    ) -> Result<NeuralRows, GpuError> {
        assert_eq!(rows.len() % 4, 0, "whole row blocks");
        if let Some(&(net, _)) = rows.iter().flatten().find(|r| r.0 >= nets.len()) {
            return Err(GpuError::Limits(format!(
                "a neural row names network {net} of {}",
                nets.len()
            )));
        }
        if let Some(n) = nets.iter().find(|n| n.len() != FLAT_WEIGHTS) {
            return Err(GpuError::Limits(format!(
                "a neural BRDF of {} weights (one has {FLAT_WEIGHTS})",
                n.len()
            )));
        }
        let limits = &ctx.limits;
        if (limits.max_uniform_buffer_binding_size as usize) < REGION_BYTES {
            return Err(GpuError::Limits(format!(
                "the adapter binds at most {} bytes of uniforms; a block of neural BRDFs needs \
                 {REGION_BYTES}",
                limits.max_uniform_buffer_binding_size
            )));
        }
        let stride = (REGION_BYTES as u64)
            .next_multiple_of(limits.min_uniform_buffer_offset_alignment.max(16) as u64);
        let blocks = block_descs(rows);
        let bytes = stride * blocks.len().max(1) as u64;
        if bytes > limits.max_buffer_size {
            return Err(GpuError::Limits(format!(
                "{} neural rows need {bytes} bytes of weights; the adapter's buffers hold at \
                 most {}",
                rows.len(),
                limits.max_buffer_size
            )));
        }
        let kernel: Vec<Vec<f32>> = nets.iter().map(|n| kernel_weights(n)).collect();
        let mut data = vec![0u8; bytes as usize];
        for (b, (desc, used)) in blocks.iter().enumerate() {
            let region = &mut data[b * stride as usize..][..REGION_BYTES];
            let (head, w) = region.split_at_mut(std::mem::size_of::<BlockDesc>());
            head.copy_from_slice(bytemuck::bytes_of(desc));
            for (slot, &net) in used.iter().enumerate() {
                w[slot * NET_VEC4 * 16..(slot + 1) * NET_VEC4 * 16]
                    .copy_from_slice(bytemuck::cast_slice(&kernel[net]));
            }
        }
        use wgpu::util::DeviceExt;
        let regions = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("neural row blocks"),
                contents: &data,
                usage: wgpu::BufferUsages::UNIFORM,
            });
        Ok(NeuralRows {
            regions,
            stride,
            n_blocks: blocks.len(),
        })
    }

    /// Records, into `encoder`, the evaluation of every row block of `rows` at the cells
    /// uploaded in `cells`, written to `target`: one dispatch per row block (its weights
    /// bound as uniforms).
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        rows: &NeuralRows,
        cells: &NeuralCells,
        target: NeuralTarget<'_>,
    ) {
        self.encode_with(ctx, encoder, rows, cells, target, &self.grid);
    }

    fn encode_with(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        rows: &NeuralRows,
        cells: &NeuralCells,
        target: NeuralTarget<'_>,
        features: &wgpu::TextureView,
    ) {
        let n_cells = cells.n as u32;
        if n_cells == 0 || rows.n_blocks == 0 {
            return;
        }
        let params = NeuralParams {
            n_cells,
            row_stride: target.row_stride as u32,
            out_base: target.base as u32,
            one_bits: 1f32.to_bits(),
        };
        let pbuf = ctx.uniform("neural params", &params);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("neural rows"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        for b in 0..rows.n_blocks {
            let bind = ctx.bind_at(
                &self.pipeline,
                vec![
                    (0, pbuf.as_entire_binding()),
                    (
                        1,
                        wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &rows.regions,
                            offset: b as u64 * rows.stride,
                            size: std::num::NonZeroU64::new(REGION_BYTES as u64),
                        }),
                    ),
                    (2, cells.cells.as_entire_binding()),
                    (3, cells.scales.as_entire_binding()),
                    (4, wgpu::BindingResource::TextureView(features)),
                    (5, wgpu::BindingResource::TextureView(target.view)),
                ],
            );
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(n_cells.div_ceil(WORKGROUP), 1, 1);
        }
    }

    /// Tabulates `rows` (networks `nets`, flat weights) over the grid `cells` and reads
    /// the values back: `out[r * cells.len() + c]`, one row per entry of `rows`.
    pub fn tabulate(
        &self,
        ctx: &GpuContext,
        nets: &[&[f32]],
        rows: &[NeuralRow],
        cells: &[u32],
    ) -> Result<Vec<f32>, GpuError> {
        if let Some(&c) = cells.iter().find(|&&c| c as usize >= N_TH * D_CELLS) {
            return Err(GpuError::Limits(format!(
                "cell {c} is outside the MERL grid"
            )));
        }
        self.run_rows(ctx, nets, rows, cells, &self.grid)
    }

    /// The networks' rows at arbitrary half/difference angles `(theta_h, theta_d, phi_d)`
    /// (radians): `out[r * points.len() + p]`.
    pub fn eval_points(
        &self,
        ctx: &GpuContext,
        nets: &[&[f32]],
        rows: &[NeuralRow],
        points: &[[f64; 3]],
    ) -> Result<Vec<f32>, GpuError> {
        let mut out = vec![0f32; rows.len() * points.len()];
        for (k, batch) in points.chunks(MAX_POINTS).enumerate() {
            let mut t = vec![0f32; 4 * (2 * D_CELLS + batch.len())];
            for (p, &[th, td, pd]) in batch.iter().enumerate() {
                set_d(&mut t, p, td, pd);
                set_h(&mut t, p, th);
            }
            let features = ctx.linear_texture("point features", &t);
            // Point p decodes as (p, p): h texel D_CELLS + p, d texel p.
            let ids: Vec<u32> = (0..batch.len()).map(|p| (p * D_CELLS + p) as u32).collect();
            let vals = self.run_rows(ctx, nets, rows, &ids, &features)?;
            let start = k * MAX_POINTS;
            for r in 0..rows.len() {
                out[r * points.len() + start..r * points.len() + start + batch.len()]
                    .copy_from_slice(&vals[r * batch.len()..(r + 1) * batch.len()]);
            }
        }
        Ok(out)
    }

    /// [`Self::tabulate`] with the given features texture: chunks of cells into a packed
    /// texture reused chunk after chunk, each copied out while the next is computed and
    /// unpacked on the host in parallel ([`PackedStream`]).
    fn run_rows(
        &self,
        ctx: &GpuContext,
        nets: &[&[f32]],
        rows: &[NeuralRow],
        cells: &[u32],
        features: &wgpu::TextureView,
    ) -> Result<Vec<f32>, GpuError> {
        let n = cells.len();
        let mut out = vec![0f32; rows.len() * n];
        if n == 0 || rows.is_empty() {
            return Ok(out);
        }
        // Batches of rows and chunks of cells whose texture fits a small budget and the
        // largest texture side.
        let max_blocks = ctx.pack_max_blocks();
        let mut stream = PackedStream::new(ctx);
        for (batch, rb) in rows.chunks(4 * max_blocks).enumerate() {
            let mut padded: Vec<Option<NeuralRow>> = rb.iter().map(|&r| Some(r)).collect();
            padded.resize(rb.len().div_ceil(4) * 4, None);
            let blocks = padded.len() / 4;
            let prepared = self.prepare(ctx, nets, &padded)?;
            let by_dispatch = ctx.limits.max_compute_workgroups_per_dimension as usize
                * WORKGROUP as usize
                / TEX_W
                * TEX_W;
            let chunk = ctx.pack_chunk(blocks, n, by_dispatch);
            let texture = ctx.packed_texture(
                "neural rows",
                (blocks * chunk / TEX_W) as u32,
                wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
            );
            let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
            let mut up = NeuralCells::new(ctx, chunk);
            for (k, cc) in cells.chunks(chunk).enumerate() {
                up.write(ctx, cc, None);
                let mut enc = ctx.encoder();
                let target = NeuralTarget {
                    view: &view,
                    base: 0,
                    row_stride: chunk,
                };
                self.encode_with(ctx, &mut enc, &prepared, &up, target, features);
                let at = Unpack {
                    chunk,
                    rows: rb.len(),
                    row0: batch * 4 * max_blocks,
                    n,
                    start: k * chunk,
                    len: cc.len(),
                };
                stream.push(ctx, enc, &texture, at, &mut out)?;
            }
        }
        stream.finish(ctx, &mut out)?;
        Ok(out)
    }
}
