//! The GPU back-end (wgpu: Vulkan, Metal, DX12 or any adapter): device context, buffers,
//! one module per kernel. Kernels live beside their host module (`<name>.wgsl`), each compiled together
//! with `common.wgsl`; each kernel module owns its pipeline and a CPU twin.

mod backend;
pub mod flip;
#[doc(hidden)]
pub mod neural;
#[doc(hidden)]
pub mod pairwise;
#[doc(hidden)]
pub mod pgd;
mod readback;
#[doc(hidden)]
pub mod tabulate;
pub mod weighted;

pub use backend::GpuBackend;

use brdf_basis_core::error::GpuError;
use brdf_basis_core::merl::GridTables;
use std::sync::Arc;

/// The determinism contract's tolerance (docs/determinism.md): a sum whose terms the
/// kernels compute with a multiply feeding an add (analytic lobes with a diffuse term:
/// `beta g + alpha w`; every dot product of a Gram pass: `acc + a b`) may differ between
/// back-ends and drivers by this much, relative, because a driver may fuse the two into
/// one `fma` (NVIDIA does; lavapipe does not). Measured on an NVIDIA H200: 4.0e-8 (BRDF_it
/// of the Ngan table, full lobe), 1.1e-7 (full-lobe L1, one kernel shape), 7.2e-8
/// (specular Gram). The L1 sums of specular lobes and of measured rows (no multiply-add
/// in the canonical order) and the f64 totals of partial sums are identical on every
/// conformant driver.
pub const CONTRACTION_TOLERANCE: f64 = 5e-7;

/// WGSL shared by every kernel.
#[doc(hidden)]
pub const COMMON_WGSL: &str = include_str!("common.wgsl");

/// Offsets of the grid-table buffer; keep in sync with `T_*` in `common.wgsl`.
#[doc(hidden)]
pub const TABLE_COS_H: usize = 0;
/// See [`TABLE_COS_H`].
#[doc(hidden)]
pub const TABLE_SIN_H: usize = 90;
/// See [`TABLE_COS_H`].
#[doc(hidden)]
pub const TABLE_COS_D: usize = 180;
/// See [`TABLE_COS_H`].
#[doc(hidden)]
pub const TABLE_SIN_D: usize = 270;
/// See [`TABLE_COS_H`].
#[doc(hidden)]
pub const TABLE_ABS_COS_P: usize = 360;
/// Length of the grid-table buffer in f32 (a whole number of `vec4`s: the kernels read it
/// as `array<vec4<f32>, T_LEN / 4u>`).
#[doc(hidden)]
pub const TABLE_LEN: usize = 540;

/// Width in texels of the packed value textures (pairwise and tabulation kernels); keep
/// in sync with `TEX_W` in `common.wgsl`.
pub const TEX_W: usize = 4096;

/// Bytes of the packed texture of one batch of a tabulation on a software adapter
/// ([`GpuContext::pack_chunk`]).
const PACK_BUDGET: usize = 16 << 20;
/// The same on a hardware GPU: large transfers, yet at least two chunks for a batch of a
/// few dozen full-grid lobes, so that the device's copy of one overlaps the host's unpack
/// of the other (two staging buffers of this size are kept while a tabulation streams).
const PACK_BUDGET_HARDWARE: usize = 64 << 20;
/// Texels of one lobe's separable beta table: one per (theta_h, theta_d) row pair,
/// 90 x 90 (the alpha texel follows it).
pub const NIJ: usize = brdf_basis_core::merl::N_TH * brdf_basis_core::merl::N_TD;

/// The grid tables as the f32 array the kernels read (each entry computed in f64 and
/// rounded once).
#[doc(hidden)]
pub fn grid_table_f32(t: &GridTables) -> Vec<f32> {
    let mut v = vec![0f32; TABLE_LEN];
    for i in 0..90 {
        v[TABLE_COS_H + i] = t.cos_h[i] as f32;
        v[TABLE_SIN_H + i] = t.sin_h[i] as f32;
        v[TABLE_COS_D + i] = t.cos_d[i] as f32;
        v[TABLE_SIN_D + i] = t.sin_d[i] as f32;
    }
    for k in 0..180 {
        v[TABLE_ABS_COS_P + k] = t.abs_cos_p[k] as f32;
    }
    v
}

/// The full source of a kernel: `common.wgsl` followed by the kernel's own file.
#[doc(hidden)]
pub fn kernel_source(kernel: &str) -> String {
    format!("{COMMON_WGSL}\n{kernel}")
}

/// A wgpu device and queue, with the adapter's description and the limits in force.
#[derive(Clone, Debug)]
pub struct GpuContext {
    /// The device.
    pub device: Arc<wgpu::Device>,
    /// Its queue.
    pub queue: Arc<wgpu::Queue>,
    /// The adapter's description.
    pub info: wgpu::AdapterInfo,
    /// The limits the device was opened with.
    pub limits: wgpu::Limits,
    /// The readback buffer, reused while large enough (fresh mappable memory costs page
    /// faults on every call).
    staging: Arc<std::sync::Mutex<Option<wgpu::Buffer>>>,
    /// The two staging buffers of streamed readbacks ([`readback`]), kept between calls:
    /// pinning hundreds of MB of host memory per call costs more than the copies.
    stream_staging: Arc<std::sync::Mutex<[Option<wgpu::Buffer>; 2]>>,
}

impl GpuContext {
    /// Opens the best adapter (wgpu's `WGPU_*` environment variables are honoured, e.g.
    /// `WGPU_ADAPTER_NAME=llvmpipe`) with the adapter's own limits.
    pub fn new() -> Result<Self, GpuError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(wgpu::util::initialize_adapter_from_env_or_default(
            &instance, None,
        ))
        .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        let info = adapter.get_info();
        let limits = adapter.limits();
        // f64 in shaders where the adapter has it: the pairwise kernel then adds its f32
        // partial sums into f64 totals on the device (the host's order, bit for bit)
        // instead of reading every partial back.
        let features = adapter.features() & wgpu::Features::SHADER_F64;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("brdf-basis"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device(e.to_string()))?;
        Ok(Self {
            device: Arc::new(device),
            queue: Arc::new(queue),
            info,
            limits,
            staging: Default::default(),
            stream_staging: Default::default(),
        })
    }

    /// Wraps a caller's device and queue (embedding brdf-basis as a compute back-end).
    /// The limits are read from the device (`device.limits()`); open it with the
    /// adapter's (`required_limits: adapter.limits()`) so the kernels can use them.
    pub fn from_device(
        device: Arc<wgpu::Device>,
        queue: Arc<wgpu::Queue>,
        info: wgpu::AdapterInfo,
    ) -> Self {
        let limits = device.limits();
        Self {
            device,
            queue,
            info,
            limits,
            staging: Default::default(),
            stream_staging: Default::default(),
        }
    }

    /// Whether the device computes in f64 in shaders (`SHADER_F64`: the pairwise kernel's
    /// partial sums are then added on the device). `BRDF_BASIS_NO_DEVICE_F64=1` turns it
    /// off (the tests compare both paths).
    pub fn has_f64(&self) -> bool {
        self.device.features().contains(wgpu::Features::SHADER_F64)
            && std::env::var_os("BRDF_BASIS_NO_DEVICE_F64").is_none_or(|v| v != "1")
    }

    /// Whether the adapter is a software rasteriser (lavapipe, WARP, SwiftShader).
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// Largest storage-buffer binding, in bytes.
    pub fn max_binding(&self) -> u64 {
        self.limits
            .max_storage_buffer_binding_size
            .min(self.limits.max_buffer_size)
    }

    /// Compiles a kernel (common.wgsl + `source`) into a compute pipeline with entry
    /// point `main` and an automatic layout, checking for validation errors.
    pub fn pipeline(&self, label: &str, source: &str) -> Result<wgpu::ComputePipeline, GpuError> {
        self.pipeline_with(label, source, &[])
    }

    /// [`Self::pipeline`] with values for the kernel's `override` constants.
    pub fn pipeline_with(
        &self,
        label: &str,
        source: &str,
        constants: &[(&str, f64)],
    ) -> Result<wgpu::ComputePipeline, GpuError> {
        self.pipeline_entry(label, source, "main", constants)
    }

    /// [`Self::pipeline_with`] for the entry point `entry`.
    pub fn pipeline_entry(
        &self,
        label: &str,
        source: &str,
        entry: &str,
        constants: &[(&str, f64)],
    ) -> Result<wgpu::ComputePipeline, GpuError> {
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = self
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(kernel_source(source).into()),
            });
        let pipeline = self
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants,
                    ..Default::default()
                },
                cache: None,
            });
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Wgpu {
                context: format!("compiling {label}"),
                message: e.to_string(),
            });
        }
        Ok(pipeline)
    }

    /// A storage buffer initialised with `data`.
    pub(crate) fn storage_init(
        &self,
        label: &str,
        data: &[u8],
        extra: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        use wgpu::util::DeviceExt;
        // wgpu rejects empty bindings: pad to 16 bytes.
        let mut owned;
        let contents = if data.len() < 16 {
            owned = data.to_vec();
            owned.resize(16, 0);
            &owned[..]
        } else {
            data
        };
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | extra,
            })
    }

    /// An uninitialised storage buffer of `size` bytes (at least 16).
    #[doc(hidden)]
    pub fn storage(&self, label: &str, size: u64) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: size.max(16).next_multiple_of(4),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        })
    }

    /// A uniform buffer holding `data`.
    pub(crate) fn uniform<T: bytemuck::Pod>(&self, label: &str, data: &T) -> wgpu::Buffer {
        self.uniform_slice(label, std::slice::from_ref(data))
    }

    /// A uniform buffer holding the elements of `data`.
    pub(crate) fn uniform_slice<T: bytemuck::Pod>(&self, label: &str, data: &[T]) -> wgpu::Buffer {
        use wgpu::util::DeviceExt;
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(data),
                usage: wgpu::BufferUsages::UNIFORM,
            })
    }

    /// An rgba32float texture of width [`TEX_W`] holding `texels` (rgba)
    /// linearly (texel `k` at `(k % TEX_W, k / TEX_W)`, zero-padded to whole rows): a table
    /// the kernels fetch with vector gathers.
    pub(crate) fn linear_texture(&self, label: &str, texels: &[f32]) -> wgpu::TextureView {
        let row = 4 * TEX_W;
        let mut padded = texels.to_vec();
        padded.resize(texels.len().div_ceil(row).max(1) * row, 0.0);
        let tex = self.packed_texture(
            label,
            (padded.len() / row) as u32,
            wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        );
        self.write_texel_rows(&tex, 0, &padded);
        tex.create_view(&wgpu::TextureViewDescriptor::default())
    }

    /// Writes `texels` (rgba, whole rows of [`TEX_W`]) into `texture` from row
    /// `first_row`.
    pub fn write_texel_rows(&self, texture: &wgpu::Texture, first_row: usize, texels: &[f32]) {
        let w = TEX_W;
        self.queue.write_texture(
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
                bytes_per_row: Some((w * 16) as u32),
                rows_per_image: None,
            },
            wgpu::Extent3d {
                width: w as u32,
                height: (texels.len() / (4 * w)) as u32,
                depth_or_array_layers: 1,
            },
        );
    }

    /// An rgba32float texture of width [`TEX_W`] and `height` rows, used as
    /// `usage` says.
    pub(crate) fn packed_texture(
        &self,
        label: &str,
        height: u32,
        usage: wgpu::TextureUsages,
    ) -> wgpu::Texture {
        self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: TEX_W as u32,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Float,
            usage,
            view_formats: &[],
        })
    }

    /// Bytes of a packed tabulation's texture: small on a software adapter, large on a
    /// hardware GPU (within its largest buffer).
    fn pack_budget(&self) -> usize {
        match self.is_software() {
            true => PACK_BUDGET,
            false => PACK_BUDGET_HARDWARE.min(self.limits.max_buffer_size as usize),
        }
    }

    /// Texel blocks (four rows each) per batch of a packed tabulation: as many as the
    /// budget's texture of one [`TEX_W`]-wide texel row per block holds, within the largest texture
    /// side. The texture and readback buffers are reused chunk after chunk (fresh memory
    /// costs more in page faults than the kernels).
    pub(crate) fn pack_max_blocks(&self) -> usize {
        let max_dim = self.limits.max_texture_dimension_2d as usize;
        (self.pack_budget() / (16 * TEX_W)).min(max_dim).max(1)
    }

    /// Cells per chunk of a packed tabulation of `blocks` texel blocks over `n` cells:
    /// within the budget, the largest texture side and `cap`, whole texel rows.
    pub(crate) fn pack_chunk(&self, blocks: usize, n: usize, cap: usize) -> usize {
        let max_dim = self.limits.max_texture_dimension_2d as usize;
        ((self.pack_budget() / (16 * blocks)).min(TEX_W * max_dim / blocks) / TEX_W * TEX_W)
            .min(cap)
            .clamp(TEX_W, n.next_multiple_of(TEX_W))
    }

    /// A bind group over `buffers` bound at 0, 1, 2, ... of group 0 of `pipeline`.
    pub(crate) fn bind(
        &self,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[&wgpu::Buffer],
    ) -> wgpu::BindGroup {
        let entries: Vec<(u32, wgpu::BindingResource)> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| (i as u32, b.as_entire_binding()))
            .collect();
        self.bind_at(pipeline, entries)
    }

    /// A bind group of group 0 of `pipeline` from `(binding, resource)` pairs.
    pub(crate) fn bind_at(
        &self,
        pipeline: &wgpu::ComputePipeline,
        resources: Vec<(u32, wgpu::BindingResource<'_>)>,
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = resources
            .into_iter()
            .map(|(binding, resource)| wgpu::BindGroupEntry { binding, resource })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        })
    }

    /// Submits `encoder` after copying `size` bytes of `src` into a staging buffer, waits,
    /// and returns the bytes: every readback of the crate goes through here.
    #[doc(hidden)]
    pub fn submit_and_read(
        &self,
        mut encoder: wgpu::CommandEncoder,
        src: &wgpu::Buffer,
        size: u64,
    ) -> Result<Vec<u8>, GpuError> {
        let size = size.next_multiple_of(4).max(4);
        let mut slot = self.staging.lock().unwrap_or_else(|e| e.into_inner());
        let staging = match slot.as_ref() {
            Some(b) if b.size() >= size => b.clone(),
            _ => {
                let b = self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("readback"),
                    size,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                *slot = Some(b.clone());
                b
            }
        };
        encoder.copy_buffer_to_buffer(src, 0, &staging, 0, size);
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        self.queue.submit(Some(encoder.finish()));
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Wgpu {
                context: "submitting work".into(),
                message: e.to_string(),
            });
        }
        let read = || -> Result<Vec<u8>, GpuError> {
            let (tx, rx) = std::sync::mpsc::channel();
            staging
                .slice(..size)
                .map_async(wgpu::MapMode::Read, move |r| {
                    let _ = tx.send(r);
                });
            self.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| GpuError::Map(e.to_string()))?;
            rx.recv()
                .map_err(|e| GpuError::Map(e.to_string()))?
                .map_err(|e| GpuError::Map(e.to_string()))?;
            let view = staging
                .slice(..size)
                .get_mapped_range()
                .map_err(|e| GpuError::Map(e.to_string()))?;
            Ok(view.to_vec())
        };
        let bytes = match read() {
            Ok(b) => b,
            Err(e) => {
                // Never reuse a buffer left in an unknown mapping state.
                *slot = None;
                return Err(e);
            }
        };
        staging.unmap();
        Ok(bytes)
    }

    /// Submits `encoder` without waiting, reporting a validation error of the submission.
    pub(crate) fn submit(
        &self,
        encoder: wgpu::CommandEncoder,
    ) -> Result<wgpu::SubmissionIndex, GpuError> {
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let index = self.queue.submit(Some(encoder.finish()));
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Wgpu {
                context: "submitting work".into(),
                message: e.to_string(),
            });
        }
        Ok(index)
    }

    /// Waits until the work of submission `index` is done.
    pub(crate) fn wait_for(&self, index: wgpu::SubmissionIndex) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(index),
                timeout: None,
            })
            .map(|_| ())
            .map_err(|e| GpuError::Map(e.to_string()))
    }

    /// A new command encoder.
    pub(crate) fn encoder(&self) -> wgpu::CommandEncoder {
        self.device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None })
    }
}

/// Compute pipelines compiled on first use, by key (kernel variants generated per shape,
/// column count, ...).
#[derive(Debug)]
#[doc(hidden)]
pub struct PipelineCache<K> {
    compiled: std::sync::Mutex<Vec<(K, wgpu::ComputePipeline)>>,
}

impl<K> Default for PipelineCache<K> {
    fn default() -> Self {
        Self {
            compiled: Default::default(),
        }
    }
}

impl<K: PartialEq + Copy> PipelineCache<K> {
    /// The pipeline for `key`, compiled by `compile` the first time.
    pub fn get(
        &self,
        key: K,
        compile: impl FnOnce() -> Result<wgpu::ComputePipeline, GpuError>,
    ) -> Result<wgpu::ComputePipeline, GpuError> {
        let mut cache = self.compiled.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, p)) = cache.iter().find(|(k, _)| *k == key) {
            return Ok(p.clone());
        }
        let p = compile()?;
        cache.push((key, p.clone()));
        Ok(p)
    }
}

/// Records one compute pass dispatching `pipeline` over `groups` workgroups.
pub(crate) fn dispatch(
    encoder: &mut wgpu::CommandEncoder,
    pipeline: &wgpu::ComputePipeline,
    bind: &wgpu::BindGroup,
    groups: (u32, u32),
) {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: None,
        timestamp_writes: None,
    });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, bind, &[]);
    pass.dispatch_workgroups(groups.0, groups.1, 1);
}
