//! Point lights.

use isolux_core::{DVec3, Rgb};

/// An isotropic point light of radiant intensity `intensity` (W/sr, linear
/// RGB): irradiance `I cos / r^2` at distance `r`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    /// Position.
    pub position: DVec3,
    /// Radiant intensity (W/sr).
    pub intensity: Rgb,
}
