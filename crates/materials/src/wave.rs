//! # Wave-optics diffraction from a micron-scale heightfield
//!
//! The BRDF of a surface whose microgeometry is a heightfield of
//! micrometre texels, computed with wave optics: the reflected wave's
//! phase delay `exp(-i 2 pi c3 h(s) / lambda)` over a Gaussian coherence
//! area, approximated by one Gabor kernel per texel (`isolux-wave`, see
//! `docs/wave-optics.md`):
//!
//! ```text
//! f(wi, wo) = F(lambda, wi.h) O / (lambda^2 A_c) |sum_k w_k C_k FT[g_k](psi / lambda)|^2
//! ```
//!
//! with the obliquity factor `O = 1` (`obliquity = "reciprocal"`, the
//! default: reciprocal, and the albedo is at most `F` by Parseval) or the
//! seed's `cos_o / cos_i` (`"seed"`, SPEC §3 verbatim, which returns more
//! energy than it receives at grazing incidence); the reasons are in the
//! `isolux-wave` crate's `gabor` module docs.
//!
//! Spatially varying: each shading point maps to heightfield coordinates
//! (`mapping`) and queries its own coherence area, narrowed to the pixel's
//! footprint when that is smaller (camera rays). Spectral: each query
//! evaluates a **hero comb** of `wavelengths` wavelengths spread evenly in
//! wavenumber across 380-780 nm with one random offset per shading point,
//! converted to linear sRGB with the CIE 1931 functions at the same
//! wavelengths (unbiased for the band integral; negative channels of
//! out-of-gamut spectral colours are clamped to 0). Sampling draws a kernel
//! under the footprint and a direction from its lobe at the comb's first
//! wavelength; `pdf` is that strategy's density.
//!
//! Fresnel is the reflectance at the angle between `wi` and the half
//! vector, per wavelength: a named metal's measured `n + i k`, a dielectric
//! `ior`, or none (`F = 1`, the default, as in the public reference code).
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `heightfield` | path | required | `.exr`, 16-bit `.png` or raw `.f32` heights in um, relative to the scene file |
//! | `texel_um` | float | from the file, else 1 | texel size (um) |
//! | `vertical_scale` | float | 1 | multiplies every height |
//! | `raw_size` | [int, int] | - | width and height of a raw file |
//! | `model` | string | `"ghs"` | `"ghs"` (generalized Harvey-Shack) or `"ohs"` (original) |
//! | `obliquity` | string | `"reciprocal"` | `"reciprocal"` (`O = 1`) or `"seed"` (`O = cos_o / cos_i`) |
//! | `metal` / `ior` | string / float | none | Fresnel: a metal of [`crate::metals`] or a dielectric index; none means F = 1 |
//! | `coherence_um` | float | 10 | standard deviation of the coherence area (um); at least two texels; refused where a query's window would hold over [`MAX_WINDOW_KERNELS`] kernels |
//! | `mapping` | string | `"planar"` | `"planar"`, `"spherical"` or `"cylindrical"` |
//! | `axis` | string | `"z"` | planar: the projection axis; the other two (in x, y, z order) are the heightfield's x and y |
//! | `center` | [float; 3] | [0, 0, 0] | spherical / cylindrical: the centre (the cylinder's axis is +y) |
//! | `um_per_unit` | float | 1000 | micrometres per scene unit |
//! | `wavelengths` | int | 4 | hero wavelengths per query (1 to 16) |
//!
//! Source: L.-Q. Yan, M. Hasan, B. Walter, S. Marschner, R. Ramamoorthi,
//! "Rendering Specular Microgeometry with Wave Optics", SIGGRAPH 2018;
//! seed 000 eq. 3-16 with the corrections of SPEC §3.
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "brushed"
//! type = "wave"
//! heightfield = "../heightfields/brushed.exr"   # relative to the scene file
//! model = "ghs"
//! obliquity = "reciprocal"
//! metal = "Al"
//! coherence_um = 10.0
//! mapping = "spherical"
//! um_per_unit = 2000.0
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["type"].as_str(), Some("wave"));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::fresnel;
use crate::metals::Metal;
use isolux_core::{DVec3, Rgb};
use isolux_wave::{Comb, Footprint, GaborSurface, Model, Settings};
use std::sync::Arc;

/// The RMS slope above which [`Wave::roughness_warning`] warns. The model
/// scatters once, so light that a rough field sends beyond the horizon is
/// lost: a noise field's directional albedo (normal incidence, `F = 1`)
/// is 0.994 at RMS slope 0.05, 0.856 at 0.3, 0.327 at 1 and 0.027 at 3
/// (docs/wave-optics.md, "Limits").
pub const ROUGH_SLOPE: f64 = 0.3;

/// The most hero wavelengths per query (`wavelengths`).
pub const MAX_WAVELENGTHS: usize = 16;

/// The most Gabor kernels a query's coherence window may hold
/// ([`Wave::window_kernels`]): scene files with a larger `coherence_um` are
/// refused. 1e8 kernels (a `coherence_um` of about 830 um over 0.5 um
/// texels) take seconds per query even with culling, so a render would
/// not finish; the default window (10 um) holds 14,400 over such texels.
pub const MAX_WINDOW_KERNELS: f64 = 1e8;

/// Fresnel reflectance per wavelength.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WaveFresnel {
    /// `F = 1`.
    None,
    /// A measured metal.
    Metal(&'static Metal),
    /// A dielectric of this index.
    Dielectric(f64),
}

impl WaveFresnel {
    /// Reflectance at `lambda_nm` for the cosine `cos` of the incidence angle.
    pub fn reflectance(&self, lambda_nm: f64, cos: f64) -> f64 {
        match self {
            Self::None => 1.0,
            Self::Metal(m) => {
                let (n, k) = m.nk(lambda_nm);
                fresnel::conductor(cos, n, k)
            }
            Self::Dielectric(eta) => fresnel::dielectric(cos, *eta),
        }
    }

    /// Parses `none` or a metal name (the CLI's `--fresnel`).
    pub fn parse(s: &str) -> Result<Self, String> {
        if s == "none" {
            return Ok(Self::None);
        }
        Metal::by_name(s).map(Self::Metal).ok_or_else(|| {
            format!(
                "unknown Fresnel '{s}': use none or one of {}",
                Metal::names().join(", ")
            )
        })
    }
}

/// How shading points map to heightfield coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mapping {
    /// Projection along axis 0, 1 or 2.
    Planar(usize),
    /// Longitude and colatitude about +y through a centre, as arc lengths.
    Spherical(DVec3),
    /// Angle about the +y axis through a centre (arc length) and height.
    Cylindrical(DVec3),
}

impl Mapping {
    /// Heightfield coordinates (scene units) and the tangent along +x.
    pub fn map(&self, p: DVec3) -> ([f64; 2], DVec3) {
        match *self {
            Mapping::Planar(a) => {
                let (i, j) = match a {
                    0 => (1, 2),
                    1 => (0, 2),
                    _ => (0, 1),
                };
                let mut t = DVec3::ZERO;
                t[i] = 1.0;
                ([p[i], p[j]], t)
            }
            Mapping::Spherical(c) => {
                let d = p - c;
                let r = d.length().max(1e-300);
                let phi = d.z.atan2(d.x);
                let theta = (d.y / r).clamp(-1.0, 1.0).acos();
                let t = DVec3::new(-d.z, 0.0, d.x)
                    .try_normalize()
                    .unwrap_or(DVec3::X);
                ([phi * r, theta * r], t)
            }
            Mapping::Cylindrical(c) => {
                let d = p - c;
                let r = (d.x * d.x + d.z * d.z).sqrt();
                let phi = d.z.atan2(d.x);
                let t = DVec3::new(-d.z, 0.0, d.x)
                    .try_normalize()
                    .unwrap_or(DVec3::X);
                ([phi * r, d.y], t)
            }
        }
    }
}

/// The per-shading-point part of a query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WaveQuery {
    /// Footprint centre (um).
    pub center_um: [f64; 2],
    /// Footprint standard deviation (um).
    pub sigma_um: f64,
    /// Offset of the hero comb in its first cell, in [0, 1).
    pub xi: f64,
    /// World tangent of the heightfield's +x.
    pub tangent: DVec3,
}

/// A wave-optics material (see the module docs).
#[derive(Clone, Debug)]
pub struct Wave {
    /// Kernels and hierarchy, shared.
    pub surface: Arc<GaborSurface>,
    /// Diffraction model.
    pub model: Model,
    /// Fresnel per wavelength.
    pub fresnel: WaveFresnel,
    /// Coherence area standard deviation (um).
    pub coherence_um: f64,
    /// Micrometres per scene unit.
    pub um_per_unit: f64,
    /// Surface to heightfield mapping.
    pub mapping: Mapping,
    /// Hero wavelengths per query.
    pub wavelengths: usize,
    /// Obliquity factor and kernel culling.
    pub settings: Settings,
    /// The current shading point (set by [`Wave::at_point`]).
    pub query: WaveQuery,
}

impl PartialEq for Wave {
    fn eq(&self, o: &Self) -> bool {
        Arc::ptr_eq(&self.surface, &o.surface)
            && self.model == o.model
            && self.fresnel == o.fresnel
            && self.coherence_um == o.coherence_um
            && self.um_per_unit == o.um_per_unit
            && self.mapping == o.mapping
            && self.wavelengths == o.wavelengths
            && self.settings == o.settings
            && self.query == o.query
    }
}

impl Wave {
    /// The number of kernels a query with coherence area `sigma_um` sums
    /// at most: the window's square (`Settings::window_radius`) over the
    /// texel's area. A closed form, for any `sigma_um`, where
    /// `GaborSurface::window_kernels` builds the window to count them.
    pub fn window_kernels(&self, sigma_um: f64) -> f64 {
        let r = self.settings.window_radius(sigma_um);
        (2.0 * r / self.surface.texel_um).powi(2)
    }

    /// Why a coherence area `sigma_um` is too large to render (its window
    /// holds more than [`MAX_WINDOW_KERNELS`] kernels), naming the largest
    /// one accepted; `None` when it is not.
    pub fn window_too_large(&self, sigma_um: f64) -> Option<String> {
        let n = self.window_kernels(sigma_um);
        (n > MAX_WINDOW_KERNELS).then(|| {
            let most = sigma_um * (MAX_WINDOW_KERNELS / n).sqrt();
            format!(
                "{} um puts about {n:.1e} Gabor kernels of this heightfield ({} um \
                 texels) in each query's window, beyond the {MAX_WINDOW_KERNELS:.0e} a render \
                 can sum; use at most {} um",
                isolux_core::short_number(sigma_um),
                isolux_core::short_number(self.surface.texel_um),
                // Whole um where that says enough, else 3 digits.
                if most >= 10.0 {
                    format!("{most:.0}")
                } else if most >= 1e-3 {
                    format!("{most:.3}")
                } else {
                    format!("{most:.2e}")
                },
            )
        })
    }

    /// A warning when the heightfield is too rough for the model (RMS slope
    /// above [`ROUGH_SLOPE`]): it then loses energy rather than failing.
    pub fn roughness_warning(&self) -> Option<String> {
        let s = self.surface.rms_slope();
        (s > ROUGH_SLOPE).then(|| {
            format!(
                "its heightfield's RMS slope is {s:.2}, above the {ROUGH_SLOPE} the \
                 single-scattering wave model holds: the light it sends beyond the horizon \
                 is lost (a directional albedo of about 0.33 at slope 1; docs/wave-optics.md, \
                 Limits); a microfacet model (ggx, beckmann) describes such a surface"
            )
        })
    }

    /// Why a coherence area `sigma_um` cannot be rendered, if it cannot:
    /// under two texels ([`Wave::window_too_small`]) or a window of more
    /// than [`MAX_WINDOW_KERNELS`] kernels ([`Wave::window_too_large`]).
    pub fn coherence_problem(&self, sigma_um: f64) -> Option<String> {
        self.window_too_small(sigma_um)
            .or_else(|| self.window_too_large(sigma_um))
    }

    /// Why a coherence area `sigma_um` is too small for the model, if it
    /// is: under two texels the window holds too few Gabor kernels for
    /// their sum to be the surface's diffraction, and the BRDF loses its
    /// energy (a noise field of 1 um texels, RMS 0.05 um, at 0.5 um:
    /// directional albedo 0.82 at 2 um, 0.73 at 1 um, 0.40 at 0.5 um and
    /// 0.0000 at 0.1 um, which rendered black without a word). Camera
    /// rays never narrow the area below two texels either.
    pub fn window_too_small(&self, sigma_um: f64) -> Option<String> {
        let least = 2.0 * self.surface.texel_um;
        (sigma_um < least).then(|| {
            format!(
                "{} um is less than two texels of this heightfield ({} um): too few Gabor \
                 kernels for the model, whose BRDF then loses its energy; use at least {} um",
                isolux_core::short_number(sigma_um),
                isolux_core::short_number(self.surface.texel_um),
                isolux_core::short_number(least)
            )
        })
    }

    /// A material over `surface`, queried at the heightfield's origin
    /// until placed with [`Wave::at_point`].
    pub fn new(surface: Arc<GaborSurface>, model: Model, fresnel: WaveFresnel) -> Self {
        let coherence_um = 10.0;
        Self {
            surface,
            model,
            fresnel,
            coherence_um,
            um_per_unit: 1000.0,
            mapping: Mapping::Planar(2),
            wavelengths: 4,
            settings: Settings::default(),
            query: WaveQuery {
                center_um: [0.0, 0.0],
                sigma_um: coherence_um,
                xi: 0.5,
                tangent: DVec3::X,
            },
        }
    }

    /// This material placed at world point `p`: the footprint centre from
    /// the mapping, its width the coherence area or, when smaller, half
    /// the pixel footprint `footprint` (scene units; `None` past the
    /// camera ray), and the hero comb's offset `xi`.
    pub fn at_point(&self, p: DVec3, footprint: Option<f64>, xi: f64) -> Self {
        let (s, tangent) = self.mapping.map(p);
        let mut sigma = self.coherence_um;
        if let Some(fp) = footprint {
            let pix = 0.5 * fp * self.um_per_unit;
            if pix.is_finite() {
                sigma = sigma.min(pix.max(2.0 * self.surface.texel_um));
            }
        }
        Self {
            query: WaveQuery {
                center_um: [s[0] * self.um_per_unit, s[1] * self.um_per_unit],
                sigma_um: sigma,
                xi,
                tangent,
            },
            ..self.clone()
        }
    }

    fn footprint(&self) -> Footprint {
        Footprint {
            center_um: self.query.center_um,
            sigma_um: self.query.sigma_um,
        }
    }

    fn comb(&self) -> Comb {
        Comb::shifted(self.wavelengths, self.query.xi)
    }

    /// Spectral `f` converted with `comb` (Fresnel applied per wavelength).
    pub fn f_comb(&self, wo: DVec3, wi: DVec3, comb: &Comb) -> Rgb {
        let mut v = vec![0.0; comb.n];
        self.surface.eval(
            &self.footprint(),
            self.model,
            wi,
            wo,
            comb,
            &self.settings,
            &mut v,
        );
        let cos_h = {
            let h = (wi + wo).normalize_or_zero();
            wi.dot(h).abs()
        };
        for (j, x) in v.iter_mut().enumerate() {
            *x *= self.fresnel.reflectance(comb.lambda_um(j) * 1000.0, cos_h);
        }
        let c = comb.to_rgb(&v);
        Rgb::new(c[0], c[1], c[2])
    }
}

impl BxdfModel for Wave {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        self.f_comb(wo, wi, &self.comb())
    }

    fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let comb = self.comb();
        // `uc` picks the kernel (row, then column from its remainder).
        let uk = [(uc * 4096.0).fract(), uc];
        let wi = self.surface.sample(
            &self.footprint(),
            self.model,
            wo,
            comb.k0,
            &self.settings,
            uk,
            u,
        )?;
        BsdfSample::reflected(self, wo, wi, BxdfFlags::GLOSSY)
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let k = self.comb().k0;
        self.surface
            .pdf(&self.footprint(), self.model, wo, wi, k, &self.settings)
    }

    fn flags(&self) -> BxdfFlags {
        BxdfFlags::REFLECTION | BxdfFlags::GLOSSY
    }

    fn albedo(&self) -> Rgb {
        let c = crate::metals::RGB_WAVELENGTHS_NM.map(|l| self.fresnel.reflectance(l, 1.0));
        Rgb::new(c[0], c[1], c[2])
    }
}
