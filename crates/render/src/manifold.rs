//! Point lights seen through one smooth, curved refracting boundary:
//! manifold next-event estimation (Hanika, Droske and Fascione,
//! "Manifold Next Event Estimation", EGSR 2015).
//!
//! A point `p` inside a random-walk medium whose boundary is a smooth
//! dielectric (index `n_in` inside, `n_out` outside) cannot be reached
//! from a point light `L` outside by a shadow ray: the light bends at the
//! boundary. The path `L -> x -> p` that does reach it crosses the
//! surface at a point `x` where Snell's law holds,
//!
//! `n_out w_o + n_in w_i  parallel to  n(x)`,
//!
//! `w_o = (L - x) / |L - x|`, `w_i = (p - x) / |p - x|`, `n(x)` the unit
//! normal of `F'(x) = 0` (the *generalized half vector* of the paper
//! along the normal). [`connect`] finds `x` by Newton's method on the
//! constraint's two tangential components, starting where the straight
//! segment from `p` to the light meets the surface, with each iterate
//! projected back onto `F' = 0` (Newton steps along `grad F'`). The
//! constraint's Jacobian is exact, the normal's derivative (the
//! surface's curvature) from the Hessian of `F'` (`Object::hessian`), so
//! any `F'` the geometry crate evaluates works, perturbed surfaces
//! included. Points found unreachable (beyond the
//! refracted rays' reach, near the shadow edge of a convex boundary:
//! most of the solves that fail) are dropped.
//!
//! The light's irradiance at `p`, normal to the arriving ray, is `I T G`
//! with the Fresnel transmittance `T(theta_out)` and the *spreading*
//! `G = dOmega_L / dA_p`: the solid angle at the light of the rays that
//! land in a small area `dA_p` around `p` normal to the ray. By the
//! implicit function theorem, moving `p` by a unit `u` across the ray
//! moves the solution along the surface by `dx = -J^-1 (dC/dp) u` (`J`
//! the constraint's Jacobian at the solution, `dC/dp` exact: only `w_i`
//! moves with `p`), which subtends `dOmega = |(dx_1 x dx_2) . l| / D^3`
//! at the light (`l = x - L`, `D = |l|`). For a plane it equals the
//! closed form of the flat boundaries
//! (`integrator::refraction`), and on a sphere's axis the paraxial
//! `1 / (s^2 (1 - z / s')^2)` (the light at `s` before the vertex, its
//! image at `s'`, `p` at depth `z`); both are tested below.
//!
//! **What it misses.** One solution per light: where several refracted
//! rays reach `p` (behind a caustic, as in a ball lens of index above 2)
//! it finds the one nearest the straight segment's crossing, and where
//! Newton's method fails to converge (grazing crossings, a surface
//! folded between `p` and the light) the connection is dropped. Both
//! lose light, never add it. Paths that reflect inside before leaving,
//! or cross two refracting surfaces, are left to the random walk.

use isolux_core::{DVec2, DVec3, Frame, Ray};
use isolux_geometry::Object;

/// A solved refracted connection from a point light to a point inside an
/// object ([`connect`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Connection {
    /// The crossing point on the surface.
    pub x: DVec3,
    /// The outward unit normal there.
    pub normal: DVec3,
    /// The cosine between the light's ray (toward the light) and the
    /// outward normal.
    pub cos_out: f64,
    /// The spreading `G = dOmega_L / dA_p` (per unit area normal to the
    /// arriving ray): the irradiance at `p` per unit intensity, before
    /// the Fresnel transmittance and any attenuation.
    pub spread: f64,
}

/// Newton iterations of one solve at most.
const MAX_ITERATIONS: usize = 40;

/// The crossing of the refracted path from a light at `light` to `p`, a
/// point inside `obj` (`F' > 0`), through its surface: index `n_in`
/// inside, `n_out` outside. `None` where the straight segment from `p`
/// to the light does not leave the object, where the solve does not
/// converge, or where the solution is not the first crossing seen from
/// `p` (the segment from `p` to `x` leaves the object earlier).
pub fn connect(obj: &Object, p: DVec3, light: DVec3, n_in: f64, n_out: f64) -> Option<Connection> {
    let to_light = light - p;
    let dist = to_light.length();
    if !(dist > 0.0) {
        return None;
    }
    let seed = obj.intersect(&Ray::new(p, to_light / dist), 0.0, dist)?.p;
    let c = connect_from(obj, p, light, n_in, n_out, seed)?;
    // The solution must be the first crossing seen from p.
    let to_x = c.x - p;
    let lx = to_x.length();
    let first = obj.intersect(&Ray::new(p, to_x / lx), 0.0, lx * (1.0 + 1e-6))?;
    ((first.p - c.x).length() <= 1e-6 * (1.0 + lx)).then_some(c)
}

/// [`connect`] from `seed`, a point on the surface where the solve
/// starts (the straight segment's crossing, which the caller found),
/// without checking that the solution is the first crossing seen from
/// `p` (the caller's visibility test of the segment does).
pub fn connect_from(
    obj: &Object,
    p: DVec3,
    light: DVec3,
    n_in: f64,
    n_out: f64,
    seed: DVec3,
) -> Option<Connection> {
    if !(n_in > 0.0) || !(n_out > 0.0) {
        return None;
    }
    let sol = solve(obj, p, light, n_in, n_out, seed)?;
    let x = sol.x;
    let to_x = x - p;
    let lx = to_x.length();
    if !(lx > 0.0) {
        return None;
    }
    let normal = sol.frame.n;
    let wo = (light - x).normalize();
    let cos_out = wo.dot(normal);
    if !(cos_out > 0.0) {
        return None;
    }
    // The spreading, by the implicit function theorem: moving p by a
    // unit u across the arriving ray moves the solution along the surface
    // by dx = -J^-1 (dC/dp) u, and the light's direction by what dx
    // subtends from the light: dOmega = |(dx_1 x dx_2) . l| / D^3 per
    // unit area at p (l = x - L, D = |l|).
    let wi = -to_x / lx;
    let f = Frame::from_normal(wi);
    let mut dx = [DVec3::ZERO; 2];
    for (d, u) in dx.iter_mut().zip([f.s, f.t]) {
        // dC/dp u: only w_i moves with p.
        let dwi = n_in * (u - wi.dot(u) * wi) / lx;
        let [a, b] = sol.step([dwi.dot(sol.frame.s), dwi.dot(sol.frame.t)])?;
        *d = -(a * sol.frame.s + b * sol.frame.t);
    }
    let to_l = x - light;
    let dl = to_l.length();
    let spread = dx[0].cross(dx[1]).dot(to_l).abs() / (dl * dl * dl);
    (spread > 0.0 && spread.is_finite()).then_some(Connection {
        x,
        normal,
        cos_out,
        spread,
    })
}

/// A converged [`solve`]: the crossing, its tangent frame (normal `n`)
/// and the constraint's Jacobian in that frame's tangents.
struct Solution {
    x: DVec3,
    frame: Frame,
    jac: [[f64; 2]; 2],
}

impl Solution {
    /// `J^-1 d` (`None` for a singular Jacobian).
    fn step(&self, d: [f64; 2]) -> Option<[f64; 2]> {
        inverse_times(&self.jac, d)
    }
}

/// `m^-1 d` for a 2 x 2 matrix `m`.
fn inverse_times(m: &[[f64; 2]; 2], d: [f64; 2]) -> Option<[f64; 2]> {
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    if !(det.abs() > 0.0) || !det.is_finite() {
        return None;
    }
    Some([
        (m[1][1] * d[0] - m[0][1] * d[1]) / det,
        (-m[1][0] * d[0] + m[0][0] * d[1]) / det,
    ])
}

/// Newton's method on the surface for the crossing, from `seed` (a point
/// on it): each step solves the linearized tangential constraint in the
/// current point's tangent frame and projects the moved point back onto
/// `F' = 0`, halving a step that does not reduce the constraint (the
/// Jacobian: [`jacobian`]).
fn solve(
    obj: &Object,
    p: DVec3,
    light: DVec3,
    n_in: f64,
    n_out: f64,
    seed: DVec3,
) -> Option<Solution> {
    let scale = (light - p).length();
    let mut x = project(obj, seed, scale)?;
    // The gradient at x, kept for the Jacobian; the normal is
    // `Object::normal`'s, from it.
    let mut g = obj.gradient(x);
    let tol = 1e-12 * (n_in + n_out);
    for _ in 0..MAX_ITERATIONS {
        let n = (-g).normalize_or_zero();
        let frame = Frame::from_normal(n);
        let c = constraint(n, x, p, light, n_in, n_out, &frame)?;
        // (Lengths by glam, not `f64::hypot`, whose guard against overflow
        // took a tenth of the solve's time: constraints are of the order of
        // the indices and steps of the scene's size.)
        let norm = DVec2::from(c).length();
        let jac = jacobian(obj, x, n, g.length(), p, light, n_in, n_out, &frame)?;
        if norm < tol {
            return Some(Solution { x, frame, jac });
        }
        let [a, b] = inverse_times(&jac, c)?;
        let mut step = [-a, -b];
        // At most a quarter of the distance to p per step.
        let len = DVec2::from(step).length();
        let cap = 0.25 * (x - p).length();
        if len > cap {
            step = [step[0] * cap / len, step[1] * cap / len];
        }
        let mut next = None;
        for _ in 0..12 {
            if let Some(y) = project(obj, x + step[0] * frame.s + step[1] * frame.t, scale) {
                let gy = obj.gradient(y);
                let ny = (-gy).normalize_or_zero();
                if let Some(cy) = constraint(ny, y, p, light, n_in, n_out, &Frame::from_normal(ny))
                {
                    if DVec2::from(cy).length() < norm {
                        next = Some((y, gy));
                        break;
                    }
                }
            }
            step = [0.5 * step[0], 0.5 * step[1]];
        }
        (x, g) = next?;
    }
    None
}

/// The constraint's Jacobian at `x` (unit normal `n`) along the tangents
/// of `f` (`g`: `|grad F'|` there), column `k` for a move along tangent
/// `k`: with `h = n_out w_o +
/// n_in w_i`, `dC = P (dh - (h . n) dn)`, `dw = -(u - (w . u) w) / r` for
/// each unit direction `w` at distance `r`, and the normal's derivative
/// `dn = -(I - n n^T) H u / |grad F'|` from the exact Hessian `H` of `F'`
/// ([`Object::hessian`]; the normal is `-grad F' / |grad F'|`). Exact, so
/// that a point `p` close to the surface costs the solve no precision and
/// no difference step needs choosing. (Until 2026-12-04 `dn` came from
/// central differences of the normal: four gradients instead of one
/// Hessian.)
#[allow(clippy::too_many_arguments)]
fn jacobian(
    obj: &Object,
    x: DVec3,
    n: DVec3,
    g: f64,
    p: DVec3,
    light: DVec3,
    n_in: f64,
    n_out: f64,
    f: &Frame,
) -> Option<[[f64; 2]; 2]> {
    let (to_l, to_p) = (light - x, p - x);
    let (rl, rp) = (to_l.length(), to_p.length());
    if !(rl > 0.0) || !(rp > 0.0) || !(g > 0.0) {
        return None;
    }
    let (wo, wi) = (to_l / rl, to_p / rp);
    let hn = (n_out * wo + n_in * wi).dot(n);
    let hess = obj.hessian(x);
    let mut jac = [[0.0; 2]; 2];
    for (k, u) in [f.s, f.t].into_iter().enumerate() {
        let dh = -n_out * (u - wo.dot(u) * wo) / rl - n_in * (u - wi.dot(u) * wi) / rp;
        let hu = hess * u;
        let dn = -(hu - hu.dot(n) * n) / g;
        let dc = dh - hn * dn;
        jac[0][k] = dc.dot(f.s);
        jac[1][k] = dc.dot(f.t);
    }
    Some(jac)
}

/// The tangential part of `n_out w_o + n_in w_i` at `x` (unit normal
/// `n`) in the tangents of frame `f` (zero where Snell's law holds).
fn constraint(
    n: DVec3,
    x: DVec3,
    p: DVec3,
    light: DVec3,
    n_in: f64,
    n_out: f64,
    f: &Frame,
) -> Option<[f64; 2]> {
    let wo = (light - x).try_normalize()?;
    let wi = (p - x).try_normalize()?;
    let h = n_out * wo + n_in * wi;
    let t = h - h.dot(n) * n;
    Some([t.dot(f.s), t.dot(f.t)])
}

/// The point of `F' = 0` reached from `y` by Newton steps along the
/// gradient; `None` if they do not settle (to `1e-13 scale`).
fn project(obj: &Object, y: DVec3, scale: f64) -> Option<DVec3> {
    let mut y = y;
    let tol = 1e-13 * (scale + y.abs().max_element());
    for _ in 0..20 {
        let g = obj.gradient(y);
        let g2 = g.length_squared();
        if !(g2 > 0.0) || !g2.is_finite() {
            return None;
        }
        let v = obj.eval(y);
        let step = v / g2;
        y -= step * g;
        if (step * g2.sqrt()).abs() <= tol {
            return Some(y);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use isolux_geometry::Quadric;

    fn sphere(center: DVec3, r: f64) -> Object {
        Object::new(Quadric::sphere(center, r), Vec::new(), None).unwrap()
    }

    /// On the axis of a sphere the spreading is the paraxial closed
    /// form: a light at distance `s` before the vertex has its image at
    /// `s'` (`n_out / s + n_in / s' = (n_in - n_out) / R`), and the beam
    /// of solid angle `dOmega` that covered `s^2 dOmega` at the vertex
    /// covers `s^2 (1 - z / s')^2 dOmega` at depth `z`.
    #[test]
    fn spreading_on_a_spheres_axis_is_paraxial() {
        for (r, n_in, n_out, s, z) in [
            (1.0, 1.33, 1.0, 2.0, 0.5),
            (1.0, 1.5, 1.0, 5.0, 1.7),
            (2.0, 1.33, 1.1, 0.3, 3.0),
            (1.0, 0.8, 1.0, 1.0, 0.4),
        ] {
            let o = sphere(DVec3::ZERO, r);
            let light = DVec3::new(0.0, r + s, 0.0);
            let p = DVec3::new(0.0, r - z, 0.0);
            let c = connect(&o, p, light, n_in, n_out).unwrap();
            let s_img = n_in / ((n_in - n_out) / r - n_out / s);
            let want = 1.0 / (s * s * (1.0 - z / s_img).powi(2));
            assert!(
                (c.spread / want - 1.0).abs() < 1e-4,
                "R {r} n {n_in}/{n_out} s {s} z {z}: {} vs {want}",
                c.spread
            );
            assert!((c.x - DVec3::new(0.0, r, 0.0)).length() < 1e-9);
            assert!((c.cos_out - 1.0).abs() < 1e-12);
        }
    }

    /// Under a plane the spreading is the flat boundary's closed form,
    /// computed here from the landing radius `R(theta_1) = h1 tan theta_1
    /// + h2 tan theta_2` (bisection for the crossing, `dR/dtheta_1` by
    /// central differences): `G = sin theta_1 / (R cos theta_2 dR/dtheta_1)`.
    #[test]
    fn spreading_under_a_plane_is_the_flat_closed_form() {
        let o = Object::new(Quadric::plane(DVec3::ZERO, DVec3::Y), Vec::new(), None).unwrap();
        for (n_in, n_out, light, p) in [
            (
                1.33,
                1.0,
                DVec3::new(0.8, 3.0, -1.2),
                DVec3::new(0.1, -2.0, 0.4),
            ),
            (
                1.5,
                1.2,
                DVec3::new(-2.0, 0.5, 0.0),
                DVec3::new(3.0, -0.7, 1.0),
            ),
            (
                0.9,
                1.0,
                DVec3::new(0.2, 1.0, 0.1),
                DVec3::new(0.5, -0.5, 0.3),
            ),
        ] {
            let c = connect(&o, p, light, n_in, n_out).unwrap();
            let (h1, h2) = (light.y, -p.y);
            let d = DVec3::new(light.x - p.x, 0.0, light.z - p.z).length();
            let radius = |t1: f64| {
                let s2 = n_out / n_in * t1.sin();
                h1 * t1.tan() + h2 * s2 / (1.0 - s2 * s2).sqrt()
            };
            let (mut lo, mut hi) = (0.0, std::f64::consts::FRAC_PI_2 - 1e-9);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if radius(mid) < d {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let t1 = 0.5 * (lo + hi);
            let s2 = n_out / n_in * t1.sin();
            let cos2 = (1.0 - s2 * s2).sqrt();
            let e = 1e-6;
            let dr = (radius(t1 + e) - radius(t1 - e)) / (2.0 * e);
            let want = t1.sin() / (d * cos2 * dr);
            assert!(
                (c.spread / want - 1.0).abs() < 1e-4,
                "{n_in}/{n_out}: {} vs {want}",
                c.spread
            );
            assert!((c.cos_out - t1.cos()).abs() < 1e-9);
        }
    }

    /// Off the axis of a sphere, against photon tracing: a stratified
    /// grid of rays over the light's cone toward the sphere, refracted at
    /// the surface (Snell's law in vector form), their track lengths in a
    /// small ball around `p` summed: the ball's mean fluence, which equals
    /// the irradiance normal to the single ray through `p`.
    #[test]
    fn spreading_off_a_spheres_axis_matches_photon_tracing() {
        let (r, n_in, n_out) = (1.0, 1.33, 1.0);
        let o = sphere(DVec3::ZERO, r);
        let light = DVec3::new(0.3, 3.0, 0.2);
        let p = DVec3::new(0.35, -0.2, 0.1);
        let c = connect(&o, p, light, n_in, n_out).unwrap();
        let rho = 0.04;
        let axis = -light.normalize();
        let f = Frame::from_normal(axis);
        let cos_max = (1.0 - r * r / light.length_squared()).sqrt();
        let omega = 2.0 * std::f64::consts::PI * (1.0 - cos_max);
        let n = 1500;
        let mut track = 0.0;
        for i in 0..n {
            let ct = 1.0 - (1.0 - cos_max) * (i as f64 + 0.5) / n as f64;
            let st = (1.0 - ct * ct).sqrt();
            for j in 0..n {
                let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / n as f64;
                let d = f.to_world(DVec3::new(st * phi.cos(), st * phi.sin(), ct));
                // Enter the sphere.
                let b = light.dot(d);
                let disc = b * b - (light.length_squared() - r * r);
                if disc <= 0.0 {
                    continue;
                }
                let x = light + (-b - disc.sqrt()) * d;
                let nrm = x / r;
                let eta = n_out / n_in;
                let ci = -d.dot(nrm);
                let k = 1.0 - eta * eta * (1.0 - ci * ci);
                let t = eta * d + (eta * ci - k.sqrt()) * nrm;
                // Its track in the ball around p.
                let m = (p - x).dot(t);
                let q2 = (p - x).length_squared() - m * m;
                if q2 < rho * rho {
                    track += 2.0 * (rho * rho - q2).sqrt();
                }
            }
        }
        let fluence =
            track * (omega / (n * n) as f64) / (4.0 / 3.0 * std::f64::consts::PI * rho.powi(3));
        eprintln!("spread {} against photon tracing {fluence}", c.spread);
        assert!(
            (c.spread / fluence - 1.0).abs() < 0.005,
            "{} vs photon tracing {fluence}",
            c.spread
        );
    }
}
