// Exact first hit of functionally defined objects (SPEC §1) on the GPU:
// F' = F + sum f_i Q_i^3 [Q_i >= 0], mirroring crates/geometry/src/object.rs
// and its segment walk, object/walk.rs.
//
// Along a ray every Q_i is a quadratic in t; its roots split the ray into
// segments on which the set of active perturbations is fixed, so F' is one
// polynomial of degree <= 6. Each segment [a, b] is reparameterized to
// s in [0, 1] (t = a + (b - a) s), which keeps the f32 coefficients well
// conditioned, and held by its Bernstein coefficients, built from the
// quadratics' own (`bern_q`, `bern_elevate`, `bern_add_cube`; the CPU's
// `Bernstein6`): accurate at both ends of the segment, where a support's
// `f Q^3` vanishes (docs/geometry.md, "Why the Bernstein form"). Each
// quadratic is taken about a point near where it matters (the base about
// its vertex along the ray when the box's entry is far from it, the
// supports about the segment's start; `object_hit`). Its
// first root is isolated by Bernstein subdivision: the control points
// bound the polynomial on a sub-interval, an interval whose control
// points share one sign holds no root, the others are halved (left
// first) down to 2^-12 of the segment, then refined by regula falsi in
// the power basis about the nearer end of the segment. Never marching.
// The prelude (constants) is generated from Rust.
//
// Precision: every computation is in `real`, an alias the Rust side
// prepends (`geometry_source`): f32, or f64 on adapters with
// SHADER_F64 when asked for (`Precision::F64`). Buffers stay f32; the
// entry `scene_first_hit` takes and returns f32.
//
// This file holds the structs and functions only; each kernel declares the
// `objects`, `perturbations` and `nodes` storage buffers with its own
// bindings.

struct Quadric { c: array<vec4<f32>, 3> }
// A perturbation's quadric is written about its anchor `factor.yzw`, a
// point of its object's frame where it acts (layout.rs `GpuPerturbation`):
// evaluate it at `pert_local(p, x)` for a point `x` of that frame.
struct Perturbation { q: Quadric, factor: vec4<f32> }
// An object's quadrics and box are in its own frame: world coordinates
// less `origin` (layout.rs `GpuObject`).
// The base quadric is written about `anchor.xyz` (layout.rs `GpuObject`):
// evaluate it at `base_local(obj, x)`.
struct Object { base: Quadric, bmin: vec4<f32>, bmax: vec4<f32>, range: vec4<u32>, origin: vec4<f32>, anchor: vec4<f32> }
struct Ray { o: vec4<f32>, d: vec4<f32> }
// Depth-first BVH node (layout.rs `GpuBvhNode`): interior `link = (second
// child, 0, _, _)`, the first child follows; leaf `link = (_, count,
// item, item)`.
struct BvhNode { bmin: vec4<f32>, bmax: vec4<f32>, link: vec4<u32> }

// The object of the hit `scene_first_hit` returned.
var<private> hit_object: u32;

// Per-tile culling of camera rays (SPEC §1: "culled per tile"; the CPU's
// coherent culling, docs/geometry.md). Kernels that trace one camera ray
// per invocation read their 8 x 8 pixel tile's list of objects
// (`tile_entry`, camera.wgsl `cull_tiles`: the objects whose box the
// pyramid of the tile's rays meets, in the order of the object
// hierarchy's walk) and each camera ray tests those objects instead of
// walking the hierarchy (`scene_hit_real`). The list holds every object a
// ray's own walk would reach, in the same order, and those it would not
// are missed by their own box tests, with the same nearest hit so far: the
// hits are the walk's. `tile_rays` is set for the invocation's next
// `scene_hit_real` call, its camera ray, which clears it; `tile_entry(0)`
// is the list's length, `tile_entry(1 + i)` its objects (defined by each
// kernel: intersect.wgsl has no lists).
var<private> tile_rays: bool;

// The candidate list of an object of more than MASK_CANDIDATES
// perturbations, at module scope. WGSL zero-initializes every variable:
// naga gives a function's local variables an OpConstantNull initializer,
// so a local array would be cleared on every `object_hit` call, and one
// indexed at run time lives in memory (local memory on NVIDIA), where the
// driver cannot prove the stores dead. A private array is cleared once
// per invocation. It is the intersection's only array: the hierarchies are
// walked through skip links and the root isolation walks dyadic intervals,
// neither with a stack (2026-12-02; RADV, docs/gpu.md "Register
// pressure").
var<private> candidates: array<u32, MAX_CANDIDATES>;

// The candidate perturbations of the object `object_hit` is intersecting.
// An object with at most 32 perturbations keeps them as a bit mask over
// its range (`cand_mask`, bit k for perturbation `cand_first + k`), which
// lives in a register: a run-time-indexed array lives in memory (local
// memory on NVIDIA), and the gallery's objects have two perturbations
// each. A larger object lists them in `candidates` (`cand_count` of them),
// or uses all `cand_count` of its perturbations when more than
// MAX_CANDIDATES survive the culling. Walked by `next_candidate`.
const CAND_MASK: u32 = 0u;
const CAND_LIST: u32 = 1u;
const CAND_ALL: u32 = 2u;
var<private> cand_mode: u32;
var<private> cand_mask: u32;
var<private> cand_first: u32;
var<private> cand_count: u32;

// The next candidate perturbation (its index into `perturbations`), or
// NO_NODE after the last. A walk starts from `vec2(cand_mask, 0u)`: the
// mask's bits still to visit, and the position in the list.
fn next_candidate(c: ptr<function, vec2<u32>>) -> u32 {
    if (cand_mode == CAND_MASK) {
        let m = (*c).x;
        if (m == 0u) {
            return NO_NODE;
        }
        (*c).x = m & (m - 1u);
        return cand_first + firstTrailingBit(m);
    }
    let j = (*c).y;
    if (j >= cand_count) {
        return NO_NODE;
    }
    (*c).y = j + 1u;
    if (cand_mode == CAND_ALL) {
        return cand_first + j;
    }
    return candidates[j];
}

// The point `x` of its object's frame in perturbation `p`'s own, about its
// anchor: exact where `x` lies within a factor of two of the anchor
// (Sterbenz), so the quadric's terms stay as small as its support.
fn pert_local(p: Perturbation, x: vec3<real>) -> vec3<real> {
    return x - vec3<real>(p.factor.yzw);
}

// The point `x` of an object's frame in its base quadric's own, about its
// anchor.
fn base_local(obj: Object, x: vec3<real>) -> vec3<real> {
    return x - vec3<real>(obj.anchor.xyz);
}

// Coefficients [a11, a22, a33, a12, a13, a23, a14, a24, a34, a44].
fn q_m(q: Quadric, p: vec3<real>) -> vec3<real> {
    let a = vec4<real>(q.c[0]);
    let b = vec4<real>(q.c[1]);
    return vec3<real>(
        a.x * p.x + a.w * p.y + b.x * p.z,
        a.w * p.x + a.y * p.y + b.y * p.z,
        b.x * p.x + b.y * p.y + a.z * p.z,
    );
}

fn q_b(q: Quadric) -> vec3<real> {
    return vec3<real>(vec3<f32>(q.c[1].z, q.c[1].w, q.c[2].x));
}

fn q_eval(q: Quadric, p: vec3<real>) -> real {
    return dot(p, q_m(q, p)) + 2.0 * dot(q_b(q), p) + real(q.c[2].y);
}

fn q_grad(q: Quadric, p: vec3<real>) -> vec3<real> {
    return 2.0 * (q_m(q, p) + q_b(q));
}

// (A, B, C) with Q(o + t d) = A t^2 + B t + C.
fn q_along(q: Quadric, o: vec3<real>, d: vec3<real>) -> vec3<real> {
    let md = q_m(q, d);
    let b = q_b(q);
    return vec3<real>(dot(d, md), 2.0 * (dot(o, md) + dot(b, d)), q_eval(q, o));
}

// Real roots of A t^2 + B t + C, ascending; NO_ROOT where absent.
fn roots(c: vec3<real>) -> vec2<real> {
    let a = c.x;
    let b = c.y;
    let k = c.z;
    if (abs(a) < 1e-30) {
        if (abs(b) < 1e-30) {
            return vec2<real>(NO_ROOT, NO_ROOT);
        }
        let r = -k / b;
        return vec2<real>(r, NO_ROOT);
    }
    let disc = b * b - 4.0 * a * k;
    if (disc < 0.0) {
        return vec2<real>(NO_ROOT, NO_ROOT);
    }
    let s = sqrt(disc);
    let qq = -0.5 * (b + select(-s, s, b >= 0.0));
    var r0 = qq / a;
    var r1 = select(r0, k / qq, abs(qq) > 1e-30);
    if (r0 > r1) {
        let t = r0;
        r0 = r1;
        r1 = t;
    }
    return vec2<real>(r0, r1);
}

// The Bernstein coefficients on [u0, u1] of the quadratic (A, B, C) in
// u: its value at u0, `C + B (u0 + u1) / 2 + A u0 u1`, its value at u1.
// Each is evaluated where it belongs rather than summed from a power
// basis about u0, whose sum at u1 cancels (a segment ending at the base's
// vertex, `object_hit`'s `tv`, took its end value as a difference of
// terms near 1700 and saw a sign there that the vertex did not have).
fn bern_q(q: vec3<real>, u0: real, u1: real) -> vec3<real> {
    return vec3<real>(
        q.z + u0 * (q.y + u0 * q.x),
        q.z + 0.5 * q.y * (u0 + u1) + q.x * (u0 * u1),
        q.z + u1 * (q.y + u1 * q.x),
    );
}

fn poly_eval(p: array<real, 7>, s: real) -> real {
    var q = p;
    var v = q[6];
    for (var k = 5; k >= 0; k--) {
        v = v * s + q[k];
    }
    return v;
}

// The quadratic with Bernstein coefficients f raised to degree 6
// (`Bernstein6::quadratic`).
fn bern_elevate(f: vec3<real>) -> array<real, 7> {
    return array<real, 7>(
        f.x,
        (2.0 * f.x + f.y) * (1.0 / 3.0),
        (6.0 * f.x + 8.0 * f.y + f.z) * (1.0 / 15.0),
        (f.x + 3.0 * f.y + f.z) * 0.2,
        (f.x + 8.0 * f.y + 6.0 * f.z) * (1.0 / 15.0),
        (f.y + 2.0 * f.z) * (1.0 / 3.0),
        f.z,
    );
}

// Adds f q^3 to the Bernstein coefficients p, for the quadratic with
// Bernstein coefficients b (`poly::cube2`: q^2, degree 4, then q^2 q).
fn bern_add_cube(p: ptr<function, array<real, 7>>, f: real, b: vec3<real>) {
    let s0 = b.x * b.x;
    let s1 = b.x * b.y;
    let s2 = (b.x * b.z + 2.0 * (b.y * b.y)) * (1.0 / 3.0);
    let s3 = b.y * b.z;
    let s4 = b.z * b.z;
    (*p)[0] += f * (s0 * b.x);
    (*p)[1] += f * ((s0 * b.y + 2.0 * (s1 * b.x)) * (1.0 / 3.0));
    (*p)[2] += f * ((s0 * b.z + 8.0 * (s1 * b.y) + 6.0 * (s2 * b.x)) * (1.0 / 15.0));
    (*p)[3] += f * ((s1 * b.z + 3.0 * (s2 * b.y) + s3 * b.x) * 0.2);
    (*p)[4] += f * ((6.0 * (s2 * b.z) + 8.0 * (s3 * b.y) + s4 * b.x) * (1.0 / 15.0));
    (*p)[5] += f * ((2.0 * (s3 * b.z) + s4 * b.y) * (1.0 / 3.0));
    (*p)[6] += f * (s4 * b.z);
}

// The power basis of the polynomial with Bernstein coefficients b
// (`poly::power`): c_k = C(6, k) times the k-th forward difference of b
// at 0; with `reversed`, of b read backwards, the power basis in 1 - s.
fn bern_power(b: array<real, 7>, reversed: bool) -> array<real, 7> {
    var d = b;
    if (reversed) {
        d = array<real, 7>(b[6], b[5], b[4], b[3], b[2], b[1], b[0]);
    }
    var c = array<real, 7>(d[0], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    d[0] = d[1] - d[0];
    d[1] = d[2] - d[1];
    d[2] = d[3] - d[2];
    d[3] = d[4] - d[3];
    d[4] = d[5] - d[4];
    d[5] = d[6] - d[5];
    c[1] = 6.0 * d[0];
    d[0] = d[1] - d[0];
    d[1] = d[2] - d[1];
    d[2] = d[3] - d[2];
    d[3] = d[4] - d[3];
    d[4] = d[5] - d[4];
    c[2] = 15.0 * d[0];
    d[0] = d[1] - d[0];
    d[1] = d[2] - d[1];
    d[2] = d[3] - d[2];
    d[3] = d[4] - d[3];
    c[3] = 20.0 * d[0];
    d[0] = d[1] - d[0];
    d[1] = d[2] - d[1];
    d[2] = d[3] - d[2];
    c[4] = 15.0 * d[0];
    d[0] = d[1] - d[0];
    d[1] = d[2] - d[1];
    c[5] = 6.0 * d[0];
    c[6] = d[1] - d[0];
    return c;
}

// The Bernstein coefficients on [0, v] of the polynomial with those p on
// [0, 1]: de Casteljau's left part at v, in place (level k leaves its
// first point at k). The last is the value at v.
fn split_left(p: array<real, 7>, v: real) -> array<real, 7> {
    var g = p;
    if (v < 1.0) {
        let r = 1.0 - v;
        for (var k = 1; k <= 6; k++) {
            for (var j = 6; j >= k; j--) {
                g[j] = r * g[j - 1] + v * g[j];
            }
        }
    }
    return g;
}

// What the control polygon on [u, v] of a polynomial with the Bernstein
// coefficients p_v on [0, v] (`split_left`) says about its roots there,
// its end points replaced by the values fa = p(u), fb = p(v): bit 0 (HULL_ZERO), the
// control points' hull contains zero (a root is possible); bit 1
// (HULL_SINGLE), exactly one root: ends of opposite signs, one sign change
// of the polygon (Descartes' rule of signs in the Bernstein basis), and
// every point clear of `tol`, so that no sign is rounding's. The points
// are folded into those answers one at a time, not kept as a second array
// (RADV: 2 VGPRs fewer at the kernels' peak, 3-6% less code; docs/gpu.md
// "Register pressure").
const HULL_ZERO: u32 = 1u;
const HULL_SINGLE: u32 = 2u;
fn hull(p_v: array<real, 7>, u: real, v: real, fa: real, fb: real, tol: real) -> u32 {
    // de Casteljau's right part at u / v of the coefficients on [0, v]
    // (`split_left`): those on [u, v], in place (level k leaves its last
    // point at 6 - k). Convex combinations: no cancellation.
    var g = p_v;
    if (u > 0.0) {
        let x = u / v;
        let r = 1.0 - x;
        for (var k = 1; k <= 6; k++) {
            for (var j = 0; j <= 6 - k; j++) {
                g[j] = r * g[j] + x * g[j + 1];
            }
        }
    }
    let b1 = g[1];
    let b2 = g[2];
    let b3 = g[3];
    let b4 = g[4];
    let b5 = g[5];
    var lo = min(fa, fb);
    var hi = max(fa, fb);
    var clear = abs(fa) > tol && abs(fb) > tol;
    var changes = 0u;
    lo = min(lo, b1);
    hi = max(hi, b1);
    clear = clear && abs(b1) > tol;
    changes += select(0u, 1u, (fa < 0.0) != (b1 < 0.0));
    lo = min(lo, b2);
    hi = max(hi, b2);
    clear = clear && abs(b2) > tol;
    changes += select(0u, 1u, (b1 < 0.0) != (b2 < 0.0));
    lo = min(lo, b3);
    hi = max(hi, b3);
    clear = clear && abs(b3) > tol;
    changes += select(0u, 1u, (b2 < 0.0) != (b3 < 0.0));
    lo = min(lo, b4);
    hi = max(hi, b4);
    clear = clear && abs(b4) > tol;
    changes += select(0u, 1u, (b3 < 0.0) != (b4 < 0.0));
    lo = min(lo, b5);
    hi = max(hi, b5);
    clear = clear && abs(b5) > tol;
    changes += select(0u, 1u, (b4 < 0.0) != (b5 < 0.0)) + select(0u, 1u, (b5 < 0.0) != (fb < 0.0));
    var r = 0u;
    if (lo <= 0.0 && hi >= 0.0) {
        r = HULL_ZERO;
        if (fa * fb < 0.0 && clear && changes == 1u) {
            r |= HULL_SINGLE;
        }
    }
    return r;
}

// First sign change on [0, 1] of the polynomial with Bernstein
// coefficients p, or -1.
//
// Bernstein subdivision, depth first and left first, without a stack:
// the interval is the dyadic `[i, i + 1] * w` (`w = 2^-level`), the next
// one after an interval is done is its right sibling, or its nearest
// ancestor's right sibling (`i + 1`, halved while even), so the walk
// visits intervals in the order of a stack of `(u, v, p(u), p(v))` and
// holds four scalars instead of the stack (16 `vec4` in private memory:
// registers on AMD, local memory on NVIDIA, cleared at every invocation).
//
// The walk goes left to right, so an interval's left end is the last
// one's right end, and `p(u)` is carried over: every end value is computed
// once, by `split_left` at `v` (its last coefficient), and two
// neighbours agree exactly on their common end, so a sign change there
// cannot be lost. (Recomputing the Bernstein coefficients of each interval
// from the power basis gives end values off by rounding, about 1e-5 where
// the coefficients reach 1e2 in f32, and a root near a split point could
// fall between an interval whose hull rounds above zero and a neighbour
// wholly below it: rays then missed a plain exit from a glass object,
// `images.rs`, `conformance.rs`.) The hull is the Bernstein coefficients'
// with their ends replaced by these values.
//
// With `any` (shadow rays: whether p has a root, not where), the first
// interval whose ends have opposite signs answers its midpoint: it holds a
// root, and the walk would return one from it or from an interval to its
// left, so the answer "a root" is the walk's, without the subdivision and
// refinement that place it. Isolation is rare (about one thread in six
// per sample on the gallery) and so divergent: a warp waits for its one
// thread that refines.
fn first_root(p: array<real, 7>, any: bool) -> real {
    // What rounding can do to a control point: de Casteljau's convex
    // combinations, twelve levels deep at most, stay well within 1024
    // ulps of sum |p_k| (the tolerance of the power basis' Taylor shift,
    // scaling and basis change, which this walk used before 2026-12-05).
    var size: real = 0.0;
    for (var k = 0; k < 7; k++) {
        size += abs(p[k]);
    }
    let tol = 1024.0 * REAL_EPS * size;
    var level = 0u;
    var i = 0u;
    var w: real = 1.0;
    var fa = p[0];
    var guard = 0;
    loop {
        if (guard > MAX_SUBDIVISIONS) {
            break;
        }
        guard++;
        // Dyadic ends: exact (i < 2^14, w a power of two).
        let u = real(i) * w;
        let v = real(i + 1u) * w;
        let p_v = split_left(p, v);
        let fb = p_v[6];
        if (fa == 0.0) {
            return u;
        }
        if (any && fa * fb < 0.0) {
            return 0.5 * (u + v);
        }
        let hc = hull(p_v, u, v, fa, fb, tol);
        var split = false;
        if ((hc & HULL_ZERO) != 0u) {
            // Exactly one root (`hull`), decided as the CPU's
            // `Bernstein6::first_crossing` and `isolate` decide it, is
            // refined at once instead of split down to MIN_WIDTH, once
            // the interval lies in one half of the segment (`refine_bern`
            // refines about the nearer end: the whole segment is split
            // once, where the CPU finds the half by the sign at 1/2);
            // otherwise the interval is split.
            if (((hc & HULL_SINGLE) != 0u && level > 0u) || w < MIN_WIDTH) {
                if (fa * fb <= 0.0) {
                    return refine_bern(p, u, v, fa, fb);
                }
                // Touches zero without crossing: done with it.
            } else {
                split = true;
            }
        }
        if (split) {
            // The left half next; p(u) stays.
            level++;
            i = 2u * i;
            w = 0.5 * w;
            continue;
        }
        // Done with the interval: on to the next one to its right.
        i++;
        loop {
            if (level == 0u || (i & 1u) == 1u) {
                break;
            }
            i = i >> 1u;
            level--;
            w = 2.0 * w;
        }
        if (level == 0u) {
            break;
        }
        fa = fb;
    }
    return -1.0;
}

// The root in [u, v] of the polynomial with Bernstein coefficients b,
// where p(u) = fa and p(v) = fb have opposite signs (or one is zero), and
// [u, v] lies in one half of [0, 1]: [`refine`] in the power basis about
// s = 0 on [0, 1/2], about s = 1 (in 1 - s) on [1/2, 1], each accurate
// near its own end (the CPU's `Bernstein6::refine`).
fn refine_bern(b: array<real, 7>, u: real, v: real, fa: real, fb: real) -> real {
    let reversed = u >= 0.5;
    let c = bern_power(b, reversed);
    if (reversed) {
        return 1.0 - refine(c, 1.0 - v, 1.0 - u, fb, fa);
    }
    return refine(c, u, v, fa, fb);
}

// The root of p in [x0, x1], where p(x0) = f0 and p(x1) = f1 have opposite
// signs (or one is zero), by regula falsi, Illinois variant: an end kept
// twice in a row has its value halved, so both ends move (plain regula
// falsi on a convex stretch keeps one end fixed and converges from one
// side only). The answer is the last estimate, not the bracket's midpoint,
// which lay up to half the bracket from the root when one end stayed put.
// Stops at an exact zero, or when an estimate repeats.
fn refine(p: array<real, 7>, a: real, b: real, fa: real, fb: real) -> real {
    var x0 = a;
    var x1 = b;
    var f0 = fa;
    var f1 = fb;
    var xm = 0.5 * (x0 + x1);
    var kept = 0; // -1: x0 kept last step, 1: x1, 0: none yet
    for (var it = 0; it < 40; it++) {
        if (f1 == f0) {
            break;
        }
        let x = clamp(x0 - f0 * (x1 - x0) / (f1 - f0), x0, x1);
        if (it > 0 && x == xm) {
            break;
        }
        xm = x;
        let fm = poly_eval(p, xm);
        if (fm == 0.0) {
            return xm;
        }
        if (f0 * fm < 0.0) {
            x1 = xm;
            f1 = fm;
            if (kept == -1) {
                f0 = 0.5 * f0;
            }
            kept = -1;
        } else {
            x0 = xm;
            f0 = fm;
            if (kept == 1) {
                f1 = 0.5 * f1;
            }
            kept = 1;
        }
    }
    return xm;
}

// Slab test: (t_near, t_far), empty when t_near > t_far.
fn clip_box(o: vec3<real>, d: vec3<real>, bmin: vec3<real>, bmax: vec3<real>, t0: real, t1: real) -> vec2<real> {
    let inv = 1.0 / d;
    let ta = (bmin - o) * inv;
    let tb = (bmax - o) * inv;
    let tn = max(max(min(ta.x, tb.x), min(ta.y, tb.y)), min(ta.z, tb.z));
    let tf = min(min(max(ta.x, tb.x), max(ta.y, tb.y)), max(ta.z, tb.z));
    return vec2<real>(max(tn, t0), min(tf, t1));
}

// Whether perturbation `pi` may be active on the ray's span: a Q_i(t)
// with a negative leading coefficient is active only between its roots.
fn keeps_support(pi: u32, o: vec3<real>, d: vec3<real>, span: vec2<real>, slack: real) -> bool {
    let pert = perturbations[pi];
    let qa = q_along(pert.q, pert_local(pert, o), d);
    if (qa.x < 0.0) {
        let r = roots(qa);
        if (r.y >= NO_ROOT || r.y < span.x - slack || r.x > span.y + slack) {
            return false;
        }
    }
    return true;
}

// Where the active perturbations add at most this fraction of the base
// quadric's terms at a root of the base, the root is a crossing of `F'`
// (the CPU's `BUMP_NEGLIGIBLE`, 1e-14 in f64; here about 20 ulp of f32).
const BUMP_NEGLIGIBLE: f32 = 1e-6;

// By how many times the base's value at the box's entry must exceed its
// value at the vertex along the ray for `object_hit` to take the base
// about the vertex (2^11: about the entry, f32 would keep no more than 13
// of its 24 bits at the vertex).
const VERTEX_GAIN: real = 2048.0;

// The perturbations of the object being walked (the candidate set) at
// `x` (its frame): `sum f Q^3` and its gradient `sum 3 f Q^2 grad Q`, over
// those with `Q(x) > 0`.
fn bumps_at(x: vec3<real>) -> vec4<real> {
    var sum = vec4<real>(0.0);
    var walk = vec2<u32>(cand_mask, 0u);
    loop {
        let pi = next_candidate(&walk);
        if (pi == NO_NODE) {
            break;
        }
        let pert = perturbations[pi];
        let xp = pert_local(pert, x);
        let qv = q_eval(pert.q, xp);
        if (qv > 0.0) {
            let f = real(pert.factor.x);
            sum += vec4<real>(f * qv * qv * qv, 3.0 * f * qv * qv * q_grad(pert.q, xp));
        }
    }
    return sum;
}

// Whether the perturbations of the object being walked (the candidate
// set) add under BUMP_NEGLIGIBLE of the base's terms (`base`: its
// quadratic along the ray, in `u`) at the point `x` of the ray at `u`
// (the object's frame), each `f Q^3` summed in its factored form, which does not
// cancel. Then a root of the base at `t` is a
// crossing of `F'` (`Object::segment_root` on the CPU): a support that
// ends where the base crosses leaves one, which the degree-6 polynomial's
// rounding can hide, as `F` changes sign there and `f Q^3` vanishes to
// third order. Asked once per object walk, after it (`object_hit`'s
// `pending`), so that the segment loop carries one value more, not this
// loop's.
fn negligible_bump(base: vec3<real>, u: real, x: vec3<real>) -> bool {
    let bump = bumps_at(x).x;
    let scale = abs(base.z) + abs(base.y * u) + abs(base.x * u * u);
    return abs(bump) <= real(BUMP_NEGLIGIBLE) * scale;
}

// First hit of object `oi` on [t0, t1]: (t, outward normal), t < 0 if none.
// With `any` (shadow rays), some hit on [t0, t1] if there is one, its
// normal left unset (`first_root`).
//
// The ray is taken into the object's frame (`Object.origin`) and restarted
// where it enters the object's box, so that every coefficient below is
// computed near the object, at the object's own scale: a quadric along a
// ray from far away is a difference of large terms (its value at the
// origin, |o - c|^2 - r^2 for a sphere), which f32 resolves only to about
// |o - c|^2 2^-24. (A box far larger than its base leaves the entry far
// from it too: then the base is taken about its vertex along the ray, and
// the supports about each segment's start.) Parameters `t` inside are
// from the entry point; the answer is the world ray's.
fn object_hit(oi: u32, o_world: vec3<real>, d: vec3<real>, t0: real, t1: real, any: bool) -> vec4<real> {
    let obj = objects[oi];
    let o_obj = o_world - vec3<real>(obj.origin.xyz);
    let entry = clip_box(o_obj, d, vec3<real>(obj.bmin.xyz), vec3<real>(obj.bmax.xyz), t0, t1);
    if (!(entry.x <= entry.y)) {
        return vec4<real>(MISS, 0.0, 0.0, 0.0);
    }
    // A ray that enters through the box's face restarts a hair before it
    // (never before t0, where it starts): the entry point is rounded, and
    // where the surface touches the face (a sphere's poles, a disc's
    // whole face) a point rounded to the inside made the first crossing
    // found the far side's. Outside the box the object is not, so the
    // walk starts on the outside, as the ray does.
    var shift = entry.x;
    if (entry.x > t0) {
        let reach = max(max(abs(o_obj.x), abs(o_obj.y)), max(abs(o_obj.z), abs(entry.x)));
        // (In units of t for a unit direction, as every kernel's rays
        // have.)
        shift = max(t0, entry.x - 16.0 * REAL_EPS * reach);
    }
    // The exit through a face is rounded too: a surface lying on the face
    // (a floor on its box's bottom) had its crossing rounded past the
    // span's end on a quarter of the rays. The walk ends the same hair
    // beyond it (never beyond t1, where the ray ends: a shadow ray's
    // light).
    var end = entry.y;
    if (entry.y < t1) {
        let reach = max(max(abs(o_obj.x), abs(o_obj.y)), max(abs(o_obj.z), abs(entry.y)));
        end = min(t1, entry.y + 16.0 * REAL_EPS * reach);
    }
    // No longer than `REAL_SPAN` (source.rs `REAL_SPAN_F32`): the segments'
    // polynomials scale with powers of their length.
    end = min(end, shift + REAL_SPAN);
    let o = o_obj + shift * d;
    let span = vec2<real>(0.0, end - shift);
    let first = obj.range.x;
    let count = obj.range.y;
    // The base's quadratic along the ray about its vertex `tv` (where it
    // is extremal along the ray), when that lies inside the span and the
    // base's value at the entry dwarfs its value there: an object whose
    // box is far larger than its base (bounds stretched by an unbounded
    // support) is entered far from the base, and the quadratic about the
    // entry is a difference of large terms near the base (its
    // discriminant, and its Bernstein coefficients over a segment across
    // the base), which f32 resolved to 7% of a sphere's radius 139 units
    // away (`small_bases_in_large_boxes_are_hit_from_afar`). About the
    // vertex, its value and slope there are computed at the vertex
    // itself; the closed form's roots are `tv +- sqrt(-Q*/A)`, and the
    // vertex is a breakpoint of the walk, so that no segment spans it.
    // Otherwise `tv` is 0, the entry, as before. The walk below runs in
    // `u = t - tv` (from `-tv` to `u_end`), so that the vertex is `u = 0`
    // and `tv` need not be kept: `origin` is the entry's `t` plus `tv`.
    // (On RADV, with the base about the vertex computed only where it is
    // used, the wavefront's `trace_extend` 103 -> 96 VGPRs before
    // scheduling against a version that kept `tv` and the entry point:
    // 10 waves instead of 8.)
    let entry_q = q_along(obj.base, base_local(obj, o), d);
    let tv_guess = -entry_q.y / (2.0 * entry_q.x);
    let q_vertex = entry_q.z + 0.5 * tv_guess * entry_q.y;
    // (A ray along which the base is linear, `A = 0`, has none.)
    let far = entry_q.x != 0.0 && tv_guess > 0.0 && tv_guess < span.y
        && abs(entry_q.z) > VERTEX_GAIN * abs(q_vertex);
    let tv = select(0.0, tv_guess, far);
    var base = entry_q;
    if (far) {
        base = q_along(obj.base, base_local(obj, o + tv * d), d);
    }
    let origin = shift + tv;
    let u_end = span.y - tv;
    // Culling: the object's hierarchy over its perturbations' supports
    // (clipped to its box) yields those whose box the span crosses; of
    // these, a Q_i(t) with a negative leading coefficient (every bounded
    // support, and others along some rays) is active only between its
    // roots, and no roots, or roots outside the span, drop it. Up to
    // MAX_CANDIDATES are kept; beyond, every perturbation is used.
    var nc = 0u;
    var all = false;
    var mask = 0u;
    // CANDIDATE_LIST (generated, source.rs `Features::list`) is false when no
    // object of the scene has more than MASK_CANDIDATES (32, the mask's
    // bits) perturbations: the list and its array are then dead code.
    let masked = !CANDIDATE_LIST || count <= MASK_CANDIDATES;
    // The tolerances here and in the walk below hold for an object of
    // about a unit; `obj.origin.w` is its length, at most 1 (layout.rs
    // `GpuObject::origin`, from `Object::length`), so that they shrink
    // with a smaller one.
    let len = real(obj.origin.w);
    let slack = 1e-5 * max(len, max(abs(span.x), abs(span.y)));
    if (obj.range.w != NO_NODE && count <= LINEAR_CULL) {
        // A few supports: the same test on each, no traversal.
        for (var k = 0u; k < count; k++) {
            if (keeps_support(first + k, o, d, span, slack)) {
                mask |= 1u << k;
            }
        }
    } else if (obj.range.w != NO_NODE) {
        // Stackless: an interior node met goes on to its first child (the
        // next node), a node missed or a leaf's items done to its skip
        // link (layout.rs `GpuBvhNode`).
        var node = obj.range.w;
        loop {
            if (node == NO_NODE) {
                break;
            }
            let nd = nodes[node];
            let bs = clip_box(o, d, vec3<real>(nd.bmin.xyz), vec3<real>(nd.bmax.xyz), span.x - slack, span.y + slack);
            var next = nd.link.x;
            if (bs.x <= bs.y) {
                if (nd.link.y == 0u) {
                    next = node + 1u;
                } else {
                    for (var k = 0u; k < nd.link.y; k++) {
                        let pi = select(nd.link.z, nd.link.w, k == 1u);
                        if (!keeps_support(pi, o, d, span, slack)) {
                            continue;
                        }
                        if (masked) {
                            mask |= 1u << (pi - first);
                        } else if (nc < MAX_CANDIDATES) {
                            candidates[nc] = pi;
                            nc++;
                        } else {
                            all = true;
                        }
                    }
                }
            }
            node = next;
        }
    }
    cand_first = first;
    cand_mask = mask;
    cand_count = select(nc, count, all);
    cand_mode = select(select(CAND_LIST, CAND_ALL, all), CAND_MASK, masked);
    let live = select(cand_count, countOneBits(mask), masked);
    var a = -tv;
    var guard = 0u;
    // The support whose root ended the last segment (NO_NODE: none). Its
    // roots are recomputed about the new start `oa`, where that root lies
    // within rounding of `a` on either side: the rounding of `Q(oa)`, a
    // difference of terms as large as `oa`'s distance from the support's
    // centre squared, over the slope. At 50-180 units from the frame's
    // zero that is a few 1e-5 and outgrew the `eps` below: the root came
    // back just beyond it, every segment a few ulps long and inactive,
    // until the guard ended the walk with no hit (lavapipe: 1-8 of 400
    // rays from outside missed a bump's blob whose base lay 40-100 units
    // off, 3 of 2000 a bumpy plane 400 units wide; conformance.rs
    // `walks_step_past_the_support_they_enter`).
    // That root of that support is the one nearer `a`, and is skipped.
    var last = NO_NODE;
    // The sign of F' at the end of the last segment (0 before the first):
    // a segment that starts on the other side of zero had a crossing at
    // its breakpoint that rounding hid from both (a support ending where
    // the base crosses), as on the CPU (`Object::walk`'s `before`).
    var before: real = 0.0;
    // The walk's crossing, and the first base root that a segment's
    // polynomial did not show (`negligible_bump`); NO_ROOT when none.
    var t_hit = real(NO_ROOT);
    // Whether a segment's polynomial was searched (the hit may be its
    // root, which the Newton step below polishes).
    var searched = false;
    var pending = real(NO_ROOT);
    // The ray's point at `a` (the walk's segment start): the supports'
    // quadratics are taken about it, in `u - a`, near where they are
    // used; about the entry, a support's value near the base was a
    // difference of terms as large as the entry's distance squared (`tv`
    // above). Carried from segment to segment, in place of the entry
    // point `o`, which would hold three more registers through the walk.
    var oa = o;
    loop {
        if (a >= u_end || guard > 2u * live + 3u) {
            break;
        }
        guard++;
        // Next breakpoint: the nearest root of an active Q_i beyond a, or
        // the base's vertex, `u = 0` (where `tv` is 0, never beyond a).
        var b = u_end;
        let eps = 1e-6 * max(len, abs(a));
        if (0.0 > a + eps && 0.0 < b) {
            b = 0.0;
        }
        var b_pi = NO_NODE;
        var walk = vec2<u32>(cand_mask, 0u);
        loop {
            let pi = next_candidate(&walk);
            if (pi == NO_NODE) {
                break;
            }
            let pert = perturbations[pi];
            let r = a + roots(q_along(pert.q, pert_local(pert, oa), d));
            let near_x = pi == last && abs(r.x - a) <= abs(r.y - a);
            let near_y = pi == last && !near_x;
            if (!near_x && r.x > a + eps && r.x < b) {
                b = r.x;
                b_pi = pi;
            }
            if (!near_y && r.y > a + eps && r.y < b) {
                b = r.y;
                b_pi = pi;
            }
        }
        let l = b - a;
        let half = 0.5 * l;
        var p = bern_elevate(bern_q(base, a, b));
        var n_active = 0u;
        walk = vec2<u32>(cand_mask, 0u);
        loop {
            let pi = next_candidate(&walk);
            if (pi == NO_NODE) {
                break;
            }
            let pert = perturbations[pi];
            let qa = q_along(pert.q, pert_local(pert, oa), d);
            if (qa.z + half * (qa.y + half * qa.x) <= 0.0) {
                continue;
            }
            n_active++;
            bern_add_cube(&p, real(pert.factor.x), bern_q(qa, 0.0, l));
        }
        // No perturbation active: the base quadric's closed form (as on the
        // CPU), its first root in [0, 1] where the sign changes.
        var s: real = -1.0;
        if (before * p[0] < 0.0) {
            s = 0.0;
        } else if (n_active == 0u) {
            // The base's roots, about its vertex (or the entry).
            let r = roots(base);
            if (p[0] == 0.0) {
                s = 0.0;
            } else if (r.x >= a && r.x <= b && r.x != r.y) {
                s = (r.x - a) / l;
            } else if (r.y >= a && r.y <= b && r.y < NO_ROOT && r.x != r.y) {
                s = (r.y - a) / l;
            }
        } else {
            s = first_root(p, any);
            searched = true;
            // No crossing of the polynomial, but a root of the base: the
            // first such is kept aside (`pending`), and taken after the
            // walk if it comes before the walk's crossing and the
            // perturbations add nothing there (`negligible_bump`). Not
            // for shadow rays (`any`), where it would cost the kernels
            // registers at their peak (RADV: the gallery's path tracer
            // 164 -> 169 VGPRs before scheduling, 6 -> 4 waves per SIMD)
            // to darken a curve of measure zero.
            if (!any && s < 0.0 && pending == NO_ROOT) {
                // Only a base root at an end of the segment, within
                // rounding of it (a Newton step from the end no longer
                // than 16 times the breakpoints' own `eps`), is one that
                // rounding can have hidden; one inside is a crossing that
                // the perturbations moved away. The step is the root to
                // f32's precision: the base's curvature times the step's
                // square is far below it.
                for (var k = 0u; k < 2u; k++) {
                    let e = select(a, b, k == 1u);
                    let fe = base.z + e * (base.y + e * base.x);
                    let de = base.y + 2.0 * e * base.x;
                    if (de != 0.0 && abs(fe) <= 16.0 * eps * abs(de)) {
                        pending = e - fe / de;
                        break;
                    }
                }
            }
        }
        if (s >= 0.0) {
            t_hit = a + s * l;
            break;
        }
        before = sign(p[6]);
        oa += l * d;
        a = b;
        last = b_pi;
    }
    // The ray's point at `u = 0` (so that `a` is not kept with `oa`).
    let ov = oa - a * d;
    if (pending < t_hit && negligible_bump(base, pending, ov + pending * d)) {
        t_hit = pending;
    }
    if (t_hit == NO_ROOT) {
        return vec4<real>(MISS, 0.0, 0.0, 0.0);
    }
    if (any) {
        return vec4<real>(origin + t_hit, 0.0, 0.0, 0.0);
    }
    // One Newton step on F' itself, evaluated at the hit from the
    // quadrics (`bumps_at`, which the normal needs anyway), not from the
    // segment's expanded polynomial: expanding Q^3 over a long segment
    // makes coefficients that cancel near the root (a bump of factor 2.5
    // on a support of radius 7: terms of 1e6 around a value of 20), and
    // the root came out up to 5.7e-4 long, beyond the 1e-4 at which rays
    // leave the surface, so that they started on its far side. A step
    // longer than a thousandth of the span (a graze, a slope near zero;
    // beyond the vertex where that is used) is not taken. The base's closed form needs none (most hits: a GPU
    // warp whose threads all hit a base skips it).
    let x0 = ov + t_hit * d;
    let b0 = bumps_at(x0);
    let xb = base_local(obj, x0);
    let g = q_grad(obj.base, xb) + b0.yzw;
    if (searched) {
        let step = (q_eval(obj.base, xb) + b0.x) / dot(g, d);
        if (abs(step) <= 1e-3 * u_end) {
            t_hit -= step;
        }
    }
    var n = -d;
    if (dot(g, g) > 0.0) {
        n = -normalize(g);
    } else {
        n = -normalize(d);
    }
    return vec4<real>(origin + t_hit, n);
}


// Nearest hit on [t0, t_max] over the `n` objects, through their
// hierarchy (root: node 0): (t, normal), its object in `hit_object`. With
// `any`, the first hit found (shadow rays), its normal unset.
fn scene_first_hit(o: vec3<f32>, d: vec3<f32>, t0: f32, t_max: f32, n: u32, any: bool) -> vec4<f32> {
    let h = scene_hit_real(vec3<real>(o), vec3<real>(d), real(t0), real(t_max), n, any);
    return vec4<f32>(h);
}

// First hit of object `oi` alone on [t0, t1] (f32 in and out): the probe
// rays of the dipole BSSRDF (subsurface.wgsl).
fn object_first_hit(oi: u32, o: vec3<f32>, d: vec3<f32>, t0: f32, t1: f32) -> vec4<f32> {
    return vec4<f32>(object_hit(oi, vec3<real>(o), vec3<real>(d), real(t0), real(t1), false));
}

// `scene_first_hit` in the precision `real` (f32, or f64 where the
// adapter offers it and the caller asked for it).
fn scene_hit_real(o: vec3<real>, d: vec3<real>, t0: real, t_max: real, n: u32, any: bool) -> vec4<real> {
    var best = vec4<real>(MISS, 0.0, 0.0, 0.0);
    if (n == 0u) {
        return best;
    }
    var t1 = t_max;
    // A camera ray of a culled tile tests its tile's list (`tile_rays`,
    // above); other rays walk the hierarchy.
    // TILE_LISTS (generated, source.rs `Features::tiles`): without it the
    // list's code is dead.
    let listed = TILE_LISTS && tile_rays;
    tile_rays = false;
    var li = 0u;
    // Stackless, as in `object_hit`: the skip links (layout.rs
    // `GpuBvhNode`) visit the nodes in the order a stack would.
    var node = 0u;
    loop {
        // The next objects to test: a leaf's (one or two) or the list's
        // next; one call site of `object_hit` for both.
        var count = 0u;
        var first = 0u;
        var second = 0u;
        if (listed) {
            if (li >= tile_entry(0u)) {
                break;
            }
            count = 1u;
            first = tile_entry(1u + li);
            li++;
        } else {
            if (node == NO_NODE) {
                break;
            }
            let nd = nodes[node];
            let bs = clip_box(o, d, vec3<real>(nd.bmin.xyz), vec3<real>(nd.bmax.xyz), t0, t1);
            var next = nd.link.x;
            if (bs.x <= bs.y) {
                if (nd.link.y == 0u) {
                    next = node + 1u;
                } else {
                    count = nd.link.y;
                    first = nd.link.z;
                    second = nd.link.w;
                }
            }
            node = next;
        }
        for (var k = 0u; k < count; k++) {
            let oi = select(first, second, k == 1u);
            let h = object_hit(oi, o, d, t0, t1, any);
            if (h.x >= 0.0 && h.x <= t1) {
                best = h;
                t1 = h.x;
                hit_object = oi;
                if (any) {
                    return best;
                }
            }
        }
    }
    return best;
}
