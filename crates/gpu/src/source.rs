//! The kernels' WGSL source and its variants: the constants generated
//! from Rust ([`prelude`]), the intersection in f32 or f64
//! ([`Precision`]), the files of the path tracer ([`RENDER_FILES`]) and
//! the code a scene's kernels carry ([`Features`]); and the SPIR-V that
//! naga writes from a source where a probe or a statistic asks for it
//! ([`probe_spirv`], [`kernel_spirv`]). The device is in `lib.rs`, its
//! modules and pipelines in `kernels.rs`, the dispatches in `render.rs`.

use crate::layout::{self, GpuScene};
use crate::{
    render, ENV_CONSTANT, ENV_MAP, LINEAR_CULL, MASK_CANDIDATES, MASK_LIGHTS, MAX_CANDIDATES,
    MAX_SUBDIVISIONS, MIN_WIDTH, MISS, NO_ROOT, SPAWN_OFFSET, SPAWN_OFFSET_WORLD, WF_BINS,
    WORKGROUP_SIZE,
};

/// WGSL constants generated from the Rust values of the crate root and
/// the tags of [`layout`].
pub fn prelude() -> String {
    use isolux_materials::BxdfFlags as F;
    let mut s = format!(
        "const WORKGROUP_SIZE: u32 = {WORKGROUP_SIZE}u;\n\
         const MISS = {MISS:?};\n\
         const NO_ROOT = {NO_ROOT:e};\n\
         const MIN_WIDTH = {:e};\n\
         const MAX_SUBDIVISIONS: i32 = {MAX_SUBDIVISIONS};\n\
         const MAX_CANDIDATES: u32 = {MAX_CANDIDATES}u;\n\
         const MASK_CANDIDATES: u32 = {MASK_CANDIDATES}u;\n\
         const MASK_LIGHTS: u32 = {MASK_LIGHTS}u;\n\
         const LINEAR_CULL: u32 = {LINEAR_CULL}u;\n\
         const NO_NODE: u32 = {}u;\n\
         const SPAWN_OFFSET: f32 = {SPAWN_OFFSET:e};\n\
         const SPAWN_OFFSET_WORLD: f32 = {SPAWN_OFFSET_WORLD:e};\n\
         const ENV_CONSTANT: u32 = {ENV_CONSTANT}u;\n\
         const ENV_MAP: u32 = {ENV_MAP}u;\n\
         const LOD_BIAS: f32 = {:?};\n\
         const TILE: u32 = {}u;\n\
         const TILE_LIST_MAX: u32 = {}u;\n\
         const TILE_STRIDE: u32 = {}u;\n",
        MIN_WIDTH as f64,
        layout::NO_NODE,
        isolux_render::realtime::LOD_BIAS as f32,
        render::TILE,
        render::TILE_LIST_MAX,
        render::TILE_LIST_MAX + 1
    );
    s += &format!(
        "const MAX_MEDIUM_EVENTS: u32 = {}u;\nconst WF_BINS: u32 = {WF_BINS}u;\n",
        isolux_render::integrator::MAX_MEDIUM_EVENTS
    );
    s += &format!(
        "const WAVE_LEAF: i32 = {};\n\
         const WAVE_MAX_COMB: u32 = {}u;\n\
         const WAVE_WIDE_LOBE: f32 = {:?};\n\
         const WAVE_KMIN: f32 = {:?};\n\
         const WAVE_KMAX: f32 = {:?};\n",
        isolux_wave::gabor::LEAF,
        isolux_materials::wave::MAX_WAVELENGTHS,
        isolux_wave::gabor::WIDE_LOBE as f32,
        (1.0 / isolux_wave::spectral::LAMBDA_MAX_UM) as f32,
        (1.0 / isolux_wave::spectral::LAMBDA_MIN_UM) as f32,
    );
    for (name, v) in layout::tag::ALL
        .iter()
        .chain(&layout::fresnel_kind::ALL)
        .chain(&layout::distribution::ALL)
    {
        s += &format!("const {name}: u32 = {v}u;\n");
    }
    for (name, f) in [
        ("FLAG_REFLECTION", F::REFLECTION),
        ("FLAG_TRANSMISSION", F::TRANSMISSION),
        ("FLAG_DIFFUSE", F::DIFFUSE),
        ("FLAG_GLOSSY", F::GLOSSY),
        ("FLAG_SPECULAR", F::SPECULAR),
    ] {
        s += &format!("const {name}: u32 = {}u;\n", f.0);
    }
    s
}

/// Floating-point precision of the GPU intersection (`geometry.wgsl`
/// computes in an alias `real`).
///
/// Decision (docs/gpu.md, measured there): f32 is the default everywhere.
/// Each segment is reparameterized to `s in [0, 1]`, which keeps the
/// degree-6 polynomial well conditioned in f32, and the conformance suite
/// bounds its error against the CPU's f64; f64 (where the adapter offers
/// `SHADER_F64`) is available for comparison and for scenes that need it
/// (`isolux bench gpu --f64`, [`Gpu::set_precision`](crate::Gpu::set_precision)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Precision {
    /// 32-bit floats (every adapter).
    #[default]
    F32,
    /// 64-bit floats (adapters with `wgpu::Features::SHADER_F64`).
    F64,
}

impl Precision {
    /// The WGSL scalar type.
    pub fn wgsl(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
}

/// The longest stretch of a ray that `object_hit` walks in f32
/// (`REAL_SPAN` in `geometry.wgsl`): a segment's polynomial is built in
/// the segment's own parameter, its coefficients scaled by its length to
/// the power of their degree, so a quadric's over a span of 1e30 (a ray
/// to `t_max = 3e38` through an object unbounded along it: an infinite
/// slab, cylinder or cone) overflowed f32 and its hits were lost (a
/// lamp's light reached under an infinite slab through every ray; every
/// upward ray of `conformance.rs`'s slab test missed it at `t_max` 1e30,
/// 3884 of 4000 at 1e20). 1e15 keeps a quadric's coefficients within
/// f32 (`l^2` 1e30) while a hit beyond it, 1e15 units from the camera,
/// is at the horizon; f64 walks the whole ray.
pub const REAL_SPAN_F32: f64 = 1e15;

/// `geometry.wgsl` computing in `precision` (the alias `real`, its
/// machine epsilon `REAL_EPS` and the longest span walked, `REAL_SPAN`).
pub fn geometry_source(precision: Precision) -> String {
    let (eps, span) = match precision {
        Precision::F32 => (f32::EPSILON as f64, REAL_SPAN_F32),
        Precision::F64 => (f64::EPSILON, NO_ROOT as f64),
    };
    format!(
        "alias real = {};\nconst REAL_EPS: real = {eps:e};\nconst REAL_SPAN: real = {span:e};\n",
        precision.wgsl()
    ) + include_str!("shaders/geometry.wgsl")
}

/// The intersection kernel with its prelude (f32).
pub fn intersect_source() -> String {
    intersect_source_with(Precision::F32)
}

/// The intersection kernel computing in `precision` (with the candidate
/// list).
pub fn intersect_source_with(precision: Precision) -> String {
    prelude()
        + &list_source(true)
        + &geometry_source(precision)
        + include_str!("shaders/intersect.wgsl")
}

/// The WGSL constant `CANDIDATE_LIST` (whether an object may list its
/// candidates).
fn list_source(list: bool) -> String {
    format!("const CANDIDATE_LIST: bool = {list};\n")
}

/// The material conformance kernel with its prelude.
pub fn material_eval_source() -> String {
    prelude()
        + &models_source(Features::ALL)
        + include_str!("shaders/materials.wgsl")
        + include_str!("shaders/wave.wgsl")
        + include_str!("shaders/material_eval.wgsl")
}

/// The path tracer with its prelude (f32 intersection).
pub fn render_source() -> String {
    render_source_with(Precision::F32)
}

/// The path tracer and real-time kernels, intersecting in `precision`,
/// with every scene feature compiled in ([`Features::ALL`]).
pub fn render_source_with(precision: Precision) -> String {
    render_source_variant(precision, Features::ALL)
}

/// The code the render kernels (`render.wgsl`, `realtime.wgsl`) carry:
/// the material models a scene uses, and with them the optional parts of
/// the integrator. Each set is its own shader module and kernels,
/// compiled on first use and kept; a frame picks the smallest set that
/// covers its scene ([`Features::of`]).
///
/// Decision: specialize rather than branch at run time. NIR and NVIDIA's
/// compiler inline every WGSL function at every call site, so code that a
/// scene never reaches still costs compile time and registers for the
/// whole kernel: on an H100 the path tracer went from 441 to 647 ms per
/// gallery frame when the subsurface integrator joined it (c7c9a78,
/// docs/benchmarks.md), although the gallery has no medium. Lavapipe
/// runs both sides of every branch under a lane mask, so there it also
/// costs time: a diffuse-only scene renders 1.2-1.6x faster with the
/// diffuse model alone (docs/gpu.md, "Kernels specialized to the scene").
/// `isolux bench gpu --general` times the general kernels beside the
/// specialized ones.
///
/// Two models switch whole parts of the integrator on: `wave` its
/// placement and evaluation code (`wave.wgsl`, else `wave_stub.wgsl`),
/// `subsurface` the subsurface integrator (`SUBSURFACE` in the render kernels:
/// free flights and scattering in a random-walk medium, the dipole's entry
/// points and single scattering, a boundary's mirrored environment), which
/// builds the two internal lobes `SSS_SINGLE_LOBE` and `SSS_ENTRY_LOBE`.
///
/// The intersection's one private array, the candidate list, is left out
/// where the scene does not need it (`list`): private arrays are the bulk
/// of its registers on a GPU compiler that keeps them in registers (RADV:
/// the gallery's path tracer spilled 51 VGPRs with the list, 10 without),
/// and naga clears them at every invocation (docs/gpu.md, "Register
/// pressure"). The hierarchies and the root isolation need no stack.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Features {
    /// Bit `1 << tag` for each material tag ([`layout::tag`]) whose code
    /// the kernels carry (`MODELS` in the WGSL; `has_model` in
    /// `materials.wgsl`).
    pub models: u32,
    /// The run-time-indexed list of candidate perturbations
    /// (`CANDIDATE_LIST` in the WGSL), which only an object of more than
    /// [`MASK_CANDIDATES`] perturbations needs; without it every object
    /// keeps its candidates as a bit mask in a register.
    pub list: bool,
    /// Shadow rays traced in the shading loop (`MANY_LIGHTS` in the WGSL),
    /// which only a scene of more than [`MASK_LIGHTS`] point lights needs:
    /// the shadow rays of the first [`MASK_LIGHTS`] are traced before the
    /// vertex is shaded, their answers kept as a bit mask (`trace_shadows`
    /// in `direct.wgsl`), so that the shading state is not live across
    /// an intersection.
    pub many_lights: bool,
    /// Camera rays test their 8 x 8 pixel tile's list of objects instead
    /// of walking the object hierarchy each (`TILE_LISTS` in the WGSL;
    /// `cull_tiles` and `use_tile` in `camera.wgsl`). The same hits either
    /// way. On by default on GPUs, off on CPU drivers (lavapipe), where
    /// the list's code, run under an empty lane mask by every other ray,
    /// costs more than the camera rays save (docs/gpu.md, "Tile lists").
    pub tiles: bool,
    /// Point lights' shadow rays that pass null boundaries
    /// (`NULL_BOUNDARIES` in the WGSL; `shadow_transmittance` in
    /// `media.wgsl`), which only a scene with a random-walk medium of
    /// the index around it needs (`Scene::may_have_null_boundaries`):
    /// without it a shadow ray is one occlusion test, and the loop of
    /// nearest hits is left out (lavapipe: the dipole example's path
    /// tracer 1.15x slower with it).
    pub null_boundaries: bool,
    /// Point lights above a random-walk medium bounded by a plane (the
    /// sun above the sea) lighting its inside by refraction through the
    /// plane (`REFRACTION` in the WGSL; `refraction` in `subsurface.wgsl`,
    /// [`refracted_media`](crate::refracted_media)).
    pub refraction: bool,
    /// Point lights refracted into random-walk media through curved
    /// boundaries by manifold next-event estimation (`MANIFOLD` in the
    /// WGSL; `manifold_refraction` in `manifold.wgsl`), which only a scene
    /// with a point light and a curved random-walk medium needs, with
    /// `integrator.refracted_lights = "manifold"` (it comes with
    /// [`Features::refraction`]). Without it a scene whose lamps refract
    /// through flat boundaries alone leaves the solve out (RADV: the
    /// wavefront step of a scene with the solve is 43% larger).
    pub manifold: bool,
    /// Point lights through glass objects by manifold next-event
    /// estimation over both crossings (`CAUSTICS` in the WGSL; `caustic`
    /// in `manifold.wgsl`), which only a scene with
    /// `integrator.caustics = "manifold"`, a point light and a
    /// `dielectric` material needs.
    pub caustics: bool,
}

impl Features {
    /// Every model and the candidate list: runs any scene the GPU
    /// supports.
    pub const ALL: Features = Features {
        models: (1 << layout::tag::ALL.len()) - 1,
        list: true,
        many_lights: true,
        tiles: true,
        null_boundaries: true,
        refraction: true,
        manifold: true,
        caustics: true,
    };
    /// No material code at all (what the AOV kernel reaches) and no
    /// candidate list.
    pub const NONE: Features = Features {
        models: 0,
        list: false,
        many_lights: false,
        tiles: false,
        null_boundaries: false,
        refraction: false,
        manifold: false,
        caustics: false,
    };

    /// The code `materials` need: each record's model (a mix's leaves are
    /// records of their own), and the internal lobes of the subsurface
    /// integrator with a `subsurface` material; with the candidate list
    /// and the shadow rays of many lights ([`Features::fit_to`] fits them
    /// to a scene).
    pub fn of(materials: &[layout::GpuMaterial]) -> Self {
        let mut models = materials.iter().fold(0u32, |m, r| m | bit(r.tag[0]));
        if models & bit(layout::tag::SUBSURFACE) != 0 {
            models |= bit(layout::tag::SSS_SINGLE_LOBE) | bit(layout::tag::SSS_ENTRY_LOBE);
        }
        Features {
            models: models & Self::ALL.models,
            list: true,
            many_lights: true,
            tiles: true,
            null_boundaries: true,
            refraction: true,
            manifold: true,
            caustics: true,
        }
    }

    /// `self` with the candidate list only if an object of `scene` has
    /// more than [`MASK_CANDIDATES`] perturbations, and the shadow rays of
    /// many lights only if it has more than [`MASK_LIGHTS`] point lights.
    pub fn fit_to(self, scene: &GpuScene, lights: usize) -> Self {
        Features {
            list: scene.objects.iter().any(|o| o.range[1] > MASK_CANDIDATES),
            many_lights: lights > MASK_LIGHTS as usize,
            ..self
        }
    }

    /// Whether the kernels carry model `tag`.
    pub fn has(self, tag: u32) -> bool {
        self.models & bit(tag) != 0
    }

    /// The `wave` material's code.
    pub fn wave(self) -> bool {
        self.has(layout::tag::WAVE)
    }

    /// The sorted wavefront traces each hit's shadow rays in a kernel of
    /// their own, `trace_shadow`, before `trace_shade` (`SHADOWS_AHEAD`
    /// in `wavefront.wgsl`, which this mirrors): kernels of at most
    /// [`MASK_LIGHTS`] lights, without the candidate list, caustics or
    /// the subsurface integrator.
    pub fn shadows_ahead(self) -> bool {
        !self.many_lights && !self.list && !self.caustics && !self.subsurface()
    }

    /// The subsurface integrator.
    pub fn subsurface(self) -> bool {
        self.has(layout::tag::SUBSURFACE)
    }

    /// Whether kernels built with `self` run everything `needed` asks for
    /// (tile lists or not: both find the same hits).
    pub fn covers(self, needed: Features) -> bool {
        needed.models & !self.models == 0
            && (self.list || !needed.list)
            && (self.many_lights || !needed.many_lights)
            && (self.null_boundaries || !needed.null_boundaries)
            && (self.refraction || !needed.refraction)
            && (self.manifold || !needed.manifold)
            && (self.caustics || !needed.caustics)
    }

    /// The part of `self` that an entry point of the render module
    /// reaches: `main` and `trace` (the path tracers) all of it;
    /// `realtime` all but the subsurface integrator's internal lobes,
    /// which it never builds, and with `subsurface` the code of
    /// `subsurface_brdf`, the local approximation it shades a medium with
    /// (`sss_local_brdf`; a `subsurface` leaf of a mix, which only the
    /// library API builds, is still its smooth boundary there);
    /// `aov_main` no material code (first hits and
    /// albedos). Every entry keeps the candidate list. Kernels that differ
    /// only in code their entry never reaches are one kernel, compiled
    /// once.
    pub(crate) fn reached_by(self, entry: &str) -> Features {
        use layout::tag::{SSS_ENTRY_LOBE, SSS_SINGLE_LOBE, SUBSURFACE, SUBSURFACE_BRDF};
        match entry {
            "main" | "trace" | "trace_last" | "trace_shadow" | "trace_shade" => self,
            "realtime" => {
                let mut models = self.models & !(bit(SSS_SINGLE_LOBE) | bit(SSS_ENTRY_LOBE));
                if self.has(SUBSURFACE) {
                    models |= bit(SUBSURFACE_BRDF);
                }
                Features { models, ..self }
            }
            _ => Features { models: 0, ..self },
        }
    }
}

/// The bit of material tag `tag` in [`Features::models`] (0 for a tag
/// beyond them).
fn bit(tag: u32) -> u32 {
    1u32.checked_shl(tag).unwrap_or(0)
}

/// "all", "none", the models by name (`diffuse+dielectric`) up to four,
/// else their count with the integrator's optional parts
/// (`14 models`, `9 models with wave+subsurface`); then, for kernels
/// fitted to a scene, the candidate list, the shadow rays of many lights
/// and the camera rays' tile lists where there are (`diffuse`, `ggx,
/// candidate list`, `diffuse, many lights`, `diffuse, tile lists`; "all"
/// stands for every model, with or without them).
/// The internal lobes go unnamed: they come with `subsurface`.
impl std::fmt::Display for Features {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        use layout::tag::{SSS_ENTRY_LOBE, SSS_SINGLE_LOBE};
        if *self != Features::ALL
            && (self.list
                || self.many_lights
                || self.tiles
                || self.null_boundaries
                || self.refraction
                || self.manifold
                || self.caustics)
        {
            let models = Features {
                list: false,
                many_lights: false,
                tiles: false,
                null_boundaries: false,
                refraction: false,
                manifold: false,
                caustics: false,
                ..*self
            };
            write!(f, "{models}")?;
            if self.list {
                f.write_str(", candidate list")?;
            }
            if self.many_lights {
                f.write_str(", many lights")?;
            }
            if self.tiles {
                f.write_str(", tile lists")?;
            }
            if self.null_boundaries {
                f.write_str(", null boundaries")?;
            }
            if self.refraction {
                f.write_str(", refracted lights")?;
            }
            if self.manifold {
                f.write_str(", manifold lights")?;
            }
            if self.caustics {
                f.write_str(", caustics")?;
            }
            return Ok(());
        }
        if self.models == Features::ALL.models {
            return f.write_str("all");
        }
        let names: Vec<String> = layout::tag::ALL
            .iter()
            .filter(|(_, t)| self.has(*t) && *t != SSS_SINGLE_LOBE && *t != SSS_ENTRY_LOBE)
            .map(|(n, _)| n.trim_start_matches("MAT_").to_ascii_lowercase())
            .collect();
        match names.len() {
            0 => f.write_str("none"),
            1..=4 => f.write_str(&names.join("+")),
            n => {
                write!(f, "{n} models")?;
                let parts: Vec<&str> = [(self.wave(), "wave"), (self.subsurface(), "subsurface")]
                    .iter()
                    .filter(|(on, _)| *on)
                    .map(|(_, p)| *p)
                    .collect();
                if !parts.is_empty() {
                    write!(f, " with {}", parts.join("+"))?;
                }
                Ok(())
            }
        }
    }
}

/// The WGSL constant `MODELS` of `features` (`has_model` in
/// `materials.wgsl` tests it; a constant, so the driver drops the code of
/// every model left out).
fn models_source(features: Features) -> String {
    format!("const MODELS: u32 = {:#x}u;\n", features.models)
}

/// The render kernels' source with the code of `features` only: the
/// material models (`MODELS`), the `wave` material's code (else
/// `wave_stub.wgsl`: scenes without it compile a much smaller kernel) and
/// the subsurface integrator's (the constant `SUBSURFACE`, which turns its
/// branches into dead code that the driver drops).
pub fn render_source_variant(precision: Precision, features: Features) -> String {
    prelude()
        + &models_source(features)
        + &list_source(features.list)
        + &geometry_source(precision)
        + include_str!("shaders/materials.wgsl")
        + if features.wave() {
            include_str!("shaders/wave.wgsl")
        } else {
            include_str!("shaders/wave_stub.wgsl")
        }
        + &format!("const SUBSURFACE: bool = {};\n", features.subsurface())
        + &format!("const MANY_LIGHTS: bool = {};\n", features.many_lights)
        + &format!("const TILE_LISTS: bool = {};\n", features.tiles)
        + &format!(
            "const NULL_BOUNDARIES: bool = {};\n",
            features.null_boundaries
        )
        + &format!("const REFRACTION: bool = {};\n", features.refraction)
        + &format!("const MANIFOLD: bool = {};\n", features.manifold)
        + &format!("const CAUSTICS: bool = {};\n", features.caustics)
        + RENDER_WGSL
        + include_str!("shaders/realtime.wgsl")
}

/// [`RENDER_FILES`] and [`RENDER_WGSL`] from one list of the files.
macro_rules! render_files {
    ($($file:literal),* $(,)?) => {
        /// The path tracer's WGSL files (in `src/shaders/`), in the order
        /// [`render_source_variant`] concatenates them. WGSL declarations
        /// may come in any order; the files split one module by concern,
        /// mirroring the CPU integrator's modules (`crates/render/src`),
        /// and share its names.
        pub const RENDER_FILES: &[&str] = &[$($file),*];

        /// The files of [`RENDER_FILES`], concatenated.
        const RENDER_WGSL: &str = concat!($(include_str!(concat!("shaders/", $file))),*);
    };
}

render_files!(
    "render.wgsl",
    "environment.wgsl",
    "direct.wgsl",
    "subsurface.wgsl",
    "manifold.wgsl",
    "media.wgsl",
    "integrator.wgsl",
    "camera.wgsl",
    "wavefront.wgsl",
    "aov.wgsl",
);

/// What a probed kernel does with an index out of bounds
/// ([`Gpu::set_bounds_probe`](crate::Gpu::set_bounds_probe)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutOfBounds {
    /// Reads and writes the array's last element (naga's `Restrict`).
    Clamp,
    /// Reads zero and skips the write: naga's `ReadZeroSkipWrite` for local
    /// arrays and textures; for buffers the driver's robust access, which
    /// wgpu asks for (`robustBufferAccess2`: zero read, write dropped) on
    /// every device that offers it, NVIDIA's and lavapipe among them
    /// (naga cannot write `ReadZeroSkipWrite` for the atomics on the
    /// wavefront's counters).
    Zero,
}

/// `source` as SPIR-V 1.3 with every index into an array, a buffer or a
/// texture checked as `policy` says, and every loop bounded
/// ([`Gpu::set_bounds_probe`](crate::Gpu::set_bounds_probe)).
pub fn probe_spirv(source: &str, policy: OutOfBounds) -> Result<Vec<u32>, String> {
    use naga::proc::BoundsCheckPolicy as P;
    let (p, buffer) = match policy {
        OutOfBounds::Clamp => (P::Restrict, P::Restrict),
        OutOfBounds::Zero => (P::ReadZeroSkipWrite, P::Unchecked),
    };
    let policies = naga::proc::BoundsCheckPolicies {
        index: p,
        buffer,
        image_load: p,
        binding_array: p,
    };
    kernel_spirv(source, policies, true, None)
}

/// `source` as SPIR-V 1.3 written by naga after it validates the module
/// (every capability allowed): indices checked by `policies`, loops
/// bounded by iteration counters where `bound_loops` (wgpu's
/// `force_loop_bounding`), the one entry point `entry` or all of them.
/// An error is naga's, as text that points into the source. For the
/// bounds probe and `examples/kernel_stats.rs`.
pub fn kernel_spirv(
    source: &str,
    policies: naga::proc::BoundsCheckPolicies,
    bound_loops: bool,
    entry: Option<&str>,
) -> Result<Vec<u32>, String> {
    let module = naga::front::wgsl::parse_str(source).map_err(|e| e.emit_to_string(source))?;
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .map_err(|e| e.emit_to_string(source))?;
    let pipeline = entry.map(|entry| naga::back::spv::PipelineOptions {
        shader_stage: naga::ShaderStage::Compute,
        entry_point: entry.to_string(),
    });
    naga::back::spv::write_vec(
        &module,
        &info,
        &naga::back::spv::Options {
            lang_version: (1, 3),
            flags: naga::back::spv::WriterFlags::empty(),
            bounds_check_policies: policies,
            force_loop_bounding: bound_loops,
            ..Default::default()
        },
        pipeline.as_ref(),
    )
    .map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use crate::layout::tag;
    /// The path tracer's source is its files, in `RENDER_FILES`' order, and
    /// every `.wgsl` file of `src/shaders` is compiled into some kernel.
    #[test]
    fn render_files_are_the_render_source() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/shaders");
        let read = |name: &str| {
            std::fs::read_to_string(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
        };
        let joined: String = super::RENDER_FILES.iter().map(|f| read(f)).collect();
        assert_eq!(
            joined,
            super::RENDER_WGSL,
            "RENDER_WGSL is not the files of RENDER_FILES as they are on disk"
        );
        let others = [
            "geometry.wgsl",
            "intersect.wgsl",
            "materials.wgsl",
            "material_eval.wgsl",
            "wave.wgsl",
            "wave_stub.wgsl",
            "realtime.wgsl",
        ];
        for entry in std::fs::read_dir(&dir).unwrap() {
            let name = entry.unwrap().file_name().into_string().unwrap();
            assert!(
                super::RENDER_FILES.contains(&name.as_str()) || others.contains(&name.as_str()),
                "{name} is in src/shaders but no kernel includes it"
            );
        }
    }

    /// Feature sets worth compiling in tests: none, all, each model alone,
    /// and the integrator's optional parts with and without the rest.
    fn representative_sets() -> Vec<super::Features> {
        use super::Features;
        let wave = 1 << tag::WAVE;
        let sss = 1 << tag::SUBSURFACE | 1 << tag::SSS_SINGLE_LOBE | 1 << tag::SSS_ENTRY_LOBE;
        let set = |models: u32, list: bool| Features {
            models,
            list,
            many_lights: list,
            tiles: !list,
            null_boundaries: list,
            refraction: list,
            manifold: list,
            caustics: list,
        };
        let mut sets = vec![Features::NONE, Features::ALL];
        sets.extend(tag::ALL.iter().map(|(_, t)| set(1 << t, false)));
        for extra in [wave, sss, wave | sss] {
            sets.push(set(extra, true));
            sets.push(set(Features::ALL.models & !(wave | sss) | extra, false));
        }
        sets
    }

    #[test]
    fn features_cover_and_name_their_sets() {
        use super::Features;
        let all = representative_sets();
        for f in &all {
            assert!(Features::ALL.covers(*f));
            assert!(f.covers(Features::NONE));
            assert!(f.covers(*f));
            // Each entry point keeps what it reaches, and never more.
            assert_eq!(f.reached_by("main"), *f);
            assert_eq!(f.reached_by("trace"), *f);
            assert_eq!(f.reached_by("trace_last"), *f);
            assert_eq!(f.reached_by("trace_shade"), *f);
            // (Its shadow rays ask the material's lobes.)
            assert_eq!(f.reached_by("trace_shadow"), *f);
            // The sorted wavefront's other kernels reach no material.
            for entry in ["trace_extend", "trace_scatter"] {
                assert_eq!(f.reached_by(entry).models, 0, "{entry}");
            }
            let rt = f.reached_by("realtime");
            let lobes = 1 << tag::SSS_SINGLE_LOBE | 1 << tag::SSS_ENTRY_LOBE;
            let local = if f.has(tag::SUBSURFACE) {
                1 << tag::SUBSURFACE_BRDF
            } else {
                0
            };
            assert_eq!(rt.models, (f.models & !lobes) | local, "{f}");
            assert_eq!(rt.list, f.list);
            let aov = f.reached_by("aov_main");
            assert_eq!((aov.models, aov.list), (0, f.list));
            for g in &all {
                let by_parts =
                    tag::ALL.iter().all(|(_, t)| f.has(*t) || !g.has(*t)) && (f.list || !g.list);
                assert_eq!(f.covers(*g), by_parts, "{f} covers {g}");
            }
        }
        assert_eq!(Features::NONE.to_string(), "none");
        assert_eq!(Features::ALL.to_string(), "all");
        let few = Features {
            models: 1 << tag::DIFFUSE | 1 << tag::DIELECTRIC,
            tiles: false,
            null_boundaries: false,
            refraction: false,
            manifold: false,
            caustics: false,
            ..Features::ALL
        };
        assert_eq!(
            few.to_string(),
            "diffuse+dielectric, candidate list, many lights"
        );
        // Fitted to scenes: a sphere of 33 bumps needs the list, one of 32
        // does not.
        for (bumps, list) in [(32, false), (33, true)] {
            let scene =
                crate::layout::GpuScene::new(&[isolux_geometry::samples::bumpy_sphere(bumps)]);
            let fitted = few.fit_to(&scene, 1);
            assert_eq!(fitted.list, list, "{bumps}");
            assert_eq!(fitted.models, few.models);
            assert!(!fitted.many_lights);
        }
        // And to their point lights: 32 keep their answers in the mask,
        // 33 need the shading loop's shadow rays.
        let sphere = crate::layout::GpuScene::new(&[isolux_geometry::samples::bumpy_sphere(0)]);
        for (lights, many) in [(0, false), (32, false), (33, true)] {
            assert_eq!(few.fit_to(&sphere, lights).many_lights, many, "{lights}");
        }
        let fitted = Features {
            list: false,
            many_lights: false,
            ..few
        };
        assert_eq!(fitted.to_string(), "diffuse+dielectric");
        let lit = Features { list: false, ..few };
        assert_eq!(lit.to_string(), "diffuse+dielectric, many lights");
        assert!(!fitted.covers(lit) && lit.covers(fitted));
        // Tile lists are named, and either way covers the other.
        let tiled = Features {
            tiles: true,
            ..fitted
        };
        assert_eq!(tiled.to_string(), "diffuse+dielectric, tile lists");
        assert!(tiled.covers(fitted) && fitted.covers(tiled));
        let sss = Features::of(&[crate::layout::GpuMaterial {
            tag: [tag::SUBSURFACE, 0, 0, 0],
            ..Default::default()
        }]);
        assert_eq!(
            sss.to_string(),
            "subsurface, candidate list, many lights, tile lists, null boundaries, \
             refracted lights, manifold lights, caustics"
        );
        // Kernels with the null boundaries' loop cover those without.
        let plain = Features {
            null_boundaries: false,
            ..sss
        };
        assert!(sss.covers(plain) && !plain.covers(sss));
        // And kernels with refracted lights those without.
        let unrefracted = Features {
            refraction: false,
            manifold: false,
            ..sss
        };
        assert!(sss.covers(unrefracted) && !unrefracted.covers(sss));
        // And kernels with the manifold solve those with flat refraction.
        let flat = Features {
            manifold: false,
            ..sss
        };
        assert!(sss.covers(flat) && !flat.covers(sss));
        assert!(sss.has(tag::SSS_SINGLE_LOBE) && sss.has(tag::SSS_ENTRY_LOBE));
        // The real-time mode shades a medium with its local BRDF.
        let rt = sss.reached_by("realtime");
        assert!(rt.has(tag::SUBSURFACE_BRDF) && !rt.has(tag::SSS_SINGLE_LOBE));
        assert!(!sss.reached_by("main").has(tag::SUBSURFACE_BRDF));
        let many = Features {
            models: Features::ALL.models & !(1 << tag::SUBSURFACE),
            ..Features::ALL
        };
        assert_eq!(
            many.to_string(),
            "17 models with wave, candidate list, many lights, tile lists, null boundaries, \
             refracted lights, manifold lights, caustics"
        );
        // The kernels differ by their constants: a model left out, or the
        // subsurface integrator, is dead code.
        let none = super::render_source_variant(super::Precision::F32, Features::NONE);
        assert!(none.contains("const MODELS: u32 = 0x0u;"));
        assert!(none.contains("const CANDIDATE_LIST: bool = false;"));
        assert!(none.contains("const MANY_LIGHTS: bool = false;"));
        assert!(none.contains("const SUBSURFACE: bool = false;"));
        assert!(none.contains("const TILE_LISTS: bool = false;"));
        assert!(!none.contains("fn place_wave("));
        let full = super::render_source_variant(super::Precision::F32, Features::ALL);
        assert!(full.contains("const MODELS: u32 = 0xfffffu;"));
        assert!(full.contains("const CANDIDATE_LIST: bool = true;"));
        assert!(full.contains("const MANY_LIGHTS: bool = true;"));
        assert!(full.contains("const SUBSURFACE: bool = true;"));
        assert!(full.contains("const TILE_LISTS: bool = true;"));
        assert!(full.contains("fn place_wave("));
    }

    #[test]
    fn f64_variants_validate_with_naga() {
        use super::Precision::F64;
        for src in [
            super::intersect_source_with(F64),
            super::render_source_with(F64),
        ] {
            let module = naga::front::wgsl::parse_str(&src)
                .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&src)));
            naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::FLOAT64,
            )
            .validate(&module)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&src)));
            // Without the capability the same source must be refused, so
            // that the test above really exercised f64.
            assert!(naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::empty(),
            )
            .validate(&module)
            .is_err());
        }
    }

    /// `Features::shadows_ahead` is the kernels' `SHADOWS_AHEAD`, which
    /// decides whether `trace_shade` reads `trace_shadow`'s answers: were
    /// the two to differ, the sorted wavefront would shade its hits as if
    /// every light were hidden, or trace every shadow ray twice. Each set
    /// also with each of the parts that rule it out turned on alone.
    #[test]
    fn shadows_ahead_mirrors_the_kernels() {
        let mut seen = [false; 2];
        let sets = representative_sets().into_iter().flat_map(|f| {
            [
                f,
                super::Features { list: true, ..f },
                super::Features {
                    many_lights: true,
                    ..f
                },
                super::Features {
                    caustics: true,
                    ..f
                },
            ]
        });
        for f in sets {
            let src = super::render_source_variant(super::Precision::F32, f);
            let module = naga::front::wgsl::parse_str(&src)
                .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&src)));
            let (_, c) = module
                .constants
                .iter()
                .find(|(_, c)| c.name.as_deref() == Some("SHADOWS_AHEAD"))
                .expect("render.wgsl declares SHADOWS_AHEAD");
            let value = match module.global_expressions[c.init] {
                naga::Expression::Literal(naga::Literal::Bool(b)) => b,
                ref e => panic!("SHADOWS_AHEAD is not a literal: {e:?}"),
            };
            assert_eq!(value, f.shadows_ahead(), "{f}");
            seen[value as usize] = true;
        }
        assert_eq!(seen, [true, true], "both answers among the sets");
    }

    #[test]
    fn shaders_validate_with_naga() {
        for src in [
            super::intersect_source(),
            super::material_eval_source(),
            super::render_source(),
        ]
        .into_iter()
        .chain(
            representative_sets()
                .into_iter()
                .map(|f| super::render_source_variant(super::Precision::F32, f)),
        ) {
            let module = naga::front::wgsl::parse_str(&src)
                .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&src)));
            naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::empty(),
            )
            .validate(&module)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&src)));
        }
    }
}
