//! GPU data layouts: `#[repr(C)]` mirrors of the WGSL structs in
//! `shaders/`, the single source of truth for both sides. Every struct is
//! a whole number of `vec4`s (16-byte aligned, no implicit padding), and a
//! unit test checks each size against the WGSL declaration's.

use bytemuck::{Pod, Zeroable};
use isolux_core::{Aabb, DVec3};
use isolux_geometry::bvh::{Bvh, LEAF_SIZE};
use isolux_geometry::{Object, Quadric};

mod materials;

pub use materials::{distribution, fresnel_kind, supported, tag, GpuMaterial, GpuMaterials};

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
