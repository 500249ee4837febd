//! The seed's real-time mode: direct light from point lights plus
//! prefiltered environment light, no path tracing.
//!
//! Each camera sample (4 to 25 per pixel on the stratified sub-pixel grid
//! of [`crate::render()`]) finds its first hit exactly and shades it with
//!
//! ```text
//! L = sum_j f(wo, w_j) |cos_j| I_j / r_j^2  V_j          (point lights, shadowed)
//!   + f(wo, wi) |cos_i| / pdf(wi)  L_env(wi; lod)         (one BSDF sample)
//! ```
//!
//! The point-light sum is the seed's eq. 2 (SPEC §5-6), with a shadow ray
//! per light. The environment term is *filtered importance sampling*
//! (Křivánek and Colbert, "Real-time Shading with Filtered Importance
//! Sampling", EGSR 2008): one BSDF sample per camera sample reads the
//! environment from a prefiltered pyramid ([`PrefilteredEnv`]) at the level
//! whose texels cover the solid angle the sample stands for,
//!
//! ```text
//! lod = 1/2 log2(Omega_s / Omega_p) + LOD_BIAS,  Omega_s = 1 / (N pdf(wi)),
//! Omega_p = 2 pi^2 sin(theta) / (W H)     (a level-0 texel at wi)
//! ```
//!
//! with `N` the samples per pixel. Delta lobes (mirrors, glass) read level
//! 0. So a wide lobe reads a blurred environment and its few samples per
//! pixel come out smooth, while a sharp one stays sharp. For a constant
//! environment the term is exact: `L_env` times the sampling weight, which
//! for Lambertian surfaces is the albedo, noise-free.
//!
//! Decisions (a real-time preview, not a reference):
//! - Environment light is **not shadowed** and does not bounce (no
//!   path tracing): light from the environment reaches every point as if
//!   nothing stood in its way, as in the seed's separation of point lights
//!   from "environment and other light". Transmitted samples (glass) read
//!   the environment straight along the refracted direction.
//! - Subsurface materials (`subsurface`, either mode) are shaded with
//!   their local approximation, `Subsurface::local_brdf` (the seed's eq.
//!   19, the BRDF of `subsurface_brdf` for the same medium): light leaves
//!   where it entered, so the blur of light across the surface and light
//!   through thin parts are left out. That is the seed's own real-time
//!   model of translucency.

use crate::environment::{dir_to_uv, EnvMap};
use crate::integrator::FirstHit;
use crate::{Environment, Scene};
use isolux_core::{DVec3, Pcg32, Ray, Rgb, PI};
use isolux_geometry::Culled;
use isolux_materials::{Bsdf, BxdfModel};

/// Fewest samples per pixel of the real-time mode (the seed's 2 x 2 grid).
pub const MIN_SPP: u32 = 4;
/// Most samples per pixel of the real-time mode (the seed's 5 x 5 grid).
pub const MAX_SPP: u32 = 25;
/// Added to the level of detail. Colbert and Křivánek add 1 for smoother
/// images; we add none: measured against the path tracer on a convex
/// object (`tests/realtime.rs`), the +1 blur doubled the worst regional
/// error (27% against 10%) for little less noise.
pub const LOD_BIAS: f64 = 0.0;

/// One level of the pyramid: an equirectangular map (row 0 at the top).
#[derive(Clone, Debug)]
pub struct EnvLevel {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// Row-major texels.
    pub texels: Vec<Rgb>,
}

/// An environment map and its successively halved, solid-angle weighted
/// averages, down to one texel.
///
/// Level `k + 1` has `ceil(w_k / 2) x ceil(h_k / 2)` texels; each is the
/// mean of its (up to) 2 x 2 children weighted by their solid angle
/// (`sin(theta)` of the child's row centre), so every level keeps the
/// environment's total power, up to the rows' discretization.
#[derive(Clone, Debug)]
pub struct PrefilteredEnv {
    levels: Vec<EnvLevel>,
}

impl PrefilteredEnv {
    /// Builds the pyramid of `map`.
    pub fn new(map: &EnvMap) -> Self {
        let (w, h) = map.size();
        let mut levels = vec![EnvLevel {
            width: w,
            height: h,
            texels: map.texels().to_vec(),
        }];
        while {
            let l = levels.last().expect("level 0");
            l.width > 1 || l.height > 1
        } {
            let l = levels.last().expect("level 0");
            let (nw, nh) = (l.width.div_ceil(2), l.height.div_ceil(2));
            let mut texels = Vec::with_capacity(nw * nh);
            for y in 0..nh {
                for x in 0..nw {
                    let mut sum = Rgb::BLACK;
                    let mut wsum = 0.0;
                    for cy in [2 * y, 2 * y + 1] {
                        if cy >= l.height {
                            continue;
                        }
                        let s = (PI * (cy as f64 + 0.5) / l.height as f64).sin();
                        for cx in [2 * x, 2 * x + 1] {
                            if cx >= l.width {
                                continue;
                            }
                            sum += l.texels[cy * l.width + cx] * s;
                            wsum += s;
                        }
                    }
                    texels.push(if wsum > 0.0 { sum / wsum } else { sum });
                }
            }
            levels.push(EnvLevel {
                width: nw,
                height: nh,
                texels,
            });
        }
        Self { levels }
    }

    /// The levels, finest first.
    pub fn levels(&self) -> &[EnvLevel] {
        &self.levels
    }

    /// The level of detail for a sample of solid-angle density `pdf` in
    /// direction `d` among `n` samples (`0` for a delta lobe: `pdf` None).
    pub fn lod(&self, d: DVec3, pdf: Option<f64>, n: u32) -> f64 {
        let Some(pdf) = pdf else {
            return 0.0;
        };
        let l0 = &self.levels[0];
        let sin_t = (1.0 - d.y * d.y).max(0.0).sqrt().max(PI / l0.height as f64);
        let omega_p = 2.0 * PI * PI * sin_t / (l0.width * l0.height) as f64;
        let omega_s = 1.0 / (n.max(1) as f64 * pdf);
        let lod = 0.5 * (omega_s / omega_p).log2() + LOD_BIAS;
        if lod.is_nan() {
            return 0.0;
        }
        lod.clamp(0.0, (self.levels.len() - 1) as f64)
    }

    /// Radiance toward `d` at level of detail `lod`: bilinear within a
    /// level (wrapping in `u`, clamped in `v`), linear between levels.
    pub fn lookup(&self, d: DVec3, lod: f64) -> Rgb {
        let lod = lod.clamp(0.0, (self.levels.len() - 1) as f64);
        let k = lod.floor() as usize;
        let t = lod - k as f64;
        let uv = dir_to_uv(d);
        let a = bilinear(&self.levels[k], uv);
        if t > 0.0 && k + 1 < self.levels.len() {
            a * (1.0 - t) + bilinear(&self.levels[k + 1], uv) * t
        } else {
            a
        }
    }
}

fn bilinear(l: &EnvLevel, [u, v]: [f64; 2]) -> Rgb {
    let x = u * l.width as f64 - 0.5;
    let y = (v * l.height as f64 - 0.5).clamp(0.0, (l.height - 1) as f64);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let w = l.width as i64;
    let xa = (x0 as i64).rem_euclid(w) as usize;
    let xb = (x0 as i64 + 1).rem_euclid(w) as usize;
    let ya = y0 as usize;
    let yb = (ya + 1).min(l.height - 1);
    let at = |x: usize, y: usize| l.texels[y * l.width + x];
    (at(xa, ya) * (1.0 - fx) + at(xb, ya) * fx) * (1.0 - fy)
        + (at(xa, yb) * (1.0 - fx) + at(xb, yb) * fx) * fy
}

/// The environment as the real-time mode sees it.
#[derive(Clone, Debug)]
pub enum RealtimeEnv {
    /// The same radiance from every direction.
    Constant(Rgb),
    /// A prefiltered map.
    Map(PrefilteredEnv),
}

impl RealtimeEnv {
    /// Prefilters `env` (maps only).
    pub fn new(env: &Environment) -> Self {
        match env {
            Environment::Constant(c) => RealtimeEnv::Constant(*c),
            Environment::Map(m) => RealtimeEnv::Map(PrefilteredEnv::new(m)),
        }
    }

    /// Filtered radiance toward `d` for a BSDF sample of density `pdf`
    /// (None: delta) among `n` per pixel.
    pub fn filtered(&self, d: DVec3, pdf: Option<f64>, n: u32) -> Rgb {
        match self {
            RealtimeEnv::Constant(c) => *c,
            RealtimeEnv::Map(m) => m.lookup(d, m.lod(d, pdf, n)),
        }
    }
}

/// Radiance along a camera `ray` in the real-time mode, with `n` samples
/// per pixel (see the module documentation), and the first hit. With
/// `primary`, the ray lies in the beam it was culled for
/// ([`isolux_geometry::Aggregate::cull`]) and the camera ray tests only
/// the culled objects and perturbations.
pub fn realtime_radiance(
    scene: &Scene,
    env: &RealtimeEnv,
    ray: Ray,
    primary: Option<&Culled>,
    n: u32,
    rng: &mut Pcg32,
) -> (Rgb, Option<FirstHit>) {
    let found = match primary {
        Some(culled) => scene
            .geometry
            .intersect_culled(&ray, 0.0, f64::INFINITY, culled),
        None => scene.geometry.intersect(&ray, 0.0, f64::INFINITY),
    };
    let Some((obj, hit)) = found else {
        return (scene.environment.eval(ray.dir), None);
    };
    let footprint = scene.camera.pixel_footprint(hit.t, scene.film.height);
    let placed =
        scene.materials[scene.object_material[obj]]
            .at_point(hit.p, Some(footprint), || rng.next_f64());
    let material: &isolux_materials::Material = &placed;
    let first = Some(FirstHit {
        albedo: material.albedo(),
        normal: hit.n,
        depth: hit.t,
    });
    // A translucent medium is shaded with its local approximation (the
    // seed's eq. 19), its light leaving where it entered.
    let local;
    let material = match material.medium() {
        Some(m) => {
            local = isolux_materials::Material::SubsurfaceBrdf(m.local_brdf());
            &local
        }
        None => material,
    };
    let wo = -ray.dir;
    let bsdf = match material.tangent() {
        Some(t) => Bsdf::with_tangent(material, hit.n, t, wo),
        None => Bsdf::new(material, hit.n, wo),
    };
    let ns = bsdf.normal();
    let mut l = Rgb::BLACK;
    for light in &scene.lights {
        let origin = hit.spawn(light.position - hit.p);
        let Some((wi, dist, dist2)) = light.toward(origin) else {
            continue;
        };
        let fc = bsdf.f(wo, wi) * wi.dot(ns).abs();
        if fc.is_black() {
            continue;
        }
        if !scene.geometry.occluded(&Ray::new(origin, wi), 0.0, dist) {
            l += fc * light.intensity / dist2;
        }
    }
    let uc = rng.next_f64();
    if let Some(s) = bsdf.sample(wo, uc, rng.next_2d()) {
        let pdf = (!s.flags.is_specular()).then_some(s.pdf);
        l += s.weight(s.wi.dot(ns)) * env.filtered(s.wi, pdf, n);
    }
    (l, first)
}

/// What the real-time image of `scene` leaves out of its random-walk
/// media, for a warning (the caller says what renders it: the path
/// tracer), where it is more than their local approximation does
/// (`None` otherwise): the real-time mode renders no volume, so
/// - a camera inside such a medium (under water) sees through it as
///   through clear air, its scattering and absorption around the camera
///   left out (`underwater.toml`, CPU, 96 x 54 at 16 spp: image mean 0.54
///   in real time against the path tracer's 0.39);
/// - a medium of index 1 (fog: its boundary bends no ray, and its look is
///   the light it scatters inside, light shafts and haze) is reduced to
///   its boundary shaded with the medium's local BRDF (`fog.toml`: the
///   PNG's mean 0.084 in real time against 0.45 path traced);
/// - an object inside such a medium (stones on the floor of shallow
///   water) is hidden: the medium's boundary, shaded with its local BRDF,
///   is opaque (`shallows.toml`: the water an even dark blue in real
///   time, where the path tracer shows the stones through it).
///
/// Media seen from outside with nothing inside them (marble, milk) are
/// what the local approximation is for, and are not named.
pub fn volume_left_out(scene: &Scene) -> Option<String> {
    if let Some((object, _)) = scene.medium_at(scene.camera.position) {
        return Some(format!(
            "the camera is inside the random-walk medium of object[{object}] (material \"{}\"), \
             and the real-time mode renders no volume: the medium's scattering and absorption \
             around the camera are left out (docs/realtime.md)",
            scene.object_material_name(object)
        ));
    }
    if let Some((object, _, _)) = scene.media().find(|(_, _, m)| m.boundary.ior == 1.0) {
        return Some(format!(
            "the random-walk medium of object[{object}] (material \"{}\") has index 1, so its \
             look is the light it scatters inside (haze, light shafts), and the real-time mode \
             renders no volume: it shades the medium's boundary with its local BRDF alone \
             (docs/realtime.md)",
            scene.object_material_name(object)
        ));
    }
    let objects = scene.geometry.objects();
    scene.media().find_map(|(object, medium, _)| {
        let inside = objects.iter().enumerate().find(|&(j, o)| {
            let b = o.bbox();
            j != object && !b.is_empty() && b.is_finite() && medium.contains((b.min + b.max) * 0.5)
        })?;
        Some(format!(
            "object[{}] lies inside the random-walk medium of object[{object}] (material \
             \"{}\"), and the real-time mode renders no volume: it shades the medium's \
             boundary with its local BRDF, an opaque surface that hides what lies inside \
             (docs/realtime.md)",
            inside.0,
            scene.object_material_name(object)
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::environment::uv_to_dir;
    use isolux_core::sampling;

    fn map(w: usize, h: usize, f: impl Fn(usize, usize) -> f64) -> EnvMap {
        let texels = (0..w * h).map(|i| Rgb::splat(f(i % w, i / w))).collect();
        EnvMap::new(w, h, texels, 1.0).unwrap()
    }

    /// Solid-angle integral of a level, exactly per row.
    fn power(l: &EnvLevel) -> f64 {
        let mut s = 0.0;
        for y in 0..l.height {
            let t0 = PI * y as f64 / l.height as f64;
            let t1 = PI * (y + 1) as f64 / l.height as f64;
            let row = 2.0 * PI * (t0.cos() - t1.cos()) / l.width as f64;
            for x in 0..l.width {
                s += l.texels[y * l.width + x].r * row;
            }
        }
        s
    }

    #[test]
    fn pyramid_sizes_and_constant_maps() {
        let p = PrefilteredEnv::new(&map(13, 6, |_, _| 2.5));
        let sizes: Vec<_> = p.levels().iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, [(13, 6), (7, 3), (4, 2), (2, 1), (1, 1)]);
        for l in p.levels() {
            assert!(l.texels.iter().all(|t| (t.r - 2.5).abs() < 1e-12));
        }
        let mut rng = Pcg32::new(2, 2);
        for _ in 0..100 {
            let d = sampling::uniform_sphere(rng.next_2d());
            let lod = 4.0 * rng.next_f64();
            assert!((p.lookup(d, lod).r - 2.5).abs() < 1e-12);
        }
    }

    #[test]
    fn levels_keep_the_power_of_the_map() {
        // A bright band near the horizon and a gradient: each coarser
        // level integrates to the same power, within the discretization of
        // its rows (a few per cent on the coarsest ones).
        let p = PrefilteredEnv::new(&map(64, 32, |x, y| {
            if (12..16).contains(&y) {
                20.0
            } else {
                0.1 + x as f64 / 64.0
            }
        }));
        let p0 = power(&p.levels()[0]);
        for (k, l) in p.levels().iter().enumerate().take(4) {
            let pk = power(l);
            assert!((pk / p0 - 1.0).abs() < 0.03, "level {k}: {pk} vs {p0}");
        }
    }

    #[test]
    fn level_zero_lookup_interpolates_texel_centres() {
        let m = map(8, 4, |x, y| (x + 10 * y) as f64);
        let p = PrefilteredEnv::new(&m);
        // At a texel centre the bilinear lookup returns the texel.
        for (x, y) in [(0, 0), (3, 1), (7, 3), (5, 2)] {
            let d = uv_to_dir([(x as f64 + 0.5) / 8.0, (y as f64 + 0.5) / 4.0]);
            let v = p.lookup(d, 0.0).r;
            assert!((v - (x + 10 * y) as f64).abs() < 1e-9, "{x} {y} {v}");
        }
        // Halfway between columns 7 and 0 (wrapping in u): the mean.
        let d = uv_to_dir([0.0, 1.5 / 4.0]);
        assert!((p.lookup(d, 0.0).r - (7.0 + 0.0) / 2.0 - 10.0).abs() < 1e-9);
    }

    #[test]
    fn lod_follows_the_sample_density() {
        let p = PrefilteredEnv::new(&map(256, 128, |_, _| 1.0));
        let d = DVec3::new(1.0, 0.0, 0.0);
        assert_eq!(p.lod(d, None, 16), 0.0);
        // A texel's own solid angle with one sample: level 0 (plus bias).
        let omega_p = 2.0 * PI * PI / (256.0 * 128.0);
        assert!((p.lod(d, Some(1.0 / omega_p), 1) - LOD_BIAS).abs() < 1e-9);
        // Four times the solid angle, or four times fewer samples: one
        // level coarser.
        assert!((p.lod(d, Some(0.25 / omega_p), 1) - 1.0 - LOD_BIAS).abs() < 1e-9);
        assert!((p.lod(d, Some(0.25 / omega_p), 4) - LOD_BIAS).abs() < 1e-9);
        // Denser than a texel: clamped to level 0.
        assert_eq!(p.lod(d, Some(16.0 / omega_p), 1), 0.0);
        // A uniform sphere sample: about the whole map.
        assert!(p.lod(d, Some(0.25 / PI), 1) > 7.0);
        assert!(p.lod(d, Some(1e-12), 1) <= (p.levels().len() - 1) as f64);
    }
}
