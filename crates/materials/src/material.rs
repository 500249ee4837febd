//! The material enum: every model a scene can name, dispatched by `match`.

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::diffuse::Diffuse;
use isolux_core::{DVec3, Rgb};

/// A named material of a scene.
#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    /// Lambertian reflection (`type = "diffuse"`).
    Diffuse(Diffuse),
}

impl Material {
    /// The scene-file `type` of this material.
    pub fn type_name(&self) -> &'static str {
        match self {
            Material::Diffuse(_) => "diffuse",
        }
    }
}

impl BxdfModel for Material {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        match self {
            Material::Diffuse(m) => m.f(wo, wi),
        }
    }
    fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        match self {
            Material::Diffuse(m) => m.sample(wo, uc, u),
        }
    }
    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        match self {
            Material::Diffuse(m) => m.pdf(wo, wi),
        }
    }
    fn flags(&self) -> BxdfFlags {
        match self {
            Material::Diffuse(m) => m.flags(),
        }
    }
    fn albedo(&self) -> Rgb {
        match self {
            Material::Diffuse(m) => m.albedo(),
        }
    }
}
