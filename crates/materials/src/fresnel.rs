//! # Fresnel reflectance
//!
//! The fraction of light a smooth interface reflects, unpolarized (the
//! mean of the s and p reflectances):
//!
//! - **dielectric** (real relative index `eta = n_t / n_i`), exact, with
//!   total internal reflection:
//!   `r_par = (eta cos_i - cos_t)/(eta cos_i + cos_t)`,
//!   `r_perp = (cos_i - eta cos_t)/(cos_i + eta cos_t)`,
//!   `F = (r_par^2 + r_perp^2) / 2`;
//! - **conductor** (complex index `eta + i k`), exact, in the real-arithmetic
//!   form of pbrt-v3 §8.2.1: with `s^2 = sin^2 theta`,
//!   `a^2 + b^2 = sqrt((eta^2 - k^2 - s^2)^2 + 4 eta^2 k^2)`,
//!   `a = sqrt((a^2 + b^2 + eta^2 - k^2 - s^2) / 2)`,
//!   `R_s = (a^2 + b^2 + cos^2 - 2 a cos) / (a^2 + b^2 + cos^2 + 2 a cos)`,
//!   `R_p = R_s (cos^2 (a^2+b^2) + s^4 - 2 a cos s^2) / (cos^2 (a^2+b^2) + s^4 + 2 a cos s^2)`;
//! - **Schlick's approximation** `F = F0 + (1 - F0)(1 - cos)^5`.
//!
//! Scene keys (on every model that takes Fresnel): `metal = "Au"` (see
//! [`crate::metals`]), or `eta = [r, g, b]` with `k = [r, g, b]`, or
//! `ior = x` (dielectric), or `schlick = [r, g, b]` (F0). Metals give
//! coloured highlights, dielectrics white ones.
//!
//! Sources: Born and Wolf, *Principles of Optics*, §1.5 and §14.2; C.
//! Schlick, "An Inexpensive BRDF Model for Physically-based Rendering",
//! Computer Graphics Forum 13(3), 1994.

use isolux_core::Rgb;

/// A Fresnel term.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fresnel {
    /// No Fresnel: `F = 1` (perfect reflector).
    One,
    /// Dielectric interface of relative index `ior` (outside index 1).
    Dielectric {
        /// Relative index of refraction `n_t / n_i`.
        ior: f64,
    },
    /// Conductor of complex relative index `eta + i k`, per channel.
    Conductor {
        /// Real part.
        eta: Rgb,
        /// Imaginary part (extinction).
        k: Rgb,
    },
    /// Schlick's approximation with normal-incidence reflectance `f0`.
    Schlick {
        /// Reflectance at normal incidence.
        f0: Rgb,
    },
}

impl Fresnel {
    /// Reflectance for the cosine between the incident direction and the
    /// (micro)surface normal. For `Dielectric`, a negative cosine means
    /// light arriving from inside.
    pub fn eval(&self, cos_i: f64) -> Rgb {
        match *self {
            Fresnel::One => Rgb::WHITE,
            Fresnel::Dielectric { ior } => Rgb::splat(dielectric(cos_i, ior)),
            Fresnel::Conductor { eta, k } => {
                let c = cos_i.abs();
                Rgb::new(
                    conductor(c, eta.r, k.r),
                    conductor(c, eta.g, k.g),
                    conductor(c, eta.b, k.b),
                )
            }
            Fresnel::Schlick { f0 } => {
                let m = (1.0 - cos_i.abs().min(1.0)).powi(5);
                f0 + (Rgb::WHITE + f0 * -1.0) * m
            }
        }
    }
    /// The same interface seen from a medium of index `n` instead of
    /// vacuum: every index divided by `n` (a conductor's complex index
    /// too). Schlick's `f0` is read as a dielectric's, `f0 = ((m - 1) /
    /// (m + 1))^2`, per channel; its index `m / n` gives the new `f0` (a
    /// channel of `f0 >= 1` stays 1). `One` is unchanged. `None` for
    /// `n = 1` or a term that does not change.
    pub fn relative_to(&self, n: f64) -> Option<Fresnel> {
        if n == 1.0 || !(n > 0.0) {
            return None;
        }
        match *self {
            Fresnel::One => None,
            Fresnel::Dielectric { ior } => Some(Fresnel::Dielectric { ior: ior / n }),
            Fresnel::Conductor { eta, k } => Some(Fresnel::Conductor {
                eta: eta / n,
                k: k / n,
            }),
            Fresnel::Schlick { f0 } => {
                let ch = |f: f64| {
                    let r = f.clamp(0.0, 1.0).sqrt();
                    if r >= 1.0 {
                        return 1.0;
                    }
                    let m = (1.0 + r) / (1.0 - r) / n;
                    ((m - 1.0) / (m + 1.0)).powi(2)
                };
                Some(Fresnel::Schlick {
                    f0: Rgb::new(ch(f0.r), ch(f0.g), ch(f0.b)),
                })
            }
        }
    }
}

/// Exact unpolarized dielectric reflectance; `eta = n_t / n_i` for light
/// arriving from the side the normal points to (`cos_i > 0`), inverted
/// when `cos_i < 0`. Returns 1 under total internal reflection.
pub fn dielectric(cos_i: f64, eta: f64) -> f64 {
    let mut cos_i = cos_i.clamp(-1.0, 1.0);
    let mut eta = eta;
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
    }
    let sin2_i = 1.0 - cos_i * cos_i;
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_par * r_par + r_perp * r_perp)
}

/// Exact unpolarized conductor reflectance for `cos_i` in `[0, 1]` and the
/// complex relative index `eta + i k`.
pub fn conductor(cos_i: f64, eta: f64, k: f64) -> f64 {
    let c = cos_i.clamp(0.0, 1.0);
    let c2 = c * c;
    let s2 = 1.0 - c2;
    let t0 = eta * eta - k * k - s2;
    let a2b2 = (t0 * t0 + 4.0 * eta * eta * k * k).sqrt();
    let a = (0.5 * (a2b2 + t0)).max(0.0).sqrt();
    let t1 = a2b2 + c2;
    let t2 = 2.0 * c * a;
    let rs = (t1 - t2) / (t1 + t2);
    let t3 = c2 * a2b2 + s2 * s2;
    let t4 = t2 * s2;
    let rp = rs * (t3 - t4) / (t3 + t4);
    let f = 0.5 * (rp + rs);
    if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// Hemispherical average `2 int_0^1 F(mu) mu dmu` of the dielectric
/// reflectance for light arriving from outside (relative index `eta`),
/// by Simpson's rule on 2048 intervals.
pub fn diffuse_external(eta: f64) -> f64 {
    let n = 2048;
    let h = 1.0 / n as f64;
    let g = |mu: f64| dielectric(mu, eta) * mu;
    let mut s = g(0.0) + g(1.0);
    for i in 1..n {
        s += g(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    2.0 * s * h / 3.0
}

/// The same average for light inside the medium, total internal
/// reflection included: `1 - (1 - F_ext) / eta^2` (the transmitted part
/// scales by `1/eta^2` between the two sides).
pub fn diffuse_internal(eta: f64) -> f64 {
    1.0 - (1.0 - diffuse_external(eta)) / (eta * eta)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_closed_forms() {
        // Normal incidence: ((n - 1) / (n + 1))^2.
        for n in [1.33f64, 1.5, 2.4] {
            let r0 = ((n - 1.0) / (n + 1.0)).powi(2);
            assert!((dielectric(1.0, n) - r0).abs() < 1e-14);
            // The same from inside (reciprocity of normal incidence).
            assert!((dielectric(-1.0, n) - r0).abs() < 1e-14);
        }
        // Brewster angle: p reflectance vanishes, so F = R_s / 2 with
        // R_s = sin^2(i - t) / sin^2(i + t).
        let n: f64 = 1.5;
        let ib = n.atan();
        let tb = (ib.sin() / n).asin();
        let rs = ((ib - tb).sin() / (ib + tb).sin()).powi(2);
        assert!((dielectric(ib.cos(), n) - 0.5 * rs).abs() < 1e-14);
        // Total internal reflection beyond the critical angle from inside.
        let crit = (1.0 / n).asin();
        assert_eq!(dielectric(-(crit + 0.01).cos(), n), 1.0);
        assert!(dielectric(-(crit - 0.01).cos(), n) < 1.0);
        // Grazing incidence reflects everything.
        assert!((dielectric(1e-9, n) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn conductor_closed_forms() {
        // Normal incidence: ((n-1)^2 + k^2) / ((n+1)^2 + k^2).
        for (n, k) in [(0.2, 3.0), (1.5, 0.0), (2.9, 3.3)] {
            let r0 = ((n - 1.0f64).powi(2) + k * k) / ((n + 1.0f64).powi(2) + k * k);
            assert!((conductor(1.0, n, k) - r0).abs() < 1e-12, "{n} {k}");
        }
        // k = 0 reduces to the dielectric formula at every angle.
        for i in 0..=20 {
            let c = i as f64 / 20.0;
            assert!(
                (conductor(c, 1.7, 0.0) - dielectric(c, 1.7)).abs() < 1e-12,
                "{c}"
            );
        }
        assert!((conductor(0.0, 0.2, 3.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn gold_is_yellow_and_silver_is_white() {
        let (eta, k) = crate::metals::Metal::by_name("Au").unwrap().rgb();
        let f = Fresnel::Conductor {
            eta: Rgb::from_array(eta),
            k: Rgb::from_array(k),
        }
        .eval(1.0);
        assert!(f.r > 0.85 && f.b < 0.45 && f.r > f.g && f.g > f.b, "{f:?}");
        let (eta, k) = crate::metals::Metal::by_name("Ag").unwrap().rgb();
        let f = Fresnel::Conductor {
            eta: Rgb::from_array(eta),
            k: Rgb::from_array(k),
        }
        .eval(1.0);
        assert!(f.b > 0.9 && f.r > 0.95, "{f:?}");
    }

    #[test]
    fn schlick_matches_exact_at_the_ends() {
        let n = 1.5;
        let f0 = dielectric(1.0, n);
        let s = Fresnel::Schlick { f0: Rgb::splat(f0) };
        assert!((s.eval(1.0).r - f0).abs() < 1e-15);
        assert!((s.eval(0.0).r - 1.0).abs() < 1e-15);
        // And within its known error in between for glass (measured max
        // 0.036 near grazing incidence).
        let mut worst: f64 = 0.0;
        for i in 1..100 {
            let c = i as f64 / 100.0;
            worst = worst.max((s.eval(c).r - dielectric(c, n)).abs());
        }
        assert!(worst < 0.04 && worst > 0.005, "{worst}");
    }
}
