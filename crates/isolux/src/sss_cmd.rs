//! `isolux sss`: subsurface scattering tables and plots.

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use isolux_materials::subsurface::random_walk::radial_profile;
use isolux_materials::subsurface::{Dipole, Medium, MEDIA};
use plotters::prelude::*;
use std::path::PathBuf;

/// Subsurface scattering tools.
#[derive(Args, Debug)]
pub struct SssArgs {
    #[command(subcommand)]
    command: SssCommand,
}

#[derive(Subcommand, Debug)]
enum SssCommand {
    /// Print the named measured media (Jensen et al. 2001).
    Media,
    /// Plot R_d(r) per channel: the dipole against a random walk.
    Profile(ProfileArgs),
}

#[derive(Args, Debug)]
struct ProfileArgs {
    /// Named medium (see `isolux sss media`).
    #[arg(long)]
    medium: String,
    /// Millimetres per plot unit (the plot's r axis is in mm / scale).
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
    /// Photons per channel for the random walk (at most 1e8: about a
    /// minute on 2 cores).
    #[arg(long, default_value_t = 200_000)]
    photons: usize,
    /// Output image: .png or .svg.
    #[arg(short, long)]
    output: PathBuf,
}

/// Runs `isolux sss`.
pub fn run(a: SssArgs) -> Result<()> {
    match a.command {
        SssCommand::Media => {
            println!("| medium | sigma_s' R G B (1/mm) | sigma_a R G B (1/mm) | eta | R_d R G B (dipole) |");
            println!("|---|---|---|---:|---|");
            for m in MEDIA {
                let rd: Vec<String> = (0..3)
                    .map(|c| {
                        format!(
                            "{:.3}",
                            Dipole::new(m.sigma_s_reduced[c], m.sigma_a[c], m.eta).total()
                        )
                    })
                    .collect();
                println!(
                    "| {} | {:?} | {:?} | {} | {} |",
                    m.name,
                    m.sigma_s_reduced,
                    m.sigma_a,
                    m.eta,
                    rd.join(" ")
                );
            }
            Ok(())
        }
        SssCommand::Profile(p) => profile(p),
    }
}

fn profile(a: ProfileArgs) -> Result<()> {
    isolux_io::check_output(&a.output)?;
    let m = Medium::by_name(&a.medium).with_context(|| {
        format!(
            "unknown medium \"{}\" (valid: {})",
            a.medium,
            Medium::names().join(", ")
        )
    })?;
    if !(a.scale > 0.0 && a.scale.is_finite()) {
        bail!("--scale must be a positive number of millimetres per unit");
    }
    if a.photons == 0 {
        bail!("--photons must be at least 1");
    }
    // 2e6 photons take 1.5 s on one core: 1e8 about a minute, the 2^64 - 1
    // a typo can ask for, forever.
    const MAX_PHOTONS: usize = 100_000_000;
    if a.photons > MAX_PHOTONS {
        bail!(
            "--photons {}: at most {MAX_PHOTONS} photons per channel (about a minute)",
            a.photons
        );
    }
    crate::brdf_cmd::register_font()?;
    // r range: 12 mean free paths of the most translucent channel.
    let mfp = (0..3)
        .map(|c| 1.0 / (m.sigma_s_reduced[c] + m.sigma_a[c]))
        .fold(0.0f64, f64::max);
    let rmax = 12.0 * mfp;
    let bins = 40;
    let edges: Vec<f64> = (0..=bins).map(|i| rmax * i as f64 / bins as f64).collect();
    let colours = [
        RGBColor(210, 30, 30),
        RGBColor(20, 150, 40),
        RGBColor(30, 70, 210),
    ];
    let mut curves = vec![];
    for c in 0..3 {
        let d = Dipole::new(m.sigma_s_reduced[c], m.sigma_a[c], m.eta);
        let line: Vec<(f64, f64)> = (1..=400)
            .map(|i| {
                let r = rmax * i as f64 / 400.0;
                (r / a.scale, d.r_d(r).max(1e-12))
            })
            .collect();
        let (total, hist) = radial_profile(
            m.sigma_s_reduced[c],
            m.sigma_a[c],
            m.eta,
            a.photons,
            &edges,
            7 + c as u64,
        );
        let pts: Vec<(f64, f64)> = hist
            .iter()
            .enumerate()
            .filter(|(_, v)| **v > 0.0)
            .map(|(i, v)| (0.5 * (edges[i] + edges[i + 1]) / a.scale, *v))
            .collect();
        eprintln!(
            "channel {}: total diffuse reflectance dipole {:.4}, random walk {:.4}",
            ["R", "G", "B"][c],
            d.total(),
            total
        );
        curves.push((line, pts, colours[c]));
    }
    let ymax = curves
        .iter()
        .flat_map(|c| c.0.iter().map(|p| p.1))
        .fold(1e-9f64, f64::max)
        * 2.0;
    let ymin = ymax * 1e-6;
    let draw = |root: DrawingArea<BitMapBackend, plotters::coord::Shift>| -> Result<()> {
        draw_profile(root, &a.medium, &curves, rmax / a.scale, ymin, ymax)
    };
    let draw_svg = |root: DrawingArea<SVGBackend, plotters::coord::Shift>| -> Result<()> {
        draw_profile(root, &a.medium, &curves, rmax / a.scale, ymin, ymax)
    };
    crate::brdf_cmd::atomic_plot(&a.output, (800, 520), draw, draw_svg)?;
    eprintln!("isolux: wrote {}", a.output.display());
    Ok(())
}

type ProfileCurve = (Vec<(f64, f64)>, Vec<(f64, f64)>, RGBColor);

fn draw_profile<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    medium: &str,
    curves: &[ProfileCurve],
    xmax: f64,
    ymin: f64,
    ymax: f64,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("plot: {e:?}");
    root.fill(&WHITE).map_err(e)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("R_d(r), {medium}: dipole (lines) and random walk (dots)"),
            ("sans-serif", 20),
        )
        .margin(14)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..xmax, (ymin..ymax).log_scale())
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("r (mm / scale)")
        .y_desc("R_d (1/mm^2)")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    for (i, (line, pts, c)) in curves.iter().enumerate() {
        let c = *c;
        chart
            .draw_series(LineSeries::new(line.iter().copied(), c.stroke_width(2)))
            .map_err(e)?
            .label(["red", "green", "blue"][i])
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        chart
            .draw_series(pts.iter().map(|p| Circle::new(*p, 3, c.filled())))
            .map_err(e)?;
    }
    chart
        .configure_series_labels()
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}
