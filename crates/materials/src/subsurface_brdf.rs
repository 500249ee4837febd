//! # Subsurface BRDF (the seed's local approximation)
//!
//! Seed 000 eq. 19 with the corrections of SPEC §4: a translucent medium
//! seen from far enough away that light re-emerges where it entered. The
//! dipole BSSRDF integrated over the surface and the single-scattering
//! term become a BRDF, plus the smooth boundary's mirror reflection:
//!
//! ```text
//! f = (1/pi) T(cos_i) R_d T(cos_o)                             multiple scattering
//!   + T(cos_i) T(cos_o) a p(wi' . wo') / (cos_i' + cos_o')      single scattering
//!   + F(cos_o) delta(wi - reflect(wo)) / cos_i                  boundary
//! ```
//!
//! `R_d` is the dipole's closed-form total diffuse reflectance per channel
//! (see [`crate::subsurface::diffusion`]), `T = 1 - F` the Fresnel
//! transmittances, `a = sigma_s / sigma_t` the single-scattering albedo, `p`
//! Henyey-Greenstein with mean cosine `g`, primes for refracted directions.
//! The multiple-scattering term's albedo is `T(cos_o) R_d (1 - F_dr,ext) <= 1
//! - F(cos_o)`; the single-scattering term is small (it is bounded by `a T`
//! times the phase function's mean over the refracted cone). Reciprocal.
//! A fast preview of the `subsurface` material: it ignores the blur of
//! light across the surface. Sampling: the mirror with probability
//! `F(cos_o)`, otherwise cosine-weighted.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `medium` | string | | a named measured medium (see [`crate::subsurface::media`]) |
//! | `sigma_s_reduced` or `sigma_s` | RGB, 1/mm | | (reduced) scattering, instead of `medium` |
//! | `sigma_a` | RGB, 1/mm | | absorption, with `sigma_s`/`sigma_s_reduced` |
//! | `g` | number in (-1, 1) | `0` | mean cosine of the phase function |
//! | `ior` | number > 0 | medium's, else `1.3` | relative index of refraction |
//! | `scale` | number > 0 | `1` | millimetres per scene unit (used by `subsurface`; the BRDF is scale-free) |
//!
//! Sources: Jensen et al., SIGGRAPH 2001 (§3-4); Hanrahan and Krueger,
//! SIGGRAPH 1993 (single scattering).
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "milk"
//! type = "subsurface_brdf"
//! medium = "skimmilk"
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["medium"].as_str(), Some("skimmilk"));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::fresnel::dielectric;
use crate::subsurface::phase::single_scattering;
use crate::subsurface::Dipole;
use isolux_core::{sampling, DVec3, Rgb, INV_PI};

/// The local (BRDF) approximation of a translucent medium.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubsurfaceBrdf {
    /// Total diffuse reflectance of the dipole, per channel.
    pub r_d: Rgb,
    /// Single-scattering albedo `sigma_s / sigma_t`, per channel.
    pub single_albedo: Rgb,
    /// Mean cosine of the phase function.
    pub g: f64,
    /// Relative index of refraction.
    pub eta: f64,
}

impl SubsurfaceBrdf {
    /// From reduced scattering and absorption per channel (1/mm).
    pub fn new(sigma_s_reduced: Rgb, sigma_a: Rgb, g: f64, eta: f64) -> Self {
        let ch = |s: f64, a: f64| {
            let d = Dipole::new(s, a, eta);
            let sigma_s = s / (1.0 - g);
            let st = sigma_s + a;
            (d.total(), if st > 0.0 { sigma_s / st } else { 0.0 })
        };
        let (r, ar) = ch(sigma_s_reduced.r, sigma_a.r);
        let (gg, ag) = ch(sigma_s_reduced.g, sigma_a.g);
        let (b, ab) = ch(sigma_s_reduced.b, sigma_a.b);
        Self {
            r_d: Rgb::new(r, gg, b),
            single_albedo: Rgb::new(ar, ag, ab),
            g,
            eta,
        }
    }

    fn p_mirror(&self, wo: DVec3) -> f64 {
        dielectric(wo.z, self.eta).clamp(0.02, 0.98)
    }
}

impl BxdfModel for SubsurfaceBrdf {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        let t = (1.0 - dielectric(wi.z, self.eta)) * (1.0 - dielectric(wo.z, self.eta));
        let single = single_scattering(wo, wi, 1.0, self.g, self.eta);
        self.r_d * (t * INV_PI) + self.single_albedo * single
    }

    fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let pm = self.p_mirror(wo);
        if uc < pm {
            let wi = DVec3::new(-wo.x, -wo.y, wo.z);
            return Some(BsdfSample {
                wi,
                f: Rgb::splat(dielectric(wo.z, self.eta) / wi.z),
                pdf: pm,
                flags: BxdfFlags::REFLECTION | BxdfFlags::SPECULAR,
                eta: 1.0,
            });
        }
        let wi = sampling::cosine_hemisphere(u);
        BsdfSample::reflected(self, wo, wi, BxdfFlags::DIFFUSE)
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        (1.0 - self.p_mirror(wo)) * sampling::cosine_hemisphere_pdf(wi.z)
    }

    fn flags(&self) -> BxdfFlags {
        BxdfFlags::REFLECTION | BxdfFlags::DIFFUSE | BxdfFlags::SPECULAR
    }

    fn albedo(&self) -> Rgb {
        self.r_d
    }
}
