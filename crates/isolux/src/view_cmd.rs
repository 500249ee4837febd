//! `isolux view`: the interactive viewer (crate `isolux-view`).

use crate::render_cmd::TonemapArg;
use anyhow::{bail, Result};
use clap::{Args, ValueEnum};
use isolux_io::Tonemap;
use std::path::PathBuf;

/// Renderer of the viewer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ModeArg {
    /// Real-time while the view changes, progressive path tracing when still.
    Auto,
    /// Always the real-time mode (point lights plus prefiltered environment).
    Realtime,
    /// Always progressive path tracing.
    Path,
}

/// Flags of `isolux view`.
#[derive(Args, Debug)]
pub struct ViewArgs {
    /// Scene file (TOML). Its materials must all run on the GPU (docs/gpu.md).
    pub scene: PathBuf,
    /// Window width in pixels, side panel included (364-16384).
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    /// Window height in pixels (64-16384).
    #[arg(long, default_value_t = 720)]
    pub height: u32,
    /// Samples per pixel of the real-time mode (4-25, on the sub-pixel grid).
    #[arg(long, default_value_t = 4)]
    pub realtime_spp: u32,
    /// Progressive path tracing stops at this many samples per pixel.
    #[arg(long, default_value_t = 1024)]
    pub max_spp: u32,
    /// Which renderer draws the view.
    #[arg(long, value_enum, default_value_t = ModeArg::Auto)]
    pub mode: ModeArg,
    /// Exposure in stops (display and PNG screenshots).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f64,
    /// Tone map of the display and of PNG screenshots.
    #[arg(long, value_enum, default_value_t = TonemapArg::Clamp)]
    pub tonemap: TonemapArg,
    /// Scripted run: draw this many frames, then exit (with --screenshot,
    /// save the last).
    #[arg(long)]
    pub frames: Option<u32>,
    /// Scripted run: save the last frame to this .png or .exr file.
    #[arg(long, requires = "frames")]
    pub screenshot: Option<PathBuf>,
}

pub fn run(a: ViewArgs) -> Result<()> {
    if !a.exposure.is_finite() {
        bail!("--exposure must be a finite number");
    }
    if a.frames == Some(0) {
        bail!("--frames must be at least 1");
    }
    isolux_view::run(isolux_view::Options {
        scene: a.scene,
        width: a.width,
        height: a.height,
        realtime_spp: a.realtime_spp,
        max_spp: a.max_spp,
        mode: match a.mode {
            ModeArg::Auto => isolux_view::Mode::Auto,
            ModeArg::Realtime => isolux_view::Mode::Realtime,
            ModeArg::Path => isolux_view::Mode::Path,
        },
        exposure: a.exposure,
        tonemap: match a.tonemap {
            TonemapArg::Clamp => Tonemap::Clamp,
            TonemapArg::Reinhard => Tonemap::Reinhard,
        },
        frames: a.frames,
        screenshot: a.screenshot,
    })
}
