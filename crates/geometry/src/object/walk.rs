//! The segment walk of [`Object::intersect`](super::Object::intersect):
//! the ray clipped to the object's box, the perturbations it crosses
//! gathered, and the segments between their breakpoints walked in order,
//! each in closed form, proved free of a crossing by interval bounds, or
//! solved as a degree-6 polynomial; with the helpers it shares with the
//! tile walk ([`solo`](super::solo)).

use super::{Along, Candidate, Hit, Items, Object};
use crate::poly::{
    fmax, fmin, quadratic_crossings, sign, two_roots, Bernstein6, Crossings, UnitRoot,
};
use isolux_core::{DVec3, Ray};
use smallvec::SmallVec;

impl Object {
    #[inline]
    pub(super) fn intersect_in(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        items: Items,
    ) -> Option<Hit> {
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
    pub(super) fn walk<const DEFER: bool>(
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
    pub(super) fn base_hit(&self, ray: &Ray, t: f64) -> Hit {
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
pub(super) fn unit_normal(minus_grad: DVec3, ray: &Ray) -> DVec3 {
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
pub(super) fn sign_is_fixed<'a>(
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
pub(super) fn reach(
    base_q: [f64; 3],
    cands: &[Candidate],
    lo: f64,
    hi: f64,
    entering: bool,
) -> Option<f64> {
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

/// The range `(min, max)` of the quadratic `q` (ascending powers) on
/// `[a, b]`: its values at the ends, and at the vertex when the slope
/// changes sign in between.
#[inline]
pub(super) fn range2(q: [f64; 3], a: f64, b: f64) -> (f64, f64) {
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
pub(super) fn support_interval(q: [f64; 3]) -> Option<(f64, f64)> {
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
pub(super) fn positive_on(q: [f64; 3], lo: f64, hi: f64) -> bool {
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
pub(super) fn polish_more(t: f64, first: f64, mut at: impl FnMut(f64) -> (f64, f64)) -> f64 {
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
pub(super) fn polish(t: f64, value: f64, slope: f64) -> f64 {
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
pub(super) fn poly2(q: [f64; 3], t: f64) -> f64 {
    (q[2] * t + q[1]) * t + q[0]
}
