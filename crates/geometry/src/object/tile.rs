//! The tile path of [`Object::intersect_tile`]: up to [`TILE_RAYS`] rays
//! of one beam cast together. The clipping, the base quadric's crossings
//! and the first phase of the perturbation gathering run over arrays of
//! the rays, one lane per ray (loops the compiler vectorizes, compiled
//! for each instruction set, [`crate::simd`]); the segments of the lanes
//! that qualify are walked together by [`solo`], the others
//! ray by ray by the scalar path of `walk.rs`. The hits are the scalar
//! path's to the last bit (the tests in `tests.rs` compare them).

use super::{solo, unit_normal, Along, Candidate, Hit, Items, Object, TILE_RAYS};
use crate::poly::{fmax, fmin, Crossings};
#[cfg(target_arch = "x86_64")]
use crate::simd::{self, Isa};
use isolux_core::{Aabb, DVec3, Ray};
use smallvec::SmallVec;

/// The rays of an [`Object::intersect_tile`] call as arrays (one lane per
/// ray): origins, directions, squared direction lengths, and the first
/// phase's interval `[lo, hi]` (NaN for rays that miss the box).
struct Lanes {
    o: [[f64; TILE_RAYS]; 3],
    d: [[f64; TILE_RAYS]; 3],
    dd: [f64; TILE_RAYS],
    lo: [f64; TILE_RAYS],
    hi: [f64; TILE_RAYS],
}

/// For every sphere support `(centre, k, c0)` (`Q = c0 - k |p - centre|^2`)
/// `j` and every lane `r`: bit `j` of `keep[r]` when the support meets the
/// ray on `[lo, hi]`, by `Along::along` and `positive_on` operation for
/// operation (so the answers are `gather`'s to the last bit); `odd[r]` when
/// the ray's `q2` is not negative (a zero direction), which `gather` treats
/// apart. The loops run over the lanes, so the compiler vectorizes them:
/// with AVX2 where the processor has it (chosen at run time; the results
/// are the same, IEEE operations being exact whatever the vector width),
/// SSE2 otherwise.
fn filter_supports(
    lanes: &Lanes,
    spheres: &[(DVec3, f64, f64, f64)],
    out: &mut Filtered,
    roots: &mut [[[f64; TILE_RAYS]; 2]],
) {
    #[cfg(target_arch = "x86_64")]
    match simd::isa() {
        // SAFETY: `simd::isa` answers AVX-512 only where the processor has it.
        Isa::Avx512 => return unsafe { filter_supports_avx512(lanes, spheres, out, roots) },
        // SAFETY: `simd::isa` answers AVX2 only where the processor has it.
        Isa::Avx2 => return unsafe { filter_supports_avx2(lanes, spheres, out, roots) },
        Isa::Baseline => {}
    }
    filter_supports_lanes(lanes, spheres, out, roots)
}

/// [`filter_supports`] compiled for AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn filter_supports_avx512(
    lanes: &Lanes,
    spheres: &[(DVec3, f64, f64, f64)],
    out: &mut Filtered,
    roots: &mut [[[f64; TILE_RAYS]; 2]],
) {
    filter_supports_lanes(lanes, spheres, out, roots)
}

/// [`filter_supports`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn filter_supports_avx2(
    lanes: &Lanes,
    spheres: &[(DVec3, f64, f64, f64)],
    out: &mut Filtered,
    roots: &mut [[[f64; TILE_RAYS]; 2]],
) {
    filter_supports_lanes(lanes, spheres, out, roots)
}

/// The body of [`filter_supports`], inlined into each instruction set's
/// version.
#[inline(always)]
fn filter_supports_lanes(
    lanes: &Lanes,
    spheres: &[(DVec3, f64, f64, f64)],
    out: &mut Filtered,
    roots: &mut [[[f64; TILE_RAYS]; 2]],
) {
    let Lanes { o, d, dd, lo, hi } = lanes;
    let Filtered { keep, odd, raise } = out;
    for (j, &(centre, k, c0, f)) in spheres.iter().enumerate() {
        let [r0s, r1s] = &mut roots[j];
        for r in 0..TILE_RAYS {
            let (vx, vy, vz) = (o[0][r] - centre.x, o[1][r] - centre.y, o[2][r] - centre.z);
            let c = c0 - k * (vx * vx + vy * vy + vz * vz);
            let b = -2.0 * k * (d[0][r] * vx + d[1][r] * vy + d[2][r] * vz);
            let a = -k * dd[r];
            let (l, h) = (lo[r], hi[r]);
            let meets = b * b - 4.0 * a * c > 0.0
                && ((a * l + b) * l + c > 0.0
                    || (a * h + b) * h + c > 0.0
                    || (2.0 * a * l + b > 0.0 && 2.0 * a * h + b < 0.0));
            keep[r] |= ((meets && a < 0.0) as u64) << j;
            odd[r] |= a >= 0.0;
            // `two_roots`, operation for operation (lanes where it has
            // none hold values that are never read).
            let sq = (b * b - 4.0 * a * c).sqrt();
            let h = -0.5 * (b + sq.copysign(b));
            let (x0, x1) = if h == 0.0 {
                let x = sq / (2.0 * a);
                (-x, x)
            } else {
                (h / a, c / h)
            };
            let (x0, x1) = (fmin(x0, x1), fmax(x0, x1));
            r0s[r] = x0;
            r1s[r] = x1;
            // The most a raising support adds along the whole ray: its
            // value at the vertex, midway between the roots, cubed.
            let m = 0.5 * (x0 + x1);
            let top = fmax((a * m + b) * m + c, 0.0);
            let add = f * top * top * top;
            raise[r] += if meets && a < 0.0 && f > 0.0 {
                add
            } else {
                0.0
            };
        }
    }
}

/// What [`filter_supports`] finds per lane: the supports kept (bit `j`),
/// whether the ray is one that the filter does not cover (a zero
/// direction), and `raise`, an upper bound on `sum f_i Q_i^3` over the
/// whole ray (the kept supports with `f_i > 0`, each at its maximum).
struct Filtered {
    keep: [u64; TILE_RAYS],
    odd: [bool; TILE_RAYS],
    raise: [f64; TILE_RAYS],
}

/// A tile's rays against a sphere base, lane by lane (see [`setup_lanes`]).
struct BaseLanes {
    /// The clipped interval `[t0, t1]` (NaN ends: the ray misses the box).
    t0: [f64; TILE_RAYS],
    t1: [f64; TILE_RAYS],
    /// The base quadric along the ray, ascending powers.
    q: [[f64; TILE_RAYS]; 3],
    /// Its two roots, ascending (meaningful where `two`).
    r0: [f64; TILE_RAYS],
    r1: [f64; TILE_RAYS],
    two: [bool; TILE_RAYS],
    /// Lanes that the closed form below does not cover (a degenerate
    /// quadratic, a zero direction): computed ray by ray instead.
    slow: [bool; TILE_RAYS],
    /// The closed form's hit where no perturbation is met (NaN `t`: none),
    /// its point and the base sphere's normal (`Object::base_hit`, read
    /// only when the sphere's `1 / radius` is positive).
    t: [f64; TILE_RAYS],
    p: [[f64; TILE_RAYS]; 3],
    n: [[f64; TILE_RAYS]; 3],
}

/// For every lane of `lanes` (its `o`, `d`, `dd`; `lo` and `hi` are
/// written here): `Aabb::clip` to `[t_min, t_max]`, the sphere base `(centre,
/// k, c0)` along the ray (`Along::along`), its roots (`quadratic_crossings`)
/// and the split (`Object::base_along_ray`), operation for operation, so
/// that every value is the scalar code's to the last bit. The loop runs
/// over the lanes without branches, so the compiler vectorizes it (AVX2
/// chosen at run time, as for [`filter_supports`]).
fn setup_lanes(
    lanes: &mut Lanes,
    bbox: &Aabb,
    (t_min, t_max): (f64, f64),
    (centre, k, c0, inv_radius): (DVec3, f64, f64, f64),
    out: &mut BaseLanes,
) {
    let sphere = (centre, k, c0, inv_radius);
    #[cfg(target_arch = "x86_64")]
    match simd::isa() {
        // SAFETY: `simd::isa` answers AVX-512 only where the processor has it.
        Isa::Avx512 => {
            return unsafe { setup_lanes_avx512(lanes, bbox, (t_min, t_max), sphere, out) }
        }
        // SAFETY: `simd::isa` answers AVX2 only where the processor has it.
        Isa::Avx2 => return unsafe { setup_lanes_avx2(lanes, bbox, (t_min, t_max), sphere, out) },
        Isa::Baseline => {}
    }
    setup_lanes_body(lanes, bbox, (t_min, t_max), sphere, out)
}

/// [`setup_lanes`] compiled for AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn setup_lanes_avx512(
    lanes: &mut Lanes,
    bbox: &Aabb,
    ends: (f64, f64),
    sphere: (DVec3, f64, f64, f64),
    out: &mut BaseLanes,
) {
    setup_lanes_body(lanes, bbox, ends, sphere, out)
}

/// [`setup_lanes`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn setup_lanes_avx2(
    lanes: &mut Lanes,
    bbox: &Aabb,
    ends: (f64, f64),
    sphere: (DVec3, f64, f64, f64),
    out: &mut BaseLanes,
) {
    setup_lanes_body(lanes, bbox, ends, sphere, out)
}

/// The body of [`setup_lanes`].
#[inline(always)]
fn setup_lanes_body(
    lanes: &mut Lanes,
    bbox: &Aabb,
    (t_min, t_max): (f64, f64),
    (centre, k, c0, inv_radius): (DVec3, f64, f64, f64),
    out: &mut BaseLanes,
) {
    let Lanes { o, d, dd, lo, hi } = lanes;
    let (bmin, bmax) = (bbox.min.to_array(), bbox.max.to_array());
    // Branch-free (`&` and `|` on booleans, selects), so that the loop
    // vectorizes.
    #[inline(always)]
    fn sel(c: bool, a: f64, b: f64) -> f64 {
        if c {
            a
        } else {
            b
        }
    }
    for r in 0..TILE_RAYS {
        // `Aabb::clip`: an axis with a zero direction only tests the
        // origin; the others tighten `[lo, hi]` with real numbers only.
        let (mut l, mut h) = (t_min, t_max);
        let mut outside = false;
        let mut axis = |oa: f64, da: f64, bmin: f64, bmax: f64| {
            let zero = da == 0.0;
            outside |= zero & ((oa < bmin) | (oa > bmax));
            let inv = 1.0 / da;
            let (ta, tb) = ((bmin - oa) * inv, (bmax - oa) * inv);
            let (ta, tb) = (fmin(tb, ta), fmax(ta, tb));
            l = sel(!zero & (ta > l), ta, l);
            h = sel(!zero & (tb < h), tb, h);
        };
        axis(o[0][r], d[0][r], bmin[0], bmax[0]);
        axis(o[1][r], d[1][r], bmin[1], bmax[1]);
        axis(o[2][r], d[2][r], bmin[2], bmax[2]);
        let dead = outside | (l > h);
        // `Along::along` for the sphere base.
        let (vx, vy, vz) = (o[0][r] - centre.x, o[1][r] - centre.y, o[2][r] - centre.z);
        let c = c0 - k * (vx * vx + vy * vy + vz * vz);
        let b = -2.0 * k * (d[0][r] * vx + d[1][r] * vy + d[2][r] * vz);
        let qa = -k * dd[r];
        // `quadratic_crossings` through `two_roots`; its degenerate cases
        // (a zero or nearly linear quadratic, `h == 0`) go ray by ray.
        let scale = fmax(fmax(qa.abs(), b.abs()), c.abs());
        let disc = b * b - 4.0 * qa * c;
        let sq = disc.sqrt();
        let hh = -0.5 * (b + sq.copysign(b));
        let (x0, x1) = (hh / qa, c / hh);
        let (r0, r1) = (fmin(x0, x1), fmax(x0, x1));
        let two = disc > 0.0;
        out.slow[r] = !dead & ((scale == 0.0) | (qa.abs() <= 1e-15 * scale) | (two & (hh == 0.0)));
        // The split: the first root inside `(l, h)`, else `h`.
        let split = sel(
            two & (r0 > l) & (r0 < h),
            r0,
            sel(two & (r1 > l) & (r1 < h), r1, h),
        );
        let nan = f64::NAN;
        out.t0[r] = sel(dead, nan, l);
        out.t1[r] = sel(dead, nan, h);
        lo[r] = sel(dead, nan, l);
        hi[r] = sel(dead, nan, split);
        out.q[0][r] = c;
        out.q[1][r] = b;
        out.q[2][r] = qa;
        out.r0[r] = r0;
        out.r1[r] = r1;
        out.two[r] = two;
    }
    // The closed form's hit (`intersect_in` without perturbations): the
    // first root in `[t0, t1]`, and `base_hit` there.
    let (cx, cy, cz) = (centre.x, centre.y, centre.z);
    for r in 0..TILE_RAYS {
        let (t0, t1) = (out.t0[r], out.t1[r]);
        let (r0, r1, two) = (out.r0[r], out.r1[r], out.two[r]);
        let in0 = two & (r0 >= t0) & (r0 <= t1);
        let in1 = two & (r1 >= t0) & (r1 <= t1);
        let t = sel(in0, r0, sel(in1, r1, f64::NAN));
        out.t[r] = t;
        let (px, py, pz) = (
            o[0][r] + t * d[0][r],
            o[1][r] + t * d[1][r],
            o[2][r] + t * d[2][r],
        );
        out.p[0][r] = px;
        out.p[1][r] = py;
        out.p[2][r] = pz;
        out.n[0][r] = (px - cx) * inv_radius;
        out.n[1][r] = (py - cy) * inv_radius;
        out.n[2][r] = (pz - cz) * inv_radius;
    }
}

#[cfg(test)]
thread_local! {
    /// Lanes given to `solo::walk`, and those it sent back, for the tests.
    pub(super) static SOLO_LANES: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
    pub(super) static SOLO_PAIRS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
    pub(super) static SOLO_SLOW: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// [`Object::intersect_tile`]'s arrays, kept between calls in a thread's
/// [`SCRATCH`] so that no tile pays for clearing or allocating them (their
/// initialization had been a tenth of a 16-bump cast): the rays and their
/// base as lanes, the support roots (per culled support, the two roots for
/// every lane) and the lanes of `solo::walk`.
struct Scratch {
    lanes: Lanes,
    bl: BaseLanes,
    roots: Vec<[[f64; TILE_RAYS]; 2]>,
    solo1: solo::Lanes<1>,
    solo2: solo::Lanes<2>,
    solo3: solo::Lanes<3>,
}

/// What [`PackFrom::into`] copies into the lanes of `solo::walk`: ray
/// `r` of a tile, its base (`bl`), whether it enters the base on its
/// first phase, and the culled spheres and their roots per lane.
struct PackFrom<'a> {
    ray: &'a Ray,
    bl: &'a BaseLanes,
    r: usize,
    enters: bool,
    spheres: &'a [(DVec3, f64, f64, f64)],
    roots: &'a [[[f64; TILE_RAYS]; 2]],
}

impl PackFrom<'_> {
    /// Fills lane `l` of `lanes` with the ray, its base and the supports
    /// `js` (culled indices, ascending: the walk's order).
    #[inline(always)]
    fn into<const K: usize>(self, lanes: &mut solo::Lanes<K>, l: usize, js: [usize; K]) {
        let Self {
            ray,
            bl,
            r,
            enters,
            spheres,
            roots,
        } = self;
        for x in 0..3 {
            lanes.o[x][l] = ray.origin[x];
            lanes.d[x][l] = ray.dir[x];
            lanes.bq[x][l] = bl.q[x][r];
        }
        let nan = f64::NAN;
        lanes.r0[l] = if bl.two[r] { bl.r0[r] } else { nan };
        lanes.r1[l] = if bl.two[r] { bl.r1[r] } else { nan };
        lanes.t0[l] = bl.t0[r];
        lanes.hi[l] = if enters { bl.r0[r] } else { bl.t1[r] };
        lanes.enter[l] = if enters { 1.0 } else { 0.0 };
        for (k, &j) in js.iter().enumerate() {
            let (centre, kk, c0, f) = spheres[j];
            // `Along::along`, operation for operation.
            let v = ray.origin - centre;
            lanes.cq[k][0][l] = c0 - kk * v.length_squared();
            lanes.cq[k][1][l] = -2.0 * kk * ray.dir.dot(v);
            lanes.cq[k][2][l] = -kk * ray.dir.length_squared();
            lanes.clo[k][l] = roots[j][0][r];
            lanes.chi[k][l] = roots[j][1][r];
            lanes.f[k][l] = f;
            for x in 0..3 {
                lanes.sc[k][x][l] = centre[x];
            }
            lanes.sk[k][l] = kk;
            lanes.sc0[k][l] = c0;
        }
    }
}

/// Walks the lanes (`solo::walk`) and writes the hits of the rays
/// `rays[..lanes.n]` into `hits` (with `raw` where a normal is left to
/// normalize); returns the rays sent back, to walk on their own.
fn walk_lanes<const K: usize>(
    lanes: &mut solo::Lanes<K>,
    sphere: solo::BaseSphere,
    rays: &[u8; TILE_RAYS],
    hits: &mut [Option<Hit>],
    raw: &mut [bool; TILE_RAYS],
) -> u64 {
    let n = lanes.n;
    if n == 0 {
        return 0;
    }
    #[cfg(test)]
    {
        SOLO_LANES.with(|c| c.set(c.get() + n));
        if K == 2 {
            SOLO_PAIRS.with(|c| c.set(c.get() + n));
        }
    }
    let mut out = [solo::Outcome::Slow; TILE_RAYS];
    solo::walk(lanes, sphere, &mut out);
    let mut alone = 0;
    for (l, (&r, out)) in rays.iter().zip(&out).take(n).enumerate() {
        let r = r as usize;
        hits[r] = match *out {
            solo::Outcome::Miss => None,
            solo::Outcome::Hit => {
                raw[r] = !lanes.unit[l];
                Some(Hit {
                    t: lanes.t[l],
                    p: DVec3::new(lanes.p[0][l], lanes.p[1][l], lanes.p[2][l]),
                    n: DVec3::new(lanes.nrm[0][l], lanes.nrm[1][l], lanes.nrm[2][l]),
                    offset: 0.0,
                })
            }
            solo::Outcome::Slow => {
                #[cfg(test)]
                SOLO_SLOW.with(|c| c.set(c.get() + 1));
                alone |= 1 << r;
                continue;
            }
        };
    }
    alone
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Box<Scratch>> = std::cell::RefCell::new(Box::new(Scratch {
        lanes: Lanes {
            o: [[0.0; TILE_RAYS]; 3],
            d: [[0.0; TILE_RAYS]; 3],
            dd: [0.0; TILE_RAYS],
            lo: [f64::NAN; TILE_RAYS],
            hi: [f64::NAN; TILE_RAYS],
        },
        bl: BaseLanes {
            t0: [f64::NAN; TILE_RAYS],
            t1: [f64::NAN; TILE_RAYS],
            q: [[0.0; TILE_RAYS]; 3],
            r0: [0.0; TILE_RAYS],
            r1: [0.0; TILE_RAYS],
            two: [false; TILE_RAYS],
            slow: [false; TILE_RAYS],
            t: [f64::NAN; TILE_RAYS],
            p: [[0.0; TILE_RAYS]; 3],
            n: [[0.0; TILE_RAYS]; 3],
        },
        roots: Vec::new(),
        solo1: solo::Lanes::new(),
        solo2: solo::Lanes::new(),
        solo3: solo::Lanes::new(),
    }));
}

impl Object {
    /// [`Object::intersect_culled`] for up to [`TILE_RAYS`] rays of one
    /// beam at once, `hits[k]` for `rays[k]`: the same hits, found with
    /// the clipping, the base quadric's crossings and the first phase of
    /// the perturbation gathering done for all rays together, over arrays
    /// of the rays (loops that the compiler vectorizes), instead of ray by
    /// ray. Rays fall back to [`Object::intersect_culled`] where that does
    /// not apply (a base that is not a sphere, more than 64 culled
    /// perturbations, supports that are not spheres, unbounded ones, and
    /// lanes where the base's quadratic degenerates).
    ///
    /// # Panics
    /// When `rays` holds more than [`TILE_RAYS`] rays or `hits` is not as
    /// long as `rays`.
    pub fn intersect_tile(
        &self,
        rays: &[Ray],
        t_min: f64,
        t_max: f64,
        culled: &[u32],
        hits: &mut [Option<Hit>],
    ) {
        assert!(rays.len() <= TILE_RAYS && hits.len() == rays.len());
        if self.origin == DVec3::ZERO {
            // The world's frame (an object centred on the origin): no copy.
            self.intersect_tile_local(rays, t_min, t_max, culled, hits);
        } else {
            let mut local = [Ray::new(DVec3::ZERO, DVec3::ZERO); TILE_RAYS];
            for (l, ray) in local.iter_mut().zip(rays) {
                *l = self.local(ray);
            }
            self.intersect_tile_local(&local[..rays.len()], t_min, t_max, culled, hits);
        }
        for hit in hits.iter_mut().flatten() {
            *hit = self.world(*hit);
        }
    }

    /// [`Object::intersect_tile`] in the object's frame.
    fn intersect_tile_local(
        &self,
        rays: &[Ray],
        t_min: f64,
        t_max: f64,
        culled: &[u32],
        hits: &mut [Option<Hit>],
    ) {
        let spheres = culled.len() <= 64
            && culled
                .iter()
                .all(|&item| matches!(self.along[item as usize], Along::Sphere { .. }));
        let inv_radius = match self.base_along {
            Along::Sphere { inv_radius, .. } => inv_radius,
            Along::General => 0.0,
        };
        let base = match self.base_along {
            Along::Sphere { centre, k, c0, .. } => Some((centre, k, c0)),
            Along::General => None,
        };
        let Some(base) = base.filter(|_| self.unbounded.is_empty() && spheres) else {
            for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
                *hit = self.intersect_in(ray, t_min, t_max, Items::Only(culled));
            }
            return;
        };
        // Arrays of the rays' coordinates, then per lane the clipped
        // interval, the base's crossings and the first phase's interval
        // `[t0, split]`, all rays together (`setup_lanes`). Dead lanes
        // (rays missing the box, and the lanes past the rays) carry NaN
        // ends, which every test below rejects.
        // Per-tile arrays, kept between calls (see `Scratch`): every lane
        // that is read is written first.
        SCRATCH.with_borrow_mut(|sc| {
            let Scratch {
                lanes,
                bl,
                roots: scratch,
                solo1: lanes_solo1,
                solo2: lanes_solo2,
                solo3: lanes_solo3,
            } = &mut **sc;
            for (k, ray) in rays.iter().enumerate() {
                for a in 0..3 {
                    lanes.o[a][k] = ray.origin[a];
                    lanes.d[a][k] = ray.dir[a];
                }
                lanes.dd[k] = ray.dir.length_squared();
            }
            let sphere = (base.0, base.1, base.2, inv_radius);
            setup_lanes(lanes, &self.bbox, (t_min, t_max), sphere, bl);
            // The closed form's hit of lane `r`, as `base_hit` gives it.
            let closed = |r: usize| {
                let t = bl.t[r];
                (!t.is_nan()).then(|| Hit {
                    t,
                    p: DVec3::new(bl.p[0][r], bl.p[1][r], bl.p[2][r]),
                    n: DVec3::new(bl.n[0][r], bl.n[1][r], bl.n[2][r]),
                    offset: 0.0,
                })
            };
            let sphere_normals = inv_radius > 0.0;
            // Lanes past the rays: zero directions, never read, kept dead.
            for r in rays.len()..TILE_RAYS {
                (lanes.lo[r], lanes.hi[r]) = (f64::NAN, f64::NAN);
            }
            let base_of = |r: usize| {
                let q = [bl.q[0][r], bl.q[1][r], bl.q[2][r]];
                let roots = if bl.two[r] {
                    Crossings::two(bl.r0[r], bl.r1[r])
                } else {
                    Crossings::default()
                };
                (q, roots)
            };
            if culled.is_empty() {
                // No support meets the tile: the base alone, in closed form,
                // as `intersect_in` answers it.
                for (r, (ray, hit)) in rays.iter().zip(hits.iter_mut()).enumerate() {
                    let (t0, t1) = (bl.t0[r], bl.t1[r]);
                    *hit = if bl.slow[r] {
                        self.intersect_in(ray, t_min, t_max, Items::Only(culled))
                    } else if sphere_normals {
                        closed(r)
                    } else if t0.is_nan() {
                        None
                    } else {
                        base_of(r)
                            .1
                            .into_iter()
                            .find(|&x| x >= t0 && x <= t1)
                            .map(|t| self.base_hit(ray, t))
                    };
                }
                return;
            }
            let hi = lanes.hi;
            // Candidate by candidate, all rays: does the support meet the
            // ray on its first phase `[t0, split]`? The arithmetic is
            // `Along::along` and `positive_on` operation for operation, so the
            // answers are those of `gather` to the last bit. `q2 >= 0` (a
            // zero direction) is no sphere's ray: such a ray falls back.
            let spheres: SmallVec<[(DVec3, f64, f64, f64); 64]> = culled
                .iter()
                .map(|&item| match self.along[item as usize] {
                    Along::Sphere { centre, k, c0, .. } => (
                        centre,
                        k,
                        c0,
                        self.perturbations[self.bounded[item as usize] as usize].factor,
                    ),
                    Along::General => unreachable!("checked above"),
                })
                .collect();
            let mut filtered = Filtered {
                keep: [0; TILE_RAYS],
                odd: [false; TILE_RAYS],
                raise: [0.0; TILE_RAYS],
            };
            {
                if scratch.len() < spheres.len() {
                    scratch.resize(spheres.len(), [[0.0; TILE_RAYS]; 2]);
                }
                filter_supports(
                    lanes,
                    &spheres,
                    &mut filtered,
                    &mut scratch[..spheres.len()],
                );
                let Filtered { keep, odd, raise } = filtered;
                let scratch = &*scratch;
                let mut raw = [false; TILE_RAYS];
                // Rays that meet one raising support on their first phase,
                // and either enter the base there or have no second phase,
                // go to the lanes of `solo::walk`; those in `alone` walk on
                // their own.
                let mut alone = 0u64;
                let (mut n1, mut n2, mut n3) = (0, 0, 0);
                let (mut rays1, mut rays2) = ([0u8; TILE_RAYS], [0u8; TILE_RAYS]);
                let mut rays3 = [0u8; TILE_RAYS];
                for (r, ray) in rays.iter().enumerate() {
                    if bl.t0[r].is_nan() {
                        hits[r] = None;
                        continue;
                    }
                    if odd[r] || bl.slow[r] {
                        hits[r] = self.intersect_in(ray, t_min, t_max, Items::Only(culled));
                        continue;
                    }
                    // `F' <= F + raise` along the ray: where even that stays
                    // negative (the concave base's quadratic shifted up by
                    // `raise` has no real root, by a margin of `1e-9` of its
                    // discriminant's terms for rounding), the ray passes above
                    // every bump and meets nothing. (`F'` has no other terms:
                    // the kept supports are all those active on the ray, which
                    // does not enter the base.)
                    let (c, b, a) = (bl.q[0][r], bl.q[1][r], bl.q[2][r]);
                    let (bb, ac) = (b * b, 4.0 * a * (c + raise[r]));
                    if keep[r] != 0 && bb - ac < -1e-9 * (bb + ac.abs()) {
                        hits[r] = None;
                        continue;
                    }
                    let enters = bl.two[r] && bl.r0[r] > bl.t0[r] && bl.r0[r] < bl.t1[r];
                    if keep[r] == 0 && enters {
                        // No support on the first phase, which ends where the
                        // ray enters the base: the walk's answer is that
                        // crossing.
                        hits[r] = if sphere_normals {
                            closed(r)
                        } else {
                            Some(self.base_hit(ray, bl.r0[r]))
                        };
                        continue;
                    }
                    // Rays that meet one to three raising supports on their
                    // first phase, and either enter the base there or have
                    // no second phase (no base crossing inside `(t0, t1)`:
                    // the first phase is the whole interval), go to the
                    // lanes of `solo::walk`; those in `alone` walk on their
                    // own.
                    let inside = |x: f64| x > bl.t0[r] && x < bl.t1[r];
                    let whole = !(bl.two[r] && (inside(bl.r0[r]) || inside(bl.r1[r])));
                    let phase = bl.t0[r] < bl.t1[r] && bl.t1[r].is_finite();
                    let fits = sphere_normals && (enters || (whole && phase));
                    let bits = keep[r].count_ones() as usize;
                    let mut js = [0usize; 3];
                    let mut rest = keep[r];
                    for j in js.iter_mut().take(bits) {
                        *j = rest.trailing_zeros() as usize;
                        rest &= rest.wrapping_sub(1);
                    }
                    let fits = fits
                        && (1..=3).contains(&bits)
                        && js[..bits].iter().all(|&j| spheres[j].3 > 0.0);
                    let pack = PackFrom {
                        ray,
                        bl,
                        r,
                        enters,
                        spheres: &spheres,
                        roots: scratch,
                    };
                    match bits {
                        1 if fits => {
                            pack.into(lanes_solo1, n1, [js[0]]);
                            rays1[n1] = r as u8;
                            n1 += 1;
                        }
                        2 if fits => {
                            pack.into(lanes_solo2, n2, [js[0], js[1]]);
                            rays2[n2] = r as u8;
                            n2 += 1;
                        }
                        3 if fits => {
                            pack.into(lanes_solo3, n3, js);
                            rays3[n3] = r as u8;
                            n3 += 1;
                        }
                        _ => alone |= 1 << r,
                    }
                }
                let sphere = solo::BaseSphere {
                    centre: base.0.to_array(),
                    k: base.1,
                    c0: base.2,
                    inv_radius,
                };
                lanes_solo1.n = n1;
                lanes_solo2.n = n2;
                lanes_solo3.n = n3;
                alone |= walk_lanes(lanes_solo1, sphere, &rays1, hits, &mut raw);
                alone |= walk_lanes(lanes_solo2, sphere, &rays2, hits, &mut raw);
                alone |= walk_lanes(lanes_solo3, sphere, &rays3, hits, &mut raw);
                // The rest, ray by ray (`intersect_culled`, with the first
                // phase's supports taken from the filter).
                while alone != 0 {
                    let r = alone.trailing_zeros() as usize;
                    alone &= alone - 1;
                    let ray = &rays[r];
                    let mut cands: SmallVec<[Candidate; 16]> = SmallVec::new();
                    let mut bits = keep[r];
                    while bits != 0 {
                        let j = bits.trailing_zeros() as usize;
                        bits &= bits - 1;
                        cands.push(self.kept(ray, culled[j], scratch[j][0][r], scratch[j][1][r]));
                    }
                    let (t0, t1) = (bl.t0[r], bl.t1[r]);
                    let (base_q, base_roots) = base_of(r);
                    hits[r] = self.walk::<true>(
                        ray,
                        (t0, t1),
                        (base_q, base_roots, hi[r]),
                        Items::Only(culled),
                        &mut cands,
                        &mut raw[r],
                    );
                }
                // The normals, all together: each is a square root and a division
                // that the loop's independent iterations overlap.
                for ((hit, ray), raw) in hits.iter_mut().zip(rays).zip(raw) {
                    if let (Some(h), true) = (hit, raw) {
                        h.n = unit_normal(h.n, ray);
                    }
                }
            }
        });
    }

    /// The candidate of the kept support `item` on `ray`, with its
    /// roots `lo < hi` (computed for all lanes by the filter).
    #[inline(always)]
    fn kept(&self, ray: &Ray, item: u32, lo: f64, hi: f64) -> Candidate {
        let i = self.bounded[item as usize];
        let p = &self.perturbations[i as usize];
        Candidate {
            index: i,
            item,
            factor: p.factor,
            q: self.along[item as usize].along(&p.quadric, ray),
            lo,
            hi,
        }
    }
}
