//! The segment walk of [`Object::intersect_tile`](super::Object::intersect_tile)
//! for the rays that meet one or a few supports, carried through for many
//! rays at once in vector lanes.
//!
//! With few perturbations (16 benchmark bumps) nearly every ray of a tile
//! that meets a support meets just one, and with 64 most meet one or two;
//! their walk is always the same short program: the reach (where the bumps
//! can first lift `F'` to zero), at most `2K + 1` segments between the
//! supports' ends, the degree-6 polynomial of each segment where a support
//! is active, its Bernstein signs and, with one sign change (or two, split
//! once), Halley's iteration. Ray by ray that program is a few hundred
//! instructions spread over many small functions; here it runs on [`W`]
//! rays at once, as straight-line code on lane vectors ([`V`], arrays whose
//! element-wise operations the compiler turns into vector instructions)
//! with selects for branches: AVX-512 or AVX2 where the processor has them
//! (chosen at run time), SSE2 otherwise. A stage that no lane of a vector
//! needs (a segment's polynomial, Halley's iteration) is skipped.
//!
//! **Every value is the scalar walk's to the last bit.** Each lane performs
//! the scalar code's operations in the scalar code's order (`reach`,
//! `sign_is_fixed`, `range2`, `shift`, `Bernstein6::quadratic` and
//! `add_cube`, `poly::first_crossing`'s first step, `poly::isolate`'s
//! first split and `Bernstein6::refine`'s Halley iteration about the
//! nearer end, written again on
//! lanes; an inactive support's term is selected away, never added), IEEE
//! operations are exact whatever the vector width, and Rust never
//! contracts `a * b + c` into a fused multiply-add. A lane whose walk
//! leaves the common program (a second gathering phase, a polynomial that
//! needs deeper subdivision or has a zero Bernstein coefficient, a
//! degenerate reach) is marked [`Outcome::Slow`] and walked ray by ray
//! instead. `tile_batches_find_the_per_ray_hits` and
//! `solo_lanes_match_the_per_ray_walk` check the equality bit for bit, the
//! latter with every instruction set.

// Index loops over the lanes, not iterators or `array::from_fn`: the
// latter's closures were left out of line (calls per lane operation).
#![allow(clippy::needless_range_loop)]

use super::{BUMP_NEGLIGIBLE, TILE_RAYS};
use crate::poly::{bernstein2, cube2, elevate2, midpoint, power};
use std::ops::{Add, BitAnd, BitOr, Div, Mul, Not, Sub};

/// Lanes per vector: one AVX-512 register of doubles, two AVX2 ones.
const W: usize = 8;

/// What a lane's walk found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Outcome {
    /// The walk left the common program: walk the ray on its own.
    Slow,
    /// No crossing.
    Miss,
    /// A hit: the base quadric's own crossing (an `Object::base_hit`) or a
    /// crossing of `F'` (an `Object::hit_at`); its `t` (polished as
    /// `Object::hit_at` polishes it), point and normal are in
    /// [`Lanes::t`], [`Lanes::p`] and [`Lanes::nrm`].
    Hit,
}

/// The rays that meet `K` supports on their first phase, packed: lane `l`
/// of every array for the `l`-th such ray.
pub(super) struct Lanes<const K: usize> {
    /// Lanes in use.
    pub n: usize,
    /// Ray origins and directions.
    pub o: [[f64; TILE_RAYS]; 3],
    pub d: [[f64; TILE_RAYS]; 3],
    /// The base quadric along the ray (ascending powers), its two roots
    /// `r0 < r1` (NaN without), the clipped start `t0`, and the end of
    /// the first phase: the split `r0` where the ray enters the base
    /// inside `(t0, t1)` (`enter` 1), else the clipped end `t1` (`enter`
    /// 0; the split is `t1` and there is no second phase).
    pub bq: [[f64; TILE_RAYS]; 3],
    pub r0: [f64; TILE_RAYS],
    pub r1: [f64; TILE_RAYS],
    pub t0: [f64; TILE_RAYS],
    pub hi: [f64; TILE_RAYS],
    pub enter: [f64; TILE_RAYS],
    /// Per support, in the walk's order: `Q(t)` (ascending powers), its
    /// roots `clo < chi`, its factor `f > 0`, and the sphere `Q = sc0 -
    /// sk |p - sc|^2`.
    pub cq: [[[f64; TILE_RAYS]; 3]; K],
    pub clo: [[f64; TILE_RAYS]; K],
    pub chi: [[f64; TILE_RAYS]; K],
    pub f: [[f64; TILE_RAYS]; K],
    pub sc: [[[f64; TILE_RAYS]; 3]; K],
    pub sk: [[f64; TILE_RAYS]; K],
    pub sc0: [[f64; TILE_RAYS]; K],
    /// Out, for the lanes with a hit: its point and normal, unit where
    /// `unit` is set (`Object::hit_at` or `Object::base_hit`), else
    /// `-grad F'` for the caller's `unit_normal` (a vanishing gradient).
    pub p: [[f64; TILE_RAYS]; 3],
    pub nrm: [[f64; TILE_RAYS]; 3],
    pub unit: [bool; TILE_RAYS],
    /// Out: the hit's `t`, and whether it is the base's own crossing.
    pub t: [f64; TILE_RAYS],
    pub base: [bool; TILE_RAYS],
}

impl<const K: usize> Lanes<K> {
    pub fn new() -> Self {
        let z = [0.0; TILE_RAYS];
        Lanes {
            n: 0,
            o: [z; 3],
            d: [z; 3],
            bq: [z; 3],
            r0: z,
            r1: z,
            t0: z,
            hi: z,
            enter: z,
            cq: [[z; 3]; K],
            clo: [z; K],
            chi: [z; K],
            f: [z; K],
            sc: [[z; 3]; K],
            sk: [z; K],
            sc0: [z; K],
            p: [z; 3],
            nrm: [z; 3],
            unit: [false; TILE_RAYS],
            t: z,
            base: [false; TILE_RAYS],
        }
    }
}

/// The base sphere `F = c0 - k |p - centre|^2`.
#[derive(Clone, Copy)]
pub(super) struct BaseSphere {
    pub centre: [f64; 3],
    pub k: f64,
    pub c0: f64,
    /// `1 / radius`, positive.
    pub inv_radius: f64,
}

/// Walks the first `lanes.n` lanes, `out[l]` for lane `l`, and computes
/// their hits' points and normals.
pub(super) fn walk<const K: usize>(
    lanes: &mut Lanes<K>,
    base: BaseSphere,
    out: &mut [Outcome; TILE_RAYS],
) {
    #[cfg(target_arch = "x86_64")]
    match crate::simd::isa() {
        // SAFETY: `simd::isa` answers AVX-512 only where the processor has it.
        crate::simd::Isa::Avx512 => return unsafe { walk_avx512(lanes, base, out) },
        // SAFETY: `simd::isa` answers AVX2 only where the processor has it.
        crate::simd::Isa::Avx2 => return unsafe { walk_avx2(lanes, base, out) },
        crate::simd::Isa::Baseline => {}
    }
    walk_lanes(lanes, base, out);
    hits(lanes, base);
}

/// [`walk`] compiled for AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn walk_avx512<const K: usize>(
    lanes: &mut Lanes<K>,
    base: BaseSphere,
    out: &mut [Outcome; TILE_RAYS],
) {
    walk_lanes(lanes, base, out);
    hits(lanes, base);
}

/// [`walk`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn walk_avx2<const K: usize>(
    lanes: &mut Lanes<K>,
    base: BaseSphere,
    out: &mut [Outcome; TILE_RAYS],
) {
    walk_lanes(lanes, base, out);
    hits(lanes, base);
}

/// [`W`] doubles, one per lane.
#[derive(Clone, Copy)]
struct V([f64; W]);

/// [`W`] booleans, one per lane, as all-ones or all-zeros words (the
/// form of a vector comparison's result, so that masks stay in vector
/// registers).
#[derive(Clone, Copy)]
struct M([u64; W]);

#[inline(always)]
fn splat(x: f64) -> V {
    V([x; W])
}

#[inline(always)]
fn map2(a: V, b: V, f: impl Fn(f64, f64) -> f64) -> V {
    let mut r = [0.0; W];
    for i in 0..W {
        r[i] = f(a.0[i], b.0[i]);
    }
    V(r)
}

#[inline(always)]
fn cmp(a: V, b: V, f: impl Fn(f64, f64) -> bool) -> M {
    let mut r = [0; W];
    for i in 0..W {
        r[i] = (f(a.0[i], b.0[i]) as u64).wrapping_neg();
    }
    M(r)
}

macro_rules! arith {
    ($tr:ident, $f:ident, $op:tt) => {
        impl $tr for V {
            type Output = V;
            #[inline(always)]
            fn $f(self, o: V) -> V {
                map2(self, o, |a, b| a $op b)
            }
        }
        impl $tr<f64> for V {
            type Output = V;
            #[inline(always)]
            fn $f(self, o: f64) -> V {
                map2(self, splat(o), |a, b| a $op b)
            }
        }
        impl $tr<V> for f64 {
            type Output = V;
            #[inline(always)]
            fn $f(self, o: V) -> V {
                map2(splat(self), o, |a, b| a $op b)
            }
        }
    };
}
arith!(Add, add, +);
arith!(Sub, sub, -);
arith!(Mul, mul, *);
arith!(Div, div, /);

impl V {
    #[inline(always)]
    fn abs(self) -> V {
        let mut r = self.0;
        for x in &mut r {
            *x = x.abs();
        }
        V(r)
    }
    #[inline(always)]
    fn lt(self, o: impl Into<V>) -> M {
        cmp(self, o.into(), |a, b| a < b)
    }
    #[inline(always)]
    fn gt(self, o: impl Into<V>) -> M {
        cmp(self, o.into(), |a, b| a > b)
    }
    #[inline(always)]
    fn le(self, o: impl Into<V>) -> M {
        cmp(self, o.into(), |a, b| a <= b)
    }
    #[inline(always)]
    fn ge(self, o: impl Into<V>) -> M {
        cmp(self, o.into(), |a, b| a >= b)
    }
    #[inline(always)]
    fn eq(self, o: impl Into<V>) -> M {
        cmp(self, o.into(), |a, b| a == b)
    }
    #[inline(always)]
    fn ne(self, o: impl Into<V>) -> M {
        cmp(self, o.into(), |a, b| a != b)
    }
    /// Lanes `l * W ..` of `a`.
    #[inline(always)]
    fn load(a: &[f64; TILE_RAYS], chunk: usize) -> V {
        let mut r = [0.0; W];
        r.copy_from_slice(&a[chunk * W..chunk * W + W]);
        V(r)
    }
}

impl From<f64> for V {
    #[inline(always)]
    fn from(x: f64) -> V {
        splat(x)
    }
}

impl BitAnd for M {
    type Output = M;
    #[inline(always)]
    fn bitand(self, o: M) -> M {
        let mut r = [0; W];
        for i in 0..W {
            r[i] = self.0[i] & o.0[i];
        }
        M(r)
    }
}

impl BitOr for M {
    type Output = M;
    #[inline(always)]
    fn bitor(self, o: M) -> M {
        let mut r = [0; W];
        for i in 0..W {
            r[i] = self.0[i] | o.0[i];
        }
        M(r)
    }
}

impl Not for M {
    type Output = M;
    #[inline(always)]
    fn not(self) -> M {
        let mut r = self.0;
        for x in &mut r {
            *x = !*x;
        }
        M(r)
    }
}

impl M {
    #[inline(always)]
    fn any(self) -> bool {
        self.0.iter().fold(0, |a, &x| a | x) != 0
    }
    /// Whether lane `i` is set.
    #[inline(always)]
    fn at(self, i: usize) -> bool {
        self.0[i] != 0
    }
    #[inline(always)]
    fn all(x: bool) -> M {
        M([(x as u64).wrapping_neg(); W])
    }
    /// Lanes where `self` and `o` agree.
    #[inline(always)]
    fn same(self, o: M) -> M {
        let mut r = [0; W];
        for i in 0..W {
            r[i] = !(self.0[i] ^ o.0[i]);
        }
        M(r)
    }
}

/// `a` where `m`, else `b`.
#[inline(always)]
fn sel(m: M, a: impl Into<V>, b: impl Into<V>) -> V {
    let (a, b) = (a.into(), b.into());
    let mut r = [0.0; W];
    for i in 0..W {
        let m = m.0[i];
        r[i] = f64::from_bits((a.0[i].to_bits() & m) | (b.0[i].to_bits() & !m));
    }
    V(r)
}

/// `poly::fmin`: `a` where `a < b`, else `b`.
#[inline(always)]
fn fmin(a: V, b: V) -> V {
    sel(a.lt(b), a, b)
}

/// `poly::fmax`: `a` where `a > b`, else `b`.
#[inline(always)]
fn fmax(a: V, b: V) -> V {
    sel(a.gt(b), a, b)
}

/// `poly::sign`.
#[inline(always)]
fn sign(x: V) -> V {
    sel(x.gt(0.0), 1.0, sel(x.lt(0.0), -1.0, 0.0))
}

/// `walk::poly2`: `(q2 t + q1) t + q0`.
#[inline(always)]
fn poly2(q: [V; 3], t: V) -> V {
    (q[2] * t + q[1]) * t + q[0]
}

/// `walk::shift`: `q(a + s len)` as a quadratic in `s`.
#[inline(always)]
fn shift(q: [V; 3], a: V, len: V) -> [V; 3] {
    let [c0, c1, c2] = q;
    [
        (c2 * a + c1) * a + c0,
        (2.0 * c2 * a + c1) * len,
        c2 * len * len,
    ]
}

/// `walk::range2`: the range of `q` on `[a, b]`.
#[inline(always)]
fn range2(q: [V; 3], a: V, b: V) -> (V, V) {
    let (va, vb) = (poly2(q, a), poly2(q, b));
    let (lo, hi) = (fmin(va, vb), fmax(va, vb));
    let (da, db) = (2.0 * q[2] * a + q[1], 2.0 * q[2] * b + q[1]);
    let turns = da.lt(0.0).same(db.lt(0.0)).not() & q[2].ne(0.0);
    let v = q[0] - q[1] * q[1] / (4.0 * q[2]);
    (sel(turns, fmin(lo, v), lo), sel(turns, fmax(hi, v), hi))
}

/// The lane state of the segment walk.
struct Walk {
    /// Still walking (no hit, not slow).
    live: M,
    /// The sign of `F'` just before `a` (the walk's `before`).
    before: V,
    /// The current position.
    a: V,
    /// The answer: `kind` 1 base crossing, 2 crossing of `F'`, 0 none yet.
    kind: V,
    t: V,
}

impl Walk {
    /// The segment `[a, b]` on the lanes `run` where no support is active,
    /// as `Object::segment_root` and the walk answer it: a hit at `a`
    /// where `F'` changed sign across the breakpoint, else the base's
    /// crossing when one lies in `[a, b]`.
    #[inline(always)]
    fn plain(&mut self, run: M, b: V, q: [V; 3], (r0, r1): (V, V)) {
        let a = self.a;
        let in0 = r0.ge(a) & r0.le(b);
        let in1 = r1.ge(a) & r1.le(b);
        let raw = run & (self.before * sign(poly2(q, a))).lt(0.0);
        let base = run & !raw & (in0 | in1);
        let clear = run & !raw & !(in0 | in1);
        self.t = sel(base, sel(in0, r0, r1), sel(raw, a, self.t));
        self.kind = sel(base, 1.0, sel(raw, 2.0, self.kind));
        self.before = sel(clear, sign(poly2(q, b)), self.before);
        self.live = self.live & !(base | raw);
    }

    /// The segment `[a, b]` on the lanes `run` where the supports `act`
    /// are active: `sign_is_fixed`, then `segment_root`'s polynomial and
    /// `Poly::first_crossing` (its first subdivision level at most; lanes
    /// that need more leave the walk).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn active<const K: usize>(
        &mut self,
        run: M,
        b: V,
        q: [V; 3],
        c: &[[V; 3]; K],
        (clo, chi, f): (&[V; K], &[V; K], &[V; K]),
        act: &[M; K],
        f_at_a: V,
        (r0, r1): (V, V),
    ) {
        let a = self.a;
        // `sign_is_fixed(base_q, active, a, b)`.
        let (base_min, base_max) = range2(q, a, b);
        let (mut flo, mut fhi) = (base_min, base_max);
        let mut scale = base_min.abs() + base_max.abs() + q[0].abs();
        for k in 0..K {
            let qmin = fmax(fmin(poly2(c[k], a), poly2(c[k], b)), splat(0.0));
            let at = fmin(fmax(0.5 * (clo[k] + chi[k]), a), b);
            let qmax = fmax(poly2(c[k], at), splat(0.0));
            let (rmin, rmax) = (f[k] * qmin * qmin * qmin, f[k] * qmax * qmax * qmax);
            flo = sel(act[k], flo + rmin, flo);
            fhi = sel(act[k], fhi + rmax, fhi);
            scale = sel(act[k], scale + (rmin.abs() + rmax.abs()), scale);
        }
        let margin = 1e-10 * scale;
        let neg = fhi.lt(0.0 - margin);
        let pos = !neg & flo.gt(margin);
        if !(run & !neg & !pos).any() {
            // Every lane's sign is fixed: no polynomial (the rest below
            // with `Clear { s, s }` only).
            let s = sel(neg, -1.0, 1.0);
            let cleared = self.live & run;
            let raw = cleared & (self.before * s).lt(0.0);
            self.t = sel(raw, a, self.t);
            self.kind = sel(raw, 2.0, self.kind);
            self.before = sel(cleared, s, self.before);
            self.live = self.live & !raw;
            return;
        }
        // `segment_root`'s polynomial on `[a, b]`: `Bernstein6::quadratic`
        // of the shifted base (its value at `a` recomputed, `f_at_a`) plus
        // `Bernstein6::add_cube` for each active support.
        let len = b - a;
        let s = shift(q, a, len);
        let mut bz = elevate2(bernstein2([f_at_a, s[1], s[2]]));
        for k in 0..K {
            let terms = cube2(bernstein2(shift(c[k], a, len)));
            for i in 0..7 {
                bz[i] = sel(act[k], bz[i] + f[k] * terms[i], bz[i]);
            }
        }
        let mut nonzero = M::all(true);
        let mut changes = splat(0.0);
        for x in &bz {
            nonzero = nonzero & x.ne(0.0);
        }
        for k in 0..6 {
            changes = changes + sel(bz[k].lt(0.0).same(bz[k + 1].lt(0.0)), 0.0, 1.0);
        }
        let polynomial = run & !neg & !pos;
        let none = polynomial & nonzero & changes.eq(0.0);
        let one = polynomial & nonzero & changes.eq(1.0);
        // Two sign changes (a ray through a bump's rim, in and out): the
        // first level of `Poly::isolate`, de Casteljau's halves at 1/2,
        // left first.
        let two = polynomial & nonzero & changes.eq(2.0);
        let (left, right) = if two.any() {
            de_casteljau_half(&bz)
        } else {
            ([splat(0.0); 7], [splat(0.0); 7])
        };
        let (ch_left, ch_right) = (sign_changes(&left), sign_changes(&right));
        let left_one = two & ch_left.eq(1.0) & (left[0] * left[6]).lt(0.0);
        let left_none = two & ch_left.eq(0.0);
        let right_open = left_none & right[0].ne(0.0);
        let right_one = right_open & ch_right.eq(1.0) & (right[0] * right[6]).lt(0.0);
        let right_none = right_open & ch_right.eq(0.0);
        let found = one | left_one | right_one;
        let none = none | right_none;
        self.live = self.live & !(polynomial & !none & !found);
        // A base root in `[a, b]` where the supports add next to nothing
        // (`Object::segment_root`'s `BUMP_NEGLIGIBLE`, here ten times
        // wider so that no lane it would answer stays): walked alone.
        let negligible = |r: V| {
            let mut bump = splat(0.0);
            for k in 0..K {
                let x = fmax(poly2(c[k], r), splat(0.0));
                bump = sel(act[k], bump + f[k] * x * x * x, bump);
            }
            let scale = q[0].abs() + (q[1] * r).abs() + (q[2] * r * r).abs();
            bump.abs().le(10.0 * BUMP_NEGLIGIBLE * scale)
        };
        let (in0, in1) = (r0.ge(a) & r0.le(b), r1.ge(a) & r1.le(b));
        let clear_root = polynomial & none & (in0 | in1);
        if clear_root.any() {
            let near_root = (in0 & negligible(r0)) | (in1 & negligible(r1));
            self.live = self.live & !(clear_root & near_root);
        }
        let clear_start = sel(neg, -1.0, sel(pos, 1.0, sign(bz[0])));
        let clear_end = sel(neg, -1.0, sel(pos, 1.0, sign(bz[6])));
        // Halley's first step from the better end.
        let nf = 6.0;
        let (f0, d0, e0) = (
            bz[0],
            nf * (bz[1] - bz[0]),
            nf * (nf - 1.0) * (bz[2] - 2.0 * bz[1] + bz[0]),
        );
        let (f1, d1, e1) = (
            bz[6],
            nf * (bz[6] - bz[5]),
            nf * (nf - 1.0) * (bz[6] - 2.0 * bz[5] + bz[4]),
        );
        let from0 = -2.0 * f0 * d0 / (2.0 * d0 * d0 - f0 * e0);
        let from1 = 1.0 - 2.0 * f1 * d1 / (2.0 * d1 * d1 - f1 * e1);
        let guess = sel((f0 * d1).abs().lt((f1 * d0).abs()), from0, from1);
        // `refine_from(0, 1, b0, b6, guess)`, or `refine` on the half.
        let half = |l: V, r: V, one: V| sel(left_one, l, sel(right_one, r, one));
        let nan = splat(f64::NAN);
        let found = found & self.live;
        let root = if found.any() {
            refine(
                &bz,
                found,
                (
                    half(splat(0.0), splat(0.5), splat(0.0)),
                    half(splat(0.5), splat(1.0), splat(1.0)),
                ),
                (half(left[0], right[0], f0), half(left[6], right[6], f1)),
                half(nan, nan, guess),
            )
        } else {
            splat(0.0)
        };
        // A change of sign across the breakpoint `a` comes first, also on
        // lanes whose segment holds a root (as `Object::walk`).
        let raw = self.live & run & (self.before * clear_start).lt(0.0);
        let found = found & !raw;
        let cleared = self.live & run & !found;
        self.t = sel(found, a + root * len, sel(raw, a, self.t));
        self.kind = sel(found | raw, 2.0, self.kind);
        self.before = sel(cleared, clear_end, self.before);
        self.live = self.live & !(found | raw);
    }
}

/// The walk of [`W`] lanes at a time (see the module's doc).
#[inline(always)]
fn walk_lanes<const K: usize>(
    lanes: &mut Lanes<K>,
    base: BaseSphere,
    out: &mut [Outcome; TILE_RAYS],
) {
    for chunk in 0..lanes.n.div_ceil(W) {
        let ld = |a: &[f64; TILE_RAYS]| V::load(a, chunk);
        let mut valid = M::all(false);
        for i in 0..W {
            valid.0[i] = ((chunk * W + i < lanes.n) as u64).wrapping_neg();
        }
        let q = [ld(&lanes.bq[0]), ld(&lanes.bq[1]), ld(&lanes.bq[2])];
        let (lo, hi) = (ld(&lanes.t0), ld(&lanes.hi));
        let roots = (ld(&lanes.r0), ld(&lanes.r1));
        let enter = ld(&lanes.enter).ne(0.0);
        let mut c = [[splat(0.0); 3]; K];
        let (mut clo, mut chi, mut f) = ([splat(0.0); K], [splat(0.0); K], [splat(0.0); K]);
        for k in 0..K {
            c[k] = [
                ld(&lanes.cq[k][0]),
                ld(&lanes.cq[k][1]),
                ld(&lanes.cq[k][2]),
            ];
            (clo[k], chi[k], f[k]) = (ld(&lanes.clo[k]), ld(&lanes.chi[k]), ld(&lanes.f[k]));
        }
        // `reach(base_q, cands, lo, hi, enter)`, every `f > 0`.
        let mut bound = splat(0.0);
        for k in 0..K {
            let (ca, cb) = (fmax(clo[k], lo), fmin(chi[k], hi));
            let at = fmin(fmax(0.5 * (clo[k] + chi[k]), ca), cb);
            let qmax = fmax(poly2(c[k], at), splat(0.0));
            bound = sel(ca.lt(cb), bound + f[k] * qmax * qmax * qmax, bound);
        }
        let flo = poly2(q, lo);
        let scale = q[0].abs() + (q[1] * hi).abs() + (q[2] * hi * hi).abs() + bound;
        let bound = bound + 1e-10 * scale;
        let at_once = (flo + bound).lt(0.0).not();
        let slope = q[1] + 2.0 * q[2] * hi;
        let tangent = !at_once & enter & q[2].lt(0.0) & slope.gt(0.0);
        let line = fmax(fmin(hi - (bound + poly2(q, hi)) / slope, hi), lo);
        // Otherwise the first root in `(lo, hi]` of the base shifted up by
        // `bound` (`quadratic_crossings`; its degenerate cases, a zero or
        // nearly linear quadratic and `h == 0`, are walked ray by ray).
        let roots_of = !at_once & !tangent;
        let c0 = q[0] + bound;
        let qscale = fmax(fmax(q[2].abs(), q[1].abs()), c0.abs());
        let linear = qscale.eq(0.0) | q[2].abs().le(1e-15 * qscale);
        let (two, h, x0, x1) = if roots_of.any() {
            let disc = q[1] * q[1] - 4.0 * q[2] * c0;
            let mut sq = disc;
            for i in 0..W {
                sq.0[i] = sq.0[i].sqrt().copysign(q[1].0[i]);
            }
            let h = -0.5 * (q[1] + sq);
            let (x0, x1) = (h / q[2], c0 / h);
            (disc.gt(0.0), h, fmin(x0, x1), fmax(x0, x1))
        } else {
            // Read by no lane.
            let nan = splat(f64::NAN);
            (M::all(false), nan, nan, nan)
        };
        let first0 = two & x0.gt(lo) & x0.le(hi);
        let first1 = two & !first0 & x1.gt(lo) & x1.le(hi);
        let degenerate = roots_of & (linear | (two & h.eq(0.0)));
        let unreached = roots_of & !degenerate & !(first0 | first1);
        let start = sel(at_once, lo, sel(tangent, line, sel(first0, x0, x1)));
        // Unreached: `F' < 0` on all of the first phase. Without a second
        // phase the ray misses (`kind` 3); with one, it is walked alone.
        let mut w = Walk {
            live: valid & !degenerate & !unreached,
            before: sel(start.gt(lo), -1.0, 0.0),
            a: start,
            kind: sel(unreached & !enter, 3.0, 0.0),
            t: splat(0.0),
        };
        // The breaks inside `(start, hi)`, in order (the others at +inf),
        // then the split.
        let inf = splat(f64::INFINITY);
        let mut ends = [inf; 8];
        for k in 0..K {
            for (e, x) in [(2 * k, clo[k]), (2 * k + 1, chi[k])] {
                ends[e] = sel(x.gt(start) & x.lt(hi), x, inf);
            }
        }
        for i in 1..2 * K {
            // Insertion by compare-exchange (2K <= 4 values).
            for j in (0..i).rev() {
                let (x, y) = (ends[j], ends[j + 1]);
                (ends[j], ends[j + 1]) = (fmin(x, y), fmax(x, y));
            }
        }
        ends[2 * K] = hi;
        let o = [ld(&lanes.o[0]), ld(&lanes.o[1]), ld(&lanes.o[2])];
        let d = [ld(&lanes.d[0]), ld(&lanes.d[1]), ld(&lanes.d[2])];
        for e in ends.iter().take(2 * K + 1) {
            let (a, b) = (w.a, *e);
            let run = w.live & b.lt(f64::INFINITY) & b.gt(a);
            if !run.any() {
                continue;
            }
            let mid = 0.5 * (a + b);
            let mut act = [M::all(false); K];
            let mut any = M::all(false);
            for k in 0..K {
                act[k] = clo[k].lt(mid) & mid.lt(chi[k]);
                any = any | act[k];
            }
            w.plain(run & !any, b, q, roots);
            let busy = run & any;
            if busy.any() {
                // The base's value at `a`, recomputed from the point.
                let v = [
                    o[0] + a * d[0] - base.centre[0],
                    o[1] + a * d[1] - base.centre[1],
                    o[2] + a * d[2] - base.centre[2],
                ];
                let f_at_a = base.c0 - base.k * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
                w.active(busy, b, q, &c, (&clo, &chi, &f), &act, f_at_a, roots);
            }
            w.a = sel(run, b, a);
        }
        // Still walking after the first phase: a miss without a second
        // phase, else the second phase gathers again, ray by ray.
        w.kind = sel(w.live & !enter, 3.0, w.kind);
        for i in 0..W {
            let l = chunk * W + i;
            if l < lanes.n {
                lanes.t[l] = w.t.0[i];
                lanes.base[l] = w.kind.0[i] == 1.0;
                out[l] = match (w.live.at(i) & (w.kind.0[i] != 3.0), w.kind.0[i]) {
                    (false, 1.0) | (false, 2.0) => Outcome::Hit,
                    (false, 3.0) => Outcome::Miss,
                    _ => Outcome::Slow,
                };
            }
        }
    }
}

/// `poly::sign_changes`: sign changes among the non-zero entries.
#[inline(always)]
fn sign_changes(b: &[V; 7]) -> V {
    let (mut count, mut prev) = (splat(0.0), splat(0.0));
    for &x in b {
        let nz = x.ne(0.0);
        let change = nz & prev.ne(0.0) & x.lt(0.0).same(prev.lt(0.0)).not();
        count = count + sel(change, 1.0, 0.0);
        prev = sel(nz, x, prev);
    }
    count
}

/// `poly::de_casteljau_half` for degree 6: the Bernstein coefficients of
/// the halves `[0, 1/2]` and `[1/2, 1]`.
#[inline(always)]
fn de_casteljau_half(b: &[V; 7]) -> ([V; 7], [V; 7]) {
    let mut work = *b;
    let (mut left, mut right) = ([splat(0.0); 7], [splat(0.0); 7]);
    left[0] = work[0];
    right[6] = work[6];
    for level in 1..=6 {
        for i in 0..=(6 - level) {
            work[i] = 0.5 * (work[i] + work[i + 1]);
        }
        left[level] = work[0];
        right[6 - level] = work[6 - level];
    }
    (left, right)
}

/// `Bernstein6::refine(lo, hi, fa, fb, start)` on the lanes `going`: a
/// bracket across `1/2` halved by the sign there (`poly::midpoint`), then
/// [`halley`] in the power basis about `s = 0` (`poly::power`) or, on
/// `[1/2, 1]`, about `s = 1` (in `u = 1 - s`, the coefficients reversed).
#[inline(always)]
fn refine(b: &[V; 7], going: M, (lo, hi): (V, V), (fa, fb): (V, V), start: V) -> V {
    let across = going & lo.lt(0.5) & hi.gt(0.5);
    let (mut lo, mut hi, mut fa, mut fb) = (lo, hi, fa, fb);
    let mut at_mid = M::all(false);
    if across.any() {
        let mid = midpoint(b);
        at_mid = across & mid.eq(0.0);
        let right = across & !at_mid & mid.lt(0.0).same(fa.lt(0.0));
        let left = across & !at_mid & !right;
        lo = sel(right, 0.5, lo);
        fa = sel(right, mid, fa);
        hi = sel(left, 0.5, hi);
        fb = sel(left, mid, fb);
    }
    let rev = lo.ge(0.5);
    let mut r = *b;
    for k in 0..7 {
        r[k] = sel(rev, b[6 - k], b[k]);
    }
    let c = power(r);
    let u = halley(
        &c,
        going & !at_mid,
        (sel(rev, 1.0 - hi, lo), sel(rev, 1.0 - lo, hi)),
        (sel(rev, fb, fa), sel(rev, fa, fb)),
        sel(rev, 1.0 - start, start),
    );
    sel(at_mid, 0.5, sel(rev, 1.0 - u, u))
}

/// Safeguarded Halley iteration on the bracket `[lo, hi]` for the lanes
/// `going` (`Poly::refine_from(lo, hi, fa, fb, start)` operation for
/// operation), all of them together until each has returned.
#[inline(always)]
fn halley(c: &[V; 7], mut going: M, (mut lo, mut hi): (V, V), (fa, fb): (V, V), start: V) -> V {
    let neg_left = fa.lt(0.0);
    let x = sel(
        start.gt(lo) & start.lt(hi),
        start,
        lo + (hi - lo) * (fa / (fa - fb)),
    );
    let mut s = sel((x.gt(lo) & x.lt(hi)).not(), 0.5 * (lo + hi), x);
    let mut root = s;
    for _ in 0..100 {
        // `Poly::eval_d2`, degree 6.
        let p = c[6];
        let (d, p) = (p, p * s + c[5]);
        let (d2, d, p) = (d, d * s + p, p * s + c[4]);
        let (d2, d, p) = (d2 * s + d, d * s + p, p * s + c[3]);
        let (d2, d, p) = (d2 * s + d, d * s + p, p * s + c[2]);
        let (d2, d, p) = (d2 * s + d, d * s + p, p * s + c[1]);
        let (d2, d, fx) = (d2 * s + d, d * s + p, p * s + c[0]);
        let d2 = 2.0 * d2;
        let zero = fx.eq(0.0);
        let left = fx.lt(0.0).same(neg_left);
        let (nlo, nhi) = (sel(left, s, lo), sel(left, hi, s));
        let denom = 2.0 * d * d - fx * d2;
        let step = 2.0 * fx * d / denom;
        let newton = s - step;
        let ok = denom.ne(0.0) & newton.gt(nlo) & newton.lt(nhi);
        let conv = ok & step.abs().le(1e-6 * fmax(newton.abs(), splat(1e-300)));
        let next = sel(ok, newton, 0.5 * (nlo + nhi));
        let tight = (nhi - nlo).le(2.0 * f64::EPSILON * nhi.abs());
        root = sel(going, sel(zero, s, sel(conv, newton, next)), root);
        let cont = going & !(zero | conv | tight);
        s = sel(cont, next, s);
        lo = sel(cont, nlo, lo);
        hi = sel(cont, nhi, hi);
        going = cont;
        if !going.any() {
            return root;
        }
    }
    // Still going after 100 steps: the last point, as `refine_from`.
    sel(going, s, root)
}

/// The hit points and normals of the first `lanes.n` lanes (read where
/// [`walk`] found a hit): `ray.at(t)`, and the normal of `Object::base_hit`
/// (the base sphere's) or of `Object::hit_at` (`-grad F'` with each
/// support's term where `Q > 0`, then `unit_normal`), operation for
/// operation. A loop over the lanes that the compiler vectorizes.
#[inline(always)]
fn hits<const K: usize>(lanes: &mut Lanes<K>, base: BaseSphere) {
    let n = lanes.n;
    let Lanes {
        o,
        d,
        f,
        sc,
        sk,
        sc0,
        p,
        nrm,
        unit,
        t,
        base: is_base,
        ..
    } = lanes;
    // `F'` and its gradient at `t` along lane `l`: `Object::value_gradient`
    // operation for operation.
    let at = |l: usize, t: f64| {
        let q = [
            o[0][l] + t * d[0][l],
            o[1][l] + t * d[1][l],
            o[2][l] + t * d[2][l],
        ];
        let vb = [
            q[0] - base.centre[0],
            q[1] - base.centre[1],
            q[2] - base.centre[2],
        ];
        let kb = -2.0 * base.k;
        let mut v = base.c0 - base.k * (vb[0] * vb[0] + vb[1] * vb[1] + vb[2] * vb[2]);
        let mut g = [kb * vb[0], kb * vb[1], kb * vb[2]];
        for k in 0..K {
            let vc = [q[0] - sc[k][0][l], q[1] - sc[k][1][l], q[2] - sc[k][2][l]];
            let xq = sc0[k][l] - sk[k][l] * (vc[0] * vc[0] + vc[1] * vc[1] + vc[2] * vc[2]);
            let kc = -2.0 * sk[k][l];
            let s = 3.0 * f[k][l] * xq * xq;
            v = if xq > 0.0 {
                v + f[k][l] * xq * xq * xq
            } else {
                v
            };
            for x in 0..3 {
                g[x] = if xq > 0.0 {
                    g[x] + s * (kc * vc[x])
                } else {
                    g[x]
                };
            }
        }
        let slope = g[0] * d[0][l] + g[1] * d[1][l] + g[2] * d[2][l];
        (v, g, slope, vb)
    };
    let walked = *t;
    for l in 0..n {
        let tl = t[l];
        let (v, g, slope, vb) = at(l, tl);
        let on_base = is_base[l];
        // `Object::hit_at_raw`'s Newton steps (`polish`), off the base's
        // own crossings, and the point at the polished `t`. Further steps
        // (rare: a root far from converged) are taken after this loop.
        t[l] = if on_base {
            tl
        } else {
            super::polish(tl, v, slope)
        };
        let m = [-g[0], -g[1], -g[2]];
        let rcp = 1.0 / (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
        let ok = rcp.is_finite() & (rcp > 0.0);
        for x in 0..3 {
            nrm[x][l] = if on_base {
                vb[x] * base.inv_radius
            } else if ok {
                m[x] * rcp
            } else {
                m[x]
            };
        }
        unit[l] = on_base | ok;
    }
    for l in 0..n {
        if !is_base[l] {
            t[l] = super::polish_more(walked[l], t[l], |t| {
                let (v, _, slope, _) = at(l, t);
                (v, slope)
            });
        }
        for x in 0..3 {
            p[x][l] = o[x][l] + t[l] * d[x][l];
        }
    }
}
