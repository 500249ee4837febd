//! The material enum: every model a scene can name, dispatched by `match`
//! (no trait objects, so the same plain data can mirror a GPU layout).

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::{
    Beckmann, BlinnPhong, Conductor, CookTorrance, Dielectric, Diffuse, Factored, Gaussian, Ggx,
    HeidrichSeidel, Merl, Mix, Phong, Plastic, Subsurface, SubsurfaceBrdf, Ward, Wave,
};
use isolux_core::{DVec3, Rgb};
use std::borrow::Cow;

/// A named material of a scene.
#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    /// Lambertian reflection (`type = "diffuse"`).
    Diffuse(Diffuse),
    /// Normalized Phong (`type = "phong"`).
    Phong(Phong),
    /// Bounded Blinn-Phong (`type = "blinn_phong"`).
    BlinnPhong(BlinnPhong),
    /// Gaussian highlight (`type = "gaussian"`).
    Gaussian(Gaussian),
    /// Cook-Torrance (`type = "cook_torrance"`).
    CookTorrance(CookTorrance),
    /// Anisotropic Ward (`type = "ward"`).
    Ward(Ward),
    /// Heidrich-Seidel fibre model (`type = "heidrich_seidel"`).
    HeidrichSeidel(HeidrichSeidel),
    /// GGX microfacet reflection (`type = "ggx"`).
    Ggx(Ggx),
    /// Beckmann microfacet reflection (`type = "beckmann"`).
    Beckmann(Beckmann),
    /// Smooth conductor mirror (`type = "conductor"`).
    Conductor(Conductor),
    /// Smooth glass (`type = "dielectric"`).
    Dielectric(Dielectric),
    /// Coated diffuse (`type = "plastic"`).
    Plastic(Plastic),
    /// Translucent medium (`type = "subsurface"`).
    Subsurface(Subsurface),
    /// Translucent medium, BRDF approximation (`type = "subsurface_brdf"`).
    SubsurfaceBrdf(SubsurfaceBrdf),
    /// Weighted mixture (`type = "mix"`).
    Mix(Mix),
    /// Homomorphic factorization from textures (`type = "factored"`).
    Factored(Factored),
    /// Measured MERL table (`type = "merl"`).
    Merl(Merl),
    /// Wave-optics diffraction from a heightfield (`type = "wave"`).
    Wave(Wave),
}

/// Applies `$body` to the model inside any variant.
macro_rules! dispatch {
    ($self:expr, $m:ident => $body:expr) => {
        match $self {
            Material::Diffuse($m) => $body,
            Material::Phong($m) => $body,
            Material::BlinnPhong($m) => $body,
            Material::Gaussian($m) => $body,
            Material::CookTorrance($m) => $body,
            Material::Ward($m) => $body,
            Material::HeidrichSeidel($m) => $body,
            Material::Ggx($m) => $body,
            Material::Beckmann($m) => $body,
            Material::Conductor($m) => $body,
            Material::Dielectric($m) => $body,
            Material::Plastic($m) => $body,
            Material::Subsurface($m) => $body,
            Material::SubsurfaceBrdf($m) => $body,
            Material::Mix($m) => $body,
            Material::Factored($m) => $body,
            Material::Merl($m) => $body,
            Material::Wave($m) => $body,
        }
    };
}

impl Material {
    /// The scene-file `type` of this material.
    pub fn type_name(&self) -> &'static str {
        match self {
            Material::Diffuse(_) => "diffuse",
            Material::Phong(_) => "phong",
            Material::BlinnPhong(_) => "blinn_phong",
            Material::Gaussian(_) => "gaussian",
            Material::CookTorrance(_) => "cook_torrance",
            Material::Ward(_) => "ward",
            Material::HeidrichSeidel(_) => "heidrich_seidel",
            Material::Ggx(_) => "ggx",
            Material::Beckmann(_) => "beckmann",
            Material::Conductor(_) => "conductor",
            Material::Dielectric(_) => "dielectric",
            Material::Plastic(_) => "plastic",
            Material::Subsurface(_) => "subsurface",
            Material::SubsurfaceBrdf(_) => "subsurface_brdf",
            Material::Mix(_) => "mix",
            Material::Factored(_) => "factored",
            Material::Merl(_) => "merl",
            Material::Wave(_) => "wave",
        }
    }

    /// The material placed at world point `p`: spatially varying models
    /// (`wave`) query their own neighbourhood, with the pixel footprint
    /// `footprint` (scene units, camera rays only) and a random number
    /// from `xi` (drawn only by them; a mix places its `wave` components
    /// with one draw); every other model is borrowed as is.
    pub fn at_point(
        &self,
        p: DVec3,
        footprint: Option<f64>,
        xi: impl FnOnce() -> f64,
    ) -> Cow<'_, Material> {
        if self.varies_in_space() {
            Cow::Owned(self.placed(p, footprint, xi()))
        } else {
            Cow::Borrowed(self)
        }
    }

    /// [`Material::at_point`] with the random number drawn (one draw
    /// shared by a mix's components).
    fn placed(&self, p: DVec3, footprint: Option<f64>, xi: f64) -> Material {
        match self {
            Material::Wave(w) => Material::Wave(w.at_point(p, footprint, xi)),
            Material::Mix(m) => Material::Mix(crate::Mix {
                components: m
                    .components
                    .iter()
                    .map(|(c, w)| (c.placed(p, footprint, xi), *w))
                    .collect(),
            }),
            _ => self.clone(),
        }
    }

    /// Whether [`Material::at_point`] changes this material (a `wave`, or
    /// a mix holding one).
    pub fn varies_in_space(&self) -> bool {
        match self {
            Material::Wave(_) => true,
            Material::Mix(m) => m.components.iter().any(|(c, _)| c.varies_in_space()),
            _ => false,
        }
    }

    /// This material seen from inside a medium of index `n` (a surface
    /// under water) instead of from vacuum: every index of refraction it
    /// holds divided by `n` ([`crate::Fresnel::relative_to`]), so that
    /// the scene's `ior`, `eta` and `k` stay the material's own, against
    /// vacuum. `None` where nothing changes: at `n = 1`, and for models
    /// without an index (the lobe models, `factored` and `merl`, measured
    /// in air), `wave` (whose diffraction is computed in air) and
    /// `subsurface_brdf` (its reflectance derived for vacuum outside). A
    /// `subsurface` medium has its boundary (and its dipole profile)
    /// derived anew for the relative index: media nest. A mix changes
    /// where a component does.
    pub fn relative_to(&self, n: f64) -> Option<Material> {
        if n == 1.0 || !(n > 0.0) {
            return None;
        }
        match self {
            Material::Dielectric(d) => Some(Material::Dielectric(Dielectric { ior: d.ior / n })),
            Material::Conductor(c) => Some(Material::Conductor(Conductor {
                fresnel: c.fresnel.relative_to(n)?,
            })),
            Material::Plastic(p) => Some(Material::Plastic(p.relative_to(n))),
            Material::Subsurface(m) => m.relative_to(n).map(Material::Subsurface),
            Material::Ggx(m) => {
                let mut m = *m;
                m.lobe.fresnel = m.lobe.fresnel.relative_to(n)?;
                Some(Material::Ggx(m))
            }
            Material::Beckmann(m) => {
                let mut m = *m;
                m.lobe.fresnel = m.lobe.fresnel.relative_to(n)?;
                Some(Material::Beckmann(m))
            }
            Material::CookTorrance(m) => {
                let mut m = m.clone();
                m.fresnel = m.fresnel.relative_to(n)?;
                Some(Material::CookTorrance(m))
            }
            Material::Mix(mix) => {
                let changed: Vec<_> = mix
                    .components
                    .iter()
                    .map(|(c, _)| c.relative_to(n))
                    .collect();
                changed.iter().any(Option::is_some).then(|| {
                    Material::Mix(crate::Mix {
                        components: mix
                            .components
                            .iter()
                            .zip(changed)
                            .map(|((c, w), r)| (r.unwrap_or_else(|| c.clone()), *w))
                            .collect(),
                    })
                })
            }
            _ => None,
        }
    }

    /// The participating medium behind the surface, if any.
    pub fn medium(&self) -> Option<&Subsurface> {
        match self {
            Material::Subsurface(m) => Some(m),
            _ => None,
        }
    }

    /// World-space tangent hint of anisotropic models.
    pub fn tangent(&self) -> Option<DVec3> {
        match self {
            Material::Ggx(m) => m.tangent,
            Material::Beckmann(m) => m.tangent,
            Material::Ward(m) => m.tangent,
            Material::HeidrichSeidel(m) => m.tangent,
            Material::Mix(m) => m.components.iter().find_map(|(c, _)| c.tangent()),
            Material::Wave(m) => Some(m.query.tangent),
            _ => None,
        }
    }
}

impl BxdfModel for Material {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        dispatch!(self, m => m.f(wo, wi))
    }
    fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        dispatch!(self, m => m.sample(wo, uc, u))
    }
    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        dispatch!(self, m => m.pdf(wo, wi))
    }
    fn flags(&self) -> BxdfFlags {
        dispatch!(self, m => m.flags())
    }
    fn albedo(&self) -> Rgb {
        dispatch!(self, m => m.albedo())
    }
}
