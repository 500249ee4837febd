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
//! **Participating media** (`subsurface` materials in `random_walk` mode):
//! a path refracted into such an object samples exponential free flights
//! `t = -ln(u) / sigma_t` inside it; a flight that ends before the surface
//! scatters by the Henyey-Greenstein phase function (next-event estimation
//! of the point lights inside the medium, attenuated by it; the
//! environment and lights outside lie behind its boundary, a delta
//! interface, and arrive by the sampled paths alone), one that reaches
//! the surface meets the boundary's Fresnel reflection and refraction.
//! Point lights' light along a flight is also sampled by equiangular
//! sampling, one point per light, and the two estimates are combined by
//! multiple importance sampling ([`crate::MediumLightSampling`]). The
//! coefficients differ per colour channel: a path's flights sample one
//! channel's, the *hero* drawn at its first chromatic medium, and every
//! channel is weighted by spectral MIS over the three (`Spectral`), so
//! paths carry all three channels without colour noise; a grey medium
//! (fog, smoke) is the same in every channel and changes no weight
//! ratio. (Until 2026-12-04 a path carried the hero alone, with weight
//! 3: colour noise.) Events inside a medium (scattering, meeting its
//! boundary) do not count toward `max_depth`; a path is cut after 100,000
//! of them. A bounce on another surface inside a medium counts toward it,
//! as anywhere. Media nest (a marble under water, [`MediumStack`]): a path
//! crossing the boundary of a medium it is in leaves it, and else enters
//! it inside the ones it is in. A camera inside media starts its paths in
//! them ([`crate::Scene::media_at`], found once per render, outermost
//! first): under a white sky of radiance 1, a non-absorbing
//! medium of index `n` around the camera shows `n^2` everywhere, the
//! radiance of equilibrium in it. A surface inside a medium (glass or a
//! metal under water) sees the medium on its outer side: its indices of
//! refraction count relative to the medium's boundary index
//! ([`Material::relative_to`], [`Media::material`]), so that a glass of
//! the water's own index vanishes in it.
//!
//! Spawned rays start at the hit point moved by [`Hit::offset`] along the
//! geometric normal, to the side of the new direction ([`Hit::spawn`]):
//! `1e-7 (1 + |p - origin|_inf) + 1e-14 |p|_inf`, in the frame of the
//! object hit. With the exact, double-precision intersector this removes
//! self-intersection without hiding any feature thicker than that, however
//! far from the world origin the scene lies.

use crate::{MediumLightSampling, Scene};
use isolux_core::sampling::power_heuristic;
use isolux_core::{DVec3, Frame, Pcg32, Ray, Rgb, PI};
use isolux_geometry::{Culled, Hit};
use isolux_materials::subsurface::phase::sample_hg_cos;
use isolux_materials::subsurface_material::SubsurfaceMode;
use isolux_materials::{Bsdf, BxdfFlags, BxdfModel, Material, Subsurface};
use std::sync::atomic::Ordering;

mod dipole;
mod media;
mod medium;
mod refraction;

use dipole::{bssrdf_entry, single_scattering_light};
pub use media::{Media, MediumStack, MAX_NESTED_MEDIA};
use medium::{equiangular_light, medium_light, medium_lights, Flight};
use refraction::{caustic, refracted_irradiance, refraction};

/// Maximum scattering and boundary events of one path inside media. A
/// path that reaches it ends there, its light so far kept and the rest
/// lost, and is counted in [`Media::capped`]: it bounds a sample's cost
/// in a medium too thick for a walk (a camera deep inside one whose mean
/// free path is a ten-thousandth of its size needs some 10^8 events to
/// leave it), and [`crate::RenderStats::capped_paths`] says that the
/// image is darker there than the medium's light.
pub const MAX_MEDIUM_EVENTS: u32 = 100_000;

fn channel(c: Rgb, i: usize) -> f64 {
    match i {
        0 => c.r,
        1 => c.g,
        _ => c.b,
    }
}

/// `exp(-sigma_t d)` per channel: the transmittance over a distance `d`
/// (which may be infinite) of a medium of extinction `sigma_t`.
fn transmittance(sigma_t: Rgb, d: f64) -> Rgb {
    sigma_t.map(|s| if s > 0.0 { (-s * d).exp() } else { 1.0 })
}

/// The medium behind object `obj`'s surface (its material's), if any.
fn object_medium(scene: &Scene, obj: usize) -> Option<&Subsurface> {
    scene.materials[scene.object_material[obj]].medium()
}

/// The mean of the three channels.
fn mean(c: Rgb) -> f64 {
    (c.r + c.g + c.b) / 3.0
}

/// Spectral MIS over a path's colour channels (the hero scheme of Wilkie
/// et al. 2014, as in pbrt-v4): the free flights of a path through
/// chromatic media are sampled with one channel's coefficients, the
/// *hero*, drawn uniformly at the path's first flight in such a medium,
/// and every channel is weighted by the balance heuristic over the three
/// channels' densities of the whole path. The throughput `beta` holds
/// `f_c / mean_k p_k` per channel directly; `ratio` holds each channel's
/// path density relative to their mean (`mean ratio = 1`), updated with
/// every flight's densities `p` per channel: `beta *= f / mean(ratio
/// p)`, `ratio = ratio p / mean(ratio p)`. The hero's density cancels.
/// Every channel's weight stays within 3 of its own estimate, so paths
/// carry all three channels without colour noise; in a medium that
/// loses nothing (`f = p` per channel) `beta` equals `ratio`, whose
/// channels sum to exactly 3, as one channel carried with weight 3 did.
/// A grey medium's densities are the same in every channel: its flights
/// change no ratio.
#[derive(Clone, Copy, Debug)]
struct Spectral {
    hero: Option<usize>,
    ratio: Rgb,
}

impl Spectral {
    /// Weights `beta` for a flight event of densities `p` and
    /// contribution `f` per channel.
    fn update(&mut self, beta: &mut Rgb, f: Rgb, p: Rgb) {
        let m = mean(self.ratio * p);
        if m > 0.0 {
            *beta *= f / m;
            self.ratio = self.ratio * p / m;
        } else {
            *beta = Rgb::BLACK;
        }
    }
}

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

/// Next-event estimation at `p` (geometric normal `n`): point lights, and
/// the environment map with multiple importance sampling against the
/// scattering density. `f_cos_pdf(wi, need_pdf)` returns `f |cos|` and (when
/// `need_pdf`) the density with which the path would continue toward `wi`.
/// `stack`: the media the path is in at `p`; a point light's shadow ray
/// is attenuated by them and passes through null boundaries
/// ([`light_transmittance`]). The environment is never reached from inside
/// a medium: its boundary occludes it, and a path that crosses a null
/// boundary reaches the environment as a specular continuation (weight 1),
/// so the two strategies still sum to one.
fn direct_light(
    scene: &Scene,
    media: &Media,
    stack: &MediumStack,
    hit: &Hit,
    rng: &mut Pcg32,
    f_cos_pdf: impl Fn(DVec3, bool) -> (Rgb, f64),
) -> Rgb {
    let mut l = Rgb::BLACK;
    for light in &scene.lights {
        let origin = hit.spawn(light.position - hit.p);
        let Some((wi, _, dist2)) = light.toward(origin) else {
            continue;
        };
        let (fc, _) = f_cos_pdf(wi, false);
        if fc.is_black() {
            continue;
        }
        if let Some(tr) = light_transmittance(scene, media, stack, origin, light.position) {
            l += fc * light.intensity * tr / dist2;
        } else if media.caustics {
            if let Some((wi, e)) = caustic(scene, media, stack, hit, origin, light) {
                let (fc, _) = f_cos_pdf(wi, false);
                l += fc * e;
            }
        }
    }
    // Point lights behind the boundary of the medium around `p`.
    if media.refracts {
        for (k, light) in scene.lights.iter().enumerate() {
            let Some(r) = refraction(scene, media, stack, k, hit.p, rng) else {
                continue;
            };
            let (fc, _) = f_cos_pdf(r.wi, false);
            if fc.is_black() {
                continue;
            }
            if let Some(e) = refracted_irradiance(scene, media, stack, &r, light, hit.spawn(r.wi)) {
                l += fc * e;
            }
        }
    }
    let env = &scene.environment;
    if env.is_sampled() {
        if let Some(s) = env.sample(rng.next_2d()) {
            let (fc, pdf) = f_cos_pdf(s.wi, true);
            if !fc.is_black() && !s.radiance.is_black() {
                let origin = hit.spawn(s.wi);
                if !scene
                    .geometry
                    .occluded(&Ray::new(origin, s.wi), 0.0, f64::INFINITY)
                {
                    let w = power_heuristic(s.pdf, pdf);
                    l += fc * s.radiance * (w / s.pdf);
                }
            }
        }
    }
    l
}

/// The transmittance from `origin`, on a path inside the media `stack`,
/// to a point light at `light`; `None` where a surface is in the way.
/// Each medium's segment attenuates by `exp(-sigma_t d)` per channel. A
/// *null boundary* (a random-walk medium whose index equals the index on
/// its other side: fog of index 1 in air, a jelly of the water's index in
/// water) bends no ray, so the shadow ray passes through it, into or out
/// of its medium ([`Media::null_boundaries`]); every other surface
/// occludes.
fn light_transmittance(
    scene: &Scene,
    media: &Media,
    stack: &MediumStack,
    origin: DVec3,
    light: DVec3,
) -> Option<Rgb> {
    let medium_of = |obj: usize| object_medium(scene, obj);
    let extinction = |stack: &MediumStack, d: f64| match stack.top().and_then(medium_of) {
        Some(m) => transmittance(m.sigma_t(), d),
        None => Rgb::WHITE,
    };
    let (mut o, mut stack) = (origin, *stack);
    let mut tr = Rgb::WHITE;
    for _ in 0..MAX_NESTED_MEDIA * 8 {
        let to = light - o;
        let dist = to.length();
        if !(dist > 0.0) {
            return Some(tr);
        }
        let ray = Ray::new(o, to / dist);
        if !media.null_boundaries {
            return (!scene.geometry.occluded(&ray, 0.0, dist))
                .then(|| tr * extinction(&stack, dist));
        }
        let Some((obj, hit)) = scene.geometry.intersect(&ray, 0.0, dist) else {
            return Some(tr * extinction(&stack, dist));
        };
        let m = medium_of(obj).filter(|m| m.mode == SubsurfaceMode::RandomWalk)?;
        let outside = stack
            .outside_of(obj)
            .and_then(medium_of)
            .map_or(1.0, |o| o.boundary.ior);
        if m.boundary.ior != outside {
            return None;
        }
        tr *= extinction(&stack, hit.t);
        stack.cross(obj)?;
        o = hit.spawn(ray.dir);
    }
    None
}

/// Russian roulette on the throughput `beta` with the refraction scale
/// undone: survival probability `min(1, max(beta * eta_scale))`, survivors
/// reweighted. `None` ends the path (also for a black throughput).
fn russian_roulette(beta: Rgb, eta_scale: f64, rng: &mut Pcg32) -> Option<Rgb> {
    let q = (beta * eta_scale).max_component();
    let beta = if q < 1.0 {
        if rng.next_f64() >= q {
            return None;
        }
        beta / q
    } else {
        beta
    };
    (!beta.is_black()).then_some(beta)
}

/// Radiance arriving along `ray` (from the camera), and the first hit. A
/// ray starting inside random-walk media starts in them
/// ([`crate::Scene::media_at`]).
pub fn radiance(scene: &Scene, ray: Ray, rng: &mut Pcg32) -> (Rgb, Option<FirstHit>) {
    radiance_culled(scene, ray, None, &Media::new(scene, ray.origin), rng)
}

/// [`radiance`] for a camera ray inside the beam that `primary` was culled
/// for ([`isolux_geometry::Aggregate::cull`]): its first intersection
/// tests only the culled objects and perturbations (the same hit, found
/// faster); the rest of the path is unchanged. `media` tells the medium
/// the ray starts in (the camera's) and those of the lights, looked up
/// once for all the rays of a render.
pub fn radiance_culled(
    scene: &Scene,
    mut ray: Ray,
    primary: Option<&Culled>,
    media: &Media,
    rng: &mut Pcg32,
) -> (Rgb, Option<FirstHit>) {
    let mut primary = primary;
    let mut l = Rgb::BLACK;
    let mut beta = Rgb::WHITE;
    // Pdf of the BSDF sample that produced `ray` (None: camera or delta).
    let mut prev_pdf: Option<f64> = None;
    let mut first = None;
    let env = &scene.environment;
    let max_depth = scene.integrator.max_depth;
    let mut depth = 0u32;
    let mut eta_scale = 1.0;
    // The media the path is in, and its colour channels' ratios.
    let mut spectral = Spectral {
        hero: None,
        ratio: Rgb::WHITE,
    };
    let mut stack = MediumStack::default();
    for &(i, _) in &media.camera {
        stack.push(i);
    }
    let medium_of = |obj: usize| object_medium(scene, obj);
    let mut medium_events = 0u32;
    // The environment along the current ray was already counted (the
    // mirror reflection of a subsurface boundary, below).
    let mut env_counted = false;
    loop {
        // Free flight inside a medium limits the search for the surface,
        // unless equiangular sampling needs the whole flight: then the
        // search runs to the next surface, and the flight's lights are
        // sampled along it.
        let inside = stack.top().and_then(medium_of);
        let mut t_max = f64::INFINITY;
        let mut flight = None;
        if let Some(m) = inside {
            let st = m.sigma_t();
            if !st.is_black() {
                // The hero channel's free flight (drawn at the first
                // chromatic medium; a grey medium's are all the same).
                let c = if m.is_grey() {
                    spectral.hero.unwrap_or(0)
                } else {
                    *spectral
                        .hero
                        .get_or_insert_with(|| rng.next_below(3) as usize)
                };
                let stc = channel(st, c);
                if stc > 0.0 {
                    t_max = -(1.0 - rng.next_f64()).ln() / stc;
                }
                flight = Some(Flight {
                    ray,
                    t_end: f64::INFINITY,
                    sigma_t: st,
                    sigma_s: m.sigma_s,
                    g: m.g,
                    ratio: spectral.ratio,
                });
            }
        }
        let equiangular = media.gathers
            && scene.integrator.medium_lights == MediumLightSampling::Equiangular
            && flight.as_ref().is_some_and(|f| !f.sigma_s.is_black())
            && medium_lights(scene, media, &stack).next().is_some();
        let t_search = if equiangular { f64::INFINITY } else { t_max };
        let mut found = match primary.take() {
            Some(culled) => scene.geometry.intersect_culled(&ray, 0.0, t_search, culled),
            None => scene.geometry.intersect(&ray, 0.0, t_search),
        };
        if let (true, Some(f)) = (equiangular, flight.as_mut()) {
            f.t_end = found.map_or(f64::INFINITY, |(_, h)| h.t);
            l += beta * equiangular_light(scene, media, &stack, f, rng);
            found = found.filter(|(_, h)| h.t <= t_max);
        }
        // The flight passing the surface (or leaving for good): its
        // transmittance is its probability and its contribution, per
        // channel ([`Spectral`]).
        if let Some(f) = flight
            .as_ref()
            .filter(|_| found.is_some() || !t_max.is_finite())
        {
            let tr = f.transmittance(found.map_or(f64::INFINITY, |(_, h)| h.t));
            spectral.update(&mut beta, tr, tr);
        }
        if let (None, Some(m), Some(f)) = (&found, inside, &flight) {
            if t_max.is_finite() {
                // Scattering event inside the medium.
                medium_events += 1;
                if medium_events > MAX_MEDIUM_EVENTS {
                    media.capped.fetch_add(1, Ordering::Relaxed);
                    break;
                }
                let tr = f.transmittance(t_max);
                spectral.update(&mut beta, f.sigma_s * tr, f.sigma_t * tr);
                let p = ray.at(t_max);
                // Point lights, by next-event estimation (the environment
                // lies behind the medium's boundary).
                l += beta * medium_light(scene, media, &stack, f, t_max, equiangular, rng);
                match russian_roulette(beta, eta_scale, rng) {
                    Some(b) => beta = b,
                    None => break,
                }
                let cos_t = sample_hg_cos(m.g, rng.next_f64());
                let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
                let phi = 2.0 * PI * rng.next_f64();
                let f = Frame::from_normal(ray.dir);
                let dir = f.to_world(DVec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t));
                ray = Ray::new(p, dir.normalize());
                prev_pdf = None;
                env_counted = false;
                continue;
            }
        }
        let Some((obj, hit)) = found else {
            let le = env.eval(ray.dir);
            let w = match prev_pdf {
                _ if env_counted => 0.0,
                Some(p) if env.is_sampled() => power_heuristic(p, env.pdf(ray.dir)),
                _ => 1.0,
            };
            l += beta * le * w;
            break;
        };
        // Spatially varying materials (wave optics) are placed at the hit:
        // camera rays narrow their query to the pixel footprint, the
        // angle of one pixel times the distance.
        let footprint =
            (depth == 0).then(|| scene.camera.pixel_footprint(hit.t, scene.film.height));
        let placed =
            media
                .material(scene, obj, stack.outside_of(obj))
                .at_point(hit.p, footprint, || rng.next_f64());
        let material: &Material = &placed;
        if depth == 0 {
            first = Some(FirstHit {
                albedo: material.albedo(),
                normal: hit.n,
                depth: hit.t,
            });
        }
        // A surface inside a medium ends the path at `max_depth` like any
        // other; the medium's own boundary, met from inside, lets it out.
        if depth >= max_depth && (stack.is_empty() || material.medium().is_none()) {
            break;
        }
        let wo = -ray.dir;
        let bsdf = match material.tangent() {
            Some(t) => Bsdf::with_tangent(material, hit.n, t, wo),
            None => Bsdf::new(material, hit.n, wo),
        };
        let ns = bsdf.normal();

        // Inside media (a surface in them, a dipole medium's too), lights
        // are seen through them (a medium's own boundary, a delta
        // interface, gathers none).
        l += beta
            * direct_light(scene, media, &stack, &hit, rng, |wi, need_pdf| {
                // The density only weighs environment samples (MIS); point
                // lights skip it (costly for wave-optics materials).
                let pdf = if need_pdf { bsdf.pdf(wo, wi) } else { 0.0 };
                (bsdf.f(wo, wi) * wi.dot(ns).abs(), pdf)
            });
        // Single scattering of the dipole mode (Jensen's S^(1)), a local
        // lobe at x_o, estimated here for direct light only.
        if let Some(m) = material.medium() {
            if m.mode == SubsurfaceMode::Dipole && m.single_scattering && wo.dot(hit.n) > 0.0 {
                l += beta * single_scattering_light(scene, media, &stack, m, &hit, wo, rng);
            }
        }
        // The environment mirrored by a subsurface boundary, seen from
        // outside, is added here with its Fresnel weight on every path;
        // the random choice of reflection below then only carries what the
        // mirror ray meets in the scene (its escape adds nothing). Without
        // this the choice (probability F) makes the sun's reflection a
        // few very bright samples: the dominant noise of a translucent
        // object under a sky (docs/subsurface.md).
        let mirror_env = match material.medium() {
            Some(m) if wo.dot(ns) > 0.0 => {
                let cos = wo.dot(ns);
                let r = 2.0 * cos * ns - wo;
                let origin = hit.spawn(r);
                if !scene
                    .geometry
                    .occluded(&Ray::new(origin, r), 0.0, f64::INFINITY)
                {
                    let f = isolux_materials::fresnel::dielectric(cos, m.boundary.ior);
                    l += beta * env.eval(r) * f;
                }
                true
            }
            _ => false,
        };
        env_counted = false;

        // BSDF sampling.
        let uc = rng.next_f64();
        let Some(s) = bsdf.sample(wo, uc, rng.next_2d()) else {
            break;
        };
        if mirror_env && s.flags.contains(BxdfFlags::REFLECTION) {
            env_counted = true;
        }
        // Dipole BSSRDF: light refracted into the medium re-emerges at x_o
        // from an entry point x_i sampled around it (the choice of
        // transmission, probability 1 - F(cos_o), cancels the factor
        // 1 - F(cos_o) of S).
        if let Some(m) = material.medium() {
            if m.mode == SubsurfaceMode::Dipole && s.flags.contains(BxdfFlags::TRANSMISSION) {
                let Some((xi, w)) = bssrdf_entry(scene, obj, m, &hit, rng) else {
                    break;
                };
                beta *= w;
                // At x_i: light arriving through the boundary, weighted by
                // S_w(wi) = (1 - F(cos_i)) / (c pi).
                l += beta
                    * direct_light(scene, media, &stack, &xi, rng, |wi, _| {
                        let c = wi.dot(xi.n);
                        if c <= 0.0 {
                            (Rgb::BLACK, 0.0)
                        } else {
                            (Rgb::splat(m.sw(c) * c), c * isolux_core::INV_PI)
                        }
                    });
                let local = isolux_core::sampling::cosine_hemisphere(rng.next_2d());
                if local.z <= 0.0 {
                    break;
                }
                let wl = Frame::from_normal(xi.n).to_world(local);
                beta *= m.sw(local.z) * PI;
                prev_pdf = Some(local.z * isolux_core::INV_PI);
                ray = Ray::new(xi.spawn(wl), wl);
                depth += 1;
                if depth >= 3 {
                    match russian_roulette(beta, eta_scale, rng) {
                        Some(b) => beta = b,
                        None => break,
                    }
                }
                continue;
            }
        }
        beta *= s.weight(s.wi.dot(ns));
        eta_scale *= s.eta * s.eta;
        // Crossing a medium's boundary leaves it if the path is inside
        // it, and else enters it (inside the media it is in: they nest).
        if s.flags.contains(BxdfFlags::TRANSMISSION)
            && material.medium().is_some()
            && stack.cross(obj).is_none()
        {
            break;
        }
        prev_pdf = if s.flags.is_specular() {
            None
        } else {
            Some(s.pdf)
        };
        ray = Ray::new(hit.spawn(s.wi), s.wi);
        // Meetings with a medium's boundary (crossing it, or reflected
        // inside) are medium events; a bounce on any other surface counts
        // toward the depth, also inside a medium.
        if material.medium().is_some()
            && (!stack.is_empty() || s.flags.contains(BxdfFlags::TRANSMISSION))
        {
            medium_events += 1;
            if medium_events > MAX_MEDIUM_EVENTS {
                media.capped.fetch_add(1, Ordering::Relaxed);
                break;
            }
        } else {
            depth += 1;
        }

        if depth >= 3 {
            match russian_roulette(beta, eta_scale, rng) {
                Some(b) => beta = b,
                None => break,
            }
        } else if beta.is_black() {
            break;
        }
    }
    (l, first)
}
