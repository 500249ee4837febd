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
    ((first.p - c.x).length() <= 1e-6 * (obj.length() + lx)).then_some(c)
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

/// A solved path from a point light through a transparent object, in at
/// `x[1]` and out at `x[0]` toward `p` ([`connect_through`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chain {
    /// The crossing points: `x[0]` next to `p`, `x[1]` next to the light.
    pub x: [DVec3; 2],
    /// The outward unit normals there.
    pub normal: [DVec3; 2],
    /// The cosines, outside the object, between each crossing's ray and
    /// its outward normal: toward `p` at `x[0]`, toward the light at
    /// `x[1]` (the Fresnel transmittance of each crossing is a function
    /// of it).
    pub cos_out: [f64; 2],
    /// The spreading `G = dOmega_L / dA_p` (per unit area normal to the
    /// ray arriving at `p`), before the Fresnel transmittances and any
    /// attenuation.
    pub spread: f64,
}

/// The path of a point light at `light` to `p` through `obj`, a
/// transparent object of index `n_in` in surroundings of index `n_out`
/// that lies between them: the light enters at `x[1]`, crosses the
/// inside in a straight line and leaves at `x[0]` toward `p`, Snell's law
/// holding at both (the *caustic* a glass marble casts). The two
/// crossings are found together by Newton's method on the four tangential
/// components of the two constraints (each constraint `C_i`, the
/// tangential part of `n_a w_a + n_b w_b` at `x_i`, depends on `x_i` and
/// its two neighbours, so the Jacobian is block tridiagonal: Hanika et
/// al. 2015, section 4), from `seeds`, where the straight segment from
/// `p` to the light enters and leaves the object. The spreading follows
/// from the same Jacobian as for one crossing: moving `p` by `u` moves the
/// crossings by `-J^-1 (dC/dp) u`, and the crossing next to the light
/// subtends `dOmega = |(dx_1 x dx_2) . l| / D^3` there.
///
/// `None` where the solve does not converge or its solution does not
/// cross the object inward at `x[1]` and outward at `x[0]`. Whether the
/// three segments are clear (and the inside one stays inside) is left to
/// the caller, which knows the scene. One solution is found: behind a
/// ball lens's focus, where several paths reach `p`, the one nearest the
/// straight segment.
pub fn connect_through(
    obj: &Object,
    p: DVec3,
    light: DVec3,
    n_in: f64,
    n_out: f64,
    seeds: [DVec3; 2],
) -> Option<Chain> {
    if !(n_in > 0.0) || !(n_out > 0.0) {
        return None;
    }
    let scale = (light - p).length();
    let (x, frames, jac) = solve_through(obj, p, light, n_in, n_out, seeds, scale)?;
    let normal = [frames[0].n, frames[1].n];
    // Crossing directions: out at x[0] toward p, in at x[1] from the light.
    let (to_p, to_l) = ((p - x[0]).try_normalize()?, (light - x[1]).try_normalize()?);
    let inner = (x[1] - x[0]).try_normalize()?;
    let cos_out = [to_p.dot(normal[0]), to_l.dot(normal[1])];
    let crosses = cos_out[0] > 0.0
        && cos_out[1] > 0.0
        && inner.dot(normal[0]) < 0.0
        && inner.dot(normal[1]) > 0.0;
    if !crosses {
        return None;
    }
    // The spreading: only C_0 moves with p (through its w toward p).
    let lp = (p - x[0]).length();
    let f = Frame::from_normal(to_p);
    let mut dx = [DVec3::ZERO; 2];
    for (d, u) in dx.iter_mut().zip([f.s, f.t]) {
        let dw = n_out * (u - to_p.dot(u) * to_p) / lp;
        let rhs = [dw.dot(frames[0].s), dw.dot(frames[0].t), 0.0, 0.0];
        let step = solve4(jac, rhs)?;
        *d = -(step[2] * frames[1].s + step[3] * frames[1].t);
    }
    let l = x[1] - light;
    let dl = l.length();
    let spread = dx[0].cross(dx[1]).dot(l).abs() / (dl * dl * dl);
    (spread > 0.0 && spread.is_finite()).then_some(Chain {
        x,
        normal,
        cos_out,
        spread,
    })
}

/// The two crossings' residuals, in their frames' tangents: `C_0` at
/// `x[0]` (neighbours `p`, outside, and `x[1]`, inside) and `C_1` at
/// `x[1]` (neighbours `x[0]`, inside, and the light, outside), each
/// [`constraint`]'s with its neighbours for `p` and the light.
fn chain_constraints(
    x: [DVec3; 2],
    frames: &[Frame; 2],
    p: DVec3,
    light: DVec3,
    n_in: f64,
    n_out: f64,
) -> Option<[f64; 4]> {
    let [a, b] = [
        constraint(frames[0].n, x[0], p, x[1], n_out, n_in, &frames[0])?,
        constraint(frames[1].n, x[1], x[0], light, n_in, n_out, &frames[1])?,
    ];
    Some([a[0], a[1], b[0], b[1]])
}

/// The 4 x 4 Jacobian of [`chain_constraints`] in the crossings' tangent
/// coordinates (column `2 j + k`: `x[j]` moved along its tangent `k`).
/// The diagonal blocks are [`jacobian`]'s (both directions move with the
/// point, the normal turns by the Hessian); the off-diagonal ones move
/// only the direction toward the other crossing, the normal being fixed.
#[allow(clippy::too_many_arguments)]
fn chain_jacobian(
    obj: &Object,
    x: [DVec3; 2],
    frames: &[Frame; 2],
    grads: [f64; 2],
    p: DVec3,
    light: DVec3,
    n_in: f64,
    n_out: f64,
) -> Option<[[f64; 4]; 4]> {
    let diagonal = [
        jacobian(
            obj,
            x[0],
            frames[0].n,
            grads[0],
            p,
            x[1],
            n_out,
            n_in,
            &frames[0],
        )?,
        jacobian(
            obj,
            x[1],
            frames[1].n,
            grads[1],
            x[0],
            light,
            n_in,
            n_out,
            &frames[1],
        )?,
    ];
    // The direction between the crossings and its length (the direction
    // from x[1] is -w, and `u - (w . u) w` is even in w).
    let inner = x[1] - x[0];
    let r = inner.length();
    let w = inner / r;
    let mut jac = [[0.0; 4]; 4];
    for i in 0..2 {
        let (f, g, j) = (&frames[i], &frames[1 - i], 1 - i);
        for row in 0..2 {
            jac[2 * i + row][2 * i..2 * i + 2].copy_from_slice(&diagonal[i][row]);
        }
        for (k, u) in [g.s, g.t].into_iter().enumerate() {
            let dc = n_in * (u - w.dot(u) * w) / r;
            jac[2 * i][2 * j + k] = dc.dot(f.s);
            jac[2 * i + 1][2 * j + k] = dc.dot(f.t);
        }
    }
    Some(jac)
}

/// `m^-1 d` for a 4 x 4 matrix, by Gaussian elimination with partial
/// pivoting (`None` for a singular one).
fn solve4(mut m: [[f64; 4]; 4], mut d: [f64; 4]) -> Option<[f64; 4]> {
    let size = m.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
    if !(size > 0.0) || !size.is_finite() {
        return None;
    }
    for col in 0..4 {
        let piv = (col..4).max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs()))?;
        if !(m[piv][col].abs() > 1e-14 * size) {
            return None;
        }
        m.swap(col, piv);
        d.swap(col, piv);
        let pivot_row = m[col];
        for row in col + 1..4 {
            let f = m[row][col] / pivot_row[col];
            for (v, p) in m[row][col..].iter_mut().zip(&pivot_row[col..]) {
                *v -= f * p;
            }
            d[row] -= f * d[col];
        }
    }
    let mut out = [0.0; 4];
    for row in (0..4).rev() {
        let s: f64 = (row + 1..4).map(|k| m[row][k] * out[k]).sum();
        out[row] = (d[row] - s) / m[row][row];
    }
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// Newton's method for [`connect_through`]: both crossings move together
/// in their tangent planes and are projected back onto `F' = 0`, a step
/// that does not reduce the residual being halved. Returns the
/// crossings, their frames and the Jacobian at the solution.
#[allow(clippy::type_complexity)]
fn solve_through(
    obj: &Object,
    p: DVec3,
    light: DVec3,
    n_in: f64,
    n_out: f64,
    seeds: [DVec3; 2],
    scale: f64,
) -> Option<([DVec3; 2], [Frame; 2], [[f64; 4]; 4])> {
    let mut x = [
        project(obj, seeds[0], scale)?,
        project(obj, seeds[1], scale)?,
    ];
    let mut g = [obj.gradient(x[0]), obj.gradient(x[1])];
    let frames_of = |g: &[DVec3; 2]| g.map(|g| Frame::from_normal((-g).normalize_or_zero()));
    let tol = 1e-12 * (n_in + n_out);
    for _ in 0..MAX_ITERATIONS {
        let frames = frames_of(&g);
        let c = chain_constraints(x, &frames, p, light, n_in, n_out)?;
        let norm = c.iter().map(|v| v * v).sum::<f64>().sqrt();
        let jac = chain_jacobian(
            obj,
            x,
            &frames,
            [g[0].length(), g[1].length()],
            p,
            light,
            n_in,
            n_out,
        )?;
        if norm < tol {
            return Some((x, frames, jac));
        }
        let mut step = solve4(jac, c)?.map(|v| -v);
        // Each crossing moves at most a quarter of its distance to its
        // nearest neighbour per step.
        let gap = (x[1] - x[0]).length();
        for (i, near) in [
            (p - x[0]).length().min(gap),
            (light - x[1]).length().min(gap),
        ]
        .into_iter()
        .enumerate()
        {
            let len = DVec2::new(step[2 * i], step[2 * i + 1]).length();
            if len > 0.25 * near {
                step[2 * i] *= 0.25 * near / len;
                step[2 * i + 1] *= 0.25 * near / len;
            }
        }
        let mut next = None;
        for _ in 0..12 {
            let moved = [0, 1].map(|i| {
                project(
                    obj,
                    x[i] + step[2 * i] * frames[i].s + step[2 * i + 1] * frames[i].t,
                    scale,
                )
            });
            if let [Some(y0), Some(y1)] = moved {
                let y = [y0, y1];
                let gy = [obj.gradient(y0), obj.gradient(y1)];
                if let Some(cy) = chain_constraints(y, &frames_of(&gy), p, light, n_in, n_out) {
                    if cy.iter().map(|v| v * v).sum::<f64>().sqrt() < norm {
                        next = Some((y, gy));
                        break;
                    }
                }
            }
            step = step.map(|v| 0.5 * v);
        }
        (x, g) = next?;
    }
    None
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use isolux_geometry::Quadric;

    fn sphere(center: DVec3, r: f64) -> Object {
        Object::new(Quadric::sphere(center, r), Vec::new(), None).unwrap()
    }

    /// Snell's law in vector form for a unit direction `d` meeting a
    /// surface of unit normal `nrm` facing against it, `eta` the ratio of
    /// the indices before and after; `None` under total internal
    /// reflection.
    fn refract(d: DVec3, nrm: DVec3, eta: f64) -> Option<DVec3> {
        let ci = -d.dot(nrm);
        let k = 1.0 - eta * eta * (1.0 - ci * ci);
        (k > 0.0).then(|| eta * d + (eta * ci - k.sqrt()) * nrm)
    }

    /// The angle from the vertical in `[0, pi/2)` at which the landing
    /// radius `radius(theta)`, increasing, reaches `foot` (bisection).
    pub(crate) fn landing_angle(radius: impl Fn(f64) -> f64, foot: f64) -> f64 {
        let (mut lo, mut hi) = (0.0, std::f64::consts::FRAC_PI_2 - 1e-9);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if radius(mid) < foot {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// Photon tracing for the spreading tests: rays from the light over a
    /// stratified `n x n` grid of the cone about `axis` out to `cos_max`,
    /// each followed by `trace` to its last straight segment (its start
    /// and unit direction; `None`: lost), and their track lengths in the
    /// ball of radius `rho` around `p`: the ball's mean fluence per unit
    /// intensity, which equals the irradiance normal to the single path
    /// through `p`, and the number of photons that crossed the ball.
    fn photon_fluence(
        axis: DVec3,
        cos_max: f64,
        n: usize,
        p: DVec3,
        rho: f64,
        trace: impl Fn(DVec3) -> Option<(DVec3, DVec3)>,
    ) -> (f64, usize) {
        let f = Frame::from_normal(axis);
        let omega = 2.0 * std::f64::consts::PI * (1.0 - cos_max);
        let (mut track, mut count) = (0.0, 0);
        for i in 0..n {
            let ct = 1.0 - (1.0 - cos_max) * (i as f64 + 0.5) / n as f64;
            let st = (1.0 - ct * ct).sqrt();
            for j in 0..n {
                let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / n as f64;
                let d = f.to_world(DVec3::new(st * phi.cos(), st * phi.sin(), ct));
                let Some((x, t)) = trace(d) else {
                    continue;
                };
                let m = (p - x).dot(t);
                let q2 = (p - x).length_squared() - m * m;
                if m > 0.0 && q2 < rho * rho {
                    track += 2.0 * (rho * rho - q2).sqrt();
                    count += 1;
                }
            }
        }
        let fluence =
            track * (omega / (n * n) as f64) / (4.0 / 3.0 * std::f64::consts::PI * rho.powi(3));
        (fluence, count)
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
            let t1 = landing_angle(radius, d);
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
        let axis = -light.normalize();
        let cos_max = (1.0 - r * r / light.length_squared()).sqrt();
        let (fluence, _) = photon_fluence(axis, cos_max, 1500, p, 0.04, |d| {
            // Into the sphere: the track from the entry on.
            let b = light.dot(d);
            let disc = b * b - (light.length_squared() - r * r);
            if disc <= 0.0 {
                return None;
            }
            let x = light + (-b - disc.sqrt()) * d;
            Some((x, refract(d, x / r, n_out / n_in)?))
        });
        eprintln!("spread {} against photon tracing {fluence}", c.spread);
        assert!(
            (c.spread / fluence - 1.0).abs() < 0.005,
            "{} vs photon tracing {fluence}",
            c.spread
        );
    }

    /// Through a glass slab (two parallel planes, one object) the
    /// spreading is a closed form: the light's ray at `theta_1` from the
    /// vertical crosses the slab at `theta_2` (`n_out sin theta_1 = n_in
    /// sin theta_2`) and lands at the radius `R = (h1 + h2) tan theta_1 +
    /// d tan theta_2` around the light's foot, arriving at `theta_1`, so
    /// `G = sin theta_1 / (R cos theta_1 dR/dtheta_1)`; straight below the
    /// light `1 / (h1 + h2 + d n_out / n_in)^2`.
    #[test]
    fn spreading_through_a_slab_is_its_closed_form() {
        for (d, n_in, n_out, light, p) in [
            (
                0.5,
                1.5,
                1.0,
                DVec3::new(0.8, 2.0, -1.2),
                DVec3::new(0.1, -1.5, 0.4),
            ),
            (
                1.0,
                1.33,
                1.1,
                DVec3::new(-1.0, 1.0, 0.0),
                DVec3::new(1.5, -1.2, 1.0),
            ),
            (
                0.2,
                2.4,
                1.0,
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(0.0, -0.6, 0.0),
            ),
        ] {
            let slab = Quadric::from_coefficients([
                0.0,
                -1.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.25 * d * d,
            ]);
            let o = Object::new(slab, Vec::new(), None).unwrap();
            let (h1, h2) = (light.y - 0.5 * d, -0.5 * d - p.y);
            let foot = DVec3::new(light.x - p.x, 0.0, light.z - p.z).length();
            let seeds = [
                p + (light - p) * (h2 / (h1 + h2 + d)),
                p + (light - p) * ((h2 + d) / (h1 + h2 + d)),
            ];
            let c = connect_through(&o, p, light, n_in, n_out, seeds).unwrap();
            let radius = |t1: f64| {
                let s2 = n_out / n_in * t1.sin();
                (h1 + h2) * t1.tan() + d * s2 / (1.0 - s2 * s2).sqrt()
            };
            let want = if foot == 0.0 {
                1.0 / (h1 + h2 + d * n_out / n_in).powi(2)
            } else {
                let t1 = landing_angle(radius, foot);
                let e = 1e-6;
                let dr = (radius(t1 + e) - radius(t1 - e)) / (2.0 * e);
                assert!((c.cos_out[1] - t1.cos()).abs() < 1e-9);
                assert!((c.cos_out[0] - t1.cos()).abs() < 1e-9);
                t1.sin() / (foot * t1.cos() * dr)
            };
            assert!(
                (c.spread / want - 1.0).abs() < 1e-4,
                "d {d} n {n_in}/{n_out}: {} vs {want}",
                c.spread
            );
            assert!((c.x[0].y + 0.5 * d).abs() < 1e-9 && (c.x[1].y - 0.5 * d).abs() < 1e-9);
        }
    }

    /// Through a glass sphere, off its axis, against photon tracing: rays
    /// over the light's cone toward the sphere, refracted in and out
    /// (Snell's law in vector form), their track lengths in a small ball
    /// around `p` below it (the ball's mean fluence: the irradiance
    /// normal to the single path through `p`, `p` lying before the
    /// caustic, where one path reaches it).
    #[test]
    fn spreading_through_a_sphere_matches_photon_tracing() {
        let (r, n_in, n_out) = (1.0, 1.5, 1.0);
        let o = sphere(DVec3::ZERO, r);
        let light = DVec3::new(0.3, 3.0, 0.2);
        let p = DVec3::new(-0.2, -1.4, 0.05);
        let dir = (light - p).normalize();
        let seeds = [0, 1].map(|k| {
            let b = p.dot(dir);
            let disc = (b * b - (p.length_squared() - r * r)).sqrt();
            p + (-b + if k == 0 { -disc } else { disc }) * dir
        });
        let c = connect_through(&o, p, light, n_in, n_out, seeds).unwrap();
        // Photons over a narrow cone around the solution's first leg (the
        // paths near it; other paths through the lens reach p as well,
        // from elsewhere on the sphere, behind its caustic).
        let axis = (c.x[1] - light).normalize();
        let (fluence, count) = photon_fluence(axis, 0.03f64.cos(), 1500, p, 0.005, |d| {
            let b = light.dot(d);
            let disc = b * b - (light.length_squared() - r * r);
            if disc <= 0.0 {
                return None;
            }
            let x = light + (-b - disc.sqrt()) * d;
            let t = refract(d, x / r, n_out / n_in)?;
            // The far side: the chord of direction t from x.
            let y = x - 2.0 * x.dot(t) * t;
            Some((y, refract(t, -y / r, n_in / n_out)?))
        });
        eprintln!(
            "spread {} against photon tracing {fluence} ({count} photons)",
            c.spread
        );
        assert!(
            (c.spread / fluence - 1.0).abs() < 0.005,
            "{} vs photon tracing {fluence}",
            c.spread
        );
        // A marble at the same place seen straight: the same light, no
        // glass, reads 1 / |L - p|^2; the lens gathers it.
        assert!(c.spread > 1.0 / (light - p).length_squared());
    }

    /// Through a perturbed glass object (a sphere with a bump on top and a
    /// dent below, so that both crossings see the perturbations' Hessian
    /// terms), against photon tracing with the exact intersection
    /// (`Object::intersect` in and out, Snell's law at its normals): the
    /// rays of a narrow cone about the solved path's first leg, their track
    /// lengths in a small ball around `p` (0.11025 against 0.10989 from
    /// 7,803 photons). With the base sphere's Hessian in place of the
    /// object's in the Jacobian the solve no longer converges.
    #[test]
    fn spreading_through_a_perturbed_object_matches_photon_tracing() {
        use isolux_geometry::Perturbation;
        let (n_in, n_out) = (1.5, 1.0);
        let o = Object::new(
            Quadric::sphere(DVec3::ZERO, 1.0),
            vec![
                Perturbation {
                    quadric: Quadric::sphere(DVec3::new(0.3, 0.9, 0.1), 0.5),
                    factor: 20.0,
                },
                Perturbation {
                    quadric: Quadric::sphere(DVec3::new(-0.1, -1.0, 0.0), 0.5),
                    factor: -30.0,
                },
            ],
            None,
        )
        .unwrap();
        let light = DVec3::new(0.4, 3.0, 0.3);
        let p = DVec3::new(0.05, -1.3, 0.1);
        let dir = (light - p).normalize();
        let entry = o.intersect(&Ray::new(p, dir), 0.0, f64::INFINITY).unwrap();
        let exit = o
            .intersect(&Ray::new(entry.spawn(dir), dir), 0.0, f64::INFINITY)
            .unwrap();
        let c = connect_through(&o, p, light, n_in, n_out, [entry.p, exit.p]).unwrap();
        let axis = (c.x[1] - light).normalize();
        let (fluence, count) = photon_fluence(axis, 0.015f64.cos(), 800, p, 0.005, |d| {
            let a = o.intersect(&Ray::new(light, d), 0.0, f64::INFINITY)?;
            let t = refract(d, a.n, n_out / n_in)?;
            let b = o.intersect(&Ray::new(a.spawn(t), t), 0.0, f64::INFINITY)?;
            Some((b.p, refract(t, -b.n, n_in / n_out)?))
        });
        eprintln!(
            "spread {} against photon tracing {fluence} ({count} photons)",
            c.spread
        );
        assert!(count > 5000, "{count}");
        assert!(
            (c.spread / fluence - 1.0).abs() < 0.01,
            "{} vs photon tracing {fluence}",
            c.spread
        );
    }
}
