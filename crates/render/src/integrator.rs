//! Unidirectional path tracer.
//!
//! At every surface vertex:
//! 1. **Point lights** by next-event estimation (shadow ray, `f cos I / r^2`),
//!    kept separate from the environment, as the seed prescribes;
//! 2. **Environment map** by light sampling with multiple importance sampling
//!    (power heuristic) against BSDF sampling; a constant environment is
//!    reached by BSDF sampling only (see [`crate::environment`]);
//! 3. **BSDF sampling** for the next direction; a ray that escapes adds the
//!    environment radiance with the matching MIS weight.
//!
//! Russian roulette starts after three bounces with survival probability
//! `min(1, max(throughput * eta_scale))`, so a white furnace (throughput 1)
//! is never cut short and stays noise-free. `eta_scale` accumulates `eta'^2`
//! of every refraction (pbrt-v4 §14.1.4): the radiance compression inside
//! glass (throughput `1/eta^2`) is undone on the way out and must not be
//! mistaken for absorption. Paths end after `max_depth` scattering
//! events.
//!
//! Spawned rays start at the hit point moved by `1e-7 (1 + |p|_inf)` along
//! the geometric normal, to the side of the new direction: with the exact,
//! double-precision intersector this removes self-intersection without
//! hiding any feature thicker than that.

use crate::Scene;
use isolux_core::{sampling::power_heuristic, DVec3, Pcg32, Ray, Rgb};
use isolux_materials::{Bsdf, BxdfModel};

/// What the first camera-ray hit saw (for AOVs).
#[derive(Clone, Copy, Debug, Default)]
pub struct FirstHit {
    /// Material albedo.
    pub albedo: Rgb,
    /// Outward normal.
    pub normal: DVec3,
    /// Distance.
    pub depth: f64,
}

/// Moves `p` off the surface along `n` to the side of `w`.
#[inline]
pub fn offset_origin(p: DVec3, n: DVec3, w: DVec3) -> DVec3 {
    let eps = 1e-7 * (1.0 + p.abs().max_element());
    if w.dot(n) >= 0.0 {
        p + n * eps
    } else {
        p - n * eps
    }
}

/// Radiance arriving along `ray` (from the camera), and the first hit.
pub fn radiance(scene: &Scene, mut ray: Ray, rng: &mut Pcg32) -> (Rgb, Option<FirstHit>) {
    let mut l = Rgb::BLACK;
    let mut beta = Rgb::WHITE;
    // Pdf of the BSDF sample that produced `ray` (None: camera or delta).
    let mut prev_pdf: Option<f64> = None;
    let mut first = None;
    let env = &scene.environment;
    let max_depth = scene.integrator.max_depth;
    let mut depth = 0u32;
    let mut eta_scale = 1.0;
    loop {
        let Some((obj, hit)) = scene.geometry.intersect(&ray, 0.0, f64::INFINITY) else {
            let le = env.eval(ray.dir);
            let w = match prev_pdf {
                Some(p) if env.is_sampled() => power_heuristic(p, env.pdf(ray.dir)),
                _ => 1.0,
            };
            l += beta * le * w;
            break;
        };
        let material = &scene.materials[scene.object_material[obj]];
        if depth == 0 {
            first = Some(FirstHit {
                albedo: material.albedo(),
                normal: hit.n,
                depth: hit.t,
            });
        }
        if depth >= max_depth {
            break;
        }
        let wo = -ray.dir;
        let bsdf = match material.tangent() {
            Some(t) => Bsdf::with_tangent(material, hit.n, t, wo),
            None => Bsdf::new(material, hit.n, wo),
        };
        let ns = bsdf.normal();

        // Point lights.
        for light in &scene.lights {
            let origin = offset_origin(hit.p, hit.n, light.position - hit.p);
            let d = light.position - origin;
            let dist2 = d.length_squared();
            if !(dist2 > 0.0) {
                continue;
            }
            let dist = dist2.sqrt();
            let wi = d / dist;
            let f = bsdf.f(wo, wi);
            if f.is_black() {
                continue;
            }
            if !scene.geometry.occluded(&Ray::new(origin, wi), 0.0, dist) {
                l += beta * f * light.intensity * (wi.dot(ns).abs() / dist2);
            }
        }

        // Environment map light sampling.
        if env.is_sampled() {
            if let Some(s) = env.sample(rng.next_2d()) {
                let f = bsdf.f(wo, s.wi);
                if !f.is_black() && !s.radiance.is_black() {
                    let origin = offset_origin(hit.p, hit.n, s.wi);
                    if !scene
                        .geometry
                        .occluded(&Ray::new(origin, s.wi), 0.0, f64::INFINITY)
                    {
                        let w = power_heuristic(s.pdf, bsdf.pdf(wo, s.wi));
                        l += beta * f * s.radiance * (s.wi.dot(ns).abs() * w / s.pdf);
                    }
                }
            }
        }

        // BSDF sampling.
        let uc = rng.next_f64();
        let Some(s) = bsdf.sample(wo, uc, rng.next_2d()) else {
            break;
        };
        beta *= s.weight(s.wi.dot(ns));
        eta_scale *= s.eta * s.eta;
        prev_pdf = if s.flags.is_specular() {
            None
        } else {
            Some(s.pdf)
        };
        ray = Ray::new(offset_origin(hit.p, hit.n, s.wi), s.wi);
        depth += 1;

        if depth >= 3 {
            let q = (beta * eta_scale).max_component();
            if q < 1.0 {
                if rng.next_f64() >= q {
                    break;
                }
                beta = beta / q;
            }
        }
        if beta.is_black() {
            break;
        }
    }
    (l, first)
}
