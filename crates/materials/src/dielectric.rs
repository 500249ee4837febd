//! # Smooth dielectric (glass, water)
//!
//! A polished transparent interface of relative index `ior = n_inside /
//! n_outside`: light is reflected with the exact Fresnel reflectance `F`
//! and refracted by Snell's law with `1 - F`:
//!
//! ```text
//! f_r = F delta(wi - reflect(wo)) / |cos_i|
//! f_t = (1 - F) / eta'^2 delta(wi - refract(wo)) / |cos_i|,   eta' = n_t / n_i
//! ```
//!
//! The `1 / eta'^2` factor is the radiance compression across the
//! interface (pbrt-v4 §9.5.2, transport of radiance, not importance): a ray
//! that enters and leaves a glass object carries the same radiance, so a
//! clear glass sphere under a uniform sky renders exactly the sky. Both
//! lobes are Dirac deltas: evaluation returns 0; sampling picks reflection
//! with probability `F`. The interface is oriented: the local `z` is the
//! outward normal, and `wo.z < 0` means the ray is inside. Total internal
//! reflection is handled by `F = 1`.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `ior` | number > 0 | `1.5` | relative index of refraction (inside / outside) |
//!
//! Under a random-walk medium (glass under water), the integrators use
//! `ior / n_medium` ([`crate::Material::relative_to`]): `ior` is the
//! glass's own index against vacuum.
//!
//! Source: Born and Wolf §1.5; pbrt-v4 §9.5.
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "glass"
//! type = "dielectric"
//! ior = 1.5
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["ior"].as_float(), Some(1.5));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::fresnel;
use isolux_core::{DVec3, Rgb};

/// Smooth dielectric interface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dielectric {
    /// Relative index of refraction (inside over outside).
    pub ior: f64,
}

impl Default for Dielectric {
    fn default() -> Self {
        Self { ior: 1.5 }
    }
}

/// Refracts `wo` through the interface with normal `+z`; `eta` is the
/// relative index inside/outside. Returns the direction and `eta'` =
/// `n_t / n_i`, or `None` under total internal reflection.
pub fn refract(wo: DVec3, eta: f64) -> Option<(DVec3, f64)> {
    let (cos_i, etap, n) = if wo.z >= 0.0 {
        (wo.z, eta, DVec3::Z)
    } else {
        (-wo.z, 1.0 / eta, -DVec3::Z)
    };
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (etap * etap);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-wo / etap + (cos_i / etap - cos_t) * n, etap))
}

impl BxdfModel for Dielectric {
    fn f(&self, _wo: DVec3, _wi: DVec3) -> Rgb {
        Rgb::BLACK
    }

    fn sample(&self, wo: DVec3, uc: f64, _u: [f64; 2]) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let f = fresnel::dielectric(wo.z, self.ior);
        if uc < f {
            let wi = DVec3::new(-wo.x, -wo.y, wo.z);
            return Some(BsdfSample {
                wi,
                f: Rgb::splat(f / wi.z.abs()),
                pdf: f,
                flags: BxdfFlags::REFLECTION | BxdfFlags::SPECULAR,
                eta: 1.0,
            });
        }
        let (wi, etap) = refract(wo, self.ior)?;
        let t = 1.0 - f;
        Some(BsdfSample {
            wi,
            f: Rgb::splat(t / (etap * etap) / wi.z.abs()),
            pdf: t,
            flags: BxdfFlags::TRANSMISSION | BxdfFlags::SPECULAR,
            eta: etap,
        })
    }

    fn pdf(&self, _wo: DVec3, _wi: DVec3) -> f64 {
        0.0
    }

    fn flags(&self) -> BxdfFlags {
        BxdfFlags::REFLECTION | BxdfFlags::TRANSMISSION | BxdfFlags::SPECULAR
    }

    fn albedo(&self) -> Rgb {
        Rgb::WHITE
    }
}
