//! Point lights' light at scattering events inside random-walk media:
//! next-event estimation at a sampled event ([`medium_light`]) and
//! equiangular sampling along a free flight ([`equiangular_light`]),
//! combined by multiple importance sampling.

use super::refraction::{caustic, refracted_irradiance, refraction};
use super::{light_transmittance, mean, transmittance, Media, MediumStack};
use crate::{PointLight, Scene};
use isolux_core::sampling::{power_heuristic, Equiangular};
use isolux_core::{DVec3, Pcg32, Ray, Rgb};
use isolux_geometry::Hit;

/// The point lights that scattering events inside the media `stack` try.
/// Without null boundaries only the lights of the innermost medium (one
/// outside it is occluded by its boundary: no next-event estimation
/// through a delta interface, and no shadow ray is traced to find that
/// out).
pub(super) fn medium_lights<'s>(
    scene: &'s Scene,
    media: &'s Media,
    stack: &MediumStack,
) -> impl Iterator<Item = &'s PointLight> + 's {
    let top = stack.top();
    let null = media.null_boundaries;
    scene
        .lights
        .iter()
        .enumerate()
        .filter(move |(k, _)| null || (top.is_some() && media.lights.get(*k) == Some(&top)))
        .map(|(_, l)| l)
}

/// The light of `light` scattered at `p` inside the media `stack` (phase
/// Henyey-Greenstein with `g`) toward a path travelling along `dir`:
/// `I p(wl . dir) T / d^2` at distance `d` in direction `wl`, with
/// transmittance `T` ([`light_transmittance`]); `None` where the shadow
/// ray is blocked.
fn light_scattered_at(
    scene: &Scene,
    media: &Media,
    stack: &MediumStack,
    light: &PointLight,
    p: DVec3,
    dir: DVec3,
    g: f64,
) -> Option<Rgb> {
    let Some((wl, _, dist2)) = light.toward(p) else {
        return Some(Rgb::BLACK);
    };
    let tr = light_transmittance(scene, media, stack, p, light.position)?;
    let phase = isolux_materials::subsurface::phase::hg(wl.dot(dir), g);
    Some(light.intensity * tr * (phase / dist2))
}

/// The light of `light` that reaches `p`, a scattering point inside the
/// media `stack`, through glass ([`caustic`], from the point itself: no
/// surface to leave), scattered toward a path travelling along `dir`:
/// `E p(wi . dir)` with `E` the caustic's irradiance along `wi`.
pub(super) fn caustic_scattered_at(
    scene: &Scene,
    media: &Media,
    stack: &MediumStack,
    light: &PointLight,
    p: DVec3,
    dir: DVec3,
    g: f64,
) -> Rgb {
    let at = Hit {
        t: 0.0,
        p,
        n: dir,
        offset: 0.0,
    };
    match caustic(scene, media, stack, &at, p, light) {
        Some((wi, e)) => e * isolux_materials::subsurface::phase::hg(wi.dot(dir), g),
        None => Rgb::BLACK,
    }
}

/// A flight through the innermost medium of a path: the ray, the distance
/// `t_end` at which it meets the next surface, the medium's extinction
/// `sigma_t` and scattering `sigma_s` per channel, and the path's
/// [`Spectral`](super::Spectral) ratios at its start. Its scattering
/// points have the density `mean_c r_c sigma_t,c exp(-sigma_t,c t)` on
/// `[0, t_end)` ([`Flight::density`]).
///
/// (Sampling the whole ray `[0, inf)` instead, where the free flight's
/// search had not reached the surface, saved that search but wasted the
/// samples of a lamp outside the medium: on `fog.toml` the noise rose
/// from 0.052 to 0.093 at the same time; docs/subsurface.md.)
#[derive(Clone, Copy, Debug)]
pub(super) struct Flight {
    pub(super) ray: Ray,
    pub(super) t_end: f64,
    pub(super) sigma_t: Rgb,
    pub(super) sigma_s: Rgb,
    pub(super) g: f64,
    pub(super) ratio: Rgb,
}

impl Flight {
    /// The density of a scattering point at `t` over the path's channels
    /// (the balance of their densities, weighted by the path's ratios).
    pub(super) fn density(&self, t: f64) -> f64 {
        mean(self.ratio * self.sigma_t * self.transmittance(t))
    }

    /// The transmittance to `t` per channel (`t` may be infinite).
    pub(super) fn transmittance(&self, t: f64) -> Rgb {
        transmittance(self.sigma_t, t)
    }

    pub(super) fn equiangular(&self, light: &PointLight) -> Option<Equiangular> {
        Equiangular::new(self.ray.origin, self.ray.dir, self.t_end, light.position)
    }
}

/// Light from the point lights that reach `p`, a scattering event of a
/// flight inside the media `stack` at distance `t` along it
/// ([`light_scattered_at`] per light of [`medium_lights`]). With
/// equiangular sampling on, each light's share is weighted against
/// [`equiangular_light`]'s sample of it by the power heuristic. Where a
/// light's shadow ray is blocked and the scene casts caustics, its light
/// through glass ([`caustic_scattered_at`]), unweighted: the scattering
/// points alone sample it (the equiangular sample's shadow ray meets the
/// glass and gathers nothing through it), as surfaces gather caustics
/// only by their next-event estimation.
pub(super) fn medium_light(
    scene: &Scene,
    media: &Media,
    stack: &MediumStack,
    flight: &Flight,
    t: f64,
    equiangular: bool,
    rng: &mut Pcg32,
) -> Rgb {
    let (p, dir) = (flight.ray.at(t), flight.ray.dir);
    let mut l = Rgb::BLACK;
    for light in medium_lights(scene, media, stack) {
        let w = match equiangular.then(|| flight.equiangular(light)).flatten() {
            Some(e) => power_heuristic(flight.density(t), e.pdf(t)),
            None => 1.0,
        };
        match light_scattered_at(scene, media, stack, light, p, dir, flight.g) {
            Some(lit) => l += lit * w,
            None if media.caustics => {
                l += caustic_scattered_at(scene, media, stack, light, p, dir, flight.g);
            }
            None => {}
        }
    }
    // Point lights behind the medium's boundary.
    if media.refracts {
        for (k, light) in scene.lights.iter().enumerate() {
            let Some(r) = refraction(scene, media, stack, k, p, rng) else {
                continue;
            };
            if let Some(e) = refracted_irradiance(scene, media, stack, &r, light, p) {
                l += e * isolux_materials::subsurface::phase::hg(r.wi.dot(dir), flight.g);
            }
        }
    }
    l
}

/// The point lights' light scattered along a whole flight, one
/// equiangular sample per light (Kulla and Fajardo 2012,
/// [`MediumLightSampling::Equiangular`](crate::MediumLightSampling::Equiangular)):
/// `sigma_s exp(-sigma_t t) L(t) / pdf(t)` per channel, weighted against
/// the free flight's scattering point ([`medium_light`]) by the power
/// heuristic. Per unit of the path's throughput at the flight's start.
pub(super) fn equiangular_light(
    scene: &Scene,
    media: &Media,
    stack: &MediumStack,
    flight: &Flight,
    rng: &mut Pcg32,
) -> Rgb {
    let mut l = Rgb::BLACK;
    for light in medium_lights(scene, media, stack) {
        let u = rng.next_f64();
        let Some((t, pdf)) = flight.equiangular(light).and_then(|e| e.sample(u)) else {
            continue;
        };
        if !(t < flight.t_end) {
            continue;
        }
        let w = power_heuristic(pdf, flight.density(t));
        let through = flight.sigma_s * flight.transmittance(t) * (w / pdf);
        if !through.is_black() && through.is_finite() {
            let p = flight.ray.at(t);
            if let Some(lit) =
                light_scattered_at(scene, media, stack, light, p, flight.ray.dir, flight.g)
            {
                l += lit * through;
            }
        }
    }
    l
}
