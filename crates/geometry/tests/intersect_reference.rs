//! Exact intersection against a brute-force reference.
//!
//! The reference evaluates `F'` from the raw ten coefficients (its own code,
//! not `Quadric::eval`), samples it densely along the ray, and bisects the
//! first sign change to machine precision. The exact intersector must:
//! - never miss a crossing the reference finds (ours is never later);
//! - never invent one: every hit it reports is a genuine sign change of the
//!   reference `F'` in a tiny neighbourhood (thin bumps that fall between two
//!   reference samples are the only place where ours may be earlier);
//! - agree in `t` to 1e-6 relative, and in the normal with central finite
//!   differences of the reference `F'`.

use isolux_core::{sampling, Aabb, DMat3, DVec3, Pcg32, Ray};
use isolux_geometry::samples::{bumpy_sphere, fibonacci_sphere};
use isolux_geometry::{Aggregate, Beam, Culled, Hit, Object, Perturbation, Quadric};
use rayon::prelude::*;

/// Reference quadric value from raw coefficients.
fn q_ref(a: &[f64; 10], p: DVec3) -> f64 {
    let (x, y, z) = (p.x, p.y, p.z);
    a[0] * x * x
        + a[1] * y * y
        + a[2] * z * z
        + 2.0 * (a[3] * x * y + a[4] * x * z + a[5] * y * z)
        + 2.0 * (a[6] * x + a[7] * y + a[8] * z)
        + a[9]
}

struct RefObject {
    base: [f64; 10],
    perts: Vec<([f64; 10], f64)>,
    /// Region in which the reference searches (contains the whole surface).
    region: Aabb,
}

impl RefObject {
    /// The reference of `obj` (its own coefficients, read back and moved
    /// from its frame to world coordinates), searching `region`.
    fn of(obj: &Object, region: Aabb) -> Self {
        let world = |q: &Quadric| q.translated(obj.origin()).coefficients();
        RefObject {
            base: world(obj.base()),
            perts: obj
                .perturbations()
                .iter()
                .map(|p| (world(&p.quadric), p.factor))
                .collect(),
            region,
        }
    }

    fn f(&self, p: DVec3) -> f64 {
        let mut v = q_ref(&self.base, p);
        for (q, f) in &self.perts {
            let x = q_ref(q, p);
            if x > 0.0 {
                v += f * x * x * x;
            }
        }
        v
    }

    fn first_crossing(&self, ray: &Ray, samples: usize) -> Option<f64> {
        let (t0, t1) = self.region.clip(ray, 0.0, f64::INFINITY)?;
        let mut prev_t = t0;
        let mut prev = self.f(ray.at(t0));
        for i in 1..=samples {
            let t = t0 + (t1 - t0) * i as f64 / samples as f64;
            let v = self.f(ray.at(t));
            if (v > 0.0) != (prev > 0.0) {
                let (mut lo, mut hi) = (prev_t, t);
                for _ in 0..200 {
                    let m = 0.5 * (lo + hi);
                    if (self.f(ray.at(m)) > 0.0) == (prev > 0.0) {
                        lo = m;
                    } else {
                        hi = m;
                    }
                }
                return Some(0.5 * (lo + hi));
            }
            prev = v;
            prev_t = t;
        }
        None
    }

    /// Whether `F'` changes sign within some small neighbourhood of `t`.
    fn genuine(&self, ray: &Ray, t: f64) -> bool {
        let scale = 1.0 + t.abs();
        [1e-6, 1e-8, 1e-10, 1e-12].iter().any(|&d| {
            let a = self.f(ray.at(t - d * scale));
            let b = self.f(ray.at(t + d * scale));
            (a > 0.0) != (b > 0.0)
        })
    }

    fn fd_normal(&self, p: DVec3) -> Option<DVec3> {
        let h = 1e-6;
        let g = DVec3::new(
            self.f(p + DVec3::X * h) - self.f(p - DVec3::X * h),
            self.f(p + DVec3::Y * h) - self.f(p - DVec3::Y * h),
            self.f(p + DVec3::Z * h) - self.f(p - DVec3::Z * h),
        ) / (2.0 * h);
        (g.length() > 1e-6).then(|| -g.normalize())
    }
}

fn random_rotation(rng: &mut Pcg32) -> DMat3 {
    DMat3::from_rotation_z(6.3 * rng.next_f64())
        * DMat3::from_rotation_y(6.3 * rng.next_f64())
        * DMat3::from_rotation_x(6.3 * rng.next_f64())
}

/// A random object and its reference twin. Kinds: ellipsoid base with
/// ellipsoid bumps/dents (most), a bounded plane, a bounded cylinder, and an
/// unbounded (plane) perturbation on a sphere.
fn random_object(rng: &mut Pcg32) -> (Object, RefObject) {
    random_object_with(rng, 0.5, false)
}

/// [`random_object`] with a share `spheres` of its perturbations' supports
/// spheres (the others rotated ellipsoids), and with `round`, a sphere
/// instead of the ellipsoid base (same random draws).
fn random_object_with(rng: &mut Pcg32, spheres: f64, round: bool) -> (Object, RefObject) {
    let kind = rng.next_below(8);
    let centre = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5;
    let (base, bounds, region) = match kind {
        0 => {
            let b = Aabb::new(centre - 1.2, centre + 1.2);
            (
                Quadric::plane(centre, sampling::uniform_sphere(rng.next_2d())),
                Some(b),
                b,
            )
        }
        1 => {
            let b = Aabb::new(centre - 1.2, centre + 1.2);
            let axis = sampling::uniform_sphere(rng.next_2d());
            (
                Quadric::cylinder(centre, axis, 0.5 + 0.4 * rng.next_f64()),
                Some(b),
                b,
            )
        }
        _ => {
            let radii = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 0.7 + 0.3;
            let q = Quadric::ellipsoid(centre, radii, random_rotation(rng));
            let q = if round {
                Quadric::sphere(centre, radii.x)
            } else {
                q
            };
            (q, None, Aabb::new(centre - 1.6, centre + 1.6))
        }
    };
    let n = rng.next_below(33) as usize;
    let mut perts = Vec::new();
    for _ in 0..n {
        // Centre near the base surface: a point in the region pulled onto
        // the zero set by a few Newton steps.
        let mut p = centre + (sampling::uniform_sphere(rng.next_2d()) * 0.8);
        for _ in 0..8 {
            let g = base.gradient(p);
            let g2 = g.length_squared();
            if g2 > 1e-12 {
                p -= base.eval(p) / g2 * g;
            }
        }
        let r = 0.08 + 0.3 * rng.next_f64();
        let quadric = if rng.next_f64() < spheres {
            Quadric::sphere(p, r)
        } else {
            let radii = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * r + 0.3 * r;
            Quadric::ellipsoid(p, radii, random_rotation(rng))
        };
        // Bump height ~ f r^6 / |grad F|: span thin (1e-4 of r) to tall.
        let height = r * 10f64.powf(-4.0 + 4.5 * rng.next_f64());
        let sign = if rng.next_f64() < 0.6 { 1.0 } else { -1.0 };
        let factor = sign * height / r.powi(6).max(1e-12);
        // Keep the reference region valid: bumps stay inside it.
        if !region.contains(p + DVec3::splat(r)) || !region.contains(p - DVec3::splat(r)) {
            continue;
        }
        perts.push(Perturbation { quadric, factor });
    }
    if kind == 7 {
        // An unbounded perturbation (a plane) carving a dent on a bounded base.
        perts.push(Perturbation {
            quadric: Quadric::plane(centre + DVec3::Y * 0.2, -DVec3::Y),
            factor: -3.0,
        });
    }
    let obj = Object::new(base, perts, bounds).expect("valid random object");
    let region = bounds.map(|b| b.intersection(&region)).unwrap_or(region);
    let reference = RefObject::of(&obj, region);
    (obj, reference)
}

#[derive(Default, Debug)]
struct Tally {
    rays: usize,
    hits: usize,
    agree: usize,
    thin_found: usize,
    missed: Vec<String>,
    invented: Vec<String>,
    t_error: Vec<String>,
    normal_error: Vec<String>,
}

impl Tally {
    /// Counts one ray: our hit `ours` against the reference's first
    /// crossing `refr` (`label` names the ray's object in messages).
    fn add(
        &mut self,
        reference: &RefObject,
        ray: &Ray,
        ours: Option<Hit>,
        refr: Option<f64>,
        label: impl Fn() -> String,
    ) {
        self.rays += 1;
        let desc = || {
            format!(
                "{} ray {ray:?}: ours {:?} reference {refr:?}",
                label(),
                ours.map(|h| h.t)
            )
        };
        let Some(h) = ours else {
            if refr.is_some() {
                self.missed.push(desc());
            }
            return;
        };
        self.hits += 1;
        let tol = 1e-6 * h.t.abs().max(1.0);
        let consistent = match refr {
            Some(tr) if (h.t - tr).abs() <= tol => {
                self.agree += 1;
                true
            }
            Some(tr) if h.t > tr => {
                self.missed.push(desc());
                false
            }
            _ => {
                // Ours is earlier than anything the reference saw: a thin
                // feature between two samples.
                if reference.genuine(ray, h.t) {
                    self.thin_found += 1;
                    true
                } else {
                    self.invented.push(desc());
                    false
                }
            }
        };
        if consistent {
            if (ray.at(h.t) - h.p).length() > 1e-9 {
                self.t_error.push(desc());
            }
            if let Some(n) = reference.fd_normal(h.p) {
                if (n - h.n).length() > 1e-4 {
                    self.normal_error
                        .push(format!("{} normal {:?} vs fd {:?}", desc(), h.n, n));
                }
            }
        }
    }

    fn merge(parts: Vec<Tally>) -> Tally {
        let mut total = Tally::default();
        for p in parts {
            total.rays += p.rays;
            total.hits += p.hits;
            total.agree += p.agree;
            total.thin_found += p.thin_found;
            total.missed.extend(p.missed);
            total.invented.extend(p.invented);
            total.t_error.extend(p.t_error);
            total.normal_error.extend(p.normal_error);
        }
        total
    }
}

fn run(objects: usize, rays_per_object: usize, samples: usize, seed: u64) -> Tally {
    let parts: Vec<Tally> = (0..objects)
        .into_par_iter()
        .map(|oi| {
            let mut rng = Pcg32::new(seed, oi as u64);
            let (obj, reference) = random_object(&mut rng);
            let mut tally = Tally::default();
            for _ in 0..rays_per_object {
                let target = reference.region.center()
                    + (DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5) * 1.6;
                let origin = if rng.next_f64() < 0.8 {
                    target + sampling::uniform_sphere(rng.next_2d()) * 4.0
                } else {
                    // Rays starting inside the region, some inside the solid.
                    target + sampling::uniform_sphere(rng.next_2d()) * 0.3
                };
                let ray = Ray::new(origin, (target - origin).normalize());
                let ours = obj.intersect(&ray, 0.0, f64::INFINITY);
                let refr = reference.first_crossing(&ray, samples);
                tally.add(&reference, &ray, ours, refr, || format!("object {oi}"));
            }
            tally
        })
        .collect();
    Tally::merge(parts)
}

fn check(t: &Tally) {
    eprintln!(
        "rays {} hits {} agree {} thin features found between reference samples {}",
        t.rays, t.hits, t.agree, t.thin_found
    );
    for (name, list) in [
        ("missed", &t.missed),
        ("invented", &t.invented),
        ("t error", &t.t_error),
        ("normal error", &t.normal_error),
    ] {
        assert!(
            list.is_empty(),
            "{} {name}:\n{}",
            list.len(),
            list.iter().take(5).cloned().collect::<Vec<_>>().join("\n")
        );
    }
    assert!(t.hits > t.rays / 4, "too few hits for a meaningful test");
}

#[test]
fn hundred_thousand_random_rays_match_brute_force() {
    let t = run(1000, 100, 2000, 20261122);
    assert!(t.rays >= 100_000);
    check(&t);
}

/// The geometry benchmark's objects cast as tiles (`Object::intersect_tile`,
/// whose rays meeting one to three raising sphere supports take the
/// vectorized lane walk of `object/solo.rs`) against the brute-force
/// reference directly, not only against the per-ray walk: the benchmark's
/// 16 and 64 bumps, and the same 64 centres with radii, heights (thin to
/// tall) and signs (bumps and dents) drawn at random, in parallel and
/// pinhole tiles of 64 rays.
#[test]
fn benchmark_objects_cast_in_tiles_match_brute_force() {
    let mut rng = Pcg32::new(20261201, 3);
    let mut objects = vec![bumpy_sphere(16), bumpy_sphere(64)];
    let mixed: Vec<Perturbation> = fibonacci_sphere(64, 0.6)
        .into_iter()
        .map(|c| {
            let r = 0.08 + 0.2 * rng.next_f64();
            let height = r * 10f64.powf(-4.0 + 4.0 * rng.next_f64());
            let sign = if rng.next_f64() < 0.7 { 1.0 } else { -1.0 };
            Perturbation {
                quadric: Quadric::sphere(c, r),
                factor: sign * height * 1.2 / r.powi(6),
            }
        })
        .collect();
    objects.push(Object::new(Quadric::sphere(DVec3::ZERO, 0.6), mixed, None).unwrap());
    let region = Aabb::new(DVec3::splat(-1.2), DVec3::splat(1.2));
    let references: Vec<RefObject> = objects.iter().map(|o| RefObject::of(o, region)).collect();
    let tiles: Vec<(usize, Tile, u64)> = (0..3 * 40)
        .map(|i| {
            let mut t = Tile::random(&mut rng, i % 2 == 0);
            // Aim at the sphere's surface, where the bumps are.
            t.w = 0.02 + 0.12 * rng.next_f64();
            (i % 3, t, rng.next_u32() as u64)
        })
        .collect();
    let parts: Vec<Tally> = tiles
        .par_iter()
        .map(|(oi, tile, seed)| {
            let (obj, reference) = (&objects[*oi], &references[*oi]);
            let mut rng = Pcg32::new(*seed, 0);
            let rays: Vec<Ray> = (0..64)
                .map(|_| tile.ray(2.0 * rng.next_f64() - 1.0, 2.0 * rng.next_f64() - 1.0))
                .collect();
            let mut culled = Vec::new();
            obj.cull(&tile.beam(), &mut culled);
            let mut got = vec![None; rays.len()];
            obj.intersect_tile(&rays, 0.0, f64::INFINITY, &culled, &mut got);
            let mut tally = Tally::default();
            for (ray, ours) in rays.iter().zip(got) {
                let refr = reference.first_crossing(ray, 2000);
                tally.add(reference, ray, ours, refr, || format!("object {oi}"));
            }
            tally
        })
        .collect();
    let t = Tally::merge(parts);
    assert!(t.rays >= 7000);
    check(&t);
}

/// A tile of rays aimed near the origin: from one eye (`pinhole`, a cone
/// of directions) or parallel (a cylinder of origins), `w` wide.
struct Tile {
    eye: DVec3,
    axis: DVec3,
    u: DVec3,
    v: DVec3,
    w: f64,
    pinhole: bool,
}

impl Tile {
    fn random(rng: &mut Pcg32, pinhole: bool) -> Self {
        let target = (DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5) * 1.5;
        let eye = target + sampling::uniform_sphere(rng.next_2d()) * (2.0 + 3.0 * rng.next_f64());
        let axis = (target - eye).normalize();
        let (u, v) = axis.any_orthonormal_pair();
        let w = 0.02 + 0.3 * rng.next_f64();
        Tile {
            eye,
            axis,
            u,
            v,
            w,
            pinhole,
        }
    }

    /// The ray at `(a, b)` in `[-1, 1]^2` across the tile.
    fn ray(&self, a: f64, b: f64) -> Ray {
        let off = self.w * (a * self.u + b * self.v);
        if self.pinhole {
            Ray::new(self.eye, (self.axis + off).normalize())
        } else {
            Ray::new(self.eye + 2.0 * off, self.axis)
        }
    }

    /// The beam around the tile's four corner rays.
    fn beam(&self) -> Beam {
        let grid = [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)];
        if self.pinhole {
            Beam::cone(self.eye, &grid.map(|(a, b)| self.ray(a, b).dir))
        } else {
            Beam::cylinder(self.axis, &grid.map(|(a, b)| self.ray(a, b).origin))
        }
        .expect("a narrow tile has a beam")
    }
}

/// Coherent culling (`Aggregate::cull` + `intersect_culled`) finds, for
/// every ray inside its tile's beam, the hit that the per-ray BVH walk
/// finds (itself checked against the brute force above): the same object,
/// `t` to 1e-9 relative (candidates may be summed in another order), and
/// some tiles must actually cull something.
#[test]
fn tile_culled_rays_find_the_per_ray_hit() {
    let mut rng = Pcg32::new(99, 4);
    let (mut rays, mut hits, mut culled_away) = (0, 0, 0);
    let mut culled = Culled::default();
    for scene in 0..60 {
        let objects: Vec<Object> = (0..1 + rng.next_below(3))
            .map(|_| random_object(&mut rng).0)
            .collect();
        let total: usize = objects.iter().map(|o| o.perturbations().len()).sum();
        let agg = Aggregate::new(objects);
        for _ in 0..40 {
            // A tile: a pinhole cone (even scenes) or parallel rays (odd).
            let tile = Tile::random(&mut rng, scene % 2 == 0);
            let (ray_at, beam) = (|a, b| tile.ray(a, b), tile.beam());
            agg.cull(&beam, &mut culled);
            culled_away += total - culled.perturbation_count().min(total);
            for _ in 0..25 {
                let ray = ray_at(2.0 * rng.next_f64() - 1.0, 2.0 * rng.next_f64() - 1.0);
                let want = agg.intersect(&ray, 0.0, f64::INFINITY);
                let got = agg.intersect_culled(&ray, 0.0, f64::INFINITY, &culled);
                rays += 1;
                match (want, got) {
                    (None, None) => {}
                    (Some((i, a)), Some((j, b))) => {
                        hits += 1;
                        assert_eq!(i, j, "{ray:?}");
                        assert!(
                            (a.t - b.t).abs() <= 1e-9 * a.t.abs().max(1.0),
                            "{ray:?} {} {}",
                            a.t,
                            b.t
                        );
                        assert!((a.n - b.n).length() < 1e-6, "{ray:?}");
                    }
                    (a, b) => panic!(
                        "{ray:?}: per ray {:?}, culled {:?}",
                        a.map(|h| h.1.t),
                        b.map(|h| h.1.t)
                    ),
                }
            }
        }
    }
    assert!(hits > rays / 4, "{hits} of {rays}");
    assert!(
        culled_away > 1000,
        "culling removed only {culled_away} perturbations"
    );
}

/// `Object::intersect_tile` (the base and the first gathering phase done
/// for a tile's rays together) finds exactly, to the last bit, the hits of
/// `Object::intersect_culled` ray by ray: on sphere bases whose supports
/// are all spheres (the batched path, with and without culled supports),
/// on other bases and on mixed supports (which fall back), over `[0, inf)`
/// and over finite intervals.
#[test]
fn tile_batches_find_the_per_ray_hits() {
    let mut rng = Pcg32::new(7, 11);
    let (mut rays, mut hits, mut batched, mut bare) = (0, 0, 0, 0);
    let mut culled = Vec::new();
    for scene in 0..120 {
        let spheres = if scene % 4 == 3 { 0.5 } else { 1.0 };
        let round = scene % 3 != 2;
        let obj = random_object_with(&mut rng, spheres, round).0;
        for _ in 0..20 {
            let tile = Tile::random(&mut rng, scene % 2 == 0);
            let (ray_at, beam) = (|a, b| tile.ray(a, b), tile.beam());
            culled.clear();
            obj.cull(&beam, &mut culled);
            let n = 1 + rng.next_below(64) as usize;
            let batch: Vec<Ray> = (0..n)
                .map(|_| ray_at(2.0 * rng.next_f64() - 1.0, 2.0 * rng.next_f64() - 1.0))
                .collect();
            let (t_min, t_max) = if rng.next_below(3) == 0 {
                (2.0 * rng.next_f64(), 2.0 + 4.0 * rng.next_f64())
            } else {
                (0.0, f64::INFINITY)
            };
            let mut got = vec![None; n];
            obj.intersect_tile(&batch, t_min, t_max, &culled, &mut got);
            for (ray, got) in batch.iter().zip(&got) {
                let want = obj.intersect_culled(ray, t_min, t_max, &culled);
                assert_eq!(*got, want, "{ray:?} on [{t_min}, {t_max}]");
                rays += 1;
                hits += got.is_some() as usize;
                let c = obj.base().coefficients();
                let sphere = c[0] == c[1] && c[1] == c[2] && c[3..6] == [0.0; 3];
                if sphere && got.is_some() {
                    if culled.is_empty() {
                        bare += 1;
                    } else {
                        batched += 1;
                    }
                }
            }
        }
    }
    assert!(hits > rays / 4, "{hits} of {rays}");
    eprintln!("{rays} rays, {hits} hits, {batched} batched, {bare} bare");
    assert!(
        batched > 5000 && bare > 500,
        "{batched} batched, {bare} bare"
    );
}

/// `Object::cull_within` (a tile's list taken from its block's) holds
/// every perturbation that `Object::cull` lists for the tile, nothing
/// outside the block's list, and gives the same hits.
#[test]
fn tiles_culled_within_a_block_keep_every_candidate() {
    let mut rng = Pcg32::new(3, 17);
    let (mut rays, mut narrowed) = (0, 0);
    let (mut outer_list, mut inner_list, mut within) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..60 {
        let obj = random_object(&mut rng).0;
        for _ in 0..10 {
            let target = (DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5) * 1.5;
            let axis = sampling::uniform_sphere(rng.next_2d());
            let eye = target - 3.0 * axis;
            let (u, v) = axis.any_orthonormal_pair();
            let w = 0.1 + 0.4 * rng.next_f64();
            let at = |a: f64, b: f64| eye + w * (a * u + b * v);
            let grid = [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)];
            let outer = Beam::cylinder(axis, &grid.map(|(a, b)| at(a, b))).unwrap();
            outer_list.clear();
            obj.cull(&outer, &mut outer_list);
            for _ in 0..8 {
                // A quarter-size tile somewhere inside the block.
                let (a0, b0) = (rng.next_f64() * 1.5 - 1.0, rng.next_f64() * 1.5 - 1.0);
                let tile = |a: f64, b: f64| at(a0 + 0.25 * (a + 1.0), b0 + 0.25 * (b + 1.0));
                let inner = Beam::cylinder(axis, &grid.map(|(a, b)| tile(a, b))).unwrap();
                inner_list.clear();
                within.clear();
                obj.cull(&inner, &mut inner_list);
                obj.cull_within(&inner, &outer_list, &mut within);
                assert!(inner_list.iter().all(|k| within.contains(k)));
                assert!(within.iter().all(|k| outer_list.contains(k)));
                narrowed += outer_list.len() - within.len();
                for _ in 0..8 {
                    let o = tile(2.0 * rng.next_f64() - 1.0, 2.0 * rng.next_f64() - 1.0);
                    let ray = Ray::new(o, axis);
                    let want = obj.intersect_culled(&ray, 0.0, f64::INFINITY, &inner_list);
                    let got = obj.intersect_culled(&ray, 0.0, f64::INFINITY, &within);
                    assert_eq!(got, want, "{ray:?}");
                    rays += 1;
                }
            }
        }
    }
    assert!(
        rays > 30_000 && narrowed > 1000,
        "{rays} rays, {narrowed} narrowed"
    );
}

#[test]
#[ignore = "slow: a million rays at 8000 reference samples"]
fn million_random_rays_match_brute_force() {
    check(&run(10_000, 100, 8000, 7));
}

#[test]
fn tangent_and_grazing_rays() {
    // A unit sphere grazed at distance 1 - eps from the centre: two
    // crossings that merge as eps -> 0; exactly tangent rays do not enter.
    let obj = Object::new(Quadric::sphere(DVec3::ZERO, 1.0), vec![], None).unwrap();
    for k in 1..12 {
        let eps = 10f64.powi(-k);
        let ray = Ray::new(DVec3::new(-3.0, 1.0 - eps, 0.0), DVec3::X);
        let h = obj
            .intersect(&ray, 0.0, f64::INFINITY)
            .expect("near-grazing ray hits");
        let x = -(1.0 - (1.0 - eps) * (1.0 - eps)).sqrt();
        assert!((h.p.x - x).abs() < 1e-7, "eps {eps}: {} vs {x}", h.p.x);
    }
    let tangent = Ray::new(DVec3::new(-3.0, 1.0, 0.0), DVec3::X);
    assert!(obj.intersect(&tangent, 0.0, f64::INFINITY).is_none());
}

/// Rays spawned off a hit (`Hit::spawn`, the renderer's rule: `1e-7 (1 +
/// |p - origin|) + 1e-14 |p|` along the normal) do not find the surface
/// they leave, on a bumpy object at the world origin and on the same
/// object written in a frame a billion units away, where the offset is
/// about 1e-5 (the world frame's `1e-7 (1 + |p|)` would be 100 units).
#[test]
fn rays_leaving_the_surface_do_not_rehit() {
    for far in [DVec3::ZERO, DVec3::new(1e9, -2e9, 0.5e9)] {
        let mut rng = Pcg32::new(99, 1);
        let mut perts = vec![];
        for _ in 0..32 {
            let p = sampling::uniform_sphere(rng.next_2d()) * 0.6;
            perts.push(Perturbation {
                quadric: Quadric::sphere(p, 0.2),
                factor: if rng.next_f64() < 0.5 {
                    2000.0
                } else {
                    -2000.0
                },
            });
        }
        let base = Quadric::sphere(DVec3::ZERO, 0.6);
        let obj = Object::in_frame(far, base, perts, None).unwrap();
        let (mut rehits, mut hits) = (0, 0);
        for _ in 0..20_000 {
            let o = far + sampling::uniform_sphere(rng.next_2d()) * 3.0;
            let to = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 0.6 - 0.3;
            let d = (far + to - o).normalize();
            let Some(h) = obj.intersect(&Ray::new(o, d), 0.0, f64::INFINITY) else {
                continue;
            };
            hits += 1;
            assert!(h.offset < 2e-7 + 1e-14 * 2.5e9, "{}", h.offset);
            // Outgoing direction in the outer hemisphere.
            let mut w = sampling::uniform_sphere(rng.next_2d());
            if w.dot(h.n) < 0.0 {
                w = -w;
            }
            if let Some(h2) = obj.intersect(&Ray::new(h.spawn(w), w), 0.0, f64::INFINITY) {
                if h2.t < 1e-5 {
                    rehits += 1;
                }
            }
        }
        assert!(hits > 5_000, "{far}: {hits} hits");
        assert_eq!(rehits, 0, "{far}");
    }
}

#[test]
fn thin_bump_of_height_1e7_is_found_exactly() {
    // Unit sphere with a bump of radius 0.1 at the pole; f = 0.2 raises it
    // by about f r^6 / |grad F| = 0.2e-6 / 2 = 1e-7. Marching would need a
    // step far below 1e-7 to see it; the exact method finds it to 1e-12.
    let f = 0.2;
    let pole = DVec3::new(0.0, 0.0, 1.0);
    let obj = Object::new(
        Quadric::sphere(DVec3::ZERO, 1.0),
        vec![Perturbation {
            quadric: Quadric::sphere(pole, 0.1),
            factor: f,
        }],
        None,
    )
    .unwrap();
    let g = |x: f64, z: f64| {
        let q = 0.01 - x * x - (z - 1.0) * (z - 1.0);
        1.0 - x * x - z * z + if q > 0.0 { f * q * q * q } else { 0.0 }
    };
    for i in 0..40 {
        let x = i as f64 * 0.003; // across the footprint and beyond (0.1)
        let ray = Ray::new(DVec3::new(x, 0.0, 5.0), -DVec3::Z);
        let h = obj.intersect(&ray, 0.0, f64::INFINITY).unwrap();
        // Reference: bisection of g(x, z) on z in [0.9, 1.1] (outside: g < 0).
        let (mut lo, mut hi) = ((1.0 - x * x).sqrt() - 1e-3, 1.1);
        for _ in 0..200 {
            let m = 0.5 * (lo + hi);
            if g(x, m) > 0.0 {
                lo = m;
            } else {
                hi = m;
            }
        }
        let z = 0.5 * (lo + hi);
        assert!((h.p.z - z).abs() < 1e-12, "x {x}: {} vs {z}", h.p.z);
        let base = (1.0 - x * x).sqrt();
        if x < 0.09 {
            assert!(
                h.p.z - base > 1e-9,
                "x {x}: the bump must raise the surface"
            );
        } else if x > 0.1 {
            assert!(
                (h.p.z - base).abs() < 1e-14,
                "outside the footprint: the base sphere"
            );
        }
    }
}

/// Shells: a bump so large and strong that `f Q^3` inside its support
/// dwarfs the base quadric by up to 1e20, so that `F'` crosses zero a
/// hair inside the support's boundary (where `Q` is 1e-6 to 1e-2 of its
/// largest value). Rays from inside, many from near the shell, must find
/// that crossing: the reference is dense bracketing of `F'` evaluated as
/// written (`F + f Q^3`, well conditioned) and bisection.
///
/// The segment polynomial in the power basis about the segment's start
/// cancelled to noise near the support's end, and Halley's stopping rule,
/// relative to `s`, stopped early there: 2026-12-05, of 2000 rays per
/// shell, 530 (radius 3000, factor 8000: the fuzzed `metals.toml` shell),
/// 236 (radius 300, factor 8000) and 44 (radius 1000, factor 1) were off by
/// up to 5e-5 of `t`, and the walk reported the support's end instead
/// (`Bernstein6`).
#[test]
fn shells_dwarfing_their_base_are_hit_exactly() {
    let mut rng = Pcg32::new(5, 12);
    for (radius, factor) in [
        (3000.0, 8000.0),
        (300.0, 8000.0),
        (1000.0, 1.0),
        (1e4, 1.0),
        (1e5, 1e-6),
    ] {
        let centre = DVec3::new(0.3, 0.1, 0.0);
        let obj = Object::new(
            Quadric::sphere(DVec3::ZERO, 1.0),
            vec![Perturbation {
                quadric: Quadric::sphere(centre, radius),
                factor,
            }],
            None,
        )
        .unwrap();
        let reference = RefObject::of(
            &obj,
            Aabb::new(DVec3::splat(-1.01 * radius), DVec3::splat(1.01 * radius)),
        );
        let mut off = Vec::new();
        for _ in 0..150 {
            // From anywhere inside the solid, down to 1e-4 of the radius from
            // the support's boundary (the shell lies 6e-7 to 5e-5 of it inside).
            let depth = 1e-4 * (rng.next_f64() * 9.2).exp();
            let o = centre
                + sampling::uniform_sphere([rng.next_f64(), rng.next_f64()])
                    * radius
                    * (1.0 - depth);
            let d = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
            let ray = Ray::new(o, d);
            let want = reference.first_crossing(&ray, 20_000).unwrap_or_else(|| {
                panic!(
                    "radius {radius}: {ray:?} from inside the shell must cross it, F({o}) = {}",
                    reference.f(o)
                )
            });
            let got = obj.intersect(&ray, 0.0, f64::INFINITY).map(|h| h.t);
            if got.is_none_or(|t| (t - want).abs() > 1e-9 * want) {
                off.push((got, want));
            }
        }
        assert!(
            off.is_empty(),
            "radius {radius}, factor {factor}: {} of 150 rays off, e.g. {:?}",
            off.len(),
            &off[..off.len().min(3)]
        );
    }
}

/// A crossing within rounding of a breakpoint: here the base quadric's
/// crossing, where a strong bump's support ends a hair later, so that the
/// bump adds ~1e-16 there. Each of the two segments that meet there saw its
/// end value on its own side of zero and reported nothing until the walk
/// compared the signs across breakpoints (found by the million-ray test,
/// object 315 of seed 7).
#[test]
fn crossing_within_rounding_of_a_breakpoint() {
    let mut rng = Pcg32::new(7, 315);
    let (obj, reference) = random_object(&mut rng);
    let ray = Ray::new(
        DVec3::new(-2.367742819099955, -1.892125441134239, 2.790498130559265),
        DVec3::new(0.6114092122911864, 0.3668069342183115, -0.7011643517284905),
    );
    let ours = obj.intersect(&ray, 0.0, f64::INFINITY).map(|h| h.t);
    let want = reference.first_crossing(&ray, 8000).unwrap();
    assert!(
        (ours.unwrap() - want).abs() < 1e-6,
        "{ours:?} vs reference {want}"
    );
    // Since objects live in the frame of their box's centre, that ray no
    // longer lands within rounding of its breakpoint. The case built on
    // purpose: a bump whose support ends exactly where a ray down -z
    // meets the unit sphere, 20,000 of them. The first crossing is there
    // or earlier (where the bump rises above the ray), and `F'` changes
    // sign at it (the reference's own coefficients). Without the
    // comparison of signs across breakpoints about 0.3% of them pass
    // through the front and hit the back of the sphere.
    let region = Aabb::new(DVec3::splat(-2.0), DVec3::splat(2.0));
    let mut rng = Pcg32::new(1, 2);
    for _ in 0..20_000 {
        let (x, y) = (0.9 * rng.next_f64(), 0.3 * rng.next_f64());
        let z0 = (1.0 - x * x - y * y).sqrt();
        let zc = z0 + 0.05 + 0.3 * rng.next_f64();
        let bump = Perturbation {
            quadric: Quadric::sphere(DVec3::new(x, y, zc), zc - z0),
            factor: 10f64.powf(2.0 + 3.0 * rng.next_f64()),
        };
        let obj = Object::new(Quadric::sphere(DVec3::ZERO, 1.0), vec![bump], None).unwrap();
        let ray = Ray::new(DVec3::new(x, y, 5.0), -DVec3::Z);
        let t = obj.intersect(&ray, 0.0, f64::INFINITY).map(|h| h.t);
        let reference = RefObject::of(&obj, region);
        assert!(
            t.is_some_and(|t| t <= 5.0 - z0 + 1e-9 && reference.genuine(&ray, t)),
            "{x} {y} {zc}: {t:?}, the sphere at {}",
            5.0 - z0
        );
    }
}

/// The scale the scene loader allows (`MAX_EXTENT`, 1e7 units across the
/// camera and every bounded object, so no ray origin lies farther than
/// its diagonal, 1.74e7, from an object): spheres of radius 1e-3 to 1e7
/// are found from every distance up to that, from outside and inside, at
/// the distance that a cancellation-free closed form gives. (Beyond about
/// 3e7 units the closed form treats the quadratic as linear and misses:
/// docs/geometry.md, "Scene scale".)
#[test]
fn spheres_are_found_across_the_scene_extent() {
    let diagonal = 1.0e7 * 3f64.sqrt();
    let mut rng = Pcg32::new(11, 3);
    for r in [1e-3, 1.0, 1e3, 1e7] {
        let obj = Object::new(Quadric::sphere(DVec3::ZERO, r), vec![], None).unwrap();
        for d in [2.0 * r, 1e3, 1e6, diagonal] {
            // A sphere under a millionth of a radian across is lost to
            // that cancellation (its discriminant's terms agree to 1e-12
            // and more): nearer than 1e6 radii only.
            if d <= r || d > 1e6 * r {
                continue;
            }
            for _ in 0..8 {
                // From distance d, aimed at a point within r/2 of the
                // centre, in a random direction.
                let at = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]) * d;
                let aim = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]) * (0.5 * r);
                let dir = (aim - at).normalize();
                let ray = Ray::new(at, dir);
                // Independent: the nearer root of |at + t dir|^2 = r^2 in
                // the cancellation-free form (b' = at.dir, the offset of
                // the line from the centre h^2 = |at|^2 - b'^2).
                let b = at.dot(dir);
                let h2 = (at - b * dir).length_squared();
                let want = -b - (r * r - h2).sqrt();
                let hit = obj
                    .intersect(&ray, 0.0, f64::INFINITY)
                    .unwrap_or_else(|| panic!("r {r:e}, d {d:e}: missed"));
                // The power basis loses digits to cancellation as the
                // sphere shrinks in view: its discriminant's two terms
                // agree to about (r / d)^2, so t carries an error of
                // about eps d^2 / r (1e-4 of the radius at d / r = 1e6).
                let tol = 1e-9 * (r + d) + 4.0 * f64::EPSILON * d * d / r;
                assert!(
                    (hit.t - want).abs() <= tol,
                    "r {r:e}, d {d:e}: t {} want {want}",
                    hit.t
                );
            }
        }
        // From inside, at a random point within r/2 of the centre: the
        // far root.
        for _ in 0..8 {
            let at = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]) * (0.5 * r);
            let dir = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
            let b = at.dot(dir);
            let h2 = (at - b * dir).length_squared();
            let want = -b + (r * r - h2).sqrt();
            let hit = obj
                .intersect(&Ray::new(at, dir), 0.0, f64::INFINITY)
                .unwrap_or_else(|| panic!("r {r:e}: missed from inside"));
            assert!(
                (hit.t - want).abs() <= 1e-9 * r,
                "r {r:e}: t {} want {want}",
                hit.t
            );
        }
    }
}

/// The solid `{F' >= 0}` lies in the object's box, which a bounded base
/// tightens to where `F >= -delta` (`delta` the bumps' largest `f Q^3`):
/// random points around 300 random objects (the reference objects with
/// an ellipsoid base, and spheres with tall bumps, some of whose supports reach far beyond the
/// base), every point inside the solid inside the box. And a support far
/// from the base, where it makes no surface, no longer stretches the box.
#[test]
fn the_solid_lies_in_its_box() {
    let mut rng = Pcg32::new(31, 7);
    let mut inside = 0usize;
    for k in 0..300 {
        let obj = if k % 2 == 0 {
            random_object(&mut rng).0
        } else {
            let c = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5;
            let perts = (0..1 + rng.next_below(6))
                .map(|_| {
                    let at = c + sampling::uniform_sphere(rng.next_2d()) * (3.0 * rng.next_f64());
                    let r = 0.1 + 1.5 * rng.next_f64();
                    let sign = if rng.next_f64() < 0.7 { 1.0 } else { -1.0 };
                    Perturbation {
                        quadric: Quadric::sphere(at, r),
                        factor: sign * 10f64.powf(-1.0 + 4.0 * rng.next_f64()),
                    }
                })
                .collect();
            Object::new(Quadric::sphere(c, 0.3 + 0.5 * rng.next_f64()), perts, None).unwrap()
        };
        let b = obj.bbox();
        // Bounded bases only: a plane or cylinder's solid is clipped by
        // its `bounds`, which `eval` does not see.
        if obj.base().positive_bounds().is_none() {
            continue;
        }
        // Points in the box grown by half its size on each side.
        let (lo, size) = (b.min - 0.5 * (b.max - b.min), 2.0 * (b.max - b.min));
        for _ in 0..4000 {
            let p = lo + size * DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
            if obj.eval(p) >= 0.0 {
                inside += 1;
                assert!(
                    b.contains(p),
                    "object {k}: {p} inside the solid, outside {b:?}"
                );
            }
        }
    }
    assert!(inside > 10_000, "{inside}");
    // A support 1e4 out on a sphere of radius 0.55: the box stays the
    // sphere's and its near bump's.
    let c = DVec3::new(-0.75, 0.0, 0.0);
    let bump = |at: DVec3| Perturbation {
        quadric: Quadric::sphere(at, 0.3),
        factor: 400.0,
    };
    let far = Object::new(
        Quadric::sphere(c, 0.55),
        vec![
            bump(c + DVec3::new(0.0, 0.55, 0.0)),
            bump(DVec3::new(1e4, 0.55, 0.0)),
        ],
        None,
    )
    .unwrap();
    let b = far.bbox();
    assert!(b.max.x < 1.0 && b.min.x > -1.4 && b.max.y < 0.9, "{b:?}");
}

/// `Object::exit_bound` (the closed-form bound manifold next-event
/// estimation decides by) is a lower bound on the first crossing: from
/// random points inside random objects (bumps, dents, bounded planes and
/// cylinders), the reference `F'` stays positive at 400 samples up to it,
/// and the exact intersector's crossing is never sooner. It is also of
/// use: for most rays it reaches half way to the crossing or more.
#[test]
fn exit_bound_is_a_lower_bound_of_the_crossing() {
    let mut rng = Pcg32::new(77, 5);
    let (mut rays, mut useful, mut dents) = (0usize, 0usize, 0usize);
    for k in 0..400 {
        let (obj, reference) = random_object(&mut rng);
        let b = reference.region;
        let mut tries = 0;
        let mut found = 0;
        while found < 20 && tries < 4000 {
            tries += 1;
            let p = b.min
                + (b.max - b.min) * DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
            if !(reference.f(p) > 0.0) {
                continue;
            }
            found += 1;
            let ray = Ray::new(p, sampling::uniform_sphere(rng.next_2d()));
            let t_max = 5.0;
            let bound = obj.exit_bound(&ray, t_max);
            assert!((0.0..=t_max).contains(&bound), "object {k}: {bound}");
            for i in 0..400 {
                let t = bound * i as f64 / 400.0;
                assert!(
                    reference.f(ray.at(t)) > 0.0,
                    "object {k}: F' <= 0 at {t}, before the bound {bound}"
                );
            }
            if let Some(hit) = obj.intersect(&ray, 0.0, t_max) {
                assert!(
                    bound <= hit.t * (1.0 + 1e-9),
                    "object {k}: bound {bound} beyond the crossing {}",
                    hit.t
                );
                rays += 1;
                useful += usize::from(bound >= 0.5 * hit.t);
            }
        }
        dents += usize::from(obj.perturbations().iter().any(|q| q.factor < 0.0));
    }
    assert!(
        rays > 3000 && dents > 50,
        "{rays} rays, {dents} objects with dents"
    );
    assert!(useful * 2 > rays, "{useful} of {rays} at least half way");
}

/// `Object::hessian` against central differences of `Object::gradient`,
/// at random points of random objects (bumps, dents, supports' edges
/// included: `f Q^3` has a continuous second derivative).
#[test]
fn hessian_matches_differences_of_the_gradient() {
    let mut rng = Pcg32::new(78, 9);
    for k in 0..300 {
        let (obj, reference) = random_object(&mut rng);
        let b = reference.region;
        for _ in 0..20 {
            let p = b.min
                + (b.max - b.min) * DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
            let h = obj.hessian(p);
            let scale = (0..3).map(|i| h.col(i).length()).fold(1.0, f64::max);
            for u in [DVec3::X, DVec3::Y, DVec3::Z] {
                let eps = 1e-5;
                let fd = (obj.gradient(p + eps * u) - obj.gradient(p - eps * u)) / (2.0 * eps);
                assert!(
                    (h * u - fd).length() <= 1e-5 * scale,
                    "object {k} at {p}: {} against {fd}",
                    h * u
                );
            }
        }
    }
}
