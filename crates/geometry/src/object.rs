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
use crate::poly::{fmax, fmin, quadratic_crossings};
use crate::quadric::Quadric;
use isolux_core::{Aabb, DMat3, DVec3, Ray};

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
mod walk;

use walk::{polish, polish_more, poly2, range2, unit_normal, BUMP_NEGLIGIBLE};
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

#[cfg(test)]
mod tests;
