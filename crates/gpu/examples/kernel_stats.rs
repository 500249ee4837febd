//! What a GPU's own compiler makes of the kernels: registers, spills, code
//! size and occupancy, as the driver reports them through
//! `VK_KHR_pipeline_executable_properties` (RADV and other Mesa drivers,
//! NVIDIA's), one row per kernel.
//!
//! ```text
//! cargo run --release -p isolux-gpu --example kernel_stats [-- SCENE.toml ...] [--all]
//!     [--dump DIR] [--source FILE.wgsl ...] [--checks none|wgpu]
//! ```
//!
//! Kernels: the intersection alone (the conformance kernel), then for each
//! scene (default: the furnace, the gallery, the translucent scene) and for
//! every model at once (`all`, the general kernels) the path tracer
//! (`main`), the wavefront step (`trace`, `trace_last`), the sorted
//! wavefront's large kernels (`trace_extend`, `trace_shadow`, `trace_shade`) and the
//! real-time kernel (`realtime`), each specialized to the scene's models,
//! candidate list and media as `isolux render --gpu` runs it
//! (`isolux_gpu::scene_features`, the rules `Gpu::prepare` follows; until
//! 2026-12-04 this example compiled every scene's kernels with the null
//! boundaries', refracted and manifold lights' code whether the scene
//! needed it or not). `--all` prints every
//! statistic the driver reports, not only those about registers, spills,
//! code size, instructions, scratch and occupancy. `--dump DIR` also
//! writes each scene's render kernel source to `DIR/<scene>.wgsl`, and
//! `--source FILE` compiles the entry points of a WGSL file as it is
//! (rows `FILE: main` and so on, after the others; `--source` alone skips
//! the default scenes), so that an edit of a dumped kernel is weighed in
//! seconds, without rebuilding. `--checks wgpu` writes the SPIR-V with
//! the run-time checks of wgpu's checked modules (indices clamped, loops
//! bounded; `Gpu::set_runtime_checks`), `none` (the default) without, as
//! the renderer compiles them:
//!
//! ```text
//! kernel_stats examples/scenes/gallery.toml --dump /tmp/k
//! sed -i 's/.../.../' /tmp/k/gallery.wgsl
//! kernel_stats --source /tmp/k/gallery.wgsl
//! ```
//!
//! wgpu does not expose the compiler's statistics, so this compiles the
//! WGSL through naga to SPIR-V and creates the pipelines with `ash` on the
//! first Vulkan device that is not a CPU (or the first one). Without a
//! GPU, Mesa's RADV compiles for an AMD GPU on its null device (Mesa 25;
//! Debian bookworm-backports' `mesa-vulkan-drivers`, docs/gpu.md,
//! "Register pressure"):
//!
//! ```text
//! RADV_FORCE_FAMILY=navi21 VK_ICD_FILENAMES=.../radeon_icd.json \
//!     cargo run --release -p isolux-gpu --example kernel_stats
//! ```
use ash::vk;
use isolux_gpu::{render_source_variant, Features, Precision};
use std::ffi::{CStr, CString};

/// Statistics worth a column, by words in their names (case-insensitive).
const KEYWORDS: [&str; 10] = [
    "register",
    "gpr",
    "spill",
    "code size",
    "instructions",
    "scratch",
    "subgroups",
    "occupancy",
    "local memory",
    "stack",
];

/// The render module's entry points each scene's row lists.
const ENTRIES: [&str; 7] = [
    "main",
    "trace",
    "trace_last",
    "trace_extend",
    "trace_shadow",
    "trace_shade",
    "realtime",
];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut every_stat = false;
    let mut checks = Checks::None;
    let mut dump = None;
    let mut sources = Vec::new();
    let mut scenes = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--all" => every_stat = true,
            "--checks" => {
                checks = match args.next().as_deref() {
                    Some("wgpu") => Checks::Wgpu,
                    Some("none") => Checks::None,
                    _ => return Err("--checks needs wgpu or none".into()),
                }
            }
            "--dump" => dump = Some(args.next().ok_or("--dump needs a directory")?),
            "--source" => sources.push(args.next().ok_or("--source needs a file")?),
            _ => scenes.push(a),
        }
    }
    if scenes.is_empty() && sources.is_empty() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/scenes");
        scenes = ["furnace.toml", "gallery.toml", "translucent.toml"]
            .iter()
            .map(|s| format!("{dir}/{s}"))
            .collect();
    }
    // (label, models, entry point, source)
    // With `--source`, the files' kernels and the named scenes' only.
    let mut kernels = Vec::new();
    if sources.is_empty() {
        kernels.push((
            "intersection".to_string(),
            "-".to_string(),
            "main",
            isolux_gpu::intersect_source(),
        ));
    }
    let mut sets = Vec::new();
    for path in &scenes {
        let scene = isolux_scene::load(std::path::Path::new(path))?;
        let features = isolux_gpu::scene_features(&scene).map_err(|e| format!("{path}: {e}"))?;
        let name = std::path::Path::new(path)
            .file_name()
            .map_or(path.clone(), |n| n.to_string_lossy().into_owned());
        sets.push((name, features));
    }
    if sources.is_empty() {
        sets.push(("every model".to_string(), Features::ALL));
    }
    for (name, features) in &sets {
        let src = render_source_variant(Precision::F32, *features);
        if let Some(dir) = &dump {
            std::fs::create_dir_all(dir)?;
            let stem = name.strip_suffix(".toml").unwrap_or(name);
            let file = std::path::Path::new(dir).join(format!("{stem}.wgsl"));
            std::fs::write(&file, &src).map_err(|e| format!("{}: {e}", file.display()))?;
        }
        for entry in ENTRIES {
            kernels.push((
                format!("{name}: {entry}"),
                features.to_string(),
                entry,
                src.clone(),
            ));
        }
    }

    for file in &sources {
        let src = std::fs::read_to_string(file).map_err(|e| format!("{file}: {e}"))?;
        for entry in ENTRIES {
            kernels.push((
                format!("{file}: {entry}"),
                "-".to_string(),
                entry,
                src.clone(),
            ));
        }
    }

    let compiler = Compiler::new()?;
    println!("device: {}", compiler.device_name);
    println!();
    let mut columns: Vec<String> = Vec::new();
    for (label, models, entry, src) in &kernels {
        let stats = compiler.stats(src, entry, checks)?;
        if columns.is_empty() {
            columns = stats
                .iter()
                .map(|(n, _)| n.clone())
                .filter(|n| every_stat || KEYWORDS.iter().any(|k| n.to_lowercase().contains(k)))
                .collect();
            if columns.is_empty() {
                columns = stats.iter().map(|(n, _)| n.clone()).collect();
            }
            println!("| kernel | features | {} |", columns.join(" | "));
            println!("|---|---|{}", "---:|".repeat(columns.len()));
        }
        let cells: Vec<String> = columns
            .iter()
            .map(|c| {
                stats
                    .iter()
                    .find(|(n, _)| n == c)
                    .map_or("-".to_string(), |(_, v)| v.clone())
            })
            .collect();
        println!("| {label} | {models} | {} |", cells.join(" | "));
    }
    Ok(())
}

/// The run-time checks naga writes into the SPIR-V.
#[derive(Clone, Copy, PartialEq)]
enum Checks {
    /// What wgpu's Vulkan back end writes for a checked module on a device
    /// with `robustBufferAccess2` (RADV, NVIDIA, lavapipe): indices into
    /// arrays clamped (`Restrict`), buffers left to the driver, and every
    /// loop given an iteration counter (`force_loop_bounding`).
    Wgpu,
    /// None of them (`Device::create_shader_module_trusted` with
    /// `ShaderRuntimeChecks::unchecked()`): what the renderer compiles by
    /// default (`Gpu::set_runtime_checks`), and this tool's default.
    None,
}

impl Checks {
    fn policies(self) -> isolux_gpu::naga::proc::BoundsCheckPolicies {
        use isolux_gpu::naga::proc::BoundsCheckPolicy::{Restrict, Unchecked};
        isolux_gpu::naga::proc::BoundsCheckPolicies {
            index: if self == Checks::Wgpu {
                Restrict
            } else {
                Unchecked
            },
            buffer: Unchecked,
            image_load: Unchecked,
            binding_array: Unchecked,
        }
    }
}

/// A Vulkan device that compiles compute pipelines with statistics.
struct Compiler {
    _entry: ash::Entry,
    instance: ash::Instance,
    device: ash::Device,
    exec: ash::khr::pipeline_executable_properties::Device,
    sets: Vec<vk::DescriptorSetLayout>,
    layout: vk::PipelineLayout,
    device_name: String,
}

impl Compiler {
    fn new() -> Result<Self, Box<dyn std::error::Error>> {
        // SAFETY: plain Vulkan calls on objects created here, in order,
        // with valid create infos; nothing is shared between threads.
        unsafe {
            let entry = ash::Entry::load()?;
            let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_3);
            let instance = entry.create_instance(
                &vk::InstanceCreateInfo::default().application_info(&app),
                None,
            )?;
            let devices = instance.enumerate_physical_devices()?;
            let pd = *devices
                .iter()
                .find(|&&d| {
                    instance.get_physical_device_properties(d).device_type
                        != vk::PhysicalDeviceType::CPU
                })
                .or(devices.first())
                .ok_or("no Vulkan device")?;
            let props = instance.get_physical_device_properties(pd);
            let device_name = props
                .device_name_as_c_str()
                .map_or("?".into(), |n| n.to_string_lossy().into_owned());
            let ext = ash::khr::pipeline_executable_properties::NAME;
            let offered = instance
                .enumerate_device_extension_properties(pd)?
                .iter()
                .any(|e| e.extension_name_as_c_str() == Ok(ext));
            if !offered {
                return Err(format!(
                    "{device_name} does not offer {} (the compiler's statistics)",
                    ext.to_string_lossy()
                )
                .into());
            }
            let exts = [ext.as_ptr()];
            let mut feature = vk::PhysicalDevicePipelineExecutablePropertiesFeaturesKHR::default()
                .pipeline_executable_info(true);
            let family = instance
                .get_physical_device_queue_family_properties(pd)
                .iter()
                .position(|q| q.queue_flags.contains(vk::QueueFlags::COMPUTE))
                .ok_or("no compute queue")? as u32;
            let prio = [1.0f32];
            let queues = [vk::DeviceQueueCreateInfo::default()
                .queue_family_index(family)
                .queue_priorities(&prio)];
            let device = instance.create_device(
                pd,
                &vk::DeviceCreateInfo::default()
                    .queue_create_infos(&queues)
                    .enabled_extension_names(&exts)
                    .push_next(&mut feature),
                None,
            )?;
            let exec = ash::khr::pipeline_executable_properties::Device::new(&instance, &device);
            // The render kernels' groups: their storage buffers, then the
            // wavefront's (the intersection kernel uses the first 6). A
            // binding the kernel uses and the layout lacks is undefined
            // behaviour: RADV crashed on it.
            let binding = |i: u32| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(i)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            };
            let mut sets = Vec::new();
            for n in [isolux_gpu::RENDER_BINDINGS, isolux_gpu::WAVEFRONT_BINDINGS] {
                let b: Vec<_> = (0..n as u32).map(binding).collect();
                sets.push(device.create_descriptor_set_layout(
                    &vk::DescriptorSetLayoutCreateInfo::default().bindings(&b),
                    None,
                )?);
            }
            let layout = device.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default().set_layouts(&sets),
                None,
            )?;
            Ok(Self {
                _entry: entry,
                instance,
                device,
                exec,
                sets,
                layout,
                device_name,
            })
        }
    }

    /// The statistics (name, value) of entry point `entry` of `src`: those
    /// of each of the pipeline's executables (a compute pipeline has one).
    fn stats(
        &self,
        src: &str,
        entry: &str,
        checks: Checks,
    ) -> Result<Vec<(String, String)>, Box<dyn std::error::Error>> {
        let spv =
            isolux_gpu::kernel_spirv(src, checks.policies(), checks == Checks::Wgpu, Some(entry))?;
        // SAFETY: as in `new`; the module and pipeline are destroyed before
        // returning, after their statistics are read.
        unsafe {
            let sm = self
                .device
                .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&spv), None)?;
            let name = CString::new(entry)?;
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(sm)
                .name(&name);
            let info = [vk::ComputePipelineCreateInfo::default()
                .flags(vk::PipelineCreateFlags::CAPTURE_STATISTICS_KHR)
                .stage(stage)
                .layout(self.layout)];
            let pipeline = self
                .device
                .create_compute_pipelines(vk::PipelineCache::null(), &info, None)
                .map_err(|(_, e)| e)?[0];
            let executables = self.exec.get_pipeline_executable_properties(
                &vk::PipelineInfoKHR::default().pipeline(pipeline),
            )?;
            let mut out: Vec<(String, String)> = Vec::new();
            for i in 0..executables.len() as u32 {
                let stats = self.exec.get_pipeline_executable_statistics(
                    &vk::PipelineExecutableInfoKHR::default()
                        .pipeline(pipeline)
                        .executable_index(i),
                )?;
                for s in stats {
                    let n = CStr::from_ptr(s.name.as_ptr())
                        .to_string_lossy()
                        .into_owned();
                    let v = match s.format {
                        vk::PipelineExecutableStatisticFormatKHR::BOOL32 => {
                            (s.value.b32 != 0).to_string()
                        }
                        vk::PipelineExecutableStatisticFormatKHR::INT64 => s.value.i64.to_string(),
                        vk::PipelineExecutableStatisticFormatKHR::UINT64 => s.value.u64.to_string(),
                        _ => format!("{:.3}", s.value.f64),
                    };
                    out.push((n, v));
                }
            }
            self.device.destroy_pipeline(pipeline, None);
            self.device.destroy_shader_module(sm, None);
            Ok(out)
        }
    }
}

impl Drop for Compiler {
    fn drop(&mut self) {
        // SAFETY: every object was created by this device and instance and
        // is no longer in use.
        unsafe {
            self.device.destroy_pipeline_layout(self.layout, None);
            for &s in &self.sets {
                self.device.destroy_descriptor_set_layout(s, None);
            }
            self.device.destroy_device(None);
            self.instance.destroy_instance(None);
        }
    }
}
