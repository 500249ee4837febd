//! # Blinn-Phong (energy-bounded)
//!
//! The seed's half-vector highlight `(n . h)^n` over a Lambertian base, in
//! the microfacet form of Ashikhmin and Shirley (2000):
//!
//! ```text
//! f(wo, wi) = R / pi + k_s D(h) / (4 (wo . h) max(cos_o, cos_i)),
//! D(h) = (n + 1) / (2 pi) (n . h)^n,   h = normalize(wo + wi)
//! ```
//!
//! **Normalization.** `D` integrates to one over the hemisphere
//! (`int D dw_h = 1`). Changing variables `dw_i = 4 (wo . h) dw_h`, the
//! lobe's albedo is `int D(h) cos_i / max(cos_o, cos_i) dw_h <= 1`, for
//! every `wo`: the model never creates energy (`R + k_s <= 1`). The common
//! `(n + 8) / (8 pi)` factor is only an approximation of this and can
//! exceed 1. Reciprocal (`wo . h = wi . h`, `max` symmetric). Sampled by
//! drawing `h` from `D` (`cos theta_h = u^(1/(n+1))`) and reflecting `wo`:
//! density `D(h) / (4 (wo . h))`.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `exponent` | number >= 0 | `32` | exponent `n` |
//! | `specular` | RGB in [0, 1] | `[0.5, 0.5, 0.5]` | lobe weight `k_s` |
//! | `reflectance` | RGB in [0, 1] | `[0, 0, 0]` | diffuse albedo `R` (`R + k_s <= 1`) |
//!
//! Sources: J. F. Blinn, "Models of Light Reflection for Computer
//! Synthesized Pictures", SIGGRAPH 1977; M. Ashikhmin and P. Shirley, "An
//! Anisotropic Phong BRDF Model", JGT 5(2), 2000; seed 002.
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "lacquer"
//! type = "blinn_phong"
//! exponent = 200
//! specular = [0.4, 0.4, 0.4]
//! reflectance = [0.1, 0.3, 0.5]
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["type"].as_str(), Some("blinn_phong"));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::lobe::{around, DiffuseLobe, Lobe};
use crate::microfacet::reflect;
use isolux_core::{DVec3, Rgb, PI};

/// The bounded Blinn-Phong lobe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlinnPhongLobe {
    /// Exponent `n`.
    pub exponent: f64,
}

impl BlinnPhongLobe {
    fn d(&self, h: DVec3) -> f64 {
        if h.z <= 0.0 {
            return 0.0;
        }
        (self.exponent + 1.0) / (2.0 * PI) * h.z.powf(self.exponent)
    }
}

impl Lobe for BlinnPhongLobe {
    fn eval(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let Some(h) = (wo + wi).try_normalize() else {
            return 0.0;
        };
        self.d(h) / (4.0 * wo.dot(h) * wo.z.max(wi.z))
    }
    fn sample(&self, wo: DVec3, u: [f64; 2]) -> Option<DVec3> {
        let cos_h = u[0].powf(1.0 / (self.exponent + 1.0));
        let h = around(DVec3::Z, cos_h, 2.0 * PI * u[1]);
        if wo.dot(h) <= 0.0 {
            return None;
        }
        Some(reflect(wo, h))
    }
    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        let Some(h) = (wo + wi).try_normalize() else {
            return 0.0;
        };
        let c = wo.dot(h);
        if c <= 0.0 {
            return 0.0;
        }
        self.d(h) / (4.0 * c)
    }
}

/// Blinn-Phong over a Lambertian base.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlinnPhong(pub DiffuseLobe<BlinnPhongLobe>);

impl BlinnPhong {
    /// A Blinn-Phong material.
    pub fn new(exponent: f64, specular: Rgb, reflectance: Rgb) -> Self {
        Self(DiffuseLobe {
            reflectance,
            specular,
            lobe: BlinnPhongLobe { exponent },
        })
    }
}

impl BxdfModel for BlinnPhong {
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
