//! Pinhole camera.

use isolux_core::{DVec3, Ray};

/// A pinhole camera: rays leave `position` through a film plane at unit
/// distance along the view direction; `fov_y` is the full vertical field of
/// view. Pixel `(0, 0)` is the top-left corner; `x` grows to the right.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub position: DVec3,
    /// Point looked at.
    pub look_at: DVec3,
    /// Up hint (need not be orthogonal to the view direction).
    pub up: DVec3,
    /// Vertical field of view in degrees.
    pub fov_y: f64,
}

impl Default for Camera {
    fn default() -> Self {
        Self {
            position: DVec3::new(0.0, 0.0, 4.0),
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            fov_y: 40.0,
        }
    }
}

/// A camera prepared for an image size.
#[derive(Clone, Copy, Debug)]
pub struct CameraRig {
    origin: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    width: f64,
    height: f64,
}

impl Camera {
    /// Prepares ray generation for a `width x height` image. Fails when the
    /// view direction is zero or parallel to `up`.
    pub fn rig(&self, width: u32, height: u32) -> Result<CameraRig, String> {
        let forward = (self.look_at - self.position)
            .try_normalize()
            .ok_or("camera position equals look_at")?;
        let right = forward
            .cross(self.up)
            .try_normalize()
            .ok_or("camera up is parallel to the view direction")?;
        let up = right.cross(forward);
        if !(self.fov_y > 0.0 && self.fov_y < 180.0) {
            return Err("fov_y must lie in (0, 180) degrees".into());
        }
        let tan = (self.fov_y.to_radians() * 0.5).tan();
        let aspect = width as f64 / height as f64;
        Ok(CameraRig {
            origin: self.position,
            forward,
            right: right * tan * aspect,
            up: up * tan,
            width: width as f64,
            height: height as f64,
        })
    }

    /// Width of one pixel's footprint at distance `t` along a camera ray,
    /// for an image `height` pixels tall: the vertical field of view
    /// divided among the rows, times the distance (`2 t tan(fov_y / 2) /
    /// height`). Spatially varying materials (wave optics) narrow their
    /// query to it; the GPU's `pixel_footprint` mirrors it.
    pub fn pixel_footprint(&self, t: f64, height: u32) -> f64 {
        t * 2.0 * (0.5 * self.fov_y.to_radians()).tan() / height.max(1) as f64
    }
}

impl CameraRig {
    /// `[origin, forward, right, up]`: the ray through film position
    /// `(sx, sy)` in `[-1, 1]^2` (`x` right, `y` up) has the direction
    /// `forward + sx right + sy up` (`right` and `up` carry the field of
    /// view and the aspect ratio). For back ends that rebuild [`ray`].
    ///
    /// [`ray`]: CameraRig::ray
    pub fn basis(&self) -> [DVec3; 4] {
        [self.origin, self.forward, self.right, self.up]
    }

    /// The unit ray through film position `(x, y)` in pixels (continuous).
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let sx = 2.0 * x / self.width - 1.0;
        let sy = 1.0 - 2.0 * y / self.height;
        let d = self.forward + sx * self.right + sy * self.up;
        Ray::new(self.origin, d.normalize())
    }

    /// Inverse of [`CameraRig::ray`]: film position of a world point in
    /// front of the camera.
    pub fn project(&self, p: DVec3) -> Option<(f64, f64)> {
        let v = p - self.origin;
        let z = v.dot(self.forward);
        if z <= 0.0 {
            return None;
        }
        let sx = v.dot(self.right) / (z * self.right.length_squared());
        let sy = v.dot(self.up) / (z * self.up.length_squared());
        Some((
            (sx + 1.0) * 0.5 * self.width,
            (1.0 - sy) * 0.5 * self.height,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_at_target_and_projection_inverts() {
        let cam = Camera::default().rig(200, 100).unwrap();
        let r = cam.ray(100.0, 50.0);
        assert!((r.dir - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
        let r = cam.ray(13.0, 77.0);
        let (x, y) = cam.project(r.at(3.0)).unwrap();
        assert!((x - 13.0).abs() < 1e-9 && (y - 77.0).abs() < 1e-9);
        // Top edge is at +fov/2.
        let top = cam.ray(100.0, 0.0);
        assert!((top.dir.y.atan2(-top.dir.z).to_degrees() - 20.0).abs() < 1e-9);
    }

    #[test]
    fn pixel_footprint_is_the_spacing_of_neighbouring_rays() {
        // Near the image centre, two rays one row apart, followed to
        // distance t, are one footprint apart.
        let camera = Camera::default();
        let cam = camera.rig(200, 100).unwrap();
        let t = 3.0;
        let a = cam.ray(100.0, 49.5).at(t);
        let b = cam.ray(100.0, 50.5).at(t);
        let fp = camera.pixel_footprint(t, 100);
        assert!(
            ((a - b).length() - fp).abs() < 1e-4 * fp,
            "{} vs {fp}",
            (a - b).length()
        );
    }
}
