//! # Isolux GPU back end
//!
//! wgpu compute shaders in WGSL, so that Isolux runs on any Vulkan, Metal or
//! DX12 device, and in CI on Mesa's lavapipe (CPU Vulkan). Rust stays the
//! single source of truth: the `#[repr(C)]` mirrors in [`layout`] carry
//! size assertions checked against naga's layout of the shader source, and
//! the WGSL constants are generated from Rust ([`prelude`]).
//!
//! Kernels (`src/shaders/`, one file per concern, concatenated after the
//! generated [`prelude`]):
//! - `geometry.wgsl`: the exact first hit of perturbation-function objects
//!   (SPEC §1) in f32 with a per-segment reparameterization;
//! - `materials.wgsl`: the material library's `f`, `pdf` and `sample`
//!   (the models [`layout::GpuMaterials::new`] accepts);
//! - `wave.wgsl`: the `wave` material (diffraction from a heightfield,
//!   placed per shading point);
//! - `intersect.wgsl`, `material_eval.wgsl`: conformance entry points
//!   ([`Gpu::intersect`], [`Gpu::eval_materials`]) compared with the CPU
//!   in `tests/`;
//! - the path tracer ([`Gpu::render`], [`GpuFrame`]), in the files of
//!   [`RENDER_FILES`], concatenated in that order: `render.wgsl` (its
//!   parameters, bindings, random numbers and ray helpers),
//!   `environment.wgsl`, `direct.wgsl` (next-event estimation and the
//!   path's state), `subsurface.wgsl`, `manifold.wgsl` (light refracted
//!   through curved boundaries, caustics), `media.wgsl` (transmittance,
//!   lamps in media, the media a path is in), `integrator.wgsl` (a
//!   bounce, shading, a path's radiance), `camera.wgsl` (camera rays, tile
//!   lists, the megakernel `main`, `resolve`), `wavefront.wgsl` (the
//!   wavefront and sorted wavefront steps), `aov.wgsl`; then
//!   `realtime.wgsl`, the real-time mode.
//!
//! What is not on the GPU yet is listed in `docs/gpu.md`.

mod checks;
mod kernels;
pub mod layout;
mod render;
mod source;

pub use checks::{
    f32_ill_conditioned, f32_plane_at_box_face, f32_shortfall, fine_medium_warning,
    has_random_walk, mix_of_waves, object_floor, replace_unsupported, spawn_floor,
    thin_object_warning, unsupported_material, wave_count, worst_bump_condition, worst_scale_ratio,
    BumpCondition, ScaleRatio, F32_CONDITION_LIMIT, F32_PLANE_GAP_ULPS, F32_VALUE_LIMIT,
    MAX_SCALE_RATIO,
};
/// The naga that writes the bounds probe's SPIR-V ([`kernel_spirv`]): the
/// one wgpu builds on.
pub use naga;
pub use render::{
    medium_bits, nested_too_deep, padded_pixels, rebase_point, refracted_media, scene_features,
    DispatchTime, GpuFrame, Profile, SortedSteps, PARAM_BLOCKS, WF_TILE_MAX,
};
pub use source::{
    geometry_source, intersect_source, intersect_source_with, kernel_spirv, material_eval_source,
    prelude, probe_spirv, render_source, render_source_variant, render_source_with, Features,
    OutOfBounds, Precision, REAL_SPAN_F32, RENDER_FILES,
};
/// The wgpu this crate is built on (the viewer draws with the same).
pub use wgpu;

use layout::{GpuAnswer, GpuHit, GpuMaterials, GpuParams, GpuQuery, GpuRay, GpuScene};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};
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
/// Rays leaving a surface start `SPAWN_OFFSET L + SPAWN_OFFSET_WORLD
/// |p|_inf` off it along the normal, `L` the length of the surface's
/// object, its box's largest side at most 1, an unbounded object's that
/// of the scene's bounded objects (`isolux_geometry::Object::length`;
/// [`checks::object_floor`], from `GpuObject::origin.w`), so that a scene
/// renders the same in any unit and a small object beside a large one
/// keeps its own offset (until 2026-12-06 `L` was 1, then for one day the
/// scene's length). The CPU's
/// f64 path uses `1e-7 (L + |p - origin|_inf) + 1e-14 |p|_inf` in its
/// objects' frames (`isolux_geometry::Hit::offset`). The intersection works in each object's frame
/// (`layout::GpuObject`), so a hit is good to about 1e-7 of its object's
/// size there; the world point `p` adds its own f32 rounding, about
/// `6e-8 |p|`, which the second term covers 16 times over. (Until
/// 2026-12-02 the margin was `1e-4 (1 + |p|_inf)`: 0.1 units at 1000 units
/// from the origin, which lost the contact shadows of small objects
/// there; docs/gpu.md, "Precision".)
pub const SPAWN_OFFSET: f32 = 1e-4;
/// See [`SPAWN_OFFSET`].
pub const SPAWN_OFFSET_WORLD: f32 = 1e-6;
/// Perturbations a ray keeps per object after culling (those active on its
/// span); a ray that meets more uses all of the object's perturbations.
pub const MAX_CANDIDATES: u32 = 32;
/// Objects with at most this many perturbations cull them by a linear
/// pass over all of them instead of their hierarchy (the traversal's stack
/// costs more than it saves on a few supports: see docs/benchmarks.md).
pub const LINEAR_CULL: u32 = 4;
const _: () = assert!(LINEAR_CULL <= MAX_CANDIDATES);
/// Perturbations an object may have and still keep its candidates as a
/// bit mask (a `u32` in `geometry.wgsl`) rather than in a list.
pub const MASK_CANDIDATES: u32 = u32::BITS;
/// Point lights whose shadow rays a vertex traces before it is shaded, at
/// most (a bit mask; `MASK_LIGHTS` in the render kernels); a scene with more
/// traces the rest in the shading loop ([`Features::many_lights`]).
pub const MASK_LIGHTS: u32 = u32::BITS;
/// Environment kinds (`Params.counts.w`).
pub const ENV_CONSTANT: u32 = 0;
/// An equirectangular map, light-sampled.
pub const ENV_MAP: u32 = 1;
/// Storage buffers of `render.wgsl`'s group 0 (bindings 0 to 13: scene,
/// environment, accumulation, parameters, AOVs, sample layers), shared by
/// its entry points (`Gpu::render_layout`).
pub const RENDER_BINDINGS: usize = 15;

/// The render bindings' parameters (`params` of `render.wgsl`): one
/// [`GpuParams`] block of the frame's parameter buffer, chosen by a
/// dynamic offset per `set_bind_group`, so that a frame's dispatches
/// (each wavefront step, each run of samples) read their blocks from one
/// buffer written once per submission, with no copy between dispatches.
pub(crate) const PARAMS_BINDING: u32 = 7;

/// The size of a [`GpuParams`] block, as a binding size.
fn params_size() -> wgpu::BufferSize {
    wgpu::BufferSize::new(std::mem::size_of::<GpuParams>() as u64).expect("GpuParams is not empty")
}

/// Storage buffers of the wavefront's group 1 (paths, queues, step
/// counters, the sorted wavefront's hits).
pub const WAVEFRONT_BINDINGS: usize = 4;

/// Bins of the sorted wavefront's sort by material (`WF_BINS` in
/// wavefront.wgsl): material records below `WF_BINS - 1` their own, the rest
/// the last.
pub const WF_BINS: u32 = 64;

/// Which of the two path tracers of `render.wgsl` a frame runs. Both trace
/// the same paths with the same random numbers, so they give the same
/// image (within the drivers' floating-point contraction); they differ in
/// speed (docs/gpu.md, "The wavefront path tracer").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PathKernel {
    /// On GPUs the sorted wavefront ([`PathKernel::Sorted`], since later
    /// on 2026-12-04), or the wavefront for scenes with the subsurface
    /// integrator: on an NVIDIA H200 the wavefront path traces the
    /// gallery in 0.62 of the megakernel's time (84.6 against 136.2 ms
    /// at 1080p, 16 spp; direct light 0.55), and the sort leaves a
    /// 32-lane group 0.40 of the wavefront's material branches to shade
    /// there (`examples/wavefront_lanes.rs`; lavapipe on one thread: 0.73-0.85
    /// of the wavefront's time, path traced; docs/gpu.md, "The sorted
    /// wavefront").
    /// On CPU drivers (lavapipe), where the two take the same time on
    /// surfaces (the gallery 0.95-1.03, the dipole 0.88-1.02) and the
    /// wavefront's two kernels take twice the megakernel's compile time
    /// (tens of seconds each there), the wavefront only for scenes with a
    /// random-walk medium (0.52-0.57 of the megakernel's time) or a `wave`
    /// material, whose second run in the megakernel's loop Mesa 22.3
    /// miscompiles ("Known defect"; docs/gpu.md, "The wavefront path
    /// tracer").
    #[default]
    Auto,
    /// One kernel runs each path to its end (`main`).
    Megakernel,
    /// One dispatch per bounce over the paths still alive (`trace`).
    Wavefront,
    /// The wavefront with each bounce in three or four dispatches, its
    /// hits shaded in order of their material (`trace_extend`,
    /// `trace_scatter`, `trace_shadow` where
    /// [`Features::shadows_ahead`], `trace_shade`; docs/gpu.md "The
    /// sorted wavefront"): the same image, for a GPU's SIMT groups to shade one
    /// material each. The default on GPUs ([`PathKernel::Auto`]); not yet
    /// timed on one. A scene with the subsurface integrator (media,
    /// dipoles) runs [`PathKernel::Wavefront`].
    Sorted,
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
    /// The scene uses a material that has no GPU implementation yet.
    #[error("material \"{name}\" (type {type_name}) does not run on the GPU yet (docs/gpu.md lists the models that do)")]
    Unsupported {
        /// The material's name in the scene.
        name: String,
        /// Its `type`.
        type_name: String,
    },
    /// Invalid camera or film, or a setting the device cannot take.
    #[error("{0}")]
    Setup(String),
    /// The GPU reported an error while running queued work (wgpu's
    /// validation, memory running out; [`Gpu::check`]).
    #[error("the GPU reported an error: {0}")]
    Failed(String),
    /// An object of the scene lies farther from the GPU's origin than its
    /// f32 coordinates resolve for its size ([`f32_shortfall`]).
    #[error("{0}")]
    Precision(String),
    /// Scene data larger than the adapter can bind in one storage buffer.
    #[error("{what} takes {}, more than this adapter binds in one storage buffer ({}){hint}", size(*.bytes), size(*.limit))]
    TooLarge {
        /// What overflows, in the user's terms.
        what: String,
        /// Its size in bytes.
        bytes: u64,
        /// The adapter's limit in bytes.
        limit: u64,
        /// A cause to look at, or empty.
        hint: String,
    },
}

/// What an adapter with `limits` lacks for the kernels, as the end of a
/// sentence naming it, or `None`: the wavefront's kernels bind
/// [`RENDER_BINDINGS`] + [`WAVEFRONT_BINDINGS`] storage buffers in two
/// groups, one with a dynamic offset, and run workgroups of 64 threads
/// (64 in x, or 8 x 8) sharing 256 bytes. WebGPU's default limits (8
/// storage buffers a stage) and downlevel devices fall short; lavapipe,
/// NVIDIA's and most current desktop GPUs do not. Checked when the device is
/// opened, so that such an adapter is a clear error instead of wgpu's
/// validation panic at the first pipeline.
fn missing_limits(limits: &wgpu::Limits) -> Option<String> {
    let storage = (RENDER_BINDINGS + WAVEFRONT_BINDINGS) as u32;
    let needs = [
        (
            limits.max_storage_buffers_per_shader_stage,
            storage,
            "storage buffers per shader stage",
        ),
        (limits.max_bind_groups, 2, "bind groups"),
        (
            limits.max_dynamic_storage_buffers_per_pipeline_layout,
            1,
            "dynamic storage buffers per pipeline layout",
        ),
        (
            limits.max_compute_invocations_per_workgroup,
            64,
            "compute invocations per workgroup",
        ),
        (
            limits.max_compute_workgroup_size_x,
            64,
            "threads per workgroup in x",
        ),
        (
            limits.max_compute_workgroup_size_y,
            8,
            "threads per workgroup in y",
        ),
        (
            limits.max_compute_workgroup_storage_size,
            256,
            "bytes of workgroup storage",
        ),
    ];
    needs
        .iter()
        .find(|(has, need, _)| has < need)
        .map(|(has, need, what)| {
            format!("offers {has} {what}; Isolux's GPU kernels need {need} (docs/gpu.md)")
        })
}

/// A byte count for messages: KiB below 1 MiB, else MiB (one decimal).
fn size(bytes: u64) -> String {
    if bytes < 1 << 20 {
        format!("{:.1} KiB", bytes as f64 / 1024.0)
    } else {
        format!("{:.1} MiB", bytes as f64 / (1024.0 * 1024.0))
    }
}

/// Two GPU timestamps (the start of a frame's first dispatch and the end of
/// its last) and the buffer they resolve into.
pub(crate) struct Timestamps {
    pub(crate) set: wgpu::QuerySet,
    pub(crate) resolve: wgpu::Buffer,
    /// Nanoseconds per tick.
    pub(crate) period: f64,
}

impl Timestamps {
    fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Self {
        Self {
            set: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("frame timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            }),
            resolve: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("frame timestamps"),
                size: 2 * wgpu::QUERY_SIZE as u64,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            period: queue.get_timestamp_period() as f64,
        }
    }
}

/// An open device with the compiled kernels.
pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    intersect: OnceLock<wgpu::ComputePipeline>,
    material_eval: OnceLock<wgpu::ComputePipeline>,
    /// The render module's kernels by entry point and the features it
    /// reaches ([`Features::reached_by`]), each compiled on first use.
    kernels: Mutex<HashMap<(&'static str, Features), wgpu::ComputePipeline>>,
    render_layout: OnceLock<(wgpu::BindGroupLayout, wgpu::PipelineLayout)>,
    /// The wavefront path tracer's group 1 (paths, queues, step counters)
    /// and its pipeline layout (groups 0 and 1).
    wavefront_layout: OnceLock<(wgpu::BindGroupLayout, wgpu::PipelineLayout)>,
    /// One per set of [`Features`] ([`render_source_variant`]).
    render_modules: Mutex<HashMap<Features, wgpu::ShaderModule>>,
    /// GPU timestamps around a frame's dispatches, where the adapter offers
    /// `TIMESTAMP_QUERY` (for `isolux bench gpu`).
    pub(crate) timestamps: Option<Timestamps>,
    precision: Precision,
    /// Whether modules are compiled with wgpu's run-time checks
    /// ([`Gpu::set_runtime_checks`]; off by default).
    runtime_checks: bool,
    /// The device takes pass-through SPIR-V ([`Gpu::for_bounds_probes`]).
    passthrough: bool,
    /// How the render kernels treat an index out of bounds, where they are
    /// compiled to probe for one ([`Gpu::set_bounds_probe`]).
    bounds_probe: Option<OutOfBounds>,
    /// How frames prepared from now on path trace ([`Gpu::set_path_kernel`]).
    path_kernel: PathKernel,
    f64_supported: bool,
    /// The adapter is a CPU (lavapipe): frames default to kernels without
    /// tile lists ([`Features::tiles`]) and path trace surfaces with the
    /// megakernel ([`PathKernel::Auto`]).
    cpu: bool,
    /// The first error wgpu reported outside a call that returns one
    /// (validation, out of memory), kept for [`Gpu::check`] instead of
    /// wgpu's default, a panic.
    failure: Arc<Mutex<Option<String>>>,
    /// Adapter name and back end, for reports.
    pub adapter: String,
    /// The driver's name and version as it reports them (for example
    /// `llvmpipe Mesa 22.3.6 (LLVM 15.0.6)` for lavapipe), for reports and for
    /// tests that know a driver's defects.
    pub driver: String,
}

impl Gpu {
    /// Opens the first adapter (high performance preferred) and compiles the
    /// kernels.
    pub fn new() -> Result<Self, GpuError> {
        Self::open_first(false)
    }

    /// Opens the first adapter as [`Gpu::new`] does, on a device that also
    /// takes SPIR-V this crate writes itself, for [`Gpu::set_bounds_probe`]
    /// (Vulkan adapters only). For tests and diagnosis: the device is
    /// opened with wgpu's experimental pass-through shaders, which
    /// [`Gpu::new`] leaves off.
    pub fn for_bounds_probes() -> Result<Self, GpuError> {
        Self::open_first(true)
    }

    fn open_first(probes: bool) -> Result<Self, GpuError> {
        let instance = Self::instance();
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
        }))
        .map_err(|_| GpuError::NoAdapter)?;
        Self::open(&adapter, probes)
    }

    /// The instance [`Gpu::new`] opens its adapter from: Vulkan, Metal and
    /// DX12 (a window's surface, as in `isolux view`, is made from it).
    pub fn instance() -> wgpu::Instance {
        wgpu::Instance::new(&wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN | wgpu::Backends::METAL | wgpu::Backends::DX12,
            ..Default::default()
        })
    }

    /// Opens a device on `adapter` (for example one compatible with a
    /// window's surface).
    pub fn with_adapter(adapter: &wgpu::Adapter) -> Result<Self, GpuError> {
        Self::open(adapter, false)
    }

    fn open(adapter: &wgpu::Adapter, probes: bool) -> Result<Self, GpuError> {
        let info = adapter.get_info();
        if let Some(short) = missing_limits(&adapter.limits()) {
            return Err(GpuError::Device(format!(
                "the adapter {} ({:?}) {short}",
                info.name, info.backend
            )));
        }
        // f64 is requested where offered, so that `set_precision` can
        // switch the intersection without reopening the device.
        let f64_supported = adapter.features().contains(wgpu::Features::SHADER_F64);
        let timestamps_supported = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let mut required_features = wgpu::Features::empty();
        if f64_supported {
            required_features |= wgpu::Features::SHADER_F64;
        }
        // Timestamps only time the benchmark's frames; requested where
        // offered, never needed.
        if timestamps_supported {
            required_features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        // Pass-through SPIR-V, for the bounds probe only.
        let passthrough = probes
            && info.backend == wgpu::Backend::Vulkan
            && adapter
                .features()
                .contains(wgpu::Features::EXPERIMENTAL_PASSTHROUGH_SHADERS);
        if probes && !passthrough {
            return Err(GpuError::Device(format!(
                "the adapter {} ({:?}) takes no SPIR-V of its caller, which the bounds probe needs (a Vulkan adapter does)",
                info.name, info.backend
            )));
        }
        if passthrough {
            required_features |= wgpu::Features::EXPERIMENTAL_PASSTHROUGH_SHADERS;
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("isolux"),
            required_features,
            // The wavefront's kernels bind 19 storage buffers
            // (`missing_limits`): ask for what the adapter offers rather
            // than WebGPU's defaults (8).
            required_limits: adapter.limits(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
            experimental_features: if passthrough {
                // SAFETY: the one experimental feature requested is
                // pass-through shaders, used only by the bounds probe,
                // whose SPIR-V naga writes from this crate's own WGSL,
                // validated (`Gpu::probe_module`).
                unsafe { wgpu::ExperimentalFeatures::enabled() }
            } else {
                wgpu::ExperimentalFeatures::disabled()
            },
        }))
        .map_err(|e| GpuError::Device(e.to_string()))?;
        let failure: Arc<Mutex<Option<String>>> = Arc::default();
        let sink = failure.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            let what = match &e {
                wgpu::Error::OutOfMemory { .. } => {
                    format!("out of GPU memory ({e}): try a smaller film (--width, --height)")
                }
                _ => e.to_string(),
            };
            if let Ok(mut first) = sink.lock() {
                first.get_or_insert(what);
            }
        }));
        let timestamps = timestamps_supported.then(|| Timestamps::new(&device, &queue));
        Ok(Self {
            failure,
            timestamps,
            device,
            queue,
            intersect: OnceLock::new(),
            material_eval: OnceLock::new(),
            kernels: Default::default(),
            render_layout: OnceLock::new(),
            wavefront_layout: OnceLock::new(),
            render_modules: Default::default(),
            precision: Precision::F32,
            runtime_checks: false,
            passthrough,
            bounds_probe: None,
            path_kernel: PathKernel::Auto,
            f64_supported,
            cpu: info.device_type == wgpu::DeviceType::Cpu,
            adapter: format!("{} ({:?})", info.name, info.backend),
            driver: format!("{} {}", info.driver, info.driver_info)
                .trim()
                .to_string(),
        })
    }

    /// Whether the adapter offers f64 in shaders (`SHADER_F64`).
    pub fn supports_f64(&self) -> bool {
        self.f64_supported
    }

    /// Whether the driver is Mesa 22's, whose loop miscompile (docs/gpu.md,
    /// "Known defect") loses a few long paths and, in the megakernel, ends
    /// paths at their second `wave` vertex.
    pub fn miscompiles_loops(&self) -> bool {
        self.driver.contains("Mesa 22.")
    }

    /// The precision the intersection computes in.
    pub fn precision(&self) -> Precision {
        self.precision
    }

    /// Chooses the intersection's precision for `scene`: f32, unless an
    /// object is too ill-conditioned for it ([`f32_ill_conditioned`]) or
    /// a plane misses its box by less than f32 tells apart
    /// ([`f32_plane_at_box_face`]), then f64. `Ok(Some(note))` says why
    /// f64 was chosen. Without `SHADER_F64` on the adapter, an
    /// ill-conditioned object is an error naming it and the adapter
    /// (rendering it in f32 loses its surfaces), and a plane at its box's
    /// face a note that f32 draws it.
    pub fn precision_for(
        &mut self,
        scene: &isolux_render::Scene,
    ) -> Result<Option<String>, GpuError> {
        // Whether f32 loses surfaces (an error without f64) or only draws
        // a plane the CPU clips away (a note).
        let (why, loses) = if let Some(why) = f32_ill_conditioned(scene) {
            (why, true)
        } else if let Some(why) = f32_plane_at_box_face(scene) {
            (why, false)
        } else {
            self.set_precision(Precision::F32)?;
            return Ok(None);
        };
        if !self.f64_supported {
            if !loses {
                self.set_precision(Precision::F32)?;
                return Ok(Some(format!(
                    "{why}, and the adapter {} does not offer f64 in shaders (SHADER_F64): \
                     intersecting in f32, which draws the plane",
                    self.adapter
                )));
            }
            return Err(GpuError::Setup(format!(
                "{why}, and the adapter {} does not offer f64 in shaders (SHADER_F64): render \
                 without --gpu (the CPU works in f64)",
                self.adapter
            )));
        }
        self.set_precision(Precision::F64)?;
        Ok(Some(format!("{why}: intersecting in f64")))
    }

    /// Sets the precision of the intersection in every kernel (compiled
    /// again on next use). f64 on an adapter without `SHADER_F64` is an
    /// error naming the adapter.
    pub fn set_precision(&mut self, precision: Precision) -> Result<(), GpuError> {
        if precision == Precision::F64 && !self.f64_supported {
            return Err(GpuError::Setup(format!(
                "the adapter {} does not offer f64 in shaders (SHADER_F64); use f32",
                self.adapter
            )));
        }
        if precision != self.precision {
            self.precision = precision;
            self.intersect = OnceLock::new();
            self.forget_render_kernels();
        }
        Ok(())
    }

    /// Whether the kernels are compiled with the run-time checks that wgpu
    /// writes into a shader it does not trust ([`wgpu::ShaderRuntimeChecks`]):
    /// every index into an array clamped, and every loop given an iteration
    /// counter that ends it after 2^64 iterations (`force_loop_bounding`;
    /// buffers are left to the driver's robust access where it has it).
    /// Off by default: the shaders are this crate's own, every loop in
    /// them ends by construction (the hierarchies' skip links only move
    /// forward, the root isolation and segment walks have guards, the
    /// path's bounces a bound), and their indices stay in bounds (the
    /// conformance and image tests run them without the checks). On RADV's
    /// compiler the checks cost the gallery's path tracer 7 VGPRs and 6%
    /// of its instructions (`kernel_stats --checks`; docs/gpu.md). Frames
    /// prepared from now on use the setting; kernels are compiled again.
    pub fn set_runtime_checks(&mut self, on: bool) {
        if on != self.runtime_checks {
            self.runtime_checks = on;
            self.intersect = OnceLock::new();
            self.material_eval = OnceLock::new();
            self.forget_render_kernels();
        }
    }

    /// Whether the kernels are compiled with wgpu's run-time checks.
    pub fn runtime_checks(&self) -> bool {
        self.runtime_checks
    }

    /// Compiles the render kernels of frames prepared from now on so that
    /// every index out of bounds, into a local array, a buffer or a
    /// texture, does what `policy` says (`None`: as
    /// [`Gpu::set_runtime_checks`] says, the default). Rendering a scene
    /// with [`OutOfBounds::Clamp`] and with [`OutOfBounds::Zero`] gives
    /// the same image bit for bit where no kernel reads out of bounds,
    /// and a different one, almost surely, where one does: an index
    /// out of bounds is found without knowing where to look (docs/gpu.md,
    /// "Probing for indices out of bounds"). Only the render kernels
    /// (path tracer, real time, AOVs) are probed. Needs a device opened
    /// by [`Gpu::for_bounds_probes`].
    pub fn set_bounds_probe(&mut self, policy: Option<OutOfBounds>) -> Result<(), GpuError> {
        if policy.is_some() && !self.passthrough {
            return Err(GpuError::Setup(format!(
                "the bounds probe needs a device opened by Gpu::for_bounds_probes, not {}",
                self.adapter
            )));
        }
        if policy != self.bounds_probe {
            self.bounds_probe = policy;
            self.forget_render_kernels();
        }
        Ok(())
    }

    /// Drops the compiled render kernels and modules, so that frames
    /// prepared from now on compile them again with the current settings.
    /// Each setter drops its own other caches (the intersection and
    /// material-evaluation kernels) beside these.
    fn forget_render_kernels(&mut self) {
        self.kernels = Default::default();
        self.render_modules = Default::default();
    }

    /// The render kernels' bounds probe ([`Gpu::set_bounds_probe`]).
    pub fn bounds_probe(&self) -> Option<OutOfBounds> {
        self.bounds_probe
    }

    /// How frames prepared from now on (and [`Gpu::render`]) path trace
    /// ([`PathKernel`]; the same image either way).
    pub fn set_path_kernel(&mut self, kernel: PathKernel) {
        self.path_kernel = kernel;
    }

    /// How frames prepared now path trace.
    pub fn path_kernel(&self) -> PathKernel {
        self.path_kernel
    }

    /// Whether the adapter is a CPU driver (lavapipe), whose frames
    /// default to other kernels ([`Features::tiles`], [`PathKernel::Auto`]).
    pub fn is_cpu(&self) -> bool {
        self.cpu
    }

    /// The device, for callers that draw with it (the viewer).
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The queue.
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The largest storage buffer this device binds (and creates).
    fn binding_limit(&self) -> u64 {
        let l = self.device.limits();
        (l.max_storage_buffer_binding_size as u64).min(l.max_buffer_size)
    }

    fn storage(&self, label: &str, bytes: &[u8]) -> wgpu::Buffer {
        let zero = [0u8; 256];
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: if bytes.is_empty() { &zero } else { bytes },
                usage: wgpu::BufferUsages::STORAGE,
            })
    }

    /// A bind group of `pipeline`'s group 0 with `buffers` at bindings 0,
    /// 1, 2, ... in order.
    fn bind_group(
        &self,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[&wgpu::Buffer],
    ) -> wgpu::BindGroup {
        self.buffer_bind_group("kernel", &pipeline.get_bind_group_layout(0), buffers, None)
    }

    /// A zeroed storage buffer of `size` bytes that can be read back.
    fn output(&self, label: &str, size: u64) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// The bytes between two [`GpuParams`] blocks of a frame's parameter
    /// buffer: the block's size rounded up to the device's storage offset
    /// alignment (256 bytes on most devices).
    fn params_stride(&self) -> u64 {
        let align = self.device.limits().min_storage_buffer_offset_alignment as u64;
        (std::mem::size_of::<GpuParams>() as u64).next_multiple_of(align.max(1))
    }

    /// A frame's parameter buffer: `render::PARAM_BLOCKS` blocks, written
    /// by copies (`render::passes::ParamBlocks`), bound one block at a time
    /// (read-only storage, not uniform: see [`Gpu::params_buffer`]).
    fn param_blocks_buffer(&self) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("params"),
            size: render::PARAM_BLOCKS as u64 * self.params_stride(),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// A read-only storage buffer holding a kernel's parameters `value`
    /// (writable later by copies).
    ///
    /// Not a uniform buffer, on purpose: Mesa's lavapipe (the CI's
    /// driver) *inlines* uniform-buffer values that steer a branch or a
    /// loop bound into the shader and compiles a new variant of the kernel
    /// for every new set of values: every seed, image size, sample index
    /// and object count meant another LLVM compile of the path tracer
    /// (minutes each), under a disk-cache key no other run shared. Storage
    /// loads are never inlined, so each kernel compiles once. See
    /// docs/gpu.md, "Compile time on lavapipe".
    fn params_buffer<T: bytemuck::Pod>(&self, label: &str, value: &T) -> wgpu::Buffer {
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::bytes_of(value),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            })
    }

    /// Runs `pipeline` over `groups` workgroups with `buffers` bound in
    /// order, then copies `out` back.
    fn run_and_read<T: bytemuck::Pod>(
        &self,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[&wgpu::Buffer],
        groups: (u32, u32),
        out: &wgpu::Buffer,
    ) -> Result<Vec<T>, GpuError> {
        let d = &self.device;
        let bind = self.bind_group(pipeline, buffers);
        let mut enc = d.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: None,
                timestamp_writes: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(groups.0, groups.1, 1);
        }
        self.queue.submit(Some(enc.finish()));
        self.read_back(out)
    }

    /// Copies a storage buffer of this device (made with
    /// `BufferUsages::COPY_SRC`) back to the host as `T`s, after the work
    /// submitted so far (waits for the queue): for kernels of one's own on
    /// [`Gpu::device`], as the bounds probe's test runs one.
    pub fn read_back<T: bytemuck::Pod>(&self, out: &wgpu::Buffer) -> Result<Vec<T>, GpuError> {
        let d = &self.device;
        let size = out.size();
        let staging = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = d.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        enc.copy_buffer_to_buffer(out, 0, &staging, 0, size);
        self.queue.submit(Some(enc.finish()));
        let slice = staging.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.wait()?;
        rx.recv()
            .map_err(|e| GpuError::Readback(e.to_string()))?
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        let v = bytemuck::cast_slice::<u8, T>(&slice.get_mapped_range()).to_vec();
        staging.unmap();
        Ok(v)
    }

    /// The first error the GPU reported since the device was opened
    /// outside a call that returns one (a command's validation, memory
    /// running out), as [`GpuError::Failed`]; `Ok` if none. [`Gpu::wait`]
    /// and every read-back check it; a caller that only queues work (the
    /// viewer's frames) checks it itself.
    pub fn check(&self) -> Result<(), GpuError> {
        match self.failure.lock().ok().and_then(|f| f.clone()) {
            Some(what) => Err(GpuError::Failed(what)),
            None => Ok(()),
        }
    }

    /// Waits until the queue is idle.
    pub fn wait(&self) -> Result<(), GpuError> {
        // Waits of 60 s each: a long pass on a CPU driver (lavapipe on a
        // busy machine) is not an error, so wait again, up to half an hour.
        for _ in 0..30 {
            match self.device.poll(wgpu::PollType::Wait {
                submission_index: None,
                timeout: Some(std::time::Duration::from_secs(60)),
            }) {
                Ok(_) => return self.check(),
                Err(wgpu::PollError::Timeout) => continue,
                Err(e) => return Err(GpuError::Readback(e.to_string())),
            }
        }
        Err(GpuError::Readback(
            "the GPU work did not finish within 30 minutes".into(),
        ))
    }

    /// Every material's `f`, `pdf` and `sample` for `queries` (local
    /// frame), on the GPU: the material conformance kernel.
    pub fn eval_materials(
        &self,
        materials: &GpuMaterials,
        queries: &[GpuQuery],
    ) -> Result<Vec<GpuAnswer>, GpuError> {
        if queries.is_empty() {
            return Ok(Vec::new());
        }
        let pipeline = self.pipeline(&self.material_eval, "material_eval", material_eval_source);
        let mats = self.storage("materials", bytemuck::cast_slice(&materials.materials));
        let data = self.storage("material data", bytemuck::cast_slice(&materials.data));
        let qs = self.storage("queries", bytemuck::cast_slice(queries));
        let out = self.output(
            "answers",
            (queries.len() * std::mem::size_of::<GpuAnswer>()) as u64,
        );
        let counts = [queries.len() as u32, 0, 0, 0];
        let uniform = self.params_buffer("counts", &counts);
        let groups = (queries.len() as u32).div_ceil(WORKGROUP_SIZE);
        self.run_and_read(
            pipeline,
            &[&mats, &qs, &out, &uniform, &data],
            (groups, 1),
            &out,
        )
    }

    /// First hits of `rays` against the objects of `scene` (nearest over
    /// all objects): `[t, n]`, `t < 0` for a miss.
    pub fn intersect(&self, scene: &GpuScene, rays: &[GpuRay]) -> Result<Vec<GpuHit>, GpuError> {
        self.hits(scene, rays, false)
    }

    /// Whether each of `rays` meets an object of `scene` on its `[t_min,
    /// t_max]`: the render kernels' shadow rays (any hit, not the nearest;
    /// `first_root` in geometry.wgsl stops at the first interval with a
    /// sign change).
    pub fn occluded(&self, scene: &GpuScene, rays: &[GpuRay]) -> Result<Vec<bool>, GpuError> {
        Ok(self
            .hits(scene, rays, true)?
            .iter()
            .map(|h| h.v[0] >= 0.0)
            .collect())
    }

    /// The intersection kernel over `rays`: nearest hits, or with `any`
    /// some hit (its normal unset).
    fn hits(&self, scene: &GpuScene, rays: &[GpuRay], any: bool) -> Result<Vec<GpuHit>, GpuError> {
        if rays.is_empty() {
            return Ok(Vec::new());
        }
        let pipeline = self.pipeline(&self.intersect, "intersect", || {
            intersect_source_with(self.precision)
        });
        let objects = self.storage("objects", bytemuck::cast_slice(&scene.objects));
        let perts = self.storage("perturbations", bytemuck::cast_slice(&scene.perturbations));
        let ray_buf = self.storage("rays", bytemuck::cast_slice(rays));
        let nodes = self.storage("bvh nodes", bytemuck::cast_slice(&scene.nodes));
        let out = self.output("hits", (rays.len() * std::mem::size_of::<GpuHit>()) as u64);
        let counts = [rays.len() as u32, scene.objects.len() as u32, any as u32, 0];
        let uniform = self.params_buffer("counts", &counts);
        let groups = (rays.len() as u32).div_ceil(WORKGROUP_SIZE);
        self.run_and_read(
            pipeline,
            &[&objects, &perts, &ray_buf, &out, &uniform, &nodes],
            (groups, 1),
            &out,
        )
    }
}

/// Whether the render module's entry point `entry` binds the wavefront's
/// group 1 ([`Gpu::wavefront_layout`]) beside the render group: the
/// wavefront's steps (`trace...`) and the megakernel `main`, which counts
/// its capped paths there (render.rs `MegaCount`).
pub(crate) fn binds_wavefront_group(entry: &str) -> bool {
    entry.starts_with("trace") || entry == "main"
}

#[cfg(test)]
mod tests {
    /// WebGPU's default limits (8 storage buffers a stage) and downlevel
    /// ones are refused by name; a desktop device's are not.
    #[test]
    fn adapters_short_of_the_kernels_limits_are_named() {
        for limits in [wgpu::Limits::default(), wgpu::Limits::downlevel_defaults()] {
            let why = super::missing_limits(&limits).expect("too few storage buffers");
            assert!(why.contains("storage buffers per shader stage"), "{why}");
            assert!(why.contains("need 19"), "{why}");
        }
        let desktop = wgpu::Limits {
            max_storage_buffers_per_shader_stage: 1 << 20,
            ..wgpu::Limits::default()
        };
        assert_eq!(super::missing_limits(&desktop), None);
        let small = wgpu::Limits {
            max_compute_workgroup_storage_size: 128,
            ..desktop
        };
        assert!(super::missing_limits(&small).is_some_and(|w| w.contains("workgroup storage")));
    }
}
