//! What the GPU can render of a scene, checked before anything is
//! uploaded: the limits of f32 (values, distances for their size, bumps
//! that dwarf their base, planes at a box's face, `wave` coordinates),
//! the spawn offset's floor beside thin objects and fine media, the
//! materials not on the GPU and whether the material data fits a
//! buffer. `--gpu` refuses a scene by these with a message naming what
//! and where ([`crate::Gpu::prepare`]), or warns; the tests and the
//! benchmarks call them directly (docs/gpu.md, "Precision", "Thin
//! objects").

use crate::layout::{self, GpuMaterials};
use crate::render::{random_walk, rebase_point};
use crate::GpuError;
use isolux_core::Rgb;
use isolux_render::{Environment, Scene};

/// The largest ratio of a bounded object's distance from the GPU's origin
/// (the camera, [`rebase_point`]; the farthest coordinate of its box) to
/// its size (its box's longest side) that the GPU accepts. Objects are
/// intersected in their own frames (`layout::GpuObject`) and positions
/// uploaded relative to the camera, but hit points, lights and spawned
/// rays are f32, whose spacing at a coordinate M is M 2^-23. Measured on
/// lavapipe (2026-12-02; a sphere of radius 1 with a bump, 2.2 units
/// across, on a sphere of radius 100, the whole scene and the camera moved
/// T units along x from the world origin, which the GPU took as its own;
/// 96 x 64, 16 spp; the mean difference of 8 x 8 block means, GPU against
/// CPU, over the CPU's own between two seeds, as the image tests measure
/// noise; the small sphere's ratio in brackets): T = 0 to 1e4 (4500)
/// 1.13-1.14, 2e4 (9100) 1.21, 3e4 (13600) 1.32, 5e4 (22700) 1.62, 1e5
/// (45000) 2.8. The example scenes' largest ratios, from their cameras, are
/// below 10.
pub const MAX_SCALE_RATIO: f64 = 1.0e4;

/// The bounded object of `scene` that lies farthest from the GPU's origin
/// ([`rebase_point`]) for its size ([`f32_shortfall`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScaleRatio {
    /// Its index among the scene's objects.
    pub object: usize,
    /// The farthest coordinate of its box from the GPU's origin.
    pub reach: f64,
    /// Its box's longest side.
    pub size: f64,
    /// `reach / size`.
    pub ratio: f64,
}

/// The farthest coordinate of box `b` from the point `at` (the GPU's
/// origin): how large the f32 coordinates of what lies in it get.
fn box_reach(b: &isolux_core::Aabb, at: glam::DVec3) -> f64 {
    (b.min - at).abs().max((b.max - at).abs()).max_element()
}

/// The bounded object of `scene` with the largest [`ScaleRatio`], if it
/// has one.
pub fn worst_scale_ratio(scene: &Scene) -> Option<ScaleRatio> {
    let at = rebase_point(scene);
    let mut worst: Option<ScaleRatio> = None;
    for (object, o) in scene.geometry.objects().iter().enumerate() {
        let b = o.bbox();
        if !b.is_finite() {
            continue;
        }
        let reach = box_reach(&b, at);
        let size = (b.max - b.min).max_element();
        let ratio = reach / size.max(f64::MIN_POSITIVE);
        if worst.is_none_or(|w| ratio > w.ratio) {
            worst = Some(ScaleRatio {
                object,
                reach,
                size,
                ratio,
            });
        }
    }
    worst
}

/// Why f32 cannot hold `scene` on the GPU, if it cannot: a bounded object
/// lies farther from the GPU's origin ([`rebase_point`], the camera) than
/// [`MAX_SCALE_RATIO`] times its own size (10 km for a 1 m object). The
/// message names the object with the largest ratio, and what to do. (A
/// large object far out, a floor, is no obstacle to small ones near the
/// camera: each is weighed against its own size.) Also why a `wave`
/// heightfield's coordinates are too coarse in f32
/// (`wave_coordinate_shortfall`).
pub fn f32_shortfall(scene: &Scene) -> Option<String> {
    if let Some(why) = f32_overflow(scene) {
        return Some(why);
    }
    let ScaleRatio {
        object,
        reach,
        size,
        ratio,
    } = match worst_scale_ratio(scene) {
        Some(worst) if worst.ratio > MAX_SCALE_RATIO => worst,
        _ => return wave_coordinate_shortfall(scene),
    };
    Some({
        let (from, fix) = if planar_wave(scene) {
            (
                "the origin (a planar `wave` mapping keeps the GPU's origin there)",
                "move the scene nearer the origin",
            )
        } else {
            ("the camera", "bring the camera nearer it")
        };
        format!(
            "object[{object}] is {size:.4e} units across and reaches {reach:.4e} from {from}: \
             {ratio:.0} times its size, more than the GPU's f32 coordinates resolve \
             ({MAX_SCALE_RATIO}; docs/gpu.md, \"Precision\"): {fix}, or render without --gpu"
        )
    })
}

/// The finest a `wave` heightfield coordinate must be resolved on the
/// GPU, in texels: f32 (an ulp of the coordinate, in um) must place a
/// shading point on its heightfield within a quarter of a texel.
const WAVE_COORDINATE_TEXELS: f64 = 0.25;

/// Why f32 cannot place shading points on a `wave` heightfield of `scene`,
/// if it cannot: the GPU maps a point to heightfield coordinates in f32
/// (`place_wave`: `phi r` and `theta r` about a spherical mapping's
/// centre, `phi rho` and `y` about a cylindrical one's, or the world
/// coordinates for a planar one, times `um_per_unit`), so a bounded object
/// far from its mapping's centre (or, planar, from the origin) gets
/// coordinates whose f32 ulp exceeds [`WAVE_COORDINATE_TEXELS`] of the
/// heightfield's texel. (Found by `scripts/gpu-diff-fuzz.py`: a spherical
/// mapping centred 1e7 units away, coordinates of 1.6e10 um resolved to
/// 2e3 um, rendered the brushed sphere half as bright as the CPU did; at
/// 1e5 units, ulps of 16 um over texels of 1 um, the image's mean still
/// matched but not its scratches.) The CPU maps in f64.
fn wave_coordinate_shortfall(scene: &Scene) -> Option<String> {
    use isolux_materials::wave::Mapping;
    for (i, o) in scene.geometry.objects().iter().enumerate() {
        let b = o.bbox();
        if !b.is_finite() || b.is_empty() {
            continue;
        }
        let m = scene.object_material[i];
        for w in waves(&scene.materials[m]) {
            let corners = (0..8).map(|k| b.corner(k));
            // The largest coordinate on the box, in scene units (bounds:
            // |phi| and theta at most pi, the distances at most a
            // corner's).
            let (reach, from, fix) = match w.mapping {
                Mapping::Planar(a) => (
                    corners
                        .map(|p| {
                            (0..3)
                                .filter(|&k| k != a)
                                .map(|k| p[k].abs())
                                .fold(0.0, f64::max)
                        })
                        .fold(0.0, f64::max),
                    "the origin (its planar mapping's)".to_string(),
                    "move the object nearer the origin",
                ),
                Mapping::Spherical(c) => (
                    std::f64::consts::PI * corners.map(|p| (p - c).length()).fold(0.0, f64::max),
                    format!("its spherical mapping's centre {}", nums3(c)),
                    "move the mapping's `center` to the object",
                ),
                Mapping::Cylindrical(c) => (
                    corners
                        .map(|p| {
                            let d = p - c;
                            (std::f64::consts::PI * d.x.hypot(d.z)).max(d.y.abs())
                        })
                        .fold(0.0, f64::max),
                    format!("its cylindrical mapping's centre {}", nums3(c)),
                    "move the mapping's `center` to the object",
                ),
            };
            let coordinate = reach * w.um_per_unit;
            let ulp = coordinate * f32::EPSILON as f64;
            let texel = w.surface.texel_um;
            if ulp > WAVE_COORDINATE_TEXELS * texel {
                return Some(format!(
                    "object[{i}] wears the `wave` material \"{}\" and lies far from {from}: its \
                     heightfield coordinates reach {coordinate:.3e} um, which the GPU's f32 \
                     resolves to {ulp:.2e} um, coarser than {WAVE_COORDINATE_TEXELS} of its \
                     texel ({texel} um; docs/gpu.md, \"Precision\"): {fix}, or render without \
                     --gpu (the CPU maps in f64)",
                    scene.material_names.get(m).map_or("?", |n| n.as_str())
                ));
            }
        }
    }
    None
}

/// `[x, y, z]`, each as Rust writes the shortest `f64` that reads back.
fn nums3(v: glam::DVec3) -> String {
    format!("[{}, {}, {}]", v.x, v.y, v.z)
}

/// A warning for the thinnest object of `scene` whose box is thinner than
/// `THIN_FACTOR` times the offset at which the GPU starts a ray leaving its
/// surface ([`object_floor`] plus [`crate::SPAWN_OFFSET_WORLD`]
/// times its distance from the GPU's origin), if there is one: a ray
/// leaving one face of it can start beyond the other, so light through a
/// thin glass or translucent sheet, and shadows right behind it, differ
/// from the CPU's image (whose offset is about 1e-7 of the object's size).
/// A warning, not a refusal: an opaque thin object seen from outside
/// renders the same. (Found by `scripts/gpu-diff-fuzz.py`: a subsurface
/// disc 2e-6 thick rendered dark on the GPU.)
///
/// An unbounded object (a plane without `bounds`) takes the scene's floor
/// ([`spawn_floor`]), however small the objects beside it: rays leaving it
/// start that far off it, and pass under an object thinner than that
/// where it lies on the plane (its contact shadow, and the light between
/// them). So an object is also warned about when its box is thinner than
/// `THIN_FACTOR` such offsets of an unbounded object at its place, naming
/// both and the cure (`bounds` on the plane gives it its own floor): the
/// small-units test scene at 1e-4 beside a sphere 1 across, on an
/// unbounded floor, differed from the CPU by 5.4 times the noise, and by
/// 1.2 times with the floor bounded.
pub fn thin_object_warning(scene: &Scene) -> Option<String> {
    /// How many offsets thick an object must be not to be warned about.
    const THIN_FACTOR: f64 = 4.0;
    let at = rebase_point(scene);
    let objects = scene.geometry.objects();
    let unbounded = objects.iter().position(|o| !o.bbox().is_finite());
    // (object, thickness, offset, the unbounded object whose offset it is)
    let mut worst: Option<(usize, f64, f64, Option<usize>)> = None;
    for (i, o) in objects.iter().enumerate() {
        let b = o.bbox();
        if !b.is_finite() || b.is_empty() {
            continue;
        }
        let reach = box_reach(&b, at);
        let thickness = (b.max - b.min).min_element();
        let own = gpu_spawn_offset(object_floor(o), reach);
        let shared = unbounded.map(|u| (gpu_spawn_offset(object_floor(&objects[u]), reach), u));
        let thin = if thickness < THIN_FACTOR * own {
            Some((own, None))
        } else {
            shared
                .filter(|&(s, _)| thickness < THIN_FACTOR * s)
                .map(|(s, u)| (s, Some(u)))
        };
        if let Some((offset, by)) = thin {
            if worst.is_none_or(|(_, t, ..)| thickness < t) {
                worst = Some((i, thickness, offset, by));
            }
        }
    }
    worst.map(|(i, thickness, offset, by)| match by {
        None => format!(
            "object[{i}]'s box is {thickness:.2e} units thick, under {THIN_FACTOR} times the \
             {offset:.2e} units at which the GPU starts rays off a surface: light through it \
             and shadows right behind it can differ from the CPU's image (docs/gpu.md, \
             \"Precision\"); render without --gpu where they matter"
        ),
        Some(u) => format!(
            "object[{i}]'s box is {thickness:.2e} units thick, under {THIN_FACTOR} times the \
             {offset:.2e} units at which the GPU starts rays off the unbounded object[{u}], \
             whose offset is the scene's: where object[{i}] lies on it, its contact shadow \
             can differ from the CPU's image (docs/gpu.md, \"Thin objects\"); give \
             object[{u}] `bounds` (its own offset is then its box's), or render without --gpu"
        ),
    })
}

/// The GPU's ray offset off a surface at `reach` from its origin
/// (`spawn_offset_at` in render.wgsl): `floor` ([`object_floor`]) +
/// [`crate::SPAWN_OFFSET_WORLD`] `reach`.
fn gpu_spawn_offset(floor: f64, reach: f64) -> f64 {
    floor + crate::SPAWN_OFFSET_WORLD as f64 * reach
}

/// The part of the GPU's spawn offset that does not grow with the
/// distance from the camera, for `scene`'s unbounded surfaces:
/// [`crate::SPAWN_OFFSET`] times the length of its bounded objects
/// (`isolux_geometry::Aggregate::length`: the largest side of the box
/// holding them, at most 1), which its unbounded objects carry in
/// `GpuObject::origin.w` (their length, as on the CPU). A scene of unit
/// size or larger keeps 1e-4; one 1e-5 across, 1e-9. Before 2026-12-06 it
/// was 1e-4 in any scene, and the perturbed-sphere example scaled by 1e-4
/// (a sphere of radius 6e-5) rendered 1.4% brighter than on the CPU, by
/// 1e-5 12% darker (docs/gpu.md, "Scenes in small units"). Unbounded
/// objects do not count: the GPU walks them in a frame at the camera,
/// where their rounding is the offset's second term,
/// [`crate::SPAWN_OFFSET_WORLD`] times the distance. Each object's own
/// floor is [`object_floor`] (an unbounded object's is this one).
pub fn spawn_floor(scene: &Scene) -> f64 {
    floor_of(scene.geometry.length())
}

/// The part of the GPU's offset off object `o`'s surface that does not
/// grow with the distance (`object_floor` in render.wgsl):
/// [`crate::SPAWN_OFFSET`] times [`isolux_geometry::Object::length`] (its
/// box's largest side at most 1, an unbounded object's the scene's),
/// which `GpuObject::origin.w` carries. Since 2026-12-06 (later the same
/// day as [`spawn_floor`]) each object has its own, as on the CPU
/// (`isolux_geometry::Hit::offset`): before, every object took the
/// scene's, and a bead 1e-3 across in a scene 1 or more across started
/// its rays 1e-4 off it, a tenth of its radius (docs/gpu.md, "Thin
/// objects").
pub fn object_floor(o: &isolux_geometry::Object) -> f64 {
    floor_of(o.length())
}

/// [`crate::SPAWN_OFFSET`] times `length` as the GPU computes it from the
/// f32 length it is given (`GpuObject::origin.w`, at least 1e-30): the
/// f32 product, so that [`spawn_floor`] is the value render.wgsl's
/// `object_floor` gives an unbounded object.
fn floor_of(length: f64) -> f64 {
    (crate::SPAWN_OFFSET * length.max(1e-30) as f32) as f64
}

/// The random-walk medium of `scene` whose shortest mean free path spans
/// fewer than [`isolux_render::FINE_MEDIUM_OFFSETS`] of the GPU's ray
/// offsets off its surface ([`object_floor`] +
/// [`crate::SPAWN_OFFSET_WORLD`] times its box's reach from the GPU's
/// origin; an unbounded medium's at the camera), described for a
/// warning ([`isolux_render::Scene::finest_medium`]). The GPU's offset,
/// 1e-4 units on a scene of unit size or larger, is some thousand times
/// the CPU's there, so a medium whose mean free path is under a millimetre in
/// such a scene reaches it first: `lamplit-milk.toml` with its milk's
/// `scale` at 1e4 (a mean free path of 5e-5 units) came out 2% darker
/// than the CPU's image, at 1e5 8%.
pub fn fine_medium_warning(scene: &Scene) -> Option<String> {
    let at = rebase_point(scene);
    scene
        .finest_medium(|o| {
            let b = o.bbox();
            let reach = if b.is_finite() {
                box_reach(&b, at)
            } else {
                (scene.camera.position - at).abs().max_element()
            };
            gpu_spawn_offset(object_floor(o), reach)
        })
        .map(|f| f.describe(scene, "the GPU"))
}

/// Above this magnitude a light's intensity or position (from the GPU's
/// origin), the environment's radiance, or a quadric coefficient or
/// perturbation factor is refused by `--gpu`: f32 holds up to 3.4e38, and
/// the kernels square positions and coefficients and multiply radiances
/// by BSDF values and inverse densities, so a value near f32's limit
/// overflows to infinity on the way, and the samples it reaches are
/// dropped as non-finite (a silently darker image). 1e30 leaves 8 orders
/// of magnitude for that arithmetic; the CPU, in f64, takes any finite
/// value.
pub const F32_VALUE_LIMIT: f64 = 1.0e30;

/// `v` as a person writes it: plain in [1e-3, 1e6), else with an exponent
/// (`{v}` would spell out all 301 digits of 1e300).
fn num(v: f64) -> String {
    if v == 0.0 || (1e-3..1e6).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// `c` as the scene file writes it, `[r, g, b]` ([`num`]).
fn nums(c: Rgb) -> String {
    format!("[{}]", c.to_array().map(num).join(", "))
}

/// The first value of `scene`'s lights, environment or geometry beyond
/// [`F32_VALUE_LIMIT`], named as the scene file names it.
fn f32_overflow(scene: &Scene) -> Option<String> {
    let beyond = |v: f64| !(v.abs() <= F32_VALUE_LIMIT);
    let fix = "render without --gpu (the CPU works in f64)";
    let at = rebase_point(scene);
    for (i, l) in scene.lights.iter().enumerate() {
        let p = l.position - at;
        if p.to_array().into_iter().any(beyond) {
            return Some(format!(
                "light[{i}] lies {:.4e} units from {}, beyond the {F32_VALUE_LIMIT:e} that \
                 the GPU's f32 arithmetic holds: {fix}",
                p.abs().max_element(),
                if at == glam::DVec3::ZERO {
                    "the origin"
                } else {
                    "the camera"
                }
            ));
        }
        if l.intensity.to_array().into_iter().any(beyond) {
            return Some(format!(
                "light[{i}] has intensity {}, beyond the {F32_VALUE_LIMIT:e} \
                 that the GPU's f32 arithmetic holds: {fix}",
                nums(l.intensity)
            ));
        }
    }
    let env = match &scene.environment {
        Environment::Constant(c) => c
            .to_array()
            .into_iter()
            .any(beyond)
            .then(|| format!("radiance {}", nums(*c))),
        Environment::Map(m) => m
            .texels()
            .iter()
            .any(|c| c.to_array().into_iter().any(beyond))
            .then(|| "map's radiance (its texels times its `scale`)".to_string()),
    };
    if let Some(what) = env {
        return Some(format!(
            "the environment's {what} exceeds the {F32_VALUE_LIMIT:e} that the GPU's f32 \
             arithmetic holds: {fix}"
        ));
    }
    for (i, o) in scene.geometry.objects().iter().enumerate() {
        if o.base().coefficients().into_iter().any(beyond) {
            return Some(format!(
                "object[{i}]: its base quadric has a coefficient beyond the {F32_VALUE_LIMIT:e} \
                 that the GPU's f32 arithmetic holds (about its own centre: a radius above \
                 1e15, or a `transform` whose `scale` under 1e-15 divides its terms by the \
                 scale squared): {fix}"
            ));
        }
        for (k, q) in o.perturbations().iter().enumerate() {
            if beyond(q.factor) || q.quadric.coefficients().into_iter().any(beyond) {
                return Some(format!(
                    "object[{i}]: perturbation {k} has a factor or quadric coefficient beyond \
                     the {F32_VALUE_LIMIT:e} that the GPU's f32 arithmetic holds: {fix}"
                ));
            }
            let peak = bump_peak(o, q);
            if beyond(peak) {
                return Some(format!(
                    "object[{i}]: perturbation {k} adds f Q^3 = {} inside the object, beyond \
                     the {F32_VALUE_LIMIT:e} that the GPU's f32 arithmetic holds (a support of \
                     radius R gives Q up to R^2, so Q^3 up to R^6): {fix}",
                    num(peak)
                ));
            }
        }
    }
    None
}

/// Above this ratio of a perturbation's largest `|f| Q^3` inside its
/// object to the base quadric's largest `|F|` on the object's box (see
/// [`worst_bump_condition`]), the f32 intersection is not trusted. The
/// kernel builds each segment's degree-6 polynomial in the Bernstein
/// basis from the quadratics' own coefficients (since 2026-12-05;
/// docs/geometry.md, "Why the Bernstein form"), each quadratic taken
/// about a point near where it is used (the base about its vertex along
/// the ray when the box's entry is far from it, the supports about each
/// segment's start; later on 2026-12-05). Before, it expanded `F'` in the
/// power basis about the box's entry, whose terms were then that many
/// times the values near the surface and cancelled there, and the limit
/// was 1e3; then 1e6 with the Bernstein basis about the entry. Measured on
/// lavapipe against the CPU's f64 (`f32_condition_table` in the
/// conformance tests: a base sphere of radius 0.45 under one bump, 400
/// rays from inside and outside, unbounded supports within `bounds` of 80
/// units), rays off by over 1e-5 of the box and the worst:
///
/// | support, factor | ratio | power basis | Bernstein, about the entry | about the vertex |
/// |---|---:|---:|---:|---:|
/// | sphere 0.2, 3000 (the gallery's) | 0.32 | 0, 5.3e-7 | 0, 5.3e-7 | 0, 5.3e-7 |
/// | cone, 0.01 | 252 | 1, 1.9e-5 | 0, 8.1e-7 | 0, 5.0e-7 |
/// | plane, 100 | 1.3e3 | 13, 6.9e-5 | 0, 3.4e-7 | 0, 3.4e-7 |
/// | cone, 0.1 | 2.5e3 | 14, 5.3e-2 | 0, 8.1e-7 | 0, 3.5e-7 |
/// | paraboloid, 10 | 8.8e3 | 5, 2.3e-3 | 0, 1.5e-6 | 0, 2.4e-7 |
/// | plane, 1000 | 1.3e4 | 53, 1.7 | 0, 1.6e-7 | 0, 1.6e-7 |
/// | sphere 20, 2.5 | 1.3e5 | 7, 2.5e-5 | 0, 1.2e-7 | 0, 1.0e-7 |
/// | sphere 5, 3000 | 5.9e5 | 126, 0.62 | 0, 1.6e-7 | 0, 1.6e-7 |
/// | plane, 1e5 | 1.3e6 | | 0, 1.8e-7 | 0, 1.8e-7 |
/// | cone, 100 | 2.5e6 | | 1, 1.0e-5 | 0, 5.9e-7 |
/// | paraboloid, 1e4 | 8.8e6 | | 0, 1.5e-6 | 0, 1.8e-7 |
/// | cylinder 20, 1000 | 1.3e7 | | 0, 1.3e-7 | 0, 1.3e-7 |
/// | sphere 50, 3000 | 6.2e9 | 200, 0.52 | 0, 9.6e-8 | 0, 1.2e-7 |
/// | sphere 1000, 3000 | 1.0e15 | | 0, 1.3e-7 | 0, 1.2e-7 |
///
/// The f64 intersection hits every one of them as the CPU does (worst
/// 1.4e-7 of the box). 240 random bumps of six shapes (docs/gpu.md,
/// "Precision"; the generator of `f32_holds_random_bumps_below_the_limit`)
/// place every ray within 1e-5 of the box from a condition of 10 to 1e10
/// but one graze (3.9e-5, at a cosine of 6e-4 to the surface); from 1e10
/// to 1e15, two objects of 240 have one ray each off (1.4e-5 and 3.1e-5).
/// So the limit is 1e10. Beyond it f64 still matters: shells whose bump
/// dwarfs the base by 1e18 (`shells_dwarfing_their_base_match_the_cpu_in_f64`)
/// have 5 of 300 rays off by up to 1.7e-3 units in f32, none in f64.
pub const F32_CONDITION_LIMIT: f64 = 1.0e10;

/// The worst-conditioned bump of `scene` for the f32 intersection, if its
/// ratio exceeds [`F32_CONDITION_LIMIT`]: a message naming the object and
/// the perturbation, the ratio and both magnitudes. Such a scene
/// intersects correctly in f64 ([`crate::Gpu::set_precision`]); the
/// renderer switches to it where the adapter offers it
/// ([`crate::Gpu::precision_for`]). (Found by `scripts/gpu-diff-fuzz.py`:
/// the gallery with a bump's support grown from radius 0.2 to 50, a
/// copper shell around the camera whose hits the GPU placed up to 0.2
/// units short or missed, and rendered twice as bright as the CPU.)
pub fn f32_ill_conditioned(scene: &Scene) -> Option<String> {
    let BumpCondition {
        object,
        perturbation,
        ratio,
        peak,
        base,
    } = worst_bump_condition(scene)?;
    (ratio > F32_CONDITION_LIMIT).then(|| {
        format!(
            "object[{object}]: perturbation {perturbation} adds f Q^3 up to {peak:.3e} inside \
             the object, {ratio:.2e} times its base quadric's largest |F| there ({base:.3e}); \
             the f32 intersection loses such surfaces beyond {F32_CONDITION_LIMIT:e} times \
             (docs/gpu.md, \"Precision\")"
        )
    })
}

/// How close to its box, in units in the last place of f32 at the box's
/// distance from the GPU's origin or from its object's, a plane that
/// misses the box must be for [`f32_plane_at_box_face`] to name it.
pub const F32_PLANE_GAP_ULPS: f64 = 64.0;

/// The first object of `scene` whose base is a plane that misses the
/// object's box (`bounds`) by less than [`F32_PLANE_GAP_ULPS`] units in
/// the last place of f32: a message naming it and the gap. The CPU, in
/// f64, clips such a plane away; in f32 the box's face and the plane are
/// the same to the rounding, and the GPU drew some or all of it. Such a
/// scene intersects as the CPU's in f64, which
/// [`crate::Gpu::precision_for`] switches to where the adapter offers it
/// (and only notes otherwise: a plane that touches its box and one just
/// beyond it render alike in f32). (Found by `scripts/gpu-diff-fuzz.py`:
/// the gallery's floor moved to 1e-6 above its box's top face at 0, gone
/// on the CPU, drawn on the GPU; drawn in part at 1e-5, right at 1e-4.)
pub fn f32_plane_at_box_face(scene: &Scene) -> Option<String> {
    let at = rebase_point(scene);
    for (object, o) in scene.geometry.objects().iter().enumerate() {
        let q = o.base();
        let b = o.bbox();
        if q.m != glam::DMat3::ZERO || q.b == glam::DVec3::ZERO || !b.is_finite() || b.is_empty() {
            continue;
        }
        // The plane's signed distance at the box's corners (the quadric
        // is written about the object's origin).
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for k in 0..8 {
            let d = q.eval(b.corner(k) - o.origin()) / (2.0 * q.b.length());
            lo = lo.min(d);
            hi = hi.max(d);
        }
        let gap = if lo > 0.0 {
            lo
        } else if hi < 0.0 {
            -hi
        } else {
            continue;
        };
        let reach = box_reach(&b, at).max(box_reach(&b, o.origin()));
        let limit = F32_PLANE_GAP_ULPS * reach * f64::from(f32::EPSILON);
        if gap < limit {
            return Some(format!(
                "object[{object}]: its plane misses its box (bounds) by {gap:.2e} units, under \
                 the {limit:.2e} that f32 tells apart there: the CPU clips the plane away, and \
                 f32 cannot (docs/gpu.md, \"Precision\")"
            ));
        }
    }
    None
}

/// The bump of a scene that is hardest for the f32 intersection
/// ([`worst_bump_condition`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BumpCondition {
    /// Index of the object in the scene file.
    pub object: usize,
    /// Index of the perturbation in the object.
    pub perturbation: usize,
    /// `peak / base`.
    pub ratio: f64,
    /// About the largest `|f| Q^3` inside the object.
    pub peak: f64,
    /// About the base quadric's largest `|F|` on the object's box.
    pub base: f64,
}

/// The bump of `scene` with the largest ratio of its `|f| Q^3` inside its
/// object to the base quadric's largest `|F|` on the object's box; `None`
/// for a scene without bumps in bounded objects.
pub fn worst_bump_condition(scene: &Scene) -> Option<BumpCondition> {
    let mut worst: Option<BumpCondition> = None;
    for (i, o) in scene.geometry.objects().iter().enumerate() {
        let b = o.bbox();
        if o.perturbations().is_empty() || !b.is_finite() || b.is_empty() {
            continue;
        }
        // The base's largest |F| on the box, in the object's frame.
        let local = b.translated(-o.origin());
        let base = largest_abs(o.base(), &local);
        for (k, q) in o.perturbations().iter().enumerate() {
            let peak = bump_peak(o, q);
            let ratio = peak / base.max(f64::MIN_POSITIVE);
            if worst.is_none_or(|w| ratio > w.ratio) {
                worst = Some(BumpCondition {
                    object: i,
                    perturbation: k,
                    ratio,
                    peak,
                    base,
                });
            }
        }
    }
    worst
}

/// About the largest `|F|` of the quadric `q` on the box `b` (in `q`'s
/// frame), by [`max_over_box`] of `F` and of `-F`.
fn largest_abs(q: &isolux_geometry::Quadric, b: &isolux_core::Aabb) -> f64 {
    max_over_box(|p| q.eval(p), b, 9).max(max_over_box(|p| -q.eval(p), b, 9))
}

/// About the largest `|f| Q^3` that perturbation `q` adds inside object
/// `o`'s box (within its support's box, where that is bounded), by
/// [`max_over_box`]; 0 where the box is unbounded. The kernels build the
/// degree-6 polynomial from it, so a support of radius 1e5 (`Q` up to
/// 1e10, `Q^3` up to 1e30) overflows f32 on the way, where the
/// coefficients alone stay far inside it. (Found by
/// `scripts/gpu-diff-fuzz.py`: a sphere of radius 1e5 on the quadrics
/// example rendered with arcs of noise on the GPU.)
fn bump_peak(o: &isolux_geometry::Object, q: &isolux_geometry::Perturbation) -> f64 {
    // The quadrics are in the object's frame, the box in the world's.
    let mut b = o.bbox().translated(-o.origin());
    let support = q.quadric.positive_bounds();
    if let Some(support) = support {
        b = b.intersection(&support);
    }
    if !b.is_finite() || b.is_empty() {
        return 0.0;
    }
    // A bounded support's Q is concave: one ascent finds its maximum.
    let starts = if support.is_some() { 1 } else { 9 };
    let peak = max_over_box(|p| q.quadric.eval(p), &b, starts).max(0.0);
    q.factor.abs() * peak.powi(3)
}

/// About the largest value of the quadratic `f` on the box `b`:
/// coordinate ascent (each coordinate in turn set to its best value on the
/// box, the others fixed; the quadratic along it is read from three
/// values) from the box's centre and, with `starts` 9, from each corner
/// too, 16 sweeps each.
/// Exact in the limit for a concave `f` (a sphere's, a cylinder's or a
/// paraboloid's `Q`: their maximum lies on the axis or at the centre,
/// which corners alone miss) and for a linear one; for an indefinite `f`
/// (a cone, a hyperboloid) the best of nine local maxima.
fn max_over_box(f: impl Fn(glam::DVec3) -> f64, b: &isolux_core::Aabb, starts: usize) -> f64 {
    let (lo, hi) = (b.min, b.max);
    let mut best = f64::NEG_INFINITY;
    for k in (0..9).rev().take(starts) {
        let mut x = if k == 8 { b.center() } else { b.corner(k) };
        for _ in 0..16 {
            for (i, e) in glam::DVec3::AXES.into_iter().enumerate() {
                let (f0, fp, fm) = (f(x), f(x + e), f(x - e));
                // f(x + s e) = f0 + b s + a s^2.
                let (a, b) = (0.5 * (fp + fm - 2.0 * f0), 0.5 * (fp - fm));
                let gain = |s: f64| b * s + a * s * s;
                let (s_lo, s_hi) = (lo[i] - x[i], hi[i] - x[i]);
                let mut s = if gain(s_lo) >= gain(s_hi) { s_lo } else { s_hi };
                if a < 0.0 {
                    let top = -b / (2.0 * a);
                    if top > s_lo && top < s_hi && gain(top) > gain(s) {
                        s = top;
                    }
                }
                x[i] += s;
            }
        }
        best = best.max(f(x));
    }
    best
}

/// Whether an object of `scene` wears a `wave` material (alone or in a
/// mix) that maps its heightfield by plain world coordinates
/// (`Mapping::Planar`).
pub(crate) fn planar_wave(scene: &Scene) -> bool {
    use isolux_materials::wave::Mapping;
    scene.object_material.iter().any(|&m| {
        waves(&scene.materials[m])
            .iter()
            .any(|w| matches!(w.mapping, Mapping::Planar(_)))
    })
}

/// The first material of `scene` used by an object that mixes two or
/// more `wave` materials, with their number: the kernels evaluate one per
/// hit, chosen at random, which Mesa 22's lavapipe miscompiles
/// ([`crate::Gpu::miscompiles_loops`]; docs/gpu.md).
pub fn mix_of_waves(scene: &Scene) -> Option<(String, usize)> {
    scene.object_material.iter().find_map(|&m| {
        let n = waves(&scene.materials[m]).len();
        (n > 1).then(|| (scene.material_names.get(m).cloned().unwrap_or_default(), n))
    })
}

/// Whether `scene` has a random-walk `subsurface` medium, whose paths run
/// long loops of scattering events inside a bounce: on Mesa 22's
/// lavapipe ([`crate::Gpu::miscompiles_loops`]) walks of thousands of
/// events end early, the wavefront renders the rest differently from run
/// to run and the megakernel about 1% dark (docs/gpu.md, "The wavefront
/// is deterministic: Mesa 22.3's lanes are not"). False where a material
/// does not run on the GPU.
pub fn has_random_walk(scene: &Scene) -> bool {
    GpuMaterials::new(&scene.materials).is_ok_and(|m| random_walk(&m))
}

/// The number of distinct `wave` materials the objects of `scene` use
/// (a mix's leaves counted one by one): above one, neighbouring pixels
/// run the wave code with different loop bounds, which Mesa 22's lavapipe
/// miscompiles in the sampled lobes ([`crate::Gpu::miscompiles_loops`];
/// docs/gpu.md).
pub fn wave_count(scene: &Scene) -> usize {
    let mut used: Vec<usize> = scene.object_material.clone();
    used.sort_unstable();
    used.dedup();
    used.iter().map(|&m| waves(&scene.materials[m]).len()).sum()
}

/// The `wave` materials `m` is made of: itself, or a mix's `wave`
/// components (mixes nested included).
fn waves(m: &isolux_materials::Material) -> Vec<&isolux_materials::wave::Wave> {
    use isolux_materials::Material as M;
    match m {
        M::Wave(w) => vec![w],
        M::Mix(x) => x.components.iter().flat_map(|(c, _)| waves(c)).collect(),
        _ => Vec::new(),
    }
}

/// The first material used by an object of `scene` that has no GPU
/// implementation: `(name, type)`.
pub fn unsupported_material(scene: &Scene) -> Option<(String, String)> {
    scene.object_material.iter().find_map(|&m| {
        (!layout::supported(&scene.materials[m])).then(|| {
            (
                scene.material_names.get(m).cloned().unwrap_or_default(),
                scene.materials[m].type_name().to_string(),
            )
        })
    })
}

/// Checks that the material data of `used` (sampling tables, measured
/// BRDFs, factored textures, wave heightfields), laid out as `materials`,
/// fits in one storage buffer of at most `limit` bytes; if not, the error
/// names the material whose own data is largest, the usual cause being a
/// large heightfield (12 bytes per texel on the GPU: height and slopes).
pub(crate) fn material_data_fits(
    materials: &GpuMaterials,
    used: &[isolux_materials::Material],
    names: &[String],
    limit: u64,
) -> Result<(), GpuError> {
    let bytes = std::mem::size_of_val(&materials.data[..]) as u64;
    if bytes <= limit {
        return Ok(());
    }
    // Only on failure: each material's data on its own.
    let own = |m: &isolux_materials::Material| {
        GpuMaterials::new(std::slice::from_ref(m))
            .map_or(0, |g| std::mem::size_of_val(&g.data[..]) as u64)
    };
    let largest = used
        .iter()
        .zip(names)
        .map(|(m, n)| (own(m), n))
        .max_by_key(|&(b, _)| b);
    let hint = match largest {
        Some((b, name)) if b > 0 => format!(
            "; the largest is material \"{name}\" ({}): give it a smaller heightfield or table",
            crate::size(b)
        ),
        _ => String::new(),
    };
    Err(GpuError::TooLarge {
        what: "the scene's material data".into(),
        bytes,
        limit,
        hint,
    })
}

/// Whether every f32 of `m`'s GPU record (its parameter blocks, a mix's
/// components, and its tables) is finite.
fn gpu_material_finite(g: &GpuMaterials) -> bool {
    let blocks = g
        .materials
        .iter()
        .flat_map(|r| [r.a, r.b, r.c, r.d, r.e])
        .flatten();
    blocks.chain(g.data.iter().copied()).all(f32::is_finite)
}

/// Refuses materials whose parameters the GPU's f32 cannot hold (an `ior`
/// or a subsurface `scale` of 1e300 is infinite in f32, and its samples
/// would be dropped as non-finite, darkening the image without a word),
/// naming the first such material of the scene.
pub(crate) fn material_values_fit(
    materials: &GpuMaterials,
    used: &[isolux_materials::Material],
    names: &[String],
) -> Result<(), GpuError> {
    if gpu_material_finite(materials) {
        return Ok(());
    }
    // Only on failure: each material's record on its own.
    // None alone: one seen from inside a random-walk medium
    // (`GpuMaterials::relative_in_media`), its indices divided by the
    // medium's.
    let what = used
        .iter()
        .zip(names)
        .find(|(m, _)| {
            GpuMaterials::new(std::slice::from_ref(*m)).is_ok_and(|g| !gpu_material_finite(&g))
        })
        .map_or_else(
            || {
                "a material seen from inside a random-walk medium (its indices divided by the \
                 medium's `ior`)"
                    .to_string()
            },
            |(_, n)| format!("material \"{n}\""),
        );
    Err(GpuError::Precision(format!(
        "{what} has a parameter beyond the range of the GPU's f32 \
         (magnitude above {:.1e}, or a value derived from it): render without --gpu",
        f32::MAX
    )))
}

/// Replaces every material of `scene` that is not on the GPU by a grey
/// (0.5) diffuse, for comparisons and benchmarks that must run anyway;
/// returns the replaced materials' names.
pub fn replace_unsupported(scene: &mut Scene) -> Vec<String> {
    let mut replaced = Vec::new();
    for (i, m) in scene.materials.iter_mut().enumerate() {
        if !layout::supported(m) {
            replaced.push(scene.material_names.get(i).cloned().unwrap_or_default());
            *m = isolux_materials::Material::Diffuse(isolux_materials::Diffuse {
                reflectance: Rgb::splat(0.5),
            });
        }
    }
    replaced
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn oversized_material_data_is_refused_naming_the_largest() {
        use isolux_materials::wave::{Wave, WaveFresnel};
        use isolux_materials::{Diffuse, Material};
        let heights: Vec<f32> = (0..64 * 48).map(|i| (i % 5) as f32 * 0.01).collect();
        let field = isolux_wave::Heightfield::new(64, 48, 0.5, heights).unwrap();
        let surface = std::sync::Arc::new(isolux_wave::GaborSurface::new(field));
        let used = vec![
            Material::Diffuse(Diffuse {
                reflectance: Rgb::splat(0.5),
            }),
            Material::Wave(Wave::new(
                surface,
                isolux_wave::Model::Ghs,
                WaveFresnel::None,
            )),
        ];
        let names = vec!["paint".to_string(), "film".to_string()];
        let g = GpuMaterials::new(&used).unwrap();
        let bytes = 4 * g.data.len() as u64;
        // 12 bytes per texel at least.
        assert!(bytes >= 12 * 64 * 48);
        assert!(material_data_fits(&g, &used, &names, bytes).is_ok());
        let e = material_data_fits(&g, &used, &names, bytes - 4).unwrap_err();
        let text = e.to_string();
        assert!(matches!(e, GpuError::TooLarge { .. }), "{text}");
        assert!(text.contains("material \"film\""), "{text}");
        assert!(
            text.starts_with("the scene's material data takes ")
                && text.contains(" KiB, more than"),
            "{text}"
        );
    }
}
