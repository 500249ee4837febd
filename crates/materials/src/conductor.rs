//! # Smooth conductor (perfect mirror)
//!
//! A polished metal: all light leaves in the mirror direction, weighted by
//! the conductor Fresnel reflectance:
//!
//! ```text
//! f(wo, wi) = F(cos_o) delta(wi - reflect(wo)) / cos_i
//! ```
//!
//! A Dirac delta lobe: evaluation returns 0 (no light direction can hit
//! it), sampling returns the mirror direction with discrete probability 1.
//! The energy reflected is exactly `F <= 1`.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | Fresnel | `metal`, `eta` + `k`, `ior` or `schlick` | none (`F = 1`) | see [`crate::fresnel`] |
//!
//! Source: pbrt-v4 §9.4 (specular reflection).
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "mirror"
//! type = "conductor"
//! metal = "Ag"
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["metal"].as_str(), Some("Ag"));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::Fresnel;
use isolux_core::{DVec3, Rgb};

/// Perfect mirror with Fresnel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conductor {
    /// Fresnel term.
    pub fresnel: Fresnel,
}

impl BxdfModel for Conductor {
    fn f(&self, _wo: DVec3, _wi: DVec3) -> Rgb {
        Rgb::BLACK
    }
    fn sample(&self, wo: DVec3, _uc: f64, _u: [f64; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = DVec3::new(-wo.x, -wo.y, wo.z);
        Some(BsdfSample {
            wi,
            f: self.fresnel.eval(wo.z) * (1.0 / wi.z),
            pdf: 1.0,
            flags: BxdfFlags::REFLECTION | BxdfFlags::SPECULAR,
            eta: 1.0,
        })
    }
    fn pdf(&self, _wo: DVec3, _wi: DVec3) -> f64 {
        0.0
    }
    fn flags(&self) -> BxdfFlags {
        BxdfFlags::REFLECTION | BxdfFlags::SPECULAR
    }
    fn albedo(&self) -> Rgb {
        self.fresnel.eval(1.0)
    }
}
