//! `isolux heightfield gen` and `isolux wave brdf`: micron-scale
//! heightfields and their wave-optics BRDF (see `docs/wave-optics.md`).

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use isolux_core::{DVec3, Image};
use isolux_materials::wave::{Wave, WaveFresnel};
use isolux_wave::generate::{generate, Kind};
use isolux_wave::{Comb, GaborSurface, Heightfield, LoadOptions, Model, Obliquity, Settings};
use rayon::prelude::*;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// Heightfield tools.
#[derive(Args, Debug)]
pub struct HeightfieldArgs {
    #[command(subcommand)]
    command: HeightfieldCommand,
}

#[derive(Subcommand, Debug)]
enum HeightfieldCommand {
    /// Generate a heightfield (heights in um) as a one-channel EXR.
    Gen(GenArgs),
}

/// Generator kinds.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum GenKind {
    /// Isotropic Gaussian-filtered noise (--rms-um, --corr-um).
    Noise,
    /// Brushed metal: anisotropic noise (--rms-um, --along-um, --across-um, --direction-deg).
    Brushed,
    /// Random scratches (--count, --depth-um, --width-um, --length-um) over optional noise (--rms-um, --corr-um).
    Scratches,
    /// Sinusoidal grating (--period-um, --amplitude-um, --direction-deg).
    Grating,
}

#[derive(Args, Debug)]
struct GenArgs {
    /// What to generate.
    #[arg(long, value_enum)]
    kind: GenKind,
    /// Width in texels.
    #[arg(long, default_value_t = 1024)]
    width: usize,
    /// Height in texels (default: the width).
    #[arg(long)]
    height: Option<usize>,
    /// Texel size (um), stored in the EXR header.
    #[arg(long, default_value_t = 1.0)]
    texel_um: f64,
    /// RMS height (um): noise, brushed, and the base noise of scratches (0: none).
    #[arg(long, default_value_t = 0.05)]
    rms_um: f64,
    /// Correlation length (um): noise and the base noise of scratches.
    #[arg(long, default_value_t = 2.0)]
    corr_um: f64,
    /// Brushed: correlation length along the brushing direction (um).
    #[arg(long, default_value_t = 50.0)]
    along_um: f64,
    /// Brushed: correlation length across it (um).
    #[arg(long, default_value_t = 1.0)]
    across_um: f64,
    /// Brushed / grating: direction, degrees from +x toward +y.
    #[arg(long, default_value_t = 0.0)]
    direction_deg: f64,
    /// Scratches: how many.
    #[arg(long, default_value_t = 200)]
    count: usize,
    /// Scratches: groove depth (um).
    #[arg(long, default_value_t = 0.2)]
    depth_um: f64,
    /// Scratches: groove half-width (um).
    #[arg(long, default_value_t = 1.0)]
    width_um: f64,
    /// Scratches: length (um).
    #[arg(long, default_value_t = 200.0)]
    length_um: f64,
    /// Grating: period (um).
    #[arg(long, default_value_t = 4.0)]
    period_um: f64,
    /// Grating: amplitude (um).
    #[arg(long, default_value_t = 0.05)]
    amplitude_um: f64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output `.exr` file.
    #[arg(short, long)]
    output: PathBuf,
}

/// Wave-optics tools.
#[derive(Args, Debug)]
pub struct WaveArgs {
    #[command(subcommand)]
    command: WaveCommand,
}

#[derive(Subcommand, Debug)]
enum WaveCommand {
    /// Write the BRDF over the projected outgoing hemisphere as an image.
    Brdf(BrdfArgs),
}

/// Scalar diffraction models.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum ModelArg {
    /// Generalized Harvey-Shack (c3 = cos_i + cos_o).
    Ghs,
    /// Original Harvey-Shack (c3 = 2).
    Ohs,
}

/// Obliquity factors of the BRDF.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum ObliquityArg {
    /// O = 1: reciprocal, albedo at most 1 (default).
    Reciprocal,
    /// O = cos_o / cos_i: the seed's factor (SPEC §3); albedo above 1 at grazing incidence.
    Seed,
}

#[derive(Args, Debug)]
struct BrdfArgs {
    /// Heightfield: .exr, 16-bit .png, or raw .f32 (with --raw-size).
    #[arg(long)]
    heightfield: PathBuf,
    /// Texel size (um); default: the file's, else 1.
    #[arg(long)]
    texel_um: Option<f64>,
    /// Multiplies every height.
    #[arg(long, default_value_t = 1.0)]
    vertical_scale: f64,
    /// Width and height of a raw f32 file, as WxH.
    #[arg(long)]
    raw_size: Option<String>,
    /// Coherence area centre (um), as X,Y.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    center_um: Vec<f64>,
    /// Coherence area standard deviation (um).
    #[arg(long, default_value_t = 10.0)]
    sigma_um: f64,
    /// Direction toward the light, as X,Y,Z (normalized; z > 0).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    incident: Vec<f64>,
    /// One wavelength (um), 0.2 to 2.
    #[arg(long, conflicts_with = "spectral")]
    lambda_um: Option<f64>,
    /// N wavelengths across 380-780 nm, converted to linear sRGB.
    #[arg(long)]
    spectral: Option<usize>,
    /// Diffraction model.
    #[arg(long, value_enum, default_value_t = ModelArg::Ghs)]
    model: ModelArg,
    /// Obliquity factor (see docs/wave-optics.md, "Energy").
    #[arg(long, value_enum, default_value_t = ObliquityArg::Reciprocal)]
    obliquity: ObliquityArg,
    /// Fresnel: none, or a metal (Ag, Al, Au, Cr, Cu, Fe, Ni, Ti).
    #[arg(long, default_value = "none")]
    fresnel: String,
    /// Output resolution (R x R).
    #[arg(long, default_value_t = 128)]
    res: usize,
    /// Visit every kernel instead of using the quadtree (same result, slower).
    #[arg(long)]
    no_hierarchy: bool,
    /// Output image (.exr, or .png tonemapped).
    #[arg(short, long)]
    output: PathBuf,
}

/// Runs `isolux heightfield`.
pub fn run_heightfield(a: HeightfieldArgs) -> Result<()> {
    let HeightfieldCommand::Gen(g) = a.command;
    let ext = g.output.extension().and_then(|e| e.to_str()).unwrap_or("");
    if !ext.eq_ignore_ascii_case("exr") {
        bail!("{}: heightfields are written as .exr", g.output.display());
    }
    isolux_io::check_output(&g.output)?;
    let height = g.height.unwrap_or(g.width);
    for (flag, v) in [("--width", g.width), ("--height", height)] {
        if v == 0 {
            bail!("{flag} must be at least 1 texel");
        }
    }
    let max = isolux_wave::heightfield::MAX_TEXELS;
    if g.width.saturating_mul(height) > max {
        bail!(
            "--width x --height: {} x {height} texels, more than the {max} a heightfield may hold",
            g.width
        );
    }
    let kind = match g.kind {
        GenKind::Noise => Kind::Noise {
            rms_um: g.rms_um,
            corr_um: g.corr_um,
        },
        GenKind::Brushed => Kind::Brushed {
            rms_um: g.rms_um,
            along_um: g.along_um,
            across_um: g.across_um,
            direction_deg: g.direction_deg,
        },
        GenKind::Scratches => Kind::Scratches {
            count: g.count,
            depth_um: g.depth_um,
            width_um: g.width_um,
            length_um: g.length_um,
            base_rms_um: g.rms_um,
            base_corr_um: g.corr_um,
        },
        GenKind::Grating => Kind::Grating {
            period_um: g.period_um,
            amplitude_um: g.amplitude_um,
            direction_deg: g.direction_deg,
        },
    };
    let t = Instant::now();
    let h = generate(&kind, g.width, height, g.texel_um, g.seed)?;
    if let GenKind::Grating = g.kind {
        if let Some(why) = isolux_wave::generate::grating_seam(
            g.width,
            height,
            g.texel_um,
            g.period_um,
            g.direction_deg,
        ) {
            eprintln!("isolux: warning: {why}");
        }
    }
    h.write_exr(&g.output)?;
    eprintln!(
        "wrote {} ({} x {} texels of {} um, RMS height {:.4} um) in {:.2} s",
        g.output.display(),
        h.width,
        h.height,
        h.texel_um,
        h.rms(),
        t.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Runs `isolux wave`.
pub fn run_wave(a: WaveArgs) -> Result<()> {
    let WaveCommand::Brdf(b) = a.command;
    brdf(b)
}

fn parse_raw_size(s: &str) -> Result<(usize, usize)> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .with_context(|| format!("--raw-size {s}: expected WxH"))?;
    Ok((
        w.trim()
            .parse()
            .with_context(|| format!("--raw-size {s}: bad width"))?,
        h.trim()
            .parse()
            .with_context(|| format!("--raw-size {s}: bad height"))?,
    ))
}

fn brdf(b: BrdfArgs) -> Result<()> {
    isolux_io::check_output(&b.output)?;
    if b.center_um.len() != 2 || b.center_um.iter().any(|v| !v.is_finite()) {
        bail!("--center-um needs two finite numbers X,Y");
    }
    if b.incident.len() != 3 || b.incident.iter().any(|v| !v.is_finite()) {
        bail!("--incident needs three finite numbers X,Y,Z");
    }
    let wi = DVec3::new(b.incident[0], b.incident[1], b.incident[2]);
    let Some(wi) = wi.try_normalize() else {
        bail!("--incident must not be the zero vector");
    };
    if !(wi.z > 0.0) {
        bail!(
            "--incident {:?} points below the surface (z must be > 0)",
            b.incident
        );
    }
    if !(b.sigma_um > 0.0) || !b.sigma_um.is_finite() {
        bail!("--sigma-um must be positive, got {}", b.sigma_um);
    }
    if b.res == 0 || b.res > 4096 {
        bail!("--res must be between 1 and 4096, got {}", b.res);
    }
    let comb = match (b.lambda_um, b.spectral) {
        (Some(l), None) => {
            if !(0.2..=2.0).contains(&l) {
                bail!("--lambda-um {l} is outside 0.2-2 um");
            }
            Comb::single(l)
        }
        (None, Some(n)) => {
            if !(1..=64).contains(&n) {
                bail!("--spectral must be between 1 and 64 wavelengths, got {n}");
            }
            Comb::visible(n)
        }
        _ => bail!("give exactly one of --lambda-um L or --spectral N"),
    };
    let fresnel = WaveFresnel::parse(&b.fresnel).map_err(anyhow::Error::msg)?;
    let opts = LoadOptions {
        texel_um: b.texel_um,
        vertical_scale: b.vertical_scale,
        raw_size: b.raw_size.as_deref().map(parse_raw_size).transpose()?,
    };
    if let Some(t) = b.texel_um {
        if !(t > 0.0) || !t.is_finite() {
            bail!("--texel-um must be positive, got {t}");
        }
    }
    let t0 = Instant::now();
    let field = Heightfield::load(&b.heightfield, &opts)?;
    let surface = Arc::new(GaborSurface::new(field));
    let build = t0.elapsed().as_secs_f64();
    let model = match b.model {
        ModelArg::Ghs => Model::Ghs,
        ModelArg::Ohs => Model::Ohs,
    };
    let mut m = Wave::new(surface.clone(), model, fresnel);
    m.settings = Settings {
        hierarchy: !b.no_hierarchy,
        obliquity: match b.obliquity {
            ObliquityArg::Reciprocal => Obliquity::Reciprocal,
            ObliquityArg::Seed => Obliquity::Seed,
        },
        ..Settings::default()
    };
    if let Some(why) = m.roughness_warning() {
        eprintln!("isolux: warning: {}: {why}", b.heightfield.display());
    }
    if let Some(why) = m.coherence_problem(b.sigma_um) {
        bail!("--sigma-um {why}");
    }
    m.query.center_um = [b.center_um[0], b.center_um[1]];
    m.query.sigma_um = b.sigma_um;
    let res = b.res;
    let show = std::io::stderr().is_terminal();
    let bar = ProgressBar::with_draw_target(
        Some(res as u64),
        if show {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        },
    );
    bar.set_style(
        ProgressStyle::with_template("{spinner} BRDF rows [{bar:40}] {pos}/{len} ETA {eta}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    let t1 = Instant::now();
    let rows: Vec<Vec<[f32; 3]>> = (0..res)
        .into_par_iter()
        .map(|r| {
            let row = (0..res)
                .map(|c| {
                    let x = (c as f64 + 0.5) / res as f64 * 2.0 - 1.0;
                    let y = 1.0 - (r as f64 + 0.5) / res as f64 * 2.0;
                    let r2 = x * x + y * y;
                    if r2 >= 1.0 {
                        return [0.0; 3];
                    }
                    let wo = DVec3::new(x, y, (1.0 - r2).sqrt());
                    let f = m.f_comb(wo, wi, &comb);
                    [f.r as f32, f.g as f32, f.b as f32]
                })
                .collect();
            bar.inc(1);
            row
        })
        .collect();
    bar.finish_and_clear();
    let wall = t1.elapsed().as_secs_f64();
    let rgb: Vec<[f32; 3]> = rows.into_iter().flatten().collect();
    let queries = rgb.len();
    let cell = (2.0 / res as f64).powi(2);
    let mut albedo = [0.0f64; 3];
    for p in &rgb {
        for k in 0..3 {
            albedo[k] += p[k] as f64 * cell;
        }
    }
    if rgb.iter().any(|p| p.iter().any(|v| !v.is_finite())) {
        bail!("internal error: non-finite BRDF value");
    }
    let image = Image {
        width: res as u32,
        height: res as u32,
        rgb,
        aov: None,
    };
    isolux_io::write_image(&b.output, &image, 0.0, isolux_io::Tonemap::default())?;
    let threads = rayon::current_num_threads();
    let fp = isolux_wave::Footprint {
        center_um: m.query.center_um,
        sigma_um: b.sigma_um,
    };
    println!("wrote {}", b.output.display());
    println!(
        "heightfield {} x {} texels of {} um: loaded and built in {:.2} s ({} MiB)",
        surface.width,
        surface.height,
        surface.texel_um,
        build,
        surface.memory_bytes() / (1 << 20)
    );
    println!(
        "kernels in the window: {}; {} wavelength(s)",
        surface.window_kernels(&fp, &m.settings),
        comb.n
    );
    if comb.n == 1 {
        println!("directional albedo: {:.4}", albedo[0]);
    } else {
        println!(
            "directional albedo (linear sRGB): {:.4} {:.4} {:.4}",
            albedo[0], albedo[1], albedo[2]
        );
    }
    println!(
        "time per query: {:.1} us wall on {threads} threads, {:.1} us CPU",
        wall / queries as f64 * 1e6,
        wall * threads as f64 / queries as f64 * 1e6
    );
    Ok(())
}
