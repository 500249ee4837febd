//! Functionally defined objects: a base quadric plus perturbations.
//!
//! ```text
//! F'(p) = F(p) + sum_i f_i R_i(p),   R_i(p) = Q_i(p)^3 if Q_i(p) >= 0 else 0
//! ```
//!
//! (SPEC §1, seed 000 eq. 1-2.) The solid is `F' >= 0`, the surface
//! `F' = 0`, and the outward normal `-grad F' / |grad F'|` with
//!
//! ```text
//! grad F' = grad F + sum_{Q_i >= 0} 3 f_i Q_i^2 grad Q_i.
//! ```
//!
//! ## Exact intersection
//! Along a ray every quadric is a quadratic in `t`, so `F'` is piecewise
//! polynomial of degree <= 6 with breakpoints at the roots of the active
//! `Q_i(t)`. [`Object::intersect`]:
//! 1. clips the ray to the object's box (the base's bounded positive set
//!    united with the supports of bumps `f_i > 0`, intersected with the
//!    optional user `bounds`);
//! 2. gathers the perturbations whose support box the ray crosses (BVH), and
//!    the roots of their `Q_i(t)` inside the interval: the breakpoints;
//! 3. walks the segments between breakpoints in order: with no perturbation
//!    active, the base quadric's crossings in closed form (stable quadratic);
//!    otherwise, unless interval bounds of each term prove that `F'` keeps
//!    one sign on the segment (most of a bump's support, away from the
//!    surface), the degree-6 polynomial in a local parameter with
//!    Bernstein root isolation (see [`crate::poly`]).
//!
//! Rays of one tile (a [`Beam`]) can share the perturbation list that
//! [`Object::cull`] makes for the beam ([`Object::intersect_culled`]), and
//! can be cast together ([`Object::intersect_tile`]): step 2's test of each
//! support against the ray's interval then runs support by support over
//! arrays of the tile's rays, in vector registers, and finds the same
//! candidates. The geometry benchmark's primary rays go that way; the
//! renderer still casts ray by ray (its per-pixel random streams order the
//! camera rays between shading calls).
//!
//! `F'` is C² across breakpoints, so nothing special happens there. No
//! marching, no sphere tracing: thin bumps and grazing rays are found as
//! long as their two crossings are more than `2^-48` of a segment apart.
//!
//! ## Bounds
//! `bounds` clips the *surface* (open surfaces such as a paraboloid cut by a
//! box show their inside through the cut); it does not add caps.

use crate::beam::Beam;
use crate::bvh::Bvh;
use crate::poly::{
    fmax, fmin, quadratic_crossings, sign, two_roots, Bernstein6, Crossings, UnitRoot,
};
use crate::quadric::Quadric;
use isolux_core::{Aabb, DMat3, DVec3, Ray};
use smallvec::SmallVec;

/// One perturbation `f Q^3 [Q >= 0]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Perturbation {
    /// The perturbing quadric `Q_i`.
    pub quadric: Quadric,
    /// Form factor `f_i` (positive: bump, negative: dent).
    pub factor: f64,
}

/// A ray-surface intersection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter.
    pub t: f64,
    /// Hit point.
    pub p: DVec3,
    /// Unit outward normal `-grad F' / |grad F'|`.
    pub n: DVec3,
    /// How far along `n` from `p` a ray leaving the surface starts
    /// ([`Hit::spawn`]) so as not to meet it again at `t ~ 0`: `1e-7 (L +
    /// |p - origin|_inf) + 1e-14 |p|_inf`, with `origin` the object's
    /// frame ([`Object::origin`]) and `L` its length ([`Object::length`]:
    /// its size, at most 1; until 2026-12-06 always 1, which lost the
    /// contact shadows of a scene modelled under about 1e-6 units across,
    /// docs/geometry.md "Scene scale"). The first term covers the exact
    /// intersection's error in the object's frame (a relative 1e-7 holds
    /// even near-tangent crossings, whose roots are ill-conditioned); the
    /// second, about 45 units in the last place of `p`, the rounding of
    /// world coordinates, so the offset no longer grows with the distance
    /// from the world origin (docs/geometry.md, "Scene scale").
    pub offset: f64,
}

/// The length of a box for [`Object::length`]: its largest side, at most
/// 1 (1 for an unbounded or empty box; at least 1e-300).
pub fn length_of(b: &Aabb) -> f64 {
    if b.is_empty() || !b.is_finite() {
        return 1.0;
    }
    (b.max - b.min).max_element().clamp(1e-300, 1.0)
}

/// The part of the world point `at` along the directions in which a
/// translation leaves the quadric `q` unchanged: the plane's own
/// directions for a plane (`m` zero), the axis for a cylinder (`m` of
/// rank two whose null direction `a` has `b . a` zero); zero for any
/// other quadric. Moving the frame's zero from `at` by minus this part
/// brings it to the point nearest the world origin among those where `q`
/// reads the same ([`Object::in_frame`]).
fn invariant_part(q: &Quadric, at: DVec3) -> DVec3 {
    let m = q.m;
    if m == DMat3::ZERO {
        if q.b == DVec3::ZERO {
            return DVec3::ZERO;
        }
        let n = q.b.normalize();
        return at - n * n.dot(at);
    }
    let s = m.abs().to_cols_array().into_iter().fold(0.0, f64::max);
    let (r0, r1, r2) = (m.x_axis, m.y_axis, m.z_axis);
    let a = [r0.cross(r1), r1.cross(r2), r2.cross(r0)]
        .into_iter()
        .max_by(|x, y| x.length_squared().total_cmp(&y.length_squared()))
        .unwrap_or(DVec3::ZERO);
    if !(a.length() > 1e-9 * s * s) {
        return DVec3::ZERO;
    }
    let a = a.normalize();
    let tol = 1e-12 * s * (1.0 + q.b.length() / s);
    if (m * a).abs().max_element() > tol || q.b.dot(a).abs() > tol {
        return DVec3::ZERO;
    }
    a * a.dot(at)
}

impl Hit {
    /// [`Hit::offset`] for a hit at `local` in the frame of an object of
    /// length `length` ([`Object::length`]) and at `world` in world
    /// coordinates (also a bound for a region: its largest coordinates in
    /// each).
    #[inline]
    pub fn offset_at(local: DVec3, world: DVec3, length: f64) -> f64 {
        1e-7 * (length + local.abs().max_element()) + 1e-14 * world.abs().max_element()
    }

    /// The origin of a ray leaving the hit along `w`: `p` moved
    /// [`Hit::offset`] along the normal, to the side of `w`.
    #[inline]
    pub fn spawn(&self, w: DVec3) -> DVec3 {
        if w.dot(self.n) >= 0.0 {
            self.p + self.n * self.offset
        } else {
            self.p - self.n * self.offset
        }
    }
}

/// Errors building an object.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GeometryError {
    /// A perturbation with unbounded support on an unbounded object.
    #[error("perturbation {0} has unbounded support (its quadric is not an ellipsoid) and the object is unbounded: give the object `bounds`")]
    UnboundedPerturbation(usize),
    /// Non-finite coefficient.
    #[error("{0} has a non-finite coefficient")]
    NonFinite(String),
    /// The object's box is empty.
    #[error("the object is empty: its bounds do not overlap its solid")]
    Empty,
}

/// A functionally defined object (see the module docs).
///
/// Its quadrics, boxes and hierarchy live in the object's own frame, whose
/// zero is the world point [`Object::origin`] (near the object, for a
/// bounded one): far from the world origin the quadrics keep small
/// coefficients and the spawn offset stays small ([`Hit::offset`]). The
/// methods take and give world coordinates.
#[derive(Clone, Debug)]
pub struct Object {
    /// The world point that is zero in the object's frame.
    origin: DVec3,
    base: Quadric,
    perturbations: Vec<Perturbation>,
    /// Which perturbation each BVH item is.
    bounded: Vec<u32>,
    /// Perturbations with unbounded support.
    unbounded: Vec<u32>,
    /// Bounding sphere of each BVH item's support (for [`Object::cull`]).
    spheres: Vec<(DVec3, f64)>,
    /// How each BVH item's quadric is restricted to a ray.
    along: Vec<Along>,
    bvh: Bvh,
    bbox: Aabb,
    /// [`Object::length`].
    length: f64,
    /// How the base quadric is restricted to a ray (a sphere, usually).
    base_along: Along,
    /// A ball holding the solid, when it is bounded: tighter than `bbox`
    /// for round objects (for [`Object::meets`]).
    ball: Option<(DVec3, f64)>,
}

/// Which bounded perturbations a ray considers: all (through the BVH) or
/// a list culled for its beam.
#[derive(Clone, Copy, Debug)]
enum Items<'a> {
    All,
    Only(&'a [u32]),
}

/// How a bounded perturbation's `Q_i` is restricted to a ray: spheres, the
/// common case, in 13 multiplications instead of the general quadric's 27.
#[derive(Clone, Copy, Debug)]
enum Along {
    /// `Q(p) = c0 - k |p - centre|^2`, `k > 0`.
    Sphere {
        centre: DVec3,
        k: f64,
        c0: f64,
        /// `1 / radius` (0 for an empty sphere): the unit normal on the
        /// sphere is `(p - centre) / radius`, no square root needed.
        inv_radius: f64,
    },
    /// Any other ellipsoid: [`Quadric::along`].
    General,
}

impl Along {
    fn new(q: &Quadric) -> Self {
        let m = q.m;
        let k = -m.x_axis.x;
        let off = [
            m.x_axis.y, m.x_axis.z, m.y_axis.x, m.y_axis.z, m.z_axis.x, m.z_axis.y,
        ];
        if k > 0.0 && m.y_axis.y == -k && m.z_axis.z == -k && off.iter().all(|&x| x == 0.0) {
            // p^T M p + 2 b.p + c = -k |p - b/k|^2 + c + |b|^2 / k.
            let c0 = q.c + q.b.length_squared() / k;
            let r2 = c0 / k;
            Along::Sphere {
                centre: q.b / k,
                k,
                c0,
                inv_radius: if r2 > 0.0 { 1.0 / r2.sqrt() } else { 0.0 },
            }
        } else {
            Along::General
        }
    }

    /// `Q(o + t d)` as `[c, b, a]` (ascending powers).
    #[inline(always)]
    fn along(&self, q: &Quadric, ray: &Ray) -> [f64; 3] {
        match *self {
            Along::Sphere { centre, k, c0, .. } => {
                let v = ray.origin - centre;
                [
                    c0 - k * v.length_squared(),
                    -2.0 * k * ray.dir.dot(v),
                    -k * ray.dir.length_squared(),
                ]
            }
            Along::General => q.along(ray),
        }
    }

    /// `Q(p)`.
    #[inline(always)]
    fn value(&self, q: &Quadric, p: DVec3) -> f64 {
        match *self {
            Along::Sphere { centre, k, c0, .. } => c0 - k * (p - centre).length_squared(),
            Along::General => q.eval(p),
        }
    }

    /// `Q(p)` and `grad Q(p)`.
    #[inline(always)]
    fn value_gradient(&self, q: &Quadric, p: DVec3) -> (f64, DVec3) {
        match *self {
            Along::Sphere { centre, k, c0, .. } => {
                let v = p - centre;
                (c0 - k * v.length_squared(), -2.0 * k * v)
            }
            Along::General => (q.eval(p), q.gradient(p)),
        }
    }
}

mod solo;
mod tile;

/// Most rays that one [`Object::intersect_tile`] call takes.
pub const TILE_RAYS: usize = 64;

/// A perturbation the current ray crosses.
#[derive(Clone, Copy, Debug)]
struct Candidate {
    /// Perturbation index.
    index: u32,
    /// Its support BVH item (for [`Object::along`]), `u32::MAX` when
    /// unbounded.
    item: u32,
    /// Its form factor `f_i`.
    factor: f64,
    /// `Q_i(t)` along the ray, ascending powers.
    q: [f64; 3],
    /// Active interval `(lo, hi)` for bounded supports; NaN for unbounded.
    lo: f64,
    hi: f64,
}

impl Candidate {
    /// Whether `Q_i` is the concave quadratic of a bounded support, whose
    /// vertex lies midway between the roots `lo` and `hi`.
    #[inline]
    fn concave(&self) -> bool {
        self.q[2] < 0.0 && !self.lo.is_nan()
    }

    /// The maximum of `Q_i` on `[a, b]`: for a bounded support at its
    /// vertex clamped into `[a, b]`, without [`range2`]'s division.
    #[inline]
    fn max_on(&self, a: f64, b: f64) -> f64 {
        if self.concave() {
            poly2(self.q, fmin(fmax(0.5 * (self.lo + self.hi), a), b))
        } else {
            range2(self.q, a, b).1
        }
    }

    /// The range `(min, max)` of `Q_i` on `[a, b]`: for a bounded
    /// support the minimum is at an end (`Q_i` is concave).
    #[inline]
    fn range_on(&self, a: f64, b: f64) -> (f64, f64) {
        if self.concave() {
            (
                fmin(poly2(self.q, a), poly2(self.q, b)),
                poly2(self.q, fmin(fmax(0.5 * (self.lo + self.hi), a), b)),
            )
        } else {
            range2(self.q, a, b)
        }
    }
}

impl Object {
    /// Builds an object from quadrics and `bounds` in world coordinates;
    /// `bounds` clips the surface. The object moves them into its own
    /// frame (see [`Object::in_frame`]).
    pub fn new(
        base: Quadric,
        perturbations: Vec<Perturbation>,
        bounds: Option<Aabb>,
    ) -> Result<Self, GeometryError> {
        Self::in_frame(DVec3::ZERO, base, perturbations, bounds)
    }

    /// Builds an object from quadrics and `bounds` given in a frame whose
    /// zero is the world point `origin` (a world point `p` is `p - origin`
    /// there). Building the quadrics about a point near the object (the
    /// scene loader takes the base's centre) keeps their coefficients
    /// small: a sphere of radius 1 written about the world origin a
    /// million units away has a constant term of `1 - 1e12`, whose
    /// rounding alone moves its surface by 5e-5. The object then moves
    /// its frame to the centre of its box, when that is finite and lies
    /// farther from `origin` than the box's longest side (an object given
    /// about a point near it keeps that point).
    pub fn in_frame(
        origin: DVec3,
        base: Quadric,
        perturbations: Vec<Perturbation>,
        bounds: Option<Aabb>,
    ) -> Result<Self, GeometryError> {
        if !origin.is_finite() {
            return Err(GeometryError::NonFinite("the object's origin".into()));
        }
        let obj = Self::build(origin, base, perturbations, bounds)?;
        // The move of the frame's zero, and whether the base reads the
        // same after it (a move along its unchanging directions).
        let (c, same_base) = if obj.bbox.is_finite() {
            // Moved only when the box lies farther from the frame's zero
            // than its own size: an object near its frame's zero keeps it
            // (and the same numbers to the last bit).
            let c = obj.bbox.center();
            if c.abs().max_element() <= (obj.bbox.max - obj.bbox.min).max_element() {
                return Ok(obj);
            }
            (c, false)
        } else {
            // An unbounded base (a plane, a cylinder) is the same surface
            // about any point of its own along the directions that leave
            // it unchanged, so the point it was written about says nothing
            // of where it is seen: a plane through `[1e7, 0, 0]` is the
            // plane through the world origin. Its frame moves along those
            // directions to the point nearest the world origin, where the
            // scene's camera and objects are, so that hits near them keep
            // a small spawn offset ([`Hit::offset`]); a move under a unit
            // keeps the frame (and the same numbers to the last bit). The
            // base keeps its coefficients: translating them would add the
            // rounding of its unchanging directions times the move squared
            // (a cylinder's axis off by 1e-16 moves its surface by 1e-2
            // over 1e7 units).
            let v = invariant_part(&obj.base, origin);
            if v.abs().max_element() <= 1.0 {
                return Ok(obj);
            }
            (-v, true)
        };
        let Object {
            base,
            perturbations,
            ..
        } = obj;
        let moved = |q: &Quadric| q.translated(-c);
        let perturbations = perturbations
            .iter()
            .map(|p| Perturbation {
                quadric: moved(&p.quadric),
                factor: p.factor,
            })
            .collect();
        let bounds = bounds.map(|b| b.translated(-c));
        let base = if same_base { base } else { moved(&base) };
        Self::build(origin + c, base, perturbations, bounds)
    }

    /// [`Object::in_frame`] without the move to the box's centre.
    fn build(
        origin: DVec3,
        base: Quadric,
        perturbations: Vec<Perturbation>,
        bounds: Option<Aabb>,
    ) -> Result<Self, GeometryError> {
        let finite = |q: &Quadric| q.coefficients().iter().all(|c| c.is_finite());
        if !finite(&base) {
            return Err(GeometryError::NonFinite("the base quadric".into()));
        }
        let base_box = base.positive_bounds();
        let mut bbox = base_box.unwrap_or(Aabb::EVERYTHING);
        // The bumps' largest `f Q^3` added up, and whether a bump's
        // support is unbounded (then no sum bounds them).
        let mut delta = 0.0;
        let mut unbounded_bump = false;
        let mut support = Vec::new();
        let mut spheres = Vec::new();
        let mut along = Vec::new();
        let mut bounded = Vec::new();
        let mut unbounded = Vec::new();
        for (i, p) in perturbations.iter().enumerate() {
            if !finite(&p.quadric) || !p.factor.is_finite() {
                return Err(GeometryError::NonFinite(format!("perturbation {i}")));
            }
            match p.quadric.positive_bounds() {
                Some(b) if b.is_empty() => {}
                Some(b) => {
                    if p.factor > 0.0 {
                        bbox = bbox.union(&b);
                        delta += p.factor * p.quadric.positive_max().unwrap_or(0.0).powi(3);
                    }
                    support.push(b);
                    let sphere = p.quadric.positive_bounding_sphere();
                    spheres.push(sphere.unwrap_or((b.center(), 0.5 * (b.max - b.min).length())));
                    along.push(Along::new(&p.quadric));
                    bounded.push(i as u32);
                }
                None => {
                    if p.factor > 0.0 {
                        bbox = Aabb::EVERYTHING;
                        unbounded_bump = true;
                    }
                    unbounded.push(i as u32);
                }
            }
        }
        // Tighter where the base is bounded: `F' >= 0` only where `F >=
        // -delta`, with `delta` the bumps' largest `f Q^3` added up (a dent
        // only lowers `F'`), an ellipsoid grown from the base's own. So a
        // bump's support far from the base, which makes no surface there,
        // no longer stretches the box, nor a huge support around a small
        // base (the GPU restarts its rays where they enter the box and
        // writes quadrics about a point inside it, in f32).
        if base_box.is_some() && !unbounded_bump {
            let grown = Quadric {
                c: base.c + delta * (1.0 + 1e-9),
                ..base
            };
            if let Some(g) = grown.positive_bounds() {
                bbox = bbox.intersection(&g);
            }
        }
        if let Some(b) = bounds {
            bbox = bbox.intersection(&b);
        }
        if bbox.is_empty() {
            return Err(GeometryError::Empty);
        }
        if !bbox.is_finite() {
            if let Some(&i) = unbounded.first() {
                return Err(GeometryError::UnboundedPerturbation(i as usize));
            }
        }
        let bvh = Bvh::build(&support);
        // The solid lies in the base's positive set united with the
        // supports of the bumps (`f > 0`). (It also lies in the box, whose
        // circumscribed ball `Beam::meets_box` tests already.)
        let mut ball = base.positive_bounding_sphere();
        for (k, &i) in bounded.iter().enumerate() {
            if perturbations[i as usize].factor > 0.0 {
                ball = ball.map(|b| enclose(b, spheres[k]));
            }
        }
        if unbounded_bump {
            ball = None;
        }
        Ok(Self {
            origin,
            base,
            perturbations,
            bounded,
            unbounded,
            spheres,
            along,
            bvh,
            length: length_of(&bbox),
            bbox,
            base_along: Along::new(&base),
            ball,
        })
    }

    /// The world point that is zero in the object's frame, in which
    /// [`Object::base`] and [`Object::perturbations`] are written: the
    /// point it was written about ([`Object::in_frame`]; the world origin
    /// for [`Object::new`]), or the centre of its box where that lies
    /// farther away than the box's size.
    pub fn origin(&self) -> DVec3 {
        self.origin
    }

    /// The base quadric `F`, in the object's frame ([`Object::origin`]).
    pub fn base(&self) -> &Quadric {
        &self.base
    }

    /// The perturbations, in the object's frame ([`Object::origin`]).
    pub fn perturbations(&self) -> &[Perturbation] {
        &self.perturbations
    }

    /// The length that scales the spawn offset's first term
    /// ([`Hit::offset`]): the largest side of the object's box, at most 1;
    /// for an unbounded object, 1, or what [`Object::set_length`] gave it
    /// ([`crate::Aggregate::new`]: the length of the scene's bounded
    /// objects). An offset absolute below a unit made the surfaces of a
    /// scene modelled in small units meet their own rays (or lose contact
    /// shadows): the perturbed-sphere example scaled by 1e-8 rendered 11%
    /// darker; it renders the same at any scale now.
    pub fn length(&self) -> f64 {
        self.length
    }

    /// Sets [`Object::length`] (clamped to `[1e-300, 1]`; NaN is taken as
    /// 1).
    pub fn set_length(&mut self, length: f64) {
        self.length = if length.is_nan() {
            1.0
        } else {
            length.clamp(1e-300, 1.0)
        };
    }

    /// Box containing the surface (infinite for unbounded objects), in
    /// world coordinates.
    pub fn bbox(&self) -> Aabb {
        self.bbox.translated(self.origin)
    }

    /// A ray in the object's frame.
    #[inline]
    fn local(&self, ray: &Ray) -> Ray {
        Ray::new(ray.origin - self.origin, ray.dir)
    }

    /// A hit found in the object's frame, in world coordinates, with its
    /// spawn offset ([`Hit::offset`]). (`t` is the same in both frames:
    /// the direction is.)
    #[inline]
    pub(crate) fn world(&self, hit: Hit) -> Hit {
        let p = hit.p + self.origin;
        Hit {
            p,
            offset: Hit::offset_at(hit.p, p, self.length),
            ..hit
        }
    }

    /// A beam in the object's frame.
    fn local_beam(&self, beam: &Beam) -> Beam {
        beam.translated(-self.origin)
    }

    /// Whether `p` (world coordinates) lies inside the object: in its box,
    /// where `F'(p) > 0`. (A point on the surface is not inside.)
    pub fn contains(&self, p: DVec3) -> bool {
        self.bbox().contains(p) && self.eval(p) > 0.0
    }

    /// `F'(p)`: positive inside (`p` in world coordinates).
    pub fn eval(&self, p: DVec3) -> f64 {
        let p = p - self.origin;
        let mut v = self.base.eval(p);
        for q in &self.perturbations {
            let x = q.quadric.eval(p);
            if x > 0.0 {
                v += q.factor * x * x * x;
            }
        }
        v
    }

    /// `grad F'(p)` (`p` in world coordinates).
    pub fn gradient(&self, p: DVec3) -> DVec3 {
        let p = p - self.origin;
        let mut g = self.base.gradient(p);
        for q in &self.perturbations {
            let x = q.quadric.eval(p);
            if x > 0.0 {
                g += 3.0 * q.factor * x * x * q.quadric.gradient(p);
            }
        }
        g
    }

    /// The Hessian of `F'` at `p` (world coordinates), exact: `2 M` of the
    /// base, and of each active perturbation `6 f Q grad Q grad Q^T + 6 f
    /// Q^2 M_Q` (the second derivative of `f Q^3`, continuous across the
    /// support's edge, where both terms vanish). The surface's curvature
    /// (manifold next-event estimation's Jacobian).
    pub fn hessian(&self, p: DVec3) -> DMat3 {
        let p = p - self.origin;
        let mut h = 2.0 * self.base.m;
        for q in &self.perturbations {
            let x = q.quadric.eval(p);
            if x > 0.0 {
                let g = q.quadric.gradient(p);
                let outer = DMat3::from_cols(g * g.x, g * g.y, g * g.z);
                h += 6.0 * q.factor * x * outer + 6.0 * q.factor * x * x * q.quadric.m;
            }
        }
        h
    }

    /// Unit outward normal at `p` (`-grad F'` normalized).
    pub fn normal(&self, p: DVec3) -> DVec3 {
        (-self.gradient(p)).normalize_or_zero()
    }

    /// First crossing of the surface with `t` in `[t_min, t_max]`.
    ///
    /// Two phases keep the work near the front of the object: candidates
    /// and breakpoints are first gathered only up to the base quadric's
    /// first crossing `L` (perturbations cannot move the surface outside
    /// their supports, so any earlier hit lies in a support that starts
    /// before `L`); only when `[t0, L]` holds no hit (a dent at the base
    /// surface, say) is the rest of the ray gathered and searched.
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit> {
        self.intersect_local(ray, t_min, t_max)
            .map(|h| self.world(h))
    }

    /// [`Object::intersect`] with the hit left in the object's frame (for
    /// [`crate::Aggregate`], which moves only the nearest to the world).
    #[inline]
    pub(crate) fn intersect_local(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit> {
        self.intersect_in(&self.local(ray), t_min, t_max, Items::All)
    }

    /// A lower bound, by closed forms alone, on the first crossing of the
    /// surface `F' = 0` along `ray` (up to `t_max`, which it returns where
    /// it finds nothing sooner) from a start inside the object: the base
    /// quadric's first crossing, or the ray's entry into the support of a
    /// dent (a perturbation of negative factor) if that comes first; 0
    /// where the start lies outside `F > 0` or in a dent's support. Bumps
    /// only add to `F'`, and dents change it only in their supports, so
    /// `F' >= F > 0` before that bound. Without dents, where the base is
    /// crossed first, it is the crossing itself. (Manifold next-event
    /// estimation decides by it whether the exact [`Object::intersect`]
    /// is worth its cost.)
    pub fn exit_bound(&self, ray: &Ray, t_max: f64) -> f64 {
        let local = self.local(ray);
        // Along the ray, ascending powers: the constant term is the value
        // at the start.
        let first = |q: [f64; 3], t: f64| {
            quadratic_crossings(q)
                .iter()
                .copied()
                .find(|&r| r > 0.0 && r < t)
                .unwrap_or(t)
        };
        let base = self.base_along.along(&self.base, &local);
        if !(base[0] > 0.0) {
            return 0.0;
        }
        let mut t = first(base, t_max);
        for q in self.perturbations.iter().filter(|q| q.factor < 0.0) {
            let dent = q.quadric.along(&local);
            if !(dent[0] <= 0.0) {
                return 0.0;
            }
            t = first(dent, t);
        }
        t
    }

    /// Whether some ray of `beam` may meet the object: its box and, for a
    /// bounded solid, a ball around it (the base's positive set and the
    /// bumps' supports), which for round objects rejects the tiles near
    /// the box's corners.
    pub fn meets(&self, beam: &Beam) -> bool {
        let beam = self.local_beam(beam);
        beam.meets_box(&self.bbox) && self.ball.is_none_or(|(c, r)| beam.meets_sphere(c, r))
    }

    /// Appends to `out` the perturbations whose support may meet a ray of
    /// `beam` (those with unbounded support are always considered and not
    /// listed), for [`Object::intersect_culled`].
    /// The list is in perturbation order: the support BVH is walked once
    /// for the whole beam (subtrees whose box the beam misses are
    /// skipped), each reached perturbation tested by its bounding sphere,
    /// and the result sorted, so that it equals a linear scan's.
    pub fn cull(&self, beam: &Beam, out: &mut Vec<u32>) {
        let beam = self.local_beam(beam);
        let start = out.len();
        self.bvh.walk(
            |b| beam.meets_box(b),
            |k| {
                let (c, r) = self.spheres[k as usize];
                if beam.meets_sphere(c, r) {
                    out.push(k);
                }
            },
        );
        out[start..].sort_unstable();
    }

    /// [`Object::cull`] for a `beam` inside an `outer` beam, from the
    /// list `coarse` that [`Object::cull`] made for `outer`: the items of
    /// `coarse` whose bounding sphere `beam` may meet, appended to `out`
    /// in the same order. A flat pass over a short list instead of a BVH
    /// walk; every perturbation that [`Object::cull`] would list is in it
    /// (possibly a few more, whose support no ray of `beam` crosses and
    /// that [`Object::intersect_culled`] sets aside), so hits are the same.
    pub fn cull_within(&self, beam: &Beam, coarse: &[u32], out: &mut Vec<u32>) {
        let beam = self.local_beam(beam);
        out.extend(coarse.iter().copied().filter(|&k| {
            let (c, r) = self.spheres[k as usize];
            beam.meets_sphere(c, r)
        }));
    }

    /// [`Object::intersect`] for a ray inside a beam, considering only the
    /// perturbations that [`Object::cull`] listed for that beam: the same
    /// hit, without the BVH walk.
    pub fn intersect_culled(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        culled: &[u32],
    ) -> Option<Hit> {
        self.intersect_culled_local(ray, t_min, t_max, culled)
            .map(|h| self.world(h))
    }

    /// [`Object::intersect_culled`] with the hit left in the object's frame.
    #[inline]
    pub(crate) fn intersect_culled_local(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        culled: &[u32],
    ) -> Option<Hit> {
        self.intersect_in(&self.local(ray), t_min, t_max, Items::Only(culled))
    }

    fn intersect_in(&self, ray: &Ray, t_min: f64, t_max: f64, items: Items) -> Option<Hit> {
        let (mut t0, mut t1) = self.bbox.clip(ray, t_min, t_max)?;
        if matches!(self.base_along, Along::Sphere { .. }) {
            // A sphere's terms are a centred square, without the loss
            // below, and it meets a face at a point or a curve, never over
            // an area: its rays keep their origin and the exact span, so
            // that the sphere's lanes stay the scalar code's to the bit.
            return self.intersect_clipped(ray, t0, t1, items);
        }
        // Where the ray enters or leaves through a face of the box, the
        // span reaches FACE_ULPS ulps of the ray's reach beyond it (never
        // beyond `[t_min, t_max]`), as on the GPU: a surface lying on the
        // face (a floor plane on its box's bottom) has its crossings and
        // the face's `t` rounded independently, and a quarter of the rays
        // leaving through that face missed it.
        let scale = ray.origin.abs().max_element() / ray.dir.abs().max_element();
        let margin = |t: f64| FACE_ULPS * f64::EPSILON * (scale + t.abs());
        if t0 > t_min {
            t0 = (t0 - margin(t0)).max(t_min);
        }
        if t1 < t_max {
            t1 = (t1 + margin(t1)).min(t_max);
        }
        if t0 > 0.0 {
            // Restarted where the ray enters the box, as the GPU does:
            // along a ray from afar, a quadric's terms are differences of
            // large values, and for an ellipsoid thin along an axis (a
            // disc 2e-6 thick seen from 4 units) their rounding placed
            // the crossing near its pole, where the surface touches the
            // box's face, before the entry, where it was dropped: a third
            // of the rays within 1e-2 of its radius from the pole missed.
            let entry = Ray::new(ray.at(t0), ray.dir);
            return self
                .intersect_clipped(&entry, 0.0, t1 - t0, items)
                .map(|h| Hit { t: h.t + t0, ..h });
        }
        self.intersect_clipped(ray, t0, t1, items)
    }

    /// [`Object::intersect_in`] on `[t0, t1]`, the span of `ray` inside
    /// the object's box.
    fn intersect_clipped(&self, ray: &Ray, t0: f64, t1: f64, items: Items) -> Option<Hit> {
        let none = match items {
            Items::All => self.spheres.is_empty(),
            Items::Only(list) => list.is_empty(),
        };
        if none && self.unbounded.is_empty() {
            // No perturbation can be met: the base quadric alone, in
            // closed form (a plain quadric, or a tile of rays between bumps).
            let t = quadratic_crossings(self.base_along.along(&self.base, ray))
                .into_iter()
                .find(|&r| r >= t0 && r <= t1)?;
            return Some(self.base_hit(ray, t));
        }
        self.intersect_perturbed(ray, t0, t1, items)
    }

    /// [`Object::intersect_in`] on the clipped interval `[t0, t1]` when
    /// perturbations may be met. Kept out of line: its large frame (the
    /// candidate and breakpoint lists) would otherwise be set up for
    /// every ray, also those that the closed form answers.
    #[inline(never)]
    fn intersect_perturbed(&self, ray: &Ray, t0: f64, t1: f64, items: Items) -> Option<Hit> {
        let (base_q, base_roots, split) = self.base_along_ray(ray, t0, t1);
        let mut cands: SmallVec<[Candidate; 16]> = SmallVec::new();
        self.gather(ray, t0, t0, split, items, &mut cands);
        self.walk::<false>(
            ray,
            (t0, t1),
            (base_q, base_roots, split),
            items,
            &mut cands,
            &mut false,
        )
    }

    /// The base quadric along `ray` (ascending powers), its crossings, and
    /// the split: the first crossing inside `(t0, t1)`, else `t1`. Computed
    /// once per ray, they place the two gathering phases and answer every
    /// segment without active perturbations.
    #[inline(always)]
    fn base_along_ray(&self, ray: &Ray, t0: f64, t1: f64) -> ([f64; 3], Crossings, f64) {
        let base_q = self.base_along.along(&self.base, ray);
        let base_roots = quadratic_crossings(base_q);
        let split = base_roots
            .iter()
            .copied()
            .find(|&r| r > t0 && r < t1)
            .unwrap_or(t1);
        (base_q, base_roots, split)
    }

    /// The rest of [`Object::intersect_perturbed`] once the perturbations
    /// active on `[t0, split]` are gathered in `cands` (in `items` order):
    /// the segment walk over `[t0, split]`, then over `[split, t1]`.
    ///
    /// With `DEFER`, a hit off the base's closed form comes back with its
    /// normal not yet normalized (`-grad F'`) and `raw` set, for the
    /// caller to normalize many at once.
    #[inline(always)]
    fn walk<const DEFER: bool>(
        &self,
        ray: &Ray,
        (t0, t1): (f64, f64),
        (base_q, base_roots, split): ([f64; 3], Crossings, f64),
        items: Items,
        cands: &mut SmallVec<[Candidate; 16]>,
        raw: &mut bool,
    ) -> Option<Hit> {
        let mut hit_at = |t: f64, cands: &[Candidate]| {
            if DEFER {
                *raw = true;
                self.hit_at_raw(ray, t, cands)
            } else {
                self.hit_at(ray, t, cands)
            }
        };
        // The sign of F' just before the current position (0: unknown). A
        // crossing within rounding of a breakpoint can escape both
        // neighbouring segments (each sees its end value on its own side
        // of zero): a change of sign across the breakpoint is that crossing.
        let mut before = 0.0;
        for (lo, hi) in [(t0, split), (split, t1)] {
            if hi <= lo && !(lo == t0 && hi == t1) {
                continue;
            }
            if lo > t0 {
                // The first phase's were gathered by the caller.
                self.gather(ray, t0, lo, hi, items, cands);
            }
            if cands.is_empty() {
                // No perturbation on [lo, hi]: the base quadric alone (a
                // change of sign at `lo` first: that crossing comes before
                // any root inside).
                if before * sign(poly2(base_q, lo)) < 0.0 {
                    return Some(hit_at(lo, cands));
                }
                if let Some(t) = base_roots.iter().copied().find(|&r| r >= lo && r <= hi) {
                    return Some(self.base_hit(ray, t));
                }
                before = sign(poly2(base_q, hi));
                if split >= t1 {
                    break;
                }
                continue;
            }
            // Skip ahead to where the bumps can reach (see `reach`).
            let lo = match reach(base_q, cands, lo, hi, hi == split && split < t1) {
                Some(start) => {
                    if start > lo {
                        before = -1.0;
                    }
                    start
                }
                None => {
                    before = -1.0;
                    if split >= t1 {
                        break;
                    }
                    continue;
                }
            };
            let mut breaks: SmallVec<[f64; 32]> = SmallVec::new();
            for c in cands.iter() {
                for x in [c.lo, c.hi] {
                    if x > lo && x < hi {
                        breaks.push(x);
                    }
                }
                if c.lo.is_nan() {
                    for x in quadratic_crossings(c.q) {
                        if x > lo && x < hi {
                            breaks.push(x);
                        }
                    }
                }
            }
            breaks.sort_unstable_by(f64::total_cmp);
            let mut a = lo;
            for k in 0..=breaks.len() {
                let b = if k < breaks.len() { breaks[k] } else { hi };
                if b <= a {
                    continue;
                }
                // A change of sign across the breakpoint `a` is a crossing
                // there, before any the segment holds.
                match self.segment_root(ray, base_q, &base_roots, cands, a, b) {
                    Segment::Crossing { start, .. }
                    | Segment::BaseCrossing { start, .. }
                    | Segment::Clear { start, .. }
                        if before * start < 0.0 =>
                    {
                        return Some(hit_at(a, cands))
                    }
                    Segment::Crossing { t, .. } => return Some(hit_at(t, cands)),
                    Segment::BaseCrossing { t, .. } => return Some(self.base_hit(ray, t)),
                    Segment::Clear { end, .. } => before = end,
                }
                a = b;
            }
            if split >= t1 {
                break;
            }
        }
        None
    }

    /// Adds the perturbations active somewhere on `[lo, hi]` and not yet
    /// gathered (those active before `lo` already are, when `lo > t0`).
    fn gather(
        &self,
        ray: &Ray,
        t0: f64,
        lo: f64,
        hi: f64,
        items: Items,
        cands: &mut SmallVec<[Candidate; 16]>,
    ) {
        let fresh = lo <= t0;
        // Bounded supports are ellipsoids: `q(t)` has a negative leading
        // coefficient, so the perturbation is active exactly between the
        // two roots of `q` (none: never active).
        let mut visit = |item: u32| {
            let i = self.bounded[item as usize];
            let q = self.along[item as usize].along(&self.perturbations[i as usize].quadric, ray);
            let interval = if q[2] < 0.0 {
                // The usual case: decided without the roots' square root
                // and divisions, which only the supports kept need. The
                // second phase asks the first phase's question again, so
                // that the two agree to the last bit on what was gathered.
                if !positive_on(q, lo, hi) || (!fresh && positive_on(q, t0, lo)) {
                    None
                } else {
                    two_roots(q)
                }
            } else {
                // Already gathered in the first phase if active before lo.
                support_interval(q)
                    .filter(|&(r0, r1)| r1 > lo && r0 < hi && (fresh || !(r1 > t0 && r0 < lo)))
            };
            if let Some((r0, r1)) = interval {
                cands.push(Candidate {
                    index: i,
                    item,
                    factor: self.perturbations[i as usize].factor,
                    q,
                    lo: r0,
                    hi: r1,
                });
            }
            true
        };
        match items {
            Items::All => {
                let mut tt = hi;
                self.bvh.traverse(ray, lo, &mut tt, |item, _| visit(item));
            }
            Items::Only(list) => {
                for &item in list {
                    visit(item);
                }
            }
        }
        if fresh {
            // Unbounded supports: active where `q > 0`, tested per segment.
            for &i in &self.unbounded {
                let q = self.perturbations[i as usize].quadric.along(ray);
                cands.push(Candidate {
                    index: i,
                    item: u32::MAX,
                    factor: self.perturbations[i as usize].factor,
                    q,
                    lo: f64::NAN,
                    hi: f64::NAN,
                });
            }
        }
    }

    /// [`Object::hit_at`] where no perturbation is active: a sphere's
    /// normal without the square root (whose latency was a third of a
    /// bump-free cast), other bases from their gradient.
    #[inline]
    fn base_hit(&self, ray: &Ray, t: f64) -> Hit {
        if let Along::Sphere {
            centre, inv_radius, ..
        } = self.base_along
        {
            if inv_radius > 0.0 {
                let p = ray.at(t);
                return Hit {
                    t,
                    p,
                    n: (p - centre) * inv_radius,
                    offset: 0.0,
                };
            }
        }
        self.hit_at(ray, t, &[])
    }

    /// The hit record at `t`: point and outward normal from `grad F'`.
    fn hit_at(&self, ray: &Ray, t: f64, cands: &[Candidate]) -> Hit {
        let mut hit = self.hit_at_raw(ray, t, cands);
        hit.n = unit_normal(hit.n, ray);
        hit
    }

    /// [`Object::hit_at`] with `n = -grad F'` not yet normalized (see
    /// [`unit_normal`]), for callers that normalize many at once.
    ///
    /// The root `t` of the segment's polynomial is first polished by one
    /// Newton step on `F'` evaluated from the quadrics at the point
    /// ([`polish`]): where a bump dwarfs its base, the polynomial expanded
    /// over a long segment has terms far larger than `F'` near the root,
    /// and its root lay microns off the surface, as far as the offset at
    /// which rays leave it (a shell of radius 50 around a white furnace
    /// leaked light through its wall). A long first step is followed by
    /// more ([`POLISH_STEPS`]). The normal is the gradient at the
    /// unpolished point (the steps move it by far less than its rounding).
    #[inline]
    fn hit_at_raw(&self, ray: &Ray, t: f64, cands: &[Candidate]) -> Hit {
        let (v, g) = self.value_gradient(ray.at(t), cands);
        let t = polish_more(t, polish(t, v, g.dot(ray.dir)), |t| {
            let (v, g) = self.value_gradient(ray.at(t), cands);
            (v, g.dot(ray.dir))
        });
        Hit {
            t,
            p: ray.at(t),
            n: -g,
            offset: 0.0,
        }
    }

    /// `F'` and its gradient at `p`, the perturbations in `cands`.
    #[inline(always)]
    fn value_gradient(&self, p: DVec3, cands: &[Candidate]) -> (f64, DVec3) {
        let (mut v, mut g) = self.base_along.value_gradient(&self.base, p);
        for c in cands {
            // Unbounded supports (no BVH item) take the general form.
            let along = self.along.get(c.item as usize).copied();
            let (x, grad) = along
                .unwrap_or(Along::General)
                .value_gradient(&self.perturbations[c.index as usize].quadric, p);
            if x > 0.0 {
                v += c.factor * x * x * x;
                g += 3.0 * c.factor * x * x * grad;
            }
        }
        (v, g)
    }

    /// Whether the surface crosses the ray within `[t_min, t_max]`.
    pub fn occludes(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        self.intersect_local(ray, t_min, t_max).is_some()
    }

    /// First crossing on the segment `[a, b]`, on which the set of active
    /// perturbations is fixed; without one, the signs of `F'` at its ends.
    fn segment_root(
        &self,
        ray: &Ray,
        base_q: [f64; 3],
        base_roots: &[f64],
        cands: &[Candidate],
        a: f64,
        b: f64,
    ) -> Segment {
        let mid = 0.5 * (a + b);
        let active = |c: &Candidate| {
            if c.lo.is_nan() {
                if b.is_finite() {
                    poly2(c.q, mid) > 0.0
                } else {
                    let q = c.q;
                    q[2] > 0.0 || (q[2] == 0.0 && (q[1] > 0.0 || (q[1] == 0.0 && q[0] > 0.0)))
                }
            } else {
                c.lo < mid && mid < c.hi
            }
        };
        match sign_is_fixed(base_q, cands.iter().filter(|c| active(c)), a, b) {
            None => {
                let start = sign(poly2(base_q, a));
                return match base_roots.iter().copied().find(|&r| r >= a && r <= b) {
                    Some(t) => Segment::BaseCrossing { t, start },
                    None => Segment::Clear {
                        start,
                        end: sign(poly2(base_q, b)),
                    },
                };
            }
            Some(Some(s)) => return Segment::Clear { start: s, end: s },
            Some(None) => debug_assert!(b.is_finite()),
        }
        // Local reparameterization t = a + s (b - a), s in [0, 1]: the base
        // quadric's value is re-evaluated at the segment origin (the
        // dominant term, which cancels near the surface); its slope and
        // curvature, and the perturbations, use the Taylor shift of the
        // ray quadratic. The polynomial is built in the Bernstein basis
        // (`Bernstein6`: accurate at both ends of the segment, where the
        // power basis was so only at its origin).
        let len = b - a;
        let mut q = shift(base_q, a, len);
        q[0] = self.base_along.value(&self.base, ray.at(a));
        let mut poly = Bernstein6::quadratic(q);
        for c in cands.iter().filter(|c| active(c)) {
            poly.add_cube(c.factor, shift(c.q, a, len));
        }
        match poly.first_crossing() {
            UnitRoot::Root(s) => Segment::Crossing {
                t: a + s * len,
                start: sign(poly.b[0]),
            },
            UnitRoot::Clear { start, end } => {
                // A base root where the active perturbations add less than
                // the base's own rounding (a support that ends there) is
                // the crossing, whatever the polynomial's rounded ends
                // say: `F` changes sign there and `f Q^3` vanishes to
                // third order. (`solo::Walk::active` sends such rays here.)
                let negligible = |r: f64| {
                    let bump: f64 = cands
                        .iter()
                        .filter(|c| active(c))
                        .map(|c| {
                            let x = poly2(c.q, r).max(0.0);
                            c.factor * x * x * x
                        })
                        .sum();
                    let scale = base_q[0].abs() + (base_q[1] * r).abs() + (base_q[2] * r * r).abs();
                    bump.abs() <= BUMP_NEGLIGIBLE * scale
                };
                match base_roots
                    .iter()
                    .copied()
                    .find(|&r| r >= a && r <= b && negligible(r))
                {
                    Some(t) => Segment::BaseCrossing { t, start },
                    None => Segment::Clear { start, end },
                }
            }
        }
    }
}

/// Where the active perturbations add at most this fraction of the base
/// quadric's terms at a root of the base, the root is a crossing of `F'`
/// (see `Object::segment_root`).
pub(crate) const BUMP_NEGLIGIBLE: f64 = 1e-14;

/// The unit normal along `-grad F'` (given as `minus_grad`), or against
/// the ray where the gradient vanishes.
#[inline]
fn unit_normal(minus_grad: DVec3, ray: &Ray) -> DVec3 {
    minus_grad
        .try_normalize()
        .unwrap_or_else(|| -ray.dir.normalize())
}

/// What [`Object::segment_root`] found on a segment.
enum Segment {
    /// The first crossing.
    Crossing {
        t: f64,
        /// The sign of `F'` at the segment's start (as `Clear`'s).
        start: f64,
    },
    /// The first crossing, of the base quadric where no perturbation is
    /// active.
    BaseCrossing { t: f64, start: f64 },
    /// None: the signs (`1`, `-1`, `0` unknown) of `F'` just after the
    /// segment's start and just before its end.
    Clear { start: f64, end: f64 },
}

/// Whether `F'` keeps one sign on `[a, b]` by interval bounds, so that
/// the segment holds no crossing and its degree-6 polynomial need not
/// be built. Each term is bounded on its own: the base quadratic and
/// every active `Q_i(t) >= 0` by their values at the ends and at the
/// vertex when inside, `f_i Q_i^3` by the cube of those bounds. A
/// margin of `1e-10` of the terms' magnitude covers rounding, so only a
/// segment whose `F'` stays clear of zero is skipped (most of a
/// bump's support away from the surface).
///
/// `None` when no perturbation is active on the segment (then `b` may be
/// infinite): the base quadric alone answers. Otherwise `Some(sign)` when
/// the sign is fixed (`1` inside, `-1` outside), `Some(None)` when not.
fn sign_is_fixed<'a>(
    base_q: [f64; 3],
    active: impl Iterator<Item = &'a Candidate>,
    a: f64,
    b: f64,
) -> Option<Option<f64>> {
    let mut active = active.peekable();
    active.peek()?;
    let (base_min, base_max) = range2(base_q, a, b);
    let (mut lo, mut hi) = (base_min, base_max);
    let mut scale = base_min.abs() + base_max.abs() + base_q[0].abs();
    for c in active {
        let f = c.factor;
        let (qmin, qmax) = c.range_on(a, b);
        // Active: Q >= 0 on the segment (up to rounding at its ends).
        let (qmin, qmax) = (fmax(qmin, 0.0), fmax(qmax, 0.0));
        let (rmin, rmax) = (f * qmin * qmin * qmin, f * qmax * qmax * qmax);
        if f > 0.0 {
            lo += rmin;
            hi += rmax;
        } else {
            lo += rmax;
            hi += rmin;
        }
        scale += rmin.abs() + rmax.abs();
    }
    let margin = 1e-10 * scale;
    Some(if hi < -margin {
        Some(-1.0)
    } else if lo > margin {
        Some(1.0)
    } else {
        None
    })
}

/// The first `t` in `[lo, hi]` where `F'` may reach zero, or `None` when
/// `F' < 0` on all of it.
///
/// Perturbations with `f_i > 0` raise `F'` by at most `B = sum f_i
/// max(Q_i)^3` (each maximum taken on the part of `[lo, hi]` where `Q_i` is
/// active), and those with `f_i < 0` only lower it, so `F' <= F + B`:
/// before the first point where the base quadratic reaches `-B`, the ray is
/// outside the solid. For bumps on a surface that is the inflated base
/// (a sphere of radius 0.65 around the benchmark's 0.6): the segment walk
/// and the degree-6 polynomial then start a bump's height from the surface
/// instead of at the edge of its support, and rays that pass the support
/// above the bump are done after one quadratic. `B` is widened by `1e-10`
/// of the magnitudes involved, so that rounding cannot skip a crossing.
///
/// With `entering` (`hi` is where the ray enters a concave base), the
/// start is where the base's tangent line at `hi` reaches `-B`: no later
/// than the quadratic's own root (the line lies above the curve), found
/// without a square root. It is earlier by a share of about `|q2| B /
/// slope^2`, which grazing rays pay in longer segments: measured side by
/// side, 3% faster at 16 benchmark bumps, 1.5% at 64, 2% slower at 256
/// (where a tightness test to choose between the two cost more than it
/// saved).
fn reach(base_q: [f64; 3], cands: &[Candidate], lo: f64, hi: f64, entering: bool) -> Option<f64> {
    if !hi.is_finite() {
        return Some(lo);
    }
    let mut bound = 0.0;
    for c in cands.iter().filter(|c| c.factor > 0.0) {
        let (a, b) = if c.lo.is_nan() {
            (lo, hi)
        } else {
            (fmax(c.lo, lo), fmin(c.hi, hi))
        };
        if a < b {
            let qmax = fmax(c.max_on(a, b), 0.0);
            bound += c.factor * qmax * qmax * qmax;
        }
    }
    let flo = poly2(base_q, lo);
    let scale = base_q[0].abs() + (base_q[1] * hi).abs() + (base_q[2] * hi * hi).abs() + bound;
    let bound = bound + 1e-10 * scale;
    if !(flo + bound < 0.0) {
        // Reachable at once (or not finite: no claim).
        return Some(lo);
    }
    if entering && base_q[2] < 0.0 {
        // `hi` is where the ray enters the concave base: below its tangent
        // line there, `F(t) <= F(hi) + F'(hi) (t - hi)`, so `F` reaches
        // `-B` no earlier than where that line does. A start as safe as
        // the root's, without its square root.
        let slope = base_q[1] + 2.0 * base_q[2] * hi;
        if slope > 0.0 {
            let start = hi - (bound + poly2(base_q, hi)) / slope;
            return Some(fmax(fmin(start, hi), lo));
        }
    }
    let shifted = [base_q[0] + bound, base_q[1], base_q[2]];
    quadratic_crossings(shifted)
        .into_iter()
        .find(|&r| r > lo && r <= hi)
}

/// The smallest ball holding the balls `a` and `b` (centre, radius).
fn enclose(a: (DVec3, f64), b: (DVec3, f64)) -> (DVec3, f64) {
    let d = (b.0 - a.0).length();
    if d + b.1 <= a.1 {
        return a;
    }
    if d + a.1 <= b.1 {
        return b;
    }
    let r = 0.5 * (d + a.1 + b.1);
    // On the segment from a's centre towards b's, r - a.1 along it.
    let c = a.0 + (b.0 - a.0) * ((r - a.1) / d);
    // Rounding: pad so that both balls stay inside.
    (c, r * (1.0 + 1e-12) + 1e-15)
}

/// The range `(min, max)` of the quadratic `q` (ascending powers) on
/// `[a, b]`: its values at the ends, and at the vertex when the slope
/// changes sign in between.
#[inline]
fn range2(q: [f64; 3], a: f64, b: f64) -> (f64, f64) {
    let (va, vb) = (poly2(q, a), poly2(q, b));
    let (mut lo, mut hi) = (fmin(va, vb), fmax(va, vb));
    let (da, db) = (2.0 * q[2] * a + q[1], 2.0 * q[2] * b + q[1]);
    if (da < 0.0) != (db < 0.0) && q[2] != 0.0 {
        let v = q[0] - q[1] * q[1] / (4.0 * q[2]);
        lo = fmin(lo, v);
        hi = fmax(hi, v);
    }
    (lo, hi)
}

/// The interval where an ellipsoid support's `q(t)` (ascending powers,
/// `q[2] < 0` for any ray direction) is positive: its two roots, without
/// the general case's degeneracy tests.
#[inline]
fn support_interval(q: [f64; 3]) -> Option<(f64, f64)> {
    if q[2] < 0.0 {
        two_roots(q)
    } else {
        quadratic_crossings(q).pair()
    }
}

/// Whether the concave quadratic `q` (ascending powers, `q[2] < 0`) is
/// positive somewhere in `(lo, hi)`: at an end, or at its vertex when
/// the slope changes sign in between (no square root, no division).
#[inline]
fn positive_on(q: [f64; 3], lo: f64, hi: f64) -> bool {
    let [c, b, a] = q;
    b * b - 4.0 * a * c > 0.0
        && (poly2(q, lo) > 0.0
            || poly2(q, hi) > 0.0
            || (2.0 * a * lo + b > 0.0 && 2.0 * a * hi + b < 0.0))
}

/// `q(a + s len)` as a quadratic in `s`.
#[inline]
fn shift(q: [f64; 3], a: f64, len: f64) -> [f64; 3] {
    let [c0, c1, c2] = q;
    [
        (c2 * a + c1) * a + c0,
        (2.0 * c2 * a + c1) * len,
        c2 * len * len,
    ]
}

/// The largest Newton step [`polish`] takes, relative to `t`: the roots
/// of the segment polynomials are that good wherever a bump's terms stay
/// within about 1e9 of `F'` near the surface (a shell 50 units across
/// whose `f Q^3` reached 4e13 needed 3e-8); a longer step is a graze
/// (`dF'/dt` near zero), where Newton's step is no better than the root.
const POLISH_LIMIT: f64 = 1e-6;

/// At most how many Newton steps [`polish`] takes per hit: a step longer
/// than [`POLISH_AGAIN`] of `t` is followed by another, so that a root
/// 3e-6 off (the shell above) ends within rounding (one step left it
/// 2e-9 off, beyond the spawn offset).
const POLISH_STEPS: usize = 3;

/// See [`POLISH_STEPS`]: a well-conditioned root's first step is a few
/// ulps, and no second one is taken.
const POLISH_AGAIN: f64 = 1e-12;

/// The Newton steps after the first, which took `t` to `first`: while
/// the last step was longer than [`POLISH_AGAIN`] of its start, another
/// ([`polish`], with `F'` and its slope at a point from `at`), up to
/// [`POLISH_STEPS`] in all. `Object::hit_at_raw` and `solo::hits` share
/// it, so the lanes take the per-ray steps to the bit.
#[inline(always)]
fn polish_more(t: f64, first: f64, mut at: impl FnMut(f64) -> (f64, f64)) -> f64 {
    let (mut before, mut after) = (t, first);
    for _ in 1..POLISH_STEPS {
        if (after - before).abs() <= POLISH_AGAIN * before.abs() {
            break;
        }
        let (v, slope) = at(after);
        (before, after) = (after, polish(after, v, slope));
    }
    after
}

/// `t` moved by one Newton step on `F'` (`value` and `slope`, its
/// derivative along the ray, at `t`), where the step is finite and within
/// [`POLISH_LIMIT`] of `t`; else `t` unchanged. `solo::hits` does the
/// same, operation for operation.
#[inline(always)]
fn polish(t: f64, value: f64, slope: f64) -> f64 {
    let step = value / slope;
    if step.abs() <= POLISH_LIMIT * t.abs() {
        t - step
    } else {
        t
    }
}

/// How far, in ulps of a ray's reach, `Object::intersect_in` takes a
/// ray's span beyond the box faces it crosses (the GPU's kernels take 16
/// ulps of f32 or f64, `geometry.wgsl`'s `object_hit`).
const FACE_ULPS: f64 = 16.0;

#[inline]
fn poly2(q: [f64; 3], t: f64) -> f64 {
    (q[2] * t + q[1]) * t + q[0]
}

#[cfg(test)]
mod tests {
    use super::*;
    use isolux_core::DMat3;

    /// Discs (ellipsoids 0.45 x 0.6 x 2r, r from 1e-3 down to 1e-7), at
    /// the origin and off it, hit from about 4 units away by rays aimed at
    /// points from the pole out to 1e-2 of the radius: every ray hits the
    /// front face, between the mid-plane and the face's farthest reach along
    /// the ray (r / |d_z|). The box's face touches the surface at the pole;
    /// the quadric along a ray from afar placed the crossing there before
    /// the box's entry by rounding, and a third of these rays missed a disc
    /// 2e-6 thick (`Object::intersect_in` restarts at the entry).
    #[test]
    fn thin_discs_are_hit_at_their_pole() {
        for r in [1e-3, 1e-4, 1e-5, 1e-6, 1e-7] {
            for c in [DVec3::ZERO, DVec3::new(0.75, -0.2, 0.3)] {
                let e = Quadric::ellipsoid(c, DVec3::new(0.45, 0.6, r), DMat3::IDENTITY);
                let o = Object::new(e, vec![], None).unwrap();
                assert!(o.bbox().is_finite());
                for rho in [0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2] {
                    for j in 0..100 {
                        let (phi, k) = (j as f64 * 0.1, j as f64);
                        let to = c + DVec3::new(0.45 * rho * phi.cos(), 0.6 * rho * phi.sin(), 0.0);
                        let side = DVec3::new(0.3 * (k * 0.37).sin(), 0.3 * (k * 0.71).cos(), 0.0);
                        let from = to + side + DVec3::new(0.0, 0.0, 4.0);
                        let ray = Ray::new(from, (to - from).normalize());
                        let h = o
                            .intersect(&ray, 0.0, 1e30)
                            .unwrap_or_else(|| panic!("r {r}, centre {c}, rho {rho}: missed"));
                        // The mid-plane z = c.z at t_mid; the front face
                        // at most r / |d_z| before it.
                        let t_mid = (c.z - from.z) / ray.dir.z;
                        let reach = r / ray.dir.z.abs();
                        assert!(
                            h.t <= t_mid + 1e-9 && h.t >= t_mid - reach * (1.0 + 1e-6) - 1e-9,
                            "r {r}, rho {rho}: t {} against [{}, {t_mid}]",
                            h.t,
                            t_mid - reach
                        );
                        assert!(h.n.z > 0.99, "r {r}, rho {rho}: normal {}", h.n);
                    }
                }
            }
        }
    }

    /// An unbounded base written about a far point of its own (a plane, a
    /// cylinder up its axis, tilted) moves its frame to the point nearest
    /// the world origin along the directions that leave it unchanged, so
    /// its hits near the origin keep the offset they have written about a
    /// near point; a paraboloid, a cone and a plane's point off the origin
    /// along its normal keep theirs (a move would change the surface).
    #[test]
    fn unbounded_bases_move_their_frame_near_the_world_origin() {
        let tilt = DVec3::new(0.3, 1.0, -0.2).normalize();
        let side = tilt.cross(DVec3::X).normalize();
        let cases = [
            (Quadric::plane(DVec3::ZERO, tilt), 1e7 * side, DVec3::ZERO),
            (
                Quadric::plane(DVec3::ZERO, tilt),
                3.0 * tilt + 1e7 * side,
                3.0 * tilt,
            ),
            (
                Quadric::cylinder(DVec3::ZERO, tilt, 0.5),
                1e7 * tilt,
                DVec3::ZERO,
            ),
            (
                Quadric::cylinder(DVec3::ZERO, tilt, 0.5),
                side + 1e6 * tilt,
                side,
            ),
        ];
        for (q, at, want) in cases {
            let o = Object::in_frame(at, q, vec![], None).unwrap();
            assert!(
                (o.origin() - want).length() < 1e-6,
                "{q:?} about {at}: frame at {}, want {want}",
                o.origin()
            );
            // The same surface: `q` reads the same about `at` and about
            // `want`, a move along its unchanging directions away (written
            // about `want`, since about `at` rounding alone would differ).
            for k in 0..20 {
                let p = want + DVec3::new(k as f64 * 0.37 - 3.0, (k as f64 * 1.3).sin(), 0.5);
                let exact = q.eval(p - want);
                let near = o.base().eval(p - o.origin());
                assert!(
                    (exact - near).abs() < 1e-6 * (1.0 + exact.abs()),
                    "{exact} against {near}"
                );
            }
            let from = want + 3.0 * side + 0.5 * tilt;
            let ray = Ray::new(from, (want - from).normalize());
            let h = o.intersect(&ray, 0.0, 1e30).expect("hit");
            assert!(h.offset < 1e-5, "offset {}", h.offset);
        }
        let kept = [
            Quadric::paraboloid(DVec3::ZERO, tilt, 0.25),
            Quadric::cone(DVec3::ZERO, tilt, 0.3),
            Quadric::sphere(DVec3::ZERO, 1.0),
        ];
        for q in kept {
            let at = 2.0 * side + 1e3 * tilt;
            let o = Object::in_frame(at, q, vec![], None).unwrap();
            if !o.bbox().is_finite() {
                assert_eq!(o.origin(), at, "{q:?}");
            }
        }
    }

    /// Planes lying on a face of their box (a floor `y = 0` whose `bounds`
    /// end at `y = 0`, tilted planes on a tilted box's face excluded: the
    /// box is axis-aligned), hit through that face from inside the box (the
    /// ray leaves through it) and from outside (it enters through it), from
    /// near and far, at any angle: every ray hits, where the plane is. The
    /// span ended exactly at the face, and the crossing, rounded
    /// independently, fell beyond it on a quarter of the leaving rays (a
    /// fuzzed scene's floor was a quarter sky).
    #[test]
    fn planes_on_their_boxs_face_are_hit() {
        let mut rng = isolux_core::Pcg32::new(5, 8);
        for plane in crate::samples::planes_on_their_boxs_face() {
            let (axis, offset) = (plane.axis, plane.offset);
            let mut missed = 0;
            for (from, to) in plane.rays(400, &mut rng) {
                let far = (to - from).length();
                let ray = Ray::new(from, (to - from) / far);
                match plane.object.intersect(&ray, 0.0, f64::INFINITY) {
                    Some(h) => {
                        assert!((h.p[axis] - offset).abs() < 1e-12, "{}", h.p);
                        assert!((h.t - far).abs() < 1e-9 * far.max(1.0), "{} {far}", h.t);
                    }
                    None => missed += 1,
                }
            }
            assert_eq!(
                missed, 0,
                "axis {axis}, side {}, offset {offset}",
                plane.side
            );
        }
    }

    /// A bump that dwarfs its base (the white furnace's sphere with a
    /// support of radius 50 and factor 2500, a fuzzed scene: `f Q^3` up to
    /// 4e13 where `F'` near the surface is of order 1e3) makes a closed
    /// shell around the camera. Diffuse paths bouncing inside it (5,000
    /// paths of 64 bounces, leaving each hit by `Hit::spawn`) must never
    /// get out: the segment polynomials' roots lay microns off the wall,
    /// as far as the spawn offset there (`1e-7 (1 + |p|)`, 5e-6), and
    /// where a root lay outside by more, the next ray met the wall again
    /// from outside and went on outward (16 leaks here; the furnace
    /// rendered speckles of sky where it is black). Now every hit is
    /// polished by Newton steps on `F'` itself (`polish`, up to
    /// `POLISH_STEPS`): each lies within 1e-9 of the surface (by `|F'| /
    /// |grad F'|`; one step left 2.3e-9), and no path leaks. Tiles of
    /// camera rays, polished in lanes, give the per-ray hits to the bit
    /// (without the lanes' further steps they differ in the last bits).
    #[test]
    fn paths_inside_a_bump_shell_stay_inside() {
        use isolux_core::{sampling, Frame, Pcg32};
        let o = Object::new(
            Quadric::sphere(DVec3::ZERO, 0.6),
            vec![
                Perturbation {
                    quadric: Quadric::sphere(DVec3::new(0.0, 0.0, 0.6), 0.35),
                    factor: -600.0,
                },
                Perturbation {
                    quadric: Quadric::sphere(DVec3::new(0.45, 0.3, 0.3), 50.0),
                    factor: 2500.0,
                },
            ],
            None,
        )
        .unwrap();
        let mut rng = Pcg32::new(1, 2);
        let (mut leaks, mut worst) = (0, 0.0f64);
        for _ in 0..5000 {
            let d = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
            let mut ray = Ray::new(DVec3::new(0.3, 0.5, 3.0), d);
            for _ in 0..64 {
                let Some(h) = o.intersect(&ray, 0.0, f64::INFINITY) else {
                    leaks += 1;
                    break;
                };
                worst = worst.max(o.eval(h.p).abs() / o.gradient(h.p).length());
                let n = if h.n.dot(ray.dir) > 0.0 { -h.n } else { h.n };
                let wi = Frame::from_normal(n).to_world(sampling::cosine_hemisphere([
                    rng.next_f64(),
                    rng.next_f64(),
                ]));
                ray = Ray::new(h.spawn(wi), wi);
            }
        }
        assert!(worst < 1e-9, "a hit {worst:e} off the surface");
        assert_eq!(leaks, 0);
        // Tiles of camera rays (`solo::hits` polishes in lanes): the
        // per-ray hits to the last bit.
        let culled = [0, 1];
        for k in 0..16 {
            let axis = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
            let (u, v) = axis.any_orthonormal_pair();
            let rays: Vec<Ray> = (0..TILE_RAYS)
                .map(|j| {
                    let (x, y) = ((j % 8) as f64 - 3.5, (j / 8) as f64 - 3.5);
                    Ray::new(
                        DVec3::new(0.3, 0.5, 3.0),
                        axis + 1e-3 * (k as f64 + 1.0) * (x * u + y * v),
                    )
                })
                .collect();
            let mut got = vec![None; rays.len()];
            o.intersect_tile(&rays, 0.0, f64::INFINITY, &culled, &mut got);
            for (ray, got) in rays.iter().zip(&got) {
                assert_eq!(*got, o.intersect_culled(ray, 0.0, f64::INFINITY, &culled));
                let h = got.expect("the shell");
                assert!(o.eval(h.p).abs() / o.gradient(h.p).length() < 1e-9);
            }
        }
    }

    /// The lanes of `solo::walk` (one or two supports) answer most rays of
    /// bumpy spheres (random
    /// parallel and perspective tiles; bumps that raise, carve, or barely
    /// rise; directions of any length; open and finite intervals), and
    /// their answers are the per-ray walk's to the last bit, with every
    /// instruction set.
    #[test]
    fn solo_lanes_match_the_per_ray_walk() {
        use crate::simd::Isa;
        for (seed, cap) in [(41, None), (42, Some(Isa::Baseline)), (43, Some(Isa::Avx2))] {
            crate::simd::FORCE.with(|f| f.set(cap));
            solo_lanes_match(seed);
        }
        crate::simd::FORCE.with(|f| f.set(None));
    }

    fn solo_lanes_match(seed: u64) {
        use super::tile::{SOLO_LANES, SOLO_PAIRS, SOLO_SLOW};
        let mut rng = isolux_core::Pcg32::new(seed, 0);
        let (lanes0, slow0) = (SOLO_LANES.with(|c| c.get()), SOLO_SLOW.with(|c| c.get()));
        let pairs0 = SOLO_PAIRS.with(|c| c.get());
        let (mut rays_cast, mut hits) = (0, 0);
        for scene in 0..16 {
            let bumps = [1, 3, 16, 40][scene % 4];
            let perts = crate::samples::fibonacci_sphere(bumps, 0.6)
                .into_iter()
                .map(|c| {
                    let factor = match rng.next_below(6) {
                        0 => -300.0,
                        1 => 1e-3,
                        _ => 1000.0 * (0.2 + 2.0 * rng.next_f64()),
                    };
                    let radius = 0.1 + 0.2 * rng.next_f64();
                    Perturbation {
                        quadric: Quadric::sphere(c, radius),
                        factor,
                    }
                })
                .collect();
            let obj = Object::new(Quadric::sphere(DVec3::ZERO, 0.6), perts, None).unwrap();
            let culled: Vec<u32> = (0..bumps as u32).collect();
            for _ in 0..60 {
                let axis = isolux_core::sampling::uniform_sphere(rng.next_2d());
                let target = 0.6 * isolux_core::sampling::uniform_sphere(rng.next_2d())
                    + 0.1 * (rng.next_f64() - 0.5) * axis;
                let (u, v) = axis.any_orthonormal_pair();
                let pitch = 10f64.powf(-3.0 + 2.0 * rng.next_f64());
                let length = 0.5 + 2.0 * rng.next_f64();
                let eye = target - 2.0 * axis;
                let perspective = rng.next_below(2) == 0;
                let rays: Vec<Ray> = (0..TILE_RAYS)
                    .map(|k| {
                        let (x, y) = ((k % 8) as f64 - 3.5, (k / 8) as f64 - 3.5);
                        let off = pitch * (x * u + y * v);
                        if perspective {
                            Ray::new(eye, (2.0 * axis + off) * length)
                        } else {
                            Ray::new(eye + off, axis * length)
                        }
                    })
                    .collect();
                let (t_min, t_max) = if rng.next_below(3) == 0 {
                    (0.3 * rng.next_f64(), 1.0 + 2.0 * rng.next_f64())
                } else {
                    (0.0, f64::INFINITY)
                };
                let mut got = vec![None; rays.len()];
                obj.intersect_tile(&rays, t_min, t_max, &culled, &mut got);
                for (ray, got) in rays.iter().zip(&got) {
                    let want = obj.intersect_culled(ray, t_min, t_max, &culled);
                    assert_eq!(*got, want, "{ray:?} on [{t_min}, {t_max}]");
                    rays_cast += 1;
                    hits += got.is_some() as usize;
                }
            }
        }
        let lanes = SOLO_LANES.with(|c| c.get()) - lanes0;
        let slow = SOLO_SLOW.with(|c| c.get()) - slow0;
        let pairs = SOLO_PAIRS.with(|c| c.get()) - pairs0;
        eprintln!(
            "{rays_cast} rays, {hits} hits, {lanes} lanes ({pairs} with two supports), {slow} sent back"
        );
        assert!(pairs > rays_cast / 50, "{pairs} lanes with two supports");
        assert!(hits > rays_cast / 4, "{hits} of {rays_cast}");
        assert!(
            lanes > rays_cast / 8 && slow < lanes / 20,
            "{lanes} lanes, {slow} slow"
        );
    }

    #[test]
    fn plain_sphere_hit() {
        let o = Object::new(Quadric::sphere(DVec3::ZERO, 1.0), vec![], None).unwrap();
        let r = Ray::new(DVec3::new(0.0, 0.0, -5.0), DVec3::Z);
        let h = o.intersect(&r, 0.0, f64::INFINITY).unwrap();
        assert!((h.t - 4.0).abs() < 1e-12);
        assert!((h.n - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
        // From inside: exits at t = 1 with outward normal +z.
        let r = Ray::new(DVec3::ZERO, DVec3::Z);
        let h = o.intersect(&r, 0.0, f64::INFINITY).unwrap();
        assert!((h.t - 1.0).abs() < 1e-12 && h.n.z > 0.999);
    }

    #[test]
    fn bump_raises_surface() {
        // Sphere radius 1 with a bump centred at (0,0,-1): along -z axis the
        // surface moves out to where F + f Q^3 = 0.
        let f = 50.0;
        let bump = Quadric::sphere(DVec3::new(0.0, 0.0, -1.0), 0.3);
        let o = Object::new(
            Quadric::sphere(DVec3::ZERO, 1.0),
            vec![Perturbation {
                quadric: bump,
                factor: f,
            }],
            None,
        )
        .unwrap();
        let r = Ray::new(DVec3::new(0.0, 0.0, -5.0), DVec3::Z);
        let h = o.intersect(&r, 0.0, f64::INFINITY).unwrap();
        // z = -(1 + e): 1 - (1+e)^2 + f (0.09 - e^2)^3 = 0
        let g = |e: f64| 1.0 - (1.0 + e) * (1.0 + e) + f * (0.09 - e * e).powi(3);
        let (mut lo, mut hi) = (0.0, 0.3);
        for _ in 0..200 {
            let m = 0.5 * (lo + hi);
            if g(m) > 0.0 {
                lo = m
            } else {
                hi = m
            }
        }
        assert!((h.t - (4.0 - lo)).abs() < 1e-10, "{} vs {}", h.t, 4.0 - lo);
        assert!(h.n.z < -0.999);
    }

    #[test]
    fn unbounded_perturbation_needs_bounds() {
        let plane = Quadric::plane(DVec3::ZERO, DVec3::Y);
        let cyl = Quadric::cylinder(DVec3::ZERO, DVec3::Y, 0.5);
        let p = vec![Perturbation {
            quadric: cyl,
            factor: 1.0,
        }];
        assert!(matches!(
            Object::new(plane, p.clone(), None),
            Err(GeometryError::UnboundedPerturbation(0))
        ));
        let b = Aabb::new(DVec3::splat(-2.0), DVec3::splat(2.0));
        let o = Object::new(plane, p, Some(b)).unwrap();
        // The cylinder bump lifts the plane near the y axis.
        let r = Ray::new(DVec3::new(0.0, 1.9, 0.0), -DVec3::Y);
        let h = o.intersect(&r, 0.0, 10.0).unwrap();
        // -y + 0.25^3 = 0 at the axis.
        assert!((h.p.y - 0.015625).abs() < 1e-12, "{:?}", h.p);
    }

    /// A random sphere with all its coefficients scaled by a positive
    /// factor, as the scene's `scale`d spheres and transforms make it.
    fn scaled_sphere(u: &mut impl FnMut() -> f64) -> Quadric {
        let q = Quadric::sphere(DVec3::new(u(), u(), u()), 0.1 + u().abs());
        let k = 0.5 + u().abs();
        Quadric {
            m: q.m * k,
            b: q.b * k,
            c: q.c * k,
        }
    }

    #[test]
    fn sphere_restriction_matches_the_general_quadric() {
        let mut rng = isolux_core::Pcg32::new(21, 0);
        let mut u = || 4.0 * rng.next_f64() - 2.0;
        for _ in 0..1000 {
            let q = scaled_sphere(&mut u);
            let along = Along::new(&q);
            assert!(matches!(along, Along::Sphere { .. }));
            let ray = Ray::new(DVec3::new(u(), u(), u()), DVec3::new(u(), u(), u()));
            let (fast, general) = (along.along(&q, &ray), q.along(&ray));
            let scale = general.iter().map(|c| c.abs()).fold(1.0, f64::max);
            for (a, b) in fast.iter().zip(general) {
                assert!((a - b).abs() <= 1e-13 * scale, "{fast:?} vs {general:?}");
            }
        }
        let e = Quadric::ellipsoid(DVec3::ZERO, DVec3::new(1.0, 2.0, 3.0), DMat3::IDENTITY);
        assert!(matches!(Along::new(&e), Along::General));
    }

    #[test]
    fn support_interval_is_where_q_is_positive() {
        let mut rng = isolux_core::Pcg32::new(22, 0);
        let mut u = || 4.0 * rng.next_f64() - 2.0;
        for _ in 0..10_000 {
            let q = [u(), u(), -u().abs() - 1e-3];
            match support_interval(q) {
                Some((r0, r1)) => {
                    assert!(r0 < r1);
                    assert!(poly2(q, 0.5 * (r0 + r1)) > 0.0);
                    let w = r1 - r0;
                    assert!(poly2(q, r0 - 1e-6 * w) < 0.0 && poly2(q, r1 + 1e-6 * w) < 0.0);
                    assert_eq!(Some((r0, r1)), quadratic_crossings(q).pair());
                }
                None => assert!(quadratic_crossings(q).pair().is_none()),
            }
        }
    }

    /// The interval bound never claims one sign on a segment where dense
    /// sampling of the same `F'` finds both signs, and it does skip most
    /// segments far from the surface.
    #[test]
    fn sign_bound_is_conservative() {
        let mut rng = isolux_core::Pcg32::new(23, 0);
        let mut u = || 2.0 * rng.next_f64() - 1.0;
        let (mut skipped, mut segments) = (0, 0);
        for _ in 0..4000 {
            let base = [u(), u(), u()];
            let cands: Vec<Candidate> = (0..1 + (u().abs() * 4.0) as usize)
                .map(|i| {
                    // Concave, positive somewhere near [0, 1].
                    let q = [0.2 + 0.3 * u(), u(), -0.5 - u().abs()];
                    // Every other one as a bounded support (its roots
                    // known, ranges from the vertex between them), the
                    // rest as unbounded ones (ranges by `range2`).
                    let (lo, hi) = two_roots(q)
                        .filter(|_| i % 2 == 0)
                        .unwrap_or((f64::NAN, f64::NAN));
                    Candidate {
                        index: i as u32,
                        item: u32::MAX,
                        factor: 10.0 * u(),
                        q,
                        lo,
                        hi,
                    }
                })
                .collect();
            let (a, b) = (0.5 * u(), 0.5 + 0.5 * u().abs());
            // Active on the whole segment: Q > 0 at both ends (concave).
            let active: Vec<&Candidate> = cands
                .iter()
                .filter(|c| poly2(c.q, a) > 0.0 && poly2(c.q, b) > 0.0)
                .collect();
            let f = |t: f64| {
                poly2(base, t)
                    + active
                        .iter()
                        .map(|c| c.factor * poly2(c.q, t).powi(3))
                        .sum::<f64>()
            };
            let n = 2000;
            let (mut neg, mut pos) = (false, false);
            for i in 0..=n {
                let v = f(a + (b - a) * i as f64 / n as f64);
                neg |= v < 0.0;
                pos |= v > 0.0;
            }
            match sign_is_fixed(base, active.iter().copied(), a, b) {
                None => assert!(active.is_empty()),
                Some(fixed) => {
                    segments += 1;
                    if let Some(sign) = fixed {
                        skipped += 1;
                        let wrong = if sign > 0.0 { neg } else { pos };
                        assert!(!wrong, "{sign}: {base:?} {active:?} on [{a}, {b}]");
                    }
                }
            }
        }
        assert!(
            segments > 1000 && skipped > segments / 10,
            "{skipped} of {segments}"
        );
    }

    #[test]
    fn support_ranges_hold_the_sampled_values() {
        // Candidate::range_on / max_on against dense sampling, for bounded
        // supports (vertex midway between the roots) and unbounded ones.
        let mut rng = isolux_core::Pcg32::new(29, 0);
        let mut u = || 2.0 * rng.next_f64() - 1.0;
        for i in 0..2000 {
            let q = [
                0.5 * u(),
                u(),
                if i % 3 == 0 { u() } else { -0.2 - u().abs() },
            ];
            let (lo, hi) = match two_roots(q) {
                Some(r) if q[2] < 0.0 && i % 2 == 0 => r,
                _ => (f64::NAN, f64::NAN),
            };
            let c = Candidate {
                index: 0,
                item: u32::MAX,
                factor: 1.0,
                q,
                lo,
                hi,
            };
            let (a, b) = (u(), u());
            let (a, b) = (a.min(b), a.max(b));
            let (min, max) = c.range_on(a, b);
            assert_eq!(max, c.max_on(a, b));
            let (mut smin, mut smax) = (f64::INFINITY, f64::NEG_INFINITY);
            for k in 0..=1000 {
                let v = poly2(q, a + (b - a) * k as f64 / 1000.0);
                smin = smin.min(v);
                smax = smax.max(v);
            }
            let tol = 1e-12 * (1.0 + smax.abs() + smin.abs());
            assert!(min <= smin + tol && max >= smax - tol, "{q:?} [{a}, {b}]");
            // Tight: the sampled extremes are within the sampling step.
            assert!(min >= smin - 1e-5 && max <= smax + 1e-5, "{q:?} [{a}, {b}]");
        }
    }

    #[test]
    fn tangent_start_is_never_after_the_root() {
        // reach with `entering` (the tangent line at the base's entry)
        // starts no later than the exact root of F + B (to rounding), and
        // not before lo.
        let mut rng = isolux_core::Pcg32::new(31, 0);
        let mut u = || 2.0 * rng.next_f64() - 1.0;
        let mut tangent_used = 0;
        for _ in 0..5000 {
            // A concave base entered at r0 within (lo, hi_end).
            let (r0, width, curv) = (u(), 0.1 + u().abs(), 0.1 + u().abs());
            let base = [-curv * r0 * (r0 + width), curv * (2.0 * r0 + width), -curv];
            let lo = r0 - 0.5 * u().abs() - 1e-3;
            let q = [0.05 * u().abs(), 0.1 * u(), -0.5 - u().abs()];
            let Some((qlo, qhi)) = two_roots(q) else {
                continue;
            };
            let c = Candidate {
                index: 0,
                item: u32::MAX,
                factor: 10.0 * u().abs(),
                q,
                lo: qlo,
                hi: qhi,
            };
            let split = quadratic_crossings(base)[0];
            let exact = reach(base, &[c], lo, split, false);
            let tangent = reach(base, &[c], lo, split, true);
            match (exact, tangent) {
                (Some(e), Some(t)) => {
                    // Both are conservative by B's widening (1e-10 of
                    // the magnitudes), which dwarfs their rounding.
                    assert!(t <= e + 1e-13 * (1.0 + e.abs()) && t >= lo, "{t} vs {e}");
                    tangent_used += (t < e) as u32;
                }
                (None, _) => {}
                (Some(e), None) => panic!("tangent start lost the root {e}"),
            }
        }
        assert!(tangent_used > 1000, "{tangent_used}");
    }

    #[test]
    fn enclosing_ball_holds_both_balls() {
        let mut rng = isolux_core::Pcg32::new(24, 0);
        let mut u = || 2.0 * rng.next_f64() - 1.0;
        for _ in 0..10_000 {
            let a = (DVec3::new(u(), u(), u()), u().abs());
            let b = (DVec3::new(u(), u(), u()) * 0.1, 0.3 * u().abs());
            let (c, r) = enclose(a, b);
            for (centre, radius) in [a, b] {
                assert!(
                    (centre - c).length() + radius <= r,
                    "{a:?} {b:?} -> {c} {r}"
                );
            }
            // Never larger than the ball around a's centre holding both.
            let loose = a.1.max((b.0 - a.0).length() + b.1);
            assert!(r <= loose * (1.0 + 1e-9) + 1e-12);
        }
    }

    /// `positive_on` (no roots) says whether the support interval meets
    /// `(lo, hi)`, as the roots do, except within rounding of an end.
    #[test]
    fn positive_on_matches_the_roots() {
        let mut rng = isolux_core::Pcg32::new(25, 0);
        let mut u = || 4.0 * rng.next_f64() - 2.0;
        for _ in 0..100_000 {
            let q = [u(), u(), -u().abs() - 1e-3];
            let (lo, hi) = {
                let (x, y) = (u(), u());
                (x.min(y), x.max(y))
            };
            let by_roots = two_roots(q).is_some_and(|(r0, r1)| r1 > lo && r0 < hi);
            if positive_on(q, lo, hi) != by_roots {
                let (r0, r1) = two_roots(q).unwrap_or((f64::NAN, f64::NAN));
                let near = |x: f64| (x - lo).abs().min((x - hi).abs()) < 1e-12;
                assert!(near(r0) || near(r1), "{q:?} on ({lo}, {hi})");
            }
        }
    }

    /// A sphere base's normal without the square root equals the
    /// gradient's.
    #[test]
    fn sphere_base_normal_matches_the_gradient() {
        let mut rng = isolux_core::Pcg32::new(26, 0);
        let mut u = || 2.0 * rng.next_f64() - 1.0;
        for _ in 0..1000 {
            let o = Object::new(scaled_sphere(&mut u), vec![], None).unwrap();
            let ray = Ray::new(DVec3::new(u(), u(), u()) * 5.0, DVec3::new(u(), u(), u()));
            if let Some(h) = o.intersect(&ray, 0.0, f64::INFINITY) {
                let g = (-o.gradient(h.p)).normalize();
                assert!((h.n - g).length() < 1e-12, "{:?} vs {g:?}", h.n);
            }
        }
    }

    #[test]
    fn infinite_plane_without_bounds() {
        let o = Object::new(
            Quadric::plane(DVec3::new(0.0, -1.0, 0.0), DVec3::Y),
            vec![],
            None,
        )
        .unwrap();
        let r = Ray::new(DVec3::new(0.3, 2.0, 0.0), DVec3::new(0.0, -1.0, 0.0));
        assert!((o.intersect(&r, 0.0, f64::INFINITY).unwrap().t - 3.0).abs() < 1e-12);
        let r = Ray::new(DVec3::new(0.3, 2.0, 0.0), DVec3::Y);
        assert!(o.intersect(&r, 0.0, f64::INFINITY).is_none());
    }

    /// An object written in a frame a million units from the world origin
    /// (`Object::in_frame`, as the scene loader builds them) hits as the
    /// same object at the origin: along rays moved by the same amount
    /// (exactly: their origins lie on a grid of 2^-16), the same hits and
    /// misses, `t` to the rounding of the frame's origin, the same normals,
    /// and a spawn offset of about 1e-7 plus 1e-14 of the distance, where
    /// the world frame's rule, `1e-7 (1 + |p|)`, gave 0.1. The same object
    /// written in world coordinates (`Object::new`) moves into a frame at
    /// its box's centre (a million units from its written frame's zero)
    /// and agrees as well, to the rounding of its constant terms.
    #[test]
    fn objects_far_from_the_origin_hit_as_at_the_origin() {
        let far = DVec3::new(1.0e6, -0.25e6, 0.5e6);
        let perts = |at: DVec3| -> Vec<Perturbation> {
            crate::samples::fibonacci_sphere(16, 0.6)
                .into_iter()
                .enumerate()
                .map(|(i, c)| Perturbation {
                    quadric: Quadric::sphere(at + c, 0.2),
                    factor: if i % 3 == 0 { -1500.0 } else { 1000.0 },
                })
                .collect()
        };
        let sphere = |at: DVec3| Quadric::sphere(at, 0.6);
        let near = Object::new(sphere(DVec3::ZERO), perts(DVec3::ZERO), None).unwrap();
        let framed = Object::in_frame(far, sphere(DVec3::ZERO), perts(DVec3::ZERO), None).unwrap();
        let world = Object::new(sphere(far), perts(far), None).unwrap();
        assert!(
            (framed.origin() - far).length() < 0.1,
            "{:?}",
            framed.origin()
        );
        assert!(
            (world.origin() - far).length() < 0.1,
            "{:?}",
            world.origin()
        );
        let grid = |v: DVec3| (v * 65536.0).round() / 65536.0;
        let mut rng = isolux_core::Pcg32::new(11, 4);
        let (mut hits, mut rays, mut world_flips) = (0, 0, 0);
        let mut world_dt = Vec::new();
        for _ in 0..4000 {
            let o = grid(2.0 * isolux_core::sampling::uniform_sphere(rng.next_2d()));
            let target = 0.7 * isolux_core::sampling::uniform_sphere(rng.next_2d());
            let ray = Ray::new(o, target - o);
            let a = near.intersect(&ray, 0.0, f64::INFINITY);
            let moved = Ray::new(ray.origin + far, ray.dir);
            match (a, framed.intersect(&moved, 0.0, f64::INFINITY)) {
                (None, None) => {}
                (Some(a), Some(b)) => {
                    assert!((a.t - b.t).abs() < 1e-9, "{a:?} vs {b:?}");
                    assert!((a.n - b.n).length() < 1e-6, "{a:?} vs {b:?}");
                    assert!(((b.p - far) - a.p).length() < 1e-8);
                    assert!(b.offset < 2e-7 + 1e-14 * 1.2e6, "{}", b.offset);
                }
                (a, b) => panic!("{ray:?}: {a:?} vs {b:?}"),
            }
            // In world coordinates, the bumps' constant terms (about
            // 1.3e12) carry a rounding of about 1e-4 of their `r^2 = 0.04`,
            // which moves the surface near them by about that much.
            match (a, world.intersect(&moved, 0.0, f64::INFINITY)) {
                (Some(a), Some(b)) => world_dt.push((a.t - b.t).abs()),
                (None, None) => {}
                _ => world_flips += 1,
            }
            rays += 1;
            hits += a.is_some() as usize;
        }
        assert!(hits > rays / 2, "{hits} of {rays}");
        world_dt.sort_by(f64::total_cmp);
        let median = world_dt[world_dt.len() / 2];
        eprintln!("world: median |dt| {median:.2e}, {world_flips} of {rays} rays flipped");
        assert!(
            median < 1e-4 && world_flips <= rays / 200,
            "{median} {world_flips}"
        );
    }
}
