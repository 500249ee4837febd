//! # Factored BRDF (homomorphic factorization)
//!
//! A BRDF stored as three lookups into two positive textures over the
//! hemisphere, the product of McCool, Ang and Ahmad's homomorphic
//! factorization (written by `isolux factor`, see `docs/factorization.md`):
//!
//! ```text
//! f(wo, wi) = scale * p(wo) * q(h) * p(wi),     h = (wo + wi) / |wo + wi|
//! ```
//!
//! per colour channel, for `wo.z > 0` and `wi.z > 0` (zero otherwise).
//! `p` and `q` are parabolic maps ([`crate::parabolic`]) looked up
//! bilinearly *in the logarithm*, `p(v) = exp(sum_k w_k log p_k)`, the
//! interpolation the least-squares fit solved for, so the material renders
//! exactly the fitted function. Positive by construction and exactly
//! reciprocal (swapping `wo` and `wi` swaps two equal factors).
//!
//! Sampling mixes cosine-weighted directions (probability 1/2) with
//! half-vectors drawn from `q` (a piecewise-constant density over the
//! texels of the map, weighted by each texel's solid angle) reflected
//! about `wo`; the pdf is the mixture's.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `dir` | path | required | directory written by `isolux factor` (`p.exr`, `q.exr`, `factors.toml`), relative to the scene file |
//!
//! Source: M. D. McCool, J. Ang and A. Ahmad, "Homomorphic Factorization
//! of BRDFs for High-Performance Rendering", SIGGRAPH 2001; seed 004;
//! parabolic maps: W. Heidrich and H.-P. Seidel, "View-independent
//! Environment Maps", Graphics Hardware 1998.
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "satin"
//! type = "factored"
//! dir = "factors/satin"
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["dir"].as_str(), Some("factors/satin"));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::microfacet::reflect;
use crate::parabolic::{from_parabolic, solid_angle_jacobian, to_parabolic, ParabolicGrid};
use isolux_core::{sampling, DVec3, Distribution2D, Rgb};
use std::sync::Arc;

/// A factored BRDF: `scale * p(wo) q(h) p(wi)`.
#[derive(Clone)]
pub struct Factored {
    grid: Arc<ParabolicGrid>,
    /// `ln p` per texel (all `res^2` texels, stand-ins included).
    log_p: Arc<Vec<[f64; 3]>>,
    /// `ln q` per texel.
    log_q: Arc<Vec<[f64; 3]>>,
    scale: Rgb,
    /// Half-vector density over the map's `[0, 1)^2` square.
    h_dist: Arc<Distribution2D>,
}

impl std::fmt::Debug for Factored {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Factored")
            .field("res", &self.grid.res())
            .field("scale", &self.scale)
            .finish_non_exhaustive()
    }
}

impl PartialEq for Factored {
    fn eq(&self, o: &Self) -> bool {
        self.scale == o.scale && self.log_p == o.log_p && self.log_q == o.log_q
    }
}

impl Factored {
    /// Builds the material from texel values (`res^2` each, row-major,
    /// row 0 at the top). Every value must be positive and finite; the
    /// values of invalid texels (outside the unit disk) are ignored and
    /// replaced by their stand-ins.
    pub fn new(res: usize, p: &[Rgb], q: &[Rgb], scale: Rgb) -> Result<Self, String> {
        let grid = ParabolicGrid::new(res)?;
        let n = grid.len();
        if p.len() != n || q.len() != n {
            return Err(format!(
                "factor maps must have {res} x {res} texels, got {} and {}",
                p.len(),
                q.len()
            ));
        }
        if !(scale.r > 0.0 && scale.g > 0.0 && scale.b > 0.0 && scale.is_finite()) {
            return Err(format!(
                "scale must be positive and finite, got {:?}",
                scale.to_array()
            ));
        }
        let logs = |m: &[Rgb], name: &str| -> Result<Vec<[f64; 3]>, String> {
            (0..n)
                .map(|i| {
                    let v = m[grid.alias(i)];
                    let a = v.to_array();
                    if a.iter().all(|x| *x > 0.0 && x.is_finite()) {
                        Ok(a.map(f64::ln))
                    } else {
                        let (c, r) = (grid.alias(i) % res, grid.alias(i) / res);
                        Err(format!(
                            "{name} texel (column {c}, row {r}) is {a:?}: factors must be positive and finite"
                        ))
                    }
                })
                .collect()
        };
        let log_p = logs(p, "p")?;
        let log_q = logs(q, "q")?;
        // Sampling density of h: q's luminance times each texel's solid
        // angle, on texels whose centre lies inside the disk.
        let mut func = vec![0.0; n];
        for &i in grid.valid() {
            let i = i as usize;
            let (x, y) = grid.center(i % res, i / res);
            let l = Rgb::from_array(log_q[i].map(f64::exp)).luminance() * scale.luminance();
            func[i] = l * solid_angle_jacobian(x, y);
        }
        let max = func.iter().cloned().fold(0.0, f64::max);
        for v in &mut func {
            *v /= max; // keep the table in a comfortable range
        }
        Ok(Self {
            h_dist: Arc::new(Distribution2D::new(&func, res, res)),
            grid: Arc::new(grid),
            log_p: Arc::new(log_p),
            log_q: Arc::new(log_q),
            scale,
        })
    }

    /// Texels per side.
    pub fn res(&self) -> usize {
        self.grid.res()
    }

    /// `ln p` per texel, row-major, stand-ins substituted (so a texel
    /// outside the disk holds its stand-in's value).
    pub fn log_p_texels(&self) -> &[[f64; 3]] {
        &self.log_p
    }

    /// `ln q` per texel, as [`Factored::log_p_texels`].
    pub fn log_q_texels(&self) -> &[[f64; 3]] {
        &self.log_q
    }

    /// The half-vector sampling density over the map's `[0, 1)^2`.
    pub fn h_distribution(&self) -> &Distribution2D {
        &self.h_dist
    }

    /// The per-channel scale.
    pub fn scale(&self) -> Rgb {
        self.scale
    }

    #[inline]
    fn lookup(&self, map: &[[f64; 3]], v: DVec3) -> [f64; 3] {
        let mut s = [0.0; 3];
        for (i, w) in self.grid.taps(v) {
            let t = map[i as usize];
            for k in 0..3 {
                s[k] += w * t[k];
            }
        }
        s
    }

    /// `ln p(v)` per channel (bilinear in the logarithm).
    pub fn log_p(&self, v: DVec3) -> [f64; 3] {
        self.lookup(&self.log_p, v)
    }

    /// `ln q(v)` per channel.
    pub fn log_q(&self, v: DVec3) -> [f64; 3] {
        self.lookup(&self.log_q, v)
    }

    /// Density of the half-vector strategy for `h` (solid angle of `h`).
    fn pdf_h(&self, h: DVec3) -> f64 {
        if h.z <= 0.0 {
            return 0.0;
        }
        let (x, y) = to_parabolic(h);
        let uv = [
            ((x + 1.0) * 0.5).clamp(0.0, 1.0 - 1e-12),
            ((1.0 - y) * 0.5).clamp(0.0, 1.0 - 1e-12),
        ];
        // du dv = dx dy / 4, and d(omega) = J dx dy.
        self.h_dist.pdf(uv) / 4.0 / solid_angle_jacobian(x, y)
    }
}

impl BxdfModel for Factored {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        let h = (wo + wi).normalize();
        let (a, b, c) = (self.log_p(wo), self.log_q(h), self.log_p(wi));
        let s = self.scale.to_array();
        // `(a + c) + b`: IEEE addition commutes, so swapping wo and wi
        // gives bit-identical values (exact reciprocity).
        Rgb::new(
            s[0] * ((a[0] + c[0]) + b[0]).exp(),
            s[1] * ((a[1] + c[1]) + b[1]).exp(),
            s[2] * ((a[2] + c[2]) + b[2]).exp(),
        )
    }

    fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = if uc < 0.5 {
            sampling::cosine_hemisphere(u)
        } else {
            let (uv, _) = self.h_dist.sample(u);
            let (x, y) = (uv[0] * 2.0 - 1.0, 1.0 - uv[1] * 2.0);
            if x * x + y * y > 1.0 {
                return None;
            }
            let h = from_parabolic(x, y);
            if wo.dot(h) <= 0.0 {
                return None;
            }
            reflect(wo, h)
        };
        BsdfSample::reflected(self, wo, wi, BxdfFlags::GLOSSY)
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let h = (wo + wi).normalize();
        let ph = self.pdf_h(h) / (4.0 * wo.dot(h).abs());
        0.5 * sampling::cosine_hemisphere_pdf(wi.z) + 0.5 * ph
    }

    fn flags(&self) -> BxdfFlags {
        BxdfFlags::REFLECTION | BxdfFlags::GLOSSY
    }

    fn albedo(&self) -> Rgb {
        // f at normal incidence and exitance, times pi: the albedo of a
        // Lambertian surface of the same value, for the albedo AOV.
        (self.f(DVec3::Z, DVec3::Z) * std::f64::consts::PI).map(|v| v.min(1.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_material() -> Factored {
        let res = 8;
        let g = ParabolicGrid::new(res).unwrap();
        let p: Vec<Rgb> = (0..g.len())
            .map(|i| {
                let v = g.texel_direction(g.alias(i));
                Rgb::new(0.5 + v.z, 1.0, 0.2 + v.x.abs())
            })
            .collect();
        let q: Vec<Rgb> = (0..g.len())
            .map(|i| {
                let v = g.texel_direction(g.alias(i));
                Rgb::splat((8.0 * (v.z - 1.0)).exp() + 0.05)
            })
            .collect();
        Factored::new(res, &p, &q, Rgb::new(0.3, 0.2, 0.1)).unwrap()
    }

    #[test]
    fn exactly_reciprocal_and_positive() {
        let m = sample_material();
        let mut rng = isolux_core::Pcg32::new(3, 4);
        for _ in 0..1000 {
            let a = sampling::cosine_hemisphere(rng.next_2d());
            let b = sampling::cosine_hemisphere(rng.next_2d());
            let (x, y) = (m.f(a, b), m.f(b, a));
            assert_eq!(x, y);
            assert!(x.r > 0.0 && x.g > 0.0 && x.b > 0.0);
        }
    }

    #[test]
    fn rejects_bad_texels() {
        let n = 16;
        let ok = vec![Rgb::splat(1.0); n];
        let mut bad = ok.clone();
        bad[5] = Rgb::new(1.0, 0.0, 1.0);
        let e = Factored::new(4, &bad, &ok, Rgb::WHITE).unwrap_err();
        assert!(e.contains("positive"), "{e}");
        assert!(Factored::new(4, &ok, &ok[..3], Rgb::WHITE).is_err());
    }
}
