//! Ray bundles for coherent culling.
//!
//! Neighbouring camera rays meet the same few perturbations. Instead of a
//! BVH walk per ray, a [`Beam`] bounds a whole tile of rays (a cone for a
//! pinhole camera, a cylinder for parallel rays), [`Aggregate::cull`]
//! lists once per tile the objects and the perturbations whose bounding
//! spheres the beam meets, and [`Aggregate::intersect_culled`] intersects
//! each ray of the tile against that list only. This is the per-tile
//! pruning of fidget's renderer, done in ray space: the answer is the same
//! exact hit as [`Aggregate::intersect`] for every ray inside the beam.
//!
//! [`Aggregate::cull`]: crate::Aggregate::cull
//! [`Aggregate::intersect_culled`]: crate::Aggregate::intersect_culled
//! [`Aggregate::intersect`]: crate::Aggregate::intersect

use isolux_core::{Aabb, DVec3};

/// A convex set of rays (origins and directions) that the rays of a tile
/// lie in. Culling against it is conservative: an item it rejects meets
/// none of its rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Beam {
    /// Rays from `origin` whose directions make an angle of at most
    /// `acos(cos_half)` with the unit `axis` (a pinhole camera's tile).
    Cone {
        /// Common origin.
        origin: DVec3,
        /// Unit axis.
        axis: DVec3,
        /// Cosine of the half-angle.
        cos_half: f64,
        /// Sine of the half-angle.
        sin_half: f64,
    },
    /// Rays along the unit `dir` whose lines pass within `radius` of the
    /// line through `point` along `dir` (an orthographic tile).
    Cylinder {
        /// A point on the axis.
        point: DVec3,
        /// Unit direction of every ray.
        dir: DVec3,
        /// Radius.
        radius: f64,
    },
}

/// Relative slack added to every beam, so that rounding in the rays'
/// construction never puts a ray outside its tile's beam.
const SLACK: f64 = 1e-7;

impl Beam {
    /// The smallest cone around the mean direction that holds the rays
    /// from `origin` along `corners` (any lengths), and so every ray
    /// through their convex hull: for a pinhole camera, the four corner
    /// rays of a rectangle of the film bound every ray through it. `None`
    /// when a corner is zero or the rays span a half-space or more (no
    /// useful cone).
    pub fn cone(origin: DVec3, corners: &[DVec3]) -> Option<Beam> {
        let units: Vec<DVec3> = corners
            .iter()
            .map(|d| d.try_normalize())
            .collect::<Option<_>>()?;
        let axis = units.iter().copied().sum::<DVec3>().try_normalize()?;
        let cos_half = units.iter().map(|u| u.dot(axis)).fold(1.0f64, f64::min);
        if !(cos_half > 0.0) {
            return None;
        }
        // Widen by a relative hair (an angle of SLACK radians and more).
        let half = cos_half.clamp(-1.0, 1.0).acos() * (1.0 + SLACK) + SLACK;
        (half < 0.5 * std::f64::consts::PI).then(|| Beam::Cone {
            origin,
            axis,
            cos_half: half.cos(),
            sin_half: half.sin(),
        })
    }

    /// The thinnest cylinder around `dir` (any length) through the centroid
    /// of `origins` that holds the parallel rays from `origins`, and so
    /// every parallel ray from their convex hull. `None` when `dir` is zero
    /// or `origins` is empty.
    pub fn cylinder(dir: DVec3, origins: &[DVec3]) -> Option<Beam> {
        let dir = dir.try_normalize()?;
        if origins.is_empty() {
            return None;
        }
        let point = origins.iter().copied().sum::<DVec3>() / origins.len() as f64;
        let radius = origins
            .iter()
            .map(|&o| off_axis(o - point, dir))
            .fold(0.0f64, f64::max);
        let scale = radius.max(point.abs().max_element()).max(1.0);
        Some(Beam::Cylinder {
            point,
            dir,
            radius: radius * (1.0 + SLACK) + SLACK * scale,
        })
    }

    /// Whether some ray of the beam may meet the ball of `radius` around
    /// `centre` (conservative: `true` when unsure).
    pub fn meets_sphere(&self, centre: DVec3, radius: f64) -> bool {
        match *self {
            Beam::Cone {
                origin,
                axis,
                cos_half,
                sin_half,
            } => {
                let v = centre - origin;
                let d2 = v.length_squared();
                if d2 <= radius * radius {
                    return true;
                }
                let dist = d2.sqrt();
                // The ball subtends a cone of half-angle alpha around v:
                // the cones overlap when the angle between the axes is at
                // most half + alpha.
                let sin_a = radius / dist;
                let cos_a = (1.0 - sin_a * sin_a).max(0.0).sqrt();
                // half < pi/2 and alpha <= pi/2, so half + alpha < pi,
                // where the cosine decreases.
                let cos_sum = cos_half * cos_a - sin_half * sin_a;
                v.dot(axis) >= cos_sum * dist
            }
            Beam::Cylinder {
                point,
                dir,
                radius: r,
            } => off_axis(centre - point, dir) <= r + radius,
        }
    }

    /// The beam moved by `v` (into an object's frame, say).
    pub fn translated(&self, v: DVec3) -> Beam {
        let mut moved = *self;
        match &mut moved {
            Beam::Cone { origin, .. } => *origin += v,
            Beam::Cylinder { point, .. } => *point += v,
        }
        moved
    }

    /// Whether some ray of the beam may meet `b` (through its
    /// circumscribed sphere; `true` for infinite boxes).
    pub fn meets_box(&self, b: &Aabb) -> bool {
        if b.is_empty() {
            return false;
        }
        if !b.is_finite() {
            return true;
        }
        self.meets_sphere(b.center(), 0.5 * (b.max - b.min).length())
    }
}

/// Distance of `v` from the line through the origin along the unit `dir`.
fn off_axis(v: DVec3, dir: DVec3) -> f64 {
    (v - v.dot(dir) * dir).length()
}

#[cfg(test)]
mod tests {
    use super::*;
    use isolux_core::{sampling::uniform_sphere, Pcg32};

    /// Brute force: does the ray from `o` along unit `d` meet the ball?
    fn ray_meets(o: DVec3, d: DVec3, c: DVec3, r: f64) -> bool {
        let v = c - o;
        let t = v.dot(d).max(0.0);
        (o + t * d - c).length() <= r
    }

    #[test]
    fn cones_never_reject_a_ball_that_a_ray_inside_meets() {
        let mut rng = Pcg32::new(5, 2);
        let mut kept_misses = 0;
        for _ in 0..300 {
            let origin = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5;
            let axis = uniform_sphere(rng.next_2d());
            let (u, v) = axis.any_orthonormal_pair();
            let w = 0.3 * rng.next_f64();
            let corners: Vec<DVec3> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                .iter()
                .map(|&(a, b)| axis + w * (a * u + 0.6 * b * v))
                .collect();
            let beam = Beam::cone(origin, &corners).unwrap();
            for _ in 0..50 {
                let c = origin + uniform_sphere(rng.next_2d()) * 3.0 * rng.next_f64();
                let r = 0.2 * rng.next_f64();
                let any = (0..200).any(|_| {
                    let (a, b) = (rng.next_f64() * 2.0 - 1.0, rng.next_f64() * 2.0 - 1.0);
                    let d = (axis + w * (a * u + 0.6 * b * v)).normalize();
                    ray_meets(origin, d, c, r)
                });
                let kept = beam.meets_sphere(c, r);
                assert!(kept || !any, "a ray of the beam meets a rejected ball");
                kept_misses += (kept && !any) as u32;
            }
        }
        // The test is not trivially "keep everything".
        assert!(kept_misses < 1000, "{kept_misses}");
    }

    #[test]
    fn cylinders_never_reject_a_ball_that_a_ray_inside_meets() {
        let mut rng = Pcg32::new(6, 2);
        let mut rejected = 0;
        for _ in 0..300 {
            let dir = uniform_sphere(rng.next_2d());
            let (u, v) = dir.any_orthonormal_pair();
            let centre = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
            let w = 0.2 * rng.next_f64();
            let origins: Vec<DVec3> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                .iter()
                .map(|&(a, b)| centre + w * (a * u + b * v))
                .collect();
            let beam = Beam::cylinder(-dir * 2.0, &origins).unwrap();
            for _ in 0..50 {
                let c = centre + uniform_sphere(rng.next_2d()) * rng.next_f64();
                let r = 0.1 * rng.next_f64();
                let meets = (0..200).any(|_| {
                    let (a, b) = (rng.next_f64() * 2.0 - 1.0, rng.next_f64() * 2.0 - 1.0);
                    let o = centre + w * (a * u + b * v);
                    ray_meets(o, -dir, c, r) || ray_meets(o, dir, c, r)
                });
                let kept = beam.meets_sphere(c, r);
                assert!(kept || !meets);
                rejected += !kept as u32;
            }
        }
        assert!(rejected > 1000, "{rejected}");
    }

    #[test]
    fn degenerate_bundles_give_no_beam() {
        assert!(Beam::cone(DVec3::ZERO, &[DVec3::X, -DVec3::X]).is_none());
        assert!(Beam::cone(DVec3::ZERO, &[DVec3::ZERO]).is_none());
        assert!(Beam::cylinder(DVec3::ZERO, &[DVec3::ONE]).is_none());
        assert!(Beam::cylinder(DVec3::Z, &[]).is_none());
    }
}
