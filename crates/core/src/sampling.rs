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
}
