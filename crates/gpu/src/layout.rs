//! GPU data layouts: `#[repr(C)]` mirrors of the WGSL structs in
//! `shaders/`, the single source of truth for both sides. Every struct is
//! a whole number of `vec4`s (16-byte aligned, no implicit padding), and a
//! unit test checks each size against the WGSL declaration's.

use bytemuck::{Pod, Zeroable};
use isolux_core::{Aabb, DVec3, Rgb};
use isolux_geometry::bvh::{Bvh, LEAF_SIZE};
use isolux_geometry::{Object, Quadric};
use isolux_materials::{Fresnel, Material};

/// A quadric's ten coefficients `[a11, a22, a33, a12, a13, a23, a14, a24,
/// a34, a44]` (see `isolux_geometry::quadric`), two zeros of padding.
/// WGSL: `struct Quadric { c: array<vec4<f32>, 3> }`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuQuadric {
    /// Coefficients in the order above, then `[0, 0]`.
    pub c: [f32; 12],
}

impl GpuQuadric {
    /// From a CPU quadric (rounded to f32).
    pub fn new(q: &Quadric) -> Self {
        let mut c = [0.0f32; 12];
        for (d, s) in c.iter_mut().zip(q.coefficients()) {
            *d = s as f32;
        }
        Self { c }
    }
}

/// One perturbation `factor * Q^3 [Q >= 0]`, its quadric written about
/// its anchor: a point of its object's frame where it acts, the point of
/// its support's box within the object's nearest the frame's zero
/// (`anchor_in`; the zero itself when the support misses the box or is
/// unbounded there). The kernels evaluate `Q` at `x -
/// anchor` for a point `x` of the object's frame (`pert_local`), so that
/// its terms are as small as the support, wherever the object's frame
/// lies. About the object's frame, a support of radius 1 on a base
/// sphere of radius 100 (a planet's bumps, the frame at its centre)
/// carried a constant term near 1e4: its f32 rounding in the buffer, and
/// that of every evaluation, moved the bumps' surfaces by 1e-4 to 1e-2,
/// beyond the rays' spawn offset (`conformance.rs`,
/// `bumps_far_from_their_frame_are_hit_precisely`).
/// WGSL: `struct Perturbation { q: Quadric, factor: vec4<f32> }`
/// (`factor.x`; the anchor `factor.yzw`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuPerturbation {
    /// Its quadric, about the anchor.
    pub q: GpuQuadric,
    /// `[factor, anchor.x, anchor.y, anchor.z]`.
    pub factor: [f32; 4],
}

/// An object: base quadric, bounding box, and its range of perturbations,
/// all in the object's own frame: the GPU's coordinates (world
/// coordinates less the frame's `render::rebase_point`) less `origin` (the
/// point the CPU object's quadrics are written about, `Object::origin`,
/// there, rounded to f32; 0 for an unbounded object). f32 quadric
/// coefficients expanded about the world origin lose about `M^2 2^-24` at
/// distance `M` from it, and an object far from the origin for its size
/// came out visibly wrong (docs/gpu.md, "Precision"); about its own base's
/// point they hold its size's precision.
/// WGSL: `struct Object { base: Quadric, bmin: vec4<f32>, bmax: vec4<f32>,
/// range: vec4<u32>, origin: vec4<f32> }` (`range.x` first perturbation,
/// `range.y` count, `range.z` material, `range.w` the root of its
/// perturbations' hierarchy in [`GpuScene::nodes`], [`NO_NODE`] when it
/// has none).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuObject {
    /// Base quadric `F`, in the object's frame.
    pub base: GpuQuadric,
    /// Box minimum in the object's frame (`w` unused).
    pub bmin: [f32; 4],
    /// Box maximum in the object's frame (`w` unused).
    pub bmax: [f32; 4],
    /// `[first perturbation, count, material index, hierarchy root]`.
    pub range: [u32; 4],
    /// The object's frame: its origin in the GPU's coordinates; `w`, the
    /// object's length (`isolux_geometry::Object::length`: its box's
    /// largest side, at most 1; an unbounded object's, its scene's bounded
    /// objects'), which scales the walk's tolerances in units of length
    /// (geometry.wgsl `object_hit`) and the offset of rays leaving its
    /// surface (render.wgsl `object_floor`), so that they hold in any
    /// unit and beside objects of other sizes.
    pub origin: [f32; 4],
    /// The base quadric's anchor in the object's frame (`w` unused): the
    /// base is written about it, and evaluated at `x - anchor` for a point
    /// `x` of the frame (`base_local`), as each perturbation about its own
    /// ([`GpuPerturbation`]).
    pub anchor: [f32; 4],
}

/// `GpuObject.range.w` of an object without perturbations.
pub const NO_NODE: u32 = u32::MAX;

/// A node of a bounding volume hierarchy, depth-first (a node's first
/// child follows it, its second child follows the first's subtree), with
/// a skip link: the node after its subtree. A traversal needs no stack
/// (geometry.wgsl): from a node whose box the ray meets it goes on to the
/// next node in the array (an interior node's first child) or, after a
/// leaf's items, to the skip link; from one it misses, to the skip link.
/// It visits the nodes in the order a stack (first child descended, second
/// pushed) would. WGSL: `struct BvhNode { bmin: vec4<f32>, bmax:
/// vec4<f32>, link: vec4<u32> }`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuBvhNode {
    /// Box minimum (`w` unused).
    pub bmin: [f32; 4],
    /// Box maximum (`w` unused).
    pub bmax: [f32; 4],
    /// `[skip, count, item, item]`: `skip` the node after this one's
    /// subtree ([`NO_NODE`] past the hierarchy's last node); `count` 0 for
    /// an interior node, else the leaf's items (1 or 2: object indices at
    /// the top level, absolute perturbation indices under an object).
    pub link: [u32; 4],
}

/// A ray: origin with `t_min` in `w`, direction with `t_max` in `w`.
/// WGSL: `struct Ray { o: vec4<f32>, d: vec4<f32> }`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuRay {
    /// `[x, y, z, t_min]`.
    pub o: [f32; 4],
    /// `[x, y, z, t_max]`.
    pub d: [f32; 4],
}

/// A hit: `[t, nx, ny, nz]`, `t < 0` for a miss.
/// WGSL: `vec4<f32>`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuHit {
    /// `[t, nx, ny, nz]`.
    pub v: [f32; 4],
}

/// Objects and their perturbations, flattened for upload, with the
/// hierarchies the traversal reads: the one over the objects' boxes (root
/// at node 0 when there are objects) and one per object over its
/// perturbations' supports clipped to the object's box.
#[derive(Clone, Debug, Default)]
pub struct GpuScene {
    /// Objects.
    pub objects: Vec<GpuObject>,
    /// All perturbations, each object's contiguous.
    pub perturbations: Vec<GpuPerturbation>,
    /// Every hierarchy's nodes, the objects' first.
    pub nodes: Vec<GpuBvhNode>,
}

/// Boxes are clamped to +-1e30 for f32.
fn clamp_box(b: &Aabb) -> ([f32; 4], [f32; 4]) {
    let lo = |v: f64| round_down(v.clamp(-1e30, 1e30));
    let hi = |v: f64| round_up(v.clamp(-1e30, 1e30));
    (
        [lo(b.min.x), lo(b.min.y), lo(b.min.z), 0.0],
        [hi(b.max.x), hi(b.max.y), hi(b.max.z), 0.0],
    )
}

/// The largest f32 at most `v` (finite `v`): a box's lower corner rounded
/// outward, so that the f32 box still holds what the f64 one does (rounded
/// to nearest, a face could move inside a surface that touches it, a
/// sphere's pole, by half a unit in the last place).
fn round_down(v: f64) -> f32 {
    let f = v as f32;
    if f as f64 <= v {
        return f;
    }
    if f > 0.0 {
        f32::from_bits(f.to_bits() - 1)
    } else if f < 0.0 {
        f32::from_bits(f.to_bits() + 1)
    } else {
        -f32::from_bits(1)
    }
}

/// The smallest f32 at least `v` (finite `v`): a box's upper corner
/// rounded outward ([`round_down`]).
fn round_up(v: f64) -> f32 {
    -round_down(-v)
}

/// The origin of an object's frame (`GpuObject::origin`), from the GPU's
/// origin `at` (the camera, for a frame): the point of the object's box
/// nearest it, rounded to f32 (the kernels subtract that f32 value, so the
/// quadrics are moved by exactly the rounding), or the GPU's origin itself
/// for an unbounded object. The kernels walk each ray in this frame, so
/// that its points near where rays from the camera meet the object are
/// held to f32's precision at the object's distance from the camera; each
/// quadric is written about its own anchor ([`anchor_in`]), near where it
/// acts, so that the frame does not need to lie near it.
///
/// Before 2026-12-06 the frame was the point the CPU object's quadrics
/// are written about (`Object::origin`), or an ellipsoid base's centre,
/// and every quadric was written about it. A perturbation far from that
/// point carried a constant term of its distance squared, whose f32
/// rounding (in the buffer, and in every evaluation) moved its surface by
/// the distance squared times 2^-24 over its slope: small bumps on a
/// sphere of radius 100 (a planet, its frame at its centre) were hit 1e-4
/// to 1e-2 units off, beyond the rays' spawn offset; a bump's blob around
/// the camera on a base 3000 units away, 0.03 units off, and rendered
/// twice as bright (`conformance.rs`, `bumps_far_from_their_frame_are_hit_precisely`,
/// `far_bases_are_hit_in_f32`). With each quadric about its anchor, a
/// base sphere of radius 1000 still lost 6e-5 units to its points' rounding
/// about its centre; about the point nearest the camera, 2e-7.
fn object_origin(o: &Object, at: DVec3) -> DVec3 {
    anchor_in(&o.bbox().translated(-at))
}

/// The anchor of a quadric acting on the box `b` of its object's frame
/// (the base's positive region, or a perturbation's support, clipped to
/// the object's box): the point of `b` nearest the frame's zero, rounded
/// to f32; the zero itself for an empty or unbounded box. About it the
/// quadric's terms are as small as its region where it acts: a thin disc's
/// (`thin_discs_are_bounded_and_hit`: a disc 2e-4 thick written about a
/// point 0.3 off it has a constant term of 9e6, whose f32 rounding is half
/// the term that makes the disc), a small sphere's far from the frame
/// (`a_far_support_keeps_the_base_precise`), a bump's on a large base.
fn anchor_in(b: &Aabb) -> DVec3 {
    if b.is_empty() || !b.is_finite() {
        return DVec3::ZERO;
    }
    f32_exact(DVec3::ZERO.clamp(b.min, b.max))
}

/// `v` rounded to f32, back in f64: a point the kernels hold exactly.
pub(crate) fn f32_exact(v: DVec3) -> DVec3 {
    DVec3::new(v.x as f32 as f64, v.y as f32 as f64, v.z as f32 as f64)
}

/// `b` as the kernels see it: clamped and rounded to f32, back in f64 (the
/// boxes the hierarchies are built over).
fn uploaded_box(b: &Aabb) -> Aabb {
    let (a, c) = clamp_box(b);
    let v = |x: [f32; 4]| DVec3::new(x[0] as f64, x[1] as f64, x[2] as f64);
    Aabb::new(v(a), v(c))
}

/// Perturbation `p`'s support clipped to its object's box `bbox` (an
/// unbounded support takes the whole box); empty when it misses the box,
/// where it never acts.
fn support_box(p: &isolux_geometry::Perturbation, bbox: &Aabb) -> Aabb {
    p.quadric
        .positive_bounds()
        .map_or(*bbox, |pb| pb.intersection(bbox))
}

/// Appends `boxes`' hierarchy to `nodes`, leaf items mapped by `item`;
/// returns its root.
fn push_bvh(nodes: &mut Vec<GpuBvhNode>, boxes: &[Aabb], item: impl Fn(u32) -> u32) -> u32 {
    let root = nodes.len() as u32;
    let flat = Bvh::build(boxes).flatten();
    // Subtree sizes, children (later in depth-first order) first: an
    // interior node's second child follows its first child's subtree.
    let mut size = vec![1u32; flat.len()];
    for (i, (_, second, items)) in flat.iter().enumerate().rev() {
        if items.is_empty() {
            debug_assert_eq!(*second as usize, i + 1 + size[i + 1] as usize);
            size[i] = 1 + size[i + 1] + size[*second as usize];
        }
    }
    for (i, (b, _, items)) in flat.iter().enumerate() {
        let (bmin, bmax) = clamp_box(b);
        let end = i as u32 + size[i];
        let skip = if end as usize == flat.len() {
            NO_NODE
        } else {
            root + end
        };
        let link = match items.as_slice() {
            [] => [skip, 0, 0, 0],
            [a] => [skip, 1, item(*a), 0],
            [a, b] => [skip, 2, item(*a), item(*b)],
            _ => unreachable!("BVH leaves hold at most {LEAF_SIZE} items"),
        };
        nodes.push(GpuBvhNode { bmin, bmax, link });
    }
    root
}

impl GpuScene {
    /// Flattens `objects` (material index 0 for all). Unbounded boxes are
    /// clamped to +-1e30.
    pub fn new(objects: &[Object]) -> Self {
        Self::with_materials(objects, &vec![0; objects.len()])
    }

    /// Flattens `objects`, object `i` wearing material `material[i]`.
    pub fn with_materials(objects: &[Object], material: &[usize]) -> Self {
        Self::with_materials_at(objects, material, DVec3::ZERO)
    }

    /// [`GpuScene::with_materials`] with the world moved by `-at`: what the
    /// kernels call the origin is the world point `at` (the camera, for a
    /// frame: `render::rebase_point`), so that f32 coordinates are finest
    /// around it. `at` should be representable in f32.
    pub fn with_materials_at(objects: &[Object], material: &[usize], at: DVec3) -> Self {
        let mut s = Self::default();
        let boxes: Vec<Aabb> = objects
            .iter()
            .map(|o| uploaded_box(&o.bbox().translated(-at)))
            .collect();
        if !objects.is_empty() {
            push_bvh(&mut s.nodes, &boxes, |i| i);
        }
        for (o, &mi) in objects.iter().zip(material) {
            let first = s.perturbations.len() as u32;
            // Everything of the object in its own frame (`GpuObject`):
            // `origin` from `at` as uploaded, the frame's world point
            // `at + origin` exactly. The CPU object's quadrics are written
            // about its own origin (`Object::origin`), which `origin` is to
            // f32's rounding, so they move by that rounding only (by the
            // GPU's origin for an unbounded object).
            let origin = object_origin(o, at);
            let shift = o.origin() - (at + origin);
            let local = |q: &Quadric| q.translated(shift);
            let bbox = o.bbox().translated(-(at + origin));
            // Supports clipped to the object's box.
            let mut live = Vec::new();
            let mut pboxes = Vec::new();
            for (i, p) in o.perturbations().iter().enumerate() {
                let p = isolux_geometry::Perturbation {
                    quadric: local(&p.quadric),
                    factor: p.factor,
                };
                let b = support_box(&p, &bbox);
                let anchor = anchor_in(&b);
                s.perturbations.push(GpuPerturbation {
                    q: GpuQuadric::new(&p.quadric.translated(-anchor)),
                    factor: [
                        p.factor as f32,
                        anchor.x as f32,
                        anchor.y as f32,
                        anchor.z as f32,
                    ],
                });
                if !b.is_empty() {
                    live.push(first + i as u32);
                    pboxes.push(uploaded_box(&b));
                }
            }
            let root = if pboxes.is_empty() {
                NO_NODE
            } else {
                push_bvh(&mut s.nodes, &pboxes, |k| live[k as usize])
            };
            let (bmin, bmax) = clamp_box(&bbox);
            let base = local(o.base());
            let base_box = base
                .positive_bounds()
                .map_or(bbox, |pb| pb.intersection(&bbox));
            let anchor = anchor_in(&base_box);
            s.objects.push(GpuObject {
                base: GpuQuadric::new(&base.translated(-anchor)),
                bmin,
                bmax,
                range: [first, o.perturbations().len() as u32, mi as u32, root],
                origin: [
                    origin.x as f32,
                    origin.y as f32,
                    origin.z as f32,
                    o.length().max(1e-30) as f32,
                ],
                anchor: [anchor.x as f32, anchor.y as f32, anchor.z as f32, 0.0],
            });
        }
        s
    }
}

/// Material tags (`Material.tag.x` in WGSL; constants `MAT_*` of the
/// generated prelude). The models on the GPU; see [`GpuMaterials::new`].
pub mod tag {
    /// Lambertian.
    pub const DIFFUSE: u32 = 0;
    /// Normalized Phong over a Lambertian base.
    pub const PHONG: u32 = 1;
    /// Bounded Blinn-Phong over a Lambertian base.
    pub const BLINN_PHONG: u32 = 2;
    /// GGX microfacet reflection.
    pub const GGX: u32 = 3;
    /// Beckmann microfacet reflection.
    pub const BECKMANN: u32 = 4;
    /// Smooth conductor mirror.
    pub const CONDUCTOR: u32 = 5;
    /// Smooth dielectric (glass).
    pub const DIELECTRIC: u32 = 6;
    /// Dielectric-coated diffuse.
    pub const PLASTIC: u32 = 7;
    /// Bounded Ward over a Lambertian base.
    pub const WARD: u32 = 8;
    /// Cook-Torrance over a Fresnel-weighted Lambertian base.
    pub const COOK_TORRANCE: u32 = 9;
    /// The seed's Gaussian highlight over a Lambertian base.
    pub const GAUSSIAN: u32 = 10;
    /// Heidrich-Seidel fibres, isotropic Phong lobe, Lambertian base.
    pub const HEIDRICH_SEIDEL: u32 = 11;
    /// A weighted mixture of other GPU materials (flattened).
    pub const MIX: u32 = 12;
    /// A factored BRDF `scale p(wo) q(h) p(wi)` from its texel maps.
    pub const FACTORED: u32 = 13;
    /// The local (BRDF) approximation of a translucent medium: dipole
    /// diffuse reflectance, single scattering, a smooth Fresnel mirror.
    pub const SUBSURFACE_BRDF: u32 = 14;
    /// A MERL measured BRDF, its table in the material data.
    pub const MERL: u32 = 15;
    /// A translucent medium behind a smooth dielectric boundary (dipole
    /// BSSRDF or random walk, in the integrator).
    pub const SUBSURFACE: u32 = 16;
    /// Internal (never in a scene): the single-scattering lobe at the exit
    /// point of a `subsurface` material, which the integrator builds from
    /// it for next-event estimation (`a.w` eta, `b` albedo and g).
    pub const SSS_SINGLE_LOBE: u32 = 17;
    /// Internal: the entry side's angular factor `S_w` of the dipole
    /// BSSRDF at the entry point (`a.x` ior, `a.w` `1 - F_dr,ext`).
    pub const SSS_ENTRY_LOBE: u32 = 18;
    /// Wave-optics diffraction from a heightfield (`wave.wgsl`).
    pub const WAVE: u32 = 19;
    /// Every tag with its WGSL name, for the prelude.
    pub const ALL: [(&str, u32); 20] = [
        ("MAT_DIFFUSE", DIFFUSE),
        ("MAT_PHONG", PHONG),
        ("MAT_BLINN_PHONG", BLINN_PHONG),
        ("MAT_GGX", GGX),
        ("MAT_BECKMANN", BECKMANN),
        ("MAT_CONDUCTOR", CONDUCTOR),
        ("MAT_DIELECTRIC", DIELECTRIC),
        ("MAT_PLASTIC", PLASTIC),
        ("MAT_WARD", WARD),
        ("MAT_COOK_TORRANCE", COOK_TORRANCE),
        ("MAT_GAUSSIAN", GAUSSIAN),
        ("MAT_HEIDRICH_SEIDEL", HEIDRICH_SEIDEL),
        ("MAT_MIX", MIX),
        ("MAT_FACTORED", FACTORED),
        ("MAT_SUBSURFACE_BRDF", SUBSURFACE_BRDF),
        ("MAT_MERL", MERL),
        ("MAT_SUBSURFACE", SUBSURFACE),
        ("MAT_SSS_SINGLE_LOBE", SSS_SINGLE_LOBE),
        ("MAT_SSS_ENTRY_LOBE", SSS_ENTRY_LOBE),
        ("MAT_WAVE", WAVE),
    ];
}

/// Microfacet distributions of `cook_torrance` and `gaussian`
/// (`Material.tag.w & 3`; prelude constants `DIST_*`); bit 2 of `tag.w`
/// selects Smith masking over the V-groove term.
pub mod distribution {
    /// GGX.
    pub const GGX: u32 = 0;
    /// Beckmann.
    pub const BECKMANN: u32 = 1;
    /// The seed's Gaussian, tabulated (table in the material data).
    pub const GAUSSIAN: u32 = 2;
    /// The Smith masking bit.
    pub const SMITH: u32 = 4;
    /// Every constant with its WGSL name.
    pub const ALL: [(&str, u32); 4] = [
        ("DIST_GGX", GGX),
        ("DIST_BECKMANN", BECKMANN),
        ("DIST_GAUSSIAN", GAUSSIAN),
        ("DIST_SMITH", SMITH),
    ];
}

/// Fresnel kinds (`Material.tag.y`; prelude constants `FRESNEL_*`),
/// mirroring [`isolux_materials::Fresnel`].
pub mod fresnel_kind {
    /// `F = 1`.
    pub const ONE: u32 = 0;
    /// Dielectric of index `b.x`.
    pub const DIELECTRIC: u32 = 1;
    /// Conductor `eta = b.rgb`, `k = c.rgb`.
    pub const CONDUCTOR: u32 = 2;
    /// Schlick with `f0 = b.rgb`.
    pub const SCHLICK: u32 = 3;
    /// Every kind with its WGSL name.
    pub const ALL: [(&str, u32); 4] = [
        ("FRESNEL_ONE", ONE),
        ("FRESNEL_DIELECTRIC", DIELECTRIC),
        ("FRESNEL_CONDUCTOR", CONDUCTOR),
        ("FRESNEL_SCHLICK", SCHLICK),
    ];
}

/// A material of the GPU library. WGSL: `struct Material { tag:
/// vec4<u32>, a: vec4<f32>, b: vec4<f32>, c: vec4<f32>, d: vec4<f32>, e:
/// vec4<f32>, idx: vec4<u32> }`; the meaning of the blocks per tag is in
/// [`GpuMaterials::new`] and `materials.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMaterial {
    /// `[model tag, Fresnel kind, has tangent, model flag]`.
    pub tag: [u32; 4],
    /// First parameter block.
    pub a: [f32; 4],
    /// Second parameter block.
    pub b: [f32; 4],
    /// Third parameter block.
    pub c: [f32; 4],
    /// Tangent hint (`xyz`), or parameters for models without a tangent.
    pub d: [f32; 4],
    /// Fifth parameter block.
    pub e: [f32; 4],
    /// `[material data offset, first mix component, mix components, the
    /// mix's wave component + 1 (0: none)]`.
    pub idx: [u32; 4],
}

fn rgb4(c: Rgb, w: f64) -> [f32; 4] {
    [c.r as f32, c.g as f32, c.b as f32, w as f32]
}

/// Sets the Fresnel kind and blocks `b`, `c` of `m`.
fn put_fresnel(m: &mut GpuMaterial, f: &Fresnel) {
    match *f {
        Fresnel::One => m.tag[1] = fresnel_kind::ONE,
        Fresnel::Dielectric { ior } => {
            m.tag[1] = fresnel_kind::DIELECTRIC;
            m.b = [ior as f32, 0.0, 0.0, 0.0];
        }
        Fresnel::Conductor { eta, k } => {
            m.tag[1] = fresnel_kind::CONDUCTOR;
            m.b = rgb4(eta, 0.0);
            m.c = rgb4(k, 0.0);
        }
        Fresnel::Schlick { f0 } => {
            m.tag[1] = fresnel_kind::SCHLICK;
            m.b = rgb4(f0, 0.0);
        }
    }
}

/// The probability with which a diffuse + lobe model samples its lobe
/// (`DiffuseLobe::p_lobe`, computed here in f64 once).
fn p_lobe(reflectance: Rgb, specular: Rgb) -> f64 {
    let d = reflectance.luminance().max(0.0);
    let s = specular.luminance().max(0.0);
    if d + s > 0.0 {
        s / (d + s)
    } else {
        0.5
    }
}

/// Whether `m` has a GPU implementation: a `mix` when all its components
/// have (with any number of `wave` leaves, of which the kernels evaluate
/// one per hit, chosen at random: docs/gpu.md, "Inside a `mix`").
pub fn supported(m: &Material) -> bool {
    match m {
        // A medium inside a mix is its boundary alone ([`flatten_mix`]).
        Material::Mix(_) => {
            let c = flatten_mix(m, 1.0, 1.0);
            c.iter().all(|(m, ..)| is_void(m) || supported(m))
        }
        // Without copying its kernels.
        Material::Wave(_) => true,
        _ => GpuMaterials::default().leaf(m).is_some(),
    }
}

/// The leaf [`flatten_mix`] puts in the place of a mix whose weights are
/// all zero: an empty mix (which scene files cannot write).
fn void_leaf() -> Material {
    Material::Mix(isolux_materials::Mix { components: vec![] })
}

fn is_void(m: &Material) -> bool {
    matches!(m, Material::Mix(x) if x.components.is_empty())
}

/// The leaves of a (nested) mix with their weight in `f` and their
/// selection probability: `f = sum w_i f_i`, component `i` sampled with
/// probability `p_i`, exactly as the CPU's nested choice. A `subsurface`
/// leaf becomes its boundary (a smooth `dielectric`): the CPU's integrator
/// enters a medium only through a material that is one, and evaluates a
/// medium inside a mix as its boundary's BSDF (`Subsurface`'s
/// `BxdfModel`), so a path refracted through it carries on as through
/// glass, on both back ends.
///
/// A mix whose weights are all zero is black and draws no sample on the
/// CPU (`Mix::sample`): in its place comes a *void* leaf (an empty mix, see
/// [`GpuMaterials::mix`]) of weight 0 and of the mix's selection
/// probability, which draws nothing, then its own leaves with weight and
/// probability 0, which keep their place in the order that gives the
/// shading frame its tangent (the first leaf's that has one, on the CPU
/// too).
fn flatten_mix(m: &Material, w: f64, p: f64) -> Vec<(Material, f64, f64)> {
    let Material::Mix(mix) = m else {
        let leaf = match m {
            Material::Subsurface(s) => Material::Dielectric(s.boundary),
            _ => m.clone(),
        };
        return vec![(leaf, w, p)];
    };
    let total: f64 = mix.components.iter().map(|c| c.1).sum();
    if !(total > 0.0) {
        let mut out = vec![(void_leaf(), 0.0, p)];
        for (c, _) in &mix.components {
            out.extend(flatten_mix(c, 0.0, 0.0));
        }
        return out;
    }
    let mut out = Vec::new();
    for (c, cw) in &mix.components {
        out.extend(flatten_mix(c, w * cw, p * cw / total));
    }
    out
}

/// The materials of a scene on the GPU: one [`GpuMaterial`] per scene
/// material at the same index, then the components of mixtures, and the
/// material data (sampling tables) they point into.
#[derive(Clone, Debug, Default)]
pub struct GpuMaterials {
    /// Materials; the first ones mirror the scene's, index for index.
    pub materials: Vec<GpuMaterial>,
    /// Tables (`f32`), addressed by `GpuMaterial::idx[0]`.
    pub data: Vec<f32>,
    /// Kernel and leaf-box offsets of the wave surfaces already copied,
    /// by address: materials sharing a heightfield share its copy.
    surfaces: Vec<(usize, u32, u32)>,
}

impl GpuMaterials {
    /// The GPU mirror of `materials`, or the index of the first one not on
    /// the GPU (see [`supported`]).
    ///
    /// | tag | a | b | c | d | e |
    /// |---|---|---|---|---|---|
    /// | diffuse | reflectance | | | | |
    /// | phong, blinn_phong | reflectance | specular | exponent, p(lobe) | | |
    /// | ward | reflectance | specular | alpha_x, p(lobe), alpha_y | tangent | |
    /// | ggx, beckmann | alpha_x, alpha_y | Fresnel | Fresnel | tangent | |
    /// | cook_torrance | reflectance, p(specular) | Fresnel | Fresnel | alpha_x, alpha_y, m, norm | |
    /// | gaussian | reflectance, p(specular) | specular | | alpha, alpha, m, norm | |
    /// | heidrich_seidel | reflectance, exponent | specular, norm | isotropic | tangent | p(diffuse), p(fibre), p(isotropic), sigma |
    /// | conductor | | Fresnel | Fresnel | | |
    /// | dielectric | ior | | | | |
    /// | plastic | reflectance | ior, coat alpha, F_dr(internal) | | | |
    /// | mix | | | | the frame's tangent (fixed, or the `wave`'s, placed) | the `wave` component's `e` (placed) |
    /// | factored | scale | | | | |
    /// | subsurface_brdf | R_d, eta | single-scattering albedo, g | | | |
    /// | merl | | | | | |
    /// | subsurface | ior, g, r_max, `1 - F_dr,ext` | sigma_s, single scattering (0/1) | sigma_a | | |
    /// | wave | texel_um, coherence_um, um_per_unit, wavelengths | mapping centre, mapping code | columns, rows, leaf columns, leaf rows | tangent (placed) | centre x, y (um), sigma (um), comb offset (placed) |
    ///
    /// `cook_torrance` and `gaussian` keep the distribution in `tag.w`
    /// ([`distribution`]); the Gaussian's sampling table is `[n, cdf (n +
    /// 1), pdf per bin (n)]` at `idx[0]` of `data`. A mix's components are
    /// `idx[2]` materials from `idx[1]`, their weights `(w_k, p_k)` in
    /// `f` and in the choice of a sample at `idx[0]` of `data`; `tag[3] -
    /// 1` is its `wave` component (0: none), placed once per hit into the
    /// mix's `e`; `idx[3]` is 1 when the frame's tangent is the placed
    /// `wave`'s (else a fixed tangent, if any, is in `d`, with `tag[2]`
    /// 1). A `factored` material's data at
    /// `idx[0]`: `res`, then `ln p` and `ln q` per texel (3 floats each,
    /// row-major, stand-ins substituted), then the half-vector density's
    /// marginal table and its `res` conditional tables (each `[n, cdf,
    /// pdf]`, `2 res + 2` floats); at `idx[1]`: `n`, the side of the `r(theta_h,
    /// theta_d)` table (0: none), then `ln r` per texel (3 floats each,
    /// row-major, rows `theta_h`). A `subsurface` material keeps its mode
    /// in `tag.w` (0 dipole, 1 random walk; in random-walk mode `tag.y - 1` is
    /// the offset of its table of the materials seen from inside it,
    /// `GpuMaterials::relative_in_media`), its per-channel dipoles at
    /// `idx[0]` (`sigma_tr, z_r, z_v, alpha'` for r, g, b, then the
    /// scale of the single-scattering term per channel,
    /// `Subsurface::single_scattering_scale`, then the real-time mode's local
    /// BRDF, `Subsurface::local_brdf`: `R_d` and the single-scattering
    /// albedo per channel) and the radial
    /// sampling tables of the channels at `idx[1..4]` (each `[n, cdf,
    /// pdf]`), all in scene units. A `wave` material keeps `model |
    /// obliquity << 1` in `tag.w` and its Fresnel kind in `tag.y` (ONE,
    /// DIELECTRIC or CONDUCTOR: a measured metal); its kernels `[h, gx,
    /// gy]` per texel (row-major) at `idx[0]`, the leaf slope boxes at
    /// `idx[1]` (4 floats each), at `idx[2]` `[eps, ior, metal rows, the
    /// 81 normalized sRGB nodes of the CIE table (3 floats each), the metal's
    /// rows (lambda um, n, k)]`, and `idx[3]` 1 when culling by the leaves.
    /// The mapping code is the planar axis (0, 1, 2), 3 spherical or 4
    /// cylindrical; `d` and `e` are filled per shading point by
    /// `place_material` (`wave.wgsl`), as `Wave::at_point` does on the CPU.
    pub fn new(materials: &[Material]) -> Result<Self, usize> {
        let mut out = GpuMaterials {
            materials: vec![GpuMaterial::default(); materials.len()],
            ..Default::default()
        };
        for (i, m) in materials.iter().enumerate() {
            if !supported(m) {
                return Err(i);
            }
            out.materials[i] = match m {
                Material::Mix(_) => out.mix(m).ok_or(i)?,
                _ => out.leaf(m).ok_or(i)?,
            };
        }
        out.relative_in_media(materials)?;
        Ok(out)
    }

    /// The materials seen from inside each random-walk medium of
    /// `materials` (a surface under water meets water): for each, a table
    /// in `data` of one material index per scene material, that
    /// material's record with its indices relative to the medium's
    /// (`Material::relative_to`, a record of its own after the others) or
    /// the material itself where nothing changes. The medium's `tag[1]`
    /// holds the table's offset + 1 (0: no table); the path tracer's
    /// `bounce` looks up every hit of a path inside the medium through it.
    fn relative_in_media(&mut self, materials: &[Material]) -> Result<(), usize> {
        use isolux_materials::subsurface_material::SubsurfaceMode;
        for (j, m) in materials.iter().enumerate() {
            let Material::Subsurface(s) = m else {
                continue;
            };
            if s.mode != SubsurfaceMode::RandomWalk {
                continue;
            }
            let mut table = Vec::with_capacity(materials.len());
            for (i, x) in materials.iter().enumerate() {
                let k = match x.relative_to(s.boundary.ior) {
                    Some(r) => {
                        let g = match r {
                            Material::Mix(_) => self.mix(&r),
                            _ => self.leaf(&r),
                        };
                        self.materials.push(g.ok_or(i)?);
                        self.materials.len() - 1
                    }
                    None => i,
                };
                table.push(k as f32);
            }
            self.materials[j].tag[1] = self.data.len() as u32 + 1;
            self.data.extend(table);
        }
        Ok(())
    }

    /// A mix: its flattened leaves as records of their own after the
    /// scene's, their weights `(w_k, p_k)` in `data` (any number of
    /// leaves), its first `wave` leaf + 1 in `tag[3]` (0: none), the sums
    /// of its `wave` leaves' weights and probabilities and their count in
    /// `a` (`[W, P, count, 0]`), and the frame's tangent: the first leaf's
    /// that has one, as on the CPU, written here, or placed per hit when
    /// that leaf is the first `wave` (`idx[3]` 1; `place_material`).
    ///
    /// With several `wave` leaves the kernels evaluate one per hit:
    /// `place_material` chooses leaf `j` with probability `w_j / W` and
    /// gives it the weight `W` and probability `P` of them all (the
    /// others count zero), so that `f` is `sum_k w_k f_k` in expectation
    /// (docs/gpu.md, "Inside a `mix`").
    fn mix(&mut self, m: &Material) -> Option<GpuMaterial> {
        let parts = flatten_mix(m, 1.0, 1.0);
        let mut g = GpuMaterial::default();
        g.tag[0] = tag::MIX;
        // The weights first: a leaf may append tables of its own.
        let weights = self.data.len() as u32;
        for (_, cw, cp) in &parts {
            self.data.extend([*cw as f32, *cp as f32]);
        }
        let first = self.materials.len();
        for (c, ..) in &parts {
            // A void leaf (a mix of zero weights, [`flatten_mix`]): a
            // record of the mix tag, which no case of the kernels' switches
            // over the leaves' models takes, so its f, pdf and flags are 0
            // and it draws no sample.
            let leaf = if is_void(c) {
                GpuMaterial {
                    tag: [tag::MIX, 0, 0, 0],
                    ..Default::default()
                }
            } else {
                self.leaf(c)?
            };
            self.materials.push(leaf);
        }
        let is_wave = |c: &Material| matches!(c, Material::Wave(_));
        if let Some(k) = parts.iter().position(|(c, ..)| is_wave(c)) {
            g.tag[3] = k as u32 + 1;
        }
        let waves = parts.iter().filter(|(c, ..)| is_wave(c));
        let (w, p, n) = waves.fold((0.0, 0.0, 0), |(w, p, n), (_, cw, cp)| {
            (w + cw, p + cp, n + 1)
        });
        g.a = [w as f32, p as f32, n as f32, 0.0];
        let mut tangent_is_wave = 0;
        match parts.iter().find_map(|(c, ..)| Some((c, c.tangent()?))) {
            Some((c, _)) if is_wave(c) => tangent_is_wave = 1,
            Some((_, t)) => {
                g.tag[2] = 1;
                g.d = [t.x as f32, t.y as f32, t.z as f32, 0.0];
            }
            None => {}
        }
        g.idx = [weights, first as u32, parts.len() as u32, tangent_is_wave];
        Some(g)
    }

    /// Appends a sampling table; returns its offset.
    fn table(&mut self, t: &isolux_core::Distribution1D) -> u32 {
        let at = self.data.len() as u32;
        let n = t.len();
        self.data.push(n as f32);
        self.data.extend(t.cdf().iter().map(|&c| c as f32));
        self.data.extend((0..n).map(|i| t.pdf_bin(i) as f32));
        at
    }

    fn leaf(&mut self, m: &Material) -> Option<GpuMaterial> {
        use isolux_materials::cook_torrance::{Masking, NormalDistribution};
        let mut g = GpuMaterial::default();
        let tangent = |g: &mut GpuMaterial, t: Option<glam::DVec3>| {
            if let Some(t) = t {
                g.tag[2] = 1;
                g.d = [t.x as f32, t.y as f32, t.z as f32, 0.0];
            }
        };
        match m {
            Material::Diffuse(d) => {
                g.tag[0] = tag::DIFFUSE;
                g.a = rgb4(d.reflectance, 0.0);
            }
            Material::Phong(p) => {
                g.tag[0] = tag::PHONG;
                g.a = rgb4(p.0.reflectance, 0.0);
                g.b = rgb4(p.0.specular, 0.0);
                let pl = p_lobe(p.0.reflectance, p.0.specular);
                g.c = [p.0.lobe.exponent as f32, pl as f32, 0.0, 0.0];
            }
            Material::BlinnPhong(p) => {
                g.tag[0] = tag::BLINN_PHONG;
                g.a = rgb4(p.0.reflectance, 0.0);
                g.b = rgb4(p.0.specular, 0.0);
                let pl = p_lobe(p.0.reflectance, p.0.specular);
                g.c = [p.0.lobe.exponent as f32, pl as f32, 0.0, 0.0];
            }
            Material::Ward(w) => {
                g.tag[0] = tag::WARD;
                let i = &w.inner;
                g.a = rgb4(i.reflectance, 0.0);
                g.b = rgb4(i.specular, 0.0);
                let pl = p_lobe(i.reflectance, i.specular);
                g.c = [i.lobe.alpha_x as f32, pl as f32, i.lobe.alpha_y as f32, 0.0];
                tangent(&mut g, w.tangent);
            }
            Material::Ggx(x) => {
                g.tag[0] = tag::GGX;
                let d = &x.lobe.distribution;
                g.a = [d.alpha_x as f32, d.alpha_y as f32, 0.0, 0.0];
                put_fresnel(&mut g, &x.lobe.fresnel);
                tangent(&mut g, x.tangent);
            }
            Material::Beckmann(x) => {
                g.tag[0] = tag::BECKMANN;
                let d = &x.lobe.distribution;
                g.a = [d.alpha_x as f32, d.alpha_y as f32, 0.0, 0.0];
                put_fresnel(&mut g, &x.lobe.fresnel);
                tangent(&mut g, x.tangent);
            }
            Material::CookTorrance(_) | Material::Gaussian(_) => {
                let (ct, specular) = match m {
                    Material::CookTorrance(ct) => (ct, None),
                    Material::Gaussian(ga) => (&ga.inner, Some(ga.specular)),
                    _ => unreachable!(),
                };
                put_fresnel(&mut g, &ct.fresnel);
                g.a = rgb4(ct.reflectance, ct.p_specular());
                let mut flag = match (&ct.distribution, ct.masking) {
                    (_, Masking::Smith) => distribution::SMITH,
                    _ => 0,
                };
                match &ct.distribution {
                    NormalDistribution::Analytic(d) => {
                        flag |= match d.kind {
                            isolux_materials::microfacet::Kind::Ggx => distribution::GGX,
                            isolux_materials::microfacet::Kind::Beckmann => distribution::BECKMANN,
                        };
                        g.d = [d.alpha_x as f32, d.alpha_y as f32, 0.0, 0.0];
                    }
                    NormalDistribution::Gaussian(gd) => {
                        // Smith is defined for Beckmann and GGX only: the
                        // CPU falls back to the V-groove term.
                        flag = distribution::GAUSSIAN;
                        g.d = [1.0, 1.0, gd.m as f32, gd.normalization() as f32];
                        g.idx[0] = self.table(gd.table());
                    }
                }
                g.tag[3] = flag;
                match specular {
                    None => g.tag[0] = tag::COOK_TORRANCE,
                    Some(s) => {
                        g.tag[0] = tag::GAUSSIAN;
                        g.b = rgb4(s, 0.0);
                    }
                }
            }
            Material::HeidrichSeidel(h) => {
                g.tag[0] = tag::HEIDRICH_SEIDEL;
                g.a = rgb4(h.reflectance, h.exponent);
                g.b = rgb4(h.specular, h.normalization());
                g.c = rgb4(h.isotropic, 0.0);
                let [pd, ps, pi] = h.weights();
                g.e = [pd as f32, ps as f32, pi as f32, h.sigma() as f32];
                tangent(&mut g, h.tangent);
            }
            Material::Factored(f) => {
                g.tag[0] = tag::FACTORED;
                g.a = rgb4(f.scale(), 0.0);
                g.idx[0] = self.data.len() as u32;
                self.data.push(f.res() as f32);
                for map in [f.log_p_texels(), f.log_q_texels()] {
                    self.data
                        .extend(map.iter().flat_map(|t| t.map(|v| v as f32)));
                }
                let h = f.h_distribution();
                self.table(h.marginal());
                for c in h.conditionals() {
                    self.table(c);
                }
                // The r(theta_h, theta_d) table: n, then ln r per texel.
                g.idx[1] = self.data.len() as u32;
                self.data.push(f.r_res() as f32);
                self.data
                    .extend(f.log_r_texels().iter().flat_map(|t| t.map(|v| v as f32)));
            }
            Material::Conductor(c) => {
                g.tag[0] = tag::CONDUCTOR;
                put_fresnel(&mut g, &c.fresnel);
            }
            Material::Dielectric(d) => {
                g.tag[0] = tag::DIELECTRIC;
                g.a = [d.ior as f32, 0.0, 0.0, 0.0];
            }
            Material::Plastic(p) => {
                g.tag[0] = tag::PLASTIC;
                g.a = rgb4(p.reflectance, 0.0);
                let alpha = p.coat.map_or(0.0, |c| c.distribution.alpha_x);
                g.b = [p.ior as f32, alpha as f32, p.f_dr_internal() as f32, 0.0];
                g.tag[3] = p.coat.is_some() as u32;
            }
            Material::Merl(t) => {
                g.tag[0] = tag::MERL;
                g.idx[0] = self.data.len() as u32;
                self.data.extend_from_slice(t.table());
            }
            Material::SubsurfaceBrdf(b) => {
                g.tag[0] = tag::SUBSURFACE_BRDF;
                g.a = rgb4(b.r_d, b.eta);
                g.b = rgb4(b.single_albedo, b.g);
            }
            Material::Subsurface(m) => {
                use isolux_materials::subsurface_material::SubsurfaceMode;
                g.tag[0] = tag::SUBSURFACE;
                g.tag[3] = (m.mode == SubsurfaceMode::RandomWalk) as u32;
                g.a = [
                    m.boundary.ior as f32,
                    m.g as f32,
                    m.r_max() as f32,
                    m.sw_norm as f32,
                ];
                g.b = rgb4(m.sigma_s, m.single_scattering as u32 as f64);
                g.c = rgb4(m.sigma_a, 0.0);
                g.idx[0] = self.data.len() as u32;
                for d in &m.dipoles {
                    self.data
                        .extend([d.sigma_tr, d.z_r, d.z_v, d.albedo_reduced].map(|v| v as f32));
                }
                self.data
                    .extend(m.single_scattering_scale().to_array().map(|v| v as f32));
                let local = m.local_brdf();
                self.data.extend(local.r_d.to_array().map(|v| v as f32));
                self.data
                    .extend(local.single_albedo.to_array().map(|v| v as f32));
                for c in 0..3 {
                    g.idx[1 + c] = self.table(m.radial_table(c));
                }
            }
            Material::Wave(w) => self.wave(w, &mut g),
            _ => return None,
        }
        Some(g)
    }

    fn wave(&mut self, w: &isolux_materials::Wave, g: &mut GpuMaterial) {
        use isolux_materials::wave::{Mapping, WaveFresnel};
        let s = &w.surface;
        g.tag[0] = tag::WAVE;
        g.tag[3] = (w.model == isolux_wave::Model::Ohs) as u32
            | ((w.settings.obliquity == isolux_wave::Obliquity::Seed) as u32) << 1;
        g.a = [
            s.texel_um as f32,
            w.coherence_um as f32,
            w.um_per_unit as f32,
            w.wavelengths as f32,
        ];
        g.b = match w.mapping {
            Mapping::Planar(a) => [0.0, 0.0, 0.0, a as f32],
            Mapping::Spherical(c) => [c.x as f32, c.y as f32, c.z as f32, 3.0],
            Mapping::Cylindrical(c) => [c.x as f32, c.y as f32, c.z as f32, 4.0],
        };
        let (nx, ny, boxes) = s.leaf_boxes();
        g.c = [s.width as f32, s.height as f32, nx as f32, ny as f32];
        let key = std::sync::Arc::as_ptr(s) as usize;
        let (kernels, leaves) = match self.surfaces.iter().find(|e| e.0 == key) {
            Some(&(_, k, l)) => (k, l),
            None => {
                let (h, gx, gy) = s.kernels();
                let k = self.data.len() as u32;
                self.data.reserve(3 * h.len() + 4 * boxes.len());
                for i in 0..h.len() {
                    self.data.extend([h[i], gx[i], gy[i]]);
                }
                let l = self.data.len() as u32;
                self.data.extend(boxes.iter().flatten());
                self.surfaces.push((key, k, l));
                (k, l)
            }
        };
        let header = self.data.len() as u32;
        let (ior, rows): (f64, &[(f64, f64, f64)]) = match w.fresnel {
            WaveFresnel::None => {
                g.tag[1] = fresnel_kind::ONE;
                (1.0, &[])
            }
            WaveFresnel::Dielectric(eta) => {
                g.tag[1] = fresnel_kind::DIELECTRIC;
                (eta, &[])
            }
            WaveFresnel::Metal(m) => {
                g.tag[1] = fresnel_kind::CONDUCTOR;
                (1.0, m.table())
            }
        };
        self.data
            .extend([w.settings.eps as f32, ior as f32, rows.len() as f32]);
        for c in isolux_wave::spectral::normalized_srgb_nodes() {
            self.data.extend(c.map(|v| v as f32));
        }
        for r in rows {
            self.data.extend([r.0 as f32, r.1 as f32, r.2 as f32]);
        }
        g.idx = [kernels, leaves, header, w.settings.hierarchy as u32];
    }
}

/// A point light. WGSL: `struct Light { position: vec4<f32>, intensity:
/// vec4<f32>, plane: vec4<f32>, flat: vec4<u32> }`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLight {
    /// `[x, y, z, m]`: `m` 1 + the material of the random-walk medium the
    /// light lies in (0: none; `medium_light` in media.wgsl gathers a
    /// light only at scattering events in its medium).
    pub position: [f32; 4],
    /// `[r, g, b, f]` (W/sr): `f` 1 + the material of the random-walk
    /// medium bounded by a plane whose inside the light reaches through
    /// the plane by refraction (0: none; `refraction` in subsurface.wgsl,
    /// `isolux_render` `Scene::flat_boundary`).
    pub intensity: [f32; 4],
    /// That medium's plane: `[nx, ny, nz, offset]`, the outward unit
    /// normal and `n . p` on the plane (in the frame's rebased
    /// coordinates).
    pub plane: [f32; 4],
    /// `[b, o, 0, 0]`: where that plane has `bounds`, `b` is 1 + its
    /// object, whose box (`GpuObject::bmin`, `bmax`) the crossing point
    /// must lie in (0: an unbounded plane, no box to test); `o` is 1 + the
    /// plane's object, bounded or not (0: no medium), whose spawn floor
    /// (`object_floor` in render.wgsl; an unbounded object's length is
    /// the scene's) the crossing point takes.
    pub flat: [u32; 4],
}

/// The render kernel's parameter block (a read-only storage buffer, see
/// `Gpu::params_buffer`). WGSL: `struct Params` in
/// `render.wgsl` (field by field).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuParams {
    /// Camera position; `w` 0 (the scene's spawn floor until
    /// 2026-12-06, now each object's, `GpuObject::origin.w`, and a flat
    /// medium boundary's through its light, `GpuLight::flat`).
    pub origin: [f32; 4],
    /// Unit view direction.
    pub forward: [f32; 4],
    /// Right vector scaled by `tan(fov/2) aspect`.
    pub right: [f32; 4],
    /// Up vector scaled by `tan(fov/2)`.
    pub up: [f32; 4],
    /// `[width, height, grid m, grid n]`.
    pub film: [u32; 4],
    /// `[first sample, samples per pixel of a real-time frame (1 when path
    /// tracing), seed low, seed high]`.
    pub pass_info: [u32; 4],
    /// `[objects, lights, max depth, environment kind]`.
    pub counts: [u32; 4],
    /// Constant environment radiance.
    pub env: [f32; 4],
    /// `[map width, map height, 0, 0]`.
    pub env_size: [u32; 4],
    /// The wavefront path tracer's `[step, steps, first padded pixel of
    /// the tile, paths in the tile]` (`trace` and `trace_last` in
    /// wavefront.wgsl, whose entry point says whether a step is the last, and
    /// the sorted wavefront's kernels; zero for the other kernels).
    pub wave: [u32; 4],
    /// `[sample layers of the dispatch, 1 when `resolve` replaces the
    /// pixels' sums, 0, 0]` (`main` and `resolve` in
    /// camera.wgsl, `realtime` in realtime.wgsl); in the wavefront's steps `[0, 0, 1 when the sorted
    /// wavefront sorts by material, 0]` (`trace_extend`).
    pub layers: [u32; 4],
    /// `[the random-walk media the camera is in, null boundaries,
    /// equiangular sampling, medium slot bits]`: `1 +` the material of the
    /// innermost in the lowest slot, of each one around it in the next
    /// (0: none),
    /// where camera paths start (`isolux_render::Scene::media_at`); 1
    /// where the scene may hold null boundaries, which point lights'
    /// shadow rays pass (`isolux_render::Scene::may_have_null_boundaries`);
    /// 1 where flights through media sample their point lights'
    /// light by equiangular sampling too
    /// (`isolux_render::MediumLightSampling::Equiangular`); the width in
    /// bits of each medium's slot in the packed media (`render::medium_bits`:
    /// 8 or 16).
    pub camera: [u32; 4],
}

/// A material conformance query: `f`, `pdf` at `(wo, wi)` and a sample for
/// `u = [uc, u0, u1]`, local frame, the material placed at `point`. WGSL: `struct Query` in
/// `material_eval.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuQuery {
    /// `wo` (`w` unused).
    pub wo: [f32; 4],
    /// `wi` (`w` unused).
    pub wi: [f32; 4],
    /// `[uc, u0, u1, 0]`.
    pub u: [f32; 4],
    /// `[material index, 0, 0, 0]`.
    pub index: [u32; 4],
    /// Where the material is placed (`wave`): `[x, y, z, pixel footprint
    /// (scene units; <= 0: none)]`, with `u[3]` the comb offset.
    pub point: [f32; 4],
}

/// The answer to a [`GpuQuery`]: `f = [rgb, pdf]`, `s_wi = [wi, pdf]`
/// (`pdf < 0`: no sample), `s_f = [rgb, flags]`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuAnswer {
    /// `f(wo, wi)` and `pdf(wo, wi)`.
    pub f: [f32; 4],
    /// Sampled direction and its pdf.
    pub s_wi: [f32; 4],
    /// Sampled `f` and the lobe flags (as a float).
    pub s_f: [f32; 4],
}

#[cfg(test)]
mod tests {
    use super::*;
    use isolux_geometry::Perturbation;
    use isolux_materials::{Diffuse, Mix};

    /// Boxes round outward to f32: never inside the f64 value, at most one
    /// unit in the last place away, exact where f32 holds the value.
    #[test]
    fn boxes_round_outward() {
        for v in [
            0.1,
            -0.1,
            0.45 + 1e-12,
            -0.45 - 1e-12,
            1e-40,
            -1e-40,
            0.0,
            0.5,
            -3.0,
            1e30,
        ] {
            let (d, u) = (round_down(v), round_up(v));
            assert!((d as f64) <= v && (u as f64) >= v, "{v}: [{d}, {u}]");
            assert!(
                u.to_bits().abs_diff(d.to_bits()) <= 2 || d == -u,
                "{v}: [{d}, {u}]"
            );
            if v as f32 as f64 == v {
                assert!(d == u && d as f64 == v, "{v}");
            }
        }
    }

    fn grey(r: f64) -> Material {
        Material::Diffuse(Diffuse {
            reflectance: Rgb::splat(r),
        })
    }

    fn mix(parts: Vec<(Material, f64)>) -> Material {
        Material::Mix(Mix { components: parts })
    }

    #[test]
    fn nested_mixes_flatten_to_the_cpus_weights_and_choice() {
        // (a 2, (b 1, c 3) 2): f weights 2, 2 * 1, 2 * 3; selection
        // probabilities 2/4, 2/4 * 1/4, 2/4 * 3/4.
        let m = mix(vec![
            (grey(0.1), 2.0),
            (mix(vec![(grey(0.2), 1.0), (grey(0.3), 3.0)]), 2.0),
        ]);
        let g = GpuMaterials::new(&[grey(0.9), m]).unwrap();
        assert_eq!(g.materials.len(), 5);
        let top = g.materials[1];
        assert_eq!(top.tag[0], tag::MIX);
        assert_eq!(top.idx[1..3], [2, 3]);
        let at = top.idx[0] as usize;
        assert_eq!(
            g.data[at..at + 6],
            [2.0, 0.5, 2.0, 0.125, 6.0, 0.375],
            "(w, p) per leaf"
        );
        let leaf_r: Vec<f32> = g.materials[2..].iter().map(|m| m.a[0]).collect();
        assert_eq!(leaf_r, [0.1, 0.2, 0.3]);
    }

    #[test]
    fn mixes_of_any_size_and_of_zero_weights_are_supported() {
        // Two mixes of 40 leaves: each one's weights at its own offset.
        let big = |r: f64| mix((0..40).map(|i| (grey(r), 1.0 + i as f64)).collect());
        let g = GpuMaterials::new(&[big(0.1), grey(0.5), big(0.2)]).unwrap();
        assert_eq!(g.materials.len(), 83);
        for (m, first) in [(g.materials[0], 3), (g.materials[2], 43)] {
            assert_eq!(m.idx[1..3], [first, 40]);
            let w = &g.data[m.idx[0] as usize..][..80];
            assert_eq!((w[78], w[79]), (40.0, 40.0 / 820.0));
        }
        // Zero weights: black, and no sample beyond the other leaves'
        // probabilities.
        let zero = mix(vec![(grey(0.5), 0.0), (grey(0.7), 0.0)]);
        let inside = mix(vec![(grey(0.5), 0.25), (zero.clone(), 0.75)]);
        let g = GpuMaterials::new(&[zero, inside]).unwrap();
        let (z, i) = (g.materials[0], g.materials[1]);
        // A void leaf each in the zero mix's place, then its leaves with
        // weight and probability 0.
        assert_eq!((z.idx[1], z.idx[2], i.idx[1], i.idx[2]), (2, 3, 5, 4));
        assert_eq!(
            g.data[z.idx[0] as usize..][..6],
            [0.0, 1.0, 0.0, 0.0, 0.0, 0.0]
        );
        assert_eq!(
            g.data[i.idx[0] as usize..][..8],
            [0.25, 0.25, 0.0, 0.75, 0.0, 0.0, 0.0, 0.0]
        );
        let void = GpuMaterial {
            tag: [tag::MIX, 0, 0, 0],
            ..Default::default()
        };
        assert_eq!((g.materials[2], g.materials[6]), (void, void));
        let kinds: Vec<u32> = g.materials[2..].iter().map(|m| m.tag[0]).collect();
        let (d, x) = (tag::DIFFUSE, tag::MIX);
        assert_eq!(kinds, [x, d, d, d, x, d, d]);
        // Its leaves' tangents still count, as on the CPU: a ward inside a
        // zero mix gives the frame its tangent.
        let mut ward = isolux_materials::Ward::new(0.1, 0.3, Rgb::splat(0.2), Rgb::splat(0.3));
        ward.tangent = Some(glam::DVec3::Y);
        let hidden = mix(vec![
            (mix(vec![(Material::Ward(ward), 0.0)]), 0.5),
            (grey(0.5), 0.5),
        ]);
        assert!(hidden.tangent().is_some());
        let g = GpuMaterials::new(&[hidden]).unwrap();
        assert_eq!(
            (g.materials[0].tag[2], g.materials[0].d),
            (1, [0.0, 1.0, 0.0, 0.0])
        );
        // A medium alone runs on the GPU; inside a mix, its boundary.
        let milk = Material::Subsurface(isolux_materials::Subsurface::new(
            Rgb::new(2.0, 2.5, 3.0),
            Rgb::new(0.01, 0.02, 0.05),
            0.5,
            1.3,
            isolux_materials::subsurface_material::SubsurfaceMode::Dipole,
        ));
        assert!(supported(&milk));
        let half = mix(vec![(milk.clone(), 1.0), (grey(0.5), 1.0)]);
        assert!(supported(&half));
        let g = GpuMaterials::new(&[half]).unwrap();
        assert_eq!(g.materials[1].tag[0], tag::DIELECTRIC);
        assert_eq!(g.materials[1].a[0], 1.3);
        let Material::Subsurface(medium) = &milk else {
            unreachable!()
        };
        let scale = medium.single_scattering_scale();
        let local = medium.local_brdf();
        let g = GpuMaterials::new(&[milk]).unwrap();
        let m = g.materials[0];
        assert_eq!((m.tag[0], m.tag[3]), (tag::SUBSURFACE, 0));
        // Dipoles, the single-scattering scale, the local BRDF, then three tables of
        // 4096 bins ([n, cdf, pdf]).
        assert_eq!(m.idx, [0, 21, 21 + 8194, 21 + 2 * 8194]);
        assert_eq!(g.data[12..15], scale.to_array().map(|v| v as f32));
        assert_eq!(g.data[15..18], local.r_d.to_array().map(|v| v as f32));
        assert_eq!(
            g.data[18..21],
            local.single_albedo.to_array().map(|v| v as f32)
        );
        assert_eq!(g.data[21], 4096.0);
        assert_eq!(g.data.len(), 21 + 3 * 8194);
    }

    #[test]
    fn random_walk_media_list_the_materials_seen_from_inside() {
        use isolux_materials::subsurface_material::SubsurfaceMode;
        let medium = |mode| {
            Material::Subsurface(isolux_materials::Subsurface::new(
                Rgb::splat(0.1),
                Rgb::splat(0.01),
                0.0,
                1.25,
                mode,
            ))
        };
        let glass = Material::Dielectric(isolux_materials::Dielectric { ior: 1.5 });
        let water = medium(SubsurfaceMode::RandomWalk);
        let g = GpuMaterials::new(&[
            grey(0.5),
            water.clone(),
            glass.clone(),
            medium(SubsurfaceMode::Dipole),
        ])
        .unwrap();
        // The water (another object of it: a medium in the medium), the
        // glass and the dipole medium seen from the water: records of
        // their own, at 1.25 / 1.25, 1.5 / 1.25 and 1.25 / 1.25; the grey
        // itself.
        assert_eq!(g.materials.len(), 7);
        assert_eq!(g.materials[4].tag[0], tag::SUBSURFACE);
        assert_eq!(g.materials[4].a[0], 1.0);
        assert_eq!(g.materials[5].tag[0], tag::DIELECTRIC);
        assert_eq!(g.materials[5].a[0], 1.2);
        assert_eq!(g.materials[6].tag[0], tag::SUBSURFACE);
        assert_eq!(g.materials[6].a[0], 1.0);
        let at = g.materials[1].tag[1] as usize - 1;
        assert_eq!(g.data[at..at + 4], [0.0, 4.0, 5.0, 6.0]);
        // Only random-walk media have a table.
        assert_eq!(g.materials[3].tag[1], 0);
        // Nothing changes without such a medium.
        let g = GpuMaterials::new(&[grey(0.5), glass]).unwrap();
        assert_eq!(g.materials.len(), 2);
        assert!(g.data.is_empty());
    }

    #[test]
    fn wave_surfaces_are_copied_once_and_fit_mixes() {
        use isolux_materials::metals::Metal;
        use isolux_materials::wave::{Wave, WaveFresnel};
        let heights: Vec<f32> = (0..40 * 24).map(|i| (i % 7) as f32 * 0.01).collect();
        let field = isolux_wave::Heightfield::new(40, 24, 0.5, heights).unwrap();
        let surface = std::sync::Arc::new(isolux_wave::GaborSurface::new(field));
        let silver = Wave::new(
            surface.clone(),
            isolux_wave::Model::Ghs,
            WaveFresnel::Metal(Metal::by_name("Ag").unwrap()),
        );
        let plain = Wave::new(surface, isolux_wave::Model::Ohs, WaveFresnel::None);
        let (a, b) = (Material::Wave(silver), Material::Wave(plain));
        assert!(supported(&a));
        // Inside mixes: one `wave` component among any number of others;
        // the frame's tangent is the first component's that has one, as on
        // the CPU. Two `wave` components are refused.
        let along = Some(glam::DVec3::X);
        let ggx = |tangent: Option<glam::DVec3>| {
            let mut g = isolux_materials::Ggx::new(
                0.2,
                0.4,
                isolux_materials::Fresnel::Schlick {
                    f0: Rgb::splat(0.04),
                },
            );
            g.tangent = tangent;
            Material::Ggx(g)
        };
        let five: Vec<_> = (0..5).map(|i| (grey(0.1 * i as f64), 1.0)).collect();
        let mixes = [
            // (mix, (fixed tangent, tangent is the wave's), wave + 1)
            (
                mix(vec![(grey(0.5), 1.0), (a.clone(), 2.0), (ggx(along), 1.0)]),
                (0, 1),
                2,
            ),
            (
                mix(vec![(ggx(along), 1.0), (grey(0.5), 1.0), (a.clone(), 1.0)]),
                (1, 0),
                3,
            ),
            (mix(vec![(ggx(None), 1.0), (b.clone(), 1.0)]), (0, 1), 2),
            (
                mix([five.clone(), vec![(a.clone(), 1.0)]].concat()),
                (0, 1),
                6,
            ),
            (mix(vec![(grey(0.5), 1.0), (ggx(along), 1.0)]), (1, 0), 0),
        ];
        for (i, (m, tangent, wave)) in mixes.iter().enumerate() {
            assert!(supported(m), "mix {i}");
            let g = GpuMaterials::new(std::slice::from_ref(m)).unwrap();
            let top = g.materials[0];
            assert_eq!((top.tag[2], top.idx[3]), *tangent, "mix {i}");
            assert_eq!(top.tag[3], *wave, "mix {i}");
            if *wave > 0 {
                assert_eq!(g.materials[*wave as usize].tag[0], tag::WAVE);
            }
            if tangent.0 == 1 {
                assert_eq!(top.d, [1.0, 0.0, 0.0, 0.0]);
            }
        }
        // Two `wave` leaves (one placed per hit): their summed weight and
        // probability and their count in `a`, the first named in `tag[3]`.
        let nested = mix(vec![
            (a.clone(), 1.0),
            (mix([five, vec![(b.clone(), 1.0)]].concat()), 1.0),
        ]);
        assert!(supported(&nested));
        let g = GpuMaterials::new(std::slice::from_ref(&nested)).unwrap();
        let top = g.materials[0];
        // f weights 1 and 1 (a mix's f is its weighted sum, unnormalized),
        // probabilities 1/2 and a sixth of the inner mix's 1/2.
        assert_eq!(top.tag[3], 1);
        let (w, p) = (2.0, 0.5 + 0.5 / 6.0);
        assert!(
            (top.a[0] - w as f32).abs() < 1e-6 && (top.a[1] - p as f32).abs() < 1e-6,
            "{:?}",
            top.a
        );
        assert_eq!(top.a[2], 2.0);
        let g = GpuMaterials::new(&[a, b]).unwrap();
        let (m0, m1) = (g.materials[0], g.materials[1]);
        assert_eq!(
            (m0.tag[0], m0.tag[1], m0.tag[3]),
            (tag::WAVE, fresnel_kind::CONDUCTOR, 0)
        );
        assert_eq!((m1.tag[1], m1.tag[3]), (fresnel_kind::ONE, 1));
        // One copy of the kernels (3 floats per texel) and of the leaf
        // boxes (3 x 2 leaves of 16 texels, 4 floats each).
        assert_eq!((m0.idx[0], m0.idx[1]), (m1.idx[0], m1.idx[1]));
        assert_eq!(m0.idx[1], 3 * 40 * 24);
        assert_eq!(m0.idx[2], m0.idx[1] + 4 * 3 * 2);
        assert_eq!(m0.c, [40.0, 24.0, 3.0, 2.0]);
        // Header: eps, ior, metal rows, 81 colour nodes, then the rows.
        let h = m0.idx[2] as usize;
        let rows = g.data[h + 2] as usize;
        assert!(rows > 2);
        assert_eq!(m1.idx[2] as usize, h + 3 + 243 + 3 * rows);
        assert_eq!(g.data.len(), m1.idx[2] as usize + 3 + 243);
    }

    /// The skip links walk a hierarchy as a stack would (geometry.wgsl's
    /// traversal, mirrored): over hierarchies of 1 to 600 objects and of
    /// one object's 1 to 600 perturbations, with boxes met or missed at
    /// random, the stackless walk visits exactly the nodes, in the same
    /// order, that a recursive descent over `Bvh::flatten`'s second-child
    /// indices visits (a box missed prunes its subtree), and with every
    /// box met, every node once.
    #[test]
    fn skip_links_walk_the_hierarchy_as_a_stack_would() {
        use isolux_geometry::samples::bumpy_sphere;
        // A node's box is "met" by ray r when this hash says so.
        let met = |r: u32, node: u32| {
            let h = (r.wrapping_mul(0x9E37_79B9) ^ node.wrapping_mul(0x85EB_CA6B)).rotate_left(13);
            r == 0 || h.wrapping_mul(0xC2B2_AE35) >> 30 != 0
        };
        let stackless = |nodes: &[GpuBvhNode], root: u32, r: u32| {
            let (mut seen, mut node) = (Vec::new(), root);
            while node != NO_NODE {
                let n = nodes[node as usize];
                seen.push(node);
                node = if met(r, node) && n.link[1] == 0 {
                    node + 1
                } else {
                    n.link[0]
                };
            }
            seen
        };
        fn descend(
            flat: &[(Aabb, u32, Vec<u32>)],
            i: u32,
            root: u32,
            met: &dyn Fn(u32) -> bool,
            seen: &mut Vec<u32>,
        ) {
            seen.push(root + i);
            let (_, second, items) = &flat[i as usize];
            if met(root + i) && items.is_empty() {
                descend(flat, i + 1, root, met, seen);
                descend(flat, *second, root, met, seen);
            }
        }
        for n in [1usize, 2, 3, 5, 17, 64, 255, 256, 257, 600] {
            let spheres: Vec<Object> = (0..n)
                .map(|i| {
                    let c = DVec3::new(i as f64 * 1.5, (i % 7) as f64, 0.0);
                    Object::new(Quadric::sphere(c, 0.5), Vec::new(), None).unwrap()
                })
                .collect();
            let bumpy = bumpy_sphere(n);
            let objects = GpuScene::new(&spheres);
            let bumps = GpuScene::new(std::slice::from_ref(&bumpy));
            let bumps_root = bumps.objects[0].range[3];
            // The boxes `with_materials` builds the hierarchies over.
            let object_boxes: Vec<Aabb> = spheres.iter().map(|o| uploaded_box(&o.bbox())).collect();
            // In the GPU's frame of the object, as `with_materials` puts them.
            let gpu_origin = object_origin(&bumpy, DVec3::ZERO);
            let gpu_box = bumpy.bbox().translated(-gpu_origin);
            let bump_boxes: Vec<Aabb> = bumpy
                .perturbations()
                .iter()
                .map(|p| Perturbation {
                    quadric: p.quadric.translated(bumpy.origin() - gpu_origin),
                    factor: p.factor,
                })
                .map(|p| support_box(&p, &gpu_box))
                .filter(|b| !b.is_empty())
                .map(|b| uploaded_box(&b))
                .collect();
            for (what, scene, root, boxes) in [
                ("objects", objects, 0, object_boxes),
                ("perturbations", bumps, bumps_root, bump_boxes),
            ] {
                let flat = Bvh::build(&boxes).flatten();
                for r in 0..20 {
                    let mut want = Vec::new();
                    descend(&flat, 0, root, &|node| met(r, node), &mut want);
                    let got = stackless(&scene.nodes, root, r);
                    assert_eq!(got, want, "{n} {what}, ray {r}");
                    if r == 0 {
                        let all: Vec<u32> = (root..root + flat.len() as u32).collect();
                        assert_eq!(got, all, "{n} {what}: every box met");
                    }
                }
            }
        }
    }

    #[test]
    fn sizes_match_the_wgsl_declarations() {
        // Quadric: 3 vec4 = 48 bytes; Perturbation: Quadric + vec4 = 64;
        // Object: Quadric + 5 vec4 = 128; Ray: 2 vec4 = 32; hit: vec4 = 16.
        assert_eq!(std::mem::size_of::<GpuQuadric>(), 48);
        assert_eq!(std::mem::size_of::<GpuPerturbation>(), 64);
        assert_eq!(std::mem::size_of::<GpuObject>(), 128);
        assert_eq!(std::mem::size_of::<GpuBvhNode>(), 48);
        assert_eq!(std::mem::size_of::<GpuRay>(), 32);
        assert_eq!(std::mem::size_of::<GpuHit>(), 16);
        assert_eq!(std::mem::size_of::<GpuMaterial>(), 112);
        assert_eq!(std::mem::size_of::<GpuLight>(), 64);
        assert_eq!(std::mem::size_of::<GpuParams>(), 192);
        assert_eq!(std::mem::size_of::<GpuQuery>(), 80);
        assert_eq!(std::mem::size_of::<GpuAnswer>(), 48);
        // And naga agrees (layouts computed from the shader sources).
        let mut seen = std::collections::BTreeSet::new();
        for src in [
            crate::intersect_source(),
            crate::render_source(),
            crate::material_eval_source(),
        ] {
            let module = naga::front::wgsl::parse_str(&src).unwrap();
            let mut layouter = naga::proc::Layouter::default();
            layouter.update(module.to_ctx()).unwrap();
            for (h, ty) in module.types.iter() {
                let want = match ty.name.as_deref() {
                    Some("Quadric") => std::mem::size_of::<GpuQuadric>(),
                    Some("Perturbation") => std::mem::size_of::<GpuPerturbation>(),
                    Some("Object") => std::mem::size_of::<GpuObject>(),
                    Some("BvhNode") => std::mem::size_of::<GpuBvhNode>(),
                    Some("Ray") => std::mem::size_of::<GpuRay>(),
                    Some("Material") => std::mem::size_of::<GpuMaterial>(),
                    Some("Light") => std::mem::size_of::<GpuLight>(),
                    Some("Params") => std::mem::size_of::<GpuParams>(),
                    Some("Query") => std::mem::size_of::<GpuQuery>(),
                    Some("Answer") => std::mem::size_of::<GpuAnswer>(),
                    _ => continue,
                };
                assert_eq!(layouter[h].size as usize, want, "{:?}", ty.name);
                seen.insert(ty.name.clone().unwrap());
            }
        }
        assert_eq!(seen.len(), 10, "{seen:?}");
    }
}
