//! Chi-square goodness of fit of the Gabor importance sampling against its
//! pdf, on a grid over the projected hemisphere.

use glam::DVec3;
use isolux_core::Pcg32;
use isolux_wave::generate::{generate, Kind};
use isolux_wave::{Footprint, GaborSurface, Model, Settings};

/// Upper critical value of chi-square with `dof` degrees of freedom at
/// significance ~1e-4 (Wilson-Hilferty).
fn chi2_critical(dof: f64) -> f64 {
    let z = 3.719;
    let a = 2.0 / (9.0 * dof);
    dof * (1.0 - a + z * a.sqrt()).powi(3)
}

#[test]
fn sampling_matches_pdf_chi_square() {
    let h = generate(
        &Kind::Noise {
            rms_um: 0.08,
            corr_um: 1.0,
        },
        64,
        64,
        0.25,
        11,
    )
    .unwrap();
    let s = GaborSurface::new(h);
    let fp = Footprint {
        center_um: [3.0, 5.0],
        sigma_um: 1.0,
    };
    let set = Settings::default();
    let kappa = 1.0 / 0.55;
    for (model, theta) in [(Model::Ghs, 0.0f64), (Model::Ghs, 40.0), (Model::Ohs, 25.0)] {
        let t = theta.to_radians();
        let given = DVec3::new(t.sin() * 0.6, t.sin() * 0.8, t.cos());
        let n = 20;
        let cell = 2.0 / n as f64;
        let samples = 200_000;
        let mut counts = vec![0.0f64; n * n];
        let mut failed = 0.0;
        let mut rng = Pcg32::new(7, 1);
        for _ in 0..samples {
            match s.sample(&fp, model, given, kappa, &set, rng.next_2d(), rng.next_2d()) {
                Some(d) => {
                    let c = (((d.x + 1.0) / cell) as usize).min(n - 1);
                    let r = (((d.y + 1.0) / cell) as usize).min(n - 1);
                    counts[r * n + c] += 1.0;
                    // The pdf of a returned sample is positive and finite.
                    let p = s.pdf(&fp, model, given, d, kappa, &set);
                    assert!(p > 0.0 && p.is_finite());
                }
                None => failed += 1.0,
            }
        }
        // Expected counts: integral of pdf dw = pdf dx dy / z, 6x6 midpoints per cell.
        let sub = 6;
        let mut expected = vec![0.0f64; n * n];
        for r in 0..n {
            for c in 0..n {
                let mut e = 0.0;
                for a in 0..sub {
                    for b in 0..sub {
                        let x = -1.0 + (c as f64 + (a as f64 + 0.5) / sub as f64) * cell;
                        let y = -1.0 + (r as f64 + (b as f64 + 0.5) / sub as f64) * cell;
                        let r2 = x * x + y * y;
                        if r2 < 1.0 {
                            let d = DVec3::new(x, y, (1.0 - r2).sqrt());
                            e += s.pdf(&fp, model, given, d, kappa, &set) / d.z;
                        }
                    }
                }
                expected[r * n + c] = e * (cell / sub as f64).powi(2) * samples as f64;
            }
        }
        let total_expected: f64 = expected.iter().sum();
        let exp_failed = samples as f64 - total_expected;
        // Pool cells with few expected samples.
        let (mut chi2, mut dof) = (0.0, 0.0);
        let (mut pool_o, mut pool_e) = (failed, exp_failed.max(0.0));
        for (o, e) in counts.iter().zip(&expected) {
            if *e < 20.0 {
                pool_o += o;
                pool_e += e;
            } else {
                chi2 += (o - e).powi(2) / e;
                dof += 1.0;
            }
        }
        if pool_e > 5.0 {
            chi2 += (pool_o - pool_e).powi(2) / pool_e;
            dof += 1.0;
        }
        let crit = chi2_critical(dof - 1.0);
        eprintln!("{model:?} theta {theta}: chi2 {chi2:.1} dof {dof} crit {crit:.1}, failed {failed} expected {exp_failed:.0}");
        assert!(dof > 20.0, "too few cells: {dof}");
        assert!(chi2 < crit, "{model:?} theta {theta}: chi2 {chi2} > {crit}");
    }
}
