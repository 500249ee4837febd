//! The `isolux` command line: a thin layer over the Isolux library crates.
//! `main` parses flags, calls the libraries, and maps errors to exit codes
//! (0 success, 1 runtime or input error, 2 usage error).

mod bench;
mod brdf_cmd;
mod factor_cmd;
mod render_cmd;
mod sss_cmd;
mod view_cmd;
mod wave_cmd;

use clap::{Parser, Subcommand};

/// Isolux: a physically based renderer for functionally defined objects
/// (quadrics with cubic perturbations, intersected exactly).
#[derive(Parser, Debug)]
#[command(name = "isolux", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a scene file to a PNG or EXR image.
    Render(render_cmd::RenderArgs),
    /// Plot materials: lobes, directional albedo, lit spheres.
    Brdf(brdf_cmd::BrdfArgs),
    /// Subsurface scattering: measured media, dipole profiles.
    Sss(sss_cmd::SssArgs),
    /// Factor a BRDF into positive textures p(wo) q(h) p(wi) (homomorphic factorization).
    Factor(factor_cmd::FactorArgs),
    /// Micron-scale heightfields for wave optics.
    Heightfield(wave_cmd::HeightfieldArgs),
    /// Wave-optics diffraction BRDF of a heightfield.
    Wave(wave_cmd::WaveArgs),
    /// Interactive viewer: orbit, live material and light editing, real-time
    /// mode while moving, progressive path tracing when still (GPU).
    ///
    /// Keys: drag to orbit, right-drag (or Shift-drag) to pan, wheel to
    /// zoom, a click on an object shows its material in the panel, a
    /// double click orbits about the point clicked, F frames the object
    /// clicked, a light's ring drags the light, P saves a screenshot to
    /// SCENE-view-NNN.png in the current directory, Ctrl+S the edited
    /// scene to SCENE-view-NNN.toml beside the scene file, Ctrl+Z and
    /// Ctrl+Shift+Z undo and redo edits (docs/viewer.md).
    View(view_cmd::ViewArgs),
    /// Run performance benchmarks and print a table.
    Bench(bench::BenchArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(a) => render_cmd::run(a),
        Command::Brdf(a) => brdf_cmd::run(a),
        Command::Sss(a) => sss_cmd::run(a),
        Command::Factor(a) => factor_cmd::run(a),
        Command::Heightfield(a) => wave_cmd::run_heightfield(a),
        Command::Wave(a) => wave_cmd::run_wave(a),
        Command::View(a) => view_cmd::run(a),
        Command::Bench(a) => bench::run(a),
    };
    if let Err(e) = result {
        // One line: the chain of causes joined, skipping a cause that its
        // parent's message already ends with (errors that print their
        // source, like `LoadError::Read`).
        let mut msg = String::new();
        for c in e.chain() {
            let c = c.to_string();
            if msg.is_empty() {
                msg = c;
            } else if !msg.ends_with(&c) {
                msg = format!("{msg}: {c}");
            }
        }
        eprintln!("isolux: error: {msg}");
        std::process::exit(1);
    }
}
