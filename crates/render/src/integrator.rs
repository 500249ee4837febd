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

use crate::scene::FlatBoundary;
use crate::{MediumLightSampling, PointLight, RefractedLights, Scene};
use isolux_core::sampling::{power_heuristic, Equiangular};
use isolux_core::{DVec3, Frame, Pcg32, Ray, Rgb, PI};
use isolux_geometry::{Culled, Hit};
use isolux_materials::subsurface::phase::sample_hg_cos;
use isolux_materials::subsurface_material::SubsurfaceMode;
use isolux_materials::{Bsdf, BxdfFlags, BxdfModel, Material, Subsurface};
use std::sync::atomic::{AtomicU64, Ordering};

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

/// A point light's connection into a medium through its boundary, flat
/// or curved: the direction `wi` from the point inside toward the
/// crossing point `c` on the boundary (outward normal `normal` there), the
/// distance `inside` to it, and `factor`, the Fresnel transmittance times
/// the refracted inverse square law ([`refraction`]).
#[derive(Clone, Copy, Debug)]
struct Refraction {
    obj: usize,
    wi: DVec3,
    inside: f64,
    c: DVec3,
    normal: DVec3,
    factor: f64,
}

/// The path from point light `k` of `scene` to `p`, a point inside the
/// innermost medium of `stack`, where that medium is bounded by a plane
/// (`Media::flat`) and the light lies in the medium just outside it, of
/// another index (a sun above water): the point lights of a medium
/// behind a smooth plane reach it by refraction, which a shadow ray
/// cannot find but a solve can. The crossing point `c` obeys Snell's law,
/// `n2 sin theta_2 = n1 sin theta_1` (inside, outside), found by
/// safeguarded Newton steps along the line between the feet of `p` and
/// the light (the mismatch is monotone in it). The light's irradiance at `p`, normal to the refracted
/// ray, is `I T(theta_1) G` with the Fresnel transmittance `T` and
///
/// `G = sin theta_1 / (R cos theta_2 dR/dtheta_1)`,
/// `R = h1 tan theta_1 + h2 tan theta_2`,
/// `dR/dtheta_1 = h1 / cos^2 theta_1 + h2 / cos^2 theta_2 (n1 cos theta_1) / (n2 cos theta_2)`,
///
/// the flux `I T dw_1` of the light's cone spread over the area it lights
/// at depth `h2` (`h1` the light's height above the plane): `1 / r^2` when
/// `n1 = n2`, and `1 / (h1 + h2 n1 / n2)^2` straight below the light.
/// Attenuation and occlusion are left to [`refracted_irradiance`].
///
/// Where the boundary is curved (any other random-walk object), the
/// crossing is found by manifold next-event estimation instead
/// ([`crate::manifold`], with [`RefractedLights::Manifold`]): the same
/// `I T G` with `G` measured by the solve. Its cost is paid only where
/// the light can matter: a connection is tried with probability
/// `q = exp(-sigma_t d)` (`sigma_t` the medium's smallest channel, `d`
/// the straight distance from `p` to the boundary toward the light), the
/// attenuation it will meet, and its factor divided by `q` (Russian
/// roulette: unbiased, and deep scattering events, whose light the
/// medium absorbs, rarely pay for a solve). On
/// `translucent-random-walk.toml` (240 x 135, 16 spp) this took 1.05 s
/// against 1.60 s for `q = min(1, 10 exp(-sigma_t d))`, with the same
/// noise within its spread over seeds; without the connections
/// ([`RefractedLights::Flat`]) 0.59 s.
fn refraction(
    scene: &Scene,
    media: &Media,
    stack: &MediumStack,
    k: usize,
    p: DVec3,
    rng: &mut Pcg32,
) -> Option<Refraction> {
    let obj = stack.top()?;
    let outside = stack.outside_of(obj);
    if media.lights.get(k) != Some(&outside) {
        return None;
    }
    let medium = object_medium(scene, obj)?;
    let n2 = medium.boundary.ior;
    let n1 = outside
        .and_then(|o| object_medium(scene, o))
        .map_or(1.0, |m| m.boundary.ior);
    if n1 == n2 {
        return None;
    }
    let light = scene.lights[k].position;
    let Some(b) = media.flat.iter().find(|(o, _)| *o == obj).map(|f| f.1) else {
        if scene.integrator.refracted_lights != RefractedLights::Manifold {
            return None;
        }
        return manifold_refraction(scene, obj, medium, p, light, n1, n2, rng);
    };
    let n = b.normal;
    let (h1, h2) = (n.dot(light) - b.offset, b.offset - n.dot(p));
    if !(h1 > 0.0) || !(h2 > 0.0) {
        return None;
    }
    let u = (light - p) - n.dot(light - p) * n;
    let d = u.length();
    let along = if d > 0.0 { u / d } else { DVec3::ZERO };
    // s: the crossing's distance from the foot of p along the feet's line,
    // where the mismatch of Snell's law (increasing in s) vanishes: Newton
    // steps from the straight line's crossing, kept inside the bracket
    // (bisection where a step would leave it).
    let mismatch = |s: f64| {
        let (a, b) = (s * s + h2 * h2, (d - s) * (d - s) + h1 * h1);
        let (ra, rb) = (a.sqrt(), b.sqrt());
        let f = n2 * s / ra - n1 * (d - s) / rb;
        let df = n2 * h2 * h2 / (a * ra) + n1 * h1 * h1 / (b * rb);
        (f, df)
    };
    let (mut lo, mut hi) = (0.0, d);
    let mut s = d * h2 / (h1 + h2);
    let tol = 1e-13 * (d + h1 + h2);
    for _ in 0..80 {
        let (f, df) = mismatch(s);
        let step = f / df;
        if !(step.abs() > tol) {
            if step.is_finite() {
                s -= step;
            }
            break;
        }
        if f < 0.0 {
            lo = s;
        } else {
            hi = s;
        }
        let next = s - step;
        s = if next > lo && next < hi {
            next
        } else {
            0.5 * (lo + hi)
        };
    }
    let c = p + s * along + h2 * n;
    if !in_box(&b.bbox, c, 1e-9, scene.geometry.objects()[obj].length()) {
        return None;
    }
    let (l1, l2) = (
        ((d - s) * (d - s) + h1 * h1).sqrt(),
        (s * s + h2 * h2).sqrt(),
    );
    if !(l2 > 0.0) {
        return None;
    }
    let (cos1, sin1, cos2) = (h1 / l1, (d - s) / l1, h2 / l2);
    let g = if d <= 1e-12 * (h1 + h2) {
        1.0 / (h1 + h2 * n1 / n2).powi(2)
    } else {
        let dr = h1 / (cos1 * cos1) + h2 / (cos2 * cos2) * (n1 * cos1) / (n2 * cos2);
        sin1 / (d * cos2 * dr)
    };
    let t = 1.0 - isolux_materials::fresnel::dielectric(cos1, n2 / n1);
    let factor = t * g;
    (factor > 0.0 && factor.is_finite()).then(|| Refraction {
        obj,
        wi: (c - p) / l2,
        inside: l2,
        c,
        normal: n,
        factor,
    })
}

/// [`refraction`] through the curved boundary of object `obj` (medium
/// `medium`, index `n2` inside, `n1` outside), by [`crate::manifold`].
///
/// A connection is tried with probability `q = exp(-sigma_min d)`, the
/// attenuation along the straight segment to the light up to its crossing
/// `d` (Russian roulette, weight `1 / q`), decided in two stages so that
/// most declined tries cost no exact intersection: first with `q_1 =
/// exp(-sigma_min d_1)` for a lower bound `d_1 <= d` from closed forms
/// ([`isolux_geometry::Object::exit_bound`]: the base quadric's crossing,
/// or a dent's support if sooner), then, the seed found, with `q_2 = q /
/// q_1`: together `q`, the single stage's estimator. (`q_2` is capped at
/// 1 against rounding.)
#[allow(clippy::too_many_arguments)]
fn manifold_refraction(
    scene: &Scene,
    obj: usize,
    medium: &Subsurface,
    p: DVec3,
    light: DVec3,
    n1: f64,
    n2: f64,
    rng: &mut Pcg32,
) -> Option<Refraction> {
    let o = &scene.geometry.objects()[obj];
    let to_light = light - p;
    let dist = to_light.length();
    if !(dist > 0.0) {
        return None;
    }
    let ray = Ray::new(p, to_light / dist);
    let st = medium.sigma_t();
    let sigma = st.r.min(st.g).min(st.b);
    let d1 = o.exit_bound(&ray, dist);
    let q1 = (-sigma * d1).exp();
    if !(q1 > 0.0) || (q1 < 1.0 && rng.next_f64() >= q1) {
        return None;
    }
    let seed = o.intersect(&ray, 0.0, dist)?;
    let q2 = ((-sigma * seed.t).exp() / q1).min(1.0);
    if !(q2 > 0.0) || (q2 < 1.0 && rng.next_f64() >= q2) {
        return None;
    }
    let q = q1 * q2;
    let c = crate::manifold::connect_from(o, p, light, n2, n1, seed.p)?;
    // On the surface as the object's box clips it (a quadric with
    // `bounds`): beyond it the solution crosses no boundary. (The seed,
    // clipped by the same box, refuses most such; a drop cut by a box
    // through its cap renders the same with and without this test.)
    if !in_box(&o.bbox(), c.x, 1e-7, o.length()) {
        return None;
    }
    let t = 1.0 - isolux_materials::fresnel::dielectric(c.cos_out, n2 / n1);
    let factor = t * c.spread / q;
    let inside = (c.x - p).length();
    (factor > 0.0 && factor.is_finite() && inside > 0.0).then(|| Refraction {
        obj,
        wi: (c.x - p) / inside,
        inside,
        c: c.x,
        normal: c.normal,
        factor,
    })
}

/// A point light's path to the surface point of `hit` through a glass
/// object ([`crate::Caustics::Manifold`]): where the shadow ray from `origin`
/// (the point spawned toward the light) first enters an object of a
/// smooth `dielectric` material and leaves it again before the light,
/// the path through it that obeys Snell's law at both crossings
/// ([`crate::manifold::connect_through`], seeded with the straight
/// segment's crossings). Returns the direction `wi` from the point
/// toward the exit crossing and the irradiance arriving along it
/// (normal to it, per channel): `I T_0 T_1 G`, the Fresnel
/// transmittances of both crossings and the spreading, attenuated by the
/// medium around the point (`stack`'s innermost) on the way out and by
/// [`light_transmittance`] from the entry crossing to the light. `None`
/// where the shadow ray meets anything else first, the solve fails, or
/// the solved path is blocked: its leg toward the point meets something
/// before the exit crossing, or its leg inside meets anything before
/// the entry crossing. No other strategy reaches a point light through
/// glass, so nothing is weighted against it.
fn caustic(
    scene: &Scene,
    media: &Media,
    stack: &MediumStack,
    hit: &Hit,
    origin: DVec3,
    light: &PointLight,
) -> Option<(DVec3, Rgb)> {
    let to_light = light.position - origin;
    let dist = to_light.length();
    if !(dist > 0.0) {
        return None;
    }
    let ray = Ray::new(origin, to_light / dist);
    let (obj, entry) = scene.geometry.intersect(&ray, 0.0, dist)?;
    let Material::Dielectric(glass) = &scene.materials[scene.object_material[obj]] else {
        return None;
    };
    let o = &scene.geometry.objects()[obj];
    // Entering (against the outward normal), then leaving the same object
    // short of the light.
    if !(ray.dir.dot(entry.n) < 0.0) {
        return None;
    }
    let inside = entry.spawn(ray.dir);
    let (exit_obj, exit) = scene.geometry.intersect(
        &Ray::new(inside, ray.dir),
        0.0,
        (light.position - inside).dot(ray.dir),
    )?;
    if exit_obj != obj {
        return None;
    }
    let around = stack.top().and_then(|m| object_medium(scene, m));
    let n_out = around.map_or(1.0, |m| m.boundary.ior);
    let chain = crate::manifold::connect_through(
        o,
        hit.p,
        light.position,
        glass.ior,
        n_out,
        [entry.p, exit.p],
    )?;
    let bbox = o.bbox();
    let length = o.length();
    if !chain.x.iter().all(|&x| in_box(&bbox, x, 1e-7, length)) {
        return None;
    }
    // The first surface the ray from `from` toward `to` meets within
    // their distance (and a little beyond) is the glass, at `to`: the hit
    // there. The ray aims at `to` from the spawned point itself: along
    // the direction from the unspawned one, it ran parallel to the leg,
    // the spawn offset off it, and met a grazing crossing that offset
    // over the cosine away, beyond the tolerance (the caustic's rim lost
    // 12% of its light where the offset was 1e-6 rather than 1e-7).
    let reaches = |from: DVec3, to: DVec3| {
        let span = (to - from).length();
        let dir = (to - from).try_normalize()?;
        let (first, at) =
            scene
                .geometry
                .intersect(&Ray::new(from, dir), 0.0, span * (1.0 + 1e-6))?;
        (first == obj && (at.p - to).length() <= 1e-6 * (length + span)).then_some(at)
    };
    // The leg from the point to the exit crossing x[0], then the leg
    // inside, from x[0] to x[1].
    let x = chain.x;
    let wi = (x[0] - hit.p).try_normalize()?;
    let from = hit.spawn(wi);
    let leg = (x[0] - from).length();
    let at = reaches(from, x[0])?;
    let dir = (x[1] - x[0]).try_normalize()?;
    reaches(at.spawn(dir), x[1])?;
    // The leg from x[1] to the light.
    let out = off_crossing(x[1], chain.normal[1], length);
    let beyond = light_transmittance(scene, media, stack, out, light.position)?;
    let around = around.map_or(Rgb::WHITE, |m| transmittance(m.sigma_t(), leg));
    let eta = glass.ior / n_out;
    let t = chain
        .cos_out
        .iter()
        .map(|&c| 1.0 - isolux_materials::fresnel::dielectric(c, eta))
        .product::<f64>();
    let factor = t * chain.spread;
    (factor > 0.0 && factor.is_finite()).then(|| (wi, light.intensity * beyond * around * factor))
}

/// Whether a crossing point `c` lies in the box `b` that clips its
/// boundary, the faces rounded outward by `rel (length + |c|_max)`, with
/// `length` its object's (`Object::length`, at most 1: so that the test
/// holds in a scene of any unit, as the spawn offset, `Hit::offset`).
fn in_box(b: &isolux_core::Aabb, c: DVec3, rel: f64, length: f64) -> bool {
    let tol = rel * (length + c.abs().max_element());
    !(c.cmplt(b.min - tol) | c.cmpgt(b.max + tol)).any()
}

/// The crossing point `c` of a boundary moved off it along its `normal`
/// by `1e-7 (length + |c|_max)` (the tolerance of [`in_box`] at `1e-7`,
/// `length` the boundary's `Object::length`): where the shadow ray toward
/// the light leaves the boundary, on the light's side (`caustic`,
/// `refracted_irradiance`).
fn off_crossing(c: DVec3, normal: DVec3, length: f64) -> DVec3 {
    c + normal * (1e-7 * (length + c.abs().max_element()))
}

/// The irradiance of point light `light` arriving along a [`Refraction`]
/// at a point inside the media `stack` (normal to the refracted ray, per
/// channel): `I T G` attenuated by the medium along `inside` and by what
/// lies beyond the boundary ([`light_transmittance`] from `c`); `None`
/// where a surface other than the boundary, or the boundary short of `c`,
/// lies before `c` (the ray from
/// `origin`, the point spawned off its surface) or one occludes the light
/// beyond it.
fn refracted_irradiance(
    scene: &Scene,
    media: &Media,
    stack: &MediumStack,
    r: &Refraction,
    light: &PointLight,
    origin: DVec3,
) -> Option<Rgb> {
    let to_c = (r.c - origin).length();
    // Tolerances in units of length scale with the boundary's own
    // (`Object::length`, at most 1), as the spawn offset does.
    let length = scene.geometry.objects()[r.obj].length();
    // Aimed at the crossing from `origin` itself (not along `r.wi`, from
    // the unspawned point: parallel to it, the spawn offset off it, the
    // ray met a grazing boundary that offset over the cosine from `c`;
    // as in `caustic`).
    let dir = (r.c - origin).try_normalize().unwrap_or(r.wi);
    if let Some((obj, hit)) =
        scene
            .geometry
            .intersect(&Ray::new(origin, dir), 0.0, to_c * (1.0 + 1e-6))
    {
        // Only the boundary, and there (not an earlier crossing of it).
        if obj != r.obj || (hit.p - r.c).length() > 1e-6 * (length + to_c) {
            return None;
        }
    }
    let inside = transmittance(object_medium(scene, r.obj)?.sigma_t(), r.inside);
    let mut after = *stack;
    after.cross(r.obj)?;
    let out = off_crossing(r.c, r.normal, length);
    let beyond = light_transmittance(scene, media, &after, out, light.position)?;
    Some(light.intensity * inside * beyond * r.factor)
}

/// The point lights that scattering events inside the media `stack` try.
/// Without null boundaries only the lights of the innermost medium (one
/// outside it is occluded by its boundary: no next-event estimation
/// through a delta interface, and no shadow ray is traced to find that
/// out).
fn medium_lights<'s>(
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
fn caustic_scattered_at(
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
/// [`Spectral`] ratios at its start. Its scattering points have the
/// density `mean_c r_c sigma_t,c exp(-sigma_t,c t)` on `[0, t_end)`
/// ([`Flight::density`]).
///
/// (Sampling the whole ray `[0, inf)` instead, where the free flight's
/// search had not reached the surface, saved that search but wasted the
/// samples of a lamp outside the medium: on `fog.toml` the noise rose
/// from 0.052 to 0.093 at the same time; docs/subsurface.md.)
#[derive(Clone, Copy, Debug)]
struct Flight {
    ray: Ray,
    t_end: f64,
    sigma_t: Rgb,
    sigma_s: Rgb,
    g: f64,
    ratio: Rgb,
}

impl Flight {
    /// The density of a scattering point at `t` over the path's channels
    /// (the balance of their densities, weighted by the path's ratios).
    fn density(&self, t: f64) -> f64 {
        mean(self.ratio * self.sigma_t * self.transmittance(t))
    }

    /// The transmittance to `t` per channel (`t` may be infinite).
    fn transmittance(&self, t: f64) -> Rgb {
        transmittance(self.sigma_t, t)
    }

    fn equiangular(&self, light: &PointLight) -> Option<Equiangular> {
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
fn medium_light(
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
/// [`MediumLightSampling::Equiangular`]): `sigma_s exp(-sigma_t t) L(t) /
/// pdf(t)` per channel, weighted against the free flight's scattering point
/// ([`medium_light`]) by the power heuristic. Per unit of the path's
/// throughput at the flight's start.
fn equiangular_light(
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

/// Direct light scattered once inside a medium and leaving at `hit`
/// toward `wo`: `f_1 = T(cos_i) T(cos_o) a p(wi' . wo') / (cos_i' + cos_o')`
/// per channel, estimated by light sampling (point lights, environment
/// map) and one cosine-sampled direction toward the environment, combined
/// by multiple importance sampling (the cosine sample alone covers a
/// constant sky). `stack`: the random-walk media around the object, which
/// attenuate its point lights ([`direct_light`]).
fn single_scattering_light(
    scene: &Scene,
    media: &Media,
    stack: &MediumStack,
    m: &Subsurface,
    hit: &Hit,
    wo: DVec3,
    rng: &mut Pcg32,
) -> Rgb {
    use isolux_materials::subsurface::phase::single_scattering;
    let frame = Frame::from_normal(hit.n);
    let wo_l = frame.to_local(wo);
    let albedo = m.albedo() * m.single_scattering_scale();
    let eta = m.boundary.ior;
    let f1 = |wi: DVec3| -> Rgb {
        let wl = frame.to_local(wi);
        if wl.z <= 0.0 {
            return Rgb::BLACK;
        }
        albedo * single_scattering(wo_l, wl, 1.0, m.g, eta)
    };
    let mut l = direct_light(scene, media, stack, hit, rng, |wi, _| {
        let c = wi.dot(hit.n);
        if c <= 0.0 {
            (Rgb::BLACK, 0.0)
        } else {
            (f1(wi) * c, c * isolux_core::INV_PI)
        }
    });
    let local = isolux_core::sampling::cosine_hemisphere(rng.next_2d());
    if local.z > 0.0 {
        let wi = frame.to_world(local);
        let env = &scene.environment;
        let origin = hit.spawn(wi);
        if !scene
            .geometry
            .occluded(&Ray::new(origin, wi), 0.0, f64::INFINITY)
        {
            let pdf = local.z * isolux_core::INV_PI;
            let w = if env.is_sampled() {
                power_heuristic(pdf, env.pdf(wi))
            } else {
                1.0
            };
            l += f1(wi) * env.eval(wi) * (PI * w);
        }
    }
    l
}

/// Samples the entry point `x_i` of the dipole BSSRDF around the exit
/// point `x_o` (pbrt-v3 §15.4): a colour channel, a projection axis (the
/// normal with probability 1/2, each tangent 1/4), a radius from the
/// channel's radial sampler, and a probe ray along the axis through the
/// object, of which one of the `k` hits is chosen. Returns `x_i` and the
/// weight `R_d(|x_i - x_o|) / pdf(x_i)`, the pdf summing every axis and
/// channel that could have produced `x_i`.
fn bssrdf_entry(
    scene: &Scene,
    obj: usize,
    m: &Subsurface,
    hit: &Hit,
    rng: &mut Pcg32,
) -> Option<(Hit, Rgb)> {
    let object = &scene.geometry.objects()[obj];
    let frame = Frame::from_normal(hit.n);
    let axes = [
        (frame.n, frame.s, frame.t, 0.5),
        (frame.s, frame.t, frame.n, 0.25),
        (frame.t, frame.n, frame.s, 0.25),
    ];
    let c = rng.next_below(3) as usize;
    let ua = rng.next_f64();
    let (axis, a1, a2, _) = if ua < 0.5 {
        axes[0]
    } else if ua < 0.75 {
        axes[1]
    } else {
        axes[2]
    };
    let r = m.sample_radius(c, rng.next_f64());
    let r_max = m.r_max();
    if !(r < r_max) {
        return None;
    }
    let phi = 2.0 * PI * rng.next_f64();
    let h = (r_max * r_max - r * r).sqrt();
    let start = hit.p + r * (phi.cos() * a1 + phi.sin() * a2) + h * axis;
    let probe = Ray::new(start, -axis);
    let mut hits: Vec<Hit> = Vec::new();
    let mut t0 = 0.0;
    while hits.len() < 64 {
        let Some(x) = object.intersect(&probe, t0, 2.0 * h) else {
            break;
        };
        t0 = x.t + x.offset;
        hits.push(x);
    }
    if hits.is_empty() {
        return None;
    }
    let k = hits.len();
    let xi = hits[(rng.next_below(k as u32) as usize).min(k - 1)];
    let d = xi.p - hit.p;
    let mut pdf = 0.0;
    for (ax, _, _, p_axis) in axes {
        let along = d.dot(ax);
        let r_proj = (d.length_squared() - along * along).max(0.0).sqrt();
        if r_proj <= 0.0 || r_proj >= r_max {
            continue;
        }
        let cos = ax.dot(xi.n).abs();
        for ch in 0..3 {
            pdf += p_axis / 3.0 * m.radial_pdf(ch, r_proj) / (2.0 * PI * r_proj) * cos;
        }
    }
    pdf /= k as f64;
    if !(pdf > 0.0) || !pdf.is_finite() {
        return None;
    }
    let w = m.profile(d.length()) / pdf;
    w.is_finite().then_some((xi, w))
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

/// What the paths of a render share about the random-walk media: those
/// around the camera ([`crate::Scene::media_at`]), the innermost each
/// point light lies in (without null boundaries, scattering events
/// gather only those lights, `medium_light`: the others lie behind the
/// medium's boundary), the materials seen from inside each, and whether
/// null boundaries may occur.
#[derive(Debug, Default)]
pub struct Media<'a> {
    /// The object indices and media the camera is in, outermost first
    /// ([`Scene::media_at`]).
    pub camera: Vec<(usize, &'a Subsurface)>,
    /// Per point light, the object index of the medium it lies in.
    pub lights: Vec<Option<usize>>,
    /// Per random-walk medium (its material's index, once however many
    /// objects share it), the scene's materials seen from inside it
    /// ([`Material::relative_to`] its boundary's index), `None` where one
    /// does not change.
    pub relative: Vec<(usize, Vec<Option<Material>>)>,
    /// Whether the scene may hold a *null boundary*
    /// ([`Scene::may_have_null_boundaries`]): point lights' shadow rays
    /// pass through them (`light_transmittance`); without any, a shadow
    /// ray stops at the first surface, and scattering events try only the
    /// lights of their own medium.
    pub null_boundaries: bool,
    /// The random-walk media bounded by a plane, by object index, with
    /// their planes ([`Scene::flat_boundary`]): point lights outside them
    /// reach inside through the plane by refraction (`refraction`).
    pub flat: Vec<(usize, FlatBoundary)>,
    /// Whether scattering events may gather any point light directly
    /// (`medium_lights`: a light inside a medium, or any light where
    /// null boundaries may be), so that flights look for lights to
    /// sample at all (0.7% of the random walk's instructions per sample
    /// in a scene lit from outside its media, callgrind; docs/benchmarks.md).
    pub gathers: bool,
    /// Whether point lights may reach a medium's inside by refraction
    /// through its boundary (`refraction`): a flat medium, or with
    /// [`RefractedLights::Manifold`] any random-walk medium, and a light.
    pub refracts: bool,
    /// Whether point lights' shadow rays blocked by a glass object look
    /// for the path through it (`caustic`, [`Scene::casts_caustics`]).
    pub caustics: bool,
    /// Paths ended at [`MAX_MEDIUM_EVENTS`] so far (of every thread's
    /// samples: the sum, the same whatever the thread count).
    pub capped: AtomicU64,
}

impl Clone for Media<'_> {
    /// A copy whose count of capped paths starts at this one's.
    fn clone(&self) -> Self {
        Media {
            camera: self.camera.clone(),
            lights: self.lights.clone(),
            relative: self.relative.clone(),
            null_boundaries: self.null_boundaries,
            flat: self.flat.clone(),
            gathers: self.gathers,
            refracts: self.refracts,
            caustics: self.caustics,
            capped: AtomicU64::new(self.capped.load(Ordering::Relaxed)),
        }
    }
}

impl<'a> Media<'a> {
    /// The media of `scene` for paths from `origin`.
    pub fn new(scene: &'a Scene, origin: DVec3) -> Self {
        let lit = !scene.lights.is_empty();
        let lights: Vec<_> = scene
            .lights
            .iter()
            .map(|l| scene.medium_at(l.position).map(|(i, _)| i))
            .collect();
        let null_boundaries = scene.may_have_null_boundaries();
        let flat = scene.flat_media();
        Media {
            camera: scene.media_at(origin),
            gathers: lit && (null_boundaries || lights.iter().any(Option::is_some)),
            refracts: lit
                && (!flat.is_empty()
                    || (scene.integrator.refracted_lights == RefractedLights::Manifold
                        && scene.media().next().is_some())),
            caustics: scene.casts_caustics(),
            lights,
            relative: scene
                .materials
                .iter()
                .enumerate()
                .filter_map(|(j, m)| match m {
                    Material::Subsurface(m) if m.mode == SubsurfaceMode::RandomWalk => {
                        let n = m.boundary.ior;
                        let seen = scene.materials.iter().map(|x| x.relative_to(n));
                        Some((j, seen.collect()))
                    }
                    _ => None,
                })
                .collect(),
            null_boundaries,
            flat,
            capped: AtomicU64::new(0),
        }
    }

    /// The material of object `obj` seen from inside the medium of
    /// object `inside` (`None`: outside every medium): a surface in a
    /// medium sees it on its outer side, so its indices of refraction
    /// count relative to the medium's ([`MediumStack::outside_of`]).
    pub fn material<'s>(
        &'s self,
        scene: &'s Scene,
        obj: usize,
        inside: Option<usize>,
    ) -> &'s Material {
        let mi = scene.object_material[obj];
        inside
            .map(|m| scene.object_material[m])
            .and_then(|m| self.relative.iter().find(|(j, _)| *j == m))
            .and_then(|(_, r)| r[mi].as_ref())
            .unwrap_or(&scene.materials[mi])
    }
}

/// The deepest nesting of random-walk media a path follows (a path
/// entering a ninth ends there).
pub const MAX_NESTED_MEDIA: usize = 8;

/// The random-walk media a path is in, outermost first, by object index:
/// media nest (a marble under water). Entering a medium's object pushes
/// it; crossing the boundary of one the path is in takes it out.
#[derive(Clone, Copy, Debug, Default)]
pub struct MediumStack {
    ids: [usize; MAX_NESTED_MEDIA],
    len: usize,
}

impl MediumStack {
    /// The innermost medium (the one the path travels in).
    pub fn top(&self) -> Option<usize> {
        self.len.checked_sub(1).map(|k| self.ids[k])
    }

    /// Whether the path is inside no medium.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Whether the path is inside object `obj`'s medium.
    pub fn contains(&self, obj: usize) -> bool {
        self.ids[..self.len].contains(&obj)
    }

    /// Enters `obj`'s medium; `false` when already [`MAX_NESTED_MEDIA`]
    /// deep.
    pub fn push(&mut self, obj: usize) -> bool {
        if self.len == MAX_NESTED_MEDIA {
            return false;
        }
        self.ids[self.len] = obj;
        self.len += 1;
        true
    }

    /// Leaves `obj`'s medium (the innermost, unless media overlap).
    pub fn remove(&mut self, obj: usize) {
        if let Some(k) = self.ids[..self.len].iter().rposition(|&i| i == obj) {
            self.ids.copy_within(k + 1..self.len, k);
            self.len -= 1;
        }
    }

    /// Crosses the boundary of object `obj`'s medium: out of it if the
    /// path is in it, else into it. `Some(true)` when it entered, `None`
    /// when it would enter a medium beyond [`MAX_NESTED_MEDIA`].
    pub fn cross(&mut self, obj: usize) -> Option<bool> {
        if self.contains(obj) {
            self.remove(obj);
            Some(false)
        } else {
            self.push(obj).then_some(true)
        }
    }

    /// The medium on the outer side of object `obj`'s surface for this
    /// path: the innermost one, or where `obj` is itself the innermost
    /// (the path leaving it), the one around it.
    pub fn outside_of(&self, obj: usize) -> Option<usize> {
        match self.top() {
            Some(t) if t == obj => self.len.checked_sub(2).map(|k| self.ids[k]),
            t => t,
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use isolux_geometry::{Aggregate, Object, Quadric};

    /// A scattering point inside a medium gathers a point light through
    /// glass: a lamp above a glass slab (index 1.5, y in [1, 1.5]), both
    /// inside water (index 1.33, extinction 0.1, isotropic), lights points
    /// of the water under the slab with the irradiance of the slab's
    /// closed form (crates/isolux/tests/analytic.rs, the floor under the
    /// same slab): `I T^2 G exp(-sigma_t (h1 + h2) / cos t1)` normal to
    /// the ray, with `G = sin t1 / (R cos t1 dR/dt1)`, `R = (h1 + h2) tan
    /// t1 + d tan t2` the foot's distance, `T` the Fresnel transmittance
    /// of index 1.5 / 1.33 at each face, times the phase 1 / (4 pi); within
    /// 1e-5. `medium_light` at such a point returns the same (the straight
    /// shadow ray meets the glass), and nothing with caustics off.
    #[test]
    fn scattering_points_gather_lamps_through_glass() {
        let (d, light) = (0.5, DVec3::new(0.3, 3.0, 0.2));
        let (n_glass, n_water, sigma_t) = (1.5, 1.33, 0.1);
        let water = Subsurface::new(
            Rgb::splat(0.05),
            Rgb::splat(0.05),
            0.0,
            n_water,
            SubsurfaceMode::RandomWalk,
        );
        let slab =
            Quadric::from_coefficients([0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.25, 0.0, -1.5]);
        let mut scene = Scene {
            geometry: Aggregate::new(vec![
                Object::new(slab, vec![], None).unwrap(),
                Object::new(Quadric::sphere(DVec3::ZERO, 10.0), vec![], None).unwrap(),
            ]),
            materials: vec![
                Material::Dielectric(isolux_materials::Dielectric { ior: n_glass }),
                Material::Subsurface(water),
            ],
            object_material: vec![0, 1],
            lights: vec![PointLight {
                position: light,
                intensity: Rgb::splat(20.0),
            }],
            ..Default::default()
        };
        scene.integrator.caustics = crate::Caustics::Manifold;
        let camera = DVec3::new(0.0, 0.6, 1.5);
        let media = Media::new(&scene, camera);
        assert!(media.caustics);
        let mut stack = MediumStack::default();
        stack.push(1);
        let eta = n_glass / n_water;
        let h1 = light.y - 1.5;
        for q in [
            DVec3::new(0.0, 0.4, 0.0),
            DVec3::new(0.5, 0.2, -0.3),
            DVec3::new(-0.7, 0.8, 0.4),
        ] {
            let h2 = 1.0 - q.y;
            let foot = DVec3::new(light.x - q.x, 0.0, light.z - q.z).length();
            let radius = |t1: f64| {
                let s2 = t1.sin() / eta;
                (h1 + h2) * t1.tan() + d * s2 / (1.0 - s2 * s2).sqrt()
            };
            let t1 = crate::manifold::tests::landing_angle(radius, foot);
            let e = 1e-6;
            let dr = (radius(t1 + e) - radius(t1 - e)) / (2.0 * e);
            let g = t1.sin() / (foot * t1.cos() * dr);
            let tr = 1.0 - isolux_materials::fresnel::dielectric(t1.cos(), eta);
            let want = 20.0 * tr * tr * g * (-sigma_t * (h1 + h2) / t1.cos()).exp() / (4.0 * PI);
            let dir = DVec3::new(0.0, -0.6, -1.5).normalize();
            let got = caustic_scattered_at(&scene, &media, &stack, &scene.lights[0], q, dir, 0.0);
            assert!(
                (got.r / want - 1.0).abs() < 1e-5 && got.r == got.g && got.g == got.b,
                "{q}: {got:?} against {want}"
            );
            // The same through the scattering point's next-event
            // estimation, and nothing without caustics.
            let t = 0.7;
            let flight = Flight {
                ray: Ray::new(q - dir * t, dir),
                t_end: 2.0,
                sigma_t: Rgb::splat(sigma_t),
                sigma_s: Rgb::splat(0.05),
                g: 0.0,
                ratio: Rgb::WHITE,
            };
            let mut rng = Pcg32::new(1, 1);
            let nee = medium_light(&scene, &media, &stack, &flight, t, true, &mut rng);
            assert!(
                (nee.r / want - 1.0).abs() < 1e-5,
                "{q}: {nee:?} against {want}"
            );
            let off = Media {
                caustics: false,
                ..media.clone()
            };
            let none = medium_light(&scene, &off, &stack, &flight, t, true, &mut rng);
            assert!(none.is_black(), "{none:?}");
        }
    }

    /// The refracted inverse square law conserves the light's flux: a
    /// point light of intensity 1 at height `h1` above a half-space of
    /// index 1.33 delivers to the plane at depth `h2` the flux its lower
    /// hemisphere sends through the surface, `2 pi int T(theta) sin theta
    /// dtheta` (integrated here by Simpson's rule against the Fresnel
    /// transmittance), whatever the depth: the irradiance `I T G cos
    /// theta_2` integrated over the plane (in the angle `a` of the point
    /// seen from straight above it, `R = h2 tan a`) agrees within 1e-4.
    #[test]
    fn refraction_conserves_the_lights_flux() {
        let (h1, n2) = (1.7, 1.33);
        let water = Subsurface::new(
            Rgb::BLACK,
            Rgb::splat(1e-3),
            0.0,
            n2,
            SubsurfaceMode::RandomWalk,
        );
        let plane = Object::new(Quadric::plane(DVec3::ZERO, DVec3::Y), vec![], None).unwrap();
        let scene = Scene {
            geometry: Aggregate::new(vec![plane]),
            materials: vec![Material::Subsurface(water)],
            object_material: vec![0],
            lights: vec![PointLight {
                position: DVec3::new(0.0, h1, 0.0),
                intensity: Rgb::WHITE,
            }],
            ..Default::default()
        };
        let media = Media::new(&scene, DVec3::new(0.0, -1.0, 0.0));
        assert_eq!(media.flat.len(), 1);
        let mut stack = MediumStack::default();
        stack.push(0);
        let simpson = |f: &dyn Fn(f64) -> f64, a: f64, b: f64, n: usize| {
            let h = (b - a) / n as f64;
            let mut sum = f(a) + f(b);
            for k in 1..n {
                sum += f(a + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
            }
            sum * h / 3.0
        };
        let flux = 2.0
            * PI
            * simpson(
                &|t: f64| (1.0 - isolux_materials::fresnel::dielectric(t.cos(), n2)) * t.sin(),
                0.0,
                PI / 2.0,
                20_000,
            );
        for h2 in [0.3, 1.0, 4.0] {
            let through = |a: f64| {
                let r_plane = h2 * a.tan();
                let p = DVec3::new(r_plane, -h2, 0.0);
                let Some(r) = refraction(&scene, &media, &stack, 0, p, &mut Pcg32::new(1, 1))
                else {
                    return 0.0;
                };
                let cos2 = r.wi.y;
                // dA = 2 pi R dR, dR = h2 / cos^2 a da.
                r.factor * cos2 * 2.0 * PI * r_plane * h2 / (a.cos() * a.cos())
            };
            let got = simpson(&through, 0.0, PI / 2.0 - 1e-4, 200_000);
            assert!(
                (got / flux - 1.0).abs() < 1e-4,
                "depth {h2}: {got} against {flux}"
            );
        }
        // Straight below the light: 1 / (h1 + h2 n1 / n2)^2 times T(0).
        let r = refraction(
            &scene,
            &media,
            &stack,
            0,
            DVec3::new(0.0, -1.0, 0.0),
            &mut Pcg32::new(1, 1),
        )
        .unwrap();
        let t0 = 1.0 - ((n2 - 1.0) / (n2 + 1.0)).powi(2);
        assert!((r.factor - t0 / (h1 + 1.0 / n2).powi(2)).abs() < 1e-12);
        assert!((r.wi - DVec3::Y).length() < 1e-12);
    }

    /// Manifold next-event estimation declines most tries by Russian
    /// roulette in two stages (a bound on the crossing, then the exact
    /// seed's, [`manifold_refraction`]): over many tries the mean factor
    /// is the solve's own `T G` ([`crate::manifold::connect`], no
    /// roulette), from a point behind a dent (the bound: the entry into
    /// its support) and behind a bump (the base's crossing).
    #[test]
    fn manifold_roulette_keeps_the_mean() {
        use isolux_geometry::Perturbation;
        let n2 = 1.5;
        let medium = Subsurface::new(
            Rgb::BLACK,
            Rgb::splat(1.5),
            0.0,
            n2,
            SubsurfaceMode::RandomWalk,
        );
        let light = DVec3::new(0.3, 3.0, -0.2);
        let p = DVec3::new(0.2, 0.3, 0.1);
        for factor in [-50.0, 50.0] {
            let bump = Perturbation {
                quadric: Quadric::sphere(DVec3::new(0.0, 1.0, 0.0), 0.4),
                factor,
            };
            let sphere = Object::new(Quadric::sphere(DVec3::ZERO, 1.0), vec![bump], None).unwrap();
            let ray = Ray::new(p, (light - p).normalize());
            let dist = (light - p).length();
            let d1 = sphere.exit_bound(&ray, dist);
            let d = sphere.intersect(&ray, 0.0, dist).unwrap().t;
            // A bound short of the crossing: the first stage takes more
            // tries than it keeps.
            assert!(d1 <= d && d - d1 > 0.02, "{d} {d1}");
            let c = crate::manifold::connect(&sphere, p, light, n2, 1.0).unwrap();
            let want = (1.0 - isolux_materials::fresnel::dielectric(c.cos_out, n2)) * c.spread;
            let scene = Scene {
                geometry: Aggregate::new(vec![sphere]),
                materials: vec![Material::Subsurface(medium.clone())],
                object_material: vec![0],
                ..Default::default()
            };
            let mut rng = Pcg32::new(7, 3);
            let n = 200_000;
            let (mut sum, mut sum2, mut tried) = (0.0, 0.0, 0);
            for _ in 0..n {
                let f = manifold_refraction(&scene, 0, &medium, p, light, 1.0, n2, &mut rng)
                    .map_or(0.0, |r| {
                        assert!((r.c - c.x).length() < 1e-9);
                        tried += 1;
                        r.factor
                    });
                sum += f;
                sum2 += f * f;
            }
            let mean = sum / n as f64;
            let err = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
            // Declined more often than not: the roulette did its work.
            assert!(tried < n / 2, "{tried}");
            assert!(
                (mean - want).abs() < 4.0 * err && err < 0.01 * want,
                "factor {factor}: {mean} +- {err} against {want}"
            );
        }
    }
}
