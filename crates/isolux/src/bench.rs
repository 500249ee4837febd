//! `isolux bench`: performance tables.

use anyhow::{bail, Result};
use clap::{Args, ValueEnum};
use isolux_geometry::{
    samples::{bumpy_sphere, cast_rows, BAND, BLOCK, TILE},
    Object,
};
use rayon::prelude::*;
use std::time::Instant;

/// What to benchmark.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum Suite {
    /// Primary-ray casting of a bumpy sphere (SPEC §1).
    Geometry,
    /// Subsurface: dipole against random walk at equal noise.
    Sss,
    /// Homomorphic factorization: fit time at 32, 64 (dense and conjugate gradients) and 128 texels per side.
    Factor,
    /// Wave optics: time per BRDF query, one and eight wavelengths.
    Wave,
    /// GPU path tracer against the CPU, ms per frame (default: the gallery).
    Gpu,
}

/// Run benchmarks.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Which benchmark.
    #[arg(value_enum)]
    pub suite: Suite,
    /// Image edge in pixels (rays = size^2; 1-16384, at most 256 used for `sss`).
    #[arg(long, default_value_t = 1024)]
    pub size: u32,
    /// Bump counts to measure, comma separated (each at most 65536).
    #[arg(long, value_delimiter = ',', default_value = "0,16,64,256")]
    pub bumps: Vec<usize>,
    /// Repetitions (1-1000); the fastest is reported.
    #[arg(long, default_value_t = 3)]
    pub repeat: u32,
    /// Scenes for `gpu` (default: examples/scenes/gallery.toml).
    pub scenes: Vec<std::path::PathBuf>,
    /// Frame width for `gpu`.
    #[arg(long, default_value_t = 1920)]
    pub width: u32,
    /// Frame height for `gpu`.
    #[arg(long, default_value_t = 1080)]
    pub height: u32,
    /// `gpu`: do not time the CPU path (slow on few cores).
    #[arg(long)]
    pub skip_cpu: bool,
    /// `gpu`: also time the intersection in f64 (adapters with
    /// SHADER_F64), in a column beside f32.
    #[arg(long)]
    pub f64: bool,
    /// `gpu`: also time the general kernels (every material model compiled
    /// in, `wave` and subsurface included), in a column beside the kernels
    /// specialized to the scene's models, with their ratio.
    #[arg(long)]
    pub general: bool,
    /// `gpu`: also time the wavefront path tracer (one dispatch per
    /// bounce over the paths still alive; `render --gpu --wavefront`), in
    /// a column beside the megakernel, with their ratio (`-` in the
    /// real-time mode).
    #[arg(long)]
    pub wavefront: bool,
    /// `gpu`: also time the sorted wavefront (each bounce's hits found in
    /// one kernel and shaded in order of their material in another;
    /// what `render --gpu` runs by default on GPUs, `--sorted`), and the
    /// same split without the sort
    /// (the hits shaded in the order they were found in), and the sorted
    /// wavefront for steps 0-2 only, one dispatch a step after
    /// (`GpuFrame::set_sorted_steps`), and the sorted wavefront with one
    /// sample's paths a run (`GpuFrame::set_wavefront_samples`), in columns
    /// beside the wavefront, with their ratios to it (the last to the
    /// sorted wavefront; `-` in the
    /// real-time mode and where the scene needs the subsurface
    /// integrator, which the sorted wavefront leaves out).
    #[arg(long)]
    pub sorted: bool,
    /// `gpu`: also time the frames with one dispatch per sample (as before
    /// 2026-12-02) instead of up to 16 samples per dispatch, in a column
    /// beside them, with their ratio: what the GPU's drain between
    /// dispatches costs.
    #[arg(long)]
    pub per_sample: bool,
    /// `gpu`: also time the frames with camera rays testing their 8 x 8
    /// tile's list of objects and with each walking the object hierarchy
    /// (`Features::tiles`: by default lists on a GPU, walks on a CPU
    /// driver), in two columns, with their ratio.
    #[arg(long)]
    pub tiles: bool,
    /// `gpu`: also time the kernels compiled with wgpu's run-time checks
    /// (indices clamped, loops bounded; `Gpu::set_runtime_checks`, off by
    /// default), in a column beside them, with their ratio.
    #[arg(long)]
    pub checked: bool,
    /// `gpu`: also print each frame's GPU time kernel by kernel, in a
    /// second table: per mode and path kernel (the megakernel, and the
    /// wavefronts where `--wavefront` or `--sorted` time them), each
    /// kernel's dispatches and time (the wavefronts' at step 0, the camera
    /// rays, step 1 and the steps after), and the time between
    /// dispatches, from GPU timestamps around each dispatch
    /// (`GpuFrame::profile`; best of `--repeat` by the frame's span).
    #[arg(long)]
    pub kernels: bool,
    /// `gpu`: also time the path-traced and direct-light frames with 1,
    /// 2, 4, 8 and 16 samples' paths a run of the sorted wavefront (the
    /// plain one for scenes with the subsurface integrator), in a third
    /// table: the default tile of 2^22 paths holds two at 1920 x 1080;
    /// larger tiles (up to 2^25 paths, 5.8 GB of buffers at 1080p for 16)
    /// as far as the device binds and dispatches them. The same image
    /// whatever the count; fewer, fuller steps against more memory.
    #[arg(long)]
    pub runs: bool,
}

/// Primary rays of [`cast_rows`] over the whole image, bands of
/// [`BAND`] rows in parallel; `coherent` culls per tile.
pub fn cast_primary(obj: &Object, size: u32, coherent: bool) -> usize {
    (0..size.div_ceil(BAND))
        .into_par_iter()
        .map(|b| cast_rows(obj, size, b * BAND..((b + 1) * BAND).min(size), coherent))
        .sum()
}

fn best_of(repeat: u32, mut f: impl FnMut() -> usize) -> (f64, usize) {
    let mut best = f64::INFINITY;
    let mut hits = 0;
    for _ in 0..repeat {
        let t = Instant::now();
        hits = f();
        best = best.min(t.elapsed().as_secs_f64());
    }
    (best, hits)
}

/// Runs `isolux bench`.
pub fn run(a: BenchArgs) -> Result<()> {
    // Bounds that keep a typo from running for hours or failing to
    // allocate (`--bumps 4294967295` asked for 100 GB).
    if !(1..=16384).contains(&a.size) {
        bail!("--size must lie in 1..=16384 pixels, got {}", a.size);
    }
    if !(1..=1000).contains(&a.repeat) {
        bail!("--repeat must lie in 1..=1000, got {}", a.repeat);
    }
    if let Some(n) = a.bumps.iter().find(|&&n| n > 65536) {
        bail!("--bumps: at most 65536 bumps per sphere, got {n}");
    }
    match a.suite {
        Suite::Sss => sss(a.size.min(256))?,
        Suite::Factor => factor(a.repeat)?,
        Suite::Wave => wave(a.repeat)?,
        Suite::Gpu => gpu(&a)?,
        Suite::Geometry => {
            let threads = rayon::current_num_threads();
            println!(
                "primary rays, {}x{} orthographic, sphere r = 0.6 with bumps r = 0.2 (best of {})",
                a.size, a.size, a.repeat
            );
            println!(
                "per ray: a BVH walk per ray; tiles: {TILE} x {TILE} rays culled together (from blocks of {BLOCK} x {BLOCK} tiles) and cast together, vector instructions {} (cap with ISOLUX_SIMD=avx2|sse2; times in ms)",
                isolux_geometry::simd::isa().name()
            );
            println!("| bumps | hits | per ray, 1 thread | tiles, 1 thread | per ray, {threads} threads | tiles, {threads} threads | Mrays/s (tiles, {threads} threads) |");
            println!("|---:|---:|---:|---:|---:|---:|---:|");
            let single = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
            for &n in &a.bumps {
                let obj = bumpy_sphere(n);
                let one = |coherent| {
                    best_of(a.repeat, || {
                        single.install(|| cast_primary(&obj, a.size, coherent))
                    })
                };
                let all = |coherent| best_of(a.repeat, || cast_primary(&obj, a.size, coherent));
                let ((r1, hits), (c1, hits_c)) = (one(false), one(true));
                let ((rn, _), (cn, _)) = (all(false), all(true));
                if hits != hits_c {
                    bail!("{n} bumps: per-ray casting hit {hits} pixels, tiles {hits_c}");
                }
                let rays = (a.size as f64).powi(2);
                println!(
                    "| {n} | {hits} | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} |",
                    r1 * 1e3,
                    c1 * 1e3,
                    rn * 1e3,
                    cn * 1e3,
                    rays / cn / 1e6
                );
            }
        }
    }
    Ok(())
}

/// Fit time of the homomorphic factorization of the three target
/// materials at 32 and 64 texels per side (default settings: 200,000 fit
/// samples, one Gauss-Newton step), all threads, each by both solvers
/// (dense Cholesky and conjugate gradients), and at 128 by the conjugate
/// gradients; the held-out errors (20,000 samples) are not timed.
fn factor(repeat: u32) -> Result<()> {
    use isolux_core::Rgb;
    use isolux_factor::{draw, evaluate, fit, FitOptions, Source, DENSE_MAX_RES};
    use isolux_materials::cook_torrance::{Masking, NormalDistribution};
    use isolux_materials::microfacet::{Kind, Microfacet};
    use isolux_materials::{CookTorrance, Fresnel, Material, Ward};
    let ct = |m: f64, kd: f64| {
        Material::CookTorrance(CookTorrance {
            distribution: NormalDistribution::Analytic(Microfacet::isotropic(Kind::Beckmann, m)),
            masking: Masking::VGroove,
            fresnel: Fresnel::Schlick {
                f0: Rgb::splat(0.05),
            },
            reflectance: Rgb::splat(kd),
        })
    };
    let cases = [
        ("Cook-Torrance m 0.3, kd 0.3, F0 0.05", ct(0.3, 0.3)),
        ("Cook-Torrance m 0.2, kd 0.1, F0 0.05", ct(0.2, 0.1)),
        (
            "Ward alpha 0.15, ks 0.5, kd 0.3",
            Material::Ward(Ward::new(0.15, 0.15, Rgb::splat(0.5), Rgb::splat(0.3))),
        ),
    ];
    println!(
        "homomorphic factorization fit, 200,000 samples, {} threads (best of {repeat})",
        rayon::current_num_threads()
    );
    println!(
        "| material | res | unknowns | solver | assembly (s) | solve (s) | coarser fits (s) | total (s) | held-out rel. RMS |"
    );
    println!("|---|---:|---:|---|---:|---:|---:|---:|---:|");
    // Each resolution by its default solver (the dense Cholesky up to
    // DENSE_MAX_RES, conjugate gradients above) and side by side by the
    // other one, so that the threshold stays justified by measurement.
    let runs = [
        (32, DENSE_MAX_RES),
        (32, 16),
        (64, DENSE_MAX_RES),
        (64, 64),
        (128, DENSE_MAX_RES),
    ];
    for (name, m) in cases {
        let src = Source::Material {
            label: name.into(),
            material: Box::new(m),
        };
        let samples = draw(&src, 200_000, 80.0, 1);
        let held = draw(&src, 20_000, 80.0, 2);
        for (res, dense_max_res) in runs {
            let opts = FitOptions {
                res,
                dense_max_res,
                ..Default::default()
            };
            let mut best: Option<(f64, isolux_factor::Factorization)> = None;
            for _ in 0..repeat {
                let t = Instant::now();
                let f = fit(&samples, &opts)?;
                let total = t.elapsed().as_secs_f64();
                if best.as_ref().is_none_or(|b| total < b.0) {
                    best = Some((total, f));
                }
            }
            let (total, f) = best.expect("at least one repeat");
            let s = &f.stats;
            let solver = if s.cg_iterations > 0 {
                format!("CG, {} iterations", s.cg_iterations)
            } else {
                format!("Cholesky x {}", s.factorizations)
            };
            let m = f.material()?;
            let err = evaluate(&held, f.floor, |wo, wi| {
                use isolux_materials::BxdfModel;
                m.f(wo, wi)
            })
            .relative_rms;
            println!(
                "| {name} | {res} | {} | {solver} | {:.3} | {:.3} | {:.3} | {total:.3} | {err:.4} |",
                s.unknowns, s.assemble_s, s.solve_s, s.coarse_s
            );
        }
    }
    Ok(())
}

/// Dipole vs random walk on a skim-milk sphere under the sky map.
///
/// Noise is measured as the RMS difference of two renders with different
/// seeds over the sphere's pixels, divided by sqrt(2) (the standard
/// deviation of one render); efficiency is `1 / (noise^2 * time)` (Monte
/// Carlo noise falls as `1/sqrt(time)`), so the ratio of efficiencies is
/// the speed-up at equal noise.
fn sss(size: u32) -> Result<()> {
    use isolux_core::{DVec3, Rgb};
    use isolux_geometry::{Aggregate, Object, Quadric};
    use isolux_materials::subsurface::Medium;
    use isolux_materials::subsurface_material::SubsurfaceMode;
    use isolux_materials::{Material, Subsurface};
    use isolux_render::{
        render, Camera, EnvMap, Environment, FilmSettings, IntegratorSettings, RenderOptions, Scene,
    };

    let sky = isolux_io::read_rgb_image(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/env/sky.hdr"
    )))?;
    let texels = sky
        .pixels
        .iter()
        .map(|p| Rgb::new(p[0] as f64, p[1] as f64, p[2] as f64))
        .collect();
    let env = Environment::Map(
        EnvMap::new(sky.width, sky.height, texels, 0.5).map_err(anyhow::Error::msg)?,
    );
    let m = Medium::by_name("skimmilk").expect("skim milk is a named medium");
    let scale = 20.0;
    let make = |mode, spp, seed| Scene {
        camera: Camera {
            position: DVec3::new(0.0, 0.3, -3.0),
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            fov_y: 30.0,
        },
        film: FilmSettings {
            width: size,
            height: size,
            spp,
        },
        integrator: IntegratorSettings {
            max_depth: 8,
            seed,
            ..Default::default()
        },
        lights: vec![],
        environment: env.clone(),
        materials: vec![Material::Subsurface(Subsurface::new(
            Rgb::from_array(m.sigma_s_reduced) * scale,
            Rgb::from_array(m.sigma_a) * scale,
            0.0,
            m.eta,
            mode,
        ))],
        material_names: vec!["milk".into()],
        geometry: Aggregate::new(vec![Object::new(
            Quadric::sphere(DVec3::ZERO, 0.6),
            vec![],
            None,
        )
        .expect("sphere")]),
        object_material: vec![0],
    };
    println!("skim milk sphere (radius 0.6, 1 unit = {scale} mm) under the sky map, {size}x{size}; noise = RMS(seed 1 - seed 2)/sqrt(2) over the sphere");
    println!("| mode | spp | time per render (s) | mean | noise (std. dev.) | share of noise^2 in the worst 1% of pixels | noise without them | efficiency 1/(noise^2 t) | same, without them |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    let mut eff = vec![];
    for (name, mode, spp) in [
        ("dipole", SubsurfaceMode::Dipole, 16u32),
        ("random_walk", SubsurfaceMode::RandomWalk, 16u32),
    ] {
        let opts = RenderOptions {
            aov: true,
            realtime: false,
        };
        let t = Instant::now();
        let (a, _) = render(&make(mode, spp, 1), &opts, &|_, _| {})?;
        let secs = t.elapsed().as_secs_f64();
        let (b, _) = render(&make(mode, spp, 2), &opts, &|_, _| {})?;
        let depth = &a.aov.as_ref().expect("aov requested").depth;
        // Per sphere pixel: the squared difference summed over channels,
        // and the mean of the first render.
        let (mut d2, mut mean) = (Vec::new(), 0.0);
        for (i, (pa, pb)) in a.rgb.iter().zip(&b.rgb).enumerate() {
            if depth[i] > 0.0 {
                d2.push(
                    (0..3)
                        .map(|c| ((pa[c] - pb[c]) as f64).powi(2))
                        .sum::<f64>(),
                );
                mean += (0..3).map(|c| pa[c] as f64).sum::<f64>() / 3.0;
            }
        }
        let px = d2.len().max(1) as f64;
        let sum: f64 = d2.iter().sum();
        let noise = (sum / (3.0 * px)).sqrt() / std::f64::consts::SQRT_2;
        d2.sort_by(|x, y| y.total_cmp(x));
        let cut = d2.len() / 100;
        let worst = d2[..cut].iter().sum::<f64>() / sum.max(f64::MIN_POSITIVE);
        let trimmed = (d2[cut..].iter().sum::<f64>() / (3.0 * (d2.len() - cut).max(1) as f64))
            .sqrt()
            / std::f64::consts::SQRT_2;
        let e = 1.0 / (noise * noise * secs);
        let et = 1.0 / (trimmed * trimmed * secs);
        eff.push((e, et));
        println!(
            "| {name} | {spp} | {secs:.2} | {:.4} | {noise:.4} | {worst:.2} | {trimmed:.4} | {e:.1} | {et:.1} |",
            mean / px
        );
    }
    println!(
        "\ndipole speed-up at equal noise: {:.0}x ({:.0}x on the noise without each mode's worst 1% of pixels)",
        eff[0].0 / eff[1].0,
        eff[0].1 / eff[1].1
    );
    Ok(())
}

/// Per-query CPU time of the wave-optics BRDF on one core: a 1024 x 1024
/// isotropic-noise heightfield (RMS 0.1 um, correlation 1 um) of 0.25 um
/// texels, sigma = 2.5 um, a 128 x 128 image of outgoing directions, one
/// wavelength (0.5 um) and eight (the visible comb), with and without the
/// quadtree, all on a one-thread pool.
fn wave(repeat: u32) -> Result<()> {
    use isolux_core::DVec3;
    use isolux_wave::generate::{generate, Kind};
    use isolux_wave::{Comb, Footprint, GaborSurface, Model, Settings};
    let t = Instant::now();
    let field = generate(
        &Kind::Noise {
            rms_um: 0.1,
            corr_um: 1.0,
        },
        1024,
        1024,
        0.25,
        1,
    )?;
    let gen = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let s = GaborSurface::new(field);
    let build = t.elapsed().as_secs_f64();
    let fp = Footprint {
        center_um: [128.0, 128.0],
        sigma_um: 2.5,
    };
    let wi = DVec3::new(0.3, 0.0, (1.0f64 - 0.09).sqrt());
    let res = 128;
    let single = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let run = |comb: &Comb, set: &Settings| -> (f64, usize) {
        let mut out = vec![0.0; comb.n];
        best_of(repeat, || {
            let mut q = 0;
            for r in 0..res {
                for c in 0..res {
                    let x = (c as f64 + 0.5) / res as f64 * 2.0 - 1.0;
                    let y = 1.0 - (r as f64 + 0.5) / res as f64 * 2.0;
                    if x * x + y * y < 1.0 {
                        let wo = DVec3::new(x, y, (1.0 - x * x - y * y).sqrt());
                        s.eval(&fp, Model::Ghs, wi, wo, comb, set, &mut out);
                        q += 1;
                    }
                }
            }
            q
        })
    };
    let on = Settings::default();
    let off = Settings {
        hierarchy: false,
        ..on
    };
    let c1 = Comb::single(0.5);
    let c8 = Comb::visible(8);
    let radius = fp.sigma_um * (2.0 * (1.0 / on.eps).ln()).sqrt();
    let in_disk = std::f64::consts::PI * (radius / 0.25).powi(2);
    println!(
        "wave-optics BRDF: 1024 x 1024 noise heightfield, 0.25 um texels (generated in {gen:.2} s, kernels and quadtree built in {build:.3} s), sigma 2.5 um (~{in_disk:.0} kernels within 3 sigma), {res} x {res} directions, 1 thread, best of {repeat}"
    );
    println!("| wavelengths | quadtree | us / query | vs 1 wavelength |");
    println!("|---:|---|---:|---:|");
    let mut base = 0.0;
    for (name, comb) in [("1", &c1), ("8", &c8)] {
        for (h, set) in [("on", &on), ("off", &off)] {
            let (t, q) = single.install(|| run(comb, set));
            let us = t / q as f64 * 1e6;
            if comb.n == 1 && h == "on" {
                base = us;
            }
            println!("| {name} | {h} | {us:.1} | {:.2}x |", us / base);
        }
    }
    Ok(())
}

/// `bench gpu`: per scene, ms per frame at `width x height` of the GPU's
/// real-time mode (4 spp, `isolux_render::realtime`), its path tracer (16
/// spp, the scene's depth) and of direct light only (4 spp, depth 1), and
/// the same work on the CPU path with all cores. The GPU column is wall
/// time from queueing a frame to the idle queue; "GPU kernels" is the
/// GPU's own time of the same frame from timestamps (where the adapter
/// offers them), so the two differ by what the host and the driver cost.
/// The path tracer's columns time the megakernel, `--wavefront` the
/// wavefront beside it and `--sorted` the sorted wavefront, which a
/// render runs by default on GPUs (`isolux_gpu::PathKernel::Auto`; the
/// megakernel's columns stay comparable with earlier measurements). "First frame" is the wall time of
/// the first frame of the mode's specialized f32 kernels, which compiles them, unless an earlier row
/// of the run did (direct light runs the path tracer's kernel) or the
/// driver's shader cache holds them (Mesa's and NVIDIA's keep compiled
/// kernels on disk across runs): the wait before a first image.
/// Materials not on the GPU yet are replaced by a grey diffuse, on both
/// sides, and named in the output.
fn gpu(a: &BenchArgs) -> Result<()> {
    use isolux_gpu::Precision;
    use isolux_render::{render, RenderOptions};
    let film = isolux_render::FilmSettings {
        width: a.width,
        height: a.height,
        spp: 16,
    };
    if let Some(p) = film.problem() {
        bail!("{}", crate::render_cmd::by_flag(&p));
    }
    let mut gpu = isolux_gpu::Gpu::new()?;
    if a.f64 && !gpu.supports_f64() {
        bail!(
            "--f64: the adapter {} does not offer f64 in shaders (SHADER_F64)",
            gpu.adapter
        );
    }
    let scenes = if a.scenes.is_empty() {
        vec![std::path::PathBuf::from(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../examples/scenes/gallery.toml"
        ))]
    } else {
        a.scenes.clone()
    };
    let threads = rayon::current_num_threads();
    // The driver's version beside the adapter: lavapipe names the same
    // adapter under Mesa 22.3 and Mesa 25 (`scripts/mesa25.sh`).
    let driver = if gpu.driver.is_empty() {
        String::new()
    } else {
        format!(" (driver: {})", gpu.driver)
    };
    println!(
        "adapter: {}{driver}; CPU: {threads} threads; {}x{}; best of {}",
        gpu.adapter, a.width, a.height, a.repeat
    );
    // Optional columns between the GPU kernels and the CPU.
    let mut extra = String::new();
    let mut rule = String::new();
    if a.f64 {
        extra += " GPU f64 (ms/frame) | f64 / f32 |";
        rule += "---:|---:|";
    }
    if a.general {
        extra += " GPU general kernels (ms/frame) | general / specialized |";
        rule += "---:|---:|";
    }
    if a.wavefront {
        extra += " GPU wavefront (ms/frame) | wavefront / megakernel |";
        rule += "---:|---:|";
    }
    if a.sorted {
        extra += " GPU sorted wavefront (ms/frame) | sorted / wavefront | GPU split, unsorted (ms/frame) | unsorted / wavefront | GPU sorted to step 2 (ms/frame) | to step 2 / wavefront | GPU sorted, a sample a run (ms/frame) | a sample a run / sorted |";
        rule += "---:|---:|---:|---:|---:|---:|---:|---:|";
    }
    if a.per_sample {
        extra += " GPU one sample per dispatch (ms/frame) | per sample / layered |";
        rule += "---:|---:|";
    }
    if a.tiles {
        extra += " GPU tile lists (ms/frame) | GPU per-ray walks (ms/frame) | lists / walks |";
        rule += "---:|---:|---:|";
    }
    if a.checked {
        extra += " GPU run-time checks (ms/frame) | checked / unchecked |";
        rule += "---:|---:|";
    }
    // `--kernels`' table, printed after the first.
    let mut kernel_table: Vec<String> = Vec::new();
    // `--runs`' table, printed last.
    let mut runs_table: Vec<String> = Vec::new();
    println!("| scene | mode | spp | kernel features | GPU (ms/frame) | GPU kernels (ms) |{extra} CPU (ms/frame) | CPU / GPU | first frame (ms) |");
    println!("|---|---|---:|---|---:|---:|{rule}---:|---:|---:|");
    for path in &scenes {
        let mut scene = isolux_scene::load(path)?;
        let replaced = isolux_gpu::replace_unsupported(&mut scene);
        scene.film.width = a.width;
        scene.film.height = a.height;
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        let depth = scene.integrator.max_depth;
        // "first hit": the camera rays' exact intersection alone, nothing
        // shaded (`Gpu::prepare_first_hits`), as many rays as the
        // real-time frame's camera rays: what of the modes' time the
        // geometry takes.
        for (mode, spp, max_depth) in [
            ("real-time", 4, depth),
            ("path traced", 16, depth),
            ("direct only", 4, 1),
            ("first hit", 4, depth),
        ] {
            let realtime = mode == "real-time";
            let first_hit = mode == "first hit";
            scene.film.spp = spp;
            scene.integrator.max_depth = max_depth;
            let mut frame = if realtime {
                gpu.prepare_realtime(&scene)?
            } else if first_hit {
                gpu.prepare_first_hits(&scene)?
            } else {
                gpu.prepare(&scene)?
            };
            // The GPU columns time the megakernel, although a render on
            // a GPU runs the sorted wavefront (`PathKernel::Auto`);
            // `--wavefront` and `--sorted` add the wavefronts'.
            frame.set_wavefront(false);
            // Wall time from queueing the frame to the idle queue, and the
            // GPU's own time of the same frames (timestamps), best of each.
            let time = |gpu: &isolux_gpu::Gpu,
                        frame: &mut isolux_gpu::GpuFrame|
             -> Result<(f64, Option<f64>, f64)> {
                // Warm-up: compiles the kernel, touches the buffers, and
                // gives the GPU two seconds to raise its clocks (an idle
                // H100 starts at 345 MHz: after half a second's warm-up
                // the first mode of a run still measured 3-4x slow, 22 ms
                // against 6.9 ms for the real-time frame, 2026-11-24).
                let warm = Instant::now();
                let mut first = None;
                while warm.elapsed().as_secs_f64() < 2.0 {
                    frame.reset(gpu);
                    frame.run(gpu, spp);
                    gpu.wait()?;
                    first.get_or_insert(warm.elapsed().as_secs_f64());
                }
                let first = first.unwrap_or(0.0);
                let mut g = f64::INFINITY;
                let mut k: Option<f64> = None;
                for _ in 0..a.repeat {
                    frame.reset(gpu);
                    gpu.wait()?;
                    let t = Instant::now();
                    frame.run_timed(gpu, spp);
                    gpu.wait()?;
                    g = g.min(t.elapsed().as_secs_f64());
                    if let Some(kt) = frame.gpu_time(gpu)? {
                        k = Some(k.map_or(kt, |k| k.min(kt)));
                    }
                }
                let (img, _) = frame.image(gpu)?;
                if img.rgb.iter().flatten().any(|c| !c.is_finite()) {
                    bail!("{name}: the GPU image has non-finite pixels");
                }
                if first_hit {
                    let aov = frame.aovs(gpu)?;
                    if aov.depth.iter().any(|d| !d.is_finite()) {
                        bail!("{name}: the GPU's first hits have non-finite distances");
                    }
                }
                Ok((g, k, first))
            };
            let (g, kernels, first) = time(&gpu, &mut frame)?;
            let kernels = kernels.map_or("-".to_string(), |k| format!("{:.2}", k * 1e3));
            // `--kernels`: the rows of `frame` as the path kernel `kernel`
            // runs it (the `Gpu` passed in, which `--f64` changes between).
            let mut profile = |gpu: &isolux_gpu::Gpu,
                               frame: &mut isolux_gpu::GpuFrame,
                               kernel: &str|
             -> Result<()> {
                if a.kernels {
                    let rows = kernel_rows(gpu, frame, spp, a.repeat, [&name, mode, kernel])?;
                    kernel_table.extend(rows);
                }
                Ok(())
            };
            let path_modes = !(realtime || first_hit);
            profile(
                &gpu,
                &mut frame,
                if path_modes { "megakernel" } else { "-" },
            )?;
            let mut cols = String::new();
            if a.f64 {
                gpu.set_precision(Precision::F64)?;
                let t = time(&gpu, &mut frame);
                gpu.set_precision(Precision::F32)?;
                let g64 = t?.0;
                cols += &format!(" {:.2} | {:.2} |", g64 * 1e3, g64 / g);
            }
            let features = frame.features();
            if a.general {
                frame.set_features(isolux_gpu::Features::ALL)?;
                let gg = time(&gpu, &mut frame)?.0;
                frame.set_features(features)?;
                cols += &format!(" {:.2} | {:.2} |", gg * 1e3, gg / g);
            }
            let mut wavefront = None;
            if a.wavefront {
                if realtime || first_hit {
                    cols += " - | - |";
                } else {
                    // The plain wavefront, not the sorted one that is
                    // the default on GPUs.
                    frame.set_wavefront(true);
                    frame.set_sorted(false);
                    let gw = time(&gpu, &mut frame)?.0;
                    profile(&gpu, &mut frame, "wavefront")?;
                    frame.set_wavefront(false);
                    cols += &format!(" {:.2} | {:.2} |", gw * 1e3, gw / g);
                    wavefront = Some(gw);
                }
            }
            if a.sorted {
                frame.set_wavefront(true);
                frame.set_sorted(true);
                if realtime || first_hit || !frame.sorted() {
                    cols += " - | - | - | - | - | - | - | - |";
                } else {
                    let gs = time(&gpu, &mut frame)?.0;
                    profile(&gpu, &mut frame, "sorted wavefront")?;
                    frame.set_sort_by_material(false);
                    let gu = time(&gpu, &mut frame);
                    frame.set_sort_by_material(true);
                    let gu = gu?.0;
                    // Steps 0-2 sorted, the rest (a few thousand paths
                    // each at 1080p) one dispatch a step.
                    frame.set_sorted_steps(3);
                    let g3 = time(&gpu, &mut frame);
                    frame.set_sorted_steps(u32::MAX);
                    let g3 = g3?.0;
                    // One sample's paths a run, as before 2026-12-05.
                    frame.set_wavefront_samples(1);
                    let g1 = time(&gpu, &mut frame);
                    frame.set_wavefront_samples(16);
                    let g1 = g1?.0;
                    frame.set_sorted(false);
                    let gw = match wavefront {
                        Some(gw) => gw,
                        None => time(&gpu, &mut frame)?.0,
                    };
                    cols += &format!(
                        " {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
                        gs * 1e3,
                        gs / gw,
                        gu * 1e3,
                        gu / gw,
                        g3 * 1e3,
                        g3 / gw,
                        g1 * 1e3,
                        g1 / gs
                    );
                }
                frame.set_sorted(false);
                frame.set_wavefront(false);
            }
            if a.runs && path_modes {
                // Tiles of n samples' padded pixels.
                let padded = isolux_gpu::padded_pixels(a.width, a.height) as u64;
                frame.set_wavefront(true);
                frame.set_sorted(true);
                let kernel = if frame.sorted() {
                    "sorted wavefront"
                } else {
                    "wavefront"
                };
                let mut default = None;
                for n in [None, Some(1u32), Some(2), Some(4), Some(8), Some(16)] {
                    let tile = n.map_or(isolux_gpu::WF_TILE_MAX, |n| n as u64 * padded);
                    frame.set_wavefront_tile(tile);
                    frame.set_wavefront_samples(n.unwrap_or(16));
                    let t = time(&gpu, &mut frame)?.0;
                    let (samples, tiles) = frame.wavefront_runs().unwrap_or((1, 1));
                    let d = *default.get_or_insert(t);
                    let asked = n.map_or("default".to_string(), |n| n.to_string());
                    runs_table.push(format!(
                        "| {name} | {mode} | {kernel} | {asked} | {samples} | {tiles} | {} | {:.2} | {:.2} |",
                        16u32.div_ceil(samples),
                        t * 1e3,
                        t / d
                    ));
                }
                frame.set_wavefront_tile(isolux_gpu::WF_TILE_MAX);
                frame.set_wavefront_samples(16);
                frame.set_sorted(false);
                frame.set_wavefront(false);
            }
            if a.per_sample && first_hit {
                // Already one dispatch per sample.
                cols += " - | - |";
            } else if a.per_sample {
                frame.set_max_layers(1);
                let gs = time(&gpu, &mut frame)?.0;
                frame.set_max_layers(16);
                cols += &format!(" {:.2} | {:.2} |", gs * 1e3, gs / g);
            }
            if a.tiles {
                let default = frame.features().tiles;
                frame.set_tile_lists(true);
                let gl = time(&gpu, &mut frame)?.0;
                frame.set_tile_lists(false);
                let gw = time(&gpu, &mut frame)?.0;
                frame.set_tile_lists(default);
                cols += &format!(" {:.2} | {:.2} | {:.2} |", gl * 1e3, gw * 1e3, gl / gw);
            }
            if a.checked {
                gpu.set_runtime_checks(true);
                let t = time(&gpu, &mut frame);
                gpu.set_runtime_checks(false);
                let gc = t?.0;
                cols += &format!(" {:.2} | {:.2} |", gc * 1e3, gc / g);
            }
            // The CPU has no mode that traces first hits alone.
            let (c, ratio) = if a.skip_cpu || first_hit {
                ("-".to_string(), "-".to_string())
            } else {
                let opts = RenderOptions {
                    aov: false,
                    realtime,
                };
                let (t, _) = best_of(a.repeat, || {
                    render(&scene, &opts, &|_, _| {})
                        .map(|r| r.1.samples as usize)
                        .unwrap_or(0)
                });
                (format!("{:.1}", t * 1e3), format!("{:.1}", t / g))
            };
            println!(
                "| {name} | {mode} | {spp} | {features} | {:.2} | {kernels} |{cols} {c} | {ratio} | {:.2} |",
                g * 1e3,
                first * 1e3
            );
        }
        if !replaced.is_empty() {
            println!(
                "({name}: not on the GPU yet, replaced by diffuse on both sides: {})",
                replaced.join(", ")
            );
        }
    }
    if a.kernels {
        println!();
        if kernel_table.is_empty() {
            println!(
                "(--kernels: the adapter {} offers no timestamps)",
                gpu.adapter
            );
        } else {
            println!("GPU time per kernel (ms per frame; `-`: not a wavefront step):");
            println!("| scene | mode | path kernel | kernel | dispatches | step 0 (ms) | step 1 (ms) | steps 2+ (ms) | total (ms) | share |");
            println!("|---|---|---|---|---:|---:|---:|---:|---:|---:|");
            for row in kernel_table {
                println!("{row}");
            }
        }
    }
    if a.runs {
        println!();
        println!("Samples a run of the wavefront (`--runs`; ratios to each mode's default row, a tile of WF_TILE_MAX paths):");
        println!("| scene | mode | path kernel | samples asked | samples a run | tiles a run | runs of 16 spp | GPU (ms/frame) | / default |");
        println!("|---|---|---|---:|---:|---:|---:|---:|---:|");
        for row in runs_table {
            println!("{row}");
        }
    }
    Ok(())
}

/// `bench gpu --kernels`: the rows of `frame`'s GPU time kernel by kernel
/// (`spp` samples, best of `repeat` by the frame's span), labelled
/// `[scene, mode, path kernel]`: per kernel in the order first queued,
/// its dispatches, its time at step 0, step 1 and the steps after (the
/// wavefronts; `-` elsewhere), its total and share of the frame's span;
/// then the time between dispatches and the span. None where the
/// adapter offers no timestamps.
fn kernel_rows(
    gpu: &isolux_gpu::Gpu,
    frame: &mut isolux_gpu::GpuFrame,
    spp: u32,
    repeat: u32,
    [scene, mode, kernel]: [&str; 3],
) -> Result<Vec<String>> {
    let mut best: Option<isolux_gpu::Profile> = None;
    for _ in 0..repeat.max(1) {
        frame.reset(gpu);
        let Some(p) = frame.profile(gpu, spp)? else {
            return Ok(Vec::new());
        };
        if best.as_ref().is_none_or(|b| p.span < b.span) {
            best = Some(p);
        }
    }
    let Some(p) = best else {
        return Ok(Vec::new());
    };
    // Per kernel: dispatches, then ms at step 0, 1, 2+ (or none), total.
    let mut order: Vec<&str> = Vec::new();
    let mut sums: std::collections::HashMap<&str, (usize, [f64; 3], bool, f64)> =
        std::collections::HashMap::new();
    for d in &p.dispatches {
        let e = sums.entry(d.kernel).or_insert_with(|| {
            order.push(d.kernel);
            (0, [0.0; 3], false, 0.0)
        });
        e.0 += 1;
        if let Some(k) = d.step {
            e.1[(k as usize).min(2)] += d.seconds;
            e.2 = true;
        }
        e.3 += d.seconds;
    }
    let span = p.span.max(f64::MIN_POSITIVE);
    let ms = |s: f64| format!("{:.3}", s * 1e3);
    let share = |s: f64| format!("{:.1}%", 100.0 * s / span);
    let mut rows = Vec::new();
    for k in order {
        let (n, steps, stepped, total) = sums[k];
        let [s0, s1, s2] = if stepped {
            steps.map(ms)
        } else {
            ["-".to_string(), "-".to_string(), "-".to_string()]
        };
        rows.push(format!(
            "| {scene} | {mode} | {kernel} | {k} | {n} | {s0} | {s1} | {s2} | {} | {} |",
            ms(total),
            share(total)
        ));
    }
    let between = (p.span - p.dispatch_seconds()).max(0.0);
    rows.push(format!(
        "| {scene} | {mode} | {kernel} | (between dispatches) | - | - | - | - | {} | {} |",
        ms(between),
        share(between)
    ));
    rows.push(format!(
        "| {scene} | {mode} | {kernel} | (frame) | {} | - | - | - | {} | 100% |",
        p.dispatches.len(),
        ms(p.span)
    ));
    Ok(rows)
}
