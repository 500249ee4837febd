//! An analog Monte Carlo random walk in a semi-infinite homogeneous
//! half-space, written here independently of the renderer, against
//! Chandrasekhar's exact result and the dipole.
//!
//! Units: lengths in reduced mean free paths (`sigma_t' = 1`); isotropic
//! scattering with the reduced albedo (similarity theory); light enters at
//! normal incidence just below the surface (the entry Fresnel factor is
//! not part of the diffuse reflectance being compared).

use isolux_core::{sampling, DVec3, Pcg32, PI};
use isolux_materials::fresnel::dielectric;
use isolux_materials::subsurface::Dipole;
use rayon::prelude::*;

/// Walks one photon; returns its exit radius if it leaves the medium.
fn walk(rng: &mut Pcg32, albedo: f64, eta: f64) -> Option<f64> {
    let mut p = DVec3::ZERO;
    let mut d = DVec3::new(0.0, 0.0, -1.0);
    for _ in 0..1_000_000 {
        let s = -(1.0 - rng.next_f64()).ln();
        let q = p + s * d;
        if q.z > 0.0 {
            // Reaches the boundary at the crossing point.
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
            return Some((exit.x * exit.x + exit.y * exit.y).sqrt());
        }
        p = q;
        if rng.next_f64() >= albedo {
            return None;
        }
        d = sampling::uniform_sphere(rng.next_2d());
    }
    None
}

/// Total diffuse reflectance and a histogram of exit radii.
fn simulate(albedo: f64, eta: f64, photons: usize, edges: &[f64], seed: u64) -> (f64, Vec<f64>) {
    let chunks = 64;
    let per = photons / chunks;
    let parts: Vec<(usize, Vec<usize>)> = (0..chunks)
        .into_par_iter()
        .map(|c| {
            let mut rng = Pcg32::new(seed, c as u64);
            let mut escaped = 0;
            let mut hist = vec![0usize; edges.len().saturating_sub(1)];
            for _ in 0..per {
                if let Some(r) = walk(&mut rng, albedo, eta) {
                    escaped += 1;
                    for b in 0..hist.len() {
                        if r >= edges[b] && r < edges[b + 1] {
                            hist[b] += 1;
                        }
                    }
                }
            }
            (escaped, hist)
        })
        .collect();
    let n = (per * chunks) as f64;
    let escaped: usize = parts.iter().map(|p| p.0).sum();
    let mut hist = vec![0.0; edges.len().saturating_sub(1)];
    for (_, h) in &parts {
        for (a, b) in hist.iter_mut().zip(h) {
            *a += *b as f64;
        }
    }
    (escaped as f64 / n, hist.iter().map(|c| c / n).collect())
}

/// Gauss-Legendre nodes and weights on [0, 1].
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-15 {
                    break;
                }
            }
            let w = 2.0 / ((1.0 - x * x) * dp * dp);
            (0.5 * (x + 1.0), 0.5 * w)
        })
        .collect()
}

/// Chandrasekhar's H function for isotropic scattering, by iterating
/// `1/H(mu) = sqrt(1 - a) + (a/2) int_0^1 mu' H(mu') / (mu + mu') dmu'`.
fn chandrasekhar_h(albedo: f64, mu: f64) -> f64 {
    let nodes = gauss_legendre(64);
    let mut h: Vec<f64> = vec![1.0; nodes.len()];
    let eval = |h: &[f64], mu: f64| {
        let s: f64 = nodes
            .iter()
            .zip(h)
            .map(|((x, w), hx)| w * x * hx / (mu + x))
            .sum();
        1.0 / ((1.0 - albedo).sqrt() + 0.5 * albedo * s)
    };
    for _ in 0..2000 {
        let next: Vec<f64> = nodes.iter().map(|(x, _)| eval(&h, *x)).collect();
        let diff = next
            .iter()
            .zip(&h)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        h = next;
        if diff < 1e-14 {
            break;
        }
    }
    eval(&h, mu)
}

#[test]
fn index_matched_half_space_matches_chandrasekhar() {
    for (a, photons) in [(0.5, 400_000), (0.9, 400_000), (0.99, 200_000)] {
        let exact = 1.0 - chandrasekhar_h(a, 1.0) * (1.0 - a).sqrt();
        let (r, _) = simulate(a, 1.0, photons, &[], 17);
        let se = (r * (1.0 - r) / photons as f64).sqrt();
        eprintln!("albedo {a}: random walk {r:.5} +- {se:.5}, Chandrasekhar {exact:.5}");
        assert!(
            (r - exact).abs() < 4.0 * se,
            "albedo {a}: {r} vs {exact} (se {se})"
        );
    }
}

#[test]
fn dipole_error_against_the_random_walk_at_eta_1_3() {
    // The dipole's known error at normal incidence: it overestimates at
    // low albedo and slightly underestimates at very high albedo. Measured
    // (400k photons): +15.9% at 0.5, +2.8% at 0.9, -1.8% at 0.99, as in
    // the literature (about +17%, +3%, -2%); bounds allow the walk's
    // statistical error.
    for (a, lo, hi) in [(0.5, 0.12, 0.20), (0.9, 0.0, 0.06), (0.99, -0.04, 0.0)] {
        let photons = 400_000;
        let (r, _) = simulate(a, 1.3, photons, &[], 23);
        let dipole = Dipole::new(a, 1.0 - a, 1.3).total();
        let rel = dipole / r - 1.0;
        eprintln!(
            "albedo {a}: random walk {r:.5}, dipole {dipole:.5}, dipole error {:+.1}%",
            rel * 100.0
        );
        assert!(rel > lo && rel < hi, "albedo {a}: dipole error {rel}");
    }
}

#[test]
fn radial_profile_matches_the_dipole_between_2_and_16_mfp() {
    let a = 0.99;
    let edges: Vec<f64> = (1..=8).map(|k| 2.0 * k as f64).collect(); // 2, 4, ..., 16
    let photons = 1_000_000;
    let (_, hist) = simulate(a, 1.3, photons, &edges, 29);
    let dp = Dipole::new(a, 1.0 - a, 1.3);
    for (b, frac) in hist.iter().enumerate() {
        let (r0, r1) = (edges[b], edges[b + 1]);
        // Dipole prediction: int_{r0}^{r1} R_d(r) 2 pi r dr (Simpson).
        let n = 200;
        let h = (r1 - r0) / n as f64;
        let g = |r: f64| dp.r_d(r) * 2.0 * PI * r;
        let mut s = g(r0) + g(r1);
        for i in 1..n {
            s += g(r0 + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
        }
        let want = s * h / 3.0;
        let rel = frac / want - 1.0;
        eprintln!(
            "r in [{r0}, {r1}): walk {frac:.3e} dipole {want:.3e} ({:+.1}%)",
            rel * 100.0
        );
        assert!(rel.abs() < 0.10, "r in [{r0}, {r1}): {rel}");
    }
}
