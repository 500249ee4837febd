//! # isolux-render
//!
//! From a [`Scene`] to an [`isolux_core::Image`]: pinhole [`Camera`], point
//! lights, environment light, the path tracer ([`integrator`]) and the
//! tiled deterministic driver ([`render()`]).
//!
//! Follow a ray: [`render()`] picks a sub-pixel position and asks the
//! [`CameraRig`] for a ray; [`integrator::radiance`] intersects it with the
//! scene's [`isolux_geometry::Aggregate`], shades the hit with the object's
//! [`isolux_materials::Material`], and continues the path.
#![warn(missing_docs)]

pub mod camera;
pub mod environment;
pub mod integrator;
pub mod light;
pub mod manifold;
pub mod realtime;
pub mod render;
pub mod scene;

pub use camera::{Camera, CameraRig};
pub use environment::{EnvMap, Environment};
pub use light::PointLight;
pub use render::{render, RenderError, RenderOptions, RenderStats};
pub use scene::{
    Caustics, FilmProblem, FilmSettings, FineMedium, FlatBoundary, IntegratorSettings,
    MediumLightSampling, RefractedLights, Scene, FINE_MEDIUM_OFFSETS,
};
