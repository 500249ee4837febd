//! # isolux-materials
//!
//! The BxDF interface ([`bxdf`]) and one file per material model. Every
//! model offers evaluation, importance sampling and its pdf in the local
//! shading frame (`z` = normal); [`Material`] dispatches over them.
//!
//! | `type` | model | file |
//! |---|---|---|
//! | `diffuse` | Lambertian | [`diffuse`] |
#![warn(missing_docs)]

pub mod bxdf;
pub mod diffuse;
pub mod material;

pub use bxdf::{Bsdf, BsdfSample, BxdfFlags, BxdfModel};
pub use diffuse::Diffuse;
pub use material::Material;
