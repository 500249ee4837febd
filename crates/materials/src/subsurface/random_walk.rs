//! Brute-force random walk in a homogeneous half-space: the reference the
//! dipole approximates, for plots (`isolux sss profile`) and the
//! `random_walk` rendering mode.
//!
//! A photon enters at normal incidence just below a smooth boundary of
//! relative index `eta`, flies exponential free paths of mean `1/sigma_t'`,
//! scatters isotropically with probability `a'` (similarity theory:
//! reduced coefficients) and is absorbed otherwise; at the boundary it is
//! reflected back with the Fresnel probability and escapes otherwise. The
//! exit radius is recorded.

use crate::fresnel::dielectric;
use isolux_core::{sampling, DVec3, Pcg32};

/// Exit radius of one photon (in the units of `1/sigma_t`), or `None` if
/// it is absorbed.
pub fn walk(rng: &mut Pcg32, sigma_t: f64, albedo: f64, eta: f64) -> Option<f64> {
    let mut p = DVec3::ZERO;
    let mut d = DVec3::new(0.0, 0.0, -1.0);
    for _ in 0..10_000_000 {
        let s = -(1.0 - rng.next_f64()).ln() / sigma_t;
        let q = p + s * d;
        if q.z > 0.0 {
            let exit = p + (-p.z / d.z) * d;
            let f = if eta == 1.0 {
                0.0
            } else {
                dielectric(d.z, 1.0 / eta)
            };
            if rng.next_f64() < f {
                p = DVec3::new(exit.x, exit.y, 0.0);
                d.z = -d.z;
                continue;
            }
            return Some(exit.x.hypot(exit.y));
        }
        p = q;
        if rng.next_f64() >= albedo {
            return None;
        }
        d = sampling::uniform_sphere(rng.next_2d());
    }
    None
}

/// Radial profile `R_d(r)` per unit area on the bins `edges`, and the total
/// diffuse reflectance, from `photons` walks.
pub fn radial_profile(
    sigma_s_reduced: f64,
    sigma_a: f64,
    eta: f64,
    photons: usize,
    edges: &[f64],
    seed: u64,
) -> (f64, Vec<f64>) {
    let st = sigma_s_reduced + sigma_a;
    let albedo = if st > 0.0 { sigma_s_reduced / st } else { 0.0 };
    let mut rng = Pcg32::new(seed, 0x55);
    let mut counts = vec![0usize; edges.len().saturating_sub(1)];
    let mut escaped = 0usize;
    for _ in 0..photons {
        if let Some(r) = walk(&mut rng, st, albedo, eta) {
            escaped += 1;
            if let Some(b) = edges.windows(2).position(|w| r >= w[0] && r < w[1]) {
                counts[b] += 1;
            }
        }
    }
    let n = photons as f64;
    let profile = counts
        .iter()
        .zip(edges.windows(2))
        .map(|(&c, w)| c as f64 / n / (std::f64::consts::PI * (w[1] * w[1] - w[0] * w[0])))
        .collect();
    (escaped as f64 / n, profile)
}
