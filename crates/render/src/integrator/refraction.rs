//! Point lights reached through a refracting boundary: into a medium
//! through its flat or curved boundary ([`refraction`], with
//! [`refracted_irradiance`]), and through glass to a surface or a
//! scattering event ([`caustic`]).

use super::{light_transmittance, object_medium, transmittance, Media, MediumStack};
use crate::{PointLight, RefractedLights, Scene};
use isolux_core::{DVec3, Pcg32, Ray, Rgb};
use isolux_geometry::Hit;
use isolux_materials::{Material, Subsurface};

/// A point light's connection into a medium through its boundary, flat
/// or curved: the direction `wi` from the point inside toward the
/// crossing point `c` on the boundary (outward normal `normal` there), the
/// distance `inside` to it, and `factor`, the Fresnel transmittance times
/// the refracted inverse square law ([`refraction`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct Refraction {
    pub(super) obj: usize,
    pub(super) wi: DVec3,
    pub(super) inside: f64,
    pub(super) c: DVec3,
    pub(super) normal: DVec3,
    pub(super) factor: f64,
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
pub(super) fn refraction(
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
pub(super) fn caustic(
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
pub(super) fn refracted_irradiance(
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

#[cfg(test)]
mod tests {
    use super::super::medium::{caustic_scattered_at, medium_light, Flight};
    use super::*;
    use isolux_core::PI;
    use isolux_geometry::{Aggregate, Object, Quadric};
    use isolux_materials::subsurface_material::SubsurfaceMode;

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
