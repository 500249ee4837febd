//! # Subsurface scattering material (`type = "subsurface"`)
//!
//! A homogeneous translucent medium (milk, marble, skin) behind a smooth
//! dielectric boundary. The boundary reflects with the exact Fresnel
//! reflectance and refracts the rest into the medium (as
//! [`crate::Dielectric`]); inside, light is absorbed (`sigma_a`) and
//! scattered (`sigma_s`, Henyey-Greenstein with mean cosine `g`).
//!
//! Rendering modes (`mode`):
//! - `random_walk`: brute-force volumetric path tracing inside the object:
//!   exponential free flights `t = -ln(u) / sigma_t` against the object's
//!   exact surface, phase-function scattering, Fresnel at the boundary on
//!   every exit attempt. Exact for the medium and the object's true shape
//!   (the reference the dipole approximates). One colour channel is
//!   tracked per path (chosen uniformly, weight 3), since the
//!   coefficients differ per channel.
//! - `dipole` (the default): the BSSRDF of Jensen et al. 2001 in the
//!   separable form of pbrt-v3 §11.4,
//!   `S = (1 - F(cos_o)) R_d(|x_i - x_o|) S_w(wi)` with
//!   `S_w = (1 - F(cos_i)) / (c pi)`, `c = 1 - F_dr,ext` (so the entry side
//!   integrates to one and the exit flux is the dipole's `R_d`). The
//!   integrator samples the entry point `x_i` around the exit point: a
//!   channel, a projection axis (the normal with probability 1/2, each
//!   tangent with 1/4), a radius from a table of the channel's own
//!   `R_d(r) 2 pi r` (4096 bins in `x = sqrt(r / r_max)`), and a probe ray
//!   through the object that
//!   picks one of its `k` hits; the pdf combines all axes and channels.
//!   Point lights and the environment are estimated at `x_i`. The
//!   single-scattering term (Jensen's `S^(1)`, see
//!   [`crate::subsurface::phase`]) is added at `x_o` for direct light
//!   (light sampling and a cosine-sampled sky direction, with MIS).
//!   Jensen's sum `S^(1) + S_d` counts the lowest orders twice (the
//!   diffusion term already approximates them): a non-absorbing sphere
//!   under a white sky rendered 1.054 with it and 0.929 without (the
//!   latter below 1 by the profile lost beyond the object). So the
//!   single-scattering term of each channel is scaled by
//!   [`Subsurface::single_scattering_scale`] (1 for absorbing media, 0
//!   without absorption; see [`crate::subsurface::energy`]): the sphere
//!   renders as the dipole alone, 0.929. `single_scattering = false` drops
//!   the term.
//!
//! Coefficients are per millimetre; `scale` gives millimetres per scene
//! unit, so `sigma` in 1/unit is `sigma_mm * scale`.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `medium` | string | | a named measured medium ([`crate::subsurface::media`]) |
//! | `sigma_s_reduced` or `sigma_s` | RGB, 1/mm | | (reduced) scattering, instead of `medium` |
//! | `sigma_a` | RGB, 1/mm | | absorption |
//! | `g` | number in (-1, 1) | `0` | mean cosine (with `sigma_s_reduced` or a medium, `sigma_s = sigma_s' / (1 - g)`) |
//! | `ior` | number > 0 | medium's, else `1.3` | relative index of refraction |
//! | `scale` | number > 0 | `1` | millimetres per scene unit |
//! | `mode` | `"dipole"`, `"random_walk"` | `"dipole"` | see above |
//! | `single_scattering` | boolean | `true` | add `S^(1)` in dipole mode |
//!
//! Sources: Jensen et al., SIGGRAPH 2001; pbrt-v4 §11 and §14 (volumetric
//! path tracing).
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "milk"
//! type = "subsurface"
//! medium = "skimmilk"
//! scale = 10.0
//! mode = "random_walk"
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["mode"].as_str(), Some("random_walk"));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::subsurface::energy::{single_scattering_scale, DiffuseExit, LobeAlbedos};
use crate::subsurface::Dipole;
use crate::{Dielectric, SubsurfaceBrdf};
use isolux_core::{DVec3, Distribution1D, Rgb, INV_PI, PI};
use std::sync::Arc;

/// Bins of the tabulated radial sampler.
const RADIAL_BINS: usize = 4096;

/// How the medium is rendered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SubsurfaceMode {
    /// Dipole BSSRDF with probe-ray entry-point sampling.
    Dipole,
    /// Volumetric random walk inside the object.
    RandomWalk,
}

/// What [`Subsurface::new`] derives from the medium's coefficients.
#[derive(Debug)]
struct Derived {
    /// Per-channel tables of `R_d(r) 2 pi r` in `x = sqrt(r / r_max)`.
    radial: [Distribution1D; 3],
    /// Per channel, the factor on the single-scattering term that keeps
    /// the dipole plus single scattering within energy on a half-space
    /// ([`crate::subsurface::energy::single_scattering_scale`]); used
    /// through [`Subsurface::single_scattering_scale`].
    single_scale: Rgb,
    /// The local approximation of the same medium (the seed's eq. 19),
    /// single scattering included: see [`Subsurface::local_brdf`].
    local: SubsurfaceBrdf,
}

/// A translucent medium behind a smooth boundary.
#[derive(Clone, Debug)]
pub struct Subsurface {
    /// The boundary.
    pub boundary: Dielectric,
    /// Scattering coefficient per scene unit.
    pub sigma_s: Rgb,
    /// Absorption coefficient per scene unit.
    pub sigma_a: Rgb,
    /// Mean cosine of the phase function.
    pub g: f64,
    /// Rendering mode.
    pub mode: SubsurfaceMode,
    /// Per-channel dipoles, in scene units (coefficients times `scale`).
    pub dipoles: [Dipole; 3],
    /// `1 - F_dr,ext`: normalizes the entry-side angular factor.
    pub sw_norm: f64,
    /// Add Jensen's single-scattering term in dipole mode.
    pub single_scattering: bool,
    /// What the constructor derives from the coefficients: the radial
    /// sampling tables, the energy scale and the local BRDF (shared, and
    /// behind a pointer to keep [`crate::Material`] small).
    derived: Arc<Derived>,
    r_max: f64,
}

impl PartialEq for Subsurface {
    fn eq(&self, o: &Self) -> bool {
        self.boundary == o.boundary
            && self.sigma_s == o.sigma_s
            && self.sigma_a == o.sigma_a
            && self.g == o.g
            && self.mode == o.mode
            && self.single_scattering == o.single_scattering
    }
}

impl Subsurface {
    /// A medium with unreduced scattering `sigma_s`, absorption `sigma_a`
    /// (per scene unit), mean cosine `g` and relative index `eta`.
    pub fn new(sigma_s: Rgb, sigma_a: Rgb, g: f64, eta: f64, mode: SubsurfaceMode) -> Self {
        let red = sigma_s * (1.0 - g);
        let dipoles = [
            Dipole::new(red.r, sigma_a.r, eta),
            Dipole::new(red.g, sigma_a.g, eta),
            Dipole::new(red.b, sigma_a.b, eta),
        ];
        // The profile is ignored beyond r_max: where the slowest channel's
        // exp(-sigma_tr r) has fallen to 1e-4 (sigma_tr floored at
        // sigma_t'/30: without absorption the tail is a power law).
        let r_max = dipoles
            .iter()
            .map(|d| 9.2 / d.sigma_tr.max(d.sigma_t_reduced / 30.0))
            .fold(0.0f64, f64::max);
        // Sample r = r_max x^2 from a table of R_d(r) 2 pi r dr/dx: the
        // warp resolves the profile's core (a mean free path) and its tail.
        let table = |d: &Dipole| {
            let w: Vec<f64> = (0..RADIAL_BINS)
                .map(|i| {
                    let x = (i as f64 + 0.5) / RADIAL_BINS as f64;
                    let r = r_max * x * x;
                    d.r_d(r) * 2.0 * PI * r * 2.0 * r_max * x
                })
                .collect();
            Distribution1D::new(&w)
        };
        // The energy check's quadrature, shared by the BSSRDF's check and
        // its local BRDF's (Jensen's normalization).
        let lobes = LobeAlbedos::new(g, eta);
        let r_d = Rgb::from_array(dipoles.map(|d| d.total()));
        let a = single_albedo(sigma_s, sigma_a);
        Self {
            boundary: Dielectric { ior: eta },
            sigma_s,
            sigma_a,
            g,
            mode,
            derived: Arc::new(Derived {
                radial: [table(&dipoles[0]), table(&dipoles[1]), table(&dipoles[2])],
                single_scale: single_scattering_scale(&lobes, r_d, a, DiffuseExit::Normalized),
                local: SubsurfaceBrdf::with_lobes(r_d, a, g, eta, &lobes),
            }),
            dipoles,
            sw_norm: 1.0 - crate::fresnel::diffuse_external(eta),
            single_scattering: true,
            r_max,
        }
    }

    /// The medium seen from inside a medium of index `n` (a marble under
    /// water): the same coefficients behind a boundary of index `ior / n`,
    /// its dipole profile, tables and single scattering derived anew.
    /// `None` at `n = 1`.
    pub fn relative_to(&self, n: f64) -> Option<Subsurface> {
        if n == 1.0 || !(n > 0.0) {
            return None;
        }
        let mut m = Subsurface::new(
            self.sigma_s,
            self.sigma_a,
            self.g,
            self.boundary.ior / n,
            self.mode,
        );
        m.single_scattering = self.single_scattering;
        Some(m)
    }

    /// Per channel, the factor on the single-scattering term that keeps
    /// the dipole mode within energy: Jensen's sum `S^(1) + S_d` counts the
    /// lowest scattering orders twice, so with little absorption it
    /// reflects more than it receives. 1 where the published model is
    /// within energy and in random-walk mode; 0 for a medium without
    /// absorption, whose dipole term alone is exactly what a half-space
    /// reflects (see [`crate::subsurface::energy`]).
    pub fn single_scattering_scale(&self) -> Rgb {
        if self.mode == SubsurfaceMode::Dipole {
            self.derived.single_scale
        } else {
            Rgb::splat(1.0)
        }
    }

    /// The local approximation of this medium, [`SubsurfaceBrdf`] (the
    /// seed's eq. 19: light leaves where it entered, the blur across the
    /// surface ignored), which the real-time mode renders it with: the
    /// seed's own real-time model of translucency. Without the
    /// single-scattering term (`single_scattering = false`) it is the
    /// dipole's term alone, as published. Scale-free: the dipole's total
    /// reflectance depends on the reduced albedo and `eta` only.
    pub fn local_brdf(&self) -> SubsurfaceBrdf {
        if self.single_scattering {
            return self.derived.local;
        }
        SubsurfaceBrdf {
            single_albedo: Rgb::BLACK,
            ..self.derived.local
        }
    }

    /// `R_d(r)` per channel (per scene unit area), as published.
    pub fn profile(&self, r: f64) -> Rgb {
        Rgb::new(
            self.dipoles[0].r_d(r),
            self.dipoles[1].r_d(r),
            self.dipoles[2].r_d(r),
        )
    }

    /// The entry side's angular factor `S_w(wi) = (1 - F(cos_i)) / (c pi)`,
    /// normalized so that `int S_w cos dw = 1`.
    pub fn sw(&self, cos_i: f64) -> f64 {
        (1.0 - crate::fresnel::dielectric(cos_i.abs(), self.boundary.ior)) * INV_PI / self.sw_norm
    }

    /// Density of the radial sampler of channel `c` at radius `r`.
    pub fn radial_pdf(&self, c: usize, r: f64) -> f64 {
        if !(r > 0.0 && r < self.r_max) {
            return 0.0;
        }
        let x = (r / self.r_max).sqrt();
        self.derived.radial[c].pdf(x) / (2.0 * self.r_max * x)
    }

    /// Samples a radius for channel `c` from its tabulated profile.
    pub fn sample_radius(&self, c: usize, u: f64) -> f64 {
        let (x, _, _) = self.derived.radial[c].sample(u);
        self.r_max * x * x
    }

    /// The radial sampling table of channel `c` (`R_d(r) 2 pi r dr/dx` in
    /// `x = sqrt(r / r_max)`), for back ends that sample it themselves.
    pub fn radial_table(&self, c: usize) -> &Distribution1D {
        &self.derived.radial[c]
    }

    /// Radius beyond which the profile is ignored.
    pub fn r_max(&self) -> f64 {
        self.r_max
    }

    /// Extinction per scene unit.
    pub fn sigma_t(&self) -> Rgb {
        self.sigma_s + self.sigma_a
    }

    /// Whether the medium scatters and absorbs every colour channel alike
    /// (grey fog, smoke): a random walk through it then carries all
    /// three channels at once, without choosing one.
    pub fn is_grey(&self) -> bool {
        let (s, a) = (self.sigma_s, self.sigma_a);
        s.r == s.g && s.g == s.b && a.r == a.g && a.g == a.b
    }
}

impl BxdfModel for Subsurface {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        self.boundary.f(wo, wi)
    }
    fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        self.boundary.sample(wo, uc, u)
    }
    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        self.boundary.pdf(wo, wi)
    }
    fn flags(&self) -> BxdfFlags {
        self.boundary.flags()
    }
    fn albedo(&self) -> Rgb {
        single_albedo(self.sigma_s, self.sigma_a)
    }
}

/// The single-scattering albedo `sigma_s / sigma_t` per channel (0 where
/// the medium neither scatters nor absorbs).
fn single_albedo(sigma_s: Rgb, sigma_a: Rgb) -> Rgb {
    let a = |s: f64, t: f64| if t > 0.0 { s / t } else { 0.0 };
    let st = sigma_s + sigma_a;
    Rgb::new(a(sigma_s.r, st.r), a(sigma_s.g, st.g), a(sigma_s.b, st.b))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The single-scattering term is scaled only where it is needed: in
    /// dipole mode, with little absorption.
    #[test]
    fn the_single_scattering_scale_applies_to_the_dipole_mode() {
        let white = |mode| Subsurface::new(Rgb::splat(20.0), Rgb::BLACK, 0.0, 1.3, mode);
        assert_eq!(
            white(SubsurfaceMode::Dipole).single_scattering_scale(),
            Rgb::BLACK
        );
        assert_eq!(
            white(SubsurfaceMode::RandomWalk).single_scattering_scale(),
            Rgb::splat(1.0)
        );
        // Strong absorption: the published model is within energy.
        let ketchup = Subsurface::new(
            Rgb::splat(1.0),
            Rgb::splat(1.0),
            0.0,
            1.3,
            SubsurfaceMode::Dipole,
        );
        assert_eq!(ketchup.single_scattering_scale(), Rgb::splat(1.0));
    }

    /// The real-time mode's local BRDF is `subsurface_brdf` of the same
    /// medium (scale-free), and without single scattering the dipole's
    /// term alone, unscaled.
    #[test]
    fn the_local_brdf_is_the_media_subsurface_brdf() {
        let (s, a) = (Rgb::new(2.19, 2.62, 3.0), Rgb::new(0.0021, 0.0041, 0.0071));
        let mut m = Subsurface::new(s * 10.0, a * 10.0, 0.0, 1.5, SubsurfaceMode::Dipole);
        let b = SubsurfaceBrdf::new(s, a, 0.0, 1.5);
        let l = m.local_brdf();
        for c in 0..3 {
            let rel = |x: f64, y: f64| (x / y - 1.0).abs();
            assert!(
                rel(l.r_d.to_array()[c], b.r_d.to_array()[c]) < 1e-12,
                "{l:?} {b:?}"
            );
            assert!(rel(l.single_albedo.to_array()[c], b.single_albedo.to_array()[c]) < 1e-12);
        }
        assert_eq!((l.g, l.eta), (0.0, 1.5));
        m.single_scattering = false;
        let l = m.local_brdf();
        assert_eq!(l.single_albedo, Rgb::BLACK);
        assert_eq!(l.r_d.r, Dipole::new(21.9, 0.021, 1.5).total());
    }
}
