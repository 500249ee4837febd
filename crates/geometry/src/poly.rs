//! Exact root finding for the piecewise polynomials along a ray.
//!
//! On a segment where the set of active perturbations is fixed, `F'(t)` is
//! a polynomial of degree <= 6. It is re-expressed in a local parameter
//! `s in [0, 1]` (so that it stays well conditioned whatever the distance of
//! the segment from the ray origin), in the Bernstein basis ([`Bernstein6`]
//! builds it there from the quadratics' own Bernstein coefficients, which
//! keeps both ends of the segment accurate; [`Poly`] converts a polynomial
//! given in the power basis), and
//! its first root is isolated by Descartes' rule of signs on the Bernstein
//! coefficients (a sign-change count of zero proves there is no root) with
//! de Casteljau subdivision at the midpoint, left half first. An interval
//! with a single sign change and opposite endpoint signs holds exactly one
//! root, which safeguarded Halley iteration (started at the false-position
//! point, bisection whenever a step leaves the bracket) refines to full
//! double precision ([`Bernstein6::refine`]: in the power basis about the
//! nearer end of the segment).
//!
//! Only *crossings* count as hits: a root of even multiplicity (a ray that
//! grazes the surface tangentially) does not enter the solid and is not
//! reported, except when subdivision reaches [`MAX_DEPTH`], where two
//! roots closer than `2^-MAX_DEPTH` of the segment are indistinguishable.

use std::ops::{Add, Mul, Sub};

/// Maximum polynomial degree handled (base quadric plus cubes of quadrics).
pub const MAX_DEGREE: usize = 6;

/// Deepest subdivision level: intervals of `2^-48` of the segment.
pub const MAX_DEPTH: u32 = 48;

/// A polynomial of degree <= 6 in ascending powers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Poly {
    /// Coefficients `c[i]` of `s^i`.
    pub c: [f64; MAX_DEGREE + 1],
    /// Degree bound (coefficients above are zero).
    pub degree: usize,
}

impl Poly {
    /// The quadratic `c0 + c1 s + c2 s^2`.
    pub fn quadratic(q: [f64; 3]) -> Self {
        let mut c = [0.0; MAX_DEGREE + 1];
        c[..3].copy_from_slice(&q);
        Poly { c, degree: 2 }
    }

    /// Adds `f * q^3` for the quadratic `q`.
    pub fn add_cube(&mut self, f: f64, q: [f64; 3]) {
        let [a0, a1, a2] = q;
        // q^2
        let s0 = a0 * a0;
        let s1 = 2.0 * a0 * a1;
        let s2 = a1 * a1 + 2.0 * a0 * a2;
        let s3 = 2.0 * a1 * a2;
        let s4 = a2 * a2;
        // q^3 = q^2 * q
        self.c[0] += f * (s0 * a0);
        self.c[1] += f * (s0 * a1 + s1 * a0);
        self.c[2] += f * (s0 * a2 + s1 * a1 + s2 * a0);
        self.c[3] += f * (s1 * a2 + s2 * a1 + s3 * a0);
        self.c[4] += f * (s2 * a2 + s3 * a1 + s4 * a0);
        self.c[5] += f * (s3 * a2 + s4 * a1);
        self.c[6] += f * (s4 * a2);
        self.degree = 6;
    }

    /// Value and derivative at `s` (Horner).
    #[inline]
    pub fn eval_d(&self, s: f64) -> (f64, f64) {
        if self.degree == MAX_DEGREE {
            // The usual degree, with the loop unrolled.
            let c = &self.c;
            let mut p = c[6];
            let mut d = p;
            p = p * s + c[5];
            d = d * s + p;
            p = p * s + c[4];
            d = d * s + p;
            p = p * s + c[3];
            d = d * s + p;
            p = p * s + c[2];
            d = d * s + p;
            p = p * s + c[1];
            d = d * s + p;
            p = p * s + c[0];
            return (p, d);
        }
        let mut p = self.c[self.degree];
        let mut d = 0.0;
        for i in (0..self.degree).rev() {
            d = d * s + p;
            p = p * s + self.c[i];
        }
        (p, d)
    }

    /// Value, first and second derivative at `s` (Horner).
    #[inline]
    pub fn eval_d2(&self, s: f64) -> (f64, f64, f64) {
        if self.degree == MAX_DEGREE {
            // The usual degree, with the loop unrolled.
            let c = &self.c;
            let p = c[6];
            let (d, p) = (p, p * s + c[5]);
            let (d2, d, p) = (d, d * s + p, p * s + c[4]);
            let (d2, d, p) = (d2 * s + d, d * s + p, p * s + c[3]);
            let (d2, d, p) = (d2 * s + d, d * s + p, p * s + c[2]);
            let (d2, d, p) = (d2 * s + d, d * s + p, p * s + c[1]);
            let (d2, d, p) = (d2 * s + d, d * s + p, p * s + c[0]);
            return (p, d, 2.0 * d2);
        }
        let mut p = self.c[self.degree];
        let mut d = 0.0;
        let mut d2 = 0.0;
        for i in (0..self.degree).rev() {
            d2 = d2 * s + d;
            d = d * s + p;
            p = p * s + self.c[i];
        }
        (p, d, 2.0 * d2)
    }

    /// Value at `s`.
    #[inline]
    pub fn eval(&self, s: f64) -> f64 {
        let mut p = self.c[self.degree];
        for i in (0..self.degree).rev() {
            p = p * s + self.c[i];
        }
        p
    }

    /// Bernstein coefficients on `[0, 1]` for degree `self.degree`:
    /// `b_k = sum_{j <= k} C(k, j) / C(n, j) a_j`.
    pub fn bernstein(&self) -> [f64; MAX_DEGREE + 1] {
        let n = self.degree;
        if n == MAX_DEGREE {
            return bernstein6(&self.c);
        }
        let table = &BERNSTEIN[n];
        let mut b = [0.0; MAX_DEGREE + 1];
        for (k, bk) in b.iter_mut().enumerate().take(n + 1) {
            *bk = table[k][..=k].iter().zip(&self.c).map(|(w, c)| w * c).sum();
        }
        b
    }

    /// First crossing root in `[0, 1]`, if any.
    pub fn first_root_unit(&self) -> Option<f64> {
        match self.first_crossing() {
            UnitRoot::Root(s) => Some(s),
            UnitRoot::Clear { .. } => None,
        }
    }

    /// First crossing root in `[0, 1]`; without one, the signs of the
    /// polynomial just after 0 and just before 1 (those of the first and
    /// last non-zero Bernstein coefficients), for the caller to compare
    /// with the neighbouring segments.
    pub fn first_crossing(&self) -> UnitRoot {
        first_crossing(&self.bernstein(), self.degree, &|lo, hi, fa, fb, start| {
            refine_from(&|s| self.eval_d2(s), lo, hi, fa, fb, start)
        })
    }
}

/// A polynomial of degree 6 on `[0, 1]` held by its Bernstein
/// coefficients, built from the segment's quadratics without the power
/// basis: the segment polynomial of [`crate::object`].
///
/// Why not [`Poly`]: near a support's end, where `Q` vanishes, a bump's
/// `f Q^3` is tiny, but its power-basis coefficients are those of
/// `f Q^3` across the whole segment. Where a bump dwarfs its base (a
/// shell, `f Q^3` reaching 1e18 times `|F|` inside the support) the
/// power basis' sums near `s = 1` (`b_6 = sum c_k` among them) cancel
/// to noise larger than `F'` itself, and a root near that end came out
/// up to 5e-5 of the ray's length off (2026-12-05: a sphere of radius 1
/// under a bump of radius 1000, factor 1; `shells_dwarfing_their_base_
/// are_hit_exactly` in the intersection tests). In the Bernstein basis a
/// product of polynomials that are small near an end has coefficients
/// small near that end ([`Bernstein6::add_cube`] multiplies the
/// quadratic's three coefficients, `Q(a)`, `Q(a) + Q'(a) len / 2`,
/// `Q(b)`), and de Casteljau's subdivision, which isolates the root, is
/// accurate relative to those coefficients, so both ends of the segment
/// are as well conditioned as the power basis' origin was (the root is
/// then refined in the power basis about the nearer end,
/// [`Bernstein6::refine`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Bernstein6 {
    /// The Bernstein coefficients `b_k` of `sum b_k C(6, k) s^k (1 - s)^(6 - k)`.
    pub b: [f64; MAX_DEGREE + 1],
}

/// The arithmetic of the Bernstein constructions below: `f64`, and the
/// vector lanes of `object::solo`, which run them on several rays at once
/// and must give the same bits (the same operations in the same order).
pub(crate) trait Real:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Mul<f64, Output = Self>
{
}
impl<T> Real for T where
    T: Copy + Add<Output = T> + Sub<Output = T> + Mul<Output = T> + Mul<f64, Output = T>
{
}

/// The Bernstein coefficients on `[0, 1]` of `q_0 + q_1 s + q_2 s^2`.
#[inline(always)]
pub(crate) fn bernstein2<T: Real>([q0, q1, q2]: [T; 3]) -> [T; 3] {
    [q0, q0 + q1 * 0.5, q0 + q1 + q2]
}

/// The quadratic with the Bernstein coefficients `f` raised to degree 6.
#[inline(always)]
pub(crate) fn elevate2<T: Real>([f0, f1, f2]: [T; 3]) -> [T; MAX_DEGREE + 1] {
    [
        f0,
        (f0 * 2.0 + f1) * (1.0 / 3.0),
        (f0 * 6.0 + f1 * 8.0 + f2) * (1.0 / 15.0),
        (f0 + f1 * 3.0 + f2) * 0.2,
        (f0 + f1 * 8.0 + f2 * 6.0) * (1.0 / 15.0),
        (f1 + f2 * 2.0) * (1.0 / 3.0),
        f2,
    ]
}

impl Bernstein6 {
    /// The quadratic `q_0 + q_1 s + q_2 s^2` raised to degree 6.
    #[inline]
    pub fn quadratic(q: [f64; 3]) -> Self {
        Bernstein6 {
            b: elevate2(bernstein2(q)),
        }
    }

    /// Adds `f * q^3` for the quadratic `q_0 + q_1 s + q_2 s^2`: the
    /// product of Bernstein forms, `(P R)_k = sum_{i + j = k} C(m, i)
    /// C(n, j) / C(m + n, k) p_i r_j`, for `q^2` and then `q^2 q`.
    #[inline]
    pub fn add_cube(&mut self, f: f64, q: [f64; 3]) {
        for (x, t) in self.b.iter_mut().zip(cube2(bernstein2(q))) {
            *x += f * t;
        }
    }

    /// Value, first and second derivative at `s` (de Casteljau).
    #[inline]
    pub fn eval_d2(&self, s: f64) -> (f64, f64, f64) {
        let r = 1.0 - s;
        let mut w = self.b;
        for level in 1..=4 {
            for i in 0..=(MAX_DEGREE - level) {
                w[i] = r * w[i] + s * w[i + 1];
            }
        }
        let d2 = 30.0 * ((w[2] - w[1]) - (w[1] - w[0]));
        let (e0, e1) = (r * w[0] + s * w[1], r * w[1] + s * w[2]);
        (r * e0 + s * e1, 6.0 * (e1 - e0), d2)
    }

    /// Value at `s` (de Casteljau).
    pub fn eval(&self, s: f64) -> f64 {
        self.eval_d2(s).0
    }

    /// The root in `[lo, hi]`, where the values `fa` and `fb` at its ends
    /// have opposite signs, from `start` when inside (NaN: none), by
    /// safeguarded Halley iteration (as [`Poly::first_crossing`] refines)
    /// in the power basis about the nearer end of `[0, 1]`: `s` on
    /// `[0, 1/2]`, `1 - s` on `[1/2, 1]` (a bracket across `1/2` is first
    /// halved by the sign of the value there). Each is as accurate near
    /// its origin as the Bernstein coefficients it comes from (`c_k =
    /// C(6, k)` times the `k`-th forward difference of the coefficients),
    /// and Horner's scheme costs half de Casteljau's.
    pub fn refine(&self, mut lo: f64, mut hi: f64, mut fa: f64, mut fb: f64, start: f64) -> f64 {
        if lo < 0.5 && hi > 0.5 {
            let mid = midpoint(&self.b);
            if mid == 0.0 {
                return 0.5;
            }
            if (mid < 0.0) == (fa < 0.0) {
                (lo, fa) = (0.5, mid);
            } else {
                (hi, fb) = (0.5, mid);
            }
        }
        if lo >= 0.5 {
            let mut r = self.b;
            r.reverse();
            let p = power_poly(r);
            1.0 - refine_from(&|u| p.eval_d2(u), 1.0 - hi, 1.0 - lo, fb, fa, 1.0 - start)
        } else {
            let p = power_poly(self.b);
            refine_from(&|s| p.eval_d2(s), lo, hi, fa, fb, start)
        }
    }

    /// [`Poly::first_crossing`] for this polynomial.
    pub fn first_crossing(&self) -> UnitRoot {
        first_crossing(&self.b, MAX_DEGREE, &|lo, hi, fa, fb, start| {
            self.refine(lo, hi, fa, fb, start)
        })
    }
}

/// The value at `1/2` of the polynomial of degree 6 with the Bernstein
/// coefficients `b` (de Casteljau, as [`de_casteljau_half`] computes it).
#[inline(always)]
pub(crate) fn midpoint<T: Real>(b: &[T; MAX_DEGREE + 1]) -> T {
    let mut w = *b;
    for level in 1..=MAX_DEGREE {
        for i in 0..=(MAX_DEGREE - level) {
            w[i] = (w[i] + w[i + 1]) * 0.5;
        }
    }
    w[0]
}

/// The power basis of the polynomial of degree 6 with the Bernstein
/// coefficients `b`: `c_k = C(6, k) D^k b_0`, the forward differences
/// `D^k b_0 = sum_j (-1)^(k - j) C(k, j) b_j`.
#[inline(always)]
pub(crate) fn power<T: Real>(b: [T; MAX_DEGREE + 1]) -> [T; MAX_DEGREE + 1] {
    const C6: [f64; MAX_DEGREE + 1] = [1.0, 6.0, 15.0, 20.0, 15.0, 6.0, 1.0];
    let mut d = b;
    let mut c = b;
    for k in 1..=MAX_DEGREE {
        for i in 0..=(MAX_DEGREE - k) {
            d[i] = d[i + 1] - d[i];
        }
        c[k] = d[0] * C6[k];
    }
    c
}

/// [`power`] as a [`Poly`].
fn power_poly(b: [f64; MAX_DEGREE + 1]) -> Poly {
    Poly {
        c: power(b),
        degree: MAX_DEGREE,
    }
}

/// The Bernstein coefficients of `q^3` (degree 6) from those of the
/// quadratic `q` (degree 2).
#[inline(always)]
pub(crate) fn cube2<T: Real>([b0, b1, b2]: [T; 3]) -> [T; MAX_DEGREE + 1] {
    // q^2, degree 4.
    let (s0, s1, s2, s3, s4) = (
        b0 * b0,
        b0 * b1,
        (b0 * b2 + (b1 * b1) * 2.0) * (1.0 / 3.0),
        b1 * b2,
        b2 * b2,
    );
    [
        s0 * b0,
        (s0 * b1 + (s1 * b0) * 2.0) * (1.0 / 3.0),
        (s0 * b2 + (s1 * b1) * 8.0 + (s2 * b0) * 6.0) * (1.0 / 15.0),
        (s1 * b2 + (s2 * b1) * 3.0 + s3 * b0) * 0.2,
        ((s2 * b2) * 6.0 + (s3 * b1) * 8.0 + s4 * b0) * (1.0 / 15.0),
        ((s3 * b2) * 2.0 + s4 * b1) * (1.0 / 3.0),
        s4 * b2,
    ]
}

/// First crossing in `[0, 1]` of the polynomial of degree `n` with the
/// Bernstein coefficients `b`, whose root in a bracket `refine(lo, hi,
/// f(lo), f(hi), start)` finds (`start`: a first guess, NaN for none);
/// without one, the signs just after 0 and just before 1 (those of
/// the first and last non-zero coefficients).
#[inline]
fn first_crossing(
    b: &[f64; MAX_DEGREE + 1],
    n: usize,
    refine: &impl Fn(f64, f64, f64, f64, f64) -> f64,
) -> UnitRoot {
    let b = *b;
    if b[..=n].iter().all(|&x| x != 0.0) {
        // The usual case, decided without the subdivision stack: no
        // zero coefficient, and no sign change (no root) or a single
        // one between ends of opposite signs (exactly one root).
        let mut changes = 0;
        for k in 0..n {
            changes += ((b[k] < 0.0) != (b[k + 1] < 0.0)) as u32;
        }
        if changes == 0 {
            return UnitRoot::Clear {
                start: sign(b[0]),
                end: sign(b[n]),
            };
        }
        if changes == 1 {
            // A first step for free: Halley's from the end whose
            // Newton correction is smaller, with the value and
            // derivatives there read off the Bernstein coefficients.
            let nf = n as f64;
            let (f0, d0, e0) = (
                b[0],
                nf * (b[1] - b[0]),
                nf * (nf - 1.0) * (b[2] - 2.0 * b[1] + b[0]),
            );
            let (f1, d1, e1) = (
                b[n],
                nf * (b[n] - b[n - 1]),
                nf * (nf - 1.0) * (b[n] - 2.0 * b[n - 1] + b[n - 2]),
            );
            let from0 = -2.0 * f0 * d0 / (2.0 * d0 * d0 - f0 * e0);
            let from1 = 1.0 - 2.0 * f1 * d1 / (2.0 * d1 * d1 - f1 * e1);
            let start = if (f0 * d1).abs() < (f1 * d0).abs() {
                from0
            } else {
                from1
            };
            return UnitRoot::Root(refine(0.0, 1.0, b[0], b[n], start));
        }
    }
    match isolate(b, n, refine) {
        Some(s) => UnitRoot::Root(s),
        None => {
            let mut nonzero = b[..=n].iter().copied().filter(|&x| x != 0.0);
            let start = sign(nonzero.next().unwrap_or(0.0));
            // The last non-zero coefficient (the first when only one).
            let end = nonzero.next_back().map_or(start, sign);
            UnitRoot::Clear { start, end }
        }
    }
}

/// First crossing in `[0, 1]` from the Bernstein coefficients `b` of
/// degree `n`.
fn isolate(
    b: [f64; MAX_DEGREE + 1],
    n: usize,
    refine: &impl Fn(f64, f64, f64, f64, f64) -> f64,
) -> Option<f64> {
    let at_zero = b[0];
    // Explicit stack of (coefficients, lo, hi, depth), left first.
    let mut stack: smallvec::SmallVec<[Interval; 24]> = smallvec::SmallVec::new();
    stack.push((b, 0.0, 1.0, 0));
    while let Some((b, lo, hi, depth)) = stack.pop() {
        if b[0] == 0.0 {
            // Exact zero at the left end (measure zero, but must not loop).
            if lo > 0.0 || at_zero == 0.0 {
                return Some(lo);
            }
        }
        let changes = sign_changes(&b[..=n]);
        if changes == 0 {
            continue;
        }
        let fa = b[0];
        let fb = b[n];
        if changes == 1 && fa * fb < 0.0 {
            return Some(refine(lo, hi, fa, fb, f64::NAN));
        }
        if depth >= MAX_DEPTH {
            if fa * fb <= 0.0 {
                return Some(refine(lo, hi, fa, fb, f64::NAN));
            }
            // Even number of roots closer than the resolution: a tangency.
            continue;
        }
        let (l, r) = de_casteljau_half(&b, n);
        let mid = 0.5 * (lo + hi);
        stack.push((r, mid, hi, depth + 1));
        stack.push((l, lo, mid, depth + 1));
    }
    None
}

/// Safeguarded Halley iteration on a bracket `[lo, hi]` with
/// `sign(f(lo)) = sign(fa)` opposite to `sign(f(hi)) = sign(fb)`, the
/// value and derivatives by `eval_d2`, from `start` when it lies inside
/// the bracket.
///
/// Otherwise from the false-position point of the end values (the
/// segments are short next to the polynomial's curvature, so it is
/// close). Bisects whenever a step would leave the bracket. Halley's
/// method converges cubically, so a step below `1e-6` of `s` (the
/// distance from the origin of the power basis `eval_d2` evaluates in:
/// the polynomial's terms vary on that scale) leaves an error of order
/// `1e-18` times the derivatives' ratios: the iteration stops after
/// applying it, or when the bracket reaches rounding. (Newton, used
/// before, needed a step below `1e-9` for the same error: 3.45
/// evaluations per root at 64 benchmark bumps against Halley's 2.44,
/// whose second-derivative chain runs beside the other two.)
fn refine_from(
    eval_d2: &impl Fn(f64) -> (f64, f64, f64),
    mut lo: f64,
    mut hi: f64,
    fa: f64,
    fb: f64,
    start: f64,
) -> f64 {
    let neg_left = fa < 0.0;
    let mut s = if start > lo && start < hi {
        start
    } else {
        lo + (hi - lo) * (fa / (fa - fb))
    };
    if !(s > lo && s < hi) {
        s = 0.5 * (lo + hi);
    }
    for _ in 0..100 {
        let (f, d, d2) = eval_d2(s);
        if f == 0.0 {
            return s;
        }
        if (f < 0.0) == neg_left {
            lo = s;
        } else {
            hi = s;
        }
        // Halley's step (cubic convergence: the second derivative's
        // chain runs beside the others, so an iteration costs about
        // what Newton's does, and fewer are needed).
        let denom = 2.0 * d * d - f * d2;
        let step = 2.0 * f * d / denom;
        let newton = s - step;
        if denom != 0.0 && newton > lo && newton < hi {
            if step.abs() <= 1e-6 * newton.abs().max(1e-300) {
                return newton;
            }
            s = newton;
        } else {
            s = 0.5 * (lo + hi);
        }
        if hi - lo <= 2.0 * f64::EPSILON * hi.abs() {
            return s;
        }
    }
    s
}

/// What [`Poly::first_crossing`] found on `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum UnitRoot {
    /// The first crossing.
    Root(f64),
    /// None: the signs (`1`, `-1`, `0` for the zero polynomial) just after
    /// 0 and just before 1.
    Clear {
        /// Sign just after 0.
        start: f64,
        /// Sign just before 1.
        end: f64,
    },
}

/// Bernstein coefficients on `[lo, hi]` and the subdivision depth.
type Interval = ([f64; MAX_DEGREE + 1], f64, f64, u32);

/// Binomial coefficient (small arguments), usable in constants.
const fn binom(n: usize, k: usize) -> u64 {
    let mut r = 1u64;
    let mut i = 0;
    while i < k {
        r = r * (n - i) as u64 / (i + 1) as u64;
        i += 1;
    }
    r
}

/// Power-to-Bernstein weights `C(k, j) / C(n, j)`, indexed `[n][k][j]`.
pub(crate) const BERNSTEIN: [[[f64; MAX_DEGREE + 1]; MAX_DEGREE + 1]; MAX_DEGREE + 1] = {
    let mut t = [[[0.0; MAX_DEGREE + 1]; MAX_DEGREE + 1]; MAX_DEGREE + 1];
    let mut n = 0;
    while n <= MAX_DEGREE {
        let mut k = 0;
        while k <= n {
            let mut j = 0;
            while j <= k {
                t[n][k][j] = binom(k, j) as f64 / binom(n, j) as f64;
                j += 1;
            }
            k += 1;
        }
        n += 1;
    }
    t
};

/// [`Poly::bernstein`] for degree 6, written out: the weights are
/// constants and the sums are in the same order, so the coefficients are
/// those of the general loop to the last bit.
#[inline]
fn bernstein6(c: &[f64; MAX_DEGREE + 1]) -> [f64; MAX_DEGREE + 1] {
    const W: [[f64; MAX_DEGREE + 1]; MAX_DEGREE + 1] = BERNSTEIN[MAX_DEGREE];
    [
        W[0][0] * c[0],
        W[1][0] * c[0] + W[1][1] * c[1],
        W[2][0] * c[0] + W[2][1] * c[1] + W[2][2] * c[2],
        W[3][0] * c[0] + W[3][1] * c[1] + W[3][2] * c[2] + W[3][3] * c[3],
        W[4][0] * c[0] + W[4][1] * c[1] + W[4][2] * c[2] + W[4][3] * c[3] + W[4][4] * c[4],
        W[5][0] * c[0]
            + W[5][1] * c[1]
            + W[5][2] * c[2]
            + W[5][3] * c[3]
            + W[5][4] * c[4]
            + W[5][5] * c[5],
        W[6][0] * c[0]
            + W[6][1] * c[1]
            + W[6][2] * c[2]
            + W[6][3] * c[3]
            + W[6][4] * c[4]
            + W[6][5] * c[5]
            + W[6][6] * c[6],
    ]
}

/// Number of sign changes among the non-zero entries.
#[inline]
fn sign_changes(b: &[f64]) -> u32 {
    let mut count = 0;
    let mut prev = 0.0f64;
    for &x in b {
        if x != 0.0 {
            if prev != 0.0 && (x < 0.0) != (prev < 0.0) {
                count += 1;
            }
            prev = x;
        }
    }
    count
}

/// Splits Bernstein coefficients at `s = 1/2` (de Casteljau).
#[inline]
fn de_casteljau_half(
    b: &[f64; MAX_DEGREE + 1],
    n: usize,
) -> ([f64; MAX_DEGREE + 1], [f64; MAX_DEGREE + 1]) {
    let mut work = *b;
    let mut left = [0.0; MAX_DEGREE + 1];
    let mut right = [0.0; MAX_DEGREE + 1];
    left[0] = work[0];
    right[n] = work[n];
    for level in 1..=n {
        for i in 0..=(n - level) {
            work[i] = 0.5 * (work[i] + work[i + 1]);
        }
        left[level] = work[0];
        right[n - level] = work[n - level];
    }
    (left, right)
}

/// Up to two roots, ascending (the result of [`quadratic_crossings`]): a
/// slice by `Deref`, without the heap or the capacity checks of a vector.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Crossings {
    roots: [f64; 2],
    len: usize,
}

impl Crossings {
    /// Two roots `r0 <= r1`.
    #[inline]
    pub(crate) fn two(r0: f64, r1: f64) -> Self {
        Self {
            roots: [r0, r1],
            len: 2,
        }
    }

    /// Both roots `(r0, r1)`, `r0 <= r1`, when there are two.
    #[inline]
    pub fn pair(&self) -> Option<(f64, f64)> {
        (self.len == 2).then_some((self.roots[0], self.roots[1]))
    }
}

impl std::ops::Deref for Crossings {
    type Target = [f64];
    #[inline]
    fn deref(&self) -> &[f64] {
        &self.roots[..self.len]
    }
}

impl IntoIterator for Crossings {
    type Item = f64;
    type IntoIter = std::iter::Take<std::array::IntoIter<f64, 2>>;
    #[inline]
    fn into_iter(self) -> Self::IntoIter {
        self.roots.into_iter().take(self.len)
    }
}

/// Roots of `c0 + c1 t + c2 t^2` where the sign changes, ascending, by the
/// numerically stable formula (no cancellation). Double roots (tangency)
/// and complex roots give none.
#[inline]
pub fn quadratic_crossings(q: [f64; 3]) -> Crossings {
    let [c, b, a] = q;
    let mut out = Crossings::default();
    let scale = fmax(fmax(a.abs(), b.abs()), c.abs());
    if scale == 0.0 {
        return out;
    }
    if a.abs() <= 1e-15 * scale {
        if b != 0.0 {
            out.roots[0] = -c / b;
            out.len = 1;
        }
        return out;
    }
    if let Some((r0, r1)) = two_roots(q) {
        out.roots = [r0, r1];
        out.len = 2;
    }
    out
}

/// Both roots of `c0 + c1 t + c2 t^2`, ascending, when the discriminant is
/// positive, by the stable formula `h = -(c1 + sign(c1) sqrt(disc)) / 2`,
/// roots `h / c2` and `c0 / h`. Assumes `c2 != 0`; callers handle the
/// degenerate cases ([`quadratic_crossings`]).
#[inline]
pub(crate) fn two_roots(q: [f64; 3]) -> Option<(f64, f64)> {
    let [c, b, a] = q;
    let disc = b * b - 4.0 * a * c;
    if !(disc > 0.0) {
        return None;
    }
    let sq = disc.sqrt();
    let h = -0.5 * (b + sq.copysign(b));
    let (r1, r2) = if h == 0.0 {
        // Only when b == 0 and c == 0, which disc > 0 excludes; kept so
        // that no division by zero can happen.
        let r = sq / (2.0 * a);
        (-r, r)
    } else {
        (h / a, c / h)
    };
    Some((fmin(r1, r2), fmax(r1, r2)))
}

/// The smaller of `a` and `b` by one comparison (a single `minsd`, where
/// `f64::min`'s NaN rules take four more instructions): for operands
/// that are not NaN, as on the intersection's hot path.
#[inline(always)]
pub(crate) fn fmin(a: f64, b: f64) -> f64 {
    if a < b {
        a
    } else {
        b
    }
}

/// The larger of `a` and `b` by one comparison; see [`fmin`].
#[inline(always)]
pub(crate) fn fmax(a: f64, b: f64) -> f64 {
    if a > b {
        a
    } else {
        b
    }
}

/// `1` or `-1` by the sign of `x`; `0` for zero and NaN.
#[inline]
pub(crate) fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn from_roots(roots: &[f64], lead: f64) -> Poly {
        let mut c = [0.0; 7];
        c[0] = lead;
        let mut deg = 0;
        for &r in roots {
            // multiply by (s - r)
            for i in (0..=deg + 1).rev() {
                let lower = if i > 0 { c[i - 1] } else { 0.0 };
                c[i] = lower - r * c[i];
            }
            deg += 1;
        }
        Poly { c, degree: deg }
    }

    #[test]
    fn finds_first_of_several_roots() {
        let p = from_roots(&[0.71, 0.2, 0.9, 1.5, -0.3, 0.45], 2.0);
        let r = p.first_root_unit().unwrap();
        assert!((r - 0.2).abs() < 1e-14, "{r}");
    }

    #[test]
    fn close_roots_are_separated() {
        // Roots 1e-6 apart: conditioning limits accuracy to ~eps/|p'|.
        let p = from_roots(&[0.5 + 1e-6, 0.5, 2.0, 3.0], 1.0);
        let r = p.first_root_unit().unwrap();
        assert!((r - 0.5).abs() < 1e-9, "{r}");
    }

    #[test]
    fn tangent_double_root_is_not_a_crossing() {
        let p = from_roots(&[0.3, 0.3, 2.0, 3.0], 1.0);
        assert!(p.first_root_unit().is_none());
        let p = from_roots(&[0.3, 0.3, 0.6, 3.0], 1.0);
        assert!((p.first_root_unit().unwrap() - 0.6).abs() < 1e-12);
    }

    #[test]
    fn no_roots_in_unit_interval() {
        let p = from_roots(&[-0.5, 1.2, 1.7, 2.0, 5.0, -3.0], -1.0);
        assert!(p.first_root_unit().is_none());
    }

    #[test]
    fn bernstein_coefficients_reproduce_the_polynomial() {
        // sum_k b_k C(n,k) s^k (1-s)^(n-k) = p(s)
        let p = from_roots(&[0.1, 0.4, 0.45, 0.9, 1.3, -2.0], 1.5);
        let b = p.bernstein();
        let n = p.degree;
        for i in 0..=10 {
            let s = i as f64 / 10.0;
            let v: f64 = (0..=n)
                .map(|k| {
                    b[k] * binom(n, k) as f64 * s.powi(k as i32) * (1.0 - s).powi((n - k) as i32)
                })
                .sum();
            assert!((v - p.eval(s)).abs() < 1e-12, "{v} {}", p.eval(s));
        }
    }

    #[test]
    fn add_cube_matches_direct_power() {
        let q = [0.3, -1.2, 0.7];
        let mut p = Poly::quadratic([1.0, 2.0, 3.0]);
        p.add_cube(-0.8, q);
        for s in [0.0, 0.3, 0.9, 1.7] {
            let qs = q[0] + q[1] * s + q[2] * s * s;
            let expect = 1.0 + 2.0 * s + 3.0 * s * s - 0.8 * qs.powi(3);
            assert!((p.eval(s) - expect).abs() < 1e-12);
        }
    }

    #[test]
    fn bernstein6_builds_the_segment_polynomial() {
        let base = [1.0, 2.0, -3.0];
        let cubes = [(-0.8, [0.3, -1.2, 0.7]), (2.5, [0.1, 0.9, -0.95])];
        let mut p = Bernstein6::quadratic(base);
        for (f, q) in cubes {
            p.add_cube(f, q);
        }
        let direct = |s: f64| {
            let q2 = |q: [f64; 3]| q[0] + q[1] * s + q[2] * s * s;
            q2(base) + cubes.iter().map(|&(f, q)| f * q2(q).powi(3)).sum::<f64>()
        };
        for i in 0..=20 {
            let s = i as f64 / 20.0;
            let (v, d, d2) = p.eval_d2(s);
            let h = 1e-5;
            assert!((v - direct(s)).abs() < 1e-13, "{s}: {v} vs {}", direct(s));
            assert!((d - (direct(s + h) - direct(s - h)) / (2.0 * h)).abs() < 1e-8);
            let fd2 = (direct(s + h) - 2.0 * direct(s) + direct(s - h)) / (h * h);
            assert!((d2 - fd2).abs() < 1e-4, "{d2} vs {fd2}");
        }
        // The power basis of the same polynomial, both ways round.
        let c = power_poly(p.b);
        let mut r = p.b;
        r.reverse();
        let reversed = power_poly(r);
        for i in 0..=20 {
            let s = i as f64 / 20.0;
            assert!((c.eval(s) - direct(s)).abs() < 1e-13);
            assert!((reversed.eval(1.0 - s) - direct(s)).abs() < 1e-13);
        }
        let b = c.bernstein();
        assert!(b.iter().zip(&p.b).all(|(x, y)| (x - y).abs() < 1e-14));
    }

    #[test]
    fn bernstein6_roots_beside_either_end_of_a_dwarfing_cube() {
        // -1 + f Q^3 with f Q^3 up to 1e18: the crossing lies about 1e-6
        // from the end where Q vanishes. The power basis about s = 0 holds
        // the right end's value only to 1e18 eps, some 200 times |p|.
        let k = 1e6;
        for right in [false, true] {
            // Q = k s (2 - s) (zero at s = 0) or k (1 - s)(1 + s) (at 1).
            let q = if right {
                [k, 0.0, -k]
            } else {
                [0.0, 2.0 * k, -k]
            };
            let mut p = Bernstein6::quadratic([-1.0, 0.0, 0.0]);
            p.add_cube(1.0, q);
            let exact = |s: f64| -1.0 + (q[0] + q[1] * s + q[2] * s * s).powi(3);
            let (mut lo, mut hi) = if right { (0.5, 1.0) } else { (0.0, 0.5) };
            for _ in 0..200 {
                let m = 0.5 * (lo + hi);
                if (exact(m) > 0.0) == (exact(lo) > 0.0) {
                    lo = m;
                } else {
                    hi = m;
                }
            }
            let UnitRoot::Root(root) = p.first_crossing() else {
                panic!("right {right}: no crossing");
            };
            let dist = if right { 1.0 - lo } else { lo };
            assert!(dist < 1e-5 && dist > 1e-7, "{dist}");
            // Within a few ulps of s (1e-16 beside s = 1, 5e-10 of `dist`).
            assert!(
                (root - lo).abs() <= 4.0 * f64::EPSILON * lo.max(1e-6),
                "right {right}: {root} vs {lo}"
            );
        }
    }

    #[test]
    fn stable_quadratic() {
        // Roots 1e-8 and 1e8: naive formula loses the small one.
        let r = quadratic_crossings([1.0, -(1e8 + 1e-8), 1.0]);
        assert!((r[0] - 1e-8).abs() < 1e-20 && (r[1] - 1e8).abs() < 1e-6);
        assert!(
            quadratic_crossings([1.0, 2.0, 1.0]).is_empty()
                || quadratic_crossings([1.0, 2.0, 1.0]).len() == 2
        );
        assert!(quadratic_crossings([1.0, 0.0, 1.0]).is_empty());
    }
}
