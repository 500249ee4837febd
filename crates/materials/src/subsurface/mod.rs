//! Subsurface scattering physics (SPEC §4, seed 000 eq. 17-19, seed 003).
//!
//! - [`diffusion`]: reduced coefficients, the diffusion constant, the
//!   effective transport coefficient, the diffuse Fresnel reflectance (fit
//!   and exact), the dipole profile `R_d(r)` and its closed-form total;
//! - [`phase`]: the Henyey-Greenstein phase function and the
//!   single-scattering term;
//! - [`energy`]: the energy bound of the dipole plus single scattering;
//! - [`media`]: Jensen et al. 2001's measured media;
//! - [`random_walk`]: the brute-force half-space reference.
//!
//! Primary source: H. W. Jensen, S. R. Marschner, M. Levoy, P. Hanrahan,
//! "A Practical Model for Subsurface Light Transport", SIGGRAPH 2001.
//! The materials that render with them are `subsurface` and
//! `subsurface_brdf`.

pub mod diffusion;
pub mod energy;
pub mod media;
pub mod phase;
pub mod random_walk;

pub use diffusion::Dipole;
pub use media::{Medium, MEDIA};
