//! Quadrics: polynomials of degree <= 2 in x, y, z.
//!
//! ```text
//! Q(p) = a11 x^2 + a22 y^2 + a33 z^2 + 2 a12 xy + 2 a13 xz + 2 a23 yz
//!        + 2 a14 x + 2 a24 y + 2 a34 z + a44
//!      = p^T M p + 2 b.p + c
//! ```
//!
//! with `M` the symmetric 3x3 block, `b = (a14, a24, a34)`, `c = a44`; in
//! homogeneous form `Q(p) = [p 1] S [p 1]^T` with the symmetric 4x4 `S`.
//!
//! **Sign convention** (Vyatkin, HyperFun, SPEC §1): every constructor yields
//! a quadric that is *positive inside*, so a sphere is `r^2 - |p - c|^2`. A
//! perturbation `f Q^3 [Q >= 0]` with `f > 0` therefore raises a bump and
//! with `f < 0` carves a dent.
//!
//! **Scale convention.** The magnitude of a quadric matters when it perturbs
//! (the bump height scales with `f Q^3`). The constructors are scaled so
//! that `Q` equals "squared radius minus squared distance" wherever that
//! phrase has a meaning:
//!
//! | constructor | Q(p) |
//! |---|---|
//! | sphere (c, r) | `r^2 - |p - c|^2` |
//! | ellipsoid (c, radii, R) | `s^2 (1 - sum (q_i / r_i)^2)`, `q = R^T (p - c)`, `s` = geometric mean of the radii (equals the sphere for equal radii) |
//! | cylinder (c, axis a, r) | `r^2 - |(p - c) - ((p - c).a) a|^2` (infinite) |
//! | cone (apex, axis a, half-angle θ) | `(h tan θ)^2 - ρ^2`, `h = (p - apex).a`, `ρ` the distance to the axis (both nappes) |
//! | paraboloid (vertex, axis a, focal length f) | `4 f h - ρ^2`, opening along `+a` |
//! | plane (point, normal n) | `-(p - point).n`: solid behind the plane, outward normal `n` |

use isolux_core::{Aabb, DMat3, DMat4, DVec3, DVec4, Ray};

/// A quadric `p^T M p + 2 b.p + c` (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quadric {
    /// Symmetric quadratic part.
    pub m: DMat3,
    /// Linear part (half the gradient at the origin).
    pub b: DVec3,
    /// Constant term.
    pub c: f64,
}

impl Quadric {
    /// From the ten coefficients `[a11, a22, a33, a12, a13, a23, a14, a24,
    /// a34, a44]` of the module formula.
    pub fn from_coefficients(a: [f64; 10]) -> Self {
        let [a11, a22, a33, a12, a13, a23, a14, a24, a34, a44] = a;
        Self {
            m: DMat3::from_cols(
                DVec3::new(a11, a12, a13),
                DVec3::new(a12, a22, a23),
                DVec3::new(a13, a23, a33),
            ),
            b: DVec3::new(a14, a24, a34),
            c: a44,
        }
    }

    /// The ten coefficients, in the order of [`Quadric::from_coefficients`].
    pub fn coefficients(&self) -> [f64; 10] {
        let m = &self.m;
        [
            m.x_axis.x, m.y_axis.y, m.z_axis.z, m.y_axis.x, m.z_axis.x, m.z_axis.y, self.b.x,
            self.b.y, self.b.z, self.c,
        ]
    }

    /// Sphere of centre `c` and radius `r`: `r^2 - |p - c|^2`.
    pub fn sphere(c: DVec3, r: f64) -> Self {
        Self {
            m: -DMat3::IDENTITY,
            b: c,
            c: r * r - c.length_squared(),
        }
    }

    /// Ellipsoid with centre `c`, semi-axes `radii` along the columns of the
    /// rotation `rot` (identity for axis-aligned).
    pub fn ellipsoid(c: DVec3, radii: DVec3, rot: DMat3) -> Self {
        let s2 = (radii.x * radii.y * radii.z).abs().powf(2.0 / 3.0);
        // Local: s^2 (1 - sum q_i^2 / r_i^2) with q = R^T (p - c).
        let d = DMat3::from_diagonal(-s2 / (radii * radii));
        let local = Self {
            m: d,
            b: DVec3::ZERO,
            c: s2,
        };
        local.transformed(&(DMat4::from_translation(c) * DMat4::from_mat3(rot)))
    }

    /// Infinite cylinder of radius `r` around the line through `c` along `axis`.
    pub fn cylinder(c: DVec3, axis: DVec3, r: f64) -> Self {
        let a = axis.normalize();
        // r^2 - |v|^2 + (v.a)^2, v = p - c  ->  M = a a^T - I.
        let m = DMat3::from_cols(a * a.x, a * a.y, a * a.z) - DMat3::IDENTITY;
        Self::centred(m, c, r * r)
    }

    /// Double cone with apex `apex`, axis `axis` and half-angle `half_angle`
    /// (radians, in `(0, pi/2)`).
    pub fn cone(apex: DVec3, axis: DVec3, half_angle: f64) -> Self {
        let a = axis.normalize();
        let t2 = half_angle.tan().powi(2);
        // h^2 tan^2 - (|v|^2 - h^2) = (1 + tan^2) h^2 - |v|^2.
        let m = DMat3::from_cols(a * a.x, a * a.y, a * a.z) * (1.0 + t2) - DMat3::IDENTITY;
        Self::centred(m, apex, 0.0)
    }

    /// Paraboloid with vertex `vertex` opening along `axis`, focal length `f`:
    /// `4 f h - rho^2`.
    pub fn paraboloid(vertex: DVec3, axis: DVec3, f: f64) -> Self {
        let a = axis.normalize();
        // 4 f (v.a) - |v|^2 + (v.a)^2
        let m = DMat3::from_cols(a * a.x, a * a.y, a * a.z) - DMat3::IDENTITY;
        let q = Self::centred(m, vertex, 0.0);
        // add linear term 4 f a.(p - vertex) = 2 (2 f a).p - 4 f a.vertex
        Self {
            m: q.m,
            b: q.b + 2.0 * f * a,
            c: q.c - 4.0 * f * a.dot(vertex),
        }
    }

    /// Half-space behind the plane through `point` with outward normal `n`.
    pub fn plane(point: DVec3, n: DVec3) -> Self {
        let n = n.normalize();
        Self {
            m: DMat3::ZERO,
            b: -0.5 * n,
            c: n.dot(point),
        }
    }

    /// `(p - c)^T m (p - c) + k`.
    fn centred(m: DMat3, c: DVec3, k: f64) -> Self {
        Self {
            m,
            b: -(m * c),
            c: c.dot(m * c) + k,
        }
    }

    /// The symmetric 4x4 homogeneous matrix `S`.
    pub fn to_mat4(&self) -> DMat4 {
        DMat4::from_cols(
            self.m.x_axis.extend(self.b.x),
            self.m.y_axis.extend(self.b.y),
            self.m.z_axis.extend(self.b.z),
            DVec4::new(self.b.x, self.b.y, self.b.z, self.c),
        )
    }

    fn from_mat4(s: &DMat4) -> Self {
        // Symmetrize to wash out round-off.
        let s = (*s + s.transpose()) * 0.5;
        Self {
            m: DMat3::from_cols(
                s.x_axis.truncate(),
                s.y_axis.truncate(),
                s.z_axis.truncate(),
            ),
            b: s.w_axis.truncate(),
            c: s.w_axis.w,
        }
    }

    /// The quadric moved by the affine map `t` (the new quadric at `t(p)`
    /// equals the old one at `p`): `S' = T^-T S T^-1`.
    pub fn transformed(&self, t: &DMat4) -> Self {
        let inv = t.inverse();
        Self::from_mat4(&(inv.transpose() * self.to_mat4() * inv))
    }

    /// The quadric moved by `v` (the new quadric at `p + v` equals the old
    /// one at `p`), computed directly rather than through the 4x4 inverse
    /// of [`Quadric::transformed`]: with `u = -v`, `M` is unchanged, `b' =
    /// b + M u`, `c' = c + u.(M u + 2 b)`. An object's frame
    /// ([`crate::Object::origin`]) moves its quadrics this way.
    pub fn translated(&self, v: DVec3) -> Self {
        let u = -v;
        let mu = self.m * u;
        Self {
            m: self.m,
            b: self.b + mu,
            c: self.c + u.dot(mu + 2.0 * self.b),
        }
    }

    /// Multiplied by a positive constant (same surface, scaled magnitude).
    pub fn scaled(&self, k: f64) -> Self {
        Self {
            m: self.m * k,
            b: self.b * k,
            c: self.c * k,
        }
    }

    /// Value at `p`.
    #[inline]
    pub fn eval(&self, p: DVec3) -> f64 {
        p.dot(self.m * p) + 2.0 * self.b.dot(p) + self.c
    }

    /// Gradient at `p`: `2 (M p + b)`.
    #[inline]
    pub fn gradient(&self, p: DVec3) -> DVec3 {
        2.0 * (self.m * p + self.b)
    }

    /// Restriction to a ray: `Q(o + t d) = a t^2 + b t + c`, as `[c, b, a]`
    /// (ascending powers).
    #[inline]
    pub fn along(&self, ray: &Ray) -> [f64; 3] {
        let md = self.m * ray.dir;
        let a = ray.dir.dot(md);
        let b = 2.0 * (md.dot(ray.origin) + self.b.dot(ray.dir));
        let c = self.eval(ray.origin);
        [c, b, a]
    }

    /// `(-M)^-1` and a bound on its relative rounding error, when `M` is
    /// negative definite and far enough from degenerate for that inverse
    /// to mean something; `None` otherwise (the positive set is then taken
    /// as unbounded).
    ///
    /// `-M` is first scaled to a unit diagonal (`S (-M) S`, `S` diagonal),
    /// which leaves its definiteness and the shape of its inverse alone
    /// (`(-M)^-1 = S (S (-M) S)^-1 S`) and removes a spread of scales
    /// between the axes: a disc of radii 0.45, 0.6 and 1e-6 along the
    /// axes, whose diagonal spans 12 orders of magnitude, is the identity
    /// then. Definiteness is Sylvester's test on the scaled matrix's
    /// leading minors, whose determinant `det` (at most 1, by Hadamard's
    /// inequality; 1 along the axes, near 0 near a degenerate quadric such
    /// as a cylinder or a slab) must exceed `1e-14`, and the inverse's
    /// relative error is about `64 eps / det`: its cofactors and
    /// determinant are sums of products of entries at most 1 in size, so
    /// their absolute rounding stays within a few tens of `eps`, and each
    /// cofactor on the diagonal is at least `det`.
    fn definite_inverse(&self) -> Option<(DMat3, f64)> {
        /// The smallest scaled determinant taken as definite.
        const DET_FLOOR: f64 = 1e-14;
        let neg = -self.m;
        let diag = DVec3::new(neg.x_axis.x, neg.y_axis.y, neg.z_axis.z);
        if !(diag.min_element() > 0.0) || !diag.is_finite() {
            return None;
        }
        let scale = DMat3::from_diagonal(DVec3::ONE / diag.map(f64::sqrt));
        let unit = scale * neg * scale;
        let m2 = unit.x_axis.x * unit.y_axis.y - unit.x_axis.y * unit.y_axis.x;
        let det = unit.determinant();
        if !(m2 > DET_FLOOR && det > DET_FLOOR) {
            return None;
        }
        Some((scale * unit.inverse() * scale, 64.0 * f64::EPSILON / det))
    }

    /// Bounding box of the positive set `{Q >= 0}` when it is bounded (an
    /// ellipsoid, possibly a point or empty), `None` when unbounded.
    ///
    /// For negative definite `M` the set is `{(p - m)^T (-M) (p - m) <= k}`
    /// with centre `m = -M^-1 b` and `k = Q(m)`; its half-extent along axis
    /// `i` is `sqrt(k ((-M)^-1)_ii)`. The box is padded by a relative hair
    /// (1e-9) and by the rounding of `(-M)^-1` (`definite_inverse`), which
    /// for most quadrics is far below the hair and for an ellipsoid thin
    /// along a turned axis can exceed it (a disc 1e-4 thick turned off the
    /// axes: about 1e-3), so that boundary roots are never culled.
    pub fn positive_bounds(&self) -> Option<Aabb> {
        let (inv, err) = self.definite_inverse()?;
        let centre = inv * self.b; // -M^-1 b = (-M)^-1 b
        let k = self.eval(centre);
        if !(k >= 0.0) {
            return Some(Aabb::EMPTY);
        }
        let half = DVec3::new(
            (k * inv.x_axis.x).max(0.0).sqrt(),
            (k * inv.y_axis.y).max(0.0).sqrt(),
            (k * inv.z_axis.z).max(0.0).sqrt(),
        );
        // `k` is a sum of terms that can dwarf it (a thin ellipsoid away
        // from the origin: `1 - (z / 1e-6)^2` written out about the
        // origin), rounded within a few `eps` of their sizes; the
        // half-extents go as its square root.
        let terms =
            centre.dot(self.m * centre).abs() + 2.0 * self.b.dot(centre).abs() + self.c.abs();
        let k_err = 8.0 * f64::EPSILON * terms / k.max(f64::MIN_POSITIVE);
        let reach = half.max_element() + centre.abs().max_element();
        let pad = half * (1e-9 + k_err.min(1.0))
            + DVec3::splat(err * reach + 1e-12 * (1.0 + centre.abs().max_element()));
        Some(Aabb::new(centre - half - pad, centre + half + pad))
    }

    /// The largest value of `Q`, at the centre of its positive set, when
    /// that set is bounded and not empty (an ellipsoid); `None` otherwise.
    pub fn positive_max(&self) -> Option<f64> {
        let b = self.positive_bounds()?;
        if b.is_empty() {
            return None;
        }
        let centre = self.definite_inverse()?.0 * self.b;
        Some(self.eval(centre).max(0.0))
    }

    /// A sphere `(centre, radius)` containing the positive set when it is
    /// bounded and not empty (an ellipsoid), `None` otherwise.
    ///
    /// The centre is the ellipsoid's, `m = -M^-1 b`; the radius is
    /// `sqrt(k lambda)` with `k = Q(m)` and `lambda` a Gershgorin bound on
    /// the largest eigenvalue of `(-M)^-1` (exact for axis-aligned
    /// ellipsoids and spheres), or the half-diagonal of
    /// [`Quadric::positive_bounds`] when that is smaller. Padded like the box,
    /// so that culling by it never loses a boundary root.
    pub fn positive_bounding_sphere(&self) -> Option<(DVec3, f64)> {
        let b = self.positive_bounds()?;
        if b.is_empty() {
            return None;
        }
        let (inv, err) = self.definite_inverse()?;
        let centre = inv * self.b;
        let k = self.eval(centre).max(0.0);
        let row = |i: usize| {
            let r = inv.row(i);
            r[i] + (0..3).filter(|&j| j != i).map(|j| r[j].abs()).sum::<f64>()
        };
        let lambda = row(0).max(row(1)).max(row(2));
        let diagonal = 0.5 * (b.max - b.min).length();
        let radius = (k * lambda).sqrt().min(diagonal);
        let pad = radius * 1e-9
            + err * (radius + centre.abs().max_element())
            + 1e-12 * (1.0 + centre.abs().max_element());
        Some((centre, radius + pad))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9 * (1.0 + a.abs().max(b.abs()))
    }

    /// `translated(v)` at `p + v` equals the original at `p`, and agrees
    /// with `transformed` by the translation, for every constructor.
    #[test]
    fn translated_moves_the_quadric() {
        let rot = DMat3::from_rotation_y(0.7) * DMat3::from_rotation_x(-0.4);
        let qs = [
            Quadric::sphere(DVec3::new(0.3, -0.2, 1.0), 0.7),
            Quadric::ellipsoid(DVec3::new(1.0, 2.0, -1.0), DVec3::new(0.5, 1.5, 0.2), rot),
            Quadric::cylinder(DVec3::new(0.1, 0.0, 2.0), DVec3::new(1.0, 1.0, 0.0), 0.4),
            Quadric::cone(DVec3::ONE, DVec3::Z, 0.3),
            Quadric::paraboloid(DVec3::new(-1.0, 0.5, 0.0), DVec3::X, 0.25),
            Quadric::plane(DVec3::new(0.0, -0.6, 0.0), DVec3::new(0.2, 1.0, 0.1)),
        ];
        let v = DVec3::new(3.5, -1.25, 0.75);
        let mut rng = isolux_core::Pcg32::new(5, 2);
        for q in qs {
            let moved = q.translated(v);
            let via = q.transformed(&DMat4::from_translation(v));
            for _ in 0..50 {
                let p = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 4.0 - 2.0;
                assert!(close(moved.eval(p + v), q.eval(p)), "{q:?}");
                assert!(close(via.eval(p + v), moved.eval(p + v)), "{q:?}");
            }
        }
    }

    #[test]
    fn bounding_spheres_contain_the_positive_set() {
        // Points on the boundary Q = 0 (found by bisection along random
        // directions from the centre) lie inside the sphere, and for a
        // sphere the bound is exact.
        let q = Quadric::sphere(DVec3::new(0.3, -0.2, 1.0), 0.7);
        let (c, r) = q.positive_bounding_sphere().unwrap();
        assert!((c - DVec3::new(0.3, -0.2, 1.0)).length() < 1e-12 && (r - 0.7).abs() < 1e-8);
        let rot = DMat3::from_rotation_y(0.7) * DMat3::from_rotation_x(-0.4);
        let e = Quadric::ellipsoid(DVec3::new(1.0, 2.0, -1.0), DVec3::new(0.5, 1.5, 0.2), rot);
        let (c, r) = e.positive_bounding_sphere().unwrap();
        assert!(r >= 1.5 && r < 1.6 * 3f64.sqrt(), "{r}");
        let mut rng = isolux_core::Pcg32::new(3, 1);
        for _ in 0..2000 {
            let d = isolux_core::sampling::uniform_sphere(rng.next_2d());
            let (mut lo, mut hi) = (0.0, 10.0);
            for _ in 0..80 {
                let m = 0.5 * (lo + hi);
                if e.eval(c + m * d) >= 0.0 {
                    lo = m
                } else {
                    hi = m
                }
            }
            assert!(lo <= r, "{lo} > {r}");
        }
        // Unbounded or empty positive sets have none.
        assert!(Quadric::cylinder(DVec3::ZERO, DVec3::Y, 1.0)
            .positive_bounding_sphere()
            .is_none());
        assert!(Quadric::sphere(DVec3::ZERO, 1.0)
            .scaled(-1.0)
            .positive_bounding_sphere()
            .is_none());
    }

    #[test]
    fn sphere_values_and_gradient() {
        let q = Quadric::sphere(DVec3::new(1.0, 2.0, 3.0), 2.0);
        assert!(close(q.eval(DVec3::new(1.0, 2.0, 3.0)), 4.0));
        assert!(close(q.eval(DVec3::new(3.0, 2.0, 3.0)), 0.0));
        let g = q.gradient(DVec3::new(3.0, 2.0, 3.0));
        assert!((g - DVec3::new(-4.0, 0.0, 0.0)).length() < 1e-12);
        let b = q.positive_bounds().unwrap();
        assert!((b.min - DVec3::new(-1.0, 0.0, 1.0)).length() < 1e-6);
        assert!((b.max - DVec3::new(3.0, 4.0, 5.0)).length() < 1e-6);
    }

    #[test]
    fn coefficient_round_trip() {
        let q = Quadric::ellipsoid(
            DVec3::new(0.1, 0.2, 0.3),
            DVec3::new(1.0, 2.0, 0.5),
            DMat3::from_rotation_y(0.3) * DMat3::from_rotation_x(0.7),
        );
        let r = Quadric::from_coefficients(q.coefficients());
        let p = DVec3::new(0.3, -0.4, 0.9);
        assert!(close(q.eval(p), r.eval(p)));
    }

    #[test]
    fn equal_radius_ellipsoid_is_sphere() {
        let c = DVec3::new(0.5, -1.0, 2.0);
        let e = Quadric::ellipsoid(c, DVec3::splat(0.7), DMat3::from_rotation_z(1.0));
        let s = Quadric::sphere(c, 0.7);
        for p in [DVec3::ZERO, DVec3::new(1.0, 2.0, 3.0), c] {
            assert!(close(e.eval(p), s.eval(p)));
        }
    }

    #[test]
    fn rotated_ellipsoid_surface_points() {
        let rot = DMat3::from_rotation_z(PI / 4.0);
        let c = DVec3::new(1.0, 0.0, 0.0);
        let e = Quadric::ellipsoid(c, DVec3::new(2.0, 1.0, 0.5), rot);
        // The first semi-axis points along (1,1,0)/sqrt2 with length 2.
        let p = c + rot * DVec3::new(2.0, 0.0, 0.0);
        assert!(close(e.eval(p), 0.0));
        assert!(e.eval(c) > 0.0);
        let b = e.positive_bounds().unwrap();
        assert!(b.contains(p) && b.contains(c + rot * DVec3::new(0.0, -1.0, 0.0)));
    }

    /// Thin ellipsoids, axis-aligned and turned, down to a disc 1e-6
    /// thick: bounded, and every point of the surface inside the box
    /// (points from the parameterization, an independent computation).
    #[test]
    fn thin_ellipsoids_keep_their_boxes() {
        for thin in [1e-2, 1e-4, 1e-6, 1e-8] {
            for rot in [
                DMat3::IDENTITY,
                DMat3::from_rotation_x(0.7) * DMat3::from_rotation_y(-0.4),
            ] {
                let c = DVec3::new(0.75, -0.2, 0.3);
                let radii = DVec3::new(0.45, 0.6, thin);
                let e = Quadric::ellipsoid(c, radii, rot);
                let Some(b) = e.positive_bounds() else {
                    // Too thin off the axes to bound in f64: unbounded,
                    // which is safe. Along the axes, never.
                    assert!(
                        rot != DMat3::IDENTITY && thin < 1e-3,
                        "radius {thin}: no box"
                    );
                    continue;
                };
                // The exact half extents, |row i of rot diag(radii)|: met
                // within 1e-3 along the axes (the box is padded by the
                // rounding of the disc's coefficients, 1e12 and its
                // products with the centre); a turned thin disc's box also
                // by its inverse's rounding, and stays within 2x, as does
                // a disc 1e-8 thick, whose coefficient 1e16 leaves its
                // constant term barely resolved.
                let aligned = rot == DMat3::IDENTITY;
                for i in 0..3 {
                    let half = (rot.row(i) * radii).length();
                    let (lo, hi) = (c[i] - b.min[i], b.max[i] - c[i]);
                    for side in [lo, hi] {
                        let ok = if aligned && thin >= 1e-6 {
                            side >= half && side < (1.0 + 1e-3) * half + 1e-11
                        } else {
                            side >= half && side < 2.0 * half + 1e-9
                        };
                        assert!(ok, "radius {thin}, axis {i}: [{lo}, {hi}] against {half}");
                    }
                }
                for k in 0..400 {
                    let (u, v) = (k as f64 * 0.618_034 % 1.0, (k as f64 + 0.5) / 400.0);
                    let (phi, cos_t) = (2.0 * PI * u, 1.0 - 2.0 * v);
                    let sin_t = (1.0 - cos_t * cos_t).sqrt();
                    let local = DVec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t);
                    let p = c + rot * (local * radii);
                    assert!(b.contains(p), "radius {thin}: {p} outside {b:?}");
                }
            }
        }
        // A long ellipsoid along an axis is bounded, however long; the
        // degenerate ones still have no box: a cylinder along an axis (a
        // zero on the diagonal) and one turned off the axes (a determinant
        // within rounding of zero).
        let long = Quadric::ellipsoid(DVec3::ZERO, DVec3::new(1.0, 1.0, 1e9), DMat3::IDENTITY);
        let b = long.positive_bounds().expect("a long ellipsoid is bounded");
        assert!(
            b.max.z >= 1e9 && b.max.z < 1.001e9 && b.max.x < 1.001,
            "{b:?}"
        );
        assert!(Quadric::cylinder(DVec3::ZERO, DVec3::Y, 0.5)
            .positive_bounds()
            .is_none());
        let turned = Quadric::cylinder(DVec3::ZERO, DVec3::new(1.0, 2.0, 3.0).normalize(), 0.5);
        assert!(turned.positive_bounds().is_none());
    }

    #[test]
    fn other_constructors_are_positive_inside() {
        let cyl = Quadric::cylinder(DVec3::ZERO, DVec3::Y, 1.0);
        assert!(cyl.eval(DVec3::new(0.5, 100.0, 0.0)) > 0.0);
        assert!(close(cyl.eval(DVec3::new(1.0, -7.0, 0.0)), 0.0));
        assert!(cyl.positive_bounds().is_none());
        let cone = Quadric::cone(DVec3::ZERO, DVec3::Z, PI / 4.0);
        assert!(close(cone.eval(DVec3::new(2.0, 0.0, 2.0)), 0.0));
        assert!(cone.eval(DVec3::new(0.0, 0.0, 1.0)) > 0.0);
        let par = Quadric::paraboloid(DVec3::ZERO, DVec3::Y, 0.25);
        assert!(close(par.eval(DVec3::new(1.0, 1.0, 0.0)), 0.0)); // y = x^2
        assert!(par.eval(DVec3::new(0.0, 1.0, 0.0)) > 0.0);
        let pl = Quadric::plane(DVec3::new(0.0, 1.0, 0.0), DVec3::Y);
        assert!(pl.eval(DVec3::ZERO) > 0.0 && pl.eval(DVec3::new(0.0, 2.0, 0.0)) < 0.0);
        // Outward normal = -grad.
        assert!((-pl.gradient(DVec3::ZERO)).normalize().dot(DVec3::Y) > 0.999);
    }

    #[test]
    fn transform_moves_surface() {
        let s = Quadric::sphere(DVec3::ZERO, 1.0);
        let t = DMat4::from_scale_rotation_translation(
            DVec3::new(2.0, 1.0, 1.0),
            glam::DQuat::from_rotation_z(0.5),
            DVec3::new(3.0, 0.0, 0.0),
        );
        let m = s.transformed(&t);
        for p in [DVec3::X, DVec3::Y, DVec3::new(0.6, 0.8, 0.0)] {
            assert!(close(m.eval(t.transform_point3(p)), 0.0));
        }
        assert!(m.eval(DVec3::new(3.0, 0.0, 0.0)) > 0.0);
    }

    #[test]
    fn along_matches_eval() {
        let q = Quadric::ellipsoid(
            DVec3::ONE,
            DVec3::new(1.0, 2.0, 3.0),
            DMat3::from_rotation_x(0.4),
        );
        let r = Ray::new(DVec3::new(-2.0, 0.5, 0.1), DVec3::new(0.3, 0.2, -0.9));
        let [c, b, a] = q.along(&r);
        for t in [-1.0, 0.0, 0.7, 3.0] {
            assert!(close(a * t * t + b * t + c, q.eval(r.at(t))));
        }
    }
}
