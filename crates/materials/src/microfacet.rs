//! Microfacet distributions shared by the rough models.
//!
//! Local frame: `z` is the macro normal, `x` the tangent. With roughness
//! `alpha_x`, `alpha_y` (equal for isotropic surfaces):
//!
//! | | GGX / Trowbridge-Reitz | Beckmann |
//! |---|---|---|
//! | `D(m)` | `1 / (pi ax ay cos^4 (1 + tan^2 (cos^2 phi/ax^2 + sin^2 phi/ay^2))^2)` | `exp(-tan^2 (cos^2 phi/ax^2 + sin^2 phi/ay^2)) / (pi ax ay cos^4)` |
//! | `Lambda(w)` | `(sqrt(1 + a^2 tan^2) - 1) / 2` | `(erf(c) - 1)/2 + exp(-c^2)/(2 c sqrt(pi))`, `c = 1/(a tan)` |
//!
//! with `a^2 = cos^2 phi ax^2 + sin^2 phi ay^2` the roughness in the
//! direction of `w`. Both `D` are normalized: `int D(m) cos(theta_m) dm = 1`.
//! Masking-shadowing is Smith's height-correlated form
//! `G(wo, wi) = 1 / (1 + Lambda(wo) + Lambda(wi))`.
//!
//! **Sampling** draws the normals *visible* from `wo`, with density
//! `D_wo(m) = G1(wo) max(0, wo.m) D(m) / cos(theta_o)`: GGX by Heitz,
//! "Sampling the GGX Distribution of Visible Normals" (JCGT 2018); Beckmann
//! by the slope-space method of Heitz and d'Eon, "Importance Sampling
//! Microfacet-Based BSDFs using the Distribution of Visible Normals" (EGSR
//! 2014), inverting the visible-slope CDF by safeguarded Newton iteration
//! in slope space.
//! Both remove the samples a plain `D(m) cos` sampler wastes on back-facing
//! normals.
//!
//! Sources: Walter, Marschner, Li, Torrance, "Microfacet Models for
//! Refraction through Rough Surfaces" (EGSR 2007); Heitz, "Understanding the
//! Masking-Shadowing Function in Microfacet-Based BRDFs" (JCGT 2014).

use isolux_core::{DVec3, PI};

/// The shape of the microfacet normal distribution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Trowbridge-Reitz (GGX).
    Ggx,
    /// Beckmann-Spizzichino.
    Beckmann,
}

/// A microfacet distribution with roughness along `x` and `y`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    /// Distribution shape.
    pub kind: Kind,
    /// Roughness along the tangent.
    pub alpha_x: f64,
    /// Roughness along the bitangent.
    pub alpha_y: f64,
}

const SQRT_PI_INV: f64 = 0.564_189_583_547_756_3;

impl Microfacet {
    /// An isotropic distribution.
    pub fn isotropic(kind: Kind, alpha: f64) -> Self {
        Self {
            kind,
            alpha_x: alpha,
            alpha_y: alpha,
        }
    }

    /// `D(m)` (1/sr), zero for `m.z <= 0`.
    pub fn d(&self, m: DVec3) -> f64 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let cos2 = m.z * m.z;
        // tan^2 (cos^2 phi / ax^2 + sin^2 phi / ay^2) = (mx^2/ax^2 + my^2/ay^2) / mz^2
        let e = (m.x * m.x / (self.alpha_x * self.alpha_x)
            + m.y * m.y / (self.alpha_y * self.alpha_y))
            / cos2;
        let cos4 = cos2 * cos2;
        match self.kind {
            Kind::Ggx => 1.0 / (PI * self.alpha_x * self.alpha_y * cos4 * (1.0 + e) * (1.0 + e)),
            Kind::Beckmann => (-e).exp() / (PI * self.alpha_x * self.alpha_y * cos4),
        }
    }

    /// Smith's `Lambda(w)`.
    pub fn lambda(&self, w: DVec3) -> f64 {
        if w.z == 0.0 {
            return f64::INFINITY;
        }
        // a^2 tan^2 = (ax^2 wx^2 + ay^2 wy^2) / wz^2
        let at2 = (self.alpha_x * self.alpha_x * w.x * w.x
            + self.alpha_y * self.alpha_y * w.y * w.y)
            / (w.z * w.z);
        match self.kind {
            Kind::Ggx => 0.5 * ((1.0 + at2).sqrt() - 1.0),
            Kind::Beckmann => {
                if at2 == 0.0 {
                    return 0.0;
                }
                let c = 1.0 / at2.sqrt();
                0.5 * (-libm::erfc(c) + (-c * c).exp() * SQRT_PI_INV / c)
            }
        }
    }

    /// Smith masking `G1(w) = 1 / (1 + Lambda(w))`.
    pub fn g1(&self, w: DVec3) -> f64 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking-shadowing `G(wo, wi)`.
    pub fn g(&self, wo: DVec3, wi: DVec3) -> f64 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Density of visible normals `D_w(m)` for `w` in the upper hemisphere.
    pub fn d_visible(&self, w: DVec3, m: DVec3) -> f64 {
        if w.z <= 0.0 {
            return 0.0;
        }
        self.g1(w) / w.z * self.d(m) * w.dot(m).max(0.0)
    }

    /// Samples a normal visible from `w` (`w.z > 0`), density
    /// [`Microfacet::d_visible`].
    pub fn sample_visible(&self, w: DVec3, u: [f64; 2]) -> DVec3 {
        match self.kind {
            Kind::Ggx => self.sample_ggx(w, u),
            Kind::Beckmann => self.sample_beckmann(w, u),
        }
    }

    fn sample_ggx(&self, w: DVec3, u: [f64; 2]) -> DVec3 {
        // Stretch to the hemisphere configuration, sample the projected
        // disk warped toward the visible half, unstretch.
        let vh = DVec3::new(self.alpha_x * w.x, self.alpha_y * w.y, w.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 {
            DVec3::new(-vh.y, vh.x, 0.0) / len2.sqrt()
        } else {
            DVec3::X
        };
        let t2 = vh.cross(t1);
        let r = u[0].sqrt();
        let phi = 2.0 * PI * u[1];
        let p1 = r * phi.cos();
        let mut p2 = r * phi.sin();
        let s = 0.5 * (1.0 + vh.z);
        p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        DVec3::new(self.alpha_x * nh.x, self.alpha_y * nh.y, nh.z.max(1e-9)).normalize()
    }

    fn sample_beckmann(&self, w: DVec3, u: [f64; 2]) -> DVec3 {
        let ws = DVec3::new(self.alpha_x * w.x, self.alpha_y * w.y, w.z).normalize();
        let theta = ws.z.clamp(-1.0, 1.0).acos();
        let phi = ws.y.atan2(ws.x);
        let (sx, sy) = beckmann_visible_slopes(theta, u);
        let (sp, cp) = phi.sin_cos();
        let (rx, ry) = (cp * sx - sp * sy, sp * sx + cp * sy);
        DVec3::new(-rx * self.alpha_x, -ry * self.alpha_y, 1.0).normalize()
    }
}

/// Slopes of the unit-roughness Beckmann distribution visible from the
/// elevation `theta` (in the `x z` plane): the `x` slope inverts the
/// visible-slope CDF by safeguarded Newton in slope space; the `y` slope
/// is Gaussian.
fn beckmann_visible_slopes(theta: f64, u: [f64; 2]) -> (f64, f64) {
    let u1 = u[0].clamp(1e-12, 1.0 - 1e-12);
    let u2 = u[1].clamp(1e-12, 1.0 - 1e-12);
    if theta < 1e-4 {
        let r = (-(1.0 - u1).ln()).sqrt();
        let (s, c) = (2.0 * PI * u2).sin_cos();
        return (r * c, r * s);
    }
    let tan_t = theta.tan();
    let cot_t = 1.0 / tan_t;
    // CDF of the visible x-slope (x < cot):
    // C(x) = norm (1 + erf(x) + tan/sqrt(pi) exp(-x^2)),
    // C'(x) = norm 2/sqrt(pi) exp(-x^2) (1 - x tan) > 0.
    // Safeguarded Newton directly in x (one erfc and one exp per step);
    // 1 + erf(x) is computed as erfc(-x), exact in the left tail.
    let norm = 1.0 / (1.0 + libm::erf(cot_t) + SQRT_PI_INV * tan_t * (-cot_t * cot_t).exp());
    let cdf = |x: f64| norm * (libm::erfc(-x) + SQRT_PI_INV * tan_t * (-x * x).exp());
    // Initial guess from a fit of the inverse (see Jakob's Mitsuba notes).
    let fit = 1.0 + theta * (-0.876 + theta * (0.4265 - 0.0594 * theta));
    let c = libm::erf(cot_t);
    let b0 = c - (1.0 + c) * (1.0 - u1).powf(fit);
    let (mut lo, mut hi) = (-8.0f64, cot_t);
    let mut x = erfinv(b0).clamp(lo, hi);
    for _ in 0..100 {
        let value = cdf(x) - u1;
        if value.abs() < 1e-14 {
            break;
        }
        if value > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        let deriv = norm * 2.0 * SQRT_PI_INV * (-x * x).exp() * (1.0 - x * tan_t);
        let next = x - value / deriv;
        x = if deriv > 0.0 && next > lo && next < hi {
            next
        } else {
            0.5 * (lo + hi)
        };
        if hi - lo < 1e-15 * (1.0 + x.abs()) {
            break;
        }
    }
    (x, erfinv(2.0 * u2 - 1.0))
}

/// Inverse error function on `(-1, 1)`: Giles' approximation ("Approximating
/// the erfinv function", GPU Computing Gems, 2010) polished by four Newton
/// steps on `erf` (on `erfc` in the tails, where `erf(y) - x` cancels) to
/// double precision.
pub fn erfinv(x: f64) -> f64 {
    if x <= -1.0 {
        return f64::NEG_INFINITY;
    }
    if x >= 1.0 {
        return f64::INFINITY;
    }
    let mut w = -((1.0 - x) * (1.0 + x)).ln();
    let mut p;
    if w < 5.0 {
        w -= 2.5;
        p = 2.810_226_36e-08;
        p = 3.432_739_39e-07 + p * w;
        p = -3.523_387_7e-06 + p * w;
        p = -4.391_506_54e-06 + p * w;
        p = 0.000_218_580_87 + p * w;
        p = -0.001_253_725_03 + p * w;
        p = -0.004_177_681_64 + p * w;
        p = 0.246_640_727 + p * w;
        p = 1.501_409_41 + p * w;
    } else {
        w = w.sqrt() - 3.0;
        p = -0.000_200_214_257;
        p = 0.000_100_950_558 + p * w;
        p = 0.001_349_343_22 + p * w;
        p = -0.003_673_428_44 + p * w;
        p = 0.005_739_507_73 + p * w;
        p = -0.007_622_461_3 + p * w;
        p = 0.009_438_870_47 + p * w;
        p = 1.001_674_06 + p * w;
        p = 2.832_976_82 + p * w;
    }
    let mut y = p * x;
    for _ in 0..4 {
        // In the tails erf(y) - x cancels; (1 - |x|) - erfc(|y|) is exact.
        let err = if x.abs() > 0.5 {
            x.signum() * ((1.0 - x.abs()) - libm::erfc(y.abs()))
        } else {
            libm::erf(y) - x
        };
        let d = 2.0 * SQRT_PI_INV * (-y * y).exp();
        if d > 0.0 {
            y -= err / d;
        }
    }
    y
}

/// A rough reflector: `f = D(m) G(wo, wi) F(wo.m) / (4 cos_o cos_i)` with
/// `m = normalize(wo + wi)` (Walter et al. 2007), sampled through the
/// visible normals of `wo`. Shared by the `ggx` and `beckmann` models.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MicrofacetReflection {
    /// Normal distribution.
    pub distribution: Microfacet,
    /// Fresnel term at the microfacet.
    pub fresnel: crate::Fresnel,
}

impl MicrofacetReflection {
    /// `f(wo, wi)` without the cosine.
    pub fn f(&self, wo: DVec3, wi: DVec3) -> isolux_core::Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return isolux_core::Rgb::BLACK;
        }
        let Some(m) = (wo + wi).try_normalize() else {
            return isolux_core::Rgb::BLACK;
        };
        let d = self.distribution.d(m);
        let g = self.distribution.g(wo, wi);
        self.fresnel.eval(wo.dot(m)) * (d * g / (4.0 * wo.z * wi.z))
    }

    /// Visible-normal sampling.
    pub fn sample(&self, wo: DVec3, u: [f64; 2]) -> Option<crate::BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let m = self.distribution.sample_visible(wo, u);
        let wi = reflect(wo, m);
        if wi.z <= 0.0 {
            return None;
        }
        let pdf = self.pdf(wo, wi);
        Some(crate::BsdfSample {
            wi,
            f: self.f(wo, wi),
            pdf,
            flags: crate::BxdfFlags::REFLECTION | crate::BxdfFlags::GLOSSY,
            eta: 1.0,
        })
    }

    /// `D_wo(m) / (4 |wo.m|)`.
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let Some(m) = (wo + wi).try_normalize() else {
            return 0.0;
        };
        self.distribution.d_visible(wo, m) / (4.0 * wo.dot(m).abs())
    }
}

/// Mirror `w` about `m`.
#[inline]
pub fn reflect(w: DVec3, m: DVec3) -> DVec3 {
    2.0 * w.dot(m) * m - w
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::validate::{chi2_test, sidak};
    use isolux_core::{sampling, Pcg32};

    fn dists() -> Vec<Microfacet> {
        let mut v = vec![];
        for kind in [Kind::Ggx, Kind::Beckmann] {
            for (ax, ay) in [(0.1, 0.1), (0.3, 0.3), (0.8, 0.8), (0.1, 0.5)] {
                v.push(Microfacet {
                    kind,
                    alpha_x: ax,
                    alpha_y: ay,
                });
            }
        }
        v
    }

    /// int f(m) dm over the upper hemisphere, fine midpoint rule in
    /// (cos theta, phi), refined near the pole where narrow lobes live.
    fn integrate(f: impl Fn(DVec3) -> f64) -> f64 {
        let (nz, np) = (4000, 256);
        let mut s = 0.0;
        for i in 0..nz {
            // z = 1 - t^2 concentrates samples near the pole; dz = 2t dt.
            let t = (i as f64 + 0.5) / nz as f64;
            let z = 1.0 - t * t;
            let r = (1.0 - z * z).max(0.0).sqrt();
            for j in 0..np {
                let phi = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
                s += f(DVec3::new(r * phi.cos(), r * phi.sin(), z)) * 2.0 * t;
            }
        }
        s / nz as f64 * 2.0 * PI / np as f64
    }

    #[test]
    fn distributions_are_normalized() {
        for d in dists() {
            let v = integrate(|m| d.d(m) * m.z);
            assert!((v - 1.0).abs() < 2e-3, "{d:?}: {v}");
        }
    }

    #[test]
    fn visible_normals_are_normalized() {
        for d in dists() {
            for theta in [0.0f64, 0.7, 1.4] {
                let w = DVec3::new(theta.sin() * 0.6, theta.sin() * 0.8, theta.cos());
                let v = integrate(|m| d.d_visible(w, m));
                assert!((v - 1.0).abs() < 3e-3, "{d:?} theta {theta}: {v}");
            }
        }
    }

    #[test]
    fn erfinv_inverts_erf() {
        for i in -99..=99 {
            let x = i as f64 / 100.0;
            assert!((libm::erf(erfinv(x)) - x).abs() < 1e-14, "{x}");
        }
        // Deep in the tail: erfc(erfinv(x)) = 1 - x.
        let x = 1.0 - 1e-12;
        assert!((libm::erfc(erfinv(x)) / (1.0 - x) - 1.0).abs() < 1e-10);
        assert!((libm::erfc(-erfinv(-x)) / (1.0 - x) - 1.0).abs() < 1e-10);
    }

    #[test]
    fn visible_normal_sampling_matches_its_density() {
        let dists = dists();
        let thetas = [0.0f64, 0.8, 1.45];
        let tests = dists.len() * thetas.len();
        let level = sidak(tests);
        for (k, d) in dists.iter().enumerate() {
            for &theta in &thetas {
                let w = DVec3::new(theta.sin() * 0.8, theta.sin() * 0.6, theta.cos());
                let r = chi2_test(
                    |m| d.d_visible(w, m),
                    |rng: &mut Pcg32| Some(d.sample_visible(w, rng.next_2d())),
                    100_000,
                    32,
                    64,
                    k as u64 * 7 + (theta * 100.0) as u64,
                );
                assert!(r.passes(level), "{d:?} theta {theta}: {r:?}");
            }
        }
    }

    #[test]
    fn masking_limits() {
        for d in dists() {
            assert!((d.g1(DVec3::Z) - 1.0).abs() < 1e-12);
            let grazing = DVec3::new(1.0, 0.0, 1e-4).normalize();
            assert!(d.g1(grazing) < 0.01);
        }
        // Beckmann Lambda at c = 1: (erf(1) - 1)/2 + exp(-1)/(2 sqrt(pi)).
        let d = Microfacet::isotropic(Kind::Beckmann, 1.0);
        let w = DVec3::new(1.0, 0.0, 1.0).normalize(); // tan = 1
        let want = 0.5 * (libm::erf(1.0) - 1.0) + (-1.0f64).exp() / (2.0 * PI.sqrt());
        assert!((d.lambda(w) - want).abs() < 1e-14);
        let _ = sampling::uniform_sphere_pdf();
    }
}
