//! # Diffuse (Lambertian) reflection
//!
//! An ideal matte surface scatters equally into all directions of the
//! upper hemisphere:
//!
//! ```text
//! f(wo, wi) = R / pi      for wo.z > 0 and wi.z > 0, else 0
//! ```
//!
//! Its directional albedo `int f cos dwi = R` for every `wo`, so
//! `reflectance <= 1` conserves energy. Sampling is cosine-weighted
//! (`pdf = cos(theta_i) / pi`), which makes `f cos / pdf = R` exactly: a
//! diffuse surface under uniform light renders without noise.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `reflectance` | RGB in `[0, 1]` | `[0.5, 0.5, 0.5]` | albedo `R` |
//!
//! Source: J. H. Lambert, *Photometria* (1760); pbrt-v4 §9.2.
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "chalk"
//! type = "diffuse"
//! reflectance = [0.8, 0.8, 0.75]
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! let m = &doc["material"].as_array().unwrap()[0];
//! assert_eq!(m["type"].as_str(), Some("diffuse"));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use isolux_core::{sampling, DVec3, Rgb, INV_PI};

/// Lambertian reflector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diffuse {
    /// Albedo `R`.
    pub reflectance: Rgb,
}

impl Default for Diffuse {
    fn default() -> Self {
        Self {
            reflectance: Rgb::splat(0.5),
        }
    }
}

impl BxdfModel for Diffuse {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z > 0.0 && wi.z > 0.0 {
            self.reflectance * INV_PI
        } else {
            Rgb::BLACK
        }
    }

    fn sample(&self, wo: DVec3, _uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = sampling::cosine_hemisphere(u);
        if wi.z <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            f: self.reflectance * INV_PI,
            pdf: sampling::cosine_hemisphere_pdf(wi.z),
            flags: BxdfFlags::REFLECTION | BxdfFlags::DIFFUSE,
            eta: 1.0,
        })
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z > 0.0 && wi.z > 0.0 {
            sampling::cosine_hemisphere_pdf(wi.z)
        } else {
            0.0
        }
    }

    fn flags(&self) -> BxdfFlags {
        BxdfFlags::REFLECTION | BxdfFlags::DIFFUSE
    }

    fn albedo(&self) -> Rgb {
        self.reflectance
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use isolux_core::Pcg32;

    #[test]
    fn albedo_equals_reflectance_and_weight_is_exact() {
        let d = Diffuse {
            reflectance: Rgb::new(0.2, 0.5, 0.9),
        };
        let wo = DVec3::new(0.3, 0.1, 0.9).normalize();
        let mut rng = Pcg32::new(4, 4);
        // Uniform-hemisphere estimate of int f cos: independent of the sampler.
        let n = 200_000;
        let mut est = Rgb::BLACK;
        for _ in 0..n {
            let mut w = sampling::uniform_sphere(rng.next_2d());
            w.z = w.z.abs();
            est += d.f(wo, w) * (w.z * 2.0 * std::f64::consts::PI);
        }
        est = est / n as f64;
        assert!((est.b - 0.9).abs() < 0.01, "{est:?}");
        for _ in 0..1000 {
            let s = d.sample(wo, rng.next_f64(), rng.next_2d()).unwrap();
            let w = s.weight(s.wi.z);
            assert!((w.g - 0.5).abs() < 1e-12);
            assert!((s.pdf - d.pdf(wo, s.wi)).abs() < 1e-12);
        }
    }

    #[test]
    fn reciprocal_and_one_sided() {
        let d = Diffuse::default();
        let a = DVec3::new(0.1, 0.2, 0.97).normalize();
        let b = DVec3::new(-0.5, 0.3, 0.8).normalize();
        assert_eq!(d.f(a, b), d.f(b, a));
        assert!(d.f(a, -b).is_black());
    }
}
