//! `isolux brdf`: plots of a scene's materials.
//!
//! - `plot`: polar plot of `f cos(theta_i)` (luminance) in the plane of
//!   incidence (`--plane in`) or the perpendicular plane through the normal
//!   (`--plane out`), for one incident direction, materials overlaid. The
//!   angle runs from -90 to 90 degrees, positive toward the mirror side.
//!   Delta lobes (mirrors, glass) have no finite value and draw as zero.
//! - `albedo`: directional albedo (luminance of the reflected plus
//!   transmitted energy, delta lobes included; radiance compression across
//!   refraction undone) against incidence angle, estimated by the material's own
//!   importance sampling (20,000 samples per angle; also printed as a table).
//! - `sphere`: a lit-sphere thumbnail under a point light and a dim sky.
//!
//! A `subsurface` material is a boundary over a medium whose light leaves
//! elsewhere on the surface, so it has no BRDF of its own (its boundary's
//! `R + T` is 1 at every angle). `plot` and `albedo` show its local
//! approximation instead, the `subsurface_brdf` of the same medium
//! (`Subsurface::local_brdf`, what the real-time mode renders), labelled
//! "NAME (local approximation)"; `sphere` path traces the medium itself.
//!
//! A `wave` material (or a mix holding one) has a BRDF per footprint on
//! its heightfield: `plot` and `albedo` show the one it holds before it is
//! placed on a surface, at the heightfield's origin over its coherence
//! area, and a note on standard error says so (`isolux wave brdf
//! --center-um` shows any other); `sphere` renders it placed.
//!
//! Text is rasterized in pure Rust (plotters' `ab_glyph` backend) with the
//! bundled DejaVu Sans font: no system font libraries are needed.

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use isolux_core::{DVec3, Pcg32, Rgb};
use isolux_materials::{BxdfModel, Material};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Material plots.
#[derive(Args, Debug)]
pub struct BrdfArgs {
    #[command(subcommand)]
    command: BrdfCommand,
}

#[derive(Subcommand, Debug)]
enum BrdfCommand {
    /// Polar plot of f cos in the plane of incidence (or perpendicular).
    Plot(PlotArgs),
    /// Directional albedo against incidence angle.
    Albedo(AlbedoArgs),
    /// Lit-sphere thumbnail of one material.
    Sphere(SphereArgs),
}

/// Which plane the polar plot shows.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum Plane {
    /// The plane of incidence.
    In,
    /// The plane through the normal perpendicular to it.
    Out,
}

#[derive(Args, Debug)]
struct PlotArgs {
    /// Scene file that defines the materials.
    scene: PathBuf,
    /// Material name (repeat to overlay several).
    #[arg(long = "material", required = true)]
    materials: Vec<String>,
    /// Incidence angle from the normal, degrees.
    #[arg(long, allow_negative_numbers = true)]
    theta_i: f64,
    /// Incidence azimuth from the tangent, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    phi_i: f64,
    /// Plane of the plot.
    #[arg(long, value_enum, default_value_t = Plane::In)]
    plane: Plane,
    /// Output image: .png or .svg.
    #[arg(short, long)]
    output: PathBuf,
}

#[derive(Args, Debug)]
struct AlbedoArgs {
    /// Scene file that defines the materials.
    scene: PathBuf,
    /// Material name (repeat to overlay several).
    #[arg(long = "material", required = true)]
    materials: Vec<String>,
    /// Output image: .png or .svg.
    #[arg(short, long)]
    output: PathBuf,
}

#[derive(Args, Debug)]
struct SphereArgs {
    /// Scene file that defines the material.
    scene: PathBuf,
    /// Material name.
    #[arg(long)]
    material: String,
    /// Output image (.png or .exr).
    #[arg(short, long)]
    output: PathBuf,
    /// Edge of the square thumbnail in pixels.
    #[arg(long, default_value_t = 256)]
    size: u32,
}

const COLOURS: [RGBColor; 12] = [
    RGBColor(200, 30, 30),
    RGBColor(30, 90, 200),
    RGBColor(20, 150, 60),
    RGBColor(230, 130, 0),
    RGBColor(130, 40, 170),
    RGBColor(0, 160, 170),
    RGBColor(120, 120, 120),
    RGBColor(180, 150, 0),
    RGBColor(240, 90, 170),
    RGBColor(100, 60, 20),
    RGBColor(0, 0, 0),
    RGBColor(120, 200, 60),
];

/// Registers the bundled font for plot text (idempotent).
pub fn register_font() -> Result<()> {
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        include_bytes!("../assets/DejaVuSans.ttf"),
    )
    .map_err(|_| anyhow::anyhow!("the bundled font could not be loaded"))
}

/// Runs `isolux brdf`.
pub fn run(a: BrdfArgs) -> Result<()> {
    register_font()?;
    match a.command {
        BrdfCommand::Plot(p) => plot(p),
        BrdfCommand::Albedo(p) => albedo(p),
        BrdfCommand::Sphere(p) => sphere(p),
    }
}

pub fn materials(scene: &Path, names: &[String]) -> Result<Vec<(String, Material)>> {
    let s = isolux_scene::load(scene)?;
    names
        .iter()
        .map(|n| {
            let i = s
                .material_names
                .iter()
                .position(|m| m == n)
                .with_context(|| {
                    format!(
                        "{}: no material named \"{n}\" (defined: {})",
                        scene.display(),
                        if s.material_names.is_empty() {
                            "none".to_string()
                        } else {
                            s.material_names.join(", ")
                        }
                    )
                })?;
            Ok((n.clone(), s.materials[i].clone()))
        })
        .collect()
}

/// `mats` with each `subsurface` medium replaced by its local
/// approximation, named "NAME (local approximation)" (see the module
/// documentation). A material that varies across the surface (a `wave`,
/// or a mix holding one) has a BRDF per footprint; it is `what` (plotted,
/// factored) at the one it holds before placement, the heightfield's
/// origin over its coherence area, and a note on standard error says so.
pub(crate) fn as_brdfs(mats: Vec<(String, Material)>, what: &str) -> Vec<(String, Material)> {
    mats.into_iter()
        .map(|(name, m)| {
            if m.varies_in_space() {
                eprintln!(
                    "isolux: note: material \"{name}\" ({}) varies across the surface: it is {what} \
                     at one footprint, the heightfield's origin over its coherence area \
                     (`isolux wave brdf --center-um` shows the BRDF at any point; `isolux brdf sphere` renders it placed)",
                    m.type_name()
                );
            }
            match m.medium() {
                Some(medium) => (
                    format!("{name} (local approximation)"),
                    Material::SubsurfaceBrdf(medium.local_brdf()),
                ),
                None => (name, m),
            }
        })
        .collect()
}

enum Kind {
    Png,
    Svg,
}

fn kind(p: &Path) -> Result<Kind> {
    match p
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .as_deref()
    {
        Some("png") => Ok(Kind::Png),
        Some("svg") => Ok(Kind::Svg),
        _ => bail!(
            "{}: unknown plot format: use a .png or .svg file name",
            p.display()
        ),
    }
}

/// Draws into a temporary file beside `out`, then renames it into place.
pub fn atomic_plot(
    out: &Path,
    size: (u32, u32),
    draw_png: impl FnOnce(DrawingArea<BitMapBackend, Shift>) -> Result<()>,
    draw_svg: impl FnOnce(DrawingArea<SVGBackend, Shift>) -> Result<()>,
) -> Result<()> {
    let k = kind(out)?;
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("png")
        .to_string();
    let tmp = tempfile::Builder::new()
        .prefix(".isolux-")
        .suffix(&format!(".{ext}"))
        .tempfile_in(&dir)
        .with_context(|| format!("{}: cannot create a temporary file", out.display()))?
        .into_temp_path();
    match k {
        Kind::Png => draw_png(BitMapBackend::new(&tmp, size).into_drawing_area())?,
        Kind::Svg => draw_svg(SVGBackend::new(&tmp, size).into_drawing_area())?,
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&tmp, std::fs::Permissions::from_mode(0o644))?;
    }
    tmp.persist(out)
        .with_context(|| format!("{}: cannot write", out.display()))?;
    Ok(())
}

type Curve = (String, Vec<(f64, f64)>);

fn draw_curves<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    curves: &[Curve],
    polar: bool,
    x_desc: &str,
    y_desc: &str,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("plot: {e:?}");
    root.fill(&WHITE).map_err(e)?;
    let ymax = curves
        .iter()
        .flat_map(|c| {
            c.1.iter()
                .map(|p| if polar { p.0.abs().max(p.1) } else { p.1 })
        })
        .fold(0.0f64, f64::max)
        .max(1e-6)
        * 1.1;
    let (xr, yr) = if polar {
        (-ymax..ymax, 0.0..ymax)
    } else {
        (0.0..90.0, 0.0..ymax.max(1.05))
    };
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(14)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(xr, yr)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    for (i, (name, pts)) in curves.iter().enumerate() {
        let c = COLOURS[i % COLOURS.len()];
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))
            .map_err(e)?
            .label(name.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}

pub fn local_dir(theta_deg: f64, phi_deg: f64) -> DVec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

fn plot(a: PlotArgs) -> Result<()> {
    isolux_io::check_output(&a.output)?;
    if !(a.theta_i >= 0.0 && a.theta_i < 90.0) {
        bail!("--theta-i must lie in [0, 90) degrees, got {}", a.theta_i);
    }
    if !a.phi_i.is_finite() {
        bail!(
            "--phi-i must be a finite number of degrees, got {}",
            a.phi_i
        );
    }
    let mats = as_brdfs(materials(&a.scene, &a.materials)?, "plotted");
    let wo = local_dir(a.theta_i, a.phi_i);
    let phi_plane = match a.plane {
        Plane::In => a.phi_i + 180.0,
        Plane::Out => a.phi_i + 90.0,
    };
    let curves: Vec<Curve> = mats
        .iter()
        .map(|(name, m)| {
            let pts = (0..=720)
                .map(|k| {
                    let t = -90.0 + k as f64 * 0.25;
                    let wi = local_dir(
                        t.abs(),
                        if t >= 0.0 {
                            phi_plane
                        } else {
                            phi_plane + 180.0
                        },
                    );
                    let r = m.f(wo, wi).luminance() * wi.z.max(0.0);
                    let tr = t.to_radians();
                    (r * tr.sin(), r * tr.cos())
                })
                .collect();
            let label = if m.flags().is_specular() && m.f(wo, DVec3::Z).is_black() {
                format!("{name} (delta lobe)")
            } else {
                name.clone()
            };
            (label, pts)
        })
        .collect();
    let title = format!(
        "f cos, theta_i = {} deg, phi_i = {} deg, {} plane",
        a.theta_i,
        a.phi_i,
        match a.plane {
            Plane::In => "incidence",
            Plane::Out => "perpendicular",
        }
    );
    atomic_plot(
        &a.output,
        (800, 520),
        |r| draw_curves(r, &title, &curves, true, "", "f cos (1/sr)"),
        |r| draw_curves(r, &title, &curves, true, "", "f cos (1/sr)"),
    )?;
    eprintln!("isolux: wrote {}", a.output.display());
    Ok(())
}

/// Directional albedo by the material's own importance sampling.
pub fn albedo_curve(m: &Material, samples: usize) -> Vec<(f64, f64)> {
    let mut rng = Pcg32::new(1, 2);
    (0..=89)
        .map(|deg| {
            let wo = local_dir(deg as f64, 0.0);
            let mut sum = Rgb::BLACK;
            for _ in 0..samples {
                if let Some(s) = m.sample(wo, rng.next_f64(), rng.next_2d()) {
                    if s.pdf > 0.0 {
                        // Energy, not radiance: undo the 1/eta^2 radiance
                        // compression of refraction (R + T = 1 for glass).
                        sum += s.weight(s.wi.z) * (s.eta * s.eta);
                    }
                }
            }
            (deg as f64, (sum / samples as f64).luminance())
        })
        .collect()
}

fn albedo(a: AlbedoArgs) -> Result<()> {
    isolux_io::check_output(&a.output)?;
    let mats = as_brdfs(materials(&a.scene, &a.materials)?, "plotted");
    let curves: Vec<Curve> = mats
        .iter()
        .map(|(n, m)| (n.clone(), albedo_curve(m, 20_000)))
        .collect();
    println!(
        "| theta_i (deg) | {} |",
        mats.iter()
            .map(|m| m.0.as_str())
            .collect::<Vec<_>>()
            .join(" | ")
    );
    println!("|---:|{}", "---:|".repeat(mats.len()));
    for deg in (0..=80).step_by(10).chain([85, 89]) {
        let row: Vec<String> = curves
            .iter()
            .map(|c| format!("{:.4}", c.1[deg].1))
            .collect();
        println!("| {deg} | {} |", row.join(" | "));
    }
    atomic_plot(
        &a.output,
        (800, 520),
        |r| {
            draw_curves(
                r,
                "directional albedo",
                &curves,
                false,
                "theta_i (degrees)",
                "albedo",
            )
        },
        |r| {
            draw_curves(
                r,
                "directional albedo",
                &curves,
                false,
                "theta_i (degrees)",
                "albedo",
            )
        },
    )?;
    eprintln!("isolux: wrote {}", a.output.display());
    Ok(())
}

fn sphere(a: SphereArgs) -> Result<()> {
    isolux_io::check_output(&a.output)?;
    if a.size == 0 || a.size > 8192 {
        bail!("--size must lie in 1..=8192");
    }
    let (name, m) = materials(&a.scene, std::slice::from_ref(&a.material))?.remove(0);
    let img = lit_sphere(name, m, a.size, 36)?;
    isolux_io::write_image(&a.output, &img, 0.0, isolux_io::Tonemap::Reinhard)?;
    eprintln!("isolux: wrote {}", a.output.display());
    Ok(())
}

/// A unit sphere with material `m` under a point light and a dim sky,
/// `size x size` pixels, path traced with `spp` samples per pixel.
pub fn lit_sphere(name: String, m: Material, size: u32, spp: u32) -> Result<isolux_core::Image> {
    use isolux_geometry::{Aggregate, Object, Quadric};
    use isolux_render::{
        render, Camera, Environment, FilmSettings, IntegratorSettings, PointLight, RenderOptions,
        Scene,
    };
    let sphere = Object::new(Quadric::sphere(DVec3::ZERO, 1.0), vec![], None)?;
    let scene = Scene {
        camera: Camera {
            position: DVec3::new(0.0, 0.0, 3.6),
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            fov_y: 38.0,
        },
        film: FilmSettings {
            width: size,
            height: size,
            spp,
        },
        integrator: IntegratorSettings {
            max_depth: 8,
            seed: 0,
            ..Default::default()
        },
        lights: vec![PointLight {
            position: DVec3::new(3.0, 3.5, 4.0),
            intensity: Rgb::splat(30.0),
        }],
        environment: Environment::Constant(Rgb::splat(0.15)),
        materials: vec![m],
        material_names: vec![name],
        geometry: Aggregate::new(vec![sphere]),
        object_material: vec![0],
    };
    let (img, _) = render(&scene, &RenderOptions::default(), &|_, _| {})?;
    Ok(img)
}
