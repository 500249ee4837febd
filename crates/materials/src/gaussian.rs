//! # Gaussian microfacet highlight
//!
//! The seed's Gaussian model `exp(-(angle(n, h)/m)^2)`, made a microfacet
//! distribution normalized numerically so that `int D(h)(n.h) dh = 1`:
//!
//! ```text
//! D(h) = C exp(-(theta_h / m)^2),   C = 1 / (2 pi int_0^{pi/2} exp(-(t/m)^2) cos t sin t dt)
//! f = R / pi + k_s D(h) G(wo, wi) / (4 cos_o cos_i)    (V-groove G, F = 1)
//! ```
//!
//! `C` is integrated by Simpson's rule at load time, in steps of at most
//! `m / 16` up to `12 m` (where the integrand has fallen by `exp(-144)`).
//! The lobe is sampled from a 4096-bin table of `D cos` over `theta_h`
//! (piecewise constant in `theta`; the reported pdf is that table's exact
//! density). The specular term is a microfacet reflector with the V-groove
//! masking of Cook and Torrance, whose directional albedo stays at or below
//! 1 (checked at ten angles by the test suite), so `R + k_s <= 1` keeps the
//! model energy-conserving. Reciprocal.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `m` | number in [1e-3, 1] | `0.2` | Gaussian width (radians) |
//! | `specular` | RGB in [0, 1] | `[0.5, 0.5, 0.5]` | highlight weight `k_s` |
//! | `reflectance` | RGB in [0, 1] | `[0, 0, 0]` | diffuse albedo `R` (`R + k_s <= 1`) |
//!
//! Sources: R. L. Cook and K. E. Torrance (1982) §3 (Gaussian slope
//! model); seed 002.
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "satin"
//! type = "gaussian"
//! m = 0.15
//! specular = [0.4, 0.4, 0.4]
//! reflectance = [0.4, 0.3, 0.2]
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["m"].as_float(), Some(0.15));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::cook_torrance::{CookTorrance, Masking, NormalDistribution};
use crate::Fresnel;
use isolux_core::{DVec3, Distribution1D, Rgb, PI};
use std::sync::Arc;

const BINS: usize = 4096;

/// The narrowest Gaussian accepted (radians). Its sampling table has 4096
/// bins over the quarter circle (`pi / 8192` each), so a narrower lobe
/// lies within a bin or two and is sampled nearly uniformly across it:
/// unbiased, but with a variance that grows as `1 / m^2`. Such a surface
/// is a mirror for any practical purpose: use `conductor`, or `ggx`,
/// whose sampling follows any roughness.
pub const MIN_M: f64 = 1e-3;

/// The normalized Gaussian normal distribution and its sampling table.
#[derive(Clone, Debug)]
pub struct GaussianDistribution {
    /// Width `m` (radians).
    pub m: f64,
    norm: f64,
    table: Arc<Distribution1D>,
}

impl PartialEq for GaussianDistribution {
    fn eq(&self, o: &Self) -> bool {
        self.m == o.m
    }
}

impl GaussianDistribution {
    /// Builds the distribution of width `m` (radians, at least
    /// [`MIN_M`]).
    pub fn new(m: f64) -> Self {
        let g = |t: f64| (-(t / m) * (t / m)).exp() * t.cos() * t.sin();
        // Simpson's rule on [a, b], with steps of at most m / 16 so that a
        // lobe narrower than the interval is resolved. Beyond 12 m the
        // integrand is below exp(-144) of its peak, so the normalization
        // stops there (the table's bins do not, so that its pdf is positive
        // wherever D is). Over the whole quarter circle in 4096 steps, m = 1e-4
        // fell between the first two nodes and was normalized 62,000
        // times too bright (a directional albedo of 62,691).
        let simpson = |a: f64, b: f64, min_steps: usize| -> f64 {
            let n = (((b - a) / (m / 16.0)).ceil() as usize).max(min_steps);
            let n = n + n % 2;
            let h = (b - a) / n as f64;
            let mut s = g(a) + g(b);
            for i in 1..n {
                s += g(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            s * h / 3.0
        };
        let integral = simpson(0.0, (12.0 * m).min(PI / 2.0), 4096);
        let w = PI / 2.0 / BINS as f64;
        let weights: Vec<f64> = (0..BINS)
            .map(|i| simpson(i as f64 * w, (i + 1) as f64 * w, 8) / w)
            .collect();
        Self {
            m,
            norm: 1.0 / (2.0 * PI * integral),
            table: Arc::new(Distribution1D::new(&weights)),
        }
    }

    /// The normalization `1 / (2 pi int exp(-(t/m)^2) cos t sin t dt)`.
    pub fn normalization(&self) -> f64 {
        self.norm
    }

    /// The sampling table over `theta / (pi / 2)`.
    pub fn table(&self) -> &Distribution1D {
        &self.table
    }

    /// `D(h)`.
    pub fn d(&self, h: DVec3) -> f64 {
        if h.z <= 0.0 {
            return 0.0;
        }
        let t = polar_angle(h);
        self.norm * (-(t / self.m) * (t / self.m)).exp()
    }

    /// Samples `h` from the table.
    pub fn sample_m(&self, u: [f64; 2]) -> DVec3 {
        let (x, _, _) = self.table.sample(u[0]);
        let t = x * PI / 2.0;
        let phi = 2.0 * PI * u[1];
        DVec3::new(t.sin() * phi.cos(), t.sin() * phi.sin(), t.cos())
    }

    /// Solid-angle density of [`GaussianDistribution::sample_m`].
    pub fn pdf_m(&self, h: DVec3) -> f64 {
        if h.z <= 0.0 {
            return 0.0;
        }
        let t = polar_angle(h);
        let s = t.sin();
        if s <= 0.0 {
            return 0.0;
        }
        let pdf_t = self.table.pdf(t / (PI / 2.0)) / (PI / 2.0);
        pdf_t / (2.0 * PI * s)
    }
}

/// The angle of `h` from the normal, accurate at small angles: `acos(h.z)`
/// loses them (below about 1e-8 rad `h.z` rounds to 1 and the angle to 0,
/// where the sampling density is 0: a sampled half-vector 2.9e-8 rad off
/// the normal at `m = 1e-3` came back with pdf 0 and an infinite weight).
fn polar_angle(h: DVec3) -> f64 {
    (h.x * h.x + h.y * h.y).sqrt().atan2(h.z)
}

/// The seed's Gaussian highlight over a Lambertian base.
#[derive(Clone, Debug, PartialEq)]
pub struct Gaussian {
    /// Highlight weight.
    pub specular: Rgb,
    /// The microfacet reflector (diffuse base included, `F = 1`).
    pub inner: CookTorrance,
}

impl Gaussian {
    /// A Gaussian-highlight material.
    pub fn new(m: f64, specular: Rgb, reflectance: Rgb) -> Self {
        Self {
            specular,
            inner: CookTorrance {
                distribution: NormalDistribution::Gaussian(GaussianDistribution::new(m)),
                masking: Masking::VGroove,
                fresnel: Fresnel::One,
                reflectance: Rgb::BLACK,
            },
        }
        .with_diffuse(reflectance)
    }

    fn with_diffuse(mut self, r: Rgb) -> Self {
        self.inner.reflectance = r;
        self
    }

    fn diffuse(&self) -> Rgb {
        self.inner.reflectance
    }
}

impl BxdfModel for Gaussian {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        // With F = 1 the inner base weight (1 - F)^2 vanishes: add R/pi here.
        self.diffuse() * isolux_core::INV_PI + self.specular * self.inner.f(wo, wi).r
    }
    fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        let s = self.inner.sample(wo, uc, u)?;
        Some(BsdfSample {
            f: self.f(wo, s.wi),
            pdf: self.pdf(wo, s.wi),
            ..s
        })
    }
    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        self.inner.pdf(wo, wi)
    }
    fn flags(&self) -> BxdfFlags {
        self.inner.flags()
    }
    fn albedo(&self) -> Rgb {
        self.diffuse() + self.specular
    }
}
