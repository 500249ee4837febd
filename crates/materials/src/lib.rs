//! # isolux-materials
//!
//! The BxDF interface ([`bxdf`]) and one file per material model. Every
//! model offers evaluation, importance sampling and its pdf in the local
//! shading frame (`z` = normal); [`Material`] dispatches over them.
//!
//! | `type` | model | file |
//! |---|---|---|
//! | `diffuse` | Lambertian | [`diffuse`] |
//! | `phong` | normalized Phong lobe + Lambert | [`phong`] |
//! | `blinn_phong` | bounded Blinn-Phong lobe + Lambert | [`blinn_phong`] |
//! | `gaussian` | the seed's Gaussian highlight, numerically normalized | [`gaussian`] |
//! | `cook_torrance` | Cook-Torrance (Beckmann/GGX/Gaussian, V-groove/Smith) + Lambert | [`cook_torrance`] |
//! | `ward` | anisotropic Ward, bounded-albedo form | [`ward`] |
//! | `heidrich_seidel` | fibre (brushed, hair) highlight + isotropic lobe + Lambert | [`heidrich_seidel`] |
//! | `ggx` | GGX / Trowbridge-Reitz microfacet reflection | [`ggx`] |
//! | `beckmann` | Beckmann microfacet reflection | [`beckmann`] |
//! | `conductor` | smooth metal mirror | [`conductor`] |
//! | `plastic` | dielectric coat (smooth or GGX) over a diffuse base | [`plastic`] |
//! | `subsurface` | translucent medium behind a smooth boundary (dipole BSSRDF or random walk) | [`subsurface_material`] |
//! | `subsurface_brdf` | translucent media, local approximation (dipole total + single scattering) | [`subsurface_brdf`] |
//! | `mix` | weighted mixture of non-delta materials | [`mix`] |
//! | `dielectric` | smooth glass: Fresnel reflection and refraction | [`dielectric`] |
//! | `factored` | homomorphic factorization `p(wo) q(h) p(wi)` from textures | [`factored`] |
//! | `merl` | measured isotropic BRDF (MERL `.binary`) | [`merl`] |
//!
//! Shared machinery: [`fresnel`] (dielectric, conductor, Schlick),
//! [`metals`] (measured `n + ik`), [`microfacet`] (distributions, masking,
//! visible-normal sampling), [`parabolic`] (hemisphere maps); statistical checks in [`validate`].
#![warn(missing_docs)]

pub mod beckmann;
pub mod blinn_phong;
pub mod bxdf;
pub mod conductor;
pub mod cook_torrance;
pub mod dielectric;
pub mod diffuse;
pub mod factored;
pub mod fresnel;
pub mod gaussian;
pub mod ggx;
pub mod heidrich_seidel;
pub mod lobe;
pub mod material;
pub mod merl;
pub mod metals;
pub mod microfacet;
pub mod mix;
pub mod parabolic;
pub mod phong;
pub mod plastic;
pub mod subsurface;
pub mod subsurface_brdf;
pub mod subsurface_material;
pub mod validate;
pub mod ward;
pub mod wave;

pub use beckmann::Beckmann;
pub use blinn_phong::BlinnPhong;
pub use bxdf::{Bsdf, BsdfSample, BxdfFlags, BxdfModel};
pub use conductor::Conductor;
pub use cook_torrance::CookTorrance;
pub use dielectric::Dielectric;
pub use diffuse::Diffuse;
pub use factored::Factored;
pub use fresnel::Fresnel;
pub use gaussian::Gaussian;
pub use ggx::Ggx;
pub use heidrich_seidel::HeidrichSeidel;
pub use material::Material;
pub use merl::Merl;
pub use mix::Mix;
pub use phong::Phong;
pub use plastic::Plastic;
pub use subsurface_brdf::SubsurfaceBrdf;
pub use subsurface_material::Subsurface;
pub use ward::Ward;
pub use wave::Wave;
