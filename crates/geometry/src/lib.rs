//! # isolux-geometry
//!
//! Functionally defined objects (SPEC §1): a base quadric `F` plus
//! perturbations `f_i Q_i^3 [Q_i >= 0]`, intersected exactly along rays.
//!
//! ```
//! use isolux_geometry::{Object, Perturbation, Quadric};
//! use isolux_core::{DVec3, Ray};
//! let base = Quadric::sphere(DVec3::ZERO, 0.6);
//! let bump = Perturbation { quadric: Quadric::sphere(DVec3::new(0.0, 0.0, 0.6), 0.2), factor: 200.0 };
//! let obj = Object::new(base, vec![bump], None).unwrap();
//! let hit = obj.intersect(&Ray::new(DVec3::new(0.0, 0.0, 3.0), -DVec3::Z), 0.0, f64::INFINITY).unwrap();
//! assert!(hit.p.z > 0.6); // the bump stands out of the sphere
//! ```
#![warn(missing_docs)]

pub mod aggregate;
pub mod beam;
pub mod bvh;
pub mod object;
pub mod poly;
pub mod quadric;
pub mod samples;
pub mod simd;

pub use aggregate::{Aggregate, Culled};
pub use beam::Beam;
pub use object::{GeometryError, Hit, Object, Perturbation};
pub use quadric::Quadric;
