//! Monte Carlo warps from the unit square and their densities.

use crate::{INV_4PI, INV_PI, PI};
use glam::{DVec2, DVec3};

/// Concentric map of the unit square onto the unit disk (Shirley-Chiu),
/// area-preserving up to the constant pi.
pub fn concentric_disk(u: [f64; 2]) -> DVec2 {
    let ox = 2.0 * u[0] - 1.0;
    let oy = 2.0 * u[1] - 1.0;
    if ox == 0.0 && oy == 0.0 {
        return DVec2::ZERO;
    }
    let (r, theta) = if ox.abs() > oy.abs() {
        (ox, PI / 4.0 * (oy / ox))
    } else {
        (oy, PI / 2.0 - PI / 4.0 * (ox / oy))
    };
    DVec2::new(r * theta.cos(), r * theta.sin())
}

/// Cosine-weighted direction on the `z >= 0` hemisphere (Malley's method).
pub fn cosine_hemisphere(u: [f64; 2]) -> DVec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    DVec3::new(d.x, d.y, z)
}

/// Density of [`cosine_hemisphere`] in solid angle: `cos(theta) / pi`.
#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f64) -> f64 {
    cos_theta.max(0.0) * INV_PI
}

/// Uniform direction on the unit sphere.
pub fn uniform_sphere(u: [f64; 2]) -> DVec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u[1];
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Density of [`uniform_sphere`]: `1 / (4 pi)`.
#[inline]
pub fn uniform_sphere_pdf() -> f64 {
    INV_4PI
}

/// Power heuristic with exponent 2 (Veach 1997) for one sample of each of
/// two strategies.
#[inline]
pub fn power_heuristic(pdf_a: f64, pdf_b: f64) -> f64 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a == 0.0 {
        return 0.0;
    }
    if a.is_infinite() {
        return 1.0;
    }
    a / (a + b)
}

/// Equiangular sampling of a distance `t` on a ray segment `[0, t_end)`
/// toward a point (Kulla and Fajardo, "Importance Sampling Techniques for
/// Path Tracing in Participating Media", EGSR 2012): the density is
/// proportional to `1 / d(t)^2`, the inverse square distance from the ray
/// point at `t` to the point, so that the light of a point source scattered
/// along the ray is sampled without its `1 / d^2` spike:
///
/// `pdf(t) = D / ((theta_b - theta_a) (D^2 + (t - delta)^2))`,
/// `t = delta + D tan(theta_a + u (theta_b - theta_a))`,
///
/// where `delta` is the point's projection on the ray, `D` its distance
/// from the ray's line and `theta_a`, `theta_b` the angles under which the
/// segment's ends are seen from it. `t_end` may be infinite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Equiangular {
    delta: f64,
    dist: f64,
    theta_a: f64,
    theta_b: f64,
}

impl Equiangular {
    /// The sampler for the segment `[0, t_end)` of the ray from `origin`
    /// along the unit vector `dir`, toward `point`; `None` where the point
    /// lies on the ray's line (closer than `1e-9` of its distance) or the
    /// segment is empty, and the density is not defined.
    pub fn new(origin: DVec3, dir: DVec3, t_end: f64, point: DVec3) -> Option<Self> {
        let to = point - origin;
        let delta = to.dot(dir);
        let dist = (to - delta * dir).length();
        if !(t_end > 0.0) || !(dist > 1e-9 * to.length()) || !dist.is_finite() {
            return None;
        }
        let theta_a = (-delta / dist).atan();
        let theta_b = ((t_end - delta) / dist).atan();
        (theta_b > theta_a).then_some(Equiangular {
            delta,
            dist,
            theta_a,
            theta_b,
        })
    }

    /// A distance for `u` in `[0, 1)` and its density; `None` where the
    /// warp rounds outside the segment.
    pub fn sample(&self, u: f64) -> Option<(f64, f64)> {
        let theta = self.theta_a + u * (self.theta_b - self.theta_a);
        let t = self.delta + self.dist * theta.tan();
        let pdf = self.pdf(t);
        (t.is_finite() && t >= 0.0 && pdf > 0.0 && pdf.is_finite()).then_some((t, pdf))
    }

    /// The density of distance `t` (inside the segment).
    pub fn pdf(&self, t: f64) -> f64 {
        let x = t - self.delta;
        self.dist / ((self.theta_b - self.theta_a) * (self.dist * self.dist + x * x))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Pcg32;

    #[test]
    fn cosine_hemisphere_moments() {
        // E[cos theta] under cos/pi is 2/3; every sample is unit length.
        let mut r = Pcg32::new(9, 9);
        let n = 100_000;
        let mut m = 0.0;
        for _ in 0..n {
            let d = cosine_hemisphere(r.next_2d());
            assert!((d.length() - 1.0).abs() < 1e-12 && d.z >= 0.0);
            m += d.z;
        }
        m /= n as f64;
        assert!((m - 2.0 / 3.0).abs() < 4e-3, "{m}");
    }

    #[test]
    fn uniform_sphere_is_centred() {
        let mut r = Pcg32::new(5, 1);
        let n = 100_000;
        let mut s = DVec3::ZERO;
        for _ in 0..n {
            s += uniform_sphere(r.next_2d());
        }
        assert!((s / n as f64).length() < 0.01);
    }

    /// The equiangular density integrates to one over its segment (dense
    /// midpoint quadrature), and its samples fall into bins as it says
    /// (chi-square, 20 bins of equal probability under the density's
    /// integral computed by quadrature, not by its inverse).
    #[test]
    fn equiangular_density_and_samples_agree() {
        let cases = [
            (DVec3::ZERO, DVec3::Z, 3.0, DVec3::new(0.2, 0.0, 1.0)),
            (DVec3::ZERO, DVec3::Z, 2.0, DVec3::new(0.0, 0.01, 2.5)),
            (
                DVec3::new(1.0, 2.0, 3.0),
                DVec3::X,
                0.5,
                DVec3::new(-1.0, 2.0, 4.0),
            ),
            (DVec3::ZERO, DVec3::Z, 5.0, DVec3::new(0.001, 0.0, 0.3)),
        ];
        for (o, d, t_end, light) in cases {
            let e = Equiangular::new(o, d, t_end, light).unwrap();
            // Quadrature of the pdf: one, and the cumulative at fine steps.
            let n = 400_000;
            let h = t_end / n as f64;
            let mut cdf = vec![0.0; n + 1];
            for i in 0..n {
                cdf[i + 1] = cdf[i] + e.pdf((i as f64 + 0.5) * h) * h;
            }
            assert!((cdf[n] - 1.0).abs() < 1e-5, "{} for {light}", cdf[n]);
            // Bin edges of equal probability from the quadrature.
            let bins = 20;
            let mut edges = vec![0.0];
            let mut i = 0;
            for b in 1..bins {
                let target = b as f64 / bins as f64 * cdf[n];
                while cdf[i + 1] < target {
                    i += 1;
                }
                edges.push((i as f64 + 1.0) * h);
            }
            edges.push(t_end);
            let mut r = crate::Pcg32::new(17, 3);
            let samples = 40_000;
            let mut count = vec![0.0f64; bins];
            for _ in 0..samples {
                let (t, pdf) = e.sample(r.next_f64()).unwrap();
                assert!((0.0..=t_end).contains(&t));
                assert!((pdf / e.pdf(t) - 1.0).abs() < 1e-12);
                let b = edges.partition_point(|&x| x <= t).clamp(1, bins) - 1;
                count[b] += 1.0;
            }
            let expected = samples as f64 / bins as f64;
            let chi2: f64 = count
                .iter()
                .map(|c| (c - expected).powi(2) / expected)
                .sum();
            // 19 degrees of freedom: p = 1e-4 at 49.
            assert!(chi2 < 49.0, "chi2 {chi2} for {light}");
        }
        // On the line, or an empty segment: no density.
        assert!(Equiangular::new(DVec3::ZERO, DVec3::Z, 1.0, DVec3::Z * 0.5).is_none());
        assert!(Equiangular::new(DVec3::ZERO, DVec3::Z, 0.0, DVec3::X).is_none());
        // An infinite segment: samples stay finite and beyond zero.
        let e = Equiangular::new(DVec3::ZERO, DVec3::Z, f64::INFINITY, DVec3::X).unwrap();
        let mut r = crate::Pcg32::new(1, 1);
        for _ in 0..1000 {
            if let Some((t, p)) = e.sample(r.next_f64()) {
                assert!(t.is_finite() && t >= 0.0 && p > 0.0);
            }
        }
    }
}
