//! Physics checks of the Gabor-kernel diffraction BRDF against closed forms
//! (flat mirror, thin phase grating) and a brute-force Fourier integral.

use glam::DVec3;
use isolux_wave::generate::{generate, Kind};
use isolux_wave::{Comb, Footprint, GaborSurface, Heightfield, Model, Obliquity, Settings};
use std::f64::consts::PI;

fn dir_from_angle(theta_deg: f64) -> DVec3 {
    let t = theta_deg.to_radians();
    DVec3::new(t.sin(), 0.0, t.cos())
}

fn wo_xy(x: f64, y: f64) -> Option<DVec3> {
    let r2 = x * x + y * y;
    (r2 < 1.0).then(|| DVec3::new(x, y, (1.0 - r2).sqrt()))
}

/// `integral f cos_o dw_o` over a square of the projected disk, midpoint rule.
#[allow(clippy::too_many_arguments)]
fn energy_in(
    s: &GaborSurface,
    fp: &Footprint,
    model: Model,
    wi: DVec3,
    lambda: f64,
    center: [f64; 2],
    half: f64,
    n: usize,
    set: &Settings,
) -> f64 {
    let d = 2.0 * half / n as f64;
    let mut e = 0.0;
    for a in 0..n {
        for b in 0..n {
            let x = center[0] - half + (a as f64 + 0.5) * d;
            let y = center[1] - half + (b as f64 + 0.5) * d;
            if let Some(wo) = wo_xy(x, y) {
                e += s.eval_single(fp, model, wi, wo, lambda, set) * d * d;
            }
        }
    }
    e
}

fn flat(n: usize, texel: f64) -> GaborSurface {
    GaborSurface::new(Heightfield::new(n, n, texel, vec![0.0; n * n]).unwrap())
}

#[test]
fn flat_mirror_reflects_all_its_energy_in_one_peak() {
    let s = flat(64, 0.5);
    let set = Settings::default();
    let fp = Footprint {
        center_um: [3.0, 7.0],
        sigma_um: 4.0,
    };
    for (theta, model) in [(0.0, Model::Ghs), (30.0, Model::Ghs), (30.0, Model::Ohs)] {
        let wi = dir_from_angle(theta);
        // Peak width in wo: lambda / (2 sqrt(2) pi sigma) = 0.011.
        let e = energy_in(&s, &fp, model, wi, 0.5, [-wi.x, 0.0], 0.08, 64, &set);
        assert!((e - 1.0).abs() < 0.01, "theta {theta}: energy {e}");
        // Away from the peak: nothing.
        let peak = s.eval_single(&fp, model, wi, wo_xy(-wi.x, 0.0).unwrap(), 0.5, &set);
        let off = s.eval_single(&fp, model, wi, wo_xy(-wi.x + 0.2, 0.0).unwrap(), 0.5, &set);
        assert!(off < 1e-6 * peak, "{off} vs peak {peak}");
        // The peak value: 4 pi sigma^2 kappa^2 for an infinite window.
        let ideal = 4.0 * PI * 16.0 * 4.0;
        assert!((peak / ideal - 1.0).abs() < 0.03, "{peak} vs {ideal}");
    }
}

/// Grating of period 4 um sampled by 16 texels of 0.25 um.
fn grating(amplitude: f64) -> GaborSurface {
    let k = Kind::Grating {
        period_um: 4.0,
        amplitude_um: amplitude,
        direction_deg: 0.0,
    };
    GaborSurface::new(generate(&k, 64, 64, 0.25, 0).unwrap())
}

/// The RMS slope of a sampled grating against its closed form
/// `2 pi A / (P sqrt 2)` (central differences of 16 texels a period read
/// it 2.6% low: `sin(2 pi / 16) / (2 pi / 16)`).
#[test]
fn rms_slope_of_a_grating() {
    for a in [0.05, 0.2] {
        let s = grating(a).rms_slope();
        let exact = 2.0 * std::f64::consts::PI * a / (4.0 * std::f64::consts::SQRT_2);
        let h = 2.0 * std::f64::consts::PI / 16.0;
        assert!(
            (s / (exact * h.sin() / h) - 1.0).abs() < 1e-3,
            "A {a}: {s} against {exact}"
        );
    }
}

/// Location of the maximum of `f` along wo_x near `x0` (wo_y = 0), by a
/// scan and a parabola through the best three points.
fn peak_near(s: &GaborSurface, fp: &Footprint, wi: DVec3, lambda: f64, x0: f64) -> f64 {
    let set = Settings::default();
    let step = 0.0005;
    let vals: Vec<(f64, f64)> = (-30..=30)
        .map(|i| {
            let x = x0 + i as f64 * step;
            (
                x,
                wo_xy(x, 0.0).map_or(0.0, |wo| {
                    s.eval_single(fp, Model::Ghs, wi, wo, lambda, &set)
                }),
            )
        })
        .collect();
    let k = (1..vals.len() - 1)
        .max_by(|&a, &b| vals[a].1.total_cmp(&vals[b].1))
        .unwrap();
    let (a, b, c) = (vals[k - 1].1, vals[k].1, vals[k + 1].1);
    let denom = a - 2.0 * b + c;
    vals[k].0
        + if denom != 0.0 {
            0.5 * step * (a - c) / denom
        } else {
            0.0
        }
}

#[test]
fn grating_orders_sit_at_the_grating_equation() {
    let s = grating(0.05);
    let fp = Footprint {
        center_um: [5.0, 5.0],
        sigma_um: 10.0,
    };
    let lambda = 0.5;
    for theta in [0.0, 20.0] {
        let wi = dir_from_angle(theta);
        for m in -2i32..=2 {
            // Along x: wo_x = -wi_x + m lambda / P (sin theta_m = sin theta_i + m lambda / P
            // with angles measured on the mirror side).
            let expect = -wi.x + m as f64 * lambda / 4.0;
            let got = peak_near(&s, &fp, wi, lambda, expect);
            eprintln!("theta {theta} m {m}: peak at {got:.5}, expected {expect:.5}");
            assert!(
                (got - expect).abs() < 0.002,
                "theta {theta} m {m}: {got} vs {expect}"
            );
        }
    }
}

#[test]
fn grating_order_energies_match_thin_phase_grating_theory() {
    let amplitude = 0.06;
    let s = grating(amplitude);
    let fp = Footprint {
        center_um: [2.0, 3.0],
        sigma_um: 5.0,
    };
    let lambda = 0.5;
    for obliquity in [Obliquity::Reciprocal, Obliquity::Seed] {
        let set = Settings {
            obliquity,
            ..Settings::default()
        };
        for theta in [0.0, 20.0] {
            let wi = dir_from_angle(theta);
            let mut total = 0.0;
            for m in -3i32..=3 {
                let x = -wi.x + m as f64 * lambda / 4.0;
                let Some(wo) = wo_xy(x, 0.0) else { continue };
                let e = energy_in(&s, &fp, Model::Ghs, wi, lambda, [x, 0.0], 0.04, 24, &set);
                // Thin phase grating: J_m(2 pi A c3 / lambda)^2, times the
                // model's obliquity factor; GHS's c3 = cos_i + cos_o.
                let c3 = wi.z + wo.z;
                let j = libm::jn(m, 2.0 * PI * amplitude * c3 / lambda);
                let expect = j * j * obliquity.factor(wi.z, wo.z);
                eprintln!(
                    "{obliquity:?} theta {theta} m {m}: energy {e:.4}, thin grating {expect:.4}"
                );
                assert!(
                    (e - expect).abs() < 0.03,
                    "{obliquity:?} theta {theta} m {m}: {e} vs {expect}"
                );
                total += e;
            }
            assert!(total <= 1.0 + 0.02, "{total}");
        }
    }
}

fn noise(seed: u64) -> Heightfield {
    generate(
        &Kind::Noise {
            rms_um: 0.05,
            corr_um: 1.0,
        },
        64,
        64,
        0.25,
        seed,
    )
    .unwrap()
}

/// Brute force: `I(u) = integral w(s) exp(-i 2 pi c3 h(s) / lambda) exp(-i 2 pi u.s) ds`
/// by the midpoint rule on a grid `sub` times finer than the texels, over
/// the bilinearly interpolated heightfield, the window truncated at 5 sigma.
fn brute_brdf(
    h: &Heightfield,
    fp: &Footprint,
    wi: DVec3,
    wo: DVec3,
    lambda: f64,
    sub: usize,
) -> f64 {
    let c3 = wi.z + wo.z;
    let u = [(wi.x + wo.x) / lambda, (wi.y + wo.y) / lambda];
    let d = h.texel_um / sub as f64;
    let half = (5.0 * fp.sigma_um / d).ceil() as i64;
    let (mut re, mut im) = (0.0, 0.0);
    for b in -half..=half {
        for a in -half..=half {
            let dx = a as f64 * d;
            let dy = b as f64 * d;
            let s = [fp.center_um[0] + dx, fp.center_um[1] + dy];
            let w = (-(dx * dx + dy * dy) / (2.0 * fp.sigma_um * fp.sigma_um)).exp();
            let ph = 2.0 * PI * (c3 * h.bilinear(s) / lambda + u[0] * dx + u[1] * dy);
            re += w * ph.cos();
            im -= w * ph.sin();
        }
    }
    let i2 = (re * re + im * im) * d.powi(4);
    let ac = PI * fp.sigma_um * fp.sigma_um;
    // The default obliquity factor, 1.
    i2 / (lambda * lambda * ac)
}

#[test]
fn gabor_sum_matches_brute_force_fourier_integral() {
    // Smooth at the texel scale: 8 texels per correlation length. (At 4
    // texels per correlation length the linearization inside each texel
    // shows: 7.8% measured.)
    let h = generate(
        &Kind::Noise {
            rms_um: 0.05,
            corr_um: 2.0,
        },
        64,
        64,
        0.25,
        5,
    )
    .unwrap();
    let s = GaborSurface::new(h.clone());
    let fp = Footprint {
        center_um: [6.0, 9.0],
        sigma_um: 1.5,
    };
    let lambda = 0.5;
    let set = Settings {
        eps: 1e-4,
        ..Settings::default()
    };
    let wi = dir_from_angle(20.0);
    let res = 24;
    let (mut num, mut den) = (0.0, 0.0);
    for r in 0..res {
        for c in 0..res {
            let x = (c as f64 + 0.5) / res as f64 * 2.0 - 1.0;
            let y = 1.0 - (r as f64 + 0.5) / res as f64 * 2.0;
            let Some(wo) = wo_xy(x, y) else { continue };
            let g = s.eval_single(&fp, Model::Ghs, wi, wo, lambda, &set);
            let b = brute_brdf(&h, &fp, wi, wo, lambda, 4);
            num += (g - b).powi(2);
            den += b * b;
        }
    }
    let rel = (num / den).sqrt();
    eprintln!("relative L2 difference Gabor vs brute force: {rel:.4}");
    // Measured 0.014 (the same with an 8x finer reference grid).
    assert!(rel < 0.03, "{rel}");
}

#[test]
fn hierarchy_does_not_change_the_result() {
    let s = GaborSurface::new(noise(2));
    let fp = Footprint {
        center_um: [1.0, 15.5],
        sigma_um: 2.0,
    };
    let on = Settings::default();
    let off = Settings {
        hierarchy: false,
        ..on
    };
    let exact = Settings {
        eps: 1e-12,
        hierarchy: false,
        ..Settings::default()
    };
    let comb = Comb::visible(8);
    let (mut worst_cull, mut global) = (0.0f64, 0.0f64);
    for k in 0..60 {
        let wi = dir_from_angle(-70.0 + k as f64 * 2.3);
        let wo = wo_xy(
            0.8 * ((k as f64) * 0.37).sin(),
            0.5 * ((k as f64) * 0.71).cos(),
        )
        .unwrap();
        let (mut a, mut b, mut c) = ([0.0; 8], [0.0; 8], [0.0; 8]);
        s.eval(&fp, Model::Ghs, wi, wo, &comb, &on, &mut a);
        s.eval(&fp, Model::Ghs, wi, wo, &comb, &off, &mut b);
        s.eval(&fp, Model::Ghs, wi, wo, &comb, &exact, &mut c);
        let peak = c
            .iter()
            .chain(a.iter())
            .cloned()
            .fold(0.0, f64::max)
            .max(1e-30);
        global = global.max(peak);
        for j in 0..8 {
            // Same kernels, summed in another order (f32 partial sums).
            assert!(
                (a[j] - b[j]).abs() <= 1e-5 * peak,
                "{k} {j}: {} {}",
                a[j],
                b[j]
            );
            worst_cull = worst_cull.max((a[j] - c[j]).abs());
        }
    }
    let worst_cull = worst_cull / global;
    eprintln!("culling at eps = exp(-4.5) vs every kernel: worst difference {worst_cull:.4} of the largest value");
    assert!(worst_cull < 0.05, "{worst_cull}");
}

fn albedo_test_fields() -> Vec<(&'static str, Heightfield)> {
    vec![
        ("noise", noise(1)),
        (
            "grating",
            generate(
                &Kind::Grating {
                    period_um: 4.0,
                    amplitude_um: 0.1,
                    direction_deg: 30.0,
                },
                64,
                64,
                0.25,
                0,
            )
            .unwrap(),
        ),
        (
            "rough",
            generate(
                &Kind::Noise {
                    rms_um: 0.3,
                    corr_um: 1.0,
                },
                64,
                64,
                0.25,
                3,
            )
            .unwrap(),
        ),
    ]
}

/// Directional albedo `sum f (2/R)^2` over the projected hemisphere, as
/// `isolux wave brdf` prints it.
fn albedo(
    s: &GaborSurface,
    fp: &Footprint,
    model: Model,
    wi: DVec3,
    set: &Settings,
    res: usize,
) -> f64 {
    let mut a = 0.0;
    for r in 0..res {
        for c in 0..res {
            let x = (c as f64 + 0.5) / res as f64 * 2.0 - 1.0;
            let y = 1.0 - (r as f64 + 0.5) / res as f64 * 2.0;
            if let Some(wo) = wo_xy(x, y) {
                a += s.eval_single(fp, model, wi, wo, 0.5, set) * (2.0 / res as f64).powi(2);
            }
        }
    }
    a
}

fn albedo_res() -> usize {
    std::env::var("RES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(128)
}

#[test]
fn albedo_is_at_most_one() {
    let res = albedo_res();
    let fp = Footprint {
        center_um: [4.0, 4.0],
        sigma_um: 2.0,
    };
    let set = Settings::default();
    for (name, h) in albedo_test_fields() {
        let s = GaborSurface::new(h);
        for model in [Model::Ghs, Model::Ohs] {
            for theta in [0.0, 30.0, 45.0, 60.0, 75.0, 85.0] {
                let wi = dir_from_angle(theta);
                let a = albedo(&s, &fp, model, wi, &set, res);
                eprintln!("{name} {model:?} theta {theta}: albedo {a:.4}");
                assert!(a <= 1.0 && a > 0.0, "{name} {model:?} theta {theta}: {a}");
            }
        }
    }
}

/// The seed's obliquity factor `cos_o / cos_i` returns more than it
/// receives where a grating diffracts grazing light toward the normal: the
/// reason the default is `O = 1` (docs/wave-optics.md, "Energy").
#[test]
fn seed_obliquity_exceeds_one_at_grazing_incidence() {
    let res = albedo_res();
    let fp = Footprint {
        center_um: [4.0, 4.0],
        sigma_um: 2.0,
    };
    let set = Settings {
        obliquity: Obliquity::Seed,
        ..Settings::default()
    };
    let (_, h) = albedo_test_fields().swap_remove(1);
    let s = GaborSurface::new(h);
    let a45 = albedo(&s, &fp, Model::Ghs, dir_from_angle(45.0), &set, res);
    let a75 = albedo(&s, &fp, Model::Ghs, dir_from_angle(75.0), &set, res);
    eprintln!("seed obliquity, grating: albedo {a45:.4} at 45, {a75:.4} at 75 degrees");
    assert!(a45 <= 1.0, "{a45}");
    assert!(a75 > 1.05, "{a75}");
}

#[test]
fn default_brdf_is_reciprocal() {
    let s = GaborSurface::new(noise(4));
    let fp = Footprint {
        center_um: [6.0, 5.0],
        sigma_um: 2.0,
    };
    let set = Settings::default();
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut worst = 0.0f64;
    for _ in 0..200 {
        let mut dir = || loop {
            let (x, y) = (2.0 * next() - 1.0, 2.0 * next() - 1.0);
            if let Some(d) = wo_xy(x, y) {
                break d;
            }
        };
        let (wi, wo) = (dir(), dir());
        for model in [Model::Ghs, Model::Ohs] {
            let a = s.eval_single(&fp, model, wi, wo, 0.5, &set);
            let b = s.eval_single(&fp, model, wo, wi, 0.5, &set);
            worst = worst.max((a - b).abs() / a.abs().max(b.abs()).max(1e-3));
        }
    }
    eprintln!("worst relative reciprocity error {worst:.2e}");
    assert!(worst < 1e-3, "{worst}");
}

/// The field repeats, so a footprint moved by whole periods sums the same
/// kernels at the same offsets: f, sample and pdf agree (to rounding) at a
/// centre seven periods out and at one 1e33 um out, where f64's spacing
/// (1e17 um) is wider than any window. That one used to build a window of
/// about 3e17 texels and exhaust the memory (scripts/gpu-diff-fuzz.py
/// --cpu-only: a spherical mapping centred 1e30 scene units away).
#[test]
fn footprints_whole_periods_apart_agree_and_far_ones_stay_bounded() {
    let s = GaborSurface::new(noise(5));
    let (w, h) = (s.width as f64 * s.texel_um, s.height as f64 * s.texel_um);
    let fp = Footprint {
        center_um: [3.3, 7.9],
        sigma_um: 2.0,
    };
    let moved = Footprint {
        center_um: [3.3 + 7.0 * w, 7.9 - 3.0 * h],
        ..fp
    };
    let set = Settings::default();
    let comb = Comb::visible(4);
    for k in 0..20 {
        let wi = dir_from_angle(-60.0 + k as f64 * 6.1);
        let wo = wo_xy(0.6 * (k as f64 * 0.37).sin(), 0.4 * (k as f64).cos()).unwrap();
        let (mut a, mut b) = ([0.0; 4], [0.0; 4]);
        s.eval(&fp, Model::Ghs, wi, wo, &comb, &set, &mut a);
        s.eval(&moved, Model::Ghs, wi, wo, &comb, &set, &mut b);
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() <= 1e-9 * x.abs().max(1e-6), "{a:?} {b:?}");
        }
        let u = [0.1 + 0.04 * k as f64, 0.7];
        let d = s.sample(&fp, Model::Ghs, wi, 10.0, &set, u, [0.3, 0.6]);
        let e = s.sample(&moved, Model::Ghs, wi, 10.0, &set, u, [0.3, 0.6]);
        match (d, e) {
            (Some(d), Some(e)) => {
                assert!((d - e).length() < 1e-9, "{d} {e}");
                let (p, q) = (
                    s.pdf(&fp, Model::Ghs, wi, d, 10.0, &set),
                    s.pdf(&moved, Model::Ghs, wi, d, 10.0, &set),
                );
                assert!((p - q).abs() <= 1e-9 * p.abs(), "{p} {q}");
            }
            (None, None) => {}
            other => panic!("{other:?}"),
        }
    }
    // 1e33 um out: a window of the usual size, a finite value.
    let far = Footprint {
        center_um: [1e33, -1e33],
        ..fp
    };
    assert_eq!(s.window_kernels(&far, &set), s.window_kernels(&fp, &set));
    let mut v = [0.0; 4];
    s.eval(
        &far,
        Model::Ghs,
        dir_from_angle(20.0),
        DVec3::Z,
        &comb,
        &set,
        &mut v,
    );
    assert!(v.iter().all(|x| x.is_finite() && *x >= 0.0), "{v:?}");
}
