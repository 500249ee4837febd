//! # Cook-Torrance
//!
//! The seed's microfacet model `D F G / (pi (v.n)(n.l))` with a normalized
//! `D`, for which the correct denominator is `4 (n.wo)(n.wi)` (Walter et
//! al. 2007; the seed's `pi` belongs to the 1981 paper's un-normalized
//! `D`), over a Lambertian base:
//!
//! ```text
//! f = R/pi (1 - F(cos_o)) (1 - F(cos_i)) + D(m) F(wo.m) G(wo, wi) / (4 cos_o cos_i)
//! G_cook_torrance = min(1, 2 (n.m)(n.wo)/(wo.m), 2 (n.m)(n.wi)/(wo.m))   (V-groove)
//! G_smith = 1 / (1 + Lambda(wo) + Lambda(wi))                           (height-correlated)
//! ```
//!
//! The base is weighted by the light the interface transmits on the way in
//! and out, `(1 - F)` at both ends: symmetric, so the model stays
//! reciprocal, and with a metal (`F` near 1) the base vanishes, as it should.
//! `D` is Beckmann, GGX or the seed's Gaussian `exp(-(theta_m/m)^2)`
//! normalized numerically (`int D cos = 1`, see [`crate::gaussian`]).
//! Sampling draws `m` from `D(m) cos(theta_m)` (visible-normal sampling
//! would be wrong for the V-groove `G`) and mixes in cosine sampling for
//! the base.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `roughness` | number > 0 | `0.3` | Beckmann/GGX `alpha`, or Gaussian `m` (radians) |
//! | `distribution` | `"beckmann"`, `"ggx"`, `"gaussian"` | `"beckmann"` | microfacet normal distribution |
//! | `masking` | `"cook_torrance"`, `"smith"` | `"cook_torrance"` | shadowing-masking (Smith needs beckmann or ggx) |
//! | `reflectance` | RGB in [0, 1] | `[0, 0, 0]` | diffuse albedo `R` |
//! | Fresnel | `metal`, `eta` + `k`, `ior`, `schlick` | `ior = 1.5` | see [`crate::fresnel`] |
//!
//! Sources: R. L. Cook and K. E. Torrance, "A Reflectance Model for
//! Computer Graphics", ACM TOG 1(1), 1982; Walter et al., EGSR 2007;
//! seed 002.
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "vase"
//! type = "cook_torrance"
//! roughness = 0.3
//! distribution = "beckmann"
//! masking = "cook_torrance"
//! schlick = [0.05, 0.05, 0.05]
//! reflectance = [0.3, 0.3, 0.3]
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["masking"].as_str(), Some("cook_torrance"));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::gaussian::GaussianDistribution;
use crate::microfacet::{reflect, Kind, Microfacet};
use crate::Fresnel;
use isolux_core::{sampling, DVec3, Rgb, INV_PI, PI};

/// A normal distribution sampled proportionally to `D(m) cos(theta_m)`.
#[derive(Clone, Debug, PartialEq)]
pub enum NormalDistribution {
    /// Beckmann or GGX.
    Analytic(Microfacet),
    /// The seed's Gaussian, tabulated.
    Gaussian(GaussianDistribution),
}

impl NormalDistribution {
    /// `D(m)`.
    pub fn d(&self, m: DVec3) -> f64 {
        match self {
            NormalDistribution::Analytic(d) => d.d(m),
            NormalDistribution::Gaussian(g) => g.d(m),
        }
    }

    /// Samples `m` with density [`NormalDistribution::pdf_m`].
    pub fn sample_m(&self, u: [f64; 2]) -> DVec3 {
        let phi = 2.0 * PI * u[1];
        let cos_t = match self {
            NormalDistribution::Analytic(d) => {
                let a2 = d.alpha_x * d.alpha_x;
                let tan2 = match d.kind {
                    Kind::Ggx => a2 * u[0] / (1.0 - u[0]).max(1e-300),
                    Kind::Beckmann => -a2 * (1.0 - u[0]).max(1e-300).ln(),
                };
                1.0 / (1.0 + tan2).sqrt()
            }
            NormalDistribution::Gaussian(g) => return g.sample_m(u),
        };
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        DVec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
    }

    /// Solid-angle density of [`NormalDistribution::sample_m`].
    pub fn pdf_m(&self, m: DVec3) -> f64 {
        match self {
            NormalDistribution::Analytic(d) => d.d(m) * m.z.max(0.0),
            NormalDistribution::Gaussian(g) => g.pdf_m(m),
        }
    }
}

/// Which shadowing-masking term.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Masking {
    /// Cook and Torrance's V-groove term.
    VGroove,
    /// Smith, height-correlated (Beckmann and GGX only).
    Smith,
}

/// Cook-Torrance over a Fresnel-weighted Lambertian base.
#[derive(Clone, Debug, PartialEq)]
pub struct CookTorrance {
    /// Microfacet distribution.
    pub distribution: NormalDistribution,
    /// Masking term.
    pub masking: Masking,
    /// Fresnel term.
    pub fresnel: Fresnel,
    /// Diffuse albedo.
    pub reflectance: Rgb,
}

impl CookTorrance {
    fn g(&self, wo: DVec3, wi: DVec3, m: DVec3) -> f64 {
        match (self.masking, &self.distribution) {
            (Masking::Smith, NormalDistribution::Analytic(d)) => d.g(wo, wi),
            _ => {
                let om = wo.dot(m);
                if om <= 0.0 {
                    return 0.0;
                }
                (2.0 * m.z * wo.z / om).min(2.0 * m.z * wi.z / om).min(1.0)
            }
        }
    }

    /// The probability of sampling the specular lobe.
    pub fn p_specular(&self) -> f64 {
        let s = self.fresnel.eval(1.0).luminance().max(0.05);
        let d = self.reflectance.luminance();
        if d <= 0.0 {
            1.0
        } else {
            (s / (s + d)).clamp(0.05, 0.95)
        }
    }
}

impl BxdfModel for CookTorrance {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        let one = Rgb::WHITE;
        let to = one + self.fresnel.eval(wo.z) * -1.0;
        let ti = one + self.fresnel.eval(wi.z) * -1.0;
        let mut f = self.reflectance * to * ti * INV_PI;
        if let Some(m) = (wo + wi).try_normalize() {
            let d = self.distribution.d(m);
            if d > 0.0 {
                f += self.fresnel.eval(wo.dot(m)) * (d * self.g(wo, wi, m) / (4.0 * wo.z * wi.z));
            }
        }
        f
    }

    fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let ps = self.p_specular();
        let wi = if uc < ps {
            let m = self.distribution.sample_m(u);
            if wo.dot(m) <= 0.0 {
                return None;
            }
            reflect(wo, m)
        } else {
            sampling::cosine_hemisphere(u)
        };
        let lobe = if uc < ps {
            BxdfFlags::GLOSSY
        } else {
            BxdfFlags::DIFFUSE
        };
        BsdfSample::reflected(self, wo, wi, lobe)
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let ps = self.p_specular();
        let mut p = (1.0 - ps) * sampling::cosine_hemisphere_pdf(wi.z);
        if let Some(m) = (wo + wi).try_normalize() {
            let om = wo.dot(m);
            if om > 0.0 {
                p += ps * self.distribution.pdf_m(m) / (4.0 * om);
            }
        }
        p
    }

    fn flags(&self) -> BxdfFlags {
        BxdfFlags::REFLECTION | BxdfFlags::GLOSSY | BxdfFlags::DIFFUSE
    }

    fn albedo(&self) -> Rgb {
        self.reflectance
    }
}
