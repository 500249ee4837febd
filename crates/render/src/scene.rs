//! A scene ready to render (built by `isolux-scene` from a TOML file, or
//! directly in code).

use crate::{Camera, Environment, PointLight};
use isolux_geometry::Aggregate;
use isolux_materials::Material;

/// Image size and sampling.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FilmSettings {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Samples per pixel (any count >= 1; stratified on a sub-pixel grid).
    pub spp: u32,
}

impl Default for FilmSettings {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            spp: 16,
        }
    }
}

/// Path tracer settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IntegratorSettings {
    /// Maximum number of scattering events on a path (1 = direct light only).
    pub max_depth: u32,
    /// Seed of every random decision: same seed, same image.
    pub seed: u64,
}

impl Default for IntegratorSettings {
    fn default() -> Self {
        Self {
            max_depth: 8,
            seed: 0,
        }
    }
}

/// Everything needed to render an image.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// Camera.
    pub camera: Camera,
    /// Film.
    pub film: FilmSettings,
    /// Integrator.
    pub integrator: IntegratorSettings,
    /// Point lights.
    pub lights: Vec<PointLight>,
    /// Environment light.
    pub environment: Environment,
    /// Materials, indexed by `object_material`.
    pub materials: Vec<Material>,
    /// Objects.
    pub geometry: Aggregate,
    /// Names of `materials`, as in the scene file.
    pub material_names: Vec<String>,
    /// Material index of each object of `geometry`.
    pub object_material: Vec<usize>,
}
