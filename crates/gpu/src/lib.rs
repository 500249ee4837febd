//! # Isolux GPU back end
//!
//! wgpu compute shaders in WGSL, so that Isolux runs on any Vulkan, Metal or
//! DX12 device, and in CI on Mesa's lavapipe (CPU Vulkan). Rust stays the
//! single source of truth: the `#[repr(C)]` mirrors in [`layout`] carry
//! size assertions checked against naga's layout of the shader source, and
//! the WGSL constants are generated from Rust ([`prelude`]).
//!
//! This first slice runs the exact first-hit intersection of
//! perturbation-function objects (SPEC §1) in f32 with a per-segment
//! reparameterization (`shaders/intersect.wgsl`): [`Gpu::intersect`]. A
//! conformance suite compares it with the CPU's `Object::intersect`.
//! Everything else of the GPU renderer is still to come (see
//! `docs/gpu.md`).

pub mod layout;

use layout::{GpuHit, GpuRay, GpuScene};
use wgpu::util::DeviceExt;

/// Threads per workgroup of the compute kernels.
pub const WORKGROUP_SIZE: u32 = 64;
/// `t` reported for a miss.
pub const MISS: f32 = -1.0;
/// Sentinel of an absent root (a large positive `t`).
pub const NO_ROOT: f32 = 3.0e38;
/// Smallest sub-interval of a segment the root isolation halves to
/// (2^-12): finer, the f32 control points of a sub-interval are dominated
/// by rounding and a sign change can be lost; regula falsi on the
/// polynomial itself refines from there.
pub const MIN_WIDTH: f32 = 1.0 / 4096.0;
/// Cap on subdivision steps per segment.
pub const MAX_SUBDIVISIONS: i32 = 4096;

/// WGSL constants generated from the Rust values above.
pub fn prelude() -> String {
    format!(
        "const WORKGROUP_SIZE: u32 = {WORKGROUP_SIZE}u;\n\
         const MISS: f32 = {MISS:?};\n\
         const NO_ROOT: f32 = {NO_ROOT:e};\n\
         const MIN_WIDTH: f32 = {MIN_WIDTH:e};\n\
         const MAX_SUBDIVISIONS: i32 = {MAX_SUBDIVISIONS};\n"
    )
}

/// The intersection shader with its prelude.
pub fn intersect_source() -> String {
    prelude() + include_str!("shaders/intersect.wgsl")
}

/// Errors of the GPU back end.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter: no Vulkan, Metal or DX12 device or driver.
    #[error("no GPU adapter found (install a Vulkan, Metal or DX12 driver; on Linux without a GPU, Mesa's lavapipe: apt-get install mesa-vulkan-drivers)")]
    NoAdapter,
    /// The device could not be opened.
    #[error("cannot open the GPU device: {0}")]
    Device(String),
    /// Reading results back failed.
    #[error("GPU readback failed: {0}")]
    Readback(String),
}

/// An open device with the compiled kernels.
pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    intersect: wgpu::ComputePipeline,
    /// Adapter name and back end, for reports.
    pub adapter: String,
}

impl Gpu {
    /// Opens the first adapter (high performance preferred) and compiles the
    /// kernels.
    pub fn new() -> Result<Self, GpuError> {
        let instance = wgpu::Instance::new(&wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN | wgpu::Backends::METAL | wgpu::Backends::DX12,
            ..Default::default()
        });
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
        }))
        .map_err(|_| GpuError::NoAdapter)?;
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("isolux"),
            required_features: wgpu::Features::empty(),
            required_limits: wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits()),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| GpuError::Device(e.to_string()))?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("intersect.wgsl"),
            source: wgpu::ShaderSource::Wgsl(intersect_source().into()),
        });
        let intersect = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("intersect"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        Ok(Self {
            device,
            queue,
            intersect,
            adapter: format!("{} ({:?})", info.name, info.backend),
        })
    }

    /// First hits of `rays` against the objects of `scene` (nearest over
    /// all objects): `[t, n]`, `t < 0` for a miss.
    pub fn intersect(&self, scene: &GpuScene, rays: &[GpuRay]) -> Result<Vec<GpuHit>, GpuError> {
        if rays.is_empty() {
            return Ok(Vec::new());
        }
        let d = &self.device;
        let storage = |label: &str, bytes: &[u8]| {
            // Storage buffers may not be empty, nor smaller than one
            // element of their array: pad with zeros.
            let zero = [0u8; 256];
            d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: if bytes.is_empty() { &zero } else { bytes },
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let objects = storage("objects", bytemuck::cast_slice(&scene.objects));
        let perts = storage("perturbations", bytemuck::cast_slice(&scene.perturbations));
        let ray_buf = storage("rays", bytemuck::cast_slice(rays));
        let size = (rays.len() * std::mem::size_of::<GpuHit>()) as u64;
        let out = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hits"),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let staging = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hits readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let counts = [rays.len() as u32, scene.objects.len() as u32, 0, 0];
        let uniform = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("counts"),
            contents: bytemuck::cast_slice(&counts),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let layout = self.intersect.get_bind_group_layout(0);
        let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("intersect"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: objects.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: perts.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: ray_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: out.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: uniform.as_entire_binding(),
                },
            ],
        });
        let mut enc = d.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("intersect"),
        });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("intersect"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.intersect);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((rays.len() as u32).div_ceil(WORKGROUP_SIZE), 1, 1);
        }
        enc.copy_buffer_to_buffer(&out, 0, &staging, 0, size);
        self.queue.submit(Some(enc.finish()));
        let slice = staging.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        d.poll(wgpu::PollType::Wait)
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        rx.recv()
            .map_err(|e| GpuError::Readback(e.to_string()))?
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        let hits = bytemuck::cast_slice::<u8, GpuHit>(&slice.get_mapped_range()).to_vec();
        staging.unmap();
        Ok(hits)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn shaders_validate_with_naga() {
        let src = super::intersect_source();
        let module = naga::front::wgsl::parse_str(&src)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&src)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::empty(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&src)));
    }
}
