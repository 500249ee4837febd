//! The BxDF interface (pbrt-v4 style) and the [`Bsdf`] wrapper.
//!
//! A BxDF works in the local shading frame, `z` along the normal:
//! - `f(wo, wi)`: the BRDF/BTDF value **without** the cosine (1/sr);
//! - `sample(wo, uc, u)`: a direction `wi` drawn with density `pdf`, with
//!   the value `f` and the lobe's [`BxdfFlags`];
//! - `pdf(wo, wi)`: the solid-angle density of `sample`;
//! - `flags()`: which lobes the model has.
//!
//! `wo` points toward the viewer and `wi` toward the light; both are unit.
//! The [`Bsdf`] wrapper owns the frame change and the guards (`wo.z == 0`,
//! zero pdf, non-finite values), so each model stays short. Dispatch over
//! models is a `match` on the [`crate::Material`] enum, never a trait
//! object, so the same data can later mirror a GPU layout.

use isolux_core::{DVec3, Frame, Rgb};

/// Lobe classification, as bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct BxdfFlags(pub u8);

impl BxdfFlags {
    /// Reflects light.
    pub const REFLECTION: Self = Self(1);
    /// Transmits light.
    pub const TRANSMISSION: Self = Self(2);
    /// Lambertian-like lobe.
    pub const DIFFUSE: Self = Self(4);
    /// Glossy lobe (rough, non-delta).
    pub const GLOSSY: Self = Self(8);
    /// Dirac delta lobe (perfect mirror or refraction).
    pub const SPECULAR: Self = Self(16);

    /// Union of flags.
    pub const fn union(self, o: Self) -> Self {
        Self(self.0 | o.0)
    }

    /// Whether all bits of `o` are set.
    pub const fn contains(self, o: Self) -> bool {
        self.0 & o.0 == o.0
    }

    /// Whether this is a delta lobe.
    pub const fn is_specular(self) -> bool {
        self.contains(Self::SPECULAR)
    }
}

impl std::ops::BitOr for BxdfFlags {
    type Output = Self;
    fn bitor(self, o: Self) -> Self {
        self.union(o)
    }
}

/// A sampled direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Sampled incident direction (local frame inside a BxDF, world frame
    /// out of [`Bsdf::sample`]).
    pub wi: DVec3,
    /// BxDF value at `(wo, wi)`, without the cosine.
    pub f: Rgb,
    /// Solid-angle density (for delta lobes: the discrete probability).
    pub pdf: f64,
    /// Lobe that produced the sample.
    pub flags: BxdfFlags,
    /// Relative index `n_t / n_i` crossed by a transmitted sample (1 for
    /// reflection): the integrator uses it to undo radiance compression in
    /// Russian roulette.
    pub eta: f64,
}

impl BsdfSample {
    /// A reflected direction scored by the model's whole `f` and `pdf`
    /// (the usual ending of a mixture's `sample`, whichever lobe drew
    /// `wi`): `None` when `wi` lies below the horizon or where the pdf is
    /// zero (or not finite), which no Monte Carlo weight survives; `flags`
    /// is the lobe that drew it (`REFLECTION` is added).
    pub fn reflected<M: BxdfModel + ?Sized>(
        model: &M,
        wo: DVec3,
        wi: DVec3,
        flags: BxdfFlags,
    ) -> Option<Self> {
        if wi.z <= 0.0 {
            return None;
        }
        let pdf = model.pdf(wo, wi);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        Some(Self {
            wi,
            f: model.f(wo, wi),
            pdf,
            flags: BxdfFlags::REFLECTION | flags,
            eta: 1.0,
        })
    }

    /// The Monte Carlo weight `f |cos| / pdf`.
    pub fn weight(&self, cos_theta: f64) -> Rgb {
        self.f * (cos_theta.abs() / self.pdf)
    }
}

/// The behaviour every model implements in its local frame.
pub trait BxdfModel {
    /// `f(wo, wi)` without the cosine.
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb;
    /// Importance-samples `wi` given `wo`; `uc` picks a lobe, `u` the
    /// direction. `None` when no direction could be generated.
    fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample>;
    /// Density of `sample` for `wi`.
    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64;
    /// Lobes of this model.
    fn flags(&self) -> BxdfFlags;
    /// A representative albedo (the diffuse colour, for the albedo AOV).
    fn albedo(&self) -> Rgb;
}

/// A BxDF placed at a surface point: the model plus its shading frame.
///
/// Opaque reflective models are **two-sided**: the frame's normal is turned
/// toward `wo`, so a surface seen from inside a solid shades like its
/// outside. Transmissive models keep the outward normal: which side is
/// inside decides the relative index of refraction.
#[derive(Clone, Copy, Debug)]
pub struct Bsdf<'a, M: BxdfModel> {
    model: &'a M,
    frame: Frame,
}

impl<'a, M: BxdfModel> Bsdf<'a, M> {
    /// Places `model` at a point with unit normal `n` seen from `wo`.
    pub fn new(model: &'a M, n: DVec3, wo: DVec3) -> Self {
        let n = Self::facing(model, n, wo);
        Self {
            model,
            frame: Frame::from_normal(n),
        }
    }

    /// Places `model` with a tangent for anisotropic models.
    pub fn with_tangent(model: &'a M, n: DVec3, tangent: DVec3, wo: DVec3) -> Self {
        let n = Self::facing(model, n, wo);
        Self {
            model,
            frame: Frame::from_normal_tangent(n, tangent),
        }
    }

    fn facing(model: &M, n: DVec3, wo: DVec3) -> DVec3 {
        if wo.dot(n) < 0.0 && !model.flags().contains(BxdfFlags::TRANSMISSION) {
            -n
        } else {
            n
        }
    }

    /// The shading normal (facing `wo` for opaque models, outward for
    /// transmissive ones).
    pub fn normal(&self) -> DVec3 {
        self.frame.n
    }

    /// `f(wo, wi)` for world directions; zero for non-finite results.
    pub fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        let (lo, li) = (self.frame.to_local(wo), self.frame.to_local(wi));
        if lo.z == 0.0 {
            return Rgb::BLACK;
        }
        let v = self.model.f(lo, li);
        if v.is_finite() {
            v
        } else {
            Rgb::BLACK
        }
    }

    /// Samples a world direction; rejects zero or non-finite pdfs.
    pub fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        let lo = self.frame.to_local(wo);
        if lo.z == 0.0 {
            return None;
        }
        let s = self.model.sample(lo, uc, u)?;
        if !(s.pdf > 0.0) || !s.pdf.is_finite() || !s.f.is_finite() || s.wi.z == 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi: self.frame.to_world(s.wi),
            ..s
        })
    }

    /// Density for world directions.
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        let (lo, li) = (self.frame.to_local(wo), self.frame.to_local(wi));
        if lo.z == 0.0 {
            return 0.0;
        }
        let p = self.model.pdf(lo, li);
        if p.is_finite() {
            p
        } else {
            0.0
        }
    }

    /// The model's flags.
    pub fn flags(&self) -> BxdfFlags {
        self.model.flags()
    }
}
