//! Tests of [`Object`](super::Object): its exact intersection against
//! dense root bracketing and closed forms, its culling and its box.

use super::walk::{positive_on, reach, sign_is_fixed, support_interval};
use super::*;
use crate::poly::two_roots;
use isolux_core::DMat3;

/// Discs (ellipsoids 0.45 x 0.6 x 2r, r from 1e-3 down to 1e-7), at
/// the origin and off it, hit from about 4 units away by rays aimed at
/// points from the pole out to 1e-2 of the radius: every ray hits the
/// front face, between the mid-plane and the face's farthest reach along
/// the ray (r / |d_z|). The box's face touches the surface at the pole;
/// the quadric along a ray from afar placed the crossing there before
/// the box's entry by rounding, and a third of these rays missed a disc
/// 2e-6 thick (`Object::intersect_in` restarts at the entry).
#[test]
fn thin_discs_are_hit_at_their_pole() {
    for r in [1e-3, 1e-4, 1e-5, 1e-6, 1e-7] {
        for c in [DVec3::ZERO, DVec3::new(0.75, -0.2, 0.3)] {
            let e = Quadric::ellipsoid(c, DVec3::new(0.45, 0.6, r), DMat3::IDENTITY);
            let o = Object::new(e, vec![], None).unwrap();
            assert!(o.bbox().is_finite());
            for rho in [0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2] {
                for j in 0..100 {
                    let (phi, k) = (j as f64 * 0.1, j as f64);
                    let to = c + DVec3::new(0.45 * rho * phi.cos(), 0.6 * rho * phi.sin(), 0.0);
                    let side = DVec3::new(0.3 * (k * 0.37).sin(), 0.3 * (k * 0.71).cos(), 0.0);
                    let from = to + side + DVec3::new(0.0, 0.0, 4.0);
                    let ray = Ray::new(from, (to - from).normalize());
                    let h = o
                        .intersect(&ray, 0.0, 1e30)
                        .unwrap_or_else(|| panic!("r {r}, centre {c}, rho {rho}: missed"));
                    // The mid-plane z = c.z at t_mid; the front face
                    // at most r / |d_z| before it.
                    let t_mid = (c.z - from.z) / ray.dir.z;
                    let reach = r / ray.dir.z.abs();
                    assert!(
                        h.t <= t_mid + 1e-9 && h.t >= t_mid - reach * (1.0 + 1e-6) - 1e-9,
                        "r {r}, rho {rho}: t {} against [{}, {t_mid}]",
                        h.t,
                        t_mid - reach
                    );
                    assert!(h.n.z > 0.99, "r {r}, rho {rho}: normal {}", h.n);
                }
            }
        }
    }
}

/// An unbounded base written about a far point of its own (a plane, a
/// cylinder up its axis, tilted) moves its frame to the point nearest
/// the world origin along the directions that leave it unchanged, so
/// its hits near the origin keep the offset they have written about a
/// near point; a paraboloid, a cone and a plane's point off the origin
/// along its normal keep theirs (a move would change the surface).
#[test]
fn unbounded_bases_move_their_frame_near_the_world_origin() {
    let tilt = DVec3::new(0.3, 1.0, -0.2).normalize();
    let side = tilt.cross(DVec3::X).normalize();
    let cases = [
        (Quadric::plane(DVec3::ZERO, tilt), 1e7 * side, DVec3::ZERO),
        (
            Quadric::plane(DVec3::ZERO, tilt),
            3.0 * tilt + 1e7 * side,
            3.0 * tilt,
        ),
        (
            Quadric::cylinder(DVec3::ZERO, tilt, 0.5),
            1e7 * tilt,
            DVec3::ZERO,
        ),
        (
            Quadric::cylinder(DVec3::ZERO, tilt, 0.5),
            side + 1e6 * tilt,
            side,
        ),
    ];
    for (q, at, want) in cases {
        let o = Object::in_frame(at, q, vec![], None).unwrap();
        assert!(
            (o.origin() - want).length() < 1e-6,
            "{q:?} about {at}: frame at {}, want {want}",
            o.origin()
        );
        // The same surface: `q` reads the same about `at` and about
        // `want`, a move along its unchanging directions away (written
        // about `want`, since about `at` rounding alone would differ).
        for k in 0..20 {
            let p = want + DVec3::new(k as f64 * 0.37 - 3.0, (k as f64 * 1.3).sin(), 0.5);
            let exact = q.eval(p - want);
            let near = o.base().eval(p - o.origin());
            assert!(
                (exact - near).abs() < 1e-6 * (1.0 + exact.abs()),
                "{exact} against {near}"
            );
        }
        let from = want + 3.0 * side + 0.5 * tilt;
        let ray = Ray::new(from, (want - from).normalize());
        let h = o.intersect(&ray, 0.0, 1e30).expect("hit");
        assert!(h.offset < 1e-5, "offset {}", h.offset);
    }
    let kept = [
        Quadric::paraboloid(DVec3::ZERO, tilt, 0.25),
        Quadric::cone(DVec3::ZERO, tilt, 0.3),
        Quadric::sphere(DVec3::ZERO, 1.0),
    ];
    for q in kept {
        let at = 2.0 * side + 1e3 * tilt;
        let o = Object::in_frame(at, q, vec![], None).unwrap();
        if !o.bbox().is_finite() {
            assert_eq!(o.origin(), at, "{q:?}");
        }
    }
}

/// Planes lying on a face of their box (a floor `y = 0` whose `bounds`
/// end at `y = 0`, tilted planes on a tilted box's face excluded: the
/// box is axis-aligned), hit through that face from inside the box (the
/// ray leaves through it) and from outside (it enters through it), from
/// near and far, at any angle: every ray hits, where the plane is. The
/// span ended exactly at the face, and the crossing, rounded
/// independently, fell beyond it on a quarter of the leaving rays (a
/// fuzzed scene's floor was a quarter sky).
#[test]
fn planes_on_their_boxs_face_are_hit() {
    let mut rng = isolux_core::Pcg32::new(5, 8);
    for plane in crate::samples::planes_on_their_boxs_face() {
        let (axis, offset) = (plane.axis, plane.offset);
        let mut missed = 0;
        for (from, to) in plane.rays(400, &mut rng) {
            let far = (to - from).length();
            let ray = Ray::new(from, (to - from) / far);
            match plane.object.intersect(&ray, 0.0, f64::INFINITY) {
                Some(h) => {
                    assert!((h.p[axis] - offset).abs() < 1e-12, "{}", h.p);
                    assert!((h.t - far).abs() < 1e-9 * far.max(1.0), "{} {far}", h.t);
                }
                None => missed += 1,
            }
        }
        assert_eq!(
            missed, 0,
            "axis {axis}, side {}, offset {offset}",
            plane.side
        );
    }
}

/// A bump that dwarfs its base (the white furnace's sphere with a
/// support of radius 50 and factor 2500, a fuzzed scene: `f Q^3` up to
/// 4e13 where `F'` near the surface is of order 1e3) makes a closed
/// shell around the camera. Diffuse paths bouncing inside it (5,000
/// paths of 64 bounces, leaving each hit by `Hit::spawn`) must never
/// get out: the segment polynomials' roots lay microns off the wall,
/// as far as the spawn offset there (`1e-7 (1 + |p|)`, 5e-6), and
/// where a root lay outside by more, the next ray met the wall again
/// from outside and went on outward (16 leaks here; the furnace
/// rendered speckles of sky where it is black). Now every hit is
/// polished by Newton steps on `F'` itself (`polish`, up to
/// `POLISH_STEPS`): each lies within 1e-9 of the surface (by `|F'| /
/// |grad F'|`; one step left 2.3e-9), and no path leaks. Tiles of
/// camera rays, polished in lanes, give the per-ray hits to the bit
/// (without the lanes' further steps they differ in the last bits).
#[test]
fn paths_inside_a_bump_shell_stay_inside() {
    use isolux_core::{sampling, Frame, Pcg32};
    let o = Object::new(
        Quadric::sphere(DVec3::ZERO, 0.6),
        vec![
            Perturbation {
                quadric: Quadric::sphere(DVec3::new(0.0, 0.0, 0.6), 0.35),
                factor: -600.0,
            },
            Perturbation {
                quadric: Quadric::sphere(DVec3::new(0.45, 0.3, 0.3), 50.0),
                factor: 2500.0,
            },
        ],
        None,
    )
    .unwrap();
    let mut rng = Pcg32::new(1, 2);
    let (mut leaks, mut worst) = (0, 0.0f64);
    for _ in 0..5000 {
        let d = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
        let mut ray = Ray::new(DVec3::new(0.3, 0.5, 3.0), d);
        for _ in 0..64 {
            let Some(h) = o.intersect(&ray, 0.0, f64::INFINITY) else {
                leaks += 1;
                break;
            };
            worst = worst.max(o.eval(h.p).abs() / o.gradient(h.p).length());
            let n = if h.n.dot(ray.dir) > 0.0 { -h.n } else { h.n };
            let wi = Frame::from_normal(n).to_world(sampling::cosine_hemisphere([
                rng.next_f64(),
                rng.next_f64(),
            ]));
            ray = Ray::new(h.spawn(wi), wi);
        }
    }
    assert!(worst < 1e-9, "a hit {worst:e} off the surface");
    assert_eq!(leaks, 0);
    // Tiles of camera rays (`solo::hits` polishes in lanes): the
    // per-ray hits to the last bit.
    let culled = [0, 1];
    for k in 0..16 {
        let axis = sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
        let (u, v) = axis.any_orthonormal_pair();
        let rays: Vec<Ray> = (0..TILE_RAYS)
            .map(|j| {
                let (x, y) = ((j % 8) as f64 - 3.5, (j / 8) as f64 - 3.5);
                Ray::new(
                    DVec3::new(0.3, 0.5, 3.0),
                    axis + 1e-3 * (k as f64 + 1.0) * (x * u + y * v),
                )
            })
            .collect();
        let mut got = vec![None; rays.len()];
        o.intersect_tile(&rays, 0.0, f64::INFINITY, &culled, &mut got);
        for (ray, got) in rays.iter().zip(&got) {
            assert_eq!(*got, o.intersect_culled(ray, 0.0, f64::INFINITY, &culled));
            let h = got.expect("the shell");
            assert!(o.eval(h.p).abs() / o.gradient(h.p).length() < 1e-9);
        }
    }
}

/// The lanes of `solo::walk` (one or two supports) answer most rays of
/// bumpy spheres (random
/// parallel and perspective tiles; bumps that raise, carve, or barely
/// rise; directions of any length; open and finite intervals), and
/// their answers are the per-ray walk's to the last bit, with every
/// instruction set.
#[test]
fn solo_lanes_match_the_per_ray_walk() {
    use crate::simd::Isa;
    for (seed, cap) in [(41, None), (42, Some(Isa::Baseline)), (43, Some(Isa::Avx2))] {
        crate::simd::FORCE.with(|f| f.set(cap));
        solo_lanes_match(seed);
    }
    crate::simd::FORCE.with(|f| f.set(None));
}

fn solo_lanes_match(seed: u64) {
    use super::tile::{SOLO_LANES, SOLO_PAIRS, SOLO_SLOW};
    let mut rng = isolux_core::Pcg32::new(seed, 0);
    let (lanes0, slow0) = (SOLO_LANES.with(|c| c.get()), SOLO_SLOW.with(|c| c.get()));
    let pairs0 = SOLO_PAIRS.with(|c| c.get());
    let (mut rays_cast, mut hits) = (0, 0);
    for scene in 0..16 {
        let bumps = [1, 3, 16, 40][scene % 4];
        let perts = crate::samples::fibonacci_sphere(bumps, 0.6)
            .into_iter()
            .map(|c| {
                let factor = match rng.next_below(6) {
                    0 => -300.0,
                    1 => 1e-3,
                    _ => 1000.0 * (0.2 + 2.0 * rng.next_f64()),
                };
                let radius = 0.1 + 0.2 * rng.next_f64();
                Perturbation {
                    quadric: Quadric::sphere(c, radius),
                    factor,
                }
            })
            .collect();
        let obj = Object::new(Quadric::sphere(DVec3::ZERO, 0.6), perts, None).unwrap();
        let culled: Vec<u32> = (0..bumps as u32).collect();
        for _ in 0..60 {
            let axis = isolux_core::sampling::uniform_sphere(rng.next_2d());
            let target = 0.6 * isolux_core::sampling::uniform_sphere(rng.next_2d())
                + 0.1 * (rng.next_f64() - 0.5) * axis;
            let (u, v) = axis.any_orthonormal_pair();
            let pitch = 10f64.powf(-3.0 + 2.0 * rng.next_f64());
            let length = 0.5 + 2.0 * rng.next_f64();
            let eye = target - 2.0 * axis;
            let perspective = rng.next_below(2) == 0;
            let rays: Vec<Ray> = (0..TILE_RAYS)
                .map(|k| {
                    let (x, y) = ((k % 8) as f64 - 3.5, (k / 8) as f64 - 3.5);
                    let off = pitch * (x * u + y * v);
                    if perspective {
                        Ray::new(eye, (2.0 * axis + off) * length)
                    } else {
                        Ray::new(eye + off, axis * length)
                    }
                })
                .collect();
            let (t_min, t_max) = if rng.next_below(3) == 0 {
                (0.3 * rng.next_f64(), 1.0 + 2.0 * rng.next_f64())
            } else {
                (0.0, f64::INFINITY)
            };
            let mut got = vec![None; rays.len()];
            obj.intersect_tile(&rays, t_min, t_max, &culled, &mut got);
            for (ray, got) in rays.iter().zip(&got) {
                let want = obj.intersect_culled(ray, t_min, t_max, &culled);
                assert_eq!(*got, want, "{ray:?} on [{t_min}, {t_max}]");
                rays_cast += 1;
                hits += got.is_some() as usize;
            }
        }
    }
    let lanes = SOLO_LANES.with(|c| c.get()) - lanes0;
    let slow = SOLO_SLOW.with(|c| c.get()) - slow0;
    let pairs = SOLO_PAIRS.with(|c| c.get()) - pairs0;
    eprintln!(
        "{rays_cast} rays, {hits} hits, {lanes} lanes ({pairs} with two supports), {slow} sent back"
    );
    assert!(pairs > rays_cast / 50, "{pairs} lanes with two supports");
    assert!(hits > rays_cast / 4, "{hits} of {rays_cast}");
    assert!(
        lanes > rays_cast / 8 && slow < lanes / 20,
        "{lanes} lanes, {slow} slow"
    );
}

#[test]
fn plain_sphere_hit() {
    let o = Object::new(Quadric::sphere(DVec3::ZERO, 1.0), vec![], None).unwrap();
    let r = Ray::new(DVec3::new(0.0, 0.0, -5.0), DVec3::Z);
    let h = o.intersect(&r, 0.0, f64::INFINITY).unwrap();
    assert!((h.t - 4.0).abs() < 1e-12);
    assert!((h.n - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
    // From inside: exits at t = 1 with outward normal +z.
    let r = Ray::new(DVec3::ZERO, DVec3::Z);
    let h = o.intersect(&r, 0.0, f64::INFINITY).unwrap();
    assert!((h.t - 1.0).abs() < 1e-12 && h.n.z > 0.999);
}

#[test]
fn bump_raises_surface() {
    // Sphere radius 1 with a bump centred at (0,0,-1): along -z axis the
    // surface moves out to where F + f Q^3 = 0.
    let f = 50.0;
    let bump = Quadric::sphere(DVec3::new(0.0, 0.0, -1.0), 0.3);
    let o = Object::new(
        Quadric::sphere(DVec3::ZERO, 1.0),
        vec![Perturbation {
            quadric: bump,
            factor: f,
        }],
        None,
    )
    .unwrap();
    let r = Ray::new(DVec3::new(0.0, 0.0, -5.0), DVec3::Z);
    let h = o.intersect(&r, 0.0, f64::INFINITY).unwrap();
    // z = -(1 + e): 1 - (1+e)^2 + f (0.09 - e^2)^3 = 0
    let g = |e: f64| 1.0 - (1.0 + e) * (1.0 + e) + f * (0.09 - e * e).powi(3);
    let (mut lo, mut hi) = (0.0, 0.3);
    for _ in 0..200 {
        let m = 0.5 * (lo + hi);
        if g(m) > 0.0 {
            lo = m
        } else {
            hi = m
        }
    }
    assert!((h.t - (4.0 - lo)).abs() < 1e-10, "{} vs {}", h.t, 4.0 - lo);
    assert!(h.n.z < -0.999);
}

#[test]
fn unbounded_perturbation_needs_bounds() {
    let plane = Quadric::plane(DVec3::ZERO, DVec3::Y);
    let cyl = Quadric::cylinder(DVec3::ZERO, DVec3::Y, 0.5);
    let p = vec![Perturbation {
        quadric: cyl,
        factor: 1.0,
    }];
    assert!(matches!(
        Object::new(plane, p.clone(), None),
        Err(GeometryError::UnboundedPerturbation(0))
    ));
    let b = Aabb::new(DVec3::splat(-2.0), DVec3::splat(2.0));
    let o = Object::new(plane, p, Some(b)).unwrap();
    // The cylinder bump lifts the plane near the y axis.
    let r = Ray::new(DVec3::new(0.0, 1.9, 0.0), -DVec3::Y);
    let h = o.intersect(&r, 0.0, 10.0).unwrap();
    // -y + 0.25^3 = 0 at the axis.
    assert!((h.p.y - 0.015625).abs() < 1e-12, "{:?}", h.p);
}

/// A random sphere with all its coefficients scaled by a positive
/// factor, as the scene's `scale`d spheres and transforms make it.
fn scaled_sphere(u: &mut impl FnMut() -> f64) -> Quadric {
    let q = Quadric::sphere(DVec3::new(u(), u(), u()), 0.1 + u().abs());
    let k = 0.5 + u().abs();
    Quadric {
        m: q.m * k,
        b: q.b * k,
        c: q.c * k,
    }
}

#[test]
fn sphere_restriction_matches_the_general_quadric() {
    let mut rng = isolux_core::Pcg32::new(21, 0);
    let mut u = || 4.0 * rng.next_f64() - 2.0;
    for _ in 0..1000 {
        let q = scaled_sphere(&mut u);
        let along = Along::new(&q);
        assert!(matches!(along, Along::Sphere { .. }));
        let ray = Ray::new(DVec3::new(u(), u(), u()), DVec3::new(u(), u(), u()));
        let (fast, general) = (along.along(&q, &ray), q.along(&ray));
        let scale = general.iter().map(|c| c.abs()).fold(1.0, f64::max);
        for (a, b) in fast.iter().zip(general) {
            assert!((a - b).abs() <= 1e-13 * scale, "{fast:?} vs {general:?}");
        }
    }
    let e = Quadric::ellipsoid(DVec3::ZERO, DVec3::new(1.0, 2.0, 3.0), DMat3::IDENTITY);
    assert!(matches!(Along::new(&e), Along::General));
}

#[test]
fn support_interval_is_where_q_is_positive() {
    let mut rng = isolux_core::Pcg32::new(22, 0);
    let mut u = || 4.0 * rng.next_f64() - 2.0;
    for _ in 0..10_000 {
        let q = [u(), u(), -u().abs() - 1e-3];
        match support_interval(q) {
            Some((r0, r1)) => {
                assert!(r0 < r1);
                assert!(poly2(q, 0.5 * (r0 + r1)) > 0.0);
                let w = r1 - r0;
                assert!(poly2(q, r0 - 1e-6 * w) < 0.0 && poly2(q, r1 + 1e-6 * w) < 0.0);
                assert_eq!(Some((r0, r1)), quadratic_crossings(q).pair());
            }
            None => assert!(quadratic_crossings(q).pair().is_none()),
        }
    }
}

/// The interval bound never claims one sign on a segment where dense
/// sampling of the same `F'` finds both signs, and it does skip most
/// segments far from the surface.
#[test]
fn sign_bound_is_conservative() {
    let mut rng = isolux_core::Pcg32::new(23, 0);
    let mut u = || 2.0 * rng.next_f64() - 1.0;
    let (mut skipped, mut segments) = (0, 0);
    for _ in 0..4000 {
        let base = [u(), u(), u()];
        let cands: Vec<Candidate> = (0..1 + (u().abs() * 4.0) as usize)
            .map(|i| {
                // Concave, positive somewhere near [0, 1].
                let q = [0.2 + 0.3 * u(), u(), -0.5 - u().abs()];
                // Every other one as a bounded support (its roots
                // known, ranges from the vertex between them), the
                // rest as unbounded ones (ranges by `range2`).
                let (lo, hi) = two_roots(q)
                    .filter(|_| i % 2 == 0)
                    .unwrap_or((f64::NAN, f64::NAN));
                Candidate {
                    index: i as u32,
                    item: u32::MAX,
                    factor: 10.0 * u(),
                    q,
                    lo,
                    hi,
                }
            })
            .collect();
        let (a, b) = (0.5 * u(), 0.5 + 0.5 * u().abs());
        // Active on the whole segment: Q > 0 at both ends (concave).
        let active: Vec<&Candidate> = cands
            .iter()
            .filter(|c| poly2(c.q, a) > 0.0 && poly2(c.q, b) > 0.0)
            .collect();
        let f = |t: f64| {
            poly2(base, t)
                + active
                    .iter()
                    .map(|c| c.factor * poly2(c.q, t).powi(3))
                    .sum::<f64>()
        };
        let n = 2000;
        let (mut neg, mut pos) = (false, false);
        for i in 0..=n {
            let v = f(a + (b - a) * i as f64 / n as f64);
            neg |= v < 0.0;
            pos |= v > 0.0;
        }
        match sign_is_fixed(base, active.iter().copied(), a, b) {
            None => assert!(active.is_empty()),
            Some(fixed) => {
                segments += 1;
                if let Some(sign) = fixed {
                    skipped += 1;
                    let wrong = if sign > 0.0 { neg } else { pos };
                    assert!(!wrong, "{sign}: {base:?} {active:?} on [{a}, {b}]");
                }
            }
        }
    }
    assert!(
        segments > 1000 && skipped > segments / 10,
        "{skipped} of {segments}"
    );
}

#[test]
fn support_ranges_hold_the_sampled_values() {
    // Candidate::range_on / max_on against dense sampling, for bounded
    // supports (vertex midway between the roots) and unbounded ones.
    let mut rng = isolux_core::Pcg32::new(29, 0);
    let mut u = || 2.0 * rng.next_f64() - 1.0;
    for i in 0..2000 {
        let q = [
            0.5 * u(),
            u(),
            if i % 3 == 0 { u() } else { -0.2 - u().abs() },
        ];
        let (lo, hi) = match two_roots(q) {
            Some(r) if q[2] < 0.0 && i % 2 == 0 => r,
            _ => (f64::NAN, f64::NAN),
        };
        let c = Candidate {
            index: 0,
            item: u32::MAX,
            factor: 1.0,
            q,
            lo,
            hi,
        };
        let (a, b) = (u(), u());
        let (a, b) = (a.min(b), a.max(b));
        let (min, max) = c.range_on(a, b);
        assert_eq!(max, c.max_on(a, b));
        let (mut smin, mut smax) = (f64::INFINITY, f64::NEG_INFINITY);
        for k in 0..=1000 {
            let v = poly2(q, a + (b - a) * k as f64 / 1000.0);
            smin = smin.min(v);
            smax = smax.max(v);
        }
        let tol = 1e-12 * (1.0 + smax.abs() + smin.abs());
        assert!(min <= smin + tol && max >= smax - tol, "{q:?} [{a}, {b}]");
        // Tight: the sampled extremes are within the sampling step.
        assert!(min >= smin - 1e-5 && max <= smax + 1e-5, "{q:?} [{a}, {b}]");
    }
}

#[test]
fn tangent_start_is_never_after_the_root() {
    // reach with `entering` (the tangent line at the base's entry)
    // starts no later than the exact root of F + B (to rounding), and
    // not before lo.
    let mut rng = isolux_core::Pcg32::new(31, 0);
    let mut u = || 2.0 * rng.next_f64() - 1.0;
    let mut tangent_used = 0;
    for _ in 0..5000 {
        // A concave base entered at r0 within (lo, hi_end).
        let (r0, width, curv) = (u(), 0.1 + u().abs(), 0.1 + u().abs());
        let base = [-curv * r0 * (r0 + width), curv * (2.0 * r0 + width), -curv];
        let lo = r0 - 0.5 * u().abs() - 1e-3;
        let q = [0.05 * u().abs(), 0.1 * u(), -0.5 - u().abs()];
        let Some((qlo, qhi)) = two_roots(q) else {
            continue;
        };
        let c = Candidate {
            index: 0,
            item: u32::MAX,
            factor: 10.0 * u().abs(),
            q,
            lo: qlo,
            hi: qhi,
        };
        let split = quadratic_crossings(base)[0];
        let exact = reach(base, &[c], lo, split, false);
        let tangent = reach(base, &[c], lo, split, true);
        match (exact, tangent) {
            (Some(e), Some(t)) => {
                // Both are conservative by B's widening (1e-10 of
                // the magnitudes), which dwarfs their rounding.
                assert!(t <= e + 1e-13 * (1.0 + e.abs()) && t >= lo, "{t} vs {e}");
                tangent_used += (t < e) as u32;
            }
            (None, _) => {}
            (Some(e), None) => panic!("tangent start lost the root {e}"),
        }
    }
    assert!(tangent_used > 1000, "{tangent_used}");
}

#[test]
fn enclosing_ball_holds_both_balls() {
    let mut rng = isolux_core::Pcg32::new(24, 0);
    let mut u = || 2.0 * rng.next_f64() - 1.0;
    for _ in 0..10_000 {
        let a = (DVec3::new(u(), u(), u()), u().abs());
        let b = (DVec3::new(u(), u(), u()) * 0.1, 0.3 * u().abs());
        let (c, r) = enclose(a, b);
        for (centre, radius) in [a, b] {
            assert!(
                (centre - c).length() + radius <= r,
                "{a:?} {b:?} -> {c} {r}"
            );
        }
        // Never larger than the ball around a's centre holding both.
        let loose = a.1.max((b.0 - a.0).length() + b.1);
        assert!(r <= loose * (1.0 + 1e-9) + 1e-12);
    }
}

/// `positive_on` (no roots) says whether the support interval meets
/// `(lo, hi)`, as the roots do, except within rounding of an end.
#[test]
fn positive_on_matches_the_roots() {
    let mut rng = isolux_core::Pcg32::new(25, 0);
    let mut u = || 4.0 * rng.next_f64() - 2.0;
    for _ in 0..100_000 {
        let q = [u(), u(), -u().abs() - 1e-3];
        let (lo, hi) = {
            let (x, y) = (u(), u());
            (x.min(y), x.max(y))
        };
        let by_roots = two_roots(q).is_some_and(|(r0, r1)| r1 > lo && r0 < hi);
        if positive_on(q, lo, hi) != by_roots {
            let (r0, r1) = two_roots(q).unwrap_or((f64::NAN, f64::NAN));
            let near = |x: f64| (x - lo).abs().min((x - hi).abs()) < 1e-12;
            assert!(near(r0) || near(r1), "{q:?} on ({lo}, {hi})");
        }
    }
}

/// A sphere base's normal without the square root equals the
/// gradient's.
#[test]
fn sphere_base_normal_matches_the_gradient() {
    let mut rng = isolux_core::Pcg32::new(26, 0);
    let mut u = || 2.0 * rng.next_f64() - 1.0;
    for _ in 0..1000 {
        let o = Object::new(scaled_sphere(&mut u), vec![], None).unwrap();
        let ray = Ray::new(DVec3::new(u(), u(), u()) * 5.0, DVec3::new(u(), u(), u()));
        if let Some(h) = o.intersect(&ray, 0.0, f64::INFINITY) {
            let g = (-o.gradient(h.p)).normalize();
            assert!((h.n - g).length() < 1e-12, "{:?} vs {g:?}", h.n);
        }
    }
}

#[test]
fn infinite_plane_without_bounds() {
    let o = Object::new(
        Quadric::plane(DVec3::new(0.0, -1.0, 0.0), DVec3::Y),
        vec![],
        None,
    )
    .unwrap();
    let r = Ray::new(DVec3::new(0.3, 2.0, 0.0), DVec3::new(0.0, -1.0, 0.0));
    assert!((o.intersect(&r, 0.0, f64::INFINITY).unwrap().t - 3.0).abs() < 1e-12);
    let r = Ray::new(DVec3::new(0.3, 2.0, 0.0), DVec3::Y);
    assert!(o.intersect(&r, 0.0, f64::INFINITY).is_none());
}

/// An object written in a frame a million units from the world origin
/// (`Object::in_frame`, as the scene loader builds them) hits as the
/// same object at the origin: along rays moved by the same amount
/// (exactly: their origins lie on a grid of 2^-16), the same hits and
/// misses, `t` to the rounding of the frame's origin, the same normals,
/// and a spawn offset of about 1e-7 plus 1e-14 of the distance, where
/// the world frame's rule, `1e-7 (1 + |p|)`, gave 0.1. The same object
/// written in world coordinates (`Object::new`) moves into a frame at
/// its box's centre (a million units from its written frame's zero)
/// and agrees as well, to the rounding of its constant terms.
#[test]
fn objects_far_from_the_origin_hit_as_at_the_origin() {
    let far = DVec3::new(1.0e6, -0.25e6, 0.5e6);
    let perts = |at: DVec3| -> Vec<Perturbation> {
        crate::samples::fibonacci_sphere(16, 0.6)
            .into_iter()
            .enumerate()
            .map(|(i, c)| Perturbation {
                quadric: Quadric::sphere(at + c, 0.2),
                factor: if i % 3 == 0 { -1500.0 } else { 1000.0 },
            })
            .collect()
    };
    let sphere = |at: DVec3| Quadric::sphere(at, 0.6);
    let near = Object::new(sphere(DVec3::ZERO), perts(DVec3::ZERO), None).unwrap();
    let framed = Object::in_frame(far, sphere(DVec3::ZERO), perts(DVec3::ZERO), None).unwrap();
    let world = Object::new(sphere(far), perts(far), None).unwrap();
    assert!(
        (framed.origin() - far).length() < 0.1,
        "{:?}",
        framed.origin()
    );
    assert!(
        (world.origin() - far).length() < 0.1,
        "{:?}",
        world.origin()
    );
    let grid = |v: DVec3| (v * 65536.0).round() / 65536.0;
    let mut rng = isolux_core::Pcg32::new(11, 4);
    let (mut hits, mut rays, mut world_flips) = (0, 0, 0);
    let mut world_dt = Vec::new();
    for _ in 0..4000 {
        let o = grid(2.0 * isolux_core::sampling::uniform_sphere(rng.next_2d()));
        let target = 0.7 * isolux_core::sampling::uniform_sphere(rng.next_2d());
        let ray = Ray::new(o, target - o);
        let a = near.intersect(&ray, 0.0, f64::INFINITY);
        let moved = Ray::new(ray.origin + far, ray.dir);
        match (a, framed.intersect(&moved, 0.0, f64::INFINITY)) {
            (None, None) => {}
            (Some(a), Some(b)) => {
                assert!((a.t - b.t).abs() < 1e-9, "{a:?} vs {b:?}");
                assert!((a.n - b.n).length() < 1e-6, "{a:?} vs {b:?}");
                assert!(((b.p - far) - a.p).length() < 1e-8);
                assert!(b.offset < 2e-7 + 1e-14 * 1.2e6, "{}", b.offset);
            }
            (a, b) => panic!("{ray:?}: {a:?} vs {b:?}"),
        }
        // In world coordinates, the bumps' constant terms (about
        // 1.3e12) carry a rounding of about 1e-4 of their `r^2 = 0.04`,
        // which moves the surface near them by about that much.
        match (a, world.intersect(&moved, 0.0, f64::INFINITY)) {
            (Some(a), Some(b)) => world_dt.push((a.t - b.t).abs()),
            (None, None) => {}
            _ => world_flips += 1,
        }
        rays += 1;
        hits += a.is_some() as usize;
    }
    assert!(hits > rays / 2, "{hits} of {rays}");
    world_dt.sort_by(f64::total_cmp);
    let median = world_dt[world_dt.len() / 2];
    eprintln!("world: median |dt| {median:.2e}, {world_flips} of {rays} rays flipped");
    assert!(
        median < 1e-4 && world_flips <= rays / 200,
        "{median} {world_flips}"
    );
}
