//! # Phong (energy-conserving, Lafortune-Willems normalization)
//!
//! The seed's Phong highlight `(r . wo)^n`, `r` the mirror direction,
//! made a BRDF over a Lambertian base:
//!
//! ```text
//! f(wo, wi) = R / pi + k_s (n + 2) / (2 pi) max(0, r . wi)^n,   r = reflect(wo)
//! ```
//!
//! **Normalization.** `(n + 2) / (2 pi)` makes the lobe's directional albedo
//! exactly 1 at normal incidence and less elsewhere (the lobe is clipped by
//! the horizon and weighted by `cos(theta_i) <= (r . wi)` there), so with
//! `reflectance + specular <= 1` the model never reflects more than it
//! receives (Lafortune and Willems 1994). Reciprocal, since
//! `reflect(wo) . wi = reflect(wi) . wo`. The lobe is sampled exactly:
//! `cos(alpha) = u^(1/(n+1))` around `r`, density `(n+1)/(2 pi) cos^n alpha`.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `exponent` | number >= 0 | `32` | Phong exponent `n` |
//! | `specular` | RGB in [0, 1] | `[0.5, 0.5, 0.5]` | lobe weight `k_s` |
//! | `reflectance` | RGB in [0, 1] | `[0, 0, 0]` | diffuse albedo `R` (`R + k_s <= 1`) |
//!
//! Sources: B. T. Phong, "Illumination for Computer Generated Pictures",
//! CACM 18(6), 1975; E. Lafortune and Y. Willems, "Using the Modified Phong
//! Reflectance Model for Physically Based Rendering", KU Leuven CW197, 1994;
//! seed 002.
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "plastic_ball"
//! type = "phong"
//! exponent = 60
//! specular = [0.3, 0.3, 0.3]
//! reflectance = [0.5, 0.1, 0.1]
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["exponent"].as_integer(), Some(60));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::lobe::{around, DiffuseLobe, Lobe};
use isolux_core::{DVec3, Rgb, PI};

/// The normalized Phong lobe around the mirror direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhongLobe {
    /// Exponent `n`.
    pub exponent: f64,
}

fn mirror(wo: DVec3) -> DVec3 {
    DVec3::new(-wo.x, -wo.y, wo.z)
}

impl Lobe for PhongLobe {
    fn eval(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let c = mirror(wo).dot(wi);
        if c <= 0.0 {
            return 0.0;
        }
        (self.exponent + 2.0) / (2.0 * PI) * c.powf(self.exponent)
    }
    fn sample(&self, wo: DVec3, u: [f64; 2]) -> Option<DVec3> {
        let cos_a = u[0].powf(1.0 / (self.exponent + 1.0));
        Some(around(mirror(wo), cos_a, 2.0 * PI * u[1]))
    }
    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        let c = mirror(wo).dot(wi);
        if c <= 0.0 {
            return 0.0;
        }
        (self.exponent + 1.0) / (2.0 * PI) * c.powf(self.exponent)
    }
}

/// Phong over a Lambertian base.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phong(pub DiffuseLobe<PhongLobe>);

impl Phong {
    /// A Phong material.
    pub fn new(exponent: f64, specular: Rgb, reflectance: Rgb) -> Self {
        Self(DiffuseLobe {
            reflectance,
            specular,
            lobe: PhongLobe { exponent },
        })
    }
}

impl BxdfModel for Phong {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        self.0.f(wo, wi)
    }
    fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        self.0.sample(wo, uc, u)
    }
    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        self.0.pdf(wo, wi)
    }
    fn flags(&self) -> BxdfFlags {
        self.0.flags()
    }
    fn albedo(&self) -> Rgb {
        self.0.reflectance + self.0.specular
    }
}
