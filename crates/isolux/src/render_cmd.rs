//! `isolux render`.

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use isolux_io::{OutputFormat, Tonemap};
use isolux_render::{render, IntegratorSettings, RenderOptions};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

/// The most worker threads `--threads` starts.
const MAX_THREADS: usize = 1024;

/// A [`isolux_render::FilmSettings::problem`] named by the command-line
/// flag that sets the key at fault instead of the key.
pub(crate) fn by_flag(p: &isolux_render::FilmProblem) -> String {
    let flag = match p.key {
        Some("width") => "--width",
        Some("height") => "--height",
        Some("spp") => "--spp",
        _ => "--width x --height",
    };
    format!("{flag}: {}", p.message)
}

/// Tone maps for 8-bit output.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum TonemapArg {
    /// Clip to [0, 1] (faithful below 1).
    Clamp,
    /// Luminance Reinhard L/(1+L), hue preserving.
    Reinhard,
}

/// Render a scene; flags override the scene file.
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene file (TOML; see docs/scene-format.md).
    pub scene: PathBuf,
    /// Output image: .png (8-bit sRGB) or .exr (linear float).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Samples per pixel (any count; stratified on a sub-pixel grid).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Image width in pixels.
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels.
    #[arg(long)]
    pub height: Option<u32>,
    /// Worker threads (default: all cores; at most 1024). The image does not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Random seed (same seed, same image).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Maximum number of scattering events per path (at most 1000000).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Exposure in stops for PNG output (linear values times 2^EV).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f64,
    /// Tone map for PNG output.
    #[arg(long, value_enum, default_value_t = TonemapArg::Clamp)]
    pub tonemap: TonemapArg,
    /// Also write albedo, normal and depth layers (EXR output only).
    #[arg(long)]
    pub aov: bool,
    /// No progress bar and no closing line.
    #[arg(short, long)]
    pub quiet: bool,
    /// Render on the GPU (wgpu compute shaders). Refuses, naming it, a
    /// material not on the GPU yet (docs/gpu.md lists the models that
    /// are); never falls back to the CPU. `--threads` does not apply.
    #[arg(long)]
    pub gpu: bool,
    /// The seed's real-time mode: point lights (shadowed) plus prefiltered
    /// environment light, one bounce, no path tracing (docs/realtime.md).
    /// 4 to 25 samples per pixel: the scene's `spp` is clamped into that
    /// range, an explicit `--spp` outside it is an error. Runs on the CPU,
    /// or on the GPU with `--gpu`.
    #[arg(long)]
    pub realtime: bool,
    /// With `--gpu`: path trace as a wavefront, one dispatch per bounce
    /// over the paths still alive, rather than one kernel running each
    /// path to its end. The same paths and random numbers, so the same
    /// image; which is faster depends on the scene and the device
    /// (`isolux bench gpu --wavefront` times both; docs/gpu.md). 0.62x
    /// the megakernel's time on the gallery on an NVIDIA H200. The
    /// default on GPUs is its sorted form (`--sorted`), and this for
    /// scenes with a `subsurface` material; on CPU drivers (lavapipe)
    /// this for scenes with a random-walk `subsurface` medium or a
    /// `wave` material, the megakernel for the rest.
    #[arg(long, requires = "gpu", conflicts_with = "realtime")]
    pub wavefront: bool,
    /// With `--gpu`: path trace with the megakernel, whatever the scene
    /// (see `--wavefront`).
    #[arg(long, requires = "gpu", conflicts_with_all = ["realtime", "wavefront"])]
    pub megakernel: bool,
    /// With `--gpu`: path trace as the sorted wavefront: each bounce in
    /// four or five dispatches, its hits found in one kernel and shaded
    /// in order of their material in another (their shadow rays traced
    /// in a third, for most scenes), so that a GPU's SIMT groups shade
    /// one material each. The same image as `--wavefront`. The default
    /// on GPUs (not on CPU drivers such as lavapipe), chosen by a model
    /// of a GPU's lanes and by lavapipe, not yet timed on a GPU
    /// (`isolux bench gpu --sorted` times it; docs/gpu.md, "The sorted
    /// wavefront"). A scene with a `subsurface` material runs as
    /// `--wavefront`.
    #[arg(long, requires = "gpu", conflicts_with_all = ["realtime", "wavefront", "megakernel"])]
    pub sorted: bool,
    /// With `--gpu`: intersect in f64 whatever the scene (adapters with
    /// SHADER_F64; an error elsewhere). By default the GPU intersects in
    /// f32, and in f64 only where a bump dwarfs its base quadric, which
    /// f32 cannot resolve (docs/gpu.md, "Precision").
    #[arg(long, requires = "gpu")]
    pub f64: bool,
    /// With `--gpu`, for diagnosis: compile the render kernels with every
    /// index out of bounds (into a local array, a buffer or a texture)
    /// clamped to the last element, or read as zero and its write
    /// skipped. Where no kernel reads out of bounds, both give the same
    /// image bit for bit (write .exr files and compare them); where one
    /// does, they differ (docs/gpu.md, "Probing for indices out of
    /// bounds"; `scripts/gpu-diff-fuzz.py --bounds`). Vulkan adapters
    /// only.
    #[arg(long, requires = "gpu", value_enum)]
    pub bounds_probe: Option<BoundsProbeArg>,
}

/// What `--bounds-probe` makes of an index out of bounds.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum BoundsProbeArg {
    /// The array's last element.
    Clamp,
    /// Zero read, write skipped.
    Zero,
}

/// Runs `isolux render`.
pub fn run(a: RenderArgs) -> Result<()> {
    let format = OutputFormat::from_path(&a.output).with_context(|| {
        format!(
            "{}: unknown output format: use a .png or .exr file name",
            a.output.display()
        )
    })?;
    if a.aov && format != OutputFormat::Exr {
        bail!("--aov needs an .exr output (PNG has no room for extra layers)");
    }
    if !a.exposure.is_finite() {
        bail!("--exposure must be a finite number");
    }
    isolux_io::check_output(&a.output)?;
    let mut scene = isolux_scene::load(&a.scene)?;
    if a.realtime {
        use isolux_render::realtime::{MAX_SPP, MIN_SPP};
        match a.spp {
            Some(v) if !(MIN_SPP..=MAX_SPP).contains(&v) => bail!(
                "--spp {v}: --realtime takes {MIN_SPP} to {MAX_SPP} samples per pixel \
                 (the seed's sub-pixel grids, 2 x 2 to 5 x 5)"
            ),
            _ => scene.film.spp = scene.film.spp.clamp(MIN_SPP, MAX_SPP),
        }
    }
    if let Some(v) = a.spp {
        scene.film.spp = v;
    }
    if let Some(v) = a.width {
        scene.film.width = v;
    }
    if let Some(v) = a.height {
        scene.film.height = v;
    }
    if let Some(v) = a.seed {
        scene.integrator.seed = v;
    }
    if let Some(v) = a.max_depth {
        if v > IntegratorSettings::MAX_DEPTH {
            bail!(
                "--max-depth must be at most {} scattering events, got {v}",
                IntegratorSettings::MAX_DEPTH
            );
        }
        scene.integrator.max_depth = v;
    }
    for (name, v) in [
        ("--spp", scene.film.spp),
        ("--width", scene.film.width),
        ("--height", scene.film.height),
    ] {
        if v == 0 {
            bail!("{name} must be at least 1");
        }
    }
    // The flags bypass the scene file's bounds: the same ones, by flag.
    if let Some(p) = scene.film.problem() {
        bail!("{}", by_flag(&p));
    }
    for why in scene
        .rough_wave_materials()
        .into_iter()
        .chain(scene.lights_outside_the_cameras_media())
    {
        eprintln!("isolux: warning: {}: {why}", a.scene.display());
    }
    if let Some(why) = a
        .realtime
        .then(|| isolux_render::realtime::volume_left_out(&scene))
        .flatten()
    {
        eprintln!(
            "isolux: warning: --realtime: {}: {why}; render without --realtime for it",
            a.scene.display()
        );
    }
    let threads = match a.threads {
        Some(0) => bail!("--threads must be at least 1"),
        // Each worker reserves a stack; 100,000 of them took minutes to
        // start before the first pixel.
        Some(n) if n > MAX_THREADS => {
            bail!("--threads {n}: at most {MAX_THREADS} worker threads")
        }
        Some(n) => n,
        None => std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1),
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot start worker threads")?;

    let show = !a.quiet && std::io::stderr().is_terminal();
    let bar = ProgressBar::with_draw_target(
        None,
        if show {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        },
    );
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} rendering [{bar:40}] {percent:>3}% {elapsed_precise} ETA {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    let progress = |done: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    let mut device = format!("{threads} threads");
    let start;
    let (image, stats) = if a.gpu {
        let mut gpu = match a.bounds_probe {
            None => isolux_gpu::Gpu::new().context("--gpu")?,
            Some(probe) => {
                let mut gpu = isolux_gpu::Gpu::for_bounds_probes().context("--bounds-probe")?;
                gpu.set_bounds_probe(Some(match probe {
                    BoundsProbeArg::Clamp => isolux_gpu::OutOfBounds::Clamp,
                    BoundsProbeArg::Zero => isolux_gpu::OutOfBounds::Zero,
                }))
                .context("--bounds-probe")?;
                gpu
            }
        };
        gpu.set_path_kernel(if a.wavefront {
            isolux_gpu::PathKernel::Wavefront
        } else if a.sorted {
            isolux_gpu::PathKernel::Sorted
        } else if a.megakernel {
            isolux_gpu::PathKernel::Megakernel
        } else {
            isolux_gpu::PathKernel::Auto
        });
        device = gpu.adapter.clone();
        // Refuse before any work, naming the material.
        if let Some((name, type_name)) = isolux_gpu::unsupported_material(&scene) {
            bail!(
                "--gpu: material \"{name}\" (type {type_name}) does not run on the GPU yet \
                 (adapter: {}; docs/gpu.md lists the models that do): render without --gpu",
                gpu.adapter
            );
        }
        if let Some(why) = isolux_gpu::f32_shortfall(&scene) {
            bail!("--gpu: {}: {why}", a.scene.display());
        }
        if let Some(why) = isolux_gpu::thin_object_warning(&scene) {
            eprintln!("isolux: warning: --gpu: {}: {why}", a.scene.display());
        }
        if let Some(why) = isolux_gpu::fine_medium_warning(&scene).filter(|_| !a.realtime) {
            eprintln!(
                "isolux: warning: --gpu: {}: {why}; render without --gpu, or model it as \
                 `mode = \"dipole\"`",
                a.scene.display()
            );
        }
        // (A mix of two is refused there, by `Gpu::render`.)
        if gpu.miscompiles_loops()
            && isolux_gpu::wave_count(&scene) > 1
            && isolux_gpu::mix_of_waves(&scene).is_none()
        {
            eprintln!(
                "isolux: warning: --gpu: {}: this driver ({}) miscompiles the `wave` code where \
                 neighbouring pixels hold different `wave` materials: their sampled lobes come \
                 out wrong (docs/gpu.md, \"Known defect\"); render without --gpu, or on another \
                 driver (Mesa 25 or later, or a GPU's)",
                a.scene.display(),
                gpu.driver
            );
        }
        // The path kernel that will run, for the summary line.
        let kernel = (!a.realtime)
            .then(|| gpu.path_kernel_for(&scene))
            .transpose()
            .with_context(|| format!("--gpu: {}", a.scene.display()))?;
        if let Some(kernel) = kernel {
            if gpu.miscompiles_loops() && isolux_gpu::has_random_walk(&scene) {
                let what = if kernel == isolux_gpu::PathKernel::Megakernel {
                    "and by the megakernel shorter walks too (1% dark on \
                     translucent-random-walk.toml)"
                } else {
                    "and by the wavefront (the default here) a few pixels differ from run to run"
                };
                eprintln!(
                    "isolux: warning: --gpu: {}: this driver ({}) miscompiles the long loops of \
                     random walks in media: walks of thousands of scattering events end early (a \
                     thick medium comes out dark, up to black), {what} (docs/gpu.md, \"The \
                     wavefront is deterministic: Mesa 22.3's lanes are not\"); render without \
                     --gpu, or on another driver (Mesa 25 or later, or a GPU's)",
                    a.scene.display(),
                    gpu.driver
                );
            }
        }
        if a.sorted && kernel == Some(isolux_gpu::PathKernel::Wavefront) {
            eprintln!(
                "isolux: note: --sorted: {}: the sorted wavefront leaves out the subsurface \
                 integrator (media, dipoles) this scene needs: it renders as --wavefront (the \
                 same image)",
                a.scene.display()
            );
        }
        if a.megakernel
            && gpu.miscompiles_loops()
            && scene.materials.iter().any(|m| m.varies_in_space())
        {
            eprintln!(
                "isolux: warning: --megakernel: {}: this driver ({}) miscompiles the `wave` \
                 code's second run in the megakernel's loop: paths end at their second `wave` \
                 vertex (docs/gpu.md, \"Known defect\"); the default runs such scenes as a \
                 wavefront",
                a.scene.display(),
                gpu.driver
            );
        }
        if a.f64 {
            gpu.set_precision(isolux_gpu::Precision::F64)
                .context("--f64")?;
        } else if let Some(note) = gpu
            .precision_for(&scene)
            .with_context(|| format!("--gpu: {}", a.scene.display()))?
        {
            eprintln!("isolux: note: --gpu: {}: {note}", a.scene.display());
        }
        if let Some(kernel) = kernel {
            device = format!("{device}, {}", kernel_name(kernel));
        }
        start = Instant::now();
        if a.realtime {
            gpu.render_realtime_with_aov(&scene, a.aov)
                .with_context(|| format!("--gpu --realtime: {}", a.scene.display()))?
        } else {
            gpu.render_with_aov(&scene, a.aov, &progress)
                .with_context(|| format!("--gpu: {}", a.scene.display()))?
        }
    } else {
        if let Some(fine) = scene
            .finest_medium(|o| scene.cpu_spawn_offset(o))
            .filter(|_| !a.realtime)
        {
            eprintln!(
                "isolux: warning: {}: {}; model it as `mode = \"dipole\"`",
                a.scene.display(),
                fine.describe(&scene, "the CPU")
            );
        }
        start = Instant::now();
        let options = RenderOptions {
            aov: a.aov,
            realtime: a.realtime,
        };
        pool.install(|| render(&scene, &options, &progress))?
    };
    bar.finish_and_clear();
    let secs = start.elapsed().as_secs_f64();
    let tonemap = match a.tonemap {
        TonemapArg::Clamp => Tonemap::Clamp,
        TonemapArg::Reinhard => Tonemap::Reinhard,
    };
    isolux_io::write_image(&a.output, &image, a.exposure, tonemap)?;
    if stats.rejected_samples > 0 {
        eprintln!(
            "isolux: warning: {} samples had non-finite radiance and were dropped",
            stats.rejected_samples
        );
    }
    if stats.capped_paths > 0 {
        eprintln!(
            "isolux: warning: {}: {} of {} paths reached {} scattering and boundary events \
             inside random-walk media and were ended there: a medium that thick (optically) \
             is beyond the walk, and the image is darker there than its light; model it as \
             `mode = \"dipole\"`, or thin it (docs/subsurface.md, \"Media too thick for the \
             walk\")",
            a.scene.display(),
            stats.capped_paths,
            stats.samples,
            isolux_render::integrator::MAX_MEDIUM_EVENTS
        );
    }
    if !a.quiet {
        eprintln!(
            "isolux: rendered {}x{} at {} spp{} in {:.2} s ({:.2} M samples/s, {}) -> {}",
            image.width,
            image.height,
            scene.film.spp,
            if a.realtime { " (real-time mode)" } else { "" },
            secs,
            stats.samples as f64 / secs / 1e6,
            device,
            a.output.display()
        );
    }
    Ok(())
}

/// How the summary line names the GPU's path kernel.
fn kernel_name(kernel: isolux_gpu::PathKernel) -> &'static str {
    match kernel {
        isolux_gpu::PathKernel::Megakernel => "megakernel",
        isolux_gpu::PathKernel::Wavefront => "wavefront",
        isolux_gpu::PathKernel::Sorted => "sorted wavefront",
        // (Resolved by `path_kernel_for`.)
        isolux_gpu::PathKernel::Auto => "automatic",
    }
}
