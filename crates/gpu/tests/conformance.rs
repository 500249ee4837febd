//! GPU against CPU: exact intersection of perturbation-function objects.
//!
//! Random objects (a sphere or an ellipsoid base with up to 12 bumps and
//! dents of random signs and sizes) and random rays through their boxes,
//! intersected by `Object::intersect` (f64) and by the WGSL kernel (f32) on
//! whatever adapter exists (lavapipe in CI). Tolerances, stated: hit/miss
//! agreement on at least 99.9% of the rays (the rest graze the surface,
//! where f32 and f64 may legitimately disagree), `t` within 1e-3 (scene
//! units, objects of size ~1) on 99.9% of the rays both hit, normals within
//! 0.01 (1 - cos) on 99% there. Measured on lavapipe: 100%, 99.986%, 100%
//! of 54,000 rays.
//!
//! Without an adapter the test is skipped with a message, except under CI
//! (`CI` set), where `.ci/run` installs lavapipe and a missing adapter is a
//! failure.

mod common;

use glam::{DMat3, DVec3};
use isolux_core::{sampling, Pcg32, Ray};
use isolux_geometry::{Object, Perturbation, Quadric};
use isolux_gpu::layout::{GpuRay, GpuScene};

/// The ray as the kernel reads it (f32, unbounded) and the same rounded
/// ray in f64 for the CPU reference.
fn kernel_ray(o: DVec3, d: DVec3) -> (GpuRay, Ray) {
    let (o, d) = (o.as_vec3(), d.as_vec3());
    let gpu = GpuRay {
        o: [o.x, o.y, o.z, 0.0],
        d: [d.x, d.y, d.z, 1e30],
    };
    (gpu, Ray::new(o.as_dvec3(), d.as_dvec3()))
}

/// The GPU's and the CPU's first hits of rays `(from, to)` on `object`
/// alone: the kernel's `t` (negative on a miss) and the CPU's, each ray
/// rounded to f32 for both ([`kernel_ray`]).
fn single_object_hits(
    gpu: &isolux_gpu::Gpu,
    object: &Object,
    rays: &[(DVec3, DVec3)],
) -> Vec<(f64, Option<f64>)> {
    let (kernel, cpu): (Vec<GpuRay>, Vec<Option<f64>>) = rays
        .iter()
        .map(|&(from, to)| {
            let (g, r) = kernel_ray(from, (to - from).normalize());
            (g, object.intersect(&r, 0.0, 1e30).map(|h| h.t))
        })
        .unzip();
    let hits = gpu
        .intersect(&GpuScene::new(std::slice::from_ref(object)), &kernel)
        .unwrap();
    hits.iter().map(|h| h.v[0] as f64).zip(cpu).collect()
}

fn random_object(rng: &mut Pcg32) -> Object {
    random_object_at(rng, DVec3::ZERO)
}

fn random_object_at(rng: &mut Pcg32, at: DVec3) -> Object {
    let u = |rng: &mut Pcg32, a: f64, b: f64| a + (b - a) * rng.next_f64();
    let base = if rng.next_f64() < 0.5 {
        Quadric::sphere(at, u(rng, 0.5, 0.8))
    } else {
        let r = DVec3::new(u(rng, 0.4, 0.9), u(rng, 0.4, 0.9), u(rng, 0.4, 0.9));
        Quadric::ellipsoid(at, r, DMat3::from_rotation_y(u(rng, 0.0, 3.0)))
    };
    let n = rng.next_below(13) as usize;
    let perts = (0..n)
        .map(|_| {
            let dir = DVec3::new(u(rng, -1.0, 1.0), u(rng, -1.0, 1.0), u(rng, -1.0, 1.0))
                .normalize_or(DVec3::Y);
            let r = u(rng, 0.1, 0.35);
            let sign = if rng.next_f64() < 0.6 { 1.0 } else { -1.0 };
            Perturbation {
                quadric: Quadric::sphere(at + dir * u(rng, 0.4, 0.8), r),
                factor: sign * u(rng, 0.5, 2.0) / r.powi(6),
            }
        })
        .collect();
    Object::new(base, perts, None).unwrap()
}

/// 40 random objects scattered over [-3, 3]^3 (scenes of many objects).
fn crowd(rng: &mut Pcg32) -> Vec<Object> {
    (0..40)
        .map(|_| {
            let at = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 6.0
                - DVec3::splat(3.0);
            random_object_at(rng, at)
        })
        .collect()
}

/// Agreement of one precision's kernel with the CPU.
struct Agreement {
    total: usize,
    agree: usize,
    both: usize,
    t_ok: usize,
    n_ok: usize,
    /// |t_gpu - t_cpu| over the common hits, sorted.
    dt: Vec<f64>,
}

impl Agreement {
    fn pct(a: usize, b: usize) -> f64 {
        100.0 * a as f64 / b.max(1) as f64
    }

    fn quantile(&self, q: f64) -> f64 {
        self.dt[((self.dt.len() - 1) as f64 * q) as usize]
    }

    fn report(&self, label: &str) {
        eprintln!(
            "{label}: {} rays: hit/miss agree {:.3}%, t within 1e-3 {:.3}% of {} common hits, normals {:.3}%; |dt| median {:.2e}, 99th {:.2e}, 99.9th {:.2e}",
            self.total,
            Self::pct(self.agree, self.total),
            Self::pct(self.t_ok, self.both),
            self.both,
            Self::pct(self.n_ok, self.t_ok),
            self.quantile(0.5),
            self.quantile(0.99),
            self.quantile(0.999),
        );
    }

    fn check(&self) {
        assert!(
            self.both > self.total / 4,
            "too few hits to compare: {}",
            self.both
        );
        assert!(Self::pct(self.agree, self.total) >= 99.9);
        assert!(Self::pct(self.t_ok, self.both) >= 99.9);
        assert!(Self::pct(self.n_ok, self.t_ok) >= 99.0);
    }
}

#[test]
fn intersection_matches_the_cpu() {
    let Some(gpu) = common::open("GPU conformance") else {
        return;
    };
    let a = agreement(&gpu);
    a.report("f32");
    a.check();
    // Each object is intersected in its own frame, from where the ray
    // enters its box (geometry.wgsl `object_hit`). Measured on lavapipe
    // (Mesa 22.3, 2026-12-02): |dt| median 9.3e-8, 99th percentile
    // 8.7e-7, 99.9th 3.1e-6, against 7.2e-7, 9.5e-6 and 2.8e-5 with the
    // quadrics expanded about the world origin and the ray from its own
    // origin; the bounds leave about three times the margin.
    assert!(a.quantile(0.5) < 3e-7, "median {}", a.quantile(0.5));
    assert!(a.quantile(0.99) < 3e-6, "99th {}", a.quantile(0.99));
    assert!(a.quantile(0.999) < 1e-5, "99.9th {}", a.quantile(0.999));
}

/// The f64 variant of the intersection (`Precision::F64`), where the
/// adapter offers it (lavapipe does), against the same CPU reference: the
/// same tolerances, and its errors no larger than f32's (half of them in
/// the tail). Both kernels read
/// the scene and rays in f32, so the CPU intersects the f32-rounded rays
/// and neither can beat the f32 rounding of the quadrics (~1e-7).
#[test]
fn f64_intersection_matches_the_cpu() {
    let Some(mut gpu) = common::open("GPU f64 conformance") else {
        return;
    };
    if !gpu.supports_f64() {
        eprintln!("{} has no SHADER_F64: f64 conformance skipped", gpu.adapter);
        return;
    }
    let single = agreement(&gpu);
    gpu.set_precision(isolux_gpu::Precision::F64).unwrap();
    let double = agreement(&gpu);
    single.report("f32");
    double.report("f64");
    double.check();
    // Measured on lavapipe (Mesa 22.3, 2026-12-01): median 6.1e-8
    // against 7.2e-7, 99th percentile 2.3e-7 against 9.5e-6, 99.9th
    // 6.0e-7 against 2.8e-5. (Before the root refinement returned its
    // last Illinois estimate instead of the bracket's midpoint, f64's
    // 99.9th percentile was 2.2e-5, as large as f32's: a regula falsi
    // that kept one end of the bracket answered half a bracket off.)
    // f64 finds the CPU's first root: `t` within 1e-3 on 100% of the
    // common hits on lavapipe. A root search that may answer a later root
    // (one taking an interval with three sign changes of its control
    // polygon for one with a single root) reads 99.927%, and f32 99.984%
    // (inside f32's tolerance above); so f64 holds the stricter line.
    assert!(
        Agreement::pct(double.t_ok, double.both) >= 99.99,
        "f64: t within 1e-3 on {:.3}% of the common hits",
        Agreement::pct(double.t_ok, double.both)
    );
    // Since each object is intersected in its own frame (2026-12-02) f32
    // sits near the floor both share, the f32 rounding of the quadrics and
    // rays: lavapipe, f64 against f32, median 6.1e-8 against 9.3e-8, 99th
    // percentile 2.1e-7 against 8.7e-7, 99.9th 4.5e-7 against 3.1e-6. So
    // f64 is no worse at the median and at most half of f32 in the tail.
    // (Since the Newton step on F' itself that polishes a polynomial's
    // root, 2026-12-03, f32 is closer still: 8.0e-8, 5.6e-7 and 1.9e-6
    // against f64's 6.1e-8, 2.3e-7 and 6.0e-7.)
    assert!(double.quantile(0.5) <= single.quantile(0.5));
    assert!(double.quantile(0.99) < 0.5 * single.quantile(0.99));
    assert!(double.quantile(0.999) < 0.5 * single.quantile(0.999));
}

fn agreement(gpu: &isolux_gpu::Gpu) -> Agreement {
    let mut rng = Pcg32::new(42, 7);
    let (mut total, mut agree, mut both, mut t_ok, mut n_ok) = (0, 0, 0, 0, 0);
    let mut dts = Vec::new();
    // 24 random objects, then three that exercise the culling: the
    // benchmark's 64 bumps, 40 overlapping supports (a ray keeps more than
    // MAX_CANDIDATES and falls back to all of them), and unbounded
    // supports (a half-space and a cylinder carving the base).
    let mut objects: Vec<Object> = (0..24).map(|_| random_object(&mut rng)).collect();
    objects.push(isolux_geometry::samples::bumpy_sphere(64));
    let crowd = (0..40)
        .map(|i| {
            let a = i as f64 * 0.7;
            Perturbation {
                quadric: Quadric::sphere(
                    DVec3::new(0.05 * a.cos(), 0.05 * a.sin(), 0.55),
                    0.3 + 0.0025 * i as f64,
                ),
                factor: if i % 3 == 0 { -20.0 } else { 30.0 },
            }
        })
        .collect();
    objects.push(Object::new(Quadric::sphere(DVec3::ZERO, 0.6), crowd, None).unwrap());
    let carved = vec![
        Perturbation {
            quadric: Quadric::plane(DVec3::new(0.0, 0.3, 0.0), DVec3::new(0.2, 1.0, 0.1)),
            factor: -8.0,
        },
        Perturbation {
            quadric: Quadric::cylinder(DVec3::ZERO, DVec3::new(1.0, 0.2, 0.0), 0.25),
            factor: -400.0,
        },
    ];
    objects.push(Object::new(Quadric::sphere(DVec3::ZERO, 0.7), carved, None).unwrap());
    const { assert!(isolux_gpu::MAX_CANDIDATES < 40) };
    for obj in &objects {
        let scene = GpuScene::new(std::slice::from_ref(obj));
        let mut rays = Vec::new();
        let mut cpu_rays = Vec::new();
        for _ in 0..2000 {
            let o = DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, 3.0);
            let o = DMat3::from_rotation_y(rng.next_f64() * std::f64::consts::TAU)
                * DMat3::from_rotation_x(rng.next_f64() - 0.5)
                * o;
            let target = DVec3::new(
                rng.next_f64() - 0.5,
                rng.next_f64() - 0.5,
                rng.next_f64() - 0.5,
            ) * 1.6;
            let d = (target - o).normalize();
            let (gpu_ray, cpu_ray) = kernel_ray(o, d);
            rays.push(gpu_ray);
            cpu_rays.push(cpu_ray);
        }
        let hits = gpu.intersect(&scene, &rays).unwrap();
        for (ray, h) in cpu_rays.iter().zip(&hits) {
            total += 1;
            let cpu = obj.intersect(ray, 0.0, f64::INFINITY);
            let gpu_hit = h.v[0] >= 0.0;
            if cpu.is_some() == gpu_hit {
                agree += 1;
            }
            if let (Some(c), true) = (cpu, gpu_hit) {
                both += 1;
                let dt = (c.t - h.v[0] as f64).abs();
                dts.push(dt);
                if dt < 1e-3 {
                    t_ok += 1;
                    let n = DVec3::new(h.v[1] as f64, h.v[2] as f64, h.v[3] as f64);
                    if 1.0 - n.dot(c.n) < 0.01 {
                        n_ok += 1;
                    }
                }
            }
        }
    }
    dts.sort_by(f64::total_cmp);
    Agreement {
        total,
        agree,
        both,
        t_ok,
        n_ok,
        dt: dts,
    }
}

/// Many objects in one scene: the GPU's hierarchy over the objects against
/// the CPU's `Aggregate` (nearest hit over all objects).
#[test]
fn scene_of_many_objects_matches_the_cpu() {
    let Some(gpu) = common::open("GPU conformance, many objects") else {
        return;
    };
    let mut rng = Pcg32::new(9, 3);
    let objects = crowd(&mut rng);
    let scene = GpuScene::new(&objects);
    let cpu = isolux_geometry::Aggregate::new(objects);
    let (mut rays, mut cpu_rays) = (Vec::new(), Vec::new());
    for _ in 0..8000 {
        let o = DMat3::from_rotation_y(rng.next_f64() * std::f64::consts::TAU)
            * DMat3::from_rotation_x(rng.next_f64() - 0.5)
            * DVec3::new(0.0, 0.0, 9.0);
        let target = (DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5) * 6.0;
        let d = (target - o).normalize();
        rays.push(GpuRay {
            o: [o.x as f32, o.y as f32, o.z as f32, 0.0],
            d: [d.x as f32, d.y as f32, d.z as f32, 1e30],
        });
        cpu_rays.push(Ray::new(o, d));
    }
    let hits = gpu.intersect(&scene, &rays).unwrap();
    let (mut agree, mut both, mut t_ok) = (0, 0, 0);
    for (ray, h) in cpu_rays.iter().zip(&hits) {
        let c = cpu.intersect(ray, 0.0, f64::INFINITY);
        if c.is_some() == (h.v[0] >= 0.0) {
            agree += 1;
        }
        if let (Some((_, c)), true) = (c, h.v[0] >= 0.0) {
            both += 1;
            if (c.t - h.v[0] as f64).abs() < 1e-3 {
                t_ok += 1;
            }
        }
    }
    let total = rays.len();
    let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
    eprintln!(
        "{} objects, {total} rays: hit/miss agree {:.3}%, t within 1e-3 {:.3}% of {both} common hits",
        cpu.objects().len(),
        pct(agree, total),
        pct(t_ok, both)
    );
    assert!(both > total / 4, "too few hits to compare: {both}");
    assert!(pct(agree, total) >= 99.9);
    assert!(pct(t_ok, both) >= 99.9);
}

/// Shadow rays (`Gpu::occluded`, the render kernels' any-hit query, which
/// stops at the first interval whose ends have opposite signs instead of
/// isolating and refining the first root) report an occluder exactly when
/// the nearest-hit query finds a hit on the same `[t_min, t_max]`, and
/// agree with the CPU's f64 intersection there. Rays of random bumpy
/// objects (each alone) and of a scene of 40 of them, with random spans:
/// starting at 0 or partway in (inside objects, often), ending at random
/// distances or unbounded.
#[test]
fn shadow_rays_find_what_first_hits_find() {
    let Some(gpu) = common::open("GPU conformance, shadow rays") else {
        return;
    };
    let mut rng = Pcg32::new(5, 11);
    let mut scenes: Vec<(Vec<Object>, f64)> = (0..16)
        .map(|_| (vec![random_object(&mut rng)], 3.0))
        .collect();
    scenes.push((vec![isolux_geometry::samples::bumpy_sphere(64)], 3.0));
    scenes.push((crowd(&mut rng), 9.0));
    let (mut total, mut occluded, mut same, mut cpu_agree) = (0, 0, 0, 0);
    for (objects, distance) in scenes {
        let scene = GpuScene::new(&objects);
        let size = if objects.len() > 1 { 6.0 } else { 1.6 };
        let cpu = isolux_geometry::Aggregate::new(objects);
        let (mut rays, mut spans) = (Vec::new(), Vec::new());
        for _ in 0..1500 {
            let o = DMat3::from_rotation_y(rng.next_f64() * std::f64::consts::TAU)
                * DMat3::from_rotation_x(rng.next_f64() - 0.5)
                * DVec3::new(0.0, 0.0, distance);
            let target = (DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5) * size;
            let d = (target - o).normalize();
            let t_min = if rng.next_f64() < 0.5 {
                0.0
            } else {
                distance * rng.next_f64()
            };
            let t_max = if rng.next_f64() < 0.25 {
                1e30
            } else {
                t_min + 1.5 * distance * rng.next_f64()
            };
            let (gpu_ray, cpu_ray) = kernel_ray(o, d);
            rays.push(GpuRay {
                o: [gpu_ray.o[0], gpu_ray.o[1], gpu_ray.o[2], t_min as f32],
                d: [gpu_ray.d[0], gpu_ray.d[1], gpu_ray.d[2], t_max as f32],
            });
            spans.push((cpu_ray, t_min as f32 as f64, t_max as f32 as f64));
        }
        let nearest = gpu.intersect(&scene, &rays).unwrap();
        let any = gpu.occluded(&scene, &rays).unwrap();
        for ((h, &hit), (ray, t0, t1)) in nearest.iter().zip(&any).zip(&spans) {
            total += 1;
            occluded += hit as usize;
            same += (hit == (h.v[0] >= 0.0)) as usize;
            cpu_agree += (hit == cpu.intersect(ray, *t0, *t1).is_some()) as usize;
        }
    }
    let pct = |a: usize| 100.0 * a as f64 / total as f64;
    eprintln!(
        "{total} shadow rays: {:.1}% occluded, nearest-hit query agrees {:.3}%, CPU {:.3}%",
        pct(occluded),
        pct(same),
        pct(cpu_agree)
    );
    assert!(
        (20.0..80.0).contains(&pct(occluded)),
        "{:.1}%",
        pct(occluded)
    );
    assert_eq!(
        same, total,
        "the any-hit query disagrees with the nearest hit"
    );
    assert!(pct(cpu_agree) >= 99.9);
}

/// Rays that start inside an object always leave it: the GPU finds an
/// exit for every one. Origins are random points of the objects' boxes
/// where `F' > 1e-4` (inside beyond the f32 rounding of the origin),
/// directions uniform; the objects are the white furnace's (a dent and a
/// strong bump, `factor = 2500`: segment polynomials with coefficients
/// ~1e2) and random bumpy spheres. The CPU intersects the f32-rounded
/// rays as the reference for `t`.
///
/// A first version of the GPU's root isolation recomputed each
/// subinterval's Bernstein coefficients from the power basis, so two
/// neighbours disagreed by rounding at their shared end and a root near
/// the split was lost: 14 of these 36,000 rays missed (rays inside glass
/// escaping with the wrong weight, `images.rs`). Measured after the fix
/// on lavapipe: no misses.
#[test]
fn rays_from_inside_always_leave() {
    let Some(gpu) = common::open("GPU conformance") else {
        return;
    };
    let furnace = common::example("furnace.toml");
    let mut objects = vec![furnace.geometry.objects()[0].clone()];
    let mut rng = Pcg32::new(9, 3);
    objects.extend((0..8).map(|_| random_object(&mut rng)));
    let (mut total, mut missed, mut t_ok) = (0usize, 0usize, 0usize);
    for obj in &objects {
        let bb = obj.bbox();
        let mut rays = Vec::new();
        let mut cpu_rays = Vec::new();
        while rays.len() < 4000 {
            let u = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
            let o = bb.min + (bb.max - bb.min) * u;
            // Inside at the origin the kernel reads.
            if obj.eval(o.as_vec3().as_dvec3()) <= 1e-4 {
                continue;
            }
            let d = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
            let (gpu_ray, cpu_ray) = kernel_ray(o, d);
            rays.push(gpu_ray);
            cpu_rays.push(cpu_ray);
        }
        let hits = gpu
            .intersect(&GpuScene::new(std::slice::from_ref(obj)), &rays)
            .unwrap();
        for (ray, h) in cpu_rays.iter().zip(&hits) {
            total += 1;
            let c = obj
                .intersect(ray, 0.0, f64::INFINITY)
                .expect("the CPU finds the exit");
            if h.v[0] < 0.0 {
                missed += 1;
            } else if (c.t - h.v[0] as f64).abs() < 1e-3 {
                t_ok += 1;
            }
        }
    }
    let pct = 100.0 * t_ok as f64 / (total - missed) as f64;
    eprintln!("{total} rays from inside: {missed} missed their exit, t within 1e-3 on {pct:.3}%");
    assert_eq!(missed, 0);
    assert!(pct >= 99.9);
}

/// Rays down `-z` onto a unit sphere whose one perturbation's support
/// ends exactly where the ray meets the sphere (a bump raises the surface
/// there or earlier, a dent leaves it there), 1000 objects side by side,
/// 10,000 rays: the breakpoint and the base's crossing agree to rounding,
/// and a walk that trusts the two segments' rounded ends passes through
/// the front to the back of the sphere. The CPU finds every one
/// (`crossing_within_rounding_of_a_breakpoint`); the f64 kernels too. The
/// f32 kernels compare the signs across breakpoints and take a base root
/// where the perturbations add under `BUMP_NEGLIGIBLE` (geometry.wgsl
/// `negligible_base_root`), as the CPU does: without the latter they lost
/// 1.3% (2.7% without either); with it none of these 10,000, and 1 of
/// 40,000 (a dent of factor 7e4 answered 1.1e-3 early, f32's rounding of
/// the degree-6 polynomial, not the breakpoint). Asserted: f32 below
/// 0.05%, f64 none.
#[test]
fn supports_ending_on_the_base_surface() {
    let Some(mut gpu) = common::open("the breakpoint rays") else {
        return;
    };
    let mut precisions = vec![isolux_gpu::Precision::F32];
    if gpu.supports_f64() {
        precisions.push(isolux_gpu::Precision::F64);
    }
    for precision in precisions {
        gpu.set_precision(precision).unwrap();
        let mut rng = Pcg32::new(9, 9);
        let (mut lost, mut total) = (0, 0);
        for _ in 0..10 {
            let (mut objects, mut rays, mut want) = (Vec::new(), Vec::new(), Vec::new());
            for i in 0..1000 {
                let (x, y) = (0.9 * rng.next_f64(), 0.3 * rng.next_f64());
                let z0 = (1.0 - x * x - y * y).sqrt();
                let zc = z0 + 0.05 + 0.3 * rng.next_f64();
                let f = 10f64.powf(2.0 + 3.0 * rng.next_f64());
                let sign = if rng.next_f64() < 0.5 { 1.0 } else { -1.0 };
                let c = DVec3::new(3.0 * (i % 40) as f64, 3.0 * (i / 40) as f64, 0.0);
                let bump = Perturbation {
                    quadric: Quadric::sphere(c + DVec3::new(x, y, zc), zc - z0),
                    factor: sign * f,
                };
                objects.push(Object::new(Quadric::sphere(c, 1.0), vec![bump], None).unwrap());
                rays.push(kernel_ray(c + DVec3::new(x, y, 5.0), -DVec3::Z).0);
                want.push((sign, 5.0 - z0));
            }
            let hits = gpu.intersect(&GpuScene::new(&objects), &rays).unwrap();
            for (h, &(sign, w)) in hits.iter().zip(&want) {
                total += 1;
                let t = h.v[0] as f64;
                let found = if sign > 0.0 {
                    t >= 0.0 && t <= w + 1e-3
                } else {
                    (t - w).abs() < 1e-3
                };
                lost += !found as usize;
            }
        }
        let share = lost as f64 / total as f64;
        eprintln!("{precision:?}: {lost} of {total} rays lost at the breakpoint");
        match precision {
            isolux_gpu::Precision::F32 => assert!(share < 5e-4, "{share}"),
            _ => assert_eq!(lost, 0),
        }
    }
}

/// An object whose box stretches far from its base (a second blob, 1e4
/// units away, raised by a bump of factor 1e12) keeps its base's
/// precision: the GPU writes its quadrics about the CPU object's own point
/// (the base's centre), not about the box's centre 5000 units away, where
/// f32 lost the sphere of radius 0.55 to rounding and the dipole scene
/// rendered a box of fireflies (found by a CPU/GPU comparison of fuzzed
/// scenes, where a support moved 1e4 out stretched the box without making
/// any surface there; the CPU's box no longer stretches for that, see
/// `the_solid_lies_in_its_box`). 2000 rays at the sphere and its near
/// bump: the same hit or miss as the CPU, `t` within 1e-3 on all but 0.1%.
#[test]
fn a_far_support_keeps_the_base_precise() {
    let Some(gpu) = common::open("a far support") else {
        return;
    };
    let c = DVec3::new(-0.75, 0.0, 0.0);
    let bump = |at: DVec3, factor: f64| Perturbation {
        quadric: Quadric::sphere(at, 0.3),
        factor,
    };
    let blob = DVec3::new(1e4, 0.55, 0.0);
    let object = Object::new(
        Quadric::sphere(c, 0.55),
        vec![
            bump(c + DVec3::new(0.0, 0.55, 0.0), 400.0),
            bump(blob, 1e12),
        ],
        None,
    )
    .unwrap();
    assert!(object.bbox().max.x > 1e4, "the far blob widens the box");
    assert!(object.eval(blob) > 0.0, "a blob there");
    let mut rng = Pcg32::new(5, 5);
    let rays: Vec<(DVec3, DVec3)> = (0..2000)
        .map(|_| {
            let from = c + 3.0 * sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
            let to = c + 0.7 * sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
            (from, to)
        })
        .collect();
    let hits = single_object_hits(&gpu, &object, &rays);
    let (mut agree, mut close) = (0, 0);
    for (t, c) in &hits {
        let t = *t;
        match c {
            Some(tc) if t >= 0.0 => {
                agree += 1;
                close += ((t - tc).abs() < 1e-3) as usize;
            }
            None if t < 0.0 => agree += 1,
            _ => {}
        }
    }
    eprintln!("{agree} of 2000 agree on hit or miss, {close} hits within 1e-3");
    let hits_cpu = hits.iter().filter(|(_, c)| c.is_some()).count();
    assert!(agree >= 1998, "{agree}");
    assert!(
        close as f64 >= 0.999 * hits_cpu as f64,
        "{close} of {hits_cpu}"
    );
}

/// Discs: ellipsoids 1e-3 and 1e-4 thick along an axis, off the origin,
/// hit from a few units away. The CPU took a quadric whose diagonal spans
/// more than 1e14 (1 / 0.6^2 against 1 / 1e-4^2) for degenerate and gave
/// the disc an unbounded box, so the GPU wrote it about its own origin,
/// where f32 cannot resolve a surface 2e-4 thick at distance 4 (every ray
/// missed; a fuzzed scene's disc was invisible). Rays aim at points of the
/// disc away from its rim and its pole (where the surface touches the
/// box's face, within rounding of the entry point).
#[test]
fn thin_discs_are_bounded_and_hit() {
    let Some(gpu) = common::open("thin discs") else {
        return;
    };
    let mut rng = Pcg32::new(12, 3);
    for thin in [1e-3, 1e-4] {
        let c = DVec3::new(0.75, -0.2, 0.3);
        let radii = DVec3::new(0.45, 0.6, thin);
        let object =
            Object::new(Quadric::ellipsoid(c, radii, DMat3::IDENTITY), vec![], None).unwrap();
        assert!(object.bbox().is_finite(), "{thin}: {:?}", object.bbox());
        let rays: Vec<(DVec3, DVec3)> = (0..1000)
            .map(|_| {
                let rho = 0.1 + 0.8 * rng.next_f64();
                let phi = 2.0 * std::f64::consts::PI * rng.next_f64();
                let to = c + DVec3::new(radii.x * rho * phi.cos(), radii.y * rho * phi.sin(), 0.0);
                let mut dir = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
                if dir.z.abs() < 0.3 {
                    dir.z = 0.3f64.copysign(dir.z);
                }
                (to + 4.0 * dir.normalize(), to)
            })
            .collect();
        let (mut both, mut close) = (0, 0);
        for (t, c) in single_object_hits(&gpu, &object, &rays) {
            let tc = c.expect("every ray aims at the disc");
            if t >= 0.0 {
                both += 1;
                close += ((t - tc).abs() < 0.1 * thin) as usize;
            }
        }
        eprintln!("thickness {thin}: the GPU hits {both} of 1000, {close} within a tenth of it");
        assert!(both >= 999 && close >= 995, "{thin}: {both}, {close}");
    }
}

/// Rays aimed at the poles of spheres and of discs, where the surface
/// touches its box's face: the kernel restarts a ray where it enters the
/// box, and that entry point, rounded to f32 (and the box itself, rounded
/// to nearest), could lie inside the surface by rounding, so that the
/// first crossing found was the far side's (a disc 1e-2 thick hit on its
/// back face by a ray aimed at its pole; 19-41% of these rays). Every
/// ray hits where the CPU's does, within a tenth of the object's
/// thickness.
#[test]
fn pole_rays_hit_the_near_side() {
    let Some(gpu) = common::open("pole rays") else {
        return;
    };
    let mut rng = Pcg32::new(7, 21);
    let c = DVec3::new(0.75, -0.2, 0.3);
    let mut worst = (0usize, 0usize);
    for radii in [
        DVec3::splat(0.45),
        DVec3::new(0.45, 0.6, 1e-2),
        DVec3::new(0.45, 0.6, 1e-3),
        DVec3::new(1e-2, 0.6, 0.45),
    ] {
        let object =
            Object::new(Quadric::ellipsoid(c, radii, DMat3::IDENTITY), vec![], None).unwrap();
        let thin = radii.min_element();
        let mut rays = Vec::new();
        // A disc's faces, not its rim (where a ray aimed at the rim from
        // off its plane grazes a sliver, ill-conditioned in any precision).
        let axes: Vec<usize> = (0..3).filter(|&a| radii[a] == thin).collect();
        for &axis in &axes {
            for sign in [-1.0, 1.0] {
                let mut pole = c;
                pole[axis] += sign * radii[axis];
                for _ in 0..200 {
                    // From the pole's side, within 70 degrees of its normal.
                    let mut dir = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
                    dir[axis] = sign * (0.35 + 0.65 * dir[axis].abs());
                    rays.push((pole + (3.0 + 2.0 * rng.next_f64()) * dir.normalize(), pole));
                }
            }
        }
        let mut bad = 0;
        for (t, c) in single_object_hits(&gpu, &object, &rays) {
            let ok = match c {
                Some(tc) => t >= 0.0 && (t - tc).abs() < 0.1 * thin,
                None => t < 0.0,
            };
            bad += (!ok) as usize;
        }
        eprintln!("radii {radii}: {bad} of {} pole rays off", rays.len());
        worst = worst.max((bad, rays.len()));
    }
    assert_eq!(worst.0, 0, "{worst:?}");
}

/// Planes lying on a face of their box (a floor `y = 0` whose `bounds` end
/// at `y = 0`), hit through that face by rays leaving the box and by rays
/// entering it, from 0.05 to 40 units away: the CPU hits every one (its
/// span reaches 16 ulps beyond the faces it crosses), and so does the
/// kernel, where it missed a quarter of the leaving rays (a fuzzed floor
/// rendered a quarter sky; `object_hit` now ends the walk 16 ulps beyond
/// the exit face, as it starts 16 ulps before the entry face).
#[test]
fn planes_on_their_boxs_face_are_hit() {
    let Some(gpu) = common::open("planes on a face") else {
        return;
    };
    let mut rng = Pcg32::new(5, 8);
    let mut worst = (0usize, 0.0f64);
    for plane in isolux_geometry::samples::planes_on_their_boxs_face() {
        let rays = plane.rays(300, &mut rng);
        let mut missed = 0;
        for (t, c) in single_object_hits(&gpu, &plane.object, &rays) {
            let tc = c.expect("the CPU hits every ray");
            if t < 0.0 {
                missed += 1;
            } else {
                worst.1 = worst.1.max((t - tc).abs() / tc.max(1.0));
            }
        }
        worst.0 = worst.0.max(missed);
        let (axis, side, offset) = (plane.axis, plane.side, plane.offset);
        assert_eq!(missed, 0, "axis {axis}, side {side}, offset {offset}");
    }
    eprintln!(
        "most rays missed per plane: {}; largest relative |t_gpu - t_cpu|: {:.1e}",
        worst.0, worst.1
    );
    assert!(worst.1 < 1e-5, "{}", worst.1);
}

/// A bump that dwarfs its base (factor 2.5 on a support of radius 7
/// around a sphere of radius 0.6: a shell of radius about 6.8 whose
/// segment polynomials, Q^3 expanded over 14 units, have terms of 1e6
/// around values of 20), hit from inside and from outside: the kernel's
/// root, polished by a Newton step on F' itself, is within 1e-5 of the
/// CPU's on every ray (2.3e-6 measured; 5.7e-4 without the step: a ray leaving the
/// surface 1e-4 off it then started on its far side, and a furnace scene
/// with the camera inside the shell rendered white where it is black).
#[test]
fn large_bumps_are_hit_precisely() {
    let Some(gpu) = common::open("large bumps") else {
        return;
    };
    let object = Object::new(
        Quadric::sphere(DVec3::ZERO, 0.6),
        vec![Perturbation {
            quadric: Quadric::sphere(DVec3::new(0.45, 0.3, 0.3), 7.0),
            factor: 2.5,
        }],
        None,
    )
    .unwrap();
    let mut rng = Pcg32::new(3, 9);
    let rays: Vec<(DVec3, DVec3)> = (0..400)
        .map(|k| {
            let d = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
            let from = if k % 2 == 0 {
                DVec3::new(0.3, 0.5, 3.0)
            } else {
                20.0 * d
            };
            (from, from + if k % 2 == 0 { d } else { -d })
        })
        .collect();
    let worst = single_object_hits(&gpu, &object, &rays)
        .into_iter()
        .map(|(t, c)| (t - c.expect("the shell")).abs())
        .fold(0.0, f64::max);
    eprintln!("largest |t_gpu - t_cpu| over 400 rays: {worst:.2e}");
    assert!(worst < 1e-5, "{worst:e}");
}

/// The scene the dwarfing-bump tests put their one object into (for
/// `worst_bump_condition`), and the point the bumps are centred on.
fn bump_scene() -> (isolux_render::Scene, DVec3) {
    let scene = isolux_scene::parse_str(
        "[camera]\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\n\
         [[material]]\nname = \"m\"\ntype = \"diffuse\"\n\
         [[object]]\nmaterial = \"m\"\n\
         base = { type = \"sphere\", center = [0.0, 0.0, 0.0], radius = 1.0 }\n",
        std::path::Path::new("bumps.toml"),
        std::path::Path::new("."),
    )
    .unwrap();
    (scene, BUMP_AT)
}

/// The point the dwarfing-bump tests centre their bumps on.
const BUMP_AT: DVec3 = DVec3::new(-2.5, 0.45, 0.0);

/// `object`'s condition (`worst_bump_condition`), `scene` holding it alone
/// (and still after, for `f32_ill_conditioned`).
fn condition_of(scene: &mut isolux_render::Scene, object: &Object) -> f64 {
    scene.geometry = isolux_geometry::Aggregate::new(vec![object.clone()]);
    isolux_gpu::worst_bump_condition(scene).unwrap().ratio
}

/// A point inside [`bumped_base`]'s base sphere, where half its rays start.
const BASE_INSIDE: DVec3 = DVec3::new(-2.0, 0.5, 0.3);

/// The object of the fixed-shape dwarfing-bump tests: a sphere of radius
/// 0.45 at `(-2.5, 0, 0)` under one perturbation.
fn bumped_base(quadric: Quadric, factor: f64, bounds: Option<isolux_core::Aabb>) -> Object {
    Object::new(
        Quadric::sphere(DVec3::new(-2.5, 0.0, 0.0), 0.45),
        vec![Perturbation { quadric, factor }],
        bounds,
    )
    .unwrap()
}

/// The unbounded supports of the dwarfing-bump tests (the cylinder of
/// radius 20 about the bumps' centre `BUMP_AT`), and the `bounds` (80
/// units) their objects take.
struct BumpShapes {
    big: isolux_core::Aabb,
    cone: Quadric,
    cyl: Quadric,
    parab: Quadric,
    plane: Quadric,
}

impl BumpShapes {
    fn new() -> Self {
        BumpShapes {
            big: isolux_core::Aabb {
                min: DVec3::splat(-40.0),
                max: DVec3::splat(40.0),
            },
            cone: Quadric::cone(DVec3::new(0.0, -1.0, 0.0), DVec3::Y, 0.5),
            cyl: Quadric::cylinder(BUMP_AT, DVec3::Y, 20.0),
            parab: Quadric::paraboloid(DVec3::new(0.0, -1.0, 0.0), DVec3::Y, 1.0),
            plane: Quadric::plane(DVec3::new(0.0, 0.3, 0.0), DVec3::Y),
        }
    }
}

/// The GPU's error on 400 rays at an object (half from the point
/// `inside`, half from around its box), relative to the
/// box's size: `|t_gpu - t_cpu| / size` per ray, infinite where the GPU
/// misses the CPU's hit, 0 where both miss.
fn bump_errors(gpu: &isolux_gpu::Gpu, object: &Object, inside: DVec3) -> Vec<f64> {
    let b = object.bbox();
    let size = (b.max - b.min).max_element();
    let mut rng = Pcg32::new(3, 9);
    let rays: Vec<(DVec3, DVec3)> = (0..400)
        .map(|k| {
            let d = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
            let from = if k % 2 == 0 {
                inside
            } else {
                object.origin() + (b.max - b.min).length() * d
            };
            (from, from + if k % 2 == 0 { d } else { -d })
        })
        .collect();
    single_object_hits(gpu, object, &rays)
        .into_iter()
        .map(|(t, c)| match c {
            Some(c) => (t - c).abs() / size,
            None if t < 0.0 => 0.0,
            None => f64::INFINITY,
        })
        .collect()
}

/// Bumps that dwarf their base (a sphere of radius 0.45) on the f32 and
/// the f64 intersection, against the CPU (400 rays from inside and
/// outside): below `F32_CONDITION_LIMIT` (the bump's largest `f Q^3` over
/// the base's largest `|F|` on the box) f32 places every hit within 1e-5
/// of the box's size; above it the scene is named ill-conditioned
/// (`f32_ill_conditioned`), and f64, which the renderers then use, places
/// every hit so. Bounded supports (spheres) and unbounded ones (a plane,
/// a cylinder, a paraboloid, a cone) within an object's `bounds` of 80
/// units. (The table behind the limit: `f32_condition_table`.)
#[test]
fn ill_conditioned_bumps_are_named_and_hit_in_f64() {
    let Some(mut gpu) = common::open("ill-conditioned bumps") else {
        return;
    };
    let (mut scene, at) = bump_scene();
    let BumpShapes {
        big,
        cone,
        cyl,
        parab,
        plane,
    } = BumpShapes::new();
    // Below the limit, cases the power basis had off (plane 1000: 53 of
    // 400 rays, up to 1.7 times the box; the cone at 0.1: 14), one that the
    // Bernstein basis about the box's entry had off (the cone at 100, 2.5e6)
    // and others up to the limit; above it, one of each shape.
    let cases = [
        ("sphere 0.2", Quadric::sphere(at, 0.2), 3000.0, None, false),
        ("sphere 20", Quadric::sphere(at, 20.0), 2.5, None, false),
        ("sphere 5", Quadric::sphere(at, 5.0), 3000.0, None, false),
        ("sphere 50", Quadric::sphere(at, 50.0), 3000.0, None, false),
        ("sphere 50", Quadric::sphere(at, 50.0), 3e6, None, true),
        ("plane", plane, 1000.0, Some(big), false),
        ("plane", plane, 1e5, Some(big), false),
        ("plane", plane, 1e10, Some(big), true),
        ("cylinder 20", cyl, 1.0, Some(big), false),
        ("cylinder 20", cyl, 1e3, Some(big), false),
        ("cylinder 20", cyl, 1e7, Some(big), true),
        ("paraboloid", parab, 10.0, Some(big), false),
        ("paraboloid", parab, 1e4, Some(big), false),
        ("paraboloid", parab, 1e8, Some(big), true),
        ("cone", cone, 0.1, Some(big), false),
        ("cone", cone, 100.0, Some(big), false),
        ("cone", cone, 1e6, Some(big), true),
    ];
    for (name, quadric, factor, bounds, ill) in cases {
        let object = bumped_base(quadric, factor, bounds);
        let ratio = condition_of(&mut scene, &object);
        let named = isolux_gpu::f32_ill_conditioned(&scene);
        assert_eq!(named.is_some(), ill, "{name}, f {factor}: ratio {ratio:e}");
        if let Some(why) = &named {
            assert!(why.starts_with("object[0]: perturbation 0 adds"), "{why}");
        }
        let precision = if ill {
            if !gpu.supports_f64() {
                continue;
            }
            isolux_gpu::Precision::F64
        } else {
            isolux_gpu::Precision::F32
        };
        gpu.set_precision(precision).unwrap();
        let worst = bump_errors(&gpu, &object, BASE_INSIDE)
            .into_iter()
            .fold(0.0, f64::max);
        eprintln!(
            "{name}, f {factor}: ratio {ratio:.2e}, {precision:?}: worst |t_gpu - t_cpu| / size \
             {worst:.2e}"
        );
        assert!(worst < 1e-5, "{name}, f {factor}, {precision:?}: {worst:e}");
    }
    gpu.set_precision(isolux_gpu::Precision::F32).unwrap();
}

/// Random bumps up to `F32_CONDITION_LIMIT`, in f32: 36 objects, a
/// sphere or an ellipsoid under one support of six shapes (sphere,
/// ellipsoid, plane, cylinder, cone, paraboloid, at random places and
/// orientations), its factor scaled so that the object's condition
/// (`worst_bump_condition`) is aimed log-uniformly at `[1e3, 1e10]` (it
/// can come out lower: the object's box, over which the base's `|F|` is
/// taken, shrinks with the factor), where the power basis' f32 walk lost
/// surfaces and f64 was used before 2026-12-05. Each object's rays (400,
/// errors relative to the box) are within 1e-4, all but one within 1e-5,
/// and at most 2 of the 14,400 are over 1e-5 (grazes; measured: one, at
/// 1.07e-5).
///
/// Measured 2026-12-05 on lavapipe, 240 such objects at conditions 10 to
/// 1e10 (docs/gpu.md, "Precision"): every ray within 1e-5 but one graze.
/// The Bernstein basis about the box's entry had a floor of up to 2e-4
/// for the unbounded shapes in their 80-unit box, whatever the condition,
/// and missed a graze from 138 units away (this test then asked only
/// for 4 times each object's worst at a condition of 1); the power basis,
/// below 1e3 already, had random ellipsoids off by 0.24, planes 1.8,
/// cylinders 0.03, and above it every shape off.
#[test]
fn f32_holds_random_bumps_below_the_limit() {
    let Some(mut gpu) = common::open("random bumps below the limit") else {
        return;
    };
    gpu.set_precision(isolux_gpu::Precision::F32).unwrap();
    let (mut scene, _) = bump_scene();
    let big = BumpShapes::new().big;
    let mut rng = Pcg32::new(17, 5);
    let (mut worst_all, mut off_all) = (0.0f64, 0);
    const SHAPES: [&str; 6] = [
        "sphere",
        "ellipsoid",
        "plane",
        "cylinder",
        "cone",
        "paraboloid",
    ];
    for k in 0..36 {
        let u = |rng: &mut Pcg32, a: f64, b: f64| a + (b - a) * rng.next_f64();
        let centre = DVec3::new(u(&mut rng, -1.0, 1.0), u(&mut rng, -1.0, 1.0), 0.0);
        let base = if k % 2 == 0 {
            Quadric::sphere(centre, u(&mut rng, 0.3, 0.8))
        } else {
            let r = DVec3::new(
                u(&mut rng, 0.3, 0.8),
                u(&mut rng, 0.3, 0.8),
                u(&mut rng, 0.3, 0.8),
            );
            Quadric::ellipsoid(centre, r, DMat3::from_rotation_y(u(&mut rng, 0.0, 3.0)))
        };
        let dir = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
        let at = centre + 0.5 * dir;
        let (support, bounds) = match k % 6 {
            0 => (Quadric::sphere(at, u(&mut rng, 0.2, 20.0)), None),
            1 => (
                Quadric::ellipsoid(
                    at,
                    DVec3::new(
                        u(&mut rng, 0.1, 5.0),
                        u(&mut rng, 0.1, 5.0),
                        u(&mut rng, 0.1, 5.0),
                    ),
                    DMat3::from_rotation_x(u(&mut rng, 0.0, 3.0)),
                ),
                None,
            ),
            2 => (Quadric::plane(at, dir), Some(big)),
            3 => (
                Quadric::cylinder(at, dir.any_orthonormal_vector(), u(&mut rng, 0.5, 20.0)),
                Some(big),
            ),
            4 => (
                Quadric::cone(at - dir, dir, u(&mut rng, 0.2, 0.8)),
                Some(big),
            ),
            _ => (
                Quadric::paraboloid(at - dir, dir, u(&mut rng, 0.1, 2.0)),
                Some(big),
            ),
        };
        let object_with = |factor: f64| {
            Object::new(
                base,
                vec![Perturbation {
                    quadric: support,
                    factor,
                }],
                bounds,
            )
            .unwrap()
        };
        let unit = condition_of(&mut scene, &object_with(1.0));
        let target = 10f64.powf(u(&mut rng, 3.0, 10.0)) * 0.999;
        let object = object_with(target / unit);
        let ratio = condition_of(&mut scene, &object);
        assert!(
            isolux_gpu::f32_ill_conditioned(&scene).is_none(),
            "{k}: ratio {ratio:e}"
        );
        let errs = bump_errors(&gpu, &object, centre);
        let worst = errs.iter().copied().fold(0.0, f64::max);
        eprintln!(
            "object {k} ({}): ratio {ratio:.2e}, f32 worst |t_gpu - t_cpu| / size {worst:.2e}",
            SHAPES[k % 6]
        );
        let off = errs.iter().filter(|&&e| e > 1e-5).count();
        assert!(
            worst <= 1e-4 && off <= 1,
            "object {k} ({}): ratio {ratio:e}: worst {worst:e}, {off} rays over 1e-5",
            SHAPES[k % 6]
        );
        off_all += off;
        worst_all = worst_all.max(worst);
    }
    eprintln!("36 random bumps in [1e3, 1e10]: worst {worst_all:.2e}, {off_all} rays over 1e-5");
    assert!(off_all <= 2, "{off_all} rays over 1e-5");
}

/// The table behind `F32_CONDITION_LIMIT` (docs/gpu.md, "Bumps that
/// dwarf their base"): for bumps of five shapes on a sphere of radius
/// 0.45 (the setup of `ill_conditioned_bumps_are_named_and_hit_in_f64`,
/// 400 rays from inside and outside), the condition ratio, how many rays
/// the f32 walk misses or places over 1e-5 of the box's size from the
/// CPU's hit, its worst, and f64's worst. A measurement, not a check:
/// `cargo test --release -p isolux-gpu --test conformance --
/// --ignored f32_condition_table --nocapture`.
#[test]
#[ignore]
fn f32_condition_table() {
    let Some(mut gpu) = common::open("condition table") else {
        return;
    };
    let (mut scene, at) = bump_scene();
    let BumpShapes {
        big,
        cone,
        cyl,
        parab,
        plane,
    } = BumpShapes::new();
    let cases = [
        ("sphere 0.2", Quadric::sphere(at, 0.2), 3000.0, None),
        ("cone", cone, 0.01, Some(big)),
        ("sphere 20", Quadric::sphere(at, 20.0), 0.01, None),
        ("paraboloid", parab, 1.0, Some(big)),
        ("cylinder 20", cyl, 0.1, Some(big)),
        ("plane", plane, 100.0, Some(big)),
        ("sphere 7", Quadric::sphere(at, 7.0), 2.5, None),
        ("cone", cone, 0.1, Some(big)),
        ("paraboloid", parab, 10.0, Some(big)),
        ("sphere 2", Quadric::sphere(at, 2.0), 3000.0, None),
        ("plane", plane, 1000.0, Some(big)),
        ("sphere 20", Quadric::sphere(at, 20.0), 2.5, None),
        ("sphere 5", Quadric::sphere(at, 5.0), 3000.0, None),
        ("sphere 50", Quadric::sphere(at, 50.0), 3000.0, None),
        ("sphere 50", Quadric::sphere(at, 50.0), 3e6, None),
        ("sphere 200", Quadric::sphere(at, 200.0), 3000.0, None),
        ("sphere 1000", Quadric::sphere(at, 1000.0), 3000.0, None),
        ("plane", plane, 1e5, Some(big)),
        ("cone", cone, 100.0, Some(big)),
        ("paraboloid", parab, 1e4, Some(big)),
        ("cylinder 20", cyl, 1e3, Some(big)),
    ];
    let has_f64 = gpu.supports_f64();
    println!("| support, factor | ratio | f32: rays off by over 1e-5 | f32: worst | f64: worst |");
    println!("|---|---:|---:|---:|---:|");
    for (name, quadric, factor, bounds) in cases {
        let object = bumped_base(quadric, factor, bounds);
        let ratio = condition_of(&mut scene, &object);
        let mut errors = |precision| {
            gpu.set_precision(precision).unwrap();
            bump_errors(&gpu, &object, BASE_INSIDE)
        };
        let f32s = errors(isolux_gpu::Precision::F32);
        let missed = |e: &[f64]| e.iter().any(|x| x.is_infinite());
        let worst = |e: &[f64]| {
            if missed(e) {
                "missed".to_string()
            } else {
                format!("{:.1e}", e.iter().copied().fold(0.0, f64::max))
            }
        };
        let off = f32s.iter().filter(|&&e| e > 1e-5).count();
        let f64s = if has_f64 {
            worst(&errors(isolux_gpu::Precision::F64))
        } else {
            "-".into()
        };
        println!(
            "| {name}, {factor} | {ratio:.1e} | {off} | {} | {f64s} |",
            worst(&f32s)
        );
    }
    gpu.set_precision(isolux_gpu::Precision::F32).unwrap();
}

/// Shells in f64: a bump whose `f Q^3` dwarfs the base by 1e12 to 1e18
/// (geometry's `shells_dwarfing_their_base_are_hit_exactly`), so that
/// the surface lies a hair inside the support's boundary, where the
/// segment polynomial's power basis about its start cancelled to noise.
/// Rays from inside, many from near the shell: the GPU's f64 walk (its
/// Bernstein coefficients built from the quadratics', `bern_add_cube`)
/// finds the CPU's crossing within f32's `t` (`GpuHit` is f32) and the
/// f32 rounding of the quadrics' coefficients in the buffers (which moves
/// a shell of radius 3000 by up to 9e-5 along its normal).
#[test]
fn shells_dwarfing_their_base_match_the_cpu_in_f64() {
    let Some(mut gpu) = common::open("shells") else {
        return;
    };
    if !gpu.supports_f64() {
        eprintln!("shells: the adapter has no f64; skipped");
        return;
    }
    gpu.set_precision(isolux_gpu::Precision::F64).unwrap();
    let mut rng = Pcg32::new(11, 4);
    for (radius, factor) in [(3000.0, 8000.0), (1000.0, 1.0), (300.0, 8000.0)] {
        let centre = DVec3::new(0.3, 0.1, 0.0);
        let object = Object::new(
            Quadric::sphere(DVec3::ZERO, 1.0),
            vec![Perturbation {
                quadric: Quadric::sphere(centre, radius),
                factor,
            }],
            None,
        )
        .unwrap();
        let rays: Vec<(DVec3, DVec3)> = (0..300)
            .map(|_| {
                let depth = 1e-4 * (rng.next_f64() * 9.2).exp();
                let from = centre
                    + sampling::uniform_sphere([rng.next_f64(), rng.next_f64()])
                        * radius
                        * (1.0 - depth);
                let d = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
                (from, from + d)
            })
            .collect();
        let hits = single_object_hits(&gpu, &object, &rays);
        // The buffers' f32 quadric moves the shell by up to half an ulp of
        // its constant term (`r^2`) over `|grad Q| = 2 r` along the normal,
        // `r 2^-25`: twice that along the normal, or 1e-6 of `t`.
        let along_normal = 2.0 * radius * 2f64.powi(-25);
        let off: Vec<_> = hits
            .iter()
            .zip(&rays)
            .filter(|&(&(t, c), &(from, to))| match c {
                Some(c) => {
                    let d = (to - from).normalize();
                    let n = object.normal(from + c * d);
                    (t - c).abs() * n.dot(d).abs() > along_normal + 1e-6 * c
                }
                None => t >= 0.0,
            })
            .map(|(h, _)| h)
            .collect();
        eprintln!(
            "shell radius {radius}, factor {factor}: {} of {} rays off",
            off.len(),
            hits.len()
        );
        assert!(
            off.is_empty(),
            "radius {radius}, factor {factor}: {} rays off, e.g. {:?}",
            off.len(),
            &off[..off.len().min(3)]
        );
    }
    gpu.set_precision(isolux_gpu::Precision::F32).unwrap();
}

/// Objects unbounded along a ray (an infinite slab, an infinite
/// cylinder) hit by rays of unbounded length (`t_max` 1e30, as camera
/// rays and a medium's equiangular flights have): the walk's span was
/// the whole ray, and a quadric's polynomial over it, its coefficients
/// scaled by the span squared, overflowed f32: every one of 4000 upward
/// rays missed the slab (3884 at `t_max` 1e20), and a lamp above the slab
/// lit the fog beneath it on the GPU. Walked no farther than
/// `REAL_SPAN_F32` (1e15), every ray hits where the CPU's does, within
/// 1e-5 relative.
#[test]
fn unbounded_quadrics_are_hit_along_unbounded_rays() {
    let Some(gpu) = common::open("unbounded quadrics") else {
        return;
    };
    let slab = Quadric::from_coefficients([0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.25, 0.0, -1.5]);
    let cylinder = Quadric::cylinder(DVec3::new(0.3, 0.0, -0.2), DVec3::new(0.0, 0.6, 0.8), 0.7);
    let mut rng = Pcg32::new(7, 7);
    for (name, quadric, below) in [("slab", slab, true), ("cylinder", cylinder, false)] {
        let object = Object::new(quadric, vec![], None).unwrap();
        let rays: Vec<(DVec3, DVec3)> = (0..2000)
            .map(|_| {
                let mut from = DVec3::new(
                    20.0 * rng.next_f64() - 10.0,
                    rng.next_f64() * 0.9 - 2.0,
                    20.0 * rng.next_f64() - 10.0,
                );
                let mut d = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
                if below {
                    d.y = d.y.abs();
                } else {
                    // From outside, toward a point of the axis.
                    while quadric.eval(from) >= 0.0 {
                        from += DVec3::new(1.0, 0.0, 0.0);
                    }
                    let axis = DVec3::new(0.0, 0.6, 0.8);
                    let on_axis =
                        DVec3::new(0.3, 0.0, -0.2) + (20.0 * rng.next_f64() - 10.0) * axis;
                    d = (on_axis - from).normalize();
                }
                (from, from + d)
            })
            .collect();
        let mut worst: f64 = 0.0;
        for (t, c) in single_object_hits(&gpu, &object, &rays) {
            let tc = c.unwrap_or_else(|| panic!("{name}: the CPU hits every ray"));
            assert!(
                t >= 0.0,
                "{name}: the GPU missed a ray the CPU hits at {tc}"
            );
            worst = worst.max((t - tc).abs() / tc);
        }
        eprintln!("{name}: 2000 rays, largest relative |t_gpu - t_cpu| {worst:.1e}");
        assert!(worst < 5e-5, "{name}: {worst:e}");
    }
}

/// A small base in a large box, hit from afar: a sphere or an ellipsoid
/// (radius 0.3 to 0.8) under one unbounded support (a plane, a cone or a
/// paraboloid) whose `bounds` stretch the object's box to 80 units, 2000
/// rays from 139 units away at points near the base. Such a ray enters
/// the box some 40 units before the base, and the base's quadratic about
/// the entry was a difference of terms near 1600 around values near 0.1,
/// which f32 resolved to 0.025 along rays at a sphere of radius 0.36 (7%
/// of it); since 2026-12-05 it is taken about its vertex along the ray
/// (`object_hit`'s `tv`), and the supports' about each segment's start.
/// What is asserted is the error along the surface's normal, `|t_gpu -
/// t_cpu| cos` (a graze's `t` is ill-conditioned by `1 / cos`): within
/// 6e-5, 4 ulp of f32 at 139 units (the ray's origin in the object's
/// frame and the `t` returned are rounded there); and at most 2 rays of
/// 2000 hit by one back end only (grazes). Measured on lavapipe: worst
/// 1.5e-5 to 2.4e-5 per object, at most one ray disagreeing; about the
/// entry, 8.4e-5 to 1.3e-3 and 2 rays on the first two objects.
#[test]
fn small_bases_in_large_boxes_are_hit_from_afar() {
    let Some(gpu) = common::open("small bases in large boxes") else {
        return;
    };
    let big = BumpShapes::new().big;
    let mut rng = Pcg32::new(23, 7);
    let u = |rng: &mut Pcg32, a: f64, b: f64| a + (b - a) * rng.next_f64();
    for k in 0..12 {
        let centre = DVec3::new(u(&mut rng, -1.0, 1.0), u(&mut rng, -1.0, 1.0), 0.0);
        let r = u(&mut rng, 0.3, 0.8);
        let base = if k % 2 == 0 {
            Quadric::sphere(centre, r)
        } else {
            let radii = DVec3::new(r, u(&mut rng, 0.3, 0.8), u(&mut rng, 0.3, 0.8));
            Quadric::ellipsoid(centre, radii, DMat3::from_rotation_y(u(&mut rng, 0.0, 3.0)))
        };
        let dir = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
        let at = centre + 0.5 * dir;
        let support = match k % 3 {
            0 => Quadric::plane(at, dir),
            1 => Quadric::cone(at - dir, dir, u(&mut rng, 0.2, 0.8)),
            _ => Quadric::paraboloid(at - dir, dir, u(&mut rng, 0.1, 2.0)),
        };
        let object = Object::new(
            base,
            vec![Perturbation {
                quadric: support,
                factor: 10f64.powf(u(&mut rng, -1.0, 1.3)),
            }],
            Some(big),
        )
        .unwrap();
        let rays: Vec<(DVec3, DVec3)> = (0..2000)
            .map(|_| {
                let mut on_sphere = || sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
                (centre + 139.0 * on_sphere(), centre + 1.2 * r * on_sphere())
            })
            .collect();
        let hits = single_object_hits(&gpu, &object, &rays);
        let (mut disagree, mut worst) = (0, 0.0f64);
        for ((t, c), (from, to)) in hits.iter().zip(&rays) {
            match c {
                Some(tc) if *t >= 0.0 => {
                    let (_, ray) = kernel_ray(*from, (*to - *from).normalize());
                    let n = object.intersect(&ray, 0.0, 1e30).unwrap().n;
                    worst = worst.max((t - tc).abs() * n.dot(ray.dir).abs());
                }
                None if *t < 0.0 => {}
                _ => disagree += 1,
            }
        }
        eprintln!(
            "object {k}: {disagree} of 2000 rays hit by one back end only, worst |t_gpu - t_cpu| \
             cos {worst:.2e}"
        );
        assert!(
            disagree <= 2 && worst < 6e-5,
            "object {k}: {disagree}, {worst:e}"
        );
    }
}

/// A surface made by a bump far from its object's base (a support of
/// radius 50 or 20 around the rays' start, on a sphere of radius 0.6 or
/// 600 moved 300 to 1e5 units away, within `bounds` of 120 units; half
/// the rays from inside the blob, half from outside the box). The GPU
/// wrote such an object about its base's centre (`layout.rs`,
/// `object_origin`), far from the supports that make its surface, whose
/// f32 constant terms then rounded by the distance squared times 2^-24:
/// from 3000 units f32 misplaced most hits by up to 2.4e-4 of the box, f64
/// (reading the same f32 coefficients) by 3.4e-5 (`gpu-diff-fuzz.py --seed
/// 34`: the perturbed sphere moved 3000 units off with its bump grown
/// around the camera, twice as bright on the GPU). With the frame at the
/// box's point nearest the rays' origin and each quadric written about its
/// own anchor (`object_origin`, `anchor_in`), every hit lies within 1e-5 of
/// the box in f32 (lavapipe: 1.3e-7 at most), so such scenes are not sent
/// to f64 (`f32_ill_conditioned`).
#[test]
fn far_bases_are_hit_in_f32() {
    let Some(mut gpu) = common::open("far bases") else {
        return;
    };
    let bounds = isolux_core::Aabb {
        min: DVec3::splat(-60.0),
        max: DVec3::splat(60.0),
    };
    let mut precisions = vec![isolux_gpu::Precision::F32];
    if gpu.supports_f64() {
        precisions.push(isolux_gpu::Precision::F64);
    }
    for (z, r, f, rad) in [
        (300.0, 0.6, 300.0, 50.0),
        (1000.0, 0.6, 300.0, 50.0),
        (3000.0, 0.6, 300.0, 50.0),
        (3000.0, 0.6, 3.0, 50.0),
        (3000.0, 600.0, 300.0, 50.0),
        (-3000.0, 0.6, 300.0, 50.0),
        (3000.0, 0.6, 3e5, 20.0),
        (1e5, 0.6, 300.0, 50.0),
    ] {
        let object = Object::new(
            Quadric::sphere(DVec3::new(0.0, 0.0, z), r),
            vec![Perturbation {
                quadric: Quadric::sphere(DVec3::new(0.0, 0.6, 0.0), rad),
                factor: f,
            }],
            Some(bounds),
        )
        .unwrap();
        let mut scene = bump_scene().0;
        condition_of(&mut scene, &object);
        let what = format!("base at z {z}, radius {r}; bump {f} of radius {rad}");
        let why = isolux_gpu::f32_ill_conditioned(&scene);
        assert!(why.is_none(), "{what}: {why:?}");
        for &precision in &precisions {
            gpu.set_precision(precision).unwrap();
            let e = bump_errors(&gpu, &object, DVec3::new(0.0, 0.9, 3.6));
            let worst = e.iter().copied().fold(0.0, f64::max);
            println!("{what}: {precision:?}, worst {worst:.1e}");
            assert!(worst < 1e-5, "{what}: {precision:?} off by {worst:e}");
        }
    }
    // Without `bounds` the object has two parts, the blob around the
    // origin and the base sphere 3000 units off, each hit precisely: the
    // frame lies near the rays' origin, each quadric is written about a
    // point near where it acts (before, about the base's centre, the blob
    // rendered twice as bright). Rays from inside the blob, and from 10
    // units off the base towards it (its GPU coordinates rounded by 1.2e-4
    // there, so 5e-4 is allowed).
    gpu.set_precision(isolux_gpu::Precision::F32).unwrap();
    let object = Object::new(
        Quadric::sphere(DVec3::new(0.0, 0.0, 3000.0), 0.6),
        vec![Perturbation {
            quadric: Quadric::sphere(DVec3::new(0.0, 0.6, 0.0), 50.0),
            factor: 300.0,
        }],
        None,
    )
    .unwrap();
    let mut rng = Pcg32::new(8, 1);
    for (from, spread, limit) in [
        (DVec3::new(0.0, 0.9, 3.6), 1.0, 5e-5),
        (DVec3::new(3.0, 2.0, 2990.0), 0.0, 5e-4),
    ] {
        let rays: Vec<(DVec3, DVec3)> = (0..400)
            .map(|_| {
                let d = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
                let to = if spread > 0.0 {
                    from + d
                } else {
                    DVec3::new(0.0, 0.0, 3000.0) + 0.55 * d
                };
                (from, to)
            })
            .collect();
        let hits = single_object_hits(&gpu, &object, &rays);
        let missed = hits
            .iter()
            .filter(|(t, c)| c.is_some() != (*t >= 0.0))
            .count();
        let found = hits.iter().filter(|(_, c)| c.is_some()).count();
        let worst = hits
            .iter()
            .filter_map(|&(t, c)| c.filter(|_| t >= 0.0).map(|c| (t - c).abs()))
            .fold(0.0, f64::max);
        println!(
            "two parts, rays from {from}: {found} hits, {missed} disagree, worst {worst:.1e} units"
        );
        assert!(found > 300, "{found}");
        assert_eq!(missed, 0, "rays from {from}");
        assert!(worst < limit, "rays from {from}: off by {worst:e}");
    }
}

/// Small bumps on a large base sphere (a planet of radius 10 to 1000 under
/// 20 bumps of radius 0.1 to 10 on its top, seen from a camera a few bump
/// radii above them): every CPU hit is hit by the f32 walk, 99% within
/// 1e-5 of the bumps' size and all within 1e-4 of it. Before each quadric
/// was written about its own anchor and the frame about the point of the
/// box nearest the camera (`layout.rs`, `object_origin`, `anchor_in`), the
/// bumps' quadrics were written about the planet's centre: 99% within
/// 4.3e-3 units on a planet of 100 with bumps of 1, the worst 0.64, and in
/// f64 (from the same f32 coefficients) no better.
#[test]
fn bumps_far_from_their_frame_are_hit_precisely() {
    let Some(mut gpu) = common::open("bumps on a planet") else {
        return;
    };
    gpu.set_precision(isolux_gpu::Precision::F32).unwrap();
    for (big, small) in [
        (10.0, 0.1),
        (100.0, 1.0),
        (100.0, 0.3),
        (1000.0, 1.0),
        (1000.0, 10.0),
    ] {
        let mut rng = Pcg32::new(5, 5);
        let bumps: Vec<Perturbation> = (0..20)
            .map(|_| {
                let at = DVec3::new(rng.next_f64() - 0.5, 0.0, rng.next_f64() - 0.5) * 10.0 * small;
                Perturbation {
                    quadric: Quadric::sphere(at, small),
                    factor: big / small.powi(5),
                }
            })
            .collect();
        let planet = Object::new(
            Quadric::sphere(DVec3::new(0.0, -big, 0.0), big),
            bumps,
            None,
        )
        .unwrap();
        let eye = DVec3::new(0.0, 3.0 * small, 8.0 * small);
        let rays: Vec<(DVec3, DVec3)> = (0..4000)
            .map(|_| {
                let to = DVec3::new(rng.next_f64() - 0.5, 0.0, rng.next_f64() - 0.5) * 10.0 * small;
                (eye, to)
            })
            .collect();
        let hits = single_object_hits(&gpu, &planet, &rays);
        let mut errors: Vec<f64> = hits
            .iter()
            .filter_map(|&(t, c)| {
                c.map(|c| {
                    if t < 0.0 {
                        f64::INFINITY
                    } else {
                        (t - c).abs()
                    }
                })
            })
            .collect();
        errors.sort_by(f64::total_cmp);
        let n = errors.len();
        let (p99, worst) = (errors[n * 99 / 100], errors[n - 1]);
        println!("planet {big}, bumps {small}: {n} hits, median {:.1e}, 99% {p99:.1e}, worst {worst:.1e} units", errors[n / 2]);
        assert!(n > 3000, "{n} hits");
        let unit = small.max(1.0);
        assert!(
            p99 < 1e-5 * unit && worst < 1e-4 * unit,
            "planet {big}, bumps {small}: 99% {p99:e}, worst {worst:e}"
        );
    }
}

/// Rays that enter a support far (50-180 units) from their object's
/// frame: the walk recomputes the support's roots about each segment's
/// start, where the root it just crossed comes back within rounding of
/// it, a few 1e-5 there. Before the walk skipped that root
/// (`geometry.wgsl`, `object_hit`'s `last`), a root just beyond the
/// breakpoints' `eps` made every segment a few ulps long, until the walk's
/// guard ended it with no hit: 1-8 of 400 rays from outside missed a
/// bump's blob whose base lay 40-100 units off (the base of radius 0.6 at
/// `z`, inside or outside a support of radius 30 or 50 about the origin),
/// whatever the bump's factor; and rays missed a bumpy plane 400 units
/// wide. Every ray the CPU hits, the f32 walk hits within 1e-5 of the box.
#[test]
fn walks_step_past_the_support_they_enter() {
    let Some(mut gpu) = common::open("supports far from the frame") else {
        return;
    };
    gpu.set_precision(isolux_gpu::Precision::F32).unwrap();
    let check = |object: &Object, rays: &[(DVec3, DVec3)], what: &str| {
        let b = object.bbox();
        let size = (b.max - b.min).max_element();
        let hits = single_object_hits(&gpu, object, rays);
        let missed = hits.iter().filter(|(t, c)| c.is_some() && *t < 0.0).count();
        let worst = hits
            .iter()
            .filter_map(|&(t, c)| c.filter(|_| t >= 0.0).map(|c| (t - c).abs() / size))
            .fold(0.0, f64::max);
        let found = hits.iter().filter(|(_, c)| c.is_some()).count();
        println!("{what}: {found} hits on the CPU, {missed} missed, worst {worst:.1e} of the box");
        assert!(
            found > rays.len() / 10,
            "{what}: only {found} hits to compare"
        );
        assert_eq!(missed, 0, "{what}: rays the CPU hits missed");
        assert!(worst < 1e-5, "{what}: off by {worst:e} of the box");
    };
    let bounds = isolux_core::Aabb {
        min: DVec3::splat(-60.0),
        max: DVec3::splat(60.0),
    };
    for (rad, z) in [(50.0, 40.0), (50.0, 60.0), (50.0, 100.0), (30.0, 60.0)] {
        for f in [3.0, 300.0] {
            let object = Object::new(
                Quadric::sphere(DVec3::new(0.0, 0.0, z), 0.6),
                vec![Perturbation {
                    quadric: Quadric::sphere(DVec3::new(0.0, 0.6, 0.0), rad),
                    factor: f,
                }],
                Some(bounds),
            )
            .unwrap();
            let b = object.bbox();
            let mut rng = Pcg32::new(3, 9);
            let rays: Vec<(DVec3, DVec3)> = (0..400)
                .map(|_| {
                    let d = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
                    let from = object.origin() + (b.max - b.min).length() * d;
                    (from, from - d)
                })
                .collect();
            check(
                &object,
                &rays,
                &format!("blob of radius {rad}, base at z {z}, factor {f}"),
            );
        }
    }
    // A terrain: the plane y = 0 under 40 bumps of radius 8 spread over
    // 400 units, seen from a camera 30 units up at one corner (before: 3
    // of 2000 rays missed it on lavapipe).
    let mut rng = Pcg32::new(11, 5);
    let bumps = (0..40)
        .map(|_| {
            let at = DVec3::new(
                400.0 * rng.next_f64() - 200.0,
                0.0,
                400.0 * rng.next_f64() - 200.0,
            );
            Perturbation {
                quadric: Quadric::sphere(at, 8.0),
                factor: 1.0 / 8f64.powi(5),
            }
        })
        .collect();
    let terrain = Object::new(
        Quadric::plane(DVec3::ZERO, DVec3::Y),
        bumps,
        Some(isolux_core::Aabb {
            min: DVec3::new(-210.0, -8.0, -210.0),
            max: DVec3::new(210.0, 8.0, 210.0),
        }),
    )
    .unwrap();
    let eye = DVec3::new(-205.0, 30.0, -205.0);
    let rays: Vec<(DVec3, DVec3)> = (0..2000)
        .map(|_| {
            let target = DVec3::new(
                400.0 * rng.next_f64() - 200.0,
                0.0,
                400.0 * rng.next_f64() - 200.0,
            );
            (eye, target)
        })
        .collect();
    check(&terrain, &rays, "bumpy plane 400 units wide");
}
