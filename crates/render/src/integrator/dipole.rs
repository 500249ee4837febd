//! The dipole BSSRDF's terms at a surface vertex: single scattering
//! under the surface ([`single_scattering_light`]) and the sampled
//! point where light entered ([`bssrdf_entry`]).

use super::{direct_light, Media, MediumStack};
use crate::Scene;
use isolux_core::sampling::power_heuristic;
use isolux_core::{DVec3, Frame, Pcg32, Ray, Rgb, PI};
use isolux_geometry::Hit;
use isolux_materials::{BxdfModel, Subsurface};

/// Direct light scattered once inside a medium and leaving at `hit`
/// toward `wo`: `f_1 = T(cos_i) T(cos_o) a p(wi' . wo') / (cos_i' + cos_o')`
/// per channel, estimated by light sampling (point lights, environment
/// map) and one cosine-sampled direction toward the environment, combined
/// by multiple importance sampling (the cosine sample alone covers a
/// constant sky). `stack`: the random-walk media around the object, which
/// attenuate its point lights ([`direct_light`]).
pub(super) fn single_scattering_light(
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
pub(super) fn bssrdf_entry(
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
