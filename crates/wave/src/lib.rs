//! # Isolux wave optics
//!
//! The diffraction BRDF of micron-scale heightfields (SPEC §3; Yan, Hasan,
//! Walter, Marschner, Ramamoorthi, "Rendering Specular Microgeometry with
//! Wave Optics", SIGGRAPH 2018): a [`Heightfield`] becomes a
//! [`GaborSurface`] of one Gabor kernel per texel with a quadtree over
//! them, queried per coherence area ([`Footprint`]), direction pair and
//! wavelength comb ([`Comb`]).
//!
//! Fresnel is not applied here: [`GaborSurface::eval`] returns `f / F`,
//! and the caller multiplies by the reflectance of the material at each
//! wavelength (the `wave` material of `isolux-materials` and
//! `isolux wave brdf` do).

mod cie_table;
pub mod fastmath;
pub mod gabor;
pub mod generate;
pub mod heightfield;
pub mod spectral;

pub use gabor::{Footprint, GaborSurface, Model, Obliquity, Settings, DEFAULT_EPS};
pub use heightfield::{Heightfield, HeightfieldError, LoadOptions};
pub use spectral::Comb;
