//! # GGX (Trowbridge-Reitz) microfacet reflection
//!
//! A rough conductor or glossy coating whose microfacet normals follow the
//! Trowbridge-Reitz distribution (long tails, the "glow" around highlights
//! that every current renderer shows):
//!
//! ```text
//! f(wo, wi) = D(m) G(wo, wi) F(wo.m) / (4 cos_o cos_i),   m = normalize(wo + wi)
//! D(m) = 1 / (pi ax ay cos^4 (1 + tan^2 (cos^2 phi / ax^2 + sin^2 phi / ay^2))^2)
//! ```
//!
//! with Smith's height-correlated masking-shadowing `G` (see
//! [`crate::microfacet`]). `D` is normalized, so with `F = 1` the model
//! loses energy only to masking (the well-known darkening of rough
//! microfacet models at high roughness), never creates it. Reciprocal.
//! Sampling draws visible normals (Heitz 2018).
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `roughness` | number > 0 | `0.2` | `alpha` (isotropic) |
//! | `roughness_u`, `roughness_v` | numbers > 0 | | `alpha_x`, `alpha_y` along the tangent and bitangent (instead of `roughness`) |
//! | `tangent` | `[x, y, z]` | frame default | direction projected onto the tangent plane as the `u` axis (anisotropy) |
//! | Fresnel | `metal`, `eta` + `k`, `ior` or `schlick` | none (`F = 1`) | see [`crate::fresnel`] |
//!
//! Source: Walter, Marschner, Li, Torrance, "Microfacet Models for
//! Refraction through Rough Surfaces", EGSR 2007; Trowbridge and Reitz,
//! JOSA 65(5), 1975.
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "brushed_gold"
//! type = "ggx"
//! roughness_u = 0.05
//! roughness_v = 0.3
//! tangent = [0.0, 1.0, 0.0]
//! metal = "Au"
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["type"].as_str(), Some("ggx"));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::microfacet::{Kind, Microfacet, MicrofacetReflection};
use crate::Fresnel;
use isolux_core::{DVec3, Rgb};

/// GGX microfacet reflector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    /// The shared microfacet reflection.
    pub lobe: MicrofacetReflection,
    /// World-space tangent hint for anisotropy.
    pub tangent: Option<DVec3>,
}

impl Ggx {
    /// A GGX reflector with roughness `(alpha_x, alpha_y)`.
    pub fn new(alpha_x: f64, alpha_y: f64, fresnel: Fresnel) -> Self {
        Self {
            lobe: MicrofacetReflection {
                distribution: Microfacet {
                    kind: Kind::Ggx,
                    alpha_x,
                    alpha_y,
                },
                fresnel,
            },
            tangent: None,
        }
    }
}

impl BxdfModel for Ggx {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        self.lobe.f(wo, wi)
    }
    fn sample(&self, wo: DVec3, _uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        self.lobe.sample(wo, u)
    }
    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        self.lobe.pdf(wo, wi)
    }
    fn flags(&self) -> BxdfFlags {
        BxdfFlags::REFLECTION | BxdfFlags::GLOSSY
    }
    fn albedo(&self) -> Rgb {
        self.lobe.fresnel.eval(1.0)
    }
}
