//! `isolux factor`: homomorphic factorization of a BRDF into positive
//! textures, `f = scale * p(wo) q(h) p(wi) r(theta_h, theta_d)` (two
//! parabolic maps and a small angle table), with a held-out error report
//! against the SVD baseline. See `docs/factorization.md`.

use crate::brdf_cmd::{as_brdfs, atomic_plot, lit_sphere, local_dir, materials};
use anyhow::{bail, Context, Result};
use clap::Args;
use isolux_core::{DVec3, Image, Rgb};
use isolux_factor::{factorize, read_csv, write_dir, RunOptions, Source};
use isolux_materials::{BxdfFlags, BxdfModel, Material, Merl};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args, Debug)]
#[command(group(clap::ArgGroup::new("input").required(true).args(["material", "merl", "samples"])))]
pub struct FactorArgs {
    /// Scene file that defines the material (with --material).
    scene: Option<PathBuf>,
    /// Factor this material of the scene (its finite part, where it also
    /// has a mirror lobe; a `subsurface` medium through its local BRDF).
    #[arg(long)]
    material: Option<String>,
    /// Factor a MERL measured BRDF (.binary).
    #[arg(long)]
    merl: Option<PathBuf>,
    /// Factor scattered samples: CSV rows wo_x,wo_y,wo_z,wi_x,wi_y,wi_z,r,g,b.
    #[arg(long)]
    samples: Option<PathBuf>,
    /// Texels per side of each factor map (4..=512).
    #[arg(long, default_value_t = 32)]
    res: usize,
    /// Texels per side of the extra factor r(theta_h, theta_d) (0: none, the
    /// paper's plain p q p; default res / 4, at least 2).
    #[arg(long = "hd-res")]
    hd_res: Option<usize>,
    /// Weight of the Laplacian smoothness term.
    #[arg(long, default_value_t = isolux_factor::fit::DEFAULT_SMOOTHNESS)]
    smoothness: f64,
    /// Floor of the fit relative to each channel's largest value (1e-8 to
    /// 0.1): smaller values, zeros included, are fitted and measured as it.
    #[arg(long = "dynamic-range", default_value_t = isolux_factor::fit::DEFAULT_DYNAMIC_RANGE)]
    dynamic_range: f64,
    /// Largest polar angle of wo and wi in the fit, degrees (at most 90).
    #[arg(long = "theta-max", default_value_t = 80.0)]
    theta_max: f64,
    /// Fitting samples drawn from a material or MERL source.
    #[arg(long = "fit-samples", default_value_t = 200_000)]
    fit_samples: usize,
    /// Held-out samples for the error report (material or MERL source).
    #[arg(long = "held-out", default_value_t = 50_000)]
    held_out: usize,
    /// Largest SVD rank of the baseline (0 disables it).
    #[arg(long = "svd-rank", default_value_t = 2)]
    svd_rank: usize,
    /// Gauss-Newton iterations toward the relative error after the log fit.
    #[arg(long, default_value_t = isolux_factor::fit::FitOptions::default().refine)]
    refine: usize,
    /// Seed of the sample directions.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Skip preview.png.
    #[arg(long)]
    no_preview: bool,
    /// Output directory (p.exr, q.exr, r.exr, factors.toml, preview.png).
    #[arg(short, long)]
    output: PathBuf,
}

/// Runs `isolux factor`.
pub fn run(a: FactorArgs) -> Result<()> {
    // Flags first, so that a bad one fails before a 35 MB MERL file is read.
    let mut opts = RunOptions::default();
    opts.fit.res = a.res;
    opts.fit.smoothness = a.smoothness;
    opts.fit.refine = a.refine;
    opts.fit.hd_res = a.hd_res;
    opts.fit.theta_max_deg = a.theta_max;
    opts.fit.dynamic_range = a.dynamic_range;
    opts.samples = a.fit_samples;
    opts.held_out = a.held_out;
    opts.svd_ranks = a.svd_rank;
    opts.seed = a.seed;
    opts.fit.validate()?;
    let source = if let Some(name) = &a.material {
        let Some(scene) = &a.scene else {
            bail!("--material needs the scene file that defines it: isolux factor SCENE.toml --material {name} -o DIR");
        };
        // A `subsurface` medium has no BRDF of its own (its boundary is a
        // smooth dielectric): its local approximation is factored, as
        // `brdf plot` shows it.
        let (n, m) = as_brdfs(materials(scene, std::slice::from_ref(name))?, "factored").remove(0);
        let flags = m.flags();
        let finite = flags.contains(BxdfFlags::DIFFUSE) || flags.contains(BxdfFlags::GLOSSY);
        if !finite {
            bail!(
                "{}: material \"{n}\" is a delta ({}) material: it has no finite BRDF to factor",
                scene.display(),
                m.type_name()
            );
        }
        let mut label = format!("{n} from {}", scene.display());
        if flags.is_specular() {
            // A smooth coat over a finite lobe (`plastic` without
            // `roughness`, `subsurface_brdf`): the finite part is
            // factored; the delta lobe, which no texture holds, is named
            // and measured, never dropped silently.
            let r = delta_albedo(&m);
            eprintln!(
                "isolux: note: material \"{n}\" ({}) has a delta lobe (a mirror reflection, {:.3} of the light at normal incidence) beside its finite BRDF: the factors hold the finite part only, and a `factored` material made from them renders without that reflection",
                m.type_name(),
                r.luminance()
            );
            label.push_str(" (finite part; its delta lobe left out)");
        }
        Source::Material {
            label,
            material: Box::new(m),
        }
    } else {
        if let Some(s) = &a.scene {
            bail!("{}: a scene file is only used with --material", s.display());
        }
        if let Some(p) = &a.merl {
            eprintln!("isolux: reading {}", p.display());
            let merl = Merl::read(p).map_err(anyhow::Error::msg)?;
            if merl.missing() > 0 {
                eprintln!(
                    "isolux: {} of {} MERL entries are missing (negative): left out of the fit",
                    merl.missing(),
                    3 * isolux_materials::merl::PLANE
                );
            }
            Source::Merl {
                path: p.clone(),
                merl,
            }
        } else {
            let p = a.samples.as_ref().expect("clap requires one input");
            read_csv(p, a.theta_max)?
        }
    };
    if let Source::Samples {
        samples, outside, ..
    } = &source
    {
        eprintln!(
            "isolux: {} samples inside the domain ({outside} outside, skipped); every fifth is held out",
            samples.len()
        );
    }
    eprintln!(
        "isolux: factoring {} at {r} x {r} ...",
        source.describe(),
        r = a.res
    );
    let t0 = Instant::now();
    let (fact, report) = factorize(&source, &opts)?;
    let s = &fact.stats;
    let how = if s.cg_iterations > 0 {
        format!(
            "assembly {:.2} s, conjugate gradients {:.2} s ({} iterations), coarser fits that start them {:.2} s",
            s.assemble_s, s.solve_s, s.cg_iterations, s.coarse_s
        )
    } else {
        format!(
            "assembly {:.2} s, Cholesky and solve {:.2} s, {} factorization{}",
            s.assemble_s,
            s.solve_s,
            s.factorizations,
            if s.factorizations == 1 { "" } else { "s" }
        )
    };
    eprintln!(
        "isolux: fit {} unknowns from {} samples in {:.2} s ({how}); total with baseline {:.2} s",
        s.unknowns,
        s.samples,
        s.assemble_s + s.solve_s + s.coarse_s,
        t0.elapsed().as_secs_f64()
    );
    if s.cg_residual > 100.0 * isolux_factor::CG_TOLERANCE {
        eprintln!(
            "isolux: warning: the conjugate gradients stopped at the cap of {} iterations with relative residual {:.1e} (tolerance {:.0e}); the factors may be imprecise: raise --smoothness or --fit-samples",
            isolux_factor::CG_MAX_ITERATIONS,
            s.cg_residual,
            isolux_factor::CG_TOLERANCE
        );
    }
    let ex = s.excluded;
    if ex.iter().any(|e| *e > 0) {
        eprintln!(
            "isolux: excluded from the log fit (missing: negative or non-finite): R {} G {} B {} of {}",
            ex[0], ex[1], ex[2], s.samples
        );
    }
    let fl = s.floored;
    if fl.iter().any(|e| *e > 0) {
        eprintln!(
            "isolux: fitted at the floor ({:e} of each channel's largest value): R {} G {} B {} of {}",
            opts.fit.dynamic_range, fl[0], fl[1], fl[2], s.samples
        );
    }
    print!("{report}");
    write_dir(&a.output, &fact, &report)?;
    if !a.no_preview {
        let factored = Material::Factored(fact.material()?);
        preview(&a.output.join("preview.png"), source.material(), factored)
            .context("preview.png")?;
    }
    eprintln!(
        "isolux: wrote {}/{{p.exr, q.exr, {}factors.toml{}}}",
        a.output.display(),
        if fact.hd_res > 0 { "r.exr, " } else { "" },
        if a.no_preview { "" } else { ", preview.png" }
    );
    Ok(())
}

/// The reflectance of `m`'s delta lobes at normal incidence: the mean
/// weight `f cos / pdf` of its delta samples over 4096 stratified lobe
/// choices (a delta lobe's `pdf` is its discrete probability, so the mean
/// is the lobe's reflectance whatever the others draw).
fn delta_albedo(m: &Material) -> Rgb {
    const N: usize = 4096;
    let mut sum = Rgb::BLACK;
    for k in 0..N {
        let uc = (k as f64 + 0.5) / N as f64;
        // Directions from a rank-1 lattice: a delta lobe ignores them.
        let u = [(k as f64 * 0.618_033_988_749_895).fract(), 0.5];
        if let Some(s) = m.sample(DVec3::Z, uc, u) {
            if s.flags.is_specular() && s.pdf > 0.0 {
                sum += s.weight(s.wi.z);
            }
        }
    }
    sum * (1.0 / N as f64)
}

/// Source and factored BRDF side by side: lit spheres, then in-plane lobes
/// at 30 and 60 degrees of incidence.
fn preview(out: &std::path::Path, source: Option<Material>, factored: Material) -> Result<()> {
    crate::brdf_cmd::register_font()?;
    let size = 240;
    let src_img = source
        .clone()
        .map(|m| lit_sphere("source".into(), m, size, 16))
        .transpose()?;
    let fac_img = lit_sphere("factored".into(), factored.clone(), size, 16)?;
    let lobes = |m: &Material| -> Vec<Vec<(f64, f64)>> {
        [30.0, 60.0]
            .iter()
            .map(|&ti| {
                let wo = local_dir(ti, 0.0);
                (0..=360)
                    .map(|k| {
                        let t = -90.0 + k as f64 * 0.5;
                        let wi = local_dir(t.abs(), if t >= 0.0 { 180.0 } else { 0.0 });
                        (t, m.f(wo, wi).luminance() * wi.z.max(0.0))
                    })
                    .collect()
            })
            .collect()
    };
    let src_lobes = source.as_ref().map(lobes);
    let fac_lobes = lobes(&factored);
    let draw = |root: DrawingArea<BitMapBackend, Shift>| -> Result<()> {
        let e = |e: DrawingAreaErrorKind<_>| anyhow::anyhow!("plot: {e:?}");
        root.fill(&WHITE).map_err(e)?;
        let (top, bottom) = root.split_vertically(300);
        let (left, right) = top.split_horizontally(400);
        let blit = |area: &DrawingArea<BitMapBackend, Shift>,
                    img: Option<&Image>,
                    title: &str|
         -> Result<()> {
            area.draw(&Text::new(title, (20, 10), ("sans-serif", 18)))
                .map_err(e)?;
            match img {
                Some(img) => {
                    let px = isolux_io::to_srgb8(img, 0.0, isolux_io::Tonemap::Reinhard);
                    for y in 0..img.height as i32 {
                        for x in 0..img.width as i32 {
                            let k = 3 * (y as usize * img.width as usize + x as usize);
                            area.draw_pixel(
                                (80 + x, 40 + y),
                                &RGBColor(px[k], px[k + 1], px[k + 2]),
                            )
                            .map_err(e)?;
                        }
                    }
                }
                None => {
                    area.draw(&Text::new(
                        "scattered samples: no direct rendering",
                        (20, 140),
                        ("sans-serif", 15),
                    ))
                    .map_err(e)?;
                }
            }
            Ok(())
        };
        blit(&left, src_img.as_ref(), "source")?;
        blit(&right, Some(&fac_img), "factored p(wo) q(h) p(wi)")?;
        let ymax = src_lobes
            .iter()
            .flatten()
            .chain(&fac_lobes)
            .flatten()
            .map(|p| p.1)
            .fold(0.0f64, f64::max)
            .max(1e-6)
            * 1.1;
        let mut chart = ChartBuilder::on(&bottom)
            .caption(
                "f cos in the plane of incidence (theta_i = 30, 60 deg)",
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(60)
            .build_cartesian_2d(-90.0..90.0, 0.0..ymax)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("theta_o (degrees, mirror side positive)")
            .y_desc("f cos (1/sr)")
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(e)?;
        let styles = [
            ("source", RGBColor(20, 20, 20)),
            ("factored", RGBColor(210, 40, 40)),
        ];
        for (set, (name, col)) in [src_lobes.as_ref(), Some(&fac_lobes)].iter().zip(styles) {
            let Some(set) = set else { continue };
            for (k, pts) in set.iter().enumerate() {
                let c = col;
                chart
                    .draw_series(LineSeries::new(pts.iter().cloned(), c.stroke_width(2)))
                    .map_err(e)?
                    .label(format!("{name}, theta_i = {}", [30, 60][k]))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c));
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(e)?;
        root.present().map_err(e)?;
        Ok(())
    };
    atomic_plot(out, (800, 640), draw, |_| {
        bail!("preview.png must be a PNG")
    })
}
