//! "Diffuse plus specular lobe" models, as the seed writes them:
//! `f = R / pi + k_s * lobe(wo, wi)`.
//!
//! Each lobe is normalized so that its own directional albedo never exceeds
//! 1; the scene loader requires `reflectance + specular <= 1` per channel,
//! so the sum never creates energy. Sampling picks the diffuse part or the
//! lobe in proportion to the luminances of `R` and `k_s`; the pdf is the
//! same mixture.

use crate::bxdf::{BsdfSample, BxdfFlags};
use isolux_core::{sampling, DVec3, Rgb, INV_PI};

/// A normalized scalar lobe in the local frame.
pub trait Lobe {
    /// Value (1/sr), zero unless both directions are above the surface.
    fn eval(&self, wo: DVec3, wi: DVec3) -> f64;
    /// A direction drawn from the lobe's sampling density.
    fn sample(&self, wo: DVec3, u: [f64; 2]) -> Option<DVec3>;
    /// Density of [`Lobe::sample`].
    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64;
}

/// Diffuse base plus a weighted lobe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffuseLobe<L> {
    /// Diffuse albedo `R`.
    pub reflectance: Rgb,
    /// Lobe weight `k_s`.
    pub specular: Rgb,
    /// The lobe.
    pub lobe: L,
}

impl<L: Lobe> DiffuseLobe<L> {
    fn p_lobe(&self) -> f64 {
        let d = self.reflectance.luminance().max(0.0);
        let s = self.specular.luminance().max(0.0);
        if d + s > 0.0 {
            s / (d + s)
        } else {
            0.5
        }
    }

    /// `f(wo, wi)`.
    pub fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        self.reflectance * INV_PI + self.specular * self.lobe.eval(wo, wi)
    }

    /// Mixture sampling.
    pub fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let ps = self.p_lobe();
        let wi = if uc < ps {
            self.lobe.sample(wo, u)?
        } else {
            sampling::cosine_hemisphere(u)
        };
        if wi.z <= 0.0 {
            return None;
        }
        let glossy = uc < ps;
        Some(BsdfSample {
            wi,
            f: self.f(wo, wi),
            pdf: self.pdf(wo, wi),
            flags: BxdfFlags::REFLECTION
                | if glossy {
                    BxdfFlags::GLOSSY
                } else {
                    BxdfFlags::DIFFUSE
                },
            eta: 1.0,
        })
    }

    /// Mixture density.
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let ps = self.p_lobe();
        ps * self.lobe.pdf(wo, wi) + (1.0 - ps) * sampling::cosine_hemisphere_pdf(wi.z)
    }

    /// Flags of the combination.
    pub fn flags(&self) -> BxdfFlags {
        BxdfFlags::REFLECTION | BxdfFlags::DIFFUSE | BxdfFlags::GLOSSY
    }
}

/// A unit vector at angle `acos(cos_a)` from `axis`, azimuth `phi`.
pub fn around(axis: DVec3, cos_a: f64, phi: f64) -> DVec3 {
    let f = isolux_core::Frame::from_normal(axis);
    let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
    f.to_world(DVec3::new(sin_a * phi.cos(), sin_a * phi.sin(), cos_a))
}
