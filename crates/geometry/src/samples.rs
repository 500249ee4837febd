//! Reference objects shared by benchmarks, tests and examples.

use crate::{Object, Perturbation, Quadric};
use isolux_core::{DVec3, Ray};

/// Form factor of the benchmark bumps: raises a bump about 0.05 high on a
/// sphere of radius 0.6 (`1.2 h = f (0.04 - h^2)^3`).
pub const BUMP_FACTOR: f64 = 1000.0;

/// Centres of `n` points spread evenly over a sphere of radius `r`
/// (Fibonacci lattice: deterministic, no clustering).
pub fn fibonacci_sphere(n: usize, r: f64) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let rho = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            DVec3::new(rho * phi.cos(), rho * phi.sin(), z) * r
        })
        .collect()
}

/// The geometry benchmark object: a sphere of radius 0.6 at the origin
/// with `bumps` perturbations `f max(Q, 0)^3`, each `Q` a sphere of radius
/// 0.2 centred on the surface.
pub fn bumpy_sphere(bumps: usize) -> Object {
    let perts = fibonacci_sphere(bumps, 0.6)
        .into_iter()
        .map(|c| Perturbation {
            quadric: Quadric::sphere(c, 0.2),
            factor: BUMP_FACTOR,
        })
        .collect();
    Object::new(Quadric::sphere(DVec3::ZERO, 0.6), perts, None).expect("valid benchmark object")
}

/// Casts one orthographic primary ray per pixel of a `size x size` image
/// over `[-1, 1]^2`, looking down `-z` from `z = 2` (the view of fidget's
/// 3D heightmap render), on the calling thread. Returns the hit count.
pub fn cast_rows(obj: &Object, size: u32, rows: std::ops::Range<u32>) -> usize {
    let mut hits = 0;
    for y in rows {
        for x in 0..size {
            let px = (x as f64 + 0.5) / size as f64 * 2.0 - 1.0;
            let py = 1.0 - (y as f64 + 0.5) / size as f64 * 2.0;
            let ray = Ray::new(DVec3::new(px, py, 2.0), -DVec3::Z);
            if obj.intersect(&ray, 0.0, f64::INFINITY).is_some() {
                hits += 1;
            }
        }
    }
    hits
}
