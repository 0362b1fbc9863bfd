//! LDR FLIP of a batch of 8-bit image pairs on the device (`flip.wgsl`): the images
//! converted to YCxCz, the separable filters' horizontal pass, then per pixel of each pair
//! the vertical pass, the perceived colour and features of both images and the error.
//! The CPU twin is [`brdf_basis_core::eval::flip`] (its filter taps are uploaded as the
//! twin built them; every sum runs over the same taps in the same order): the maps agree
//! within [`FLIP_GPU_TOLERANCE`] (WGSL's `pow`, and a driver may fuse a multiply-add).

use super::{dispatch, GpuContext};
use brdf_basis_core::error::GpuError;
use brdf_basis_core::eval::flip::FlipKernels;
use std::sync::OnceLock;

/// WGSL source.
pub const SOURCE: &str = include_str!("flip.wgsl");

/// The device's agreement with the CPU twin, absolute, per pixel of an error map (about
/// 1e-6 seen on lavapipe); the per-image means then agree within it too, well inside SPEC
/// 11's 1e-4 against NVIDIA's reference.
pub const FLIP_GPU_TOLERANCE: f32 = 1e-4;

/// Uniforms; keep in sync with `FlipUniforms` in `flip.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FlipUniforms {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Pairs in this dispatch.
    pub pairs: u32,
    /// Colour filter radius.
    pub rs: u32,
    /// Feature filter radius.
    pub rf: u32,
    /// `HyAB(green, blue)^q_c`.
    pub cmax: f32,
    /// `p_c cmax`.
    pub pccmax: f32,
    /// Padding.
    pub _pad: u32,
}

/// The three pipelines, compiled on first use.
#[derive(Debug, Default)]
pub struct FlipKernel {
    pipelines: OnceLock<[wgpu::ComputePipeline; 3]>,
}

/// Workgroups covering `n` invocations of 64, as `(x, y)` within the dispatch limits.
fn groups(n: usize) -> (u32, u32) {
    let g = n.div_ceil(64);
    (g.min(65_535) as u32, g.div_ceil(65_535) as u32)
}

impl FlipKernel {
    fn pipelines(&self, ctx: &GpuContext) -> Result<&[wgpu::ComputePipeline; 3], GpuError> {
        if let Some(p) = self.pipelines.get() {
            return Ok(p);
        }
        let compile =
            |entry: &str| ctx.pipeline_entry(&format!("flip {entry}"), SOURCE, entry, &[]);
        let p = [
            compile("ycxcz")?,
            compile("horizontal")?,
            compile("vertical_error")?,
        ];
        Ok(self.pipelines.get_or_init(|| p))
    }

    /// The FLIP error map of every pair `(reference, test)` (8-bit sRGB, interleaved RGB,
    /// `width x height`, row-major) with the filters of `kernels`: every pixel scored.
    /// Pairs go to the device in batches sized from its binding limit.
    pub fn maps(
        &self,
        ctx: &GpuContext,
        kernels: &FlipKernels,
        pairs: &[(&[u8], &[u8])],
        width: usize,
        height: usize,
    ) -> Result<Vec<Vec<f32>>, GpuError> {
        let plane = width * height;
        if let Some((i, _)) = pairs
            .iter()
            .enumerate()
            .find(|(_, (r, t))| r.len() != 3 * plane || t.len() != 3 * plane)
        {
            return Err(GpuError::Limits(format!(
                "FLIP pair {i}: a {width} x {height} image needs {} bytes",
                3 * plane
            )));
        }
        if plane == 0 || pairs.is_empty() {
            return Ok(vec![Vec::new(); pairs.len()]);
        }
        // The largest binding: the horizontal planes, 2 images x 7 planes per pair.
        let per_pair = (2 * 7 * plane * 4) as u64;
        let batch = (ctx.max_binding() / per_pair).clamp(0, 64) as usize;
        if batch == 0 {
            return Err(GpuError::Limits(format!(
                "a {width} x {height} FLIP pair needs {per_pair} bytes of one binding, over the device's {}",
                ctx.max_binding()
            )));
        }
        let [p_ycxcz, p_horizontal, p_vertical] = self.pipelines(ctx)?;
        let taps = kernels.packed_taps();
        let (cmax, pccmax) = kernels.remap();
        let tbuf = ctx.storage_init(
            "flip taps",
            bytemuck::cast_slice(&taps),
            wgpu::BufferUsages::empty(),
        );
        let mut maps = Vec::with_capacity(pairs.len());
        for chunk in pairs.chunks(batch) {
            let n = chunk.len();
            let packed: Vec<u32> = chunk
                .iter()
                .flat_map(|(r, t)| [*r, *t])
                .flat_map(|img| {
                    img.chunks_exact(3)
                        .map(|p| u32::from(p[0]) | u32::from(p[1]) << 8 | u32::from(p[2]) << 16)
                })
                .collect();
            let u = FlipUniforms {
                width: width as u32,
                height: height as u32,
                pairs: n as u32,
                rs: kernels.spatial_radius() as u32,
                rf: kernels.feature_radius() as u32,
                cmax,
                pccmax,
                _pad: 0,
            };
            let ubuf = ctx.uniform("flip params", &u);
            let ibuf = ctx.storage_init(
                "flip images",
                bytemuck::cast_slice(&packed),
                wgpu::BufferUsages::empty(),
            );
            let input = ctx.storage("flip input", (2 * 4 * n * plane * 4) as u64);
            let horiz = ctx.storage("flip horizontal", (2 * 7 * n * plane * 4) as u64);
            let map = ctx.storage("flip map", (n * plane * 4) as u64);
            let buffers = [&ubuf, &tbuf, &ibuf, &input, &horiz, &map];
            let mut enc = ctx.encoder();
            // Each entry point's layout holds the bindings it uses, no more.
            let passes: [(&wgpu::ComputePipeline, &[u32], usize); 3] = [
                (p_ycxcz, &[0, 2, 3], 2 * n * plane),
                (p_horizontal, &[0, 1, 3, 4], 2 * n * plane),
                (p_vertical, &[0, 1, 4, 5], n * plane),
            ];
            for (pipeline, used, count) in passes {
                let entries = used
                    .iter()
                    .map(|&b| (b, buffers[b as usize].as_entire_binding()))
                    .collect();
                let bind = ctx.bind_at(pipeline, entries);
                dispatch(&mut enc, pipeline, &bind, groups(count));
            }
            let data = ctx.submit_and_read(enc, &map, (n * plane * 4) as u64)?;
            let values: &[f32] = bytemuck::cast_slice(&data[..n * plane * 4]);
            maps.extend(values.chunks_exact(plane).map(<[f32]>::to_vec));
        }
        Ok(maps)
    }
}
