//! Procedural heightfields for `isolux heightfield gen`.
//!
//! | kind | parameters | construction |
//! |---|---|---|
//! | `noise` | RMS height, correlation length | white noise filtered in Fourier space by a Gaussian, so that the autocorrelation is `rms^2 exp(-r^2 / corr^2)`; rescaled to the exact RMS |
//! | `brushed` | RMS height, correlation lengths along and across, direction | the same with an anisotropic Gaussian: long streaks along the direction |
//! | `scratches` | count, depth, width, length, base noise RMS | V-shaped grooves along random segments (wrapped periodically) over optional base noise |
//! | `grating` | period, amplitude, direction | `A sin(2 pi (s . d) / P)`; seamless when the field spans whole periods |
//!
//! All heights are in um, about a zero mean. Deterministic for a seed.

use crate::heightfield::{Heightfield, HeightfieldError};
use isolux_core::{short_number, Pcg32};
use rustfft::num_complex::Complex64;
use rustfft::FftPlanner;

/// What to generate.
#[derive(Clone, Debug, PartialEq)]
pub enum Kind {
    /// Isotropic Gaussian-filtered noise.
    Noise {
        /// RMS height (um).
        rms_um: f64,
        /// Correlation length (um).
        corr_um: f64,
    },
    /// Anisotropic noise: brushed metal.
    Brushed {
        /// RMS height (um).
        rms_um: f64,
        /// Correlation length along the brushing direction (um).
        along_um: f64,
        /// Correlation length across it (um).
        across_um: f64,
        /// Brushing direction, degrees from +x toward +y.
        direction_deg: f64,
    },
    /// Random scratches over base noise.
    Scratches {
        /// Number of scratches.
        count: usize,
        /// Groove depth (um).
        depth_um: f64,
        /// Groove half-width (um).
        width_um: f64,
        /// Scratch length (um).
        length_um: f64,
        /// RMS of the isotropic base noise (um); 0 for none.
        base_rms_um: f64,
        /// Correlation length of the base noise (um).
        base_corr_um: f64,
    },
    /// Sinusoidal grating.
    Grating {
        /// Period (um).
        period_um: f64,
        /// Amplitude (um).
        amplitude_um: f64,
        /// Direction of the grating vector, degrees from +x toward +y.
        direction_deg: f64,
    },
}

/// The most texel visits `scratches` may take (a few seconds of work):
/// the scratch count times the texels of each one's bounding box.
pub const MAX_SCRATCH_VISITS: f64 = 1e9;

fn positive(name: &str, v: f64) -> Result<(), HeightfieldError> {
    if !(v > 0.0) || !v.is_finite() {
        return Err(HeightfieldError::Invalid(format!(
            "{name} must be positive and finite, got {v}"
        )));
    }
    Ok(())
}

fn finite(name: &str, v: f64) -> Result<(), HeightfieldError> {
    if !v.is_finite() {
        return Err(HeightfieldError::Invalid(format!(
            "{name} must be a finite number, got {v}"
        )));
    }
    Ok(())
}

fn non_negative(name: &str, v: f64) -> Result<(), HeightfieldError> {
    if !(v >= 0.0) || !v.is_finite() {
        return Err(HeightfieldError::Invalid(format!(
            "{name} must be non-negative and finite, got {v}"
        )));
    }
    Ok(())
}

/// Why a grating does not repeat with the field, if it does not: the field
/// tiles the surface (every reader wraps it), so a grating that does not
/// hold a whole number of periods along each side meets itself at a seam,
/// whose step diffracts light of its own. A warning rather than an error:
/// a grating at an arbitrary angle rarely fits exactly.
pub fn grating_seam(
    width: usize,
    height: usize,
    texel_um: f64,
    period_um: f64,
    direction_deg: f64,
) -> Option<String> {
    let (s, c) = direction_deg.to_radians().sin_cos();
    let along = [
        ("x", width as f64 * texel_um * c / period_um),
        ("y", height as f64 * texel_um * s / period_um),
    ];
    let (axis, periods) = along
        .into_iter()
        .find(|(_, n)| (n - n.round()).abs() > 1e-6 * n.abs().max(1.0))?;
    Some(format!(
        "the field holds {:.3} grating periods along {axis}, not a whole number: it repeats with a seam",
        periods.abs()
    ))
}

/// Refuses a length the texels cannot resolve. A correlation length under
/// a texel gives white noise at the texel scale, whose correlation is a
/// texel and whose slopes (`rms / corr`, what scatters the light) are off
/// by `texel / corr`: `--corr-um 0.01` on 1 um texels was written as such
/// a field without a word, with the requested RMS.
fn resolved(name: &str, len_um: f64, texels: f64, texel_um: f64) -> Result<(), HeightfieldError> {
    let min_um = texels * texel_um;
    if len_um < min_um {
        return Err(HeightfieldError::Invalid(format!(
            "{name} of {} um is shorter than {} ({} um): the texels cannot hold it; \
             use texels of at most {} um",
            short_number(len_um),
            if texels == 1.0 {
                "a texel"
            } else {
                "half a texel"
            },
            short_number(min_um),
            short_number(len_um / texels)
        )));
    }
    Ok(())
}

/// Generates a `width x height` field of `texel_um` texels.
pub fn generate(
    kind: &Kind,
    width: usize,
    height: usize,
    texel_um: f64,
    seed: u64,
) -> Result<Heightfield, HeightfieldError> {
    positive("texel size", texel_um)?;
    if width == 0 || height == 0 || width.saturating_mul(height) > crate::heightfield::MAX_TEXELS {
        return Err(HeightfieldError::Invalid(format!(
            "invalid size {width} x {height}"
        )));
    }
    let data = match *kind {
        Kind::Noise { rms_um, corr_um } => {
            non_negative("rms", rms_um)?;
            positive("correlation length", corr_um)?;
            resolved("a correlation length", corr_um, 1.0, texel_um)?;
            filtered_noise(width, height, texel_um, seed, rms_um, corr_um, corr_um, 0.0)?
        }
        Kind::Brushed {
            rms_um,
            along_um,
            across_um,
            direction_deg,
        } => {
            non_negative("rms", rms_um)?;
            positive("correlation length along", along_um)?;
            finite("direction", direction_deg)?;
            positive("correlation length across", across_um)?;
            resolved("a correlation length along", along_um, 1.0, texel_um)?;
            resolved("a correlation length across", across_um, 1.0, texel_um)?;
            filtered_noise(
                width,
                height,
                texel_um,
                seed,
                rms_um,
                along_um,
                across_um,
                direction_deg.to_radians(),
            )?
        }
        Kind::Scratches {
            count,
            depth_um,
            width_um,
            length_um,
            base_rms_um,
            base_corr_um,
        } => {
            positive("scratch width", width_um)?;
            positive("scratch length", length_um)?;
            non_negative("scratch depth", depth_um)?;
            non_negative("base rms", base_rms_um)?;
            // A groove narrower than a texel misses most texel centres: a
            // half-width of 0.01 um on 1 um texels left the scratches all
            // but invisible.
            resolved("a scratch half-width", width_um, 0.5, texel_um)?;
            // Each scratch visits the texels of its bounding box (at most
            // (length + 2 half-widths)^2): refused up front where that
            // would run for minutes, as 1e9 scratches or one of 1e9 um did.
            let side = (length_um + 2.0 * width_um) / texel_um + 3.0;
            let visits = count as f64 * side * side;
            if visits > MAX_SCRATCH_VISITS {
                return Err(HeightfieldError::Invalid(format!(
                    "{count} scratch(es) {length_um} um long, of half-width {width_um} um, on \
                     {texel_um} um texels would take about {visits:.1e} texel visits, beyond \
                     the {MAX_SCRATCH_VISITS:.0e} the generator allows; use fewer, shorter or \
                     narrower scratches (or larger texels)"
                )));
            }
            let mut h = if base_rms_um > 0.0 {
                positive("base correlation length", base_corr_um)?;
                resolved(
                    "a base correlation length",
                    base_corr_um,
                    texel_um,
                    texel_um,
                )?;
                filtered_noise(
                    width,
                    height,
                    texel_um,
                    seed,
                    base_rms_um,
                    base_corr_um,
                    base_corr_um,
                    0.0,
                )?
            } else {
                vec![0.0; width * height]
            };
            scratch(
                &mut h, width, height, texel_um, seed, count, depth_um, width_um, length_um,
            );
            h
        }
        Kind::Grating {
            period_um,
            amplitude_um,
            direction_deg,
        } => {
            positive("period", period_um)?;
            finite("direction", direction_deg)?;
            non_negative("amplitude", amplitude_um)?;
            let (s, c) = direction_deg.to_radians().sin_cos();
            // Sampled at fewer than two texels a period along an axis, the
            // texels hold another, aliased grating, whose orders fall
            // elsewhere: a period of 1.5 um on 1 um texels was written as
            // one of 3 um.
            let cycles = [
                c.abs() * texel_um / period_um,
                s.abs() * texel_um / period_um,
            ];
            if cycles.iter().any(|&k| k > 0.5 + 1e-9) {
                return Err(HeightfieldError::Invalid(format!(
                    "a grating period of {} um at {} degrees is shorter than two texels \
                     ({} um) along {}: the texels would hold an aliased grating of another period; \
                     use smaller texels or a longer period",
                    short_number(period_um),
                    short_number(direction_deg),
                    short_number(2.0 * texel_um),
                    if cycles[0] > 0.5 + 1e-9 { "x" } else { "y" }
                )));
            }
            let mut h = vec![0.0f32; width * height];
            for r in 0..height {
                for col in 0..width {
                    let x = (col as f64 + 0.5) * texel_um;
                    let y = (r as f64 + 0.5) * texel_um;
                    let ph = 2.0 * std::f64::consts::PI * (x * c + y * s) / period_um;
                    h[r * width + col] = (amplitude_um * ph.sin()) as f32;
                }
            }
            h
        }
    };
    if data.iter().any(|h| !h.is_finite()) {
        return Err(HeightfieldError::Invalid(
            "the heights asked for overflow the field's f32 texels (at most 3.4e38 um): \
             use a smaller RMS, depth or amplitude"
                .into(),
        ));
    }
    let field = Heightfield::new(width, height, texel_um, data)?;
    // A field too small for its grating samples too little of a period to
    // vary (1 x 64 texels across a grating along x, or 2 x 2 texels of a
    // 4 um period): it came out flat, RMS 0, where an amplitude was asked
    // for.
    if let Kind::Grating {
        period_um,
        amplitude_um,
        direction_deg,
    } = *kind
    {
        if amplitude_um > 0.0 && field.rms() < 0.01 * amplitude_um / std::f64::consts::SQRT_2 {
            return Err(HeightfieldError::Invalid(format!(
                "a field of {} x {} um is too small for a grating of period {} um at {} degrees: \
                 its texels come out flat where an amplitude of {} um was asked for",
                short_number(width as f64 * texel_um),
                short_number(height as f64 * texel_um),
                short_number(period_um),
                short_number(direction_deg),
                short_number(amplitude_um)
            )));
        }
    }
    Ok(field)
}

fn gauss(rng: &mut Pcg32) -> f64 {
    let u1 = 1.0 - rng.next_f64();
    let u2 = rng.next_f64();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

#[allow(clippy::too_many_arguments)]
fn filtered_noise(
    w: usize,
    h: usize,
    texel: f64,
    seed: u64,
    rms: f64,
    along: f64,
    across: f64,
    angle: f64,
) -> Result<Vec<f32>, HeightfieldError> {
    let mut rng = Pcg32::new(seed, 0x6e6f697365);
    let mut buf: Vec<Complex64> = (0..w * h)
        .map(|_| Complex64::new(gauss(&mut rng), 0.0))
        .collect();
    let mut planner = FftPlanner::<f64>::new();
    fft2(&mut buf, w, h, &mut planner, false);
    // Filter: the Fourier transform of the kernel exp(-2 |s|^2 / L^2) is
    // proportional to exp(-pi^2 L^2 f^2 / 2); the filtered noise then has
    // the autocorrelation exp(-r^2 / L^2), per axis of the rotated frame.
    let (sn, cs) = angle.sin_cos();
    for r in 0..h {
        let fy = freq(r, h) / (h as f64 * texel);
        for c in 0..w {
            let fx = freq(c, w) / (w as f64 * texel);
            let fa = fx * cs + fy * sn;
            let fc = -fx * sn + fy * cs;
            let g = (-std::f64::consts::PI.powi(2)
                * (along * along * fa * fa + across * across * fc * fc)
                / 2.0)
                .exp();
            buf[r * w + c] *= g;
        }
    }
    buf[0] = Complex64::new(0.0, 0.0);
    fft2(&mut buf, w, h, &mut planner, true);
    let v: Vec<f64> = buf.iter().map(|z| z.re).collect();
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let cur = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
    if rms > 0.0 && !(cur > 1e-300 && cur.is_finite()) {
        // The Gaussian filter underflowed at every frequency the field
        // holds: no rescaling can give it the requested RMS.
        return Err(HeightfieldError::Invalid(format!(
            "a correlation length of {} um is too long for a field of {} x {} um: \
             the filter leaves it flat, so it cannot have an RMS height of {rms} um; \
             use at most about the field's size",
            isolux_core::short_number(along.max(across)),
            w as f64 * texel,
            h as f64 * texel
        )));
    }
    let k = if cur > 0.0 { rms / cur } else { 0.0 };
    Ok(v.iter().map(|x| ((x - mean) * k) as f32).collect())
}

/// Signed frequency index of bin `i` of `n`.
fn freq(i: usize, n: usize) -> f64 {
    if i <= n / 2 {
        i as f64
    } else {
        i as f64 - n as f64
    }
}

/// In-place 2-D FFT (rows, then columns); `inverse` is unnormalized.
pub(crate) fn fft2(
    buf: &mut [Complex64],
    w: usize,
    h: usize,
    planner: &mut FftPlanner<f64>,
    inverse: bool,
) {
    let fr = if inverse {
        planner.plan_fft_inverse(w)
    } else {
        planner.plan_fft_forward(w)
    };
    for row in buf.chunks_exact_mut(w) {
        fr.process(row);
    }
    let fc = if inverse {
        planner.plan_fft_inverse(h)
    } else {
        planner.plan_fft_forward(h)
    };
    let mut col = vec![Complex64::new(0.0, 0.0); h];
    for c in 0..w {
        for r in 0..h {
            col[r] = buf[r * w + c];
        }
        fc.process(&mut col);
        for r in 0..h {
            buf[r * w + c] = col[r];
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn scratch(
    h: &mut [f32],
    w: usize,
    hh: usize,
    texel: f64,
    seed: u64,
    count: usize,
    depth: f64,
    half_width: f64,
    length: f64,
) {
    let mut rng = Pcg32::new(seed, 0x736372617463);
    let (pw, ph) = (w as f64 * texel, hh as f64 * texel);
    for _ in 0..count {
        let a = [rng.next_f64() * pw, rng.next_f64() * ph];
        let ang = rng.next_f64() * std::f64::consts::PI;
        let d = [ang.cos(), ang.sin()];
        let b = [a[0] + d[0] * length, a[1] + d[1] * length];
        let lo = [a[0].min(b[0]) - half_width, a[1].min(b[1]) - half_width];
        let hi = [a[0].max(b[0]) + half_width, a[1].max(b[1]) + half_width];
        let c0 = (lo[0] / texel - 0.5).floor() as i64;
        let c1 = (hi[0] / texel - 0.5).ceil() as i64;
        let r0 = (lo[1] / texel - 0.5).floor() as i64;
        let r1 = (hi[1] / texel - 0.5).ceil() as i64;
        for r in r0..=r1 {
            for c in c0..=c1 {
                let p = [(c as f64 + 0.5) * texel, (r as f64 + 0.5) * texel];
                let t = ((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]).clamp(0.0, length);
                let q = [a[0] + d[0] * t - p[0], a[1] + d[1] * t - p[1]];
                let dist = (q[0] * q[0] + q[1] * q[1]).sqrt();
                if dist < half_width {
                    let cc = c.rem_euclid(w as i64) as usize;
                    let rr = r.rem_euclid(hh as i64) as usize;
                    let v = -(depth * (1.0 - dist / half_width)) as f32;
                    let e = &mut h[rr * w + cc];
                    *e = e.min(v);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_has_the_requested_rms_and_correlation() {
        let f = generate(
            &Kind::Noise {
                rms_um: 0.1,
                corr_um: 2.0,
            },
            128,
            96,
            0.5,
            3,
        )
        .unwrap();
        assert!((f.rms() - 0.1).abs() < 1e-6);
        // Autocorrelation at lag L (4 texels along x): exp(-1) of the variance.
        let mut c = 0.0;
        for r in 0..96 {
            for col in 0..128 {
                c += f.at(col, r) as f64 * f.at(col + 4, r) as f64;
            }
        }
        let rho = c / (128.0 * 96.0) / 0.01;
        assert!((rho - (-1.0f64).exp()).abs() < 0.08, "{rho}");
    }

    #[test]
    fn a_correlation_length_that_leaves_the_field_flat_is_refused() {
        // 1e30 um: the filter underflows at every frequency of a 16 um
        // field, so no rescaling reaches the requested RMS (it used to
        // write a flat field, RMS 0, without a word).
        for kind in [
            Kind::Noise {
                rms_um: 0.1,
                corr_um: 1e30,
            },
            Kind::Brushed {
                rms_um: 0.1,
                along_um: 1e30,
                across_um: 1e30,
                direction_deg: 0.0,
            },
        ] {
            let e = generate(&kind, 32, 32, 0.5, 1).unwrap_err().to_string();
            assert!(e.contains("too long for a field of 16 x 16 um"), "{e}");
        }
        // Far longer than the field but not flat: the lowest frequencies
        // carry it, at the requested RMS; a zero RMS stays a flat field.
        let long = Kind::Noise {
            rms_um: 0.1,
            corr_um: 100.0,
        };
        assert!((generate(&long, 32, 32, 0.5, 1).unwrap().rms() - 0.1).abs() < 1e-6);
        let flat = Kind::Noise {
            rms_um: 0.0,
            corr_um: 1e30,
        };
        assert_eq!(generate(&flat, 32, 32, 0.5, 1).unwrap().rms(), 0.0);
    }

    #[test]
    fn scratches_that_would_take_minutes_are_refused() {
        let scratches = |count: usize, width_um: f64, length_um: f64| Kind::Scratches {
            count,
            depth_um: 0.2,
            width_um,
            length_um,
            base_rms_um: 0.0,
            base_corr_um: 1.0,
        };
        // Each of these ran for minutes before (1e9 scratches; a scratch
        // of 1e9 um or 1e30 um over a 16 um field).
        for k in [
            scratches(1_000_000_000, 1.0, 10.0),
            scratches(5, 1e9, 10.0),
            scratches(5, 1.0, 1e30),
        ] {
            let e = generate(&k, 32, 32, 0.5, 1).unwrap_err().to_string();
            assert!(e.contains("texel visits, beyond the 1e9"), "{e}");
        }
        // Heights beyond f32 are named as such (they read 'height at
        // column 0, row 0 is inf').
        let deep = Kind::Grating {
            period_um: 4.0,
            amplitude_um: 1e39,
            direction_deg: 0.0,
        };
        let e = generate(&deep, 8, 8, 0.5, 1).unwrap_err().to_string();
        assert!(e.contains("overflow the field's f32 texels"), "{e}");
        // A direction of NaN degrees (it read as an overflow, or for
        // brushed noise as a correlation length too long).
        let nan = Kind::Brushed {
            rms_um: 0.1,
            along_um: 2.0,
            across_um: 1.0,
            direction_deg: f64::NAN,
        };
        let e = generate(&nan, 8, 8, 0.5, 1).unwrap_err().to_string();
        assert!(
            e.contains("direction must be a finite number, got NaN"),
            "{e}"
        );
        // A long scratch wraps around the field, within the limit.
        let f = generate(&scratches(3, 1.0, 2000.0), 32, 32, 0.5, 1).unwrap();
        assert!(f.rms() > 0.0);
    }

    #[test]
    fn brushed_is_longer_along_its_direction() {
        let k = Kind::Brushed {
            rms_um: 0.1,
            along_um: 20.0,
            across_um: 1.0,
            direction_deg: 90.0,
        };
        let f = generate(&k, 128, 128, 0.5, 1).unwrap();
        let corr = |dc: i64, dr: i64| {
            let mut s = 0.0;
            for r in 0..128 {
                for c in 0..128 {
                    s += f.at(c, r) as f64 * f.at(c + dc, r + dr) as f64;
                }
            }
            s / (128.0 * 128.0) / 0.01
        };
        // Along y (90 degrees) the field stays correlated; across x it does not.
        assert!(
            corr(0, 8) > 0.8 && corr(8, 0) < 0.1,
            "{} {}",
            corr(0, 8),
            corr(8, 0)
        );
    }

    #[test]
    fn grating_and_scratches() {
        let g = generate(
            &Kind::Grating {
                period_um: 4.0,
                amplitude_um: 0.2,
                direction_deg: 0.0,
            },
            16,
            4,
            0.5,
            0,
        )
        .unwrap();
        assert!(
            (g.at(1, 0) as f64 - 0.2 * (2.0 * std::f64::consts::PI * 0.75 / 4.0).sin()).abs()
                < 1e-6
        );
        let s = Kind::Scratches {
            count: 5,
            depth_um: 0.3,
            width_um: 1.0,
            length_um: 20.0,
            base_rms_um: 0.0,
            base_corr_um: 1.0,
        };
        let f = generate(&s, 64, 64, 0.5, 9).unwrap();
        let min = f.heights.iter().cloned().fold(0.0f32, f32::min);
        assert!((-0.3..-0.25).contains(&min), "{min}");
        assert!(generate(
            &Kind::Noise {
                rms_um: 0.1,
                corr_um: 0.0
            },
            8,
            8,
            1.0,
            0
        )
        .is_err());
    }

    /// A grating the texels cannot hold is refused, not written as another
    /// one: under two texels a period it aliases (a 1.5 um period on 1 um
    /// texels came out as a 3 um one), and a field too small for it came
    /// out flat.
    #[test]
    fn gratings_the_texels_cannot_hold_are_refused() {
        let grating = |period_um: f64, direction_deg: f64| Kind::Grating {
            period_um,
            amplitude_um: 0.05,
            direction_deg,
        };
        let e = generate(&grating(1.5, 0.0), 64, 8, 1.0, 0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("shorter than two texels (2 um) along x"), "{e}");
        let e = generate(&grating(1.9, 90.0), 8, 64, 1.0, 0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("along y"), "{e}");
        // At 45 degrees each axis sees the period stretched by sqrt 2.
        assert!(generate(&grating(1.5, 45.0), 64, 64, 1.0, 0).is_ok());
        // Exactly two texels a period holds it (at the sampled phase).
        assert!(generate(&grating(2.0, 0.0), 64, 8, 1.0, 0).is_ok());
        for (w, h) in [(1, 1), (1, 64), (2, 2)] {
            let e = generate(&grating(4.0, 0.0), w, h, 1.0, 0)
                .unwrap_err()
                .to_string();
            assert!(e.contains("too small for a grating"), "{w} x {h}: {e}");
        }
        // No amplitude asked for: flat is what was asked.
        let flat = Kind::Grating {
            period_um: 4.0,
            amplitude_um: 0.0,
            direction_deg: 0.0,
        };
        assert!(generate(&flat, 2, 2, 1.0, 0).is_ok());
    }

    #[test]
    fn a_grating_that_does_not_tile_is_named() {
        // 64 um hold 16 periods of 4 um along x, none along y.
        assert_eq!(grating_seam(64, 8, 1.0, 4.0, 0.0), None);
        assert_eq!(grating_seam(8, 64, 1.0, 4.0, 90.0), None);
        let w = grating_seam(64, 8, 1.0, 3.0, 0.0).unwrap();
        assert!(w.contains("21.333 grating periods along x"), "{w}");
        let w = grating_seam(64, 64, 1.0, 4.0, 30.0).unwrap();
        assert!(w.contains("along x"), "{w}");
        // At 45 degrees each side holds n t cos(45) / P periods: with texels
        // of sqrt(2) / 2 um, 64 x 0.5 / 4 = 8.
        let t = std::f64::consts::SQRT_2 / 2.0;
        assert_eq!(grating_seam(64, 64, t, 4.0, 45.0), None);
    }

    /// Lengths the texels cannot resolve are refused: a correlation length
    /// under a texel gave white noise with the requested RMS, and a groove
    /// under half a texel wide missed the texel centres.
    #[test]
    fn lengths_below_the_texels_are_refused() {
        let noise = |corr_um: f64| Kind::Noise {
            rms_um: 0.05,
            corr_um,
        };
        let e = generate(&noise(0.01), 16, 16, 1.0, 0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("a correlation length of 0.01 um is shorter than a texel (1 um)")
                && e.contains("texels of at most 0.01 um"),
            "{e}"
        );
        assert!(generate(&noise(1.0), 16, 16, 1.0, 0).is_ok());
        assert!(generate(&noise(0.5), 16, 16, 0.5, 0).is_ok());
        let brushed = Kind::Brushed {
            rms_um: 0.05,
            along_um: 8.0,
            across_um: 0.4,
            direction_deg: 0.0,
        };
        let e = generate(&brushed, 16, 16, 0.5, 0).unwrap_err().to_string();
        assert!(e.contains("correlation length across of 0.4 um"), "{e}");
        let scratches = |width_um: f64, base_corr_um: f64| Kind::Scratches {
            count: 3,
            depth_um: 0.1,
            width_um,
            length_um: 8.0,
            base_rms_um: 0.01,
            base_corr_um,
        };
        let e = generate(&scratches(0.01, 2.0), 16, 16, 1.0, 0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("half-width of 0.01 um is shorter than half a texel (0.5 um)"),
            "{e}"
        );
        let e = generate(&scratches(1.0, 0.2), 16, 16, 1.0, 0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("base correlation length of 0.2 um"), "{e}");
        assert!(generate(&scratches(0.5, 1.0), 16, 16, 1.0, 0).is_ok());
    }
}
