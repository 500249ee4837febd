//! # Factored BRDF (homomorphic factorization)
//!
//! A BRDF stored as lookups into positive textures, the product of McCool,
//! Ang and Ahmad's homomorphic factorization (written by `isolux factor`,
//! see `docs/factorization.md`):
//!
//! ```text
//! f(wo, wi) = scale * p(wo) * q(h) * p(wi) * r(theta_h, theta_d)
//!
//! h = (wo + wi) / |wo + wi|,  cos theta_h = h.z,  cos theta_d = |wo + wi| / 2
//! ```
//!
//! per colour channel, for `wo.z > 0` and `wi.z > 0` (zero otherwise).
//! `p` and `q` are parabolic maps ([`crate::parabolic`]); `r` is an
//! optional `n x n` table over the half and difference angles (one of the
//! "other projections" of the paper's eq. 4; without it `r = 1`, the
//! paper's `p q p`). Every lookup interpolates bilinearly *in the
//! logarithm*, `p(v) = exp(sum_k w_k log p_k)`, the interpolation the
//! least-squares fit solved for, so the material renders exactly the
//! fitted function. Positive by construction and exactly reciprocal
//! (swapping `wo` and `wi` swaps two equal factors and leaves `h`,
//! `theta_h` and `theta_d` unchanged).
//!
//! Sampling mixes cosine-weighted directions (probability 1/2) with
//! half-vectors drawn from `q(h)` times the mean of `r` over `theta_d` at
//! the texel's `theta_h` (a piecewise-constant density over the texels of
//! the map, weighted by each texel's solid angle) reflected about `wo`;
//! the pdf is the mixture's.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `dir` | path | required | directory written by `isolux factor` (`p.exr`, `q.exr`, `factors.toml`, and `r.exr` when `hd_res > 0`), relative to the scene file |
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
    /// `ln r` per texel of the optional angle factor `r(theta_h, theta_d)`
    /// (empty: no such factor, `r = 1`).
    log_r: Arc<Vec<[f64; 3]>>,
    r_res: usize,
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
        self.scale == o.scale
            && self.log_p == o.log_p
            && self.log_q == o.log_q
            && self.log_r == o.log_r
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
        let mut m = Self {
            h_dist: Arc::new(Distribution2D::new(&[1.0], 1, 1)),
            grid: Arc::new(grid),
            log_p: Arc::new(log_p),
            log_q: Arc::new(log_q),
            log_r: Arc::new(Vec::new()),
            r_res: 0,
            scale,
        };
        m.build_h_distribution();
        Ok(m)
    }

    /// The half-vector sampling density: `q`'s luminance times the mean of
    /// `r` over `theta_d` at the texel's `theta_h`, times each texel's
    /// solid angle, on texels whose centre lies inside the disk.
    fn build_h_distribution(&mut self) {
        let (grid, res) = (&self.grid, self.grid.res());
        let mut func = vec![0.0; grid.len()];
        for &i in grid.valid() {
            let i = i as usize;
            let (x, y) = grid.center(i % res, i / res);
            let mut l =
                Rgb::from_array(self.log_q[i].map(f64::exp)).luminance() * self.scale.luminance();
            if self.r_res > 0 {
                let n = self.r_res;
                let h = from_parabolic(x, y);
                let (k0, k1, t) = angle_axis(n, h.z.clamp(-1.0, 1.0).acos());
                let row_mean = |k: u32| {
                    let row = &self.log_r[k as usize * n..(k as usize + 1) * n];
                    row.iter()
                        .map(|v| Rgb::from_array(v.map(f64::exp)).luminance())
                        .sum::<f64>()
                        / n as f64
                };
                l *= (1.0 - t) * row_mean(k0) + t * row_mean(k1);
            }
            func[i] = l * solid_angle_jacobian(x, y);
        }
        let max = func.iter().cloned().fold(0.0, f64::max);
        for v in &mut func {
            *v /= max; // keep the table in a comfortable range
        }
        self.h_dist = Arc::new(Distribution2D::new(&func, res, res));
    }

    /// Adds the angle factor `r(theta_h, theta_d)`: an `n x n` table
    /// (row `k`: `theta_h`, column `l`: `theta_d`, texel centred at `((k +
    /// 1/2), (l + 1/2)) 90 / n` degrees, row-major), looked up bilinearly
    /// in the logarithm and clamped at the edges. `n` must lie in
    /// `2..=512`; every value must be positive and finite.
    pub fn with_hd(mut self, n: usize, r: &[Rgb]) -> Result<Self, String> {
        if !(2..=512).contains(&n) || r.len() != n * n {
            return Err(format!(
                "the r(theta_h, theta_d) factor needs n x n texels with n in 2..=512, got n = {n} and {} texels",
                r.len()
            ));
        }
        let logs: Result<Vec<[f64; 3]>, String> = r
            .iter()
            .enumerate()
            .map(|(k, v)| {
                let a = v.to_array();
                if a.iter().all(|x| *x > 0.0 && x.is_finite()) {
                    Ok(a.map(f64::ln))
                } else {
                    Err(format!(
                        "r texel (column {}, row {}) is {a:?}: factors must be positive and finite",
                        k % n,
                        k / n
                    ))
                }
            })
            .collect();
        self.log_r = Arc::new(logs?);
        self.r_res = n;
        self.build_h_distribution();
        Ok(self)
    }

    /// `ln r` per texel, row-major (empty when the material has no `r`
    /// factor).
    pub fn log_r_texels(&self) -> &[[f64; 3]] {
        &self.log_r
    }

    /// Texels per side of the `r` table (0: none).
    pub fn r_res(&self) -> usize {
        self.r_res
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

    /// `ln r(theta_h, theta_d)` per channel for the pair `(wo, wi)` (zero
    /// without an `r` factor).
    pub fn log_r(&self, wo: DVec3, wi: DVec3) -> [f64; 3] {
        let mut out = [0.0; 3];
        if self.log_r.is_empty() {
            return out;
        }
        for (i, w) in hd_taps(self.r_res, wo, wi) {
            let t = self.log_r[i as usize];
            for k in 0..3 {
                out[k] += w * t[k];
            }
        }
        out
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
        let d = self.log_r(wo, wi);
        let s = self.scale.to_array();
        // `((a + c) + b) + d`: IEEE addition commutes and both angles of
        // `r` are computed from `wo + wi`, so swapping wo and wi gives
        // bit-identical values (exact reciprocity).
        Rgb::new(
            s[0] * (((a[0] + c[0]) + b[0]) + d[0]).exp(),
            s[1] * (((a[1] + c[1]) + b[1]) + d[1]).exp(),
            s[2] * (((a[2] + c[2]) + b[2]) + d[2]).exp(),
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

/// The difference angle `theta_d` of a direction pair in radians, from
/// `|wo + wi| = 2 cos(theta_d)` (symmetric in its arguments, bit for bit).
#[inline]
pub fn theta_d(wo: DVec3, wi: DVec3) -> f64 {
    (0.5 * (wo + wi).length()).min(1.0).acos()
}

/// One linear-interpolation axis of an `n`-texel table over `[0, pi/2]`
/// (texel `k` centred at `(k + 1/2) (pi/2) / n`, clamped at both ends):
/// `(i0, i1, weight of i1)`.
#[inline]
fn angle_axis(n: usize, angle: f64) -> (u32, u32, f64) {
    let u = (angle / std::f64::consts::FRAC_PI_2 * n as f64 - 0.5).clamp(0.0, (n - 1) as f64);
    let i0 = (u.floor() as usize).min(n.saturating_sub(2));
    (i0 as u32, (i0 + 1).min(n - 1) as u32, u - i0 as f64)
}

/// The four bilinear taps `(texel, weight)` of the `n x n` table of the
/// `r(theta_h, theta_d)` factor: row `theta_h`, column `theta_d`, texel
/// `(k, l)` centred at `((k + 1/2), (l + 1/2)) (pi/2) / n`, index `k n + l`.
#[inline]
pub fn hd_taps(n: usize, wo: DVec3, wi: DVec3) -> [(u32, f64); 4] {
    let h = (wo + wi).normalize();
    let (h0, h1, th) = angle_axis(n, h.z.clamp(-1.0, 1.0).acos());
    let (d0, d1, td) = angle_axis(n, theta_d(wo, wi));
    let n = n as u32;
    [
        (h0 * n + d0, (1.0 - th) * (1.0 - td)),
        (h0 * n + d1, (1.0 - th) * td),
        (h1 * n + d0, th * (1.0 - td)),
        (h1 * n + d1, th * td),
    ]
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
