//! The viewer's camera: an orbit about the scene camera's `look_at`.
//!
//! The eye sits at `target + d (cos(pitch) (cos(yaw) u + sin(yaw) w) +
//! sin(pitch) up)`, where `(u, up, w)` is a fixed orthonormal frame around
//! the scene camera's (normalized) `up`. Dragging turns yaw and pitch (the
//! pitch stays within 89 degrees of the horizon, so `up` is never parallel
//! to the view direction), the wheel scales the distance, and a pan
//! (right or middle drag, or Shift with the left) slides the target and
//! the eye together across the view.

use glam::DVec3;
use isolux_render::Camera;

/// Largest pitch in radians (89 degrees).
const MAX_PITCH: f64 = 89.0 * std::f64::consts::PI / 180.0;
/// Radians of yaw and pitch per pixel dragged.
const RADIANS_PER_PIXEL: f64 = 0.008;
/// Distance factor per wheel step.
const ZOOM_PER_STEP: f64 = 0.9;
/// The least distance of the eye from the target.
pub const MIN_DISTANCE: f64 = 1e-4;
/// The greatest distance of the eye from the target.
pub const MAX_DISTANCE: f64 = 1e6;

/// An orbit camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    /// The point orbited (the scene camera's `look_at`).
    pub target: DVec3,
    /// World up (unit).
    pub up: DVec3,
    /// First horizontal axis (unit, perpendicular to `up`).
    u: DVec3,
    /// Second horizontal axis, `up x u`.
    w: DVec3,
    /// Eye distance from `target`.
    pub distance: f64,
    /// Angle about `up`, radians.
    pub yaw: f64,
    /// Elevation above the plane perpendicular to `up`, radians.
    pub pitch: f64,
    /// Vertical field of view in degrees.
    pub fov_y: f64,
}

impl Orbit {
    /// The orbit through `camera` (same eye, target, up and field of view,
    /// the pitch clamped to 89 degrees).
    pub fn from_camera(camera: &Camera) -> Self {
        let up = camera.up.try_normalize().unwrap_or(DVec3::Y);
        let helper = if up.x.abs() < 0.9 { DVec3::X } else { DVec3::Z };
        let u = (helper - up * helper.dot(up)).normalize();
        let w = up.cross(u);
        let offset = camera.position - camera.look_at;
        let distance = offset.length().max(1e-6);
        let mut orbit = Self {
            target: camera.look_at,
            up,
            u,
            w,
            distance,
            yaw: 0.0,
            pitch: 0.0,
            fov_y: camera.fov_y,
        };
        orbit.turn_to(offset, distance);
        orbit
    }

    /// Yaw and pitch of the eye at `offset` from the target, `distance`
    /// long (the pitch clamped to 89 degrees).
    fn turn_to(&mut self, offset: DVec3, distance: f64) {
        self.yaw = offset.dot(self.w).atan2(offset.dot(self.u));
        self.pitch = (offset.dot(self.up) / distance)
            .clamp(-1.0, 1.0)
            .asin()
            .clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// The eye position.
    pub fn eye(&self) -> DVec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        self.target + self.distance * (cp * (cy * self.u + sy * self.w) + sp * self.up)
    }

    /// The camera this orbit describes.
    pub fn camera(&self) -> Camera {
        Camera {
            position: self.eye(),
            look_at: self.target,
            up: self.up,
            fov_y: self.fov_y,
        }
    }

    /// Turns by a mouse drag of `(dx, dy)` pixels: right turns the scene
    /// to the right, down raises the eye.
    pub fn drag(&mut self, dx: f64, dy: f64) {
        self.yaw -= dx * RADIANS_PER_PIXEL;
        self.pitch = (self.pitch + dy * RADIANS_PER_PIXEL).clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// Slides the target and the eye together across the view by a drag of
    /// `(dx, dy)` (right and down) in a view `height` units tall, in the
    /// same units: the point orbited follows the cursor, as does anything
    /// at its depth. The view direction and distance do not change.
    pub fn pan(&mut self, dx: f64, dy: f64, height: f64) {
        let eye = self.eye();
        let Some(forward) = (self.target - eye).try_normalize() else {
            return;
        };
        let Some(right) = forward.cross(self.up).try_normalize() else {
            return;
        };
        let up = right.cross(forward);
        let per_unit =
            2.0 * self.distance * (0.5 * self.fov_y.to_radians()).tan() / height.max(1.0);
        self.target += per_unit * (up * dy - right * dx);
    }

    /// Turns to orbit about `p` from where the eye is: the target becomes
    /// `p`, the distance `|eye - p|`, and the view turns to centre it (a
    /// double click in the image). The eye stays put unless `p` lies
    /// within a degree of straight above or below it, where the pitch's
    /// bound moves it about `p` to 89 degrees. A point closer to the eye
    /// or farther than the zoom's range (1e-4 to 1e6) leaves the orbit
    /// as it was and returns `false`.
    pub fn focus(&mut self, p: DVec3) -> bool {
        let offset = self.eye() - p;
        let distance = offset.length();
        if !(MIN_DISTANCE..=MAX_DISTANCE).contains(&distance) {
            return false;
        }
        self.target = p;
        self.distance = distance;
        self.turn_to(offset, distance);
        true
    }

    /// Turns to orbit about `center` from the same direction, at the
    /// distance where a sphere of `radius` about it fills the vertical
    /// field of view with a margin of 10% (the `F` key frames an object
    /// this way). Returns `false`, unchanged, for a radius that is not
    /// positive and finite or a distance beyond the zoom's range.
    pub fn frame(&mut self, center: DVec3, radius: f64) -> bool {
        let half = (0.5 * self.fov_y).to_radians();
        let distance = 1.1 * radius / half.sin();
        let fits = radius > 0.0 && (MIN_DISTANCE..=MAX_DISTANCE).contains(&distance);
        if !(fits && center.is_finite()) {
            return false;
        }
        self.target = center;
        self.distance = distance;
        true
    }

    /// Moves the eye closer (`steps > 0`) or away, by 10% per step.
    pub fn zoom(&mut self, steps: f64) {
        self.distance =
            (self.distance * ZOOM_PER_STEP.powf(steps)).clamp(MIN_DISTANCE, MAX_DISTANCE);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
        (a - b).length() <= tol * (1.0 + b.length())
    }

    #[test]
    fn round_trips_cameras_within_the_pitch_range() {
        let mut s = 0x1234_5678_u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for _ in 0..200 {
            let up = DVec3::new(next(), next(), next()).normalize();
            let look_at = DVec3::new(next(), next(), next()) * 3.0;
            let mut dir = DVec3::new(next(), next(), next()).normalize();
            // Keep within 80 degrees of the horizon.
            if dir.dot(up).abs() > 0.98 {
                dir = (dir - up * dir.dot(up)).normalize();
            }
            let cam = Camera {
                position: look_at + dir * (1.0 + 5.0 * next().abs()),
                look_at,
                up,
                fov_y: 35.0,
            };
            let o = Orbit::from_camera(&cam);
            let back = o.camera();
            assert!(close(back.position, cam.position, 1e-9), "{back:?} {cam:?}");
            assert_eq!(back.look_at, cam.look_at);
            assert!(back.rig(64, 48).is_ok());
        }
    }

    #[test]
    fn dragging_keeps_the_distance_and_never_flips_over() {
        let cam = Camera {
            position: DVec3::new(0.0, 3.4, 7.2),
            look_at: DVec3::new(0.0, -0.15, 0.0),
            up: DVec3::Y,
            fov_y: 42.0,
        };
        let mut o = Orbit::from_camera(&cam);
        let d = (cam.position - cam.look_at).length();
        for k in 0..500 {
            o.drag(37.0, if k < 250 { -41.0 } else { 53.0 });
            let c = o.camera();
            assert!(((c.position - c.look_at).length() - d).abs() < 1e-9);
            assert!(o.pitch.abs() <= MAX_PITCH + 1e-12);
            assert!(c.rig(64, 48).is_ok(), "up parallel to the view at step {k}");
        }
        // Dragging right then back left returns to the start.
        let mut a = Orbit::from_camera(&cam);
        a.drag(120.0, 0.0);
        a.drag(-120.0, 0.0);
        assert!(close(a.eye(), Orbit::from_camera(&cam).eye(), 1e-12));
    }

    /// After a pan the point orbited before it projects where the cursor
    /// went (checked with the renderer's own projection), and the view's
    /// direction and distance are unchanged.
    #[test]
    fn panning_moves_the_target_with_the_cursor() {
        let cam = Camera {
            position: DVec3::new(1.0, 3.4, 7.2),
            look_at: DVec3::new(0.5, -0.15, 0.0),
            up: DVec3::Y,
            fov_y: 42.0,
        };
        let (w, h) = (640, 360);
        let mut o = Orbit::from_camera(&cam);
        o.drag(50.0, 20.0);
        for (dx, dy) in [(30.0, 0.0), (0.0, -25.0), (-12.5, 41.0)] {
            let before = o;
            o.pan(dx, dy, h as f64);
            let (x, y) = o
                .camera()
                .rig(w, h)
                .unwrap()
                .project(before.target)
                .unwrap();
            assert!((x - (w as f64 / 2.0 + dx)).abs() < 1e-9, "{x}");
            assert!((y - (h as f64 / 2.0 + dy)).abs() < 1e-9, "{y}");
            let (a, b) = (before.camera(), o.camera());
            assert!(close(b.position - b.look_at, a.position - a.look_at, 1e-12));
            assert_eq!(
                (o.yaw, o.pitch, o.distance),
                (before.yaw, before.pitch, before.distance)
            );
        }
    }

    #[test]
    fn focusing_keeps_the_eye_and_centres_the_point() {
        let camera = Camera {
            position: DVec3::new(1.0, 2.0, 5.0),
            look_at: DVec3::new(0.0, 0.5, 0.0),
            up: DVec3::Y,
            fov_y: 40.0,
        };
        for p in [
            DVec3::new(0.7, 0.2, -0.3),
            DVec3::new(-3.0, -1.0, 2.0),
            DVec3::new(1.5, 0.0, 4.0),
        ] {
            let mut o = Orbit::from_camera(&camera);
            let eye = o.eye();
            assert!(o.focus(p));
            assert!(close(o.target, p, 1e-12));
            assert!(close(o.eye(), eye, 1e-12), "{:?} against {eye:?}", o.eye());
            // Centred: the renderer's own projection puts it mid-film.
            let rig = o.camera().rig(640, 480).unwrap();
            let (x, y) = rig.project(p).unwrap();
            assert!((x - 320.0).abs() < 1e-9 && (y - 240.0).abs() < 1e-9);
            // Orbiting now turns about p.
            o.drag(40.0, -25.0);
            assert!(((o.eye() - p).length() - (eye - p).length()).abs() < 1e-12);
        }
        // Straight below the eye: the pitch's bound moves the eye about p.
        let mut o = Orbit::from_camera(&camera);
        let eye = o.eye();
        assert!(o.focus(eye - DVec3::Y * 2.0));
        assert!((o.pitch - MAX_PITCH).abs() < 1e-12);
        assert!((o.distance - 2.0).abs() < 1e-12);
        // At the eye, or beyond the zoom's range: unchanged.
        let before = o;
        assert!(!o.focus(o.eye()));
        assert!(!o.focus(o.eye() + DVec3::X * 2e6));
        assert!(!o.focus(DVec3::NAN));
        assert_eq!(o, before);
    }

    /// A framed sphere fits the film's height, its silhouette's angular
    /// radius 1/1.1 of the half field of view, from the same direction.
    #[test]
    fn framing_fits_the_sphere_in_the_view() {
        let mut o = Orbit::from_camera(&Camera::default());
        let dir = (o.eye() - o.target).normalize();
        let (c, r) = (DVec3::new(3.0, -1.0, 2.0), 0.75);
        assert!(o.frame(c, r));
        assert_eq!(o.target, c);
        assert!(((o.eye() - o.target).normalize() - dir).length() < 1e-12);
        let half = (0.5 * o.fov_y).to_radians();
        let seen = (r / o.distance).asin();
        assert!((seen - (half.sin() / 1.1).asin()).abs() < 1e-12);
        // The sphere's top and bottom (as seen) lie inside the film.
        let rig = o.camera().rig(400, 400).unwrap();
        let [_, _, _, up] = rig.basis();
        for s in [1.0, -1.0] {
            let (_, y) = rig.project(c + s * r * up.normalize()).unwrap();
            assert!(y > 0.0 && y < 400.0, "{y}");
        }
        let before = o;
        assert!(!o.frame(c, 0.0));
        assert!(!o.frame(c, f64::INFINITY));
        assert!(!o.frame(DVec3::NAN, 1.0));
        assert!(!o.frame(c, 1e7));
        assert_eq!(o, before);
    }

    #[test]
    fn zoom_scales_the_distance() {
        let mut o = Orbit::from_camera(&Camera::default());
        o.zoom(1.0);
        assert!((o.distance - 3.6).abs() < 1e-12);
        o.zoom(-2.0);
        assert!((o.distance - 4.0 / 0.9).abs() < 1e-12);
    }
}
