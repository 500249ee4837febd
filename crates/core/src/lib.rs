//! # isolux-core
//!
//! Shared foundations of Isolux: double-precision vectors (re-exported from
//! [`glam`]), rays and boxes, orthonormal shading frames, a counter-based
//! deterministic random number generator, Monte Carlo sampling routines,
//! piecewise-constant distributions for importance sampling, and linear RGB
//! colour with the sRGB transfer function.
//!
//! Every other Isolux crate builds on these types; none of them allocate on
//! the hot path.
//!
//! ```
//! use isolux_core::{Frame, DVec3, sampling};
//! let n = DVec3::new(0.0, 0.0, 1.0);
//! let frame = Frame::from_normal(n);
//! let local = sampling::cosine_hemisphere([0.3, 0.7]);
//! let world = frame.to_world(local);
//! assert!(world.dot(n) >= 0.0);
//! ```
#![warn(missing_docs)]

pub mod color;
pub mod distribution;
pub mod frame;
pub mod image;
pub mod ray;
pub mod rng;
pub mod sampling;

pub use color::Rgb;
pub use distribution::{Distribution1D, Distribution2D};
pub use frame::Frame;
pub use glam::{DMat3, DMat4, DVec2, DVec3, DVec4};
pub use image::{Aovs, Image};
pub use ray::{Aabb, Ray};
pub use rng::Pcg32;

/// pi as f64.
pub const PI: f64 = std::f64::consts::PI;
/// 1 / pi.
pub const INV_PI: f64 = std::f64::consts::FRAC_1_PI;
/// 1 / (4 pi): the isotropic phase function and uniform sphere pdf.
pub const INV_4PI: f64 = 1.0 / (4.0 * std::f64::consts::PI);

/// `v` for an error message: as `{}` prints it, or in exponent form where
/// that would run to dozens of digits (`1e30`, not 31 of them; `1e-30`,
/// not 30 zeros).
///
/// ```
/// use isolux_core::short_number;
/// assert_eq!(short_number(0.25), "0.25");
/// assert_eq!(short_number(1e30), "1e30");
/// assert_eq!(short_number(-2.5e-9), "-2.5e-9");
/// assert_eq!(short_number(0.0), "0");
/// ```
pub fn short_number(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e7).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}
