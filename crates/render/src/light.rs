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

impl PointLight {
    /// The unit direction from `from` toward the light, the distance and
    /// its square (`I / r^2`); `None` where `from` is the light's position.
    /// The shadow ray of every next-event estimation of the light.
    pub fn toward(&self, from: DVec3) -> Option<(DVec3, f64, f64)> {
        let d = self.position - from;
        let dist2 = d.length_squared();
        if !(dist2 > 0.0) {
            return None;
        }
        let dist = dist2.sqrt();
        Some((d / dist, dist, dist2))
    }
}
