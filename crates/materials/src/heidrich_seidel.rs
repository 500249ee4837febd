//! # Heidrich-Seidel anisotropic fibre model
//!
//! Brushed surfaces and hair scatter around a cone about the fibre
//! direction `T` (seed 002): with `a = wi.T`, `b = wo.T`,
//!
//! ```text
//! k_spec = (sqrt(1 - a^2) sqrt(1 - b^2) - a b)^s = max(0, -cos(alpha_i + alpha_o))^s
//! f = R / pi + k_s C k_spec(wo, wi) + k_iso (s + 2)/(2 pi) max(0, r . wi)^s
//! ```
//!
//! where `alpha` are angles to `T`: the highlight peaks on the cone
//! `alpha_i = pi - alpha_o`. As the seed advises, the fibre lobe is combined
//! with an isotropic (Phong) lobe of weight `isotropic` and a Lambertian
//! base.
//!
//! **Normalization.** `k_spec` has no closed-form albedo, so `C` is computed
//! numerically when the material loads: the inverse of the largest
//! directional albedo `int k_spec cos_i dwi` over a 12 x 8 grid of incidence
//! directions (quadrature 160 x 320 each), times a 2% safety margin for the
//! maximum between grid points. Every part then has albedo <= 1, and
//! `R + k_s + k_iso <= 1` keeps the sum energy-conserving. Reciprocal
//! (symmetric in `a`, `b`). The fibre lobe is sampled by a truncated
//! Gaussian in `alpha_i` around `pi - alpha_o` (width `1/sqrt(s)`, since
//! `cos^s d ~ exp(-s d^2 / 2)`) and a uniform azimuth about `T`, with its
//! exact density.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `exponent` | number > 0 | `40` | `s` |
//! | `specular` | RGB in [0, 1] | `[0.5, 0.5, 0.5]` | fibre lobe weight `k_s` |
//! | `isotropic` | RGB in [0, 1] | `[0, 0, 0]` | isotropic Phong lobe weight `k_iso` |
//! | `reflectance` | RGB in [0, 1] | `[0, 0, 0]` | diffuse albedo `R` |
//! | `tangent` | `[x, y, z]` | automatic frame | fibre direction `D`, projected: `T = normalize(D - (D.N) N)` |
//!
//! Source: W. Heidrich and H.-P. Seidel, "Efficient Rendering of
//! Anisotropic Surfaces Using Computer Graphics Hardware", 1998; seed 002.
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "brushed_steel"
//! type = "heidrich_seidel"
//! exponent = 60
//! specular = [0.5, 0.5, 0.5]
//! isotropic = [0.1, 0.1, 0.1]
//! reflectance = [0.2, 0.2, 0.2]
//! tangent = [0.0, 1.0, 0.0]
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["type"].as_str(), Some("heidrich_seidel"));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::lobe::Lobe;
use crate::phong::PhongLobe;
use isolux_core::{sampling, DVec3, Rgb, INV_PI, PI};

/// Heidrich-Seidel fibre model with an isotropic lobe and a diffuse base.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeidrichSeidel {
    /// Exponent `s`.
    pub exponent: f64,
    /// Fibre lobe weight.
    pub specular: Rgb,
    /// Isotropic Phong lobe weight.
    pub isotropic: Rgb,
    /// Diffuse albedo.
    pub reflectance: Rgb,
    /// World-space fibre direction hint.
    pub tangent: Option<DVec3>,
    norm: f64,
}

fn k_spec(s: f64, wo: DVec3, wi: DVec3) -> f64 {
    let (a, b) = (wi.x.clamp(-1.0, 1.0), wo.x.clamp(-1.0, 1.0));
    let c = (1.0 - a * a).max(0.0).sqrt() * (1.0 - b * b).max(0.0).sqrt() - a * b;
    if c <= 0.0 {
        0.0
    } else {
        c.powf(s)
    }
}

impl HeidrichSeidel {
    /// Builds the model and computes its normalization.
    pub fn new(exponent: f64, specular: Rgb, isotropic: Rgb, reflectance: Rgb) -> Self {
        let (nt, np) = (160usize, 320usize);
        let mut max_albedo: f64 = 0.0;
        for i in 0..12 {
            let theta = (i as f64 + 0.5) / 12.0 * (PI / 2.0);
            for j in 0..8 {
                let phi = j as f64 / 8.0 * (PI / 2.0);
                let wo = DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                let mut s = 0.0;
                for a in 0..nt {
                    let z = (a as f64 + 0.5) / nt as f64;
                    let r = (1.0 - z * z).sqrt();
                    for b in 0..np {
                        let p = (b as f64 + 0.5) / np as f64 * 2.0 * PI;
                        s += k_spec(exponent, wo, DVec3::new(r * p.cos(), r * p.sin(), z)) * z;
                    }
                }
                max_albedo = max_albedo.max(s * 2.0 * PI / (nt * np) as f64);
            }
        }
        Self {
            exponent,
            specular,
            isotropic,
            reflectance,
            tangent: None,
            norm: if max_albedo > 0.0 {
                1.0 / (1.02 * max_albedo)
            } else {
                0.0
            },
        }
    }

    /// The numerical normalization constant `C`.
    pub fn normalization(&self) -> f64 {
        self.norm
    }

    /// Selection probabilities of the diffuse, fibre and isotropic lobes.
    pub fn weights(&self) -> [f64; 3] {
        let w = [
            self.reflectance.luminance(),
            self.specular.luminance(),
            self.isotropic.luminance(),
        ];
        let t: f64 = w.iter().sum();
        if t > 0.0 {
            w.map(|x| x / t)
        } else {
            [1.0, 0.0, 0.0]
        }
    }

    /// Width of the fibre sampler's Gaussian in angle.
    pub fn sigma(&self) -> f64 {
        1.0 / self.exponent.max(1e-3).sqrt()
    }

    /// Density of the fibre-lobe sampler.
    fn fibre_pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        let center = PI - wo.x.clamp(-1.0, 1.0).acos();
        let alpha = wi.x.clamp(-1.0, 1.0).acos();
        let sin_a = alpha.sin();
        if sin_a <= 0.0 {
            return 0.0;
        }
        let sg = self.sigma();
        let z = |x: f64| 0.5 * (1.0 + libm::erf(x / (sg * std::f64::consts::SQRT_2)));
        let mass = z(PI - center) - z(-center);
        if mass <= 0.0 {
            return 0.0;
        }
        let g = (-(alpha - center).powi(2) / (2.0 * sg * sg)).exp() / (sg * (2.0 * PI).sqrt());
        g / mass / (2.0 * PI * sin_a)
    }

    fn fibre_sample(&self, wo: DVec3, u: [f64; 2]) -> DVec3 {
        let center = PI - wo.x.clamp(-1.0, 1.0).acos();
        let sg = self.sigma();
        let z = |x: f64| 0.5 * (1.0 + libm::erf(x / (sg * std::f64::consts::SQRT_2)));
        let (lo, hi) = (z(-center), z(PI - center));
        let p = (lo + u[0] * (hi - lo)).clamp(1e-15, 1.0 - 1e-15);
        let d = sg * std::f64::consts::SQRT_2 * crate::microfacet::erfinv(2.0 * p - 1.0);
        let alpha = (center + d).clamp(0.0, PI);
        let phi = 2.0 * PI * u[1];
        DVec3::new(
            alpha.cos(),
            alpha.sin() * phi.cos(),
            alpha.sin() * phi.sin(),
        )
    }
}

impl BxdfModel for HeidrichSeidel {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        let iso = PhongLobe {
            exponent: self.exponent,
        }
        .eval(wo, wi);
        self.reflectance * INV_PI
            + self.specular * (self.norm * k_spec(self.exponent, wo, wi))
            + self.isotropic * iso
    }

    fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let [pd, ps, _] = self.weights();
        let (wi, flags) = if uc < pd {
            (sampling::cosine_hemisphere(u), BxdfFlags::DIFFUSE)
        } else if uc < pd + ps {
            (self.fibre_sample(wo, u), BxdfFlags::GLOSSY)
        } else {
            (
                PhongLobe {
                    exponent: self.exponent,
                }
                .sample(wo, u)?,
                BxdfFlags::GLOSSY,
            )
        };
        BsdfSample::reflected(self, wo, wi, flags)
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let [pd, ps, pi] = self.weights();
        pd * sampling::cosine_hemisphere_pdf(wi.z)
            + ps * self.fibre_pdf(wo, wi)
            + pi * PhongLobe {
                exponent: self.exponent,
            }
            .pdf(wo, wi)
    }

    fn flags(&self) -> BxdfFlags {
        BxdfFlags::REFLECTION | BxdfFlags::DIFFUSE | BxdfFlags::GLOSSY
    }

    fn albedo(&self) -> Rgb {
        self.reflectance + self.specular + self.isotropic
    }
}
