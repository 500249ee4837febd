//! Henyey-Greenstein phase function and single scattering.
//!
//! ```text
//! p(cos t) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos t)^(3/2))
//! ```
//!
//! normalized over the sphere (`int p dw = 1`; the seed 003 misprint
//! `1/(4 pi)` for the sphere's solid angle is `4 pi`), mean cosine `g`.
//!
//! Single scattering (seed 000 eq. 19, first term; Hanrahan and Krueger
//! 1993): light refracted in along `wi'` and out along `wo'` scatters once:
//!
//! ```text
//! f_1(wi, wo) = T(wi) T(wo) a p(wi' . wo') / (cos_i' + cos_o')
//! ```
//!
//! with `T = 1 - F` the Fresnel transmittances, `a` the (unreduced)
//! single-scattering albedo and primes for refracted directions.

use crate::dielectric::refract;
use crate::fresnel::dielectric;
use isolux_core::{DVec3, INV_4PI};

/// Henyey-Greenstein phase function of the cosine between the incoming
/// propagation direction and the scattered one.
pub fn hg(cos_t: f64, g: f64) -> f64 {
    let denom = 1.0 + g * g - 2.0 * g * cos_t;
    INV_4PI * (1.0 - g * g) / (denom * denom.max(0.0).sqrt())
}

/// Samples `cos t` from Henyey-Greenstein.
pub fn sample_hg_cos(g: f64, u: f64) -> f64 {
    if g.abs() < 1e-3 {
        return 1.0 - 2.0 * u;
    }
    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
    ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
}

/// The single-scattering BRDF of a smooth half-space (local frame, `z` the
/// outward normal, both directions above the surface).
pub fn single_scattering(wo: DVec3, wi: DVec3, albedo: f64, g: f64, eta: f64) -> f64 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    let Some((ti, _)) = refract(wi, eta) else {
        return 0.0;
    };
    let Some((to, _)) = refract(wo, eta) else {
        return 0.0;
    };
    // Light travels along -ti inside... it enters along ti (pointing down)
    // and must leave along -to reversed: the scattering angle is between
    // the propagation directions ti and -to.
    let cos_t = ti.dot(-to);
    let t = (1.0 - dielectric(wi.z, eta)) * (1.0 - dielectric(wo.z, eta));
    t * albedo * hg(cos_t, g) / (ti.z.abs() + to.z.abs())
}

#[cfg(test)]
mod tests {
    use super::*;
    use isolux_core::{Pcg32, PI};

    #[test]
    fn hg_is_normalized_with_mean_cosine_g() {
        for g in [-0.7, 0.0, 0.3, 0.9] {
            let n = 200_000;
            let (mut norm, mut mean) = (0.0, 0.0);
            for i in 0..n {
                let c = -1.0 + (i as f64 + 0.5) / n as f64 * 2.0;
                norm += hg(c, g) * 2.0 * PI * 2.0 / n as f64;
                mean += c * hg(c, g) * 2.0 * PI * 2.0 / n as f64;
            }
            assert!((norm - 1.0).abs() < 1e-4, "{g}: {norm}");
            assert!((mean - g).abs() < 1e-4, "{g}: {mean}");
            // Sampling reproduces the mean cosine.
            let mut rng = Pcg32::new(3, 3);
            let m: f64 = (0..100_000)
                .map(|_| sample_hg_cos(g, rng.next_f64()))
                .sum::<f64>()
                / 1e5;
            assert!((m - g).abs() < 0.01, "{g}: sampled mean {m}");
        }
    }

    #[test]
    fn single_scattering_is_reciprocal_and_small() {
        let a = DVec3::new(0.3, 0.1, 0.95).normalize();
        let b = DVec3::new(-0.6, 0.2, 0.77).normalize();
        let (x, y) = (
            single_scattering(a, b, 0.9, 0.3, 1.3),
            single_scattering(b, a, 0.9, 0.3, 1.3),
        );
        assert!((x - y).abs() < 1e-12 * x.abs().max(1.0));
        assert!(x > 0.0 && x < 1.0);
    }
}
