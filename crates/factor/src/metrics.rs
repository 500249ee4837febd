//! Error metrics on held-out samples.

use crate::source::Sample;
use isolux_core::{DVec3, Rgb};
use rayon::prelude::*;

/// Errors of an approximation over held-out samples.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Metrics {
    /// `sqrt(mean(((f_hat - f) / max(f, floor))^2))` over samples and
    /// channels with a value (`f >= 0`, finite): relative above the fit's
    /// floor, relative to the floor below it (where a relative error
    /// against `f = 1e-150` would measure nothing anyone sees).
    pub relative_rms: f64,
    /// `sqrt(mean(((f_hat - f) cos(theta_i))^2))` over the same terms (1/sr).
    pub cosine_abs_rms: f64,
    /// `sqrt(mean((f cos(theta_i))^2))` over the same terms (1/sr): the
    /// error of an approximation by zero, which any fit worth keeping
    /// beats.
    pub reference_rms: f64,
    /// Terms (sample x channel) averaged.
    pub terms: usize,
}

/// Measures `approx` against the held-out samples, relative errors
/// against `max(f, floor)` per channel (the fit's floor,
/// [`crate::Factorization::floor`]; zero for plain relative errors).
pub fn evaluate(
    held: &[Sample],
    floor: Rgb,
    approx: impl Fn(DVec3, DVec3) -> Rgb + Sync,
) -> Metrics {
    let floor = floor.to_array();
    let (rel, abs, reference, n) = held
        .par_iter()
        .map(|s| {
            let Some(f) = s.f else {
                return (0.0, 0.0, 0.0, 0usize);
            };
            let g = approx(s.wo, s.wi).to_array();
            let f = f.to_array();
            let (mut rel, mut abs, mut reference, mut n) = (0.0, 0.0, 0.0, 0);
            for c in 0..3 {
                let base = f[c].max(floor[c]);
                if f[c] >= 0.0 && f[c].is_finite() && base > 0.0 {
                    rel += ((g[c] - f[c]) / base).powi(2);
                    abs += ((g[c] - f[c]) * s.wi.z).powi(2);
                    reference += (f[c] * s.wi.z).powi(2);
                    n += 1;
                }
            }
            (rel, abs, reference, n)
        })
        .reduce(
            || (0.0, 0.0, 0.0, 0),
            |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2, a.3 + b.3),
        );
    if n == 0 {
        return Metrics::default();
    }
    Metrics {
        relative_rms: (rel / n as f64).sqrt(),
        cosine_abs_rms: (abs / n as f64).sqrt(),
        reference_rms: (reference / n as f64).sqrt(),
        terms: n,
    }
}
