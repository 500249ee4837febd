//! The wave-optics BRDF of a heightfield through Gabor kernels (SPEC §3;
//! Yan, Hasan, Walter, Marschner, Ramamoorthi, SIGGRAPH 2018).
//!
//! # The formula
//! With `psi = (wi + wo)_xy`, `kappa = 1 / lambda` and `c3` the model's
//! phase factor (`ghs`: `cos_i + cos_o`, `ohs`: 2), the reflection function
//! `r(s) = exp(-i 2 pi c3 kappa h(s))` windowed by the coherence area
//! `w(s) = exp(-|s - x_c|^2 / (2 sigma^2))` gives
//!
//! ```text
//! f(wi, wo) = F O kappa^2 / A_c |I(psi kappa)|^2,   A_c = integral w^2 = pi sigma^2
//! ```
//!
//! with the obliquity factor `O` ([`Obliquity`]): 1 by default
//! (`reciprocal`), or the seed's `cos_o / cos_i` (`seed`, SPEC §3).
//!
//! # Why the default obliquity is 1
//! Since `d^2 u = kappa^2 cos_o dw_o`, the directional albedo is
//! `integral F O |I(u)|^2 / A_c d^2u` over the outgoing disk. With `O = 1`
//! Parseval bounds it: `integral |I|^2 d^2u = integral w^2 |r|^2 = A_c`, so
//! the albedo is at most `F` (less where orders go evanescent), and
//! `f(wi, wo) = f(wo, wi)` (`psi` and `c3` are symmetric). The seed's
//! `O = cos_o / cos_i` is neither: where light is diffracted toward the
//! normal from grazing incidence (`cos_o > cos_i`) it returns more than it
//! receives (a grating: 1.006 at 60 degrees, 1.19 at 75 degrees). Both are
//! scalar approximations; against first-order perturbation theory for a
//! shallow perfectly conducting sinusoid (unpolarized), at 75 degrees
//! incidence and an order at 45.6 degrees the seed's factor overestimates
//! the order's efficiency by 1.7x and `O = 1` underestimates it by 1.5x, and
//! at normal incidence the two differ only by `cos_o` (1 at the specular
//! peak). `O = 1` is the one that keeps energy and reciprocity, so it is
//! the default; `obliquity = "seed"` keeps SPEC §3 verbatim.
//!
//! Each texel `k` (centre `c_k`, size `l`) becomes a Gabor kernel of width
//! `zeta = l/2` from its height `h_k` and slope `g_k` (central
//! differences): `r_k(s) = l^2 G(s; c_k, zeta) exp(-i 2 pi c3 kappa (h_k + g_k.(s - c_k)))`.
//! With the (corrected, SPEC §3) Fourier transform of a Gabor kernel the
//! phases `g_k.c_k` cancel and
//!
//! ```text
//! I(psi kappa) = l^2 sum_k w_k exp(-B_k kappa^2) exp(-i Theta_k kappa),
//! B_k = 2 pi^2 zeta^2 |psi + c3 g_k|^2,   Theta_k = 2 pi (c3 h_k + (c_k - x_c).psi)
//! ```
//!
//! (a global phase `x_c.psi` is dropped: only `|I|` matters). `F` is
//! applied by the caller ([`crate`] docs).
//!
//! # Which kernels are summed
//! A kernel's amplitude relative to a centred, aligned one is
//! `a_k = w_k exp(-B_k kappa_min^2)`, with `kappa_min` the smallest
//! wavenumber of the query. The sum keeps exactly the kernels with
//! `a_k >= eps` (default `eps = exp(-4.5)`, the window's value at 3 sigma)
//! inside the square `|c_k - x_c|_inf <= sigma sqrt(2 ln(1/eps))`.
//! The quadtree skips a node only when the bound
//! `max w over its position box * exp(-kappa_min^2 min B over its slope box)`
//! is below `eps`, so every kernel under it fails the test anyway: the
//! result is the same with the hierarchy on or off (tested). Dropped
//! kernels each contribute under `eps l^2` to `I`; the window's tail beyond
//! the square holds `2 erfc(sqrt(ln(1/eps)))` of its mass (0.5% at the
//! default).
//!
//! # Importance sampling
//! Given one direction `d`, a kernel is drawn with probability
//! proportional to `w_k^2` (separable: a row, then a column), then
//! `u = psi kappa` from a Gaussian of mean `-c3' kappa g_k`, where
//! `c3' = c3(d.z, d.z)` (the specular guess; the pdf uses the same value,
//! so the estimator stays exact). Its standard deviation per axis is,
//! with probability 1/4, that of the kernel's own lobe `|FT|^2`,
//! `1 / (2 sqrt(2) pi zeta)` (wide: a texel is small), or, with
//! probability 3/4, that of the coherence window's,
//! `1 / (2 sqrt(2) pi sigma)` (narrow: where the coherent sum concentrates
//! on smooth surfaces). The other direction is `u / kappa - d_xy`; outside
//! the unit disk the sample fails. Its solid-angle pdf is
//! `p_u(u) kappa^2 cos`.

use crate::fastmath::{cis_neg, exp_neg};
use crate::heightfield::Heightfield;
use crate::spectral::Comb;
use glam::DVec3;
use std::f64::consts::PI;

/// Scalar diffraction model (SPEC §3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Model {
    /// Generalized Harvey-Shack: `c3 = cos_i + cos_o` (the seed's choice).
    #[default]
    Ghs,
    /// Original Harvey-Shack: `c3 = 2`.
    Ohs,
}

impl Model {
    /// Parses `ghs` or `ohs`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "ghs" => Some(Self::Ghs),
            "ohs" => Some(Self::Ohs),
            _ => None,
        }
    }

    /// The phase factor `c3`.
    pub fn c3(self, cos_i: f64, cos_o: f64) -> f64 {
        match self {
            Self::Ghs => cos_i + cos_o,
            Self::Ohs => 2.0,
        }
    }
}

/// Default culling threshold: the window's value at 3 sigma.
pub const DEFAULT_EPS: f64 = 0.011_108_996_538_242_306; // exp(-4.5)

/// The obliquity factor `O` of the BRDF (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Obliquity {
    /// `O = 1`: reciprocal, directional albedo at most 1 (Parseval).
    #[default]
    Reciprocal,
    /// `O = cos_o / cos_i`: the seed's eq. 4-5 factor (SPEC §3); the
    /// albedo exceeds 1 at grazing incidence.
    Seed,
}

impl Obliquity {
    /// Parses `reciprocal` or `seed`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "reciprocal" => Some(Self::Reciprocal),
            "seed" => Some(Self::Seed),
            _ => None,
        }
    }

    /// The factor for these cosines (both positive).
    pub fn factor(self, cos_i: f64, cos_o: f64) -> f64 {
        match self {
            Self::Reciprocal => 1.0,
            Self::Seed => cos_o / cos_i,
        }
    }
}

/// The coherence area of a query: a Gaussian of standard deviation
/// `sigma_um` centred at `center_um`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// Centre (um) in heightfield coordinates.
    pub center_um: [f64; 2],
    /// Standard deviation (um).
    pub sigma_um: f64,
}

/// The obliquity factor, and accuracy and acceleration settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Relative amplitude under which a kernel is dropped (see module docs).
    pub eps: f64,
    /// Use the quadtree (off: visit every kernel of the window square).
    pub hierarchy: bool,
    /// The BRDF's obliquity factor.
    pub obliquity: Obliquity,
}

impl Settings {
    /// The half side of a query's window square for a coherence area of
    /// standard deviation `sigma_um`: `sigma sqrt(2 ln(1 / eps))` (module
    /// docs), where the window's weight falls to `eps`.
    pub fn window_radius(&self, sigma_um: f64) -> f64 {
        sigma_um * (2.0 * (1.0 / self.eps).ln()).max(0.0).sqrt()
    }
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            eps: DEFAULT_EPS,
            hierarchy: true,
            obliquity: Obliquity::default(),
        }
    }
}

/// Probability of the wide (single-kernel) sampling lobe; the narrow
/// (coherence-window) lobe takes the rest.
pub const WIDE_LOBE: f64 = 0.25;

/// Kernels per chunk (and accumulator lanes) of the spectral loop.
const COMB_CHUNK: usize = 32;

/// Texels per side of a quadtree leaf.
pub const LEAF: usize = 16;

/// One level of the quadtree: slope boxes `[gx_min, gx_max, gy_min,
/// gy_max]` of `LEAF 2^level`-texel blocks.
#[derive(Clone, Debug)]
struct Level {
    nx: usize,
    ny: usize,
    boxes: Vec<[f32; 4]>,
}

/// A heightfield turned into Gabor kernels, with its quadtree.
#[derive(Clone, Debug)]
pub struct GaborSurface {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Texel size (um).
    pub texel_um: f64,
    h: Vec<f32>,
    gx: Vec<f32>,
    gy: Vec<f32>,
    levels: Vec<Level>,
}

/// A texel rectangle inside one period, and the period's offset.
#[derive(Clone, Copy, Debug)]
struct Piece {
    c: (usize, usize),
    r: (usize, usize),
    /// Unwrapped index of local column/row 0.
    off: (i64, i64),
}

/// Per-query window tables.
struct Window {
    i0: i64,
    j0: i64,
    wx: Vec<f32>,
    wy: Vec<f64>,
    pieces: Vec<Piece>,
}

impl GaborSurface {
    /// Builds the kernels (slopes by periodic central differences) and the
    /// quadtree; parallel over rows.
    pub fn new(field: Heightfield) -> Self {
        use rayon::prelude::*;
        let (w, hgt) = (field.width, field.height);
        let l = field.texel_um as f32;
        let h = field.heights;
        let mut gx = vec![0.0f32; w * hgt];
        let mut gy = vec![0.0f32; w * hgt];
        gx.par_chunks_mut(w)
            .zip(gy.par_chunks_mut(w))
            .enumerate()
            .for_each(|(r, (rx, ry))| {
                let up = (r + hgt - 1) % hgt;
                let dn = (r + 1) % hgt;
                for c in 0..w {
                    let (cl, cr) = ((c + w - 1) % w, (c + 1) % w);
                    rx[c] = (h[r * w + cr] - h[r * w + cl]) / (2.0 * l);
                    ry[c] = (h[dn * w + c] - h[up * w + c]) / (2.0 * l);
                }
            });
        // Leaf level.
        let (nx, ny) = (w.div_ceil(LEAF), hgt.div_ceil(LEAF));
        let boxes: Vec<[f32; 4]> = (0..nx * ny)
            .into_par_iter()
            .map(|b| {
                let (bx, by) = (b % nx, b / nx);
                let mut bb = [
                    f32::INFINITY,
                    f32::NEG_INFINITY,
                    f32::INFINITY,
                    f32::NEG_INFINITY,
                ];
                for r in by * LEAF..((by + 1) * LEAF).min(hgt) {
                    for c in bx * LEAF..((bx + 1) * LEAF).min(w) {
                        let (x, y) = (gx[r * w + c], gy[r * w + c]);
                        bb = [bb[0].min(x), bb[1].max(x), bb[2].min(y), bb[3].max(y)];
                    }
                }
                bb
            })
            .collect();
        let mut levels = vec![Level { nx, ny, boxes }];
        while levels.last().is_some_and(|l| l.nx > 1 || l.ny > 1) {
            let prev = levels.last().unwrap();
            let (nx, ny) = (prev.nx.div_ceil(2), prev.ny.div_ceil(2));
            let mut boxes = vec![
                [
                    f32::INFINITY,
                    f32::NEG_INFINITY,
                    f32::INFINITY,
                    f32::NEG_INFINITY
                ];
                nx * ny
            ];
            for by in 0..prev.ny {
                for bx in 0..prev.nx {
                    let c = prev.boxes[by * prev.nx + bx];
                    let p = &mut boxes[(by / 2) * nx + bx / 2];
                    *p = [
                        p[0].min(c[0]),
                        p[1].max(c[1]),
                        p[2].min(c[2]),
                        p[3].max(c[3]),
                    ];
                }
            }
            levels.push(Level { nx, ny, boxes });
        }
        Self {
            width: w,
            height: hgt,
            texel_um: field.texel_um,
            h,
            gx,
            gy,
            levels,
        }
    }

    /// Height (um) and slope of kernel `(c, r)` (wrapped).
    pub fn kernel(&self, c: i64, r: i64) -> (f32, f32, f32) {
        let c = c.rem_euclid(self.width as i64) as usize;
        let r = r.rem_euclid(self.height as i64) as usize;
        let i = r * self.width + c;
        (self.h[i], self.gx[i], self.gy[i])
    }

    /// The RMS of the slope `|grad h|` over the field (dimensionless).
    pub fn rms_slope(&self) -> f64 {
        let sum: f64 = self
            .gx
            .iter()
            .zip(&self.gy)
            .map(|(&x, &y)| (x as f64).powi(2) + (y as f64).powi(2))
            .sum();
        (sum / self.gx.len().max(1) as f64).sqrt()
    }

    /// Heights (um) and slopes `x`, `y` of every kernel, row-major (the
    /// GPU's copy is made from these).
    pub fn kernels(&self) -> (&[f32], &[f32], &[f32]) {
        (&self.h, &self.gx, &self.gy)
    }

    /// The quadtree's leaf level: columns and rows of [`LEAF`]-texel
    /// blocks and each block's slope box `[gx_min, gx_max, gy_min,
    /// gy_max]`, row-major.
    pub fn leaf_boxes(&self) -> (usize, usize, &[[f32; 4]]) {
        let l = &self.levels[0];
        (l.nx, l.ny, &l.boxes)
    }

    /// Bytes held by the kernels and the tree.
    pub fn memory_bytes(&self) -> usize {
        12 * self.h.len()
            + self
                .levels
                .iter()
                .map(|l| 16 * l.boxes.len())
                .sum::<usize>()
    }

    /// Number of kernels in the window square of a footprint.
    pub fn window_kernels(&self, fp: &Footprint, set: &Settings) -> usize {
        let w = self.window(&self.wrapped(fp), set);
        w.wx.len() * w.wy.len()
    }

    /// `fp` with its centre moved by whole periods into the first one.
    /// The field repeats, and every kernel's term depends on its offset
    /// from the centre only, so the sums are the same; but a centre far
    /// out (1e33 um, from a mapping centred 1e30 units away) has an f64
    /// spacing wider than the window, whose ends then rounded apart by
    /// about 3e17 texels: a window that no memory held.
    fn wrapped(&self, fp: &Footprint) -> Footprint {
        let period = [
            self.width as f64 * self.texel_um,
            self.height as f64 * self.texel_um,
        ];
        let c = [0, 1].map(|a| {
            let c = fp.center_um[a].rem_euclid(period[a]);
            // rem_euclid may round up to the period itself.
            if c < period[a] && c.is_finite() {
                c
            } else {
                0.0
            }
        });
        Footprint {
            center_um: c,
            sigma_um: fp.sigma_um,
        }
    }

    fn window(&self, fp: &Footprint, set: &Settings) -> Window {
        let l = self.texel_um;
        let s = fp.sigma_um;
        let r = set.window_radius(s);
        let span = |c: f64| {
            let a = ((c - r) / l - 0.5).ceil() as i64;
            let b = ((c + r) / l - 0.5).floor() as i64;
            (a, b.max(a))
        };
        let (i0, i1) = span(fp.center_um[0]);
        let (j0, j1) = span(fp.center_um[1]);
        let g = |i: i64, c: f64| {
            let d = (i as f64 + 0.5) * l - c;
            (-d * d / (2.0 * s * s)).exp()
        };
        let wx = (i0..=i1).map(|i| g(i, fp.center_um[0]) as f32).collect();
        let wy = (j0..=j1).map(|j| g(j, fp.center_um[1])).collect();
        let segs = |a: i64, b: i64, n: usize| {
            let n = n as i64;
            let mut v = Vec::new();
            let mut x = a;
            while x <= b {
                let t = x.div_euclid(n);
                let end = ((t + 1) * n - 1).min(b);
                v.push(((x - t * n) as usize, (end - t * n + 1) as usize, t * n));
                x = end + 1;
            }
            v
        };
        let mut pieces = Vec::new();
        for &(ra, rb, oy) in &segs(j0, j1, self.height) {
            for &(ca, cb, ox) in &segs(i0, i1, self.width) {
                pieces.push(Piece {
                    c: (ca, cb),
                    r: (ra, rb),
                    off: (ox, oy),
                });
            }
        }
        Window {
            i0,
            j0,
            wx,
            wy,
            pieces,
        }
    }

    /// `f(wi, wo)` without Fresnel for every wavelength of `comb`, into
    /// `out` (1/sr). Directions are in the heightfield's frame (z up); zero
    /// when either is below the surface.
    #[allow(clippy::too_many_arguments)]
    pub fn eval(
        &self,
        fp: &Footprint,
        model: Model,
        wi: DVec3,
        wo: DVec3,
        comb: &Comb,
        set: &Settings,
        out: &mut [f64],
    ) {
        out.iter_mut().for_each(|v| *v = 0.0);
        if !(wi.z > 0.0 && wo.z > 0.0 && fp.sigma_um > 0.0) {
            return;
        }
        let fp = &self.wrapped(fp);
        let c3 = model.c3(wi.z, wo.z);
        let psi = [wi.x + wo.x, wi.y + wo.y];
        let win = self.window(fp, set);
        let l = self.texel_um;
        let ex = if comb.n == 1 {
            (0..win.wx.len())
                .map(|k| {
                    let x = (win.i0 + k as i64) as f64 * l + 0.5 * l - fp.center_um[0];
                    let (s, c) = (2.0 * PI * comb.k0 * x * psi[0]).sin_cos();
                    (c as f32, -s as f32)
                })
                .unzip()
        } else {
            (Vec::new(), Vec::new())
        };
        let q = Query {
            s: self,
            win: &win,
            fp,
            c3,
            psi,
            kmin: comb.k0,
            eps: set.eps,
            a0: 2.0 * PI * PI * (0.5 * l).powi(2),
            radius: set.window_radius(fp.sigma_um),
            ex,
        };
        let mut acc = vec![(0.0f64, 0.0f64); comb.n];
        if comb.n == 1 {
            q.run(set.hierarchy, &mut |p, r, ca, cb| {
                q.row_single(p, r, ca, cb, comb.k0, &mut acc[0])
            });
        } else {
            let mut lanes = vec![[0.0f32; COMB_CHUNK]; 2 * comb.n];
            q.run(set.hierarchy, &mut |p, r, ca, cb| {
                q.row_comb(p, r, ca, cb, comb, &mut lanes)
            });
            for (j, a) in acc.iter_mut().enumerate() {
                a.0 = lanes[2 * j].iter().map(|&v| v as f64).sum();
                a.1 = lanes[2 * j + 1].iter().map(|&v| v as f64).sum();
            }
        }
        let l2 = self.texel_um * self.texel_um;
        let ac = PI * fp.sigma_um * fp.sigma_um;
        let o = set.obliquity.factor(wi.z, wo.z);
        for (j, (re, im)) in acc.iter().enumerate() {
            let k = comb.k0 + j as f64 * comb.dk;
            out[j] = k * k * o * l2 * l2 * (re * re + im * im) / ac;
        }
    }

    /// Single-wavelength convenience: `f(wi, wo)` without Fresnel.
    pub fn eval_single(
        &self,
        fp: &Footprint,
        model: Model,
        wi: DVec3,
        wo: DVec3,
        lambda_um: f64,
        set: &Settings,
    ) -> f64 {
        let mut out = [0.0];
        self.eval(fp, model, wi, wo, &Comb::single(lambda_um), set, &mut out);
        out[0]
    }

    /// Per-axis standard deviations in `u` (1/um) of the two proposal
    /// lobes: one kernel's, and the coherence window's.
    fn lobe_sigmas(&self, fp: &Footprint) -> [f64; 2] {
        let k = 1.0 / (2.0 * 2f64.sqrt() * PI);
        [k / (0.5 * self.texel_um), k / fp.sigma_um]
    }

    /// Samples the direction paired with `given` (see module docs) at
    /// wavenumber `kappa` (1/um).
    #[allow(clippy::too_many_arguments)]
    pub fn sample(
        &self,
        fp: &Footprint,
        model: Model,
        given: DVec3,
        kappa: f64,
        set: &Settings,
        u_kernel: [f64; 2],
        u_lobe: [f64; 2],
    ) -> Option<DVec3> {
        if !(given.z > 0.0) || !(fp.sigma_um > 0.0) {
            return None;
        }
        let fp = &self.wrapped(fp);
        let win = self.window(fp, set);
        let pick = |w: &mut dyn Iterator<Item = f64>, u: f64| -> usize {
            let v: Vec<f64> = w.collect();
            let total: f64 = v.iter().sum();
            let mut t = u * total;
            for (i, x) in v.iter().enumerate() {
                if t < *x {
                    return i;
                }
                t -= x;
            }
            v.len() - 1
        };
        let jy = pick(&mut win.wy.iter().map(|w| w * w), u_kernel[1]);
        let ix = pick(
            &mut win.wx.iter().map(|&w| (w as f64) * (w as f64)),
            u_kernel[0],
        );
        let (_, gx, gy) = self.kernel(win.i0 + ix as i64, win.j0 + jy as i64);
        let c3 = model.c3(given.z, given.z);
        // One uniform picks the lobe and, rescaled, the radius.
        let sig = self.lobe_sigmas(fp);
        let (s, ur) = if u_lobe[0] < WIDE_LOBE {
            (sig[0], u_lobe[0] / WIDE_LOBE)
        } else {
            (sig[1], (u_lobe[0] - WIDE_LOBE) / (1.0 - WIDE_LOBE))
        };
        let r = (-2.0 * (1.0 - ur).ln()).sqrt() * s;
        let (sn, cs) = (2.0 * PI * u_lobe[1]).sin_cos();
        let ux = -c3 * kappa * gx as f64 + r * cs;
        let uy = -c3 * kappa * gy as f64 + r * sn;
        let x = ux / kappa - given.x;
        let y = uy / kappa - given.y;
        let r2 = x * x + y * y;
        if r2 >= 1.0 {
            return None;
        }
        Some(DVec3::new(x, y, (1.0 - r2).sqrt()))
    }

    /// Solid-angle density of [`Self::sample`] for `sampled` given `given`.
    pub fn pdf(
        &self,
        fp: &Footprint,
        model: Model,
        given: DVec3,
        sampled: DVec3,
        kappa: f64,
        set: &Settings,
    ) -> f64 {
        if !(given.z > 0.0 && sampled.z > 0.0 && fp.sigma_um > 0.0) {
            return 0.0;
        }
        let fp = &self.wrapped(fp);
        let win = self.window(fp, set);
        let c3 = model.c3(given.z, given.z);
        let [sa, sb] = self.lobe_sigmas(fp);
        let ux = ((given.x + sampled.x) * kappa) as f32;
        let uy = ((given.y + sampled.y) * kappa) as f32;
        let m = (c3 * kappa) as f32;
        let (ia, ib2) = (
            (1.0 / (2.0 * sa * sa)) as f32,
            (1.0 / (2.0 * sb * sb)) as f32,
        );
        // Mixture weights folded with the Gaussians' normalizations.
        let (na, nb) = (
            (WIDE_LOBE / (2.0 * PI * sa * sa)) as f32,
            ((1.0 - WIDE_LOBE) / (2.0 * PI * sb * sb)) as f32,
        );
        let sx: f64 = win.wx.iter().map(|&w| (w as f64).powi(2)).sum();
        let sy: f64 = win.wy.iter().map(|w| w * w).sum();
        let mut total = 0.0f64;
        for p in &win.pieces {
            for r in p.r.0..p.r.1 {
                let jj = (r as i64 + p.off.1 - win.j0) as usize;
                let base = r * self.width;
                let ib = (p.c.0 as i64 + p.off.0 - win.i0) as usize;
                let (gxs, gys) = (
                    &self.gx[base + p.c.0..base + p.c.1],
                    &self.gy[base + p.c.0..base + p.c.1],
                );
                let wx = &win.wx[ib..ib + gxs.len()];
                let mut row = 0.0f32;
                for t in 0..gxs.len() {
                    let dx = ux + m * gxs[t];
                    let dy = uy + m * gys[t];
                    let d2 = dx * dx + dy * dy;
                    row += wx[t] * wx[t] * (na * exp_neg(d2 * ia) + nb * exp_neg(d2 * ib2));
                }
                total += row as f64 * win.wy[jj] * win.wy[jj];
            }
        }
        let pu = total / (sx * sy);
        pu * kappa * kappa * sampled.z
    }
}

/// Shared state of one evaluation.
struct Query<'a> {
    s: &'a GaborSurface,
    win: &'a Window,
    fp: &'a Footprint,
    c3: f64,
    psi: [f64; 2],
    kmin: f64,
    eps: f64,
    a0: f64,
    /// Radius of the window's disk (um).
    radius: f64,
    /// Column phase factors `exp(-i 2 pi kappa (x - cx) psi_x)` (single
    /// wavelength only).
    ex: (Vec<f32>, Vec<f32>),
}

impl Query<'_> {
    /// Visits every row segment that may hold accepted kernels.
    fn run(&self, hierarchy: bool, row: &mut dyn FnMut(&Piece, usize, usize, usize)) {
        for p in &self.win.pieces {
            if hierarchy {
                // Accepted leaves, then runs of them merged along rows so
                // that the kernel loops stay long.
                let top = self.s.levels.len() - 1;
                let lv = &self.s.levels[top];
                let mut leaves = Vec::new();
                for by in 0..lv.ny {
                    for bx in 0..lv.nx {
                        self.visit(p, top, bx, by, &mut leaves);
                    }
                }
                leaves.sort_unstable_by_key(|l: &[usize; 4]| (l[2], l[0]));
                let mut k = 0;
                while k < leaves.len() {
                    let [ca, mut cb, ra, rb] = leaves[k];
                    k += 1;
                    while k < leaves.len() && leaves[k][2] == ra && leaves[k][0] == cb {
                        cb = leaves[k][1];
                        k += 1;
                    }
                    for r in ra..rb {
                        row(p, r, ca, cb);
                    }
                }
            } else {
                for r in p.r.0..p.r.1 {
                    row(p, r, p.c.0, p.c.1);
                }
            }
        }
    }

    /// Collects the leaves under node `(bx, by)` of `level` that may hold
    /// accepted kernels, as `[ca, cb, ra, rb]` texel ranges.
    fn visit(&self, p: &Piece, level: usize, bx: usize, by: usize, out: &mut Vec<[usize; 4]>) {
        let size = LEAF << level;
        let ca = (bx * size).max(p.c.0);
        let cb = ((bx + 1) * size).min(p.c.1).min(self.s.width);
        let ra = (by * size).max(p.r.0);
        let rb = ((by + 1) * size).min(p.r.1).min(self.s.height);
        if ca >= cb || ra >= rb {
            return;
        }
        let lv = &self.s.levels[level];
        if bx >= lv.nx || by >= lv.ny {
            return;
        }
        // Bound on every kernel's amplitude under the node.
        let l = self.s.texel_um;
        let near = |a: usize, b: usize, off: i64, c: f64| {
            let lo = (a as i64 + off) as f64 * l + 0.5 * l;
            let hi = (b as i64 - 1 + off) as f64 * l + 0.5 * l;
            (lo - c).max(c - hi).max(0.0)
        };
        let dx = near(ca, cb, p.off.0, self.fp.center_um[0]);
        let dy = near(ra, rb, p.off.1, self.fp.center_um[1]);
        let s = self.fp.sigma_um;
        let bb = lv.boxes[by * lv.nx + bx];
        let gx = (-self.psi[0] / self.c3).clamp(bb[0] as f64, bb[1] as f64);
        let gy = (-self.psi[1] / self.c3).clamp(bb[2] as f64, bb[3] as f64);
        let bmin =
            self.a0 * ((self.psi[0] + self.c3 * gx).powi(2) + (self.psi[1] + self.c3 * gy).powi(2));
        let log_bound = -(dx * dx + dy * dy) / (2.0 * s * s) - bmin * self.kmin * self.kmin;
        if log_bound < self.eps.ln() - 1e-3 {
            return;
        }
        if level == 0 {
            out.push([ca, cb, ra, rb]);
            return;
        }
        for cy in 0..2 {
            for cx in 0..2 {
                self.visit(p, level - 1, 2 * bx + cx, 2 * by + cy, out);
            }
        }
    }

    /// Slices of row `r`, columns `ca..cb`, and the window's column offset.
    fn slices(
        &self,
        p: &Piece,
        r: usize,
        ca: usize,
        cb: usize,
    ) -> (&[f32], &[f32], &[f32], usize, usize) {
        let base = r * self.s.width;
        let ib = (ca as i64 + p.off.0 - self.win.i0) as usize;
        let jj = (r as i64 + p.off.1 - self.win.j0) as usize;
        (
            &self.s.h[base + ca..base + cb],
            &self.s.gx[base + ca..base + cb],
            &self.s.gy[base + ca..base + cb],
            ib,
            jj,
        )
    }

    /// Columns `ca..cb` of row `r` clipped to the window's disk: outside
    /// it `w_k < eps`, so every kernel there fails the amplitude test.
    fn clip(&self, p: &Piece, r: usize, ca: usize, cb: usize) -> (usize, usize) {
        let l = self.s.texel_um;
        let y = ((r as i64 + p.off.1) as f64 + 0.5) * l - self.fp.center_um[1];
        let h2 = self.radius * self.radius - y * y;
        if h2 < 0.0 {
            return (ca, ca);
        }
        let h = h2.sqrt();
        let cx = self.fp.center_um[0] - p.off.0 as f64 * l;
        let lo = ((cx - h) / l - 0.5).ceil().max(ca as f64);
        let hi = (((cx + h) / l - 0.5).floor() + 1.0).min(cb as f64);
        if hi <= lo {
            return (ca, ca);
        }
        (lo as usize, hi as usize)
    }

    /// One wavelength: separable spatial phase (column factors computed
    /// once per query), one `cis` and one `exp` per kernel.
    fn row_single(
        &self,
        p: &Piece,
        r: usize,
        ca: usize,
        cb: usize,
        kappa: f64,
        acc: &mut (f64, f64),
    ) {
        let (ca, cb) = self.clip(p, r, ca, cb);
        if ca >= cb {
            return;
        }
        let (hs, gxs, gys, ib, jj) = self.slices(p, r, ca, cb);
        let n = hs.len();
        let wy = self.win.wy[jj];
        let thr = (self.eps / wy) as f32;
        let l = self.s.texel_um;
        let cy = self.fp.center_um[1];
        let (psx, psy) = (self.psi[0] as f32, self.psi[1] as f32);
        let c3 = self.c3 as f32;
        let ak = (self.a0 * kappa * kappa) as f32;
        let hk = (2.0 * PI * kappa * self.c3) as f32;
        let wx = &self.win.wx[ib..ib + n];
        let er = &self.ex.0[ib..ib + n];
        let ei = &self.ex.1[ib..ib + n];
        const B: usize = 32;
        let mut tr = [0.0f32; B];
        let mut ti = [0.0f32; B];
        let mut start = 0;
        while start < n {
            let m = (n - start).min(B);
            let (h, gx, gy) = (
                &hs[start..start + m],
                &gxs[start..start + m],
                &gys[start..start + m],
            );
            let (w, xr, xi) = (
                &wx[start..start + m],
                &er[start..start + m],
                &ei[start..start + m],
            );
            for t in 0..m {
                let dx = psx + c3 * gx[t];
                let dy = psy + c3 * gy[t];
                let amp = w[t] * exp_neg(ak * (dx * dx + dy * dy));
                let amp = if amp >= thr { amp } else { 0.0 };
                let (c, s) = cis_neg(hk * h[t]);
                tr[t] += amp * (c * xr[t] - s * xi[t]);
                ti[t] += amp * (c * xi[t] + s * xr[t]);
            }
            start += m;
        }
        let sr: f64 = tr.iter().map(|&v| v as f64).sum();
        let si: f64 = ti.iter().map(|&v| v as f64).sum();
        let y = ((r as i64 + p.off.1) as f64 + 0.5) * l - cy;
        let (s, c) = (2.0 * PI * kappa * y * self.psi[1]).sin_cos();
        let (eyr, eyi) = (c * wy, -s * wy);
        acc.0 += sr * eyr - si * eyi;
        acc.1 += sr * eyi + si * eyr;
    }

    /// A comb of wavelengths: per kernel two `cis` and three `exp`, then a
    /// complex recurrence across the comb; element-wise loops over chunks
    /// of kernels, so that they vectorize.
    fn row_comb(
        &self,
        p: &Piece,
        r: usize,
        ca: usize,
        cb: usize,
        comb: &Comb,
        lanes: &mut [[f32; COMB_CHUNK]],
    ) {
        const B: usize = COMB_CHUNK;
        let (ca, cb) = self.clip(p, r, ca, cb);
        if ca >= cb {
            return;
        }
        let (hs, gxs, gys, ib, jj) = self.slices(p, r, ca, cb);
        let wy = self.win.wy[jj];
        let thr = self.eps as f32;
        let wyf = wy as f32;
        let l = self.s.texel_um;
        let cx = self.fp.center_um[0];
        let cy = self.fp.center_um[1];
        let (psx, psy) = (self.psi[0] as f32, self.psi[1] as f32);
        let c3 = self.c3 as f32;
        let a0 = self.a0 as f32;
        let (k0, dk) = (comb.k0 as f32, comb.dk as f32);
        let (g1, g2, g3) = (k0 * k0, 2.0 * k0 * dk + dk * dk, 2.0 * dk * dk);
        let hph = 2.0 * std::f32::consts::PI * c3;
        let yph = (2.0 * PI * (((r as i64 + p.off.1) as f64 + 0.5) * l - cy) * self.psi[1]) as f32;
        let x0 = ((ca as i64 + p.off.0) as f64 * l + 0.5 * l - cx) as f32;
        let xph = (2.0 * PI * self.psi[0]) as f32;
        let lf = l as f32;
        let n = comb.n;
        let m = hs.len();
        let mut start = 0;
        let (mut e, mut ratio, mut q) = ([0.0f32; B], [0.0f32; B], [0.0f32; B]);
        let (mut br, mut bi, mut sr, mut si) = ([0.0f32; B], [0.0f32; B], [0.0f32; B], [0.0f32; B]);
        while start < m {
            let c = (m - start).min(B);
            let (h, gx, gy) = (
                &hs[start..start + c],
                &gxs[start..start + c],
                &gys[start..start + c],
            );
            let w = &self.win.wx[ib + start..ib + start + c];
            for t in 0..c {
                let dx = psx + c3 * gx[t];
                let dy = psy + c3 * gy[t];
                let b = a0 * (dx * dx + dy * dy);
                let amp = w[t] * wyf * exp_neg(b * g1);
                e[t] = if amp >= thr { amp } else { 0.0 };
                ratio[t] = exp_neg(b * g2);
                q[t] = exp_neg(b * g3);
                let x = x0 + (start + t) as f32 * lf;
                let theta = hph * h[t] + xph * x + yph;
                (br[t], bi[t]) = cis_neg(theta * k0);
                (sr[t], si[t]) = cis_neg(theta * dk);
            }
            for j in 0..n {
                let (lr, li) = lanes[2 * j..2 * j + 2].split_at_mut(1);
                let (lr, li) = (&mut lr[0], &mut li[0]);
                for t in 0..c {
                    lr[t] += e[t] * br[t];
                    li[t] += e[t] * bi[t];
                    let nr = br[t] * sr[t] - bi[t] * si[t];
                    bi[t] = br[t] * si[t] + bi[t] * sr[t];
                    br[t] = nr;
                    e[t] *= ratio[t];
                    ratio[t] *= q[t];
                }
            }
            start += c;
        }
    }
}
