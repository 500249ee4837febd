//! # isolux-view
//!
//! `isolux view SCENE.toml`: an interactive window over the GPU renderer
//! (`isolux-gpu`). A winit window with a wgpu surface on the same device
//! the compute kernels run on; the central area shows the renderer's
//! accumulation buffer directly ([`display`]), an egui side panel edits
//! the scene live.
//!
//! - **Orbit, pan and zoom**: drag in the image to turn about the scene
//!   camera's `look_at` ([`orbit`]), right-drag (or Shift-drag) to pan,
//!   the wheel zooms; a double click orbits about the point under the
//!   cursor, and `F` frames the object clicked last.
//! - **Picking**: a click on an object shows its material in the panel
//!   (the CPU's exact intersection of the camera ray through the cursor).
//! - **Modes**: while the view changes (a drag, an edit, and for a quarter
//!   of a second after) each frame is the real-time mode
//!   (`isolux render --realtime`: point lights plus the prefiltered
//!   environment, `--realtime-spp` samples per pixel on the sub-pixel
//!   grid); when still, progressive path tracing adds a sample per pixel
//!   per frame up to `--max-spp`.
//! - **Live editing** of material parameters and models ([`params`]:
//!   every edit is re-read with the scene format's own checks, and a
//!   refused value shows the scene format's message), and of the point
//!   lights (moved, dimmed, added and removed; dragged by their rings in
//!   the image); exposure and tone map.
//! - **Undo and redo** of the edits (`Ctrl+Z`, `Ctrl+Shift+Z`; [`history`]).
//! - **Save**: `Ctrl+S` (or the panel's button) writes the scene file with
//!   the edits beside it as `<scene>-view-<n>.toml`, comments and layout
//!   kept (module `save`).
//! - **Screenshot**: the `P` key (or the panel's button) writes the image
//!   shown, at film resolution, to `<scene>-view-<n>.png` in the current
//!   directory.
//!
//! A scripted run (`--frames N --screenshot FILE`) draws `N` frames, saves
//! the last and exits: the CI test runs it under Xvfb on lavapipe.
//!
//! The scene's materials must all run on the GPU (the same rule as
//! `render --gpu`; docs/gpu.md lists them).
#![warn(missing_docs)]

pub mod display;
pub mod history;
pub mod orbit;
mod panel;
pub mod params;
mod save;

use anyhow::{anyhow, bail, Context as _};
use display::{Display, DisplayParams};
use isolux_gpu::{wgpu, Gpu, GpuFrame};
use isolux_io::Tonemap;
use isolux_render::{Environment, FilmSettings, Scene};
use orbit::Orbit;
use panel::{FrameInfo, UiOutcome};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::window::{Window, WindowId};

/// Which renderer the viewer draws with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Mode {
    /// Real-time while the view changes, progressive path tracing when
    /// still.
    #[default]
    Auto,
    /// Always the real-time mode.
    Realtime,
    /// Always progressive path tracing.
    Path,
}

/// Settings of a viewer session.
#[derive(Clone, Debug)]
pub struct Options {
    /// Scene file.
    pub scene: PathBuf,
    /// Window width in pixels (the side panel included).
    pub width: u32,
    /// Window height in pixels.
    pub height: u32,
    /// Samples per pixel of the real-time mode (4-25).
    pub realtime_spp: u32,
    /// Progressive path tracing stops at this many samples per pixel.
    pub max_spp: u32,
    /// Renderer choice.
    pub mode: Mode,
    /// Exposure in stops.
    pub exposure: f64,
    /// Tone map of the display and of PNG screenshots.
    pub tonemap: Tonemap,
    /// Scripted run: draw this many frames, then exit.
    pub frames: Option<u32>,
    /// Scripted run: save the last frame here (`.png` or `.exr`).
    pub screenshot: Option<PathBuf>,
}

/// The window's smallest size: the side panel's 300 pixels (at one pixel
/// per point) and an image at least 64 pixels wide and high (a narrower
/// window left the image no room, and a scripted screenshot nothing to
/// save).
const MIN_WINDOW: (u32, u32) = (364, 64);
/// The largest side: the texture size most adapters offer (the window
/// system may still open the window smaller, to fit the screen).
const MAX_WINDOW: u32 = 16384;

/// Opens the viewer and runs until the window closes (or the scripted
/// frames are drawn).
pub fn run(opts: Options) -> anyhow::Result<()> {
    if !(4..=25).contains(&opts.realtime_spp) {
        bail!(
            "--realtime-spp must lie in 4..=25 (the seed's sub-pixel grids), got {}",
            opts.realtime_spp
        );
    }
    if !(1..=FilmSettings::MAX_SPP).contains(&opts.max_spp) {
        bail!(
            "--max-spp must lie in 1..={}, got {}",
            FilmSettings::MAX_SPP,
            opts.max_spp
        );
    }
    for (flag, v, min) in [
        ("--width", opts.width, MIN_WINDOW.0),
        ("--height", opts.height, MIN_WINDOW.1),
    ] {
        if !(min..=MAX_WINDOW).contains(&v) {
            bail!("{flag} must lie in {min}..={MAX_WINDOW} pixels, got {v}");
        }
    }
    if let Some(s) = &opts.screenshot {
        if isolux_io::OutputFormat::from_path(s).is_none() {
            bail!(
                "{}: unknown screenshot format: use a .png or .exr file name",
                s.display()
            );
        }
    }
    let state = State::load(&opts)?;
    let file = opts.scene.display();
    if let Some((name, ty)) = isolux_gpu::unsupported_material(&state.scene) {
        bail!(
            "{file}: material \"{name}\" (type {ty}) does not run on the GPU yet, so `isolux view` \
             cannot show it (docs/gpu.md lists the models that do; `isolux render` renders it on \
             the CPU)"
        );
    }
    if let Some(why) = isolux_gpu::f32_shortfall(&state.scene) {
        bail!("{file}: {why}");
    }
    // What `isolux render --gpu` warns of, before the window opens: an
    // object thinner than a few of the GPU's ray offsets, and a
    // random-walk medium whose mean free path spans fewer than ten of
    // them (docs/subsurface.md, "Media too thick for the walk").
    let scene = &state.scene;
    for why in isolux_gpu::thin_object_warning(scene)
        .into_iter()
        .chain(isolux_gpu::fine_medium_warning(scene))
    {
        eprintln!("isolux: warning: {file}: {why}");
    }
    // And what `render --realtime` warns of: the viewer's frames while
    // moving are real-time ones, which render no volume.
    if let Some(why) = isolux_render::realtime::volume_left_out(scene) {
        match opts.mode {
            Mode::Path => {}
            Mode::Auto => eprintln!(
                "isolux: warning: {file}: in the real-time frames (while moving): {why}; the \
                 path-traced frames (when still) show it"
            ),
            Mode::Realtime => {
                eprintln!("isolux: warning: {file}: {why}; `--mode path` or `--mode auto` shows it")
            }
        }
    }
    check_display()?;
    #[allow(unused_mut)]
    let mut builder = EventLoop::builder();
    #[cfg(all(unix, not(target_os = "macos"), not(target_os = "ios")))]
    if std::env::var_os("WAYLAND_DISPLAY").is_none_or(|v| v.is_empty()) {
        // X11 only: winit would try Wayland first, and libwayland prints
        // errors to stderr when there is none.
        use winit::platform::x11::EventLoopBuilderExtX11;
        builder.with_x11();
    }
    let event_loop = builder.build().context("cannot open a window")?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut app = App {
        opts,
        state,
        running: None,
        error: None,
    };
    event_loop
        .run_app(&mut app)
        .context("window event loop failed")?;
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// A clear error rather than a backend panic when there is no display.
fn check_display() -> anyhow::Result<()> {
    #[cfg(all(unix, not(target_os = "macos"), not(target_os = "ios")))]
    {
        let set = |k: &str| std::env::var_os(k).is_some_and(|v| !v.is_empty());
        if !set("DISPLAY") && !set("WAYLAND_DISPLAY") {
            bail!(
                "no display: `isolux view` opens a window; set DISPLAY (X11) or WAYLAND_DISPLAY, \
                 or run it under a virtual X server (`xvfb-run isolux view ...`)"
            );
        }
    }
    Ok(())
}

/// What an undo step restores ([`history`]): the panel's scene edits.
#[derive(Clone, Debug, PartialEq)]
struct Edited {
    tables: Vec<toml::Table>,
    lights: Vec<isolux_render::PointLight>,
    light_origin: Vec<Option<usize>>,
    /// A constant environment's radiance, or a map's scale.
    environment: Result<isolux_core::Rgb, f64>,
}

impl Edited {
    fn of(tables: &[toml::Table], scene: &Scene, light_origin: &[Option<usize>]) -> Self {
        Self {
            tables: tables.to_vec(),
            lights: scene.lights.clone(),
            light_origin: light_origin.to_vec(),
            environment: match &scene.environment {
                Environment::Constant(c) => Ok(*c),
                Environment::Map(m) => Err(m.scale()),
            },
        }
    }
}

/// Where a point light is marked in the image ([`State::light_markers`]).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Marker {
    x: f64,
    y: f64,
    /// The light is in view (else the marker is on the border).
    inside: bool,
}

/// The view's camera in the image area's units (`width x height`, any
/// unit, `y` down): the renderer's [`isolux_render::CameraRig`] at the
/// nearest whole size, its film coordinates scaled to the area's.
struct ImageRig {
    rig: isolux_render::CameraRig,
    /// Film pixels per image unit, across and down.
    scale: (f64, f64),
}

impl ImageRig {
    /// The camera ray through `(x, y)`.
    fn ray(&self, x: f64, y: f64) -> isolux_core::Ray {
        self.rig.ray(x * self.scale.0, y * self.scale.1)
    }

    /// Where a point in front of the camera shows.
    fn project(&self, p: glam::DVec3) -> Option<(f64, f64)> {
        let (x, y) = self.rig.project(p)?;
        Some((x / self.scale.0, y / self.scale.1))
    }
}

/// The marker within `radius` of `(x, y)` nearest to it, and its index.
fn nearest_marker(
    markers: &[Option<Marker>],
    x: f64,
    y: f64,
    radius: f64,
) -> Option<(usize, Marker)> {
    markers
        .iter()
        .enumerate()
        .filter_map(|(i, m)| m.map(|m| (i, m, (m.x - x).hypot(m.y - y))))
        .filter(|&(_, _, d)| d <= radius)
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .map(|(i, m, _)| (i, m))
}

/// What a click in the image found ([`State::pick`]).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Pick {
    /// Index of the object in the scene (file order).
    object: usize,
    /// Index of its material.
    material: usize,
    /// The point hit.
    point: glam::DVec3,
}

/// The scene and everything the panel edits.
struct State {
    /// Undo and redo of the edits.
    history: history::History<Edited>,
    scene: Scene,
    /// The materials' tables as in the scene file (edited live).
    tables: Vec<toml::Table>,
    base_dir: PathBuf,
    /// The scene file as opened, which a save copies with the edits.
    src: String,
    path: PathBuf,
    file_name: String,
    scene_stem: String,
    /// For each light of `scene.lights`, the `[[light]]` table of the file
    /// it was read from, `None` for one added in the panel.
    light_origin: Vec<Option<usize>>,
    orbit: Orbit,
    initial_orbit: Orbit,
    /// The light a drag in the image moves, and the offset from the
    /// cursor to its marker when the drag began.
    light_drag: Option<(usize, egui::Vec2)>,
    /// Each `[[object]]` table's `name`, where it has one.
    object_names: Vec<Option<String>>,
    /// The object a click picked last (`None` after a click on the
    /// environment): the one `F` frames.
    picked: Option<usize>,
    selected: usize,
    material_error: Option<String>,
    exposure: f64,
    tonemap: Tonemap,
    /// The environment map's `scale` shown in the panel, which
    /// [`isolux_render::EnvMap::with_scale`] applies (1 for a constant
    /// environment, where it is not shown).
    env_scale: f64,
    /// Last change of view or scene.
    last_change: Instant,
    status: String,
}

impl State {
    fn load(opts: &Options) -> anyhow::Result<Self> {
        // Read once: the scene, the panel's tables and a saved copy all
        // come from the same text.
        let src = std::fs::read_to_string(&opts.scene)
            .with_context(|| format!("{}: cannot read scene file", opts.scene.display()))?;
        let base_dir = opts.scene.parent().unwrap_or(Path::new("."));
        let scene = isolux_scene::parse_str(&src, &opts.scene, base_dir)?;
        let doc: toml::Table = toml::from_str(&src)
            .with_context(|| format!("{}: invalid TOML", opts.scene.display()))?;
        let tables: Vec<toml::Table> = doc
            .get("material")
            .and_then(|v| v.as_array())
            .map(|a| a.iter().filter_map(|m| m.as_table().cloned()).collect())
            .unwrap_or_default();
        // The objects' optional names, which a click reports.
        let object_names: Vec<Option<String>> = doc
            .get("object")
            .and_then(|v| v.as_array())
            .map(|a| {
                a.iter()
                    .map(|o| o.get("name").and_then(|n| n.as_str()).map(String::from))
                    .collect()
            })
            .unwrap_or_default();
        if tables.len() != scene.materials.len() {
            bail!(
                "{}: the [[material]] tables do not match the materials read",
                opts.scene.display()
            );
        }
        let orbit = Orbit::from_camera(&scene.camera);
        let env_scale = match &scene.environment {
            Environment::Map(m) => m.scale(),
            Environment::Constant(_) => 1.0,
        };
        let light_origin: Vec<Option<usize>> = (0..scene.lights.len()).map(Some).collect();
        Ok(Self {
            history: history::History::new(Edited::of(&tables, &scene, &light_origin)),
            env_scale,
            light_origin,
            orbit,
            initial_orbit: orbit,
            tables,
            base_dir: base_dir.to_path_buf(),
            src,
            path: opts.scene.clone(),
            file_name: opts.scene.display().to_string(),
            scene_stem: opts
                .scene
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "isolux".into()),
            scene,
            object_names,
            picked: None,
            light_drag: None,
            selected: 0,
            material_error: None,
            exposure: opts.exposure,
            tonemap: opts.tonemap,
            // Still at start: path tracing right away in the auto mode.
            last_change: Instant::now() - Duration::from_secs(1),
            status: String::new(),
        })
    }

    /// The panel's edits as they stand.
    fn edited(&self) -> Edited {
        Edited::of(&self.tables, &self.scene, &self.light_origin)
    }

    /// The view's camera for an image area `width x height` ([`ImageRig`]);
    /// `None` where the orbit gives no camera.
    fn image_rig(&self, width: f64, height: f64) -> Option<ImageRig> {
        let (w, h) = (width.round().max(1.0), height.round().max(1.0));
        Some(ImageRig {
            rig: self.orbit.camera().rig(w as u32, h as u32).ok()?,
            scale: (w / width, h / height),
        })
    }

    /// What the view shows at `(x, y)` in an image `width x height` (any
    /// unit, `y` down): the nearest object the camera ray meets (the CPU's
    /// exact intersection, as in `isolux render`), its material and the
    /// point hit; `None` for the environment.
    fn pick(&self, x: f64, y: f64, width: f64, height: f64) -> Option<Pick> {
        let ray = self.image_rig(width, height)?.ray(x, y);
        let (object, hit) = self.scene.geometry.intersect(&ray, 0.0, f64::INFINITY)?;
        Some(Pick {
            object,
            material: *self.scene.object_material.get(object)?,
            point: hit.p,
        })
    }

    /// Where each point light's marker shows in an image `width x height`
    /// (`y` down), and whether the light itself is in view: a light in
    /// front of the eye but out of view is marked on the image's border
    /// (`inset` inside it), where the line from the image's centre to it
    /// leaves the image. `None` for a light behind the eye's plane.
    fn light_markers(&self, width: f64, height: f64, inset: f64) -> Vec<Option<Marker>> {
        let Some(rig) = self.image_rig(width, height) else {
            return vec![None; self.scene.lights.len()];
        };
        let (cx, cy) = (0.5 * width, 0.5 * height);
        let (hx, hy) = ((cx - inset).max(0.0), (cy - inset).max(0.0));
        self.scene
            .lights
            .iter()
            .map(|l| {
                let (x, y) = rig.project(l.position)?;
                let (dx, dy) = (x - cx, y - cy);
                let inside =
                    (0.0..=width).contains(&(cx + dx)) && (0.0..=height).contains(&(cy + dy));
                let s = (hx / dx.abs()).min(hy / dy.abs()).min(1.0);
                let s = if inside || !s.is_finite() { 1.0 } else { s };
                Some(Marker {
                    x: cx + s * dx,
                    y: cy + s * dy,
                    inside,
                })
            })
            .collect()
    }

    /// The light whose marker lies within `radius` of `(x, y)` (the
    /// nearest), with its marker, in the units of [`State::light_markers`].
    fn light_at(
        &self,
        x: f64,
        y: f64,
        width: f64,
        height: f64,
        radius: f64,
    ) -> Option<(usize, Marker)> {
        nearest_marker(&self.light_markers(width, height, radius), x, y, radius)
    }

    /// Moves light `i` to show at `(x, y)` of an image `width x height`,
    /// at the same depth along the view (in the plane through it facing
    /// the camera), its coordinates rounded to 1e-4 of the view's
    /// distance (to a power of ten: 4 decimals at a distance of 1 to 10),
    /// far finer than a pixel and short in a saved scene. Returns whether
    /// it moved.
    fn move_light(&mut self, i: usize, x: f64, y: f64, width: f64, height: f64) -> bool {
        let (Some(rig), Some(light)) = (self.image_rig(width, height), self.scene.lights.get(i))
        else {
            return false;
        };
        let [origin, forward, ..] = rig.rig.basis();
        let depth = (light.position - origin).dot(forward);
        let ray = rig.ray(x, y);
        let along = ray.dir.dot(forward);
        if !(depth > 0.0 && along > 0.0) {
            return false;
        }
        let p = origin + ray.dir * (depth / along);
        let decimals = 4 - self.orbit.distance.log10().floor() as i32;
        let p = glam::DVec3::from_array(save::round_decimals(p.to_array(), decimals));
        if !p.is_finite() || p == light.position {
            return false;
        }
        self.scene.lights[i].position = p;
        true
    }

    /// `object N` (counting the `[[object]]` tables from 1), `of M` with
    /// `of_all`, then its `name` where it has one.
    fn object_label(&self, o: usize, of_all: bool) -> String {
        let mut s = format!("object {}", o + 1);
        if of_all {
            s += &format!(" of {}", self.scene.geometry.objects().len());
        }
        if let Some(Some(n)) = self.object_names.get(o) {
            s += &format!(" \"{n}\"");
        }
        s
    }

    /// Frames the object picked last ([`Orbit::frame`]: the same view
    /// direction, its box's bounding sphere filling the view's height).
    /// Returns whether the camera moved; the status says what was framed
    /// or why not. (With nothing picked it asks for a click rather than
    /// framing every object: a bounded floor would fill the view.)
    fn frame(&mut self) -> bool {
        let objects = self.scene.geometry.objects();
        let Some(o) = self.picked.filter(|&o| o < objects.len()) else {
            self.status = "click an object first: F frames the object clicked".into();
            return false;
        };
        let (what, b) = (self.object_label(o, false), objects[o].bbox());
        if !b.is_finite() {
            self.status = format!("{what}: unbounded, nothing to frame");
            return false;
        }
        let radius = 0.5 * (b.max - b.min).length();
        if self.orbit.frame(b.center(), radius) {
            self.status = format!("framed {what}");
            true
        } else {
            self.status = format!("cannot frame {what} (radius {radius:.3e})");
            false
        }
    }

    /// A click in the image at `(x, y)` of `width x height`: the panel
    /// shows the material under the cursor, and with `focus` (a double
    /// click) the view turns to orbit about the point. Returns whether
    /// the camera moved.
    fn click(&mut self, x: f64, y: f64, width: f64, height: f64, focus: bool) -> bool {
        let Some(pick) = self.pick(x, y, width, height) else {
            self.status = "nothing under the cursor but the environment".into();
            self.picked = None;
            return false;
        };
        self.picked = Some(pick.object);
        if self.selected != pick.material {
            self.selected = pick.material;
            self.material_error = None;
        }
        let p = pick.point;
        let name = &self.scene.material_names[pick.material];
        let at = format!("({:.4}, {:.4}, {:.4})", p.x, p.y, p.z);
        if !focus {
            self.status = format!(
                "{}, material \"{name}\", at {at}",
                self.object_label(pick.object, true)
            );
            false
        } else if self.orbit.focus(p) {
            self.status = format!("orbiting about {at} (material \"{name}\")");
            true
        } else {
            self.status = format!("cannot orbit about {at}: too close or too far");
            false
        }
    }

    /// Goes back (`back`) or forward one step of the history; returns
    /// whether the scene changed.
    fn undo(&mut self, back: bool) -> bool {
        let now = self.edited();
        let step = if back {
            self.history.undo(&now)
        } else {
            self.history.redo(&now)
        };
        let Some(e) = step else {
            self.status = format!("nothing to {}", if back { "undo" } else { "redo" });
            return false;
        };
        self.restore(e);
        self.status = if back { "undone" } else { "redone" }.into();
        true
    }

    /// Puts the edits back to `e`: the materials whose tables differ are
    /// re-read (the mixes after them too), and the panel shows the first.
    fn restore(&mut self, e: Edited) {
        let changed: Vec<usize> = (0..self.tables.len())
            .filter(|&i| self.tables[i] != e.tables[i])
            .collect();
        self.tables = e.tables;
        self.material_error = None;
        for &i in &changed {
            if let Err(err) = self.rebuild_material(i) {
                self.material_error = Some(err);
            }
        }
        if let Some(&i) = changed.first() {
            self.selected = i;
        }
        self.scene.lights = e.lights;
        self.light_origin = e.light_origin;
        match (&mut self.scene.environment, e.environment) {
            (Environment::Constant(c), Ok(v)) => *c = v,
            (Environment::Map(m), Err(scale)) => match m.with_scale(scale) {
                Ok(r) => {
                    *m = r;
                    self.env_scale = scale;
                }
                Err(err) => self.status = err,
            },
            _ => {}
        }
    }

    /// Saves the scene file with the edits to the next free
    /// `<scene>-view-<n>.toml` beside it ([`save`]); returns the status
    /// line.
    fn save_scene(&self) -> String {
        let camera = (self.orbit != self.initial_orbit).then(|| self.orbit.camera());
        let edits = save::Edits {
            materials: &self.tables,
            lights: &self.scene.lights,
            light_origin: &self.light_origin,
            camera,
            environment: &self.scene.environment,
        };
        let path = save::free_path(&self.base_dir, &self.scene_stem);
        match save::edited_scene(&self.src, &edits, &self.path, &self.base_dir)
            .and_then(|text| save::write(&path, &text))
        {
            Ok(()) => format!("saved {}", path.display()),
            Err(e) => format!("scene not saved: {e}"),
        }
    }

    /// Re-reads material `i` from its table, then the mixes after it (a
    /// mix copies its components when read).
    fn rebuild_material(&mut self, i: usize) -> Result<(), String> {
        let read = |s: &Self, j: usize| {
            let label = format!("material \"{}\" (edited)", s.scene.material_names[j]);
            let m = isolux_scene::parse_material(
                &params::to_source(&s.tables[j]),
                label.as_ref(),
                &s.scene.material_names[..j],
                &s.scene.materials[..j],
                &s.base_dir,
            )
            .map_err(|e| e.to_string())?;
            if !isolux_gpu::layout::supported(&m) {
                return Err(format!(
                    "{label}: type {} does not run on the GPU",
                    m.type_name()
                ));
            }
            Ok(m)
        };
        self.scene.materials[i] = read(self, i)?;
        for j in i + 1..self.tables.len() {
            if self.tables[j].get("type").and_then(|v| v.as_str()) == Some("mix") {
                self.scene.materials[j] = read(self, j)?;
            }
        }
        Ok(())
    }
}

/// The renderer's two frames at the current film size.
struct Frames {
    realtime: GpuFrame,
    path: GpuFrame,
    film: (u32, u32),
}

/// The window and the device state.
struct Running {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    gpu: Gpu,
    display: Display,
    encode_srgb: bool,
    egui_ctx: egui::Context,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
    frames: Option<Frames>,
    /// Why `frames` is `None` when the renderer refused the scene (a
    /// scripted screenshot names it).
    refusal: Option<String>,
    /// The frame drawn last is the real-time one.
    showing_realtime: bool,
    frames_drawn: u32,
    last_present: Instant,
    frame_ms: f64,
    screenshots: u32,
    /// Draw another frame at once (egui asked for one, or the status
    /// changed after the panel was drawn).
    again: bool,
}

struct App {
    opts: Options,
    state: State,
    running: Option<Running>,
    error: Option<anyhow::Error>,
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.running.is_some() {
            return;
        }
        match Running::new(event_loop, &self.opts, &self.state.scene) {
            Ok(r) => self.running = Some(r),
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(r) = self.running.as_mut() else {
            return;
        };
        let response = r.egui_state.on_window_event(&r.window, &event);
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                r.config.width = size.width.max(1);
                r.config.height = size.height.max(1);
                r.surface.configure(r.gpu.device(), &r.config);
                r.window.request_redraw();
            }
            WindowEvent::RedrawRequested => match r.redraw(&mut self.state, &self.opts) {
                Ok(true) => {}
                Ok(false) => event_loop.exit(),
                Err(e) => {
                    self.error = Some(e);
                    event_loop.exit();
                }
            },
            _ => {
                if response.repaint {
                    r.window.request_redraw();
                }
            }
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        let Some(r) = self.running.as_ref() else {
            return;
        };
        // Keep drawing while there is work (moving, or samples to add);
        // otherwise sleep until an event.
        let busy = self.opts.frames.is_some()
            || r.again
            || r.frames
                .as_ref()
                .is_none_or(|f| r.showing_realtime || f.path.samples < self.opts.max_spp.max(1))
            || self.state.last_change.elapsed() < Duration::from_millis(400);
        if busy {
            event_loop.set_control_flow(ControlFlow::Poll);
            r.window.request_redraw();
        } else {
            event_loop.set_control_flow(ControlFlow::Wait);
        }
    }
}

impl Running {
    fn new(
        event_loop: &ActiveEventLoop,
        opts: &Options,
        scene: &isolux_render::Scene,
    ) -> anyhow::Result<Self> {
        let attrs = Window::default_attributes()
            .with_title(format!("Isolux - {}", opts.scene.display()))
            .with_inner_size(winit::dpi::PhysicalSize::new(opts.width, opts.height));
        let window = Arc::new(
            event_loop
                .create_window(attrs)
                .context("cannot open a window")?,
        );
        let instance = Gpu::instance();
        let surface = instance
            .create_surface(window.clone())
            .context("cannot draw into the window (no Vulkan, Metal or DX12 surface)")?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: Some(&surface),
        }))
        .map_err(|_| anyhow!(isolux_gpu::GpuError::NoAdapter))?;
        let mut gpu = Gpu::with_adapter(&adapter)?;
        // Objects too ill-conditioned for the f32 intersection are
        // intersected in f64, or refused where the adapter has none.
        if let Some(note) = gpu
            .precision_for(scene)
            .with_context(|| opts.scene.display().to_string())?
        {
            eprintln!("isolux: note: {}: {note}", opts.scene.display());
        }
        let size = window.inner_size();
        let mut config = surface
            .get_default_config(&adapter, size.width.max(1), size.height.max(1))
            .ok_or_else(|| anyhow!("the GPU adapter cannot present to this window"))?;
        // Prefer a format that encodes sRGB itself.
        let caps = surface.get_capabilities(&adapter);
        if let Some(f) = caps.formats.iter().find(|f| f.is_srgb()) {
            config.format = *f;
        }
        config.present_mode = wgpu::PresentMode::AutoVsync;
        surface.configure(gpu.device(), &config);
        let encode_srgb = !config.format.is_srgb();
        let display = Display::new(gpu.device(), config.format);
        let egui_ctx = egui::Context::default();
        let egui_state = egui_winit::State::new(
            egui_ctx.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(gpu.device().limits().max_texture_dimension_2d as usize),
        );
        let egui_renderer =
            egui_wgpu::Renderer::new(gpu.device(), config.format, Default::default());
        Ok(Self {
            window,
            surface,
            config,
            gpu,
            display,
            encode_srgb,
            egui_ctx,
            egui_state,
            egui_renderer,
            frames: None,
            showing_realtime: false,
            frames_drawn: 0,
            last_present: Instant::now(),
            frame_ms: 0.0,
            refusal: None,
            screenshots: 0,
            again: false,
        })
    }

    /// Uploads the scene for both modes at `film` pixels.
    fn prepare(
        &mut self,
        state: &mut State,
        opts: &Options,
        film: (u32, u32),
    ) -> anyhow::Result<()> {
        let scene = &mut state.scene;
        scene.camera = state.orbit.camera();
        scene.film = FilmSettings {
            width: film.0,
            height: film.1,
            spp: opts.max_spp,
        };
        let path = self.gpu.prepare(scene)?;
        scene.film.spp = opts.realtime_spp;
        let realtime = self.gpu.prepare_realtime(scene)?;
        self.frames = Some(Frames {
            realtime,
            path,
            film,
        });
        Ok(())
    }

    /// Draws one frame; `Ok(false)` ends a scripted run.
    fn redraw(&mut self, state: &mut State, opts: &Options) -> anyhow::Result<bool> {
        let info = FrameInfo {
            adapter: self.gpu.adapter.clone(),
            film: self.frames.as_ref().map_or((0, 0), |f| f.film),
            mode: match &self.frames {
                Some(f) if self.showing_realtime => {
                    format!("real-time, {} spp", f.realtime.samples)
                }
                Some(f) => format!("path tracing, {} / {} spp", f.path.samples, opts.max_spp),
                // Shown until an edit makes the scene renderable again.
                None => match &self.refusal {
                    Some(why) => format!("cannot render: {why}"),
                    None => "starting".into(),
                },
            },
            frame_ms: self.frame_ms,
        };
        let input = self.egui_state.take_egui_input(&self.window);
        let mut outcome = UiOutcome::default();
        let full = self
            .egui_ctx
            .run(input, |ctx| outcome = state.ui(ctx, &info));
        self.egui_state
            .handle_platform_output(&self.window, full.platform_output);
        // What egui asks to draw again at once (a click's result in the
        // panel drawn before it), as eframe does.
        self.again = full
            .viewport_output
            .get(&egui::ViewportId::ROOT)
            .is_some_and(|v| v.repaint_delay.is_zero());

        // The image area in framebuffer pixels.
        let ppp = full.pixels_per_point;
        let v = outcome.viewport;
        let area = [
            (v.min.x * ppp).round().max(0.0),
            (v.min.y * ppp).round().max(0.0),
            (v.width() * ppp).round(),
            (v.height() * ppp).round(),
        ];
        let area = [
            area[0],
            area[1],
            area[2].min(self.config.width as f32 - area[0]).max(0.0),
            area[3].min(self.config.height as f32 - area[1]).max(0.0),
        ];
        let film = (area[2] as u32, area[3] as u32);
        let film_ok = film.0 >= 1 && film.1 >= 1;
        if outcome.camera || outcome.scene {
            state.last_change = Instant::now();
        }
        if film_ok {
            let stale = self.frames.as_ref().is_none_or(|f| f.film != film);
            if stale || outcome.scene {
                self.refusal = self.prepare(state, opts, film).err().map(|e| e.to_string());
                if self.refusal.is_some() {
                    self.frames = None;
                }
            } else if outcome.camera {
                let camera = state.orbit.camera();
                if let Some(f) = self.frames.as_mut() {
                    f.path.set_camera(&self.gpu, &camera)?;
                    f.realtime.set_camera(&self.gpu, &camera)?;
                }
            }
        }

        // Render: real-time while moving, else add path samples.
        if let Some(f) = self.frames.as_mut() {
            let moving =
                outcome.dragging || state.last_change.elapsed() < Duration::from_millis(250);
            let realtime = match opts.mode {
                Mode::Realtime => true,
                Mode::Path => false,
                Mode::Auto => moving,
            };
            if realtime {
                f.realtime.run(&self.gpu, opts.realtime_spp);
            } else if f.path.samples < opts.max_spp {
                f.path.run(&self.gpu, 1);
            }
            self.showing_realtime = realtime;
        }
        // An error the GPU reported while running what was queued (out
        // of memory, say) ends the viewer with it, instead of frames that
        // never change.
        self.gpu.check()?;

        // Draw.
        let texture = match self.surface.get_current_texture() {
            Ok(t) => t,
            Err(wgpu::SurfaceError::Lost | wgpu::SurfaceError::Outdated) => {
                self.surface.configure(self.gpu.device(), &self.config);
                return Ok(true);
            }
            Err(wgpu::SurfaceError::Timeout) => return Ok(true),
            Err(e) => bail!("cannot draw into the window: {e}"),
        };
        let view = texture
            .texture
            .create_view(&wgpu::TextureViewDescriptor::default());
        let device = self.gpu.device();
        let queue = self.gpu.queue();
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [self.config.width, self.config.height],
            pixels_per_point: ppp,
        };
        let jobs = self.egui_ctx.tessellate(full.shapes, ppp);
        for (id, delta) in &full.textures_delta.set {
            self.egui_renderer.update_texture(device, queue, *id, delta);
        }
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("viewer frame"),
        });
        let extra = self
            .egui_renderer
            .update_buffers(device, queue, &mut enc, &jobs, &screen);
        {
            let mut pass = enc
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("viewer"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                })
                .forget_lifetime();
            if let (Some(f), true) = (&self.frames, film_ok && area[2] > 0.0 && area[3] > 0.0) {
                let frame = if self.showing_realtime {
                    &f.realtime
                } else {
                    &f.path
                };
                let mut flags = 0;
                if state.tonemap == Tonemap::Reinhard {
                    flags |= display::REINHARD;
                }
                if self.encode_srgb {
                    flags |= display::ENCODE_SRGB;
                }
                let params = DisplayParams {
                    scale: (2f64.powf(state.exposure) / frame.samples.max(1) as f64) as f32,
                    flags,
                    ..Default::default()
                };
                self.display
                    .draw(device, queue, &mut pass, frame, area, params);
                pass.set_viewport(
                    0.0,
                    0.0,
                    self.config.width as f32,
                    self.config.height as f32,
                    0.0,
                    1.0,
                );
            }
            self.egui_renderer.render(&mut pass, &jobs, &screen);
        }
        queue.submit(extra.into_iter().chain(Some(enc.finish())));
        self.window.pre_present_notify();
        texture.present();
        for id in &full.textures_delta.free {
            self.egui_renderer.free_texture(id);
        }
        let now = Instant::now();
        self.frame_ms = (now - self.last_present).as_secs_f64() * 1e3;
        self.last_present = now;
        self.frames_drawn += 1;

        if outcome.screenshot {
            let path = self.next_screenshot_path(state);
            match self.save(state, &path) {
                Ok(()) => state.status = format!("saved {}", path.display()),
                Err(e) => state.status = format!("screenshot failed: {e}"),
            }
            self.again = true;
        }
        if let Some(n) = opts.frames {
            if self.frames_drawn >= n {
                if let Some(path) = &opts.screenshot {
                    self.save(state, path)?;
                }
                return Ok(false);
            }
        }
        Ok(true)
    }

    fn next_screenshot_path(&mut self, state: &State) -> PathBuf {
        loop {
            self.screenshots += 1;
            let p = PathBuf::from(format!(
                "{}-view-{:03}.png",
                state.scene_stem, self.screenshots
            ));
            if !p.exists() {
                return p;
            }
        }
    }

    /// Writes the image shown at film resolution.
    fn save(&self, state: &State, path: &Path) -> anyhow::Result<()> {
        let f = self.frames.as_ref().ok_or_else(|| match &self.refusal {
            Some(why) => anyhow!("nothing rendered: {why}"),
            None => anyhow!("nothing rendered yet (the window's image area is empty)"),
        })?;
        let frame = if self.showing_realtime {
            &f.realtime
        } else {
            &f.path
        };
        let (image, _) = frame.image(&self.gpu)?;
        isolux_io::write_image(path, &image, state.exposure, state.tonemap)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gallery() -> State {
        let opts = Options {
            scene: Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/scenes/gallery.toml"),
            width: 800,
            height: 600,
            realtime_spp: 4,
            max_spp: 16,
            mode: Mode::Auto,
            exposure: 0.0,
            tonemap: Tonemap::Clamp,
            frames: None,
            screenshot: None,
        };
        State::load(&opts).unwrap()
    }

    /// A click names what the view shows under the cursor: checked against
    /// each object intersected on its own (no hierarchy) and the camera's
    /// projection; a double click orbits about the point from the same eye.
    #[test]
    fn clicks_pick_the_nearest_object_and_focus_on_it() {
        use glam::DVec3;
        let mut s = gallery();
        let (w, h) = (400.0, 300.0);
        let rig = s.orbit.camera().rig(400, 300).unwrap();
        let mut materials = std::collections::BTreeSet::new();
        let mut sky = 0;
        for j in 0..15 {
            for i in 0..20 {
                let (x, y) = ((i as f64 + 0.5) * w / 20.0, (j as f64 + 0.5) * h / 15.0);
                let ray = rig.ray(x, y);
                // The nearest of every object's own first hit.
                let nearest = s
                    .scene
                    .geometry
                    .objects()
                    .iter()
                    .enumerate()
                    .filter_map(|(k, o)| o.intersect(&ray, 0.0, f64::INFINITY).map(|h| (k, h.t)))
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                let Some(pick) = s.pick(x, y, w, h) else {
                    assert!(nearest.is_none(), "({x}, {y}): missed {nearest:?}");
                    sky += 1;
                    continue;
                };
                let (k, t) = nearest.expect("a hit where no object is");
                assert_eq!(pick.object, k, "({x}, {y})");
                assert!(((pick.point - ray.origin).length() - t).abs() < 1e-9 * (1.0 + t));
                let (px, py) = rig.project(pick.point).unwrap();
                assert!((px - x).abs() < 1e-6 && (py - y).abs() < 1e-6);
                assert_eq!(pick.material, s.scene.object_material[k]);
                materials.insert(pick.material);
            }
        }
        // The gallery's floor is a plane under every view from above.
        assert_eq!(sky, 0);
        assert!(materials.len() >= 10, "{materials:?}");

        // A click selects the material and leaves the view; a double click
        // on the same spot orbits about the point from the same eye.
        let (x, y) = (0.5 * w, 0.6 * h);
        let pick = s.pick(x, y, w, h).unwrap();
        s.selected = (pick.material + 1) % s.tables.len();
        let before = s.orbit;
        assert!(!s.click(x, y, w, h, false));
        assert_eq!((s.selected, s.orbit), (pick.material, before));
        assert!(s.status.contains(&s.scene.material_names[pick.material]));
        // The gallery names its objects; the status gives the name.
        assert_eq!(s.object_names.len(), s.scene.geometry.objects().len());
        let object = s.object_names[pick.object].clone().unwrap();
        let n = s.scene.geometry.objects().len();
        let label = format!("object {} of {n} \"{object}\", ", pick.object + 1);
        assert!(s.status.starts_with(&label), "{}", s.status);
        assert!(s.click(x, y, w, h, true));
        assert!((s.orbit.target - pick.point).length() < 1e-12);
        assert!((s.orbit.eye() - before.eye()).length() < 1e-9);
        // F frames the object picked: its box's centre becomes the target,
        // seen from the same direction, all of the box's corners in view.
        let dir = (s.orbit.eye() - s.orbit.target).normalize();
        assert!(s.frame());
        assert!(s.status.contains(&format!("\"{object}\"")), "{}", s.status);
        let b = s.scene.geometry.objects()[pick.object].bbox();
        assert!((s.orbit.target - b.center()).length() < 1e-12);
        assert!(((s.orbit.eye() - s.orbit.target).normalize() - dir).length() < 1e-12);
        let rig = s.orbit.camera().rig(300, 300).unwrap();
        for k in 0..8 {
            let corner = DVec3::new(
                if k & 1 == 0 { b.min.x } else { b.max.x },
                if k & 2 == 0 { b.min.y } else { b.max.y },
                if k & 4 == 0 { b.min.z } else { b.max.z },
            );
            let (x, y) = rig.project(corner).unwrap();
            assert!(
                (0.0..300.0).contains(&x) && (0.0..300.0).contains(&y),
                "{x} {y}"
            );
        }
        // The environment (the view turned up to the sky): nothing
        // selected, nothing moved.
        s.orbit.target = DVec3::new(0.0, 5.0, 0.0);
        s.orbit.pitch = -0.3;
        let (orbit, selected) = (s.orbit, s.selected);
        assert!(s.pick(0.5 * w, 0.5 * h, w, h).is_none());
        assert!(!s.click(0.5 * w, 0.5 * h, w, h, true));
        assert_eq!((s.orbit, s.selected), (orbit, selected));
        assert!(s.status.contains("environment"));
        // With nothing picked, F asks for a click.
        assert!(!s.frame());
        assert_eq!(s.orbit, orbit);
        assert!(s.status.contains("click an object"));
    }

    /// A light dragged by its marker follows the cursor at its depth along
    /// the view (the renderer's projection puts it under the cursor, the
    /// plane facing the camera keeps its depth), and the drag is one undo
    /// step.
    #[test]
    fn lights_dragged_in_the_image_follow_the_cursor() {
        use glam::DVec3;
        let mut s = gallery();
        let (w, h) = (640.0, 360.0);
        // A second light in view, the first the file's (out of view here).
        let target = s.orbit.target;
        s.scene.lights.push(isolux_render::PointLight {
            position: target + DVec3::new(0.5, 1.5, 0.25),
            intensity: isolux_core::Rgb::splat(4.0),
        });
        s.light_origin.push(None);
        // Its own step: a frame changing nothing ends the burst.
        s.history.observe(&s.edited());
        s.history.observe(&s.edited());
        let markers = s.light_markers(w, h, 9.0);
        let Some(Marker {
            x: mx,
            y: my,
            inside: true,
        }) = markers[1]
        else {
            panic!("{markers:?}");
        };
        // The file's light is above the view: marked on the top border,
        // the way it lies.
        let rig = s.orbit.camera().rig(640, 360).unwrap();
        let (lx, ly) = rig.project(s.scene.lights[0].position).unwrap();
        let top = markers[0].unwrap();
        assert!(
            !top.inside && ly < 0.0 && (top.y - 9.0).abs() < 1e-9,
            "{top:?}"
        );
        let along = ((top.x - 320.0) / (top.y - 180.0) - (lx - 320.0) / (ly - 180.0)).abs();
        assert!(along < 1e-9, "{top:?} against ({lx}, {ly})");
        // Dragged from its border marker, it comes into view (then back,
        // unobserved: no undo step).
        let file_light = s.scene.lights[0].position;
        assert!(s.move_light(0, top.x, top.y + 20.0, w, h));
        assert!(s.light_markers(w, h, 9.0)[0].unwrap().inside);
        s.scene.lights[0].position = file_light;
        assert_eq!(s.light_at(mx + 3.0, my - 4.0, w, h, 9.0).unwrap().0, 1);
        assert_eq!(s.light_at(mx + 9.0, my + 9.0, w, h, 9.0), None);
        let [origin, forward, ..] = rig.basis();
        let depth = |p: DVec3| (p - origin).dot(forward);
        let d0 = depth(s.scene.lights[1].position);
        for (x, y) in [(mx + 40.0, my), (mx - 120.5, my + 60.25), (20.0, 330.0)] {
            assert!(s.move_light(1, x, y, w, h));
            let p = s.scene.lights[1].position;
            let (px, py) = rig.project(p).unwrap();
            // Rounded to 1e-4 (the view's distance is 8): a hundredth
            // of a pixel here.
            assert!((px - x).abs() < 0.02 && (py - y).abs() < 0.02, "{px} {py}");
            for v in p.to_array() {
                assert!(((v * 1e4).round() - v * 1e4).abs() < 1e-6, "{p:?}");
            }
            assert!((depth(p) - d0).abs() < 1e-3 * d0);
            s.history.observe(&s.edited());
        }
        s.history.observe(&s.edited());
        // Behind the eye's plane, nothing moves; the whole drag is one step.
        assert!(!s.move_light(7, 10.0, 10.0, w, h));
        let moved = s.scene.lights[1].position;
        assert!(s.undo(true));
        assert_eq!(
            s.scene.lights[1].position,
            target + DVec3::new(0.5, 1.5, 0.25)
        );
        assert!(s.undo(false));
        assert_eq!(s.scene.lights[1].position, moved);
    }

    /// Undo puts back the materials (re-read, the mix that copies an edited
    /// component too), the lights and the environment, as loaded; redo
    /// brings the edits back; each burst of edits is one step.
    #[test]
    fn undo_and_redo_restore_the_scene_as_read() {
        let mut s = gallery();
        let start = (s.scene.materials.clone(), s.scene.lights.clone());
        let index = |name: &str| {
            s.scene
                .material_names
                .iter()
                .position(|n| n == name)
                .unwrap()
        };
        let (ggx, mix) = (index("ggx"), index("mix"));
        assert!(mix > ggx);
        // A burst: the roughness dragged over three frames, then still.
        for r in [0.2, 0.3, 0.45] {
            s.tables[ggx].insert("roughness".into(), toml::Value::Float(r));
            s.rebuild_material(ggx).unwrap();
            s.history.observe(&s.edited());
        }
        s.history.observe(&s.edited());
        // Another: a light moved and the map brightened together.
        s.scene.lights[0].position.y += 1.0;
        let Environment::Map(m) = &s.scene.environment else {
            panic!("the gallery has a map")
        };
        s.scene.environment = Environment::Map(m.with_scale(2.0).unwrap());
        s.history.observe(&s.edited());
        s.history.observe(&s.edited());
        assert_eq!(s.history.depth(), (2, 0));
        let edited = (s.scene.materials.clone(), s.scene.lights.clone());
        assert_ne!(
            edited.0[mix], start.0[mix],
            "the mix copies the ggx it holds"
        );

        assert!(s.undo(true));
        assert_eq!(s.scene.lights, start.1);
        assert_eq!(s.env_scale, 0.7);
        assert!(s.undo(true));
        assert_eq!(s.scene.materials, start.0);
        assert_eq!(s.selected, ggx);
        assert!(!s.undo(true), "nothing left");
        assert!(s.undo(false) && s.undo(false));
        assert_eq!((s.scene.materials.clone(), s.scene.lights.clone()), edited);
        let Environment::Map(m) = &s.scene.environment else {
            panic!("map lost")
        };
        assert_eq!(m.scale(), 2.0);
    }
}
