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
pub mod fresnel;
pub mod material;
pub mod metals;
pub mod microfacet;
pub mod validate;

pub use bxdf::{Bsdf, BsdfSample, BxdfFlags, BxdfModel};
pub use diffuse::Diffuse;
pub use fresnel::Fresnel;
pub use material::Material;
