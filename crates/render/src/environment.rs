//! Environment light: radiance arriving from infinitely far away.
//!
//! ## Equirectangular mapping (`+y` up)
//! A direction `d` maps to image coordinates `(u, v)` in `[0, 1)^2` by
//!
//! ```text
//! u = 1/2 + atan2(d.x, -d.z) / (2 pi),   v = acos(d.y) / pi
//! ```
//!
//! so the top row is straight up, the centre of the image lies along `-z`
//! (what the default camera looks at), and `u` grows toward `+x`. Pixels
//! are looked up bilinearly-free (nearest texel), matching the
//! piecewise-constant sampling density exactly.
//!
//! ## Sampling
//! A map is importance-sampled by a 2D piecewise-constant distribution over
//! its texels weighted by luminance times `sin(theta)`; the solid-angle
//! density is `pdf_uv / (2 pi^2 sin(theta))`. A constant environment is
//! *not* light-sampled: it has no features to find, and BSDF sampling alone
//! is optimal (for a Lambertian surface it is noise-free).

use std::sync::Arc;

use isolux_core::{DVec3, Distribution2D, Rgb, PI};

/// Environment radiance.
#[derive(Clone, Debug)]
pub enum Environment {
    /// The same radiance from every direction.
    Constant(Rgb),
    /// An equirectangular radiance map.
    Map(EnvMap),
}

impl Default for Environment {
    fn default() -> Self {
        Environment::Constant(Rgb::BLACK)
    }
}

/// An equirectangular radiance map with its sampling distribution.
///
/// The map keeps the texels as read beside its `scale`, so that
/// [`EnvMap::with_scale`] can set any scale later, 0 included, and the
/// result is exactly the map built with that scale in the first place.
#[derive(Clone, Debug)]
pub struct EnvMap {
    width: usize,
    height: usize,
    /// The texels as read, before `scale` (shared by rescaled copies).
    read: Arc<[Rgb]>,
    scale: f64,
    /// `read` times `scale`: the radiance.
    texels: Vec<Rgb>,
    dist: Distribution2D,
}

impl EnvMap {
    /// Builds a map from row-major linear RGB texels (row 0 at the top),
    /// multiplied by `scale`. Non-finite or negative texels, and a scale
    /// that is negative or not finite, are errors.
    pub fn new(width: usize, height: usize, texels: Vec<Rgb>, scale: f64) -> Result<Self, String> {
        check_scale(scale)?;
        if width == 0 || height == 0 || texels.len() != width * height {
            return Err(format!(
                "environment map has inconsistent size {width} x {height}"
            ));
        }
        if let Some(i) = texels
            .iter()
            .position(|t| !t.is_finite() || t.r < 0.0 || t.g < 0.0 || t.b < 0.0)
        {
            return Err(format!(
                "environment map texel ({}, {}) is negative or not finite",
                i % width,
                i / width
            ));
        }
        Ok(Self::build(width, height, texels.into(), scale))
    }

    /// The map of already checked texels at `scale`.
    fn build(width: usize, height: usize, read: Arc<[Rgb]>, scale: f64) -> Self {
        let texels: Vec<Rgb> = read.iter().map(|&t| t * scale).collect();
        let mut w = vec![0.0; width * height];
        for y in 0..height {
            let sin_t = (PI * (y as f64 + 0.5) / height as f64).sin();
            for x in 0..width {
                w[y * width + x] = texels[y * width + x].luminance().max(0.0) * sin_t;
            }
        }
        Self {
            dist: Distribution2D::new(&w, width, height),
            width,
            height,
            read,
            scale,
            texels,
        }
    }

    /// The same map at another `scale` (finite, not negative), applied to
    /// the texels as read: `isolux view`'s live `scale`. However many
    /// times a map is rescaled, and from whatever scale (0 included), the
    /// result equals [`EnvMap::new`] with the new scale, texel for texel.
    /// The sampling density, proportional to luminance, is the same for
    /// every positive scale.
    pub fn with_scale(&self, scale: f64) -> Result<Self, String> {
        check_scale(scale)?;
        Ok(Self::build(
            self.width,
            self.height,
            self.read.clone(),
            scale,
        ))
    }

    /// The factor on the texels as read (the scene's `environment.scale`).
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// Size in texels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The texels (scaled), row-major, row 0 at the top.
    pub fn texels(&self) -> &[Rgb] {
        &self.texels
    }
}

/// A map's `scale` must be finite and not negative.
fn check_scale(scale: f64) -> Result<(), String> {
    if scale.is_finite() && scale >= 0.0 {
        Ok(())
    } else {
        Err(format!(
            "scale must be finite and non-negative, got {scale}"
        ))
    }
}

/// `(u, v)` of a unit direction.
pub fn dir_to_uv(d: DVec3) -> [f64; 2] {
    let u = 0.5 + d.x.atan2(-d.z) / (2.0 * PI);
    let v = d.y.clamp(-1.0, 1.0).acos() / PI;
    [u.rem_euclid(1.0), v.min(1.0 - 1e-16)]
}

/// Unit direction of `(u, v)`.
pub fn uv_to_dir(uv: [f64; 2]) -> DVec3 {
    let phi = (uv[0] - 0.5) * 2.0 * PI;
    let theta = uv[1] * PI;
    let (st, ct) = theta.sin_cos();
    DVec3::new(st * phi.sin(), ct, -st * phi.cos())
}

/// A light sample from the environment.
#[derive(Clone, Copy, Debug)]
pub struct EnvSample {
    /// Direction toward the environment.
    pub wi: DVec3,
    /// Radiance arriving along `-wi`.
    pub radiance: Rgb,
    /// Solid-angle density.
    pub pdf: f64,
}

impl Environment {
    /// Radiance arriving from direction `d` (pointing away from the scene).
    pub fn eval(&self, d: DVec3) -> Rgb {
        match self {
            Environment::Constant(c) => *c,
            Environment::Map(m) => {
                let [u, v] = dir_to_uv(d);
                let x = ((u * m.width as f64) as usize).min(m.width - 1);
                let y = ((v * m.height as f64) as usize).min(m.height - 1);
                m.texels[y * m.width + x]
            }
        }
    }

    /// Whether the integrator should light-sample this environment.
    pub fn is_sampled(&self) -> bool {
        matches!(self, Environment::Map(_))
    }

    /// Importance-samples a direction (maps only).
    pub fn sample(&self, u: [f64; 2]) -> Option<EnvSample> {
        let Environment::Map(m) = self else {
            return None;
        };
        let (uv, pdf_uv) = m.dist.sample(u);
        let sin_t = (uv[1] * PI).sin();
        if !(pdf_uv > 0.0) || !(sin_t > 0.0) {
            return None;
        }
        let wi = uv_to_dir(uv);
        Some(EnvSample {
            wi,
            radiance: self.eval(wi),
            pdf: pdf_uv / (2.0 * PI * PI * sin_t),
        })
    }

    /// Solid-angle density of [`Environment::sample`] for direction `d`.
    pub fn pdf(&self, d: DVec3) -> f64 {
        let Environment::Map(m) = self else {
            return 0.0;
        };
        let uv = dir_to_uv(d);
        let sin_t = (uv[1] * PI).sin();
        if !(sin_t > 0.0) {
            return 0.0;
        }
        m.dist.pdf(uv) / (2.0 * PI * PI * sin_t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use isolux_core::{sampling, Pcg32};

    #[test]
    fn uv_round_trip() {
        let mut rng = Pcg32::new(1, 0);
        for _ in 0..1000 {
            let d = sampling::uniform_sphere(rng.next_2d());
            assert!((uv_to_dir(dir_to_uv(d)) - d).length() < 1e-9);
        }
        assert!((uv_to_dir([0.5, 0.5]) - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
        assert!(uv_to_dir([0.3, 0.0]).y > 0.999_999);
    }

    /// A rescaled map's radiance is the scale ratio times the original's
    /// in every direction, its sampling density and samples' directions
    /// are the original's, rescaling (through 0 too) gives exactly the map
    /// built with the final scale, and a negative or non-finite scale is
    /// refused.
    #[test]
    fn rescaling_a_map_scales_radiance_and_keeps_the_density() {
        let (w, h) = (12, 6);
        let texels: Vec<Rgb> = (0..w * h)
            .map(|i| Rgb::new(0.1 + i as f64, 0.5, 2.0 + (i % 5) as f64))
            .collect();
        let map = EnvMap::new(w, h, texels.clone(), 0.5).unwrap();
        assert_eq!(map.scale(), 0.5);
        let a = Environment::Map(map.clone());
        let b = Environment::Map(map.with_scale(1.5).unwrap());
        let mut rng = Pcg32::new(9, 1);
        for _ in 0..500 {
            let d = sampling::uniform_sphere(rng.next_2d());
            let (la, lb) = (a.eval(d), b.eval(d));
            for (x, y) in la.to_array().into_iter().zip(lb.to_array()) {
                assert!((y - 3.0 * x).abs() <= 1e-12 * y, "{la:?} {lb:?}");
            }
            assert!((a.pdf(d) - b.pdf(d)).abs() <= 1e-12 * a.pdf(d));
            let u = rng.next_2d();
            let (sa, sb) = (a.sample(u).unwrap(), b.sample(u).unwrap());
            assert!((sa.wi - sb.wi).length() < 1e-12);
        }
        let dark = map.with_scale(0.0).unwrap();
        assert_eq!(dark.scale(), 0.0);
        assert_eq!(Environment::Map(dark.clone()).eval(DVec3::Y), Rgb::BLACK);
        // Through 0 and back, and through a chain of odd factors: the map
        // built at the last scale, texel for texel, density for density.
        let fresh = EnvMap::new(w, h, texels, 0.7).unwrap();
        for back in [
            dark.with_scale(0.7).unwrap(),
            map.with_scale(0.3)
                .and_then(|m| m.with_scale(1.0 / 3.0))
                .and_then(|m| m.with_scale(0.7))
                .unwrap(),
        ] {
            assert_eq!(back.texels(), fresh.texels());
            let (e, f) = (Environment::Map(back), Environment::Map(fresh.clone()));
            for _ in 0..50 {
                let d = sampling::uniform_sphere(rng.next_2d());
                assert_eq!(e.pdf(d), f.pdf(d));
            }
        }
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            let e = map.with_scale(bad).unwrap_err();
            assert!(e.contains("non-negative"), "{e}");
            let e = EnvMap::new(w, h, vec![Rgb::BLACK; w * h], bad).unwrap_err();
            assert!(e.contains("non-negative"), "{e}");
        }
    }

    #[test]
    fn sampling_density_is_consistent_and_unbiased() {
        // A map with one bright band: E[L / pdf] = int L dw, computed exactly.
        let (w, h) = (16, 8);
        let texels: Vec<Rgb> = (0..w * h)
            .map(|i| {
                if (i / w) == 2 {
                    Rgb::splat(10.0)
                } else {
                    Rgb::splat(0.5)
                }
            })
            .collect();
        let env = Environment::Map(EnvMap::new(w, h, texels.clone(), 1.0).unwrap());
        let mut exact = 0.0;
        for y in 0..h {
            let (t0, t1) = (PI * y as f64 / h as f64, PI * (y + 1) as f64 / h as f64);
            let solid = 2.0 * PI * (t0.cos() - t1.cos());
            exact += texels[y * w].r * solid;
        }
        let mut rng = Pcg32::new(3, 3);
        let n = 200_000;
        let mut est = 0.0;
        for _ in 0..n {
            let s = env.sample(rng.next_2d()).unwrap();
            assert!((s.pdf - env.pdf(s.wi)).abs() < 1e-6 * s.pdf);
            est += s.radiance.r / s.pdf;
        }
        est /= n as f64;
        assert!((est - exact).abs() < 0.01 * exact, "{est} vs {exact}");
    }
}
