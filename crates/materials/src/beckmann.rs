//! # Beckmann microfacet reflection
//!
//! A rough surface whose microfacet slopes are Gaussian (Beckmann and
//! Spizzichino 1963): the seed's `exp(-tan^2 a / m^2) / (pi m^2 cos^4 a)`, with
//! the roughness `m` the RMS slope, made anisotropic:
//!
//! ```text
//! f(wo, wi) = D(m) G(wo, wi) F(wo.m) / (4 cos_o cos_i),   m = normalize(wo + wi)
//! D(m) = exp(-tan^2 (cos^2 phi / ax^2 + sin^2 phi / ay^2)) / (pi ax ay cos^4)
//! ```
//!
//! with Smith's height-correlated masking-shadowing `G` (see
//! [`crate::microfacet`]). `D` is normalized, so with `F = 1` the model
//! loses energy only to masking (the well-known darkening of rough
//! microfacet models at high roughness), never creates it. Reciprocal.
//! Sampling draws visible normals (Heitz and d'Eon 2014).
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `roughness` | number > 0 | `0.2` | RMS slope `m` (isotropic) |
//! | `roughness_u`, `roughness_v` | numbers > 0 | | `alpha_x`, `alpha_y` along the tangent and bitangent (instead of `roughness`) |
//! | `tangent` | `[x, y, z]` | frame default | direction projected onto the tangent plane as the `u` axis (anisotropy) |
//! | Fresnel | `metal`, `eta` + `k`, `ior` or `schlick` | none (`F = 1`) | see [`crate::fresnel`] |
//!
//! Source: Beckmann and Spizzichino, *The Scattering of Electromagnetic
//! Waves from Rough Surfaces* (1963); Walter et al., EGSR 2007; seed 002.

//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "satin_copper"
//! type = "beckmann"
//! roughness_u = 0.05
//! roughness_v = 0.3
//! tangent = [0.0, 1.0, 0.0]
//! metal = "Cu"
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["type"].as_str(), Some("beckmann"));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::microfacet::{Kind, Microfacet, MicrofacetReflection};
use crate::Fresnel;
use isolux_core::{DVec3, Rgb};

/// Beckmann microfacet reflector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Beckmann {
    /// The shared microfacet reflection.
    pub lobe: MicrofacetReflection,
    /// World-space tangent hint for anisotropy.
    pub tangent: Option<DVec3>,
}

impl Beckmann {
    /// A Beckmann reflector with roughness `(alpha_x, alpha_y)`.
    pub fn new(alpha_x: f64, alpha_y: f64, fresnel: Fresnel) -> Self {
        Self {
            lobe: MicrofacetReflection {
                distribution: Microfacet {
                    kind: Kind::Beckmann,
                    alpha_x,
                    alpha_y,
                },
                fresnel,
            },
            tangent: None,
        }
    }
}

impl BxdfModel for Beckmann {
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
