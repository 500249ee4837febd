// Light through curved boundaries (crates/render/src/manifold.rs): a
// point light refracted into a random-walk medium through its curved
// surface (`manifold_refraction`), and caustics, point lights through
// glass (`caustic`), both by Newton's method on the surfaces. Part of the
// path tracer's module (source.rs `RENDER_FILES`).

// ---- Manifold next-event estimation (manifold.rs) --------------------------
//
// A point light reaching a point p inside a random-walk medium through its
// curved boundary (integrator/refraction.rs `manifold_refraction`): Newton's method
// on the surface for the crossing x where `n_out w_o + n_in w_i` lies
// along the normal, from the straight segment's crossing, each iterate
// projected back onto F' = 0; the spreading `dOmega_L / dA_p` from the
// implicit function theorem, `|(dx_1 x dx_2) . l| / D^3` (l = x - L)
// for p moved by a unit across the arriving ray. The Jacobian is exact,
// the normal's derivative from the Hessian (`object_curvature`).

// F' of object oi at x (the GPU's coordinates) and its gradient.
fn object_field(oi: u32, x_gpu: vec3<f32>) -> vec4<f32> {
    let obj = objects[oi];
    let x = vec3<real>(x_gpu - obj.origin.xyz);
    let xb = base_local(obj, x);
    var v = vec4<real>(q_eval(obj.base, xb), q_grad(obj.base, xb));
    let first = obj.range.x;
    for (var k = first; k < first + obj.range.y; k++) {
        let pert = perturbations[k];
        let xp = pert_local(pert, x);
        let qv = q_eval(pert.q, xp);
        if (qv > 0.0) {
            let f = real(pert.factor.x);
            v += vec4<real>(f * qv * qv * qv, 3.0 * f * qv * qv * q_grad(pert.q, xp));
        }
    }
    return vec4<f32>(v);
}

// The outward unit normal of object oi at x.
fn object_normal_at(oi: u32, x: vec3<f32>) -> vec3<f32> {
    return -normalize(object_field(oi, x).yzw);
}

// From y back onto F' = 0 by Newton steps along the gradient; w = 0
// where they do not settle.
fn manifold_project(oi: u32, y0: vec3<f32>, scale: f32) -> vec4<f32> {
    var y = y0;
    let tol = 1e-6 * scale;
    for (var k = 0u; k < 12u; k++) {
        let f = object_field(oi, y);
        let g2 = dot(f.yzw, f.yzw);
        if (!(g2 > 0.0) || !finite(g2)) {
            return vec4<f32>(y, 0.0);
        }
        let step = f.x / g2;
        y -= step * f.yzw;
        if (abs(step) * sqrt(g2) <= tol) {
            return vec4<f32>(y, 1.0);
        }
    }
    return vec4<f32>(y, 0.0);
}

// The tangential part of `n_out w_o + n_in w_i` at x (normal n) in the
// tangents s, t.
fn manifold_constraint(n: vec3<f32>, x: vec3<f32>, p: vec3<f32>, light: vec3<f32>,
                       n_in: f32, n_out: f32, fr: Frame) -> vec2<f32> {
    let h = n_out * normalize(light - x) + n_in * normalize(p - x);
    let tt = h - dot(h, n) * n;
    return vec2<f32>(dot(tt, fr.s), dot(tt, fr.t));
}

// The gradient of object oi's F' at x and its Hessian times s and t
// (geometry `Object::hessian`: 2 M of the base, and of each active
// perturbation 6 f Q (grad Q . u) grad Q + 6 f Q^2 M_Q u), in one pass
// over the perturbations.
struct Curvature {
    g: vec3<f32>,
    hs: vec3<f32>,
    ht: vec3<f32>,
}

fn object_curvature(oi: u32, x_gpu: vec3<f32>, s: vec3<f32>, t: vec3<f32>) -> Curvature {
    let obj = objects[oi];
    let x = vec3<real>(x_gpu - obj.origin.xyz);
    let sr = vec3<real>(s);
    let tr = vec3<real>(t);
    var g = q_grad(obj.base, base_local(obj, x));
    var hs = 2.0 * q_m(obj.base, sr);
    var ht = 2.0 * q_m(obj.base, tr);
    let first = obj.range.x;
    for (var k = first; k < first + obj.range.y; k++) {
        let pert = perturbations[k];
        let xp = pert_local(pert, x);
        let qv = q_eval(pert.q, xp);
        if (qv > 0.0) {
            let f = real(pert.factor.x);
            let gq = q_grad(pert.q, xp);
            g += 3.0 * f * qv * qv * gq;
            hs += 6.0 * f * qv * (dot(gq, sr) * gq + qv * q_m(pert.q, sr));
            ht += 6.0 * f * qv * (dot(gq, tr) * gq + qv * q_m(pert.q, tr));
        }
    }
    return Curvature(vec3<f32>(g), vec3<f32>(hs), vec3<f32>(ht));
}

// The constraint's Jacobian at x (manifold.rs `jacobian`), its columns
// for x moved along the tangents s and t: exact, the normal's derivative
// dn = -(I - n n^T) H u / |grad F'| from the Hessian (`object_curvature`;
// until 2026-12-04 by central differences of the normal, whose step had
// to be tuned against f32's resolution and the perturbations' size).
fn manifold_jacobian(oi: u32, x: vec3<f32>, n: vec3<f32>, p: vec3<f32>, light: vec3<f32>,
                     n_in: f32, n_out: f32, fr: Frame) -> mat2x2<f32> {
    let to_l = light - x;
    let to_p = p - x;
    let rl = length(to_l);
    let rp = length(to_p);
    let wo = to_l / rl;
    let wi = to_p / rp;
    let hn = dot(n_out * wo + n_in * wi, n);
    let cv = object_curvature(oi, x, fr.s, fr.t);
    let gl = length(cv.g);
    var cols: array<vec2<f32>, 2>;
    for (var k = 0u; k < 2u; k++) {
        let u = select(fr.t, fr.s, k == 0u);
        let hu = select(cv.ht, cv.hs, k == 0u);
        let dh = -n_out * (u - dot(wo, u) * wo) / rl - n_in * (u - dot(wi, u) * wi) / rp;
        let dn = -(hu - dot(hu, n) * n) / gl;
        let dc = dh - hn * dn;
        cols[k] = vec2<f32>(dot(dc, fr.s), dot(dc, fr.t));
    }
    return mat2x2<f32>(cols[0], cols[1]);
}

// m^-1 v for the 2 x 2 matrix of columns a, b (zero if singular).
fn solve2(a: vec2<f32>, b: vec2<f32>, v: vec2<f32>) -> vec2<f32> {
    let det = a.x * b.y - b.x * a.y;
    if (!(abs(det) > 0.0)) {
        return vec2<f32>(0.0);
    }
    return vec2<f32>(b.y * v.x - b.x * v.y, -a.y * v.x + a.x * v.y) / det;
}

// The first root of the quadratic (A, B, C) in (0, t), else t.
fn first_root_below(c: vec3<real>, t: f32) -> f32 {
    let b = vec2<f32>(roots(c));
    return select(select(t, b.y, b.y > 0.0 && b.y < t), b.x, b.x > 0.0 && b.x < t);
}

// A lower bound on the first crossing of object ob's surface from p (inside
// it) along dir, up to t_max, by closed forms (geometry `Object::exit_bound`):
// the base quadric's crossing, or the entry into a dent's support if
// sooner; 0 where p lies outside the base or in a dent's support.
fn exit_bound(ob: Object, p: vec3<f32>, dir: vec3<f32>, t_max: f32) -> f32 {
    let lo = vec3<real>(p - ob.origin.xyz);
    let d = vec3<real>(dir);
    // Along the ray (A, B, C): C is the value at p.
    let base = q_along(ob.base, base_local(ob, lo), d);
    if (!(base.z > 0.0)) {
        return 0.0;
    }
    var t = first_root_below(base, t_max);
    for (var k = ob.range.x; k < ob.range.x + ob.range.y; k++) {
        let pert = perturbations[k];
        if (pert.factor.x < 0.0) {
            let dent = q_along(pert.q, pert_local(pert, lo), d);
            if (!(dent.z <= 0.0)) {
                return 0.0;
            }
            t = first_root_below(dent, t);
        }
    }
    return t;
}

// The object of a medium's list (material data at `list`: count, then
// the objects) that holds p: the one whose box holds p where F' > 0, else
// (p beyond every box, where a path in the medium by its record can be:
// bounds are no surfaces) one where F' > 0; NO_OBJECT if none.
const NO_OBJECT: u32 = 0xffffffffu;
fn medium_object(list: u32, p: vec3<f32>) -> u32 {
    let count = u32(material_data[list]);
    if (count == 1u) {
        return u32(material_data[list + 1u]);
    }
    for (var round = 0u; round < 2u; round++) {
        for (var k = 0u; k < count; k++) {
            let o = u32(material_data[list + 1u + k]);
            let obj = objects[o];
            let lc = p - obj.origin.xyz;
            let boxed = all(lc >= obj.bmin.xyz) && all(lc <= obj.bmax.xyz);
            if ((boxed || round == 1u) && object_field(o, p).x > 0.0) {
                return o;
            }
        }
    }
    return NO_OBJECT;
}

// Manifold next-event estimation of the light at `light` from p through
// the curved surface of object oi, the boundary of medium id (1 + its
// material; index n2 inside, n1 outside): integrator/refraction.rs
// `manifold_refraction`, manifold.rs `connect_from`.
fn manifold_refraction(oi: u32, id: u32, p: vec3<f32>, light: vec3<f32>, n1: f32, n2: f32) -> Refraction {
    var r = Refraction(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0);
    let to_light = light - p;
    let dist = length(to_light);
    if (!(dist > 0.0)) {
        return r;
    }
    // Russian roulette by the attenuation of the straight way out, in two
    // stages (integrator/refraction.rs `manifold_refraction`): first by d1, a lower
    // bound on the crossing from closed forms (geometry `Object::exit_bound`:
    // the base quadric's crossing, or a dent's support if sooner; 0 where p
    // is outside the base or in a dent's support), so that most declined
    // tries cost no exact intersection, then, the seed found, by q / q1.
    let mm = materials[id - 1u];
    let sigma = min3(mm.b.rgb + mm.c.rgb);
    let ob = objects[oi];
    let dir = to_light / dist;
    let d1 = exit_bound(ob, p, dir, dist);
    let q1 = exp(-sigma * d1);
    if (!(q1 > 0.0) || (q1 < 1.0 && rand() >= q1)) {
        return r;
    }
    let seed = object_first_hit(oi, p, dir, 0.0, dist);
    if (!(seed.x >= 0.0)) {
        return r;
    }
    let q2 = min(exp(-sigma * seed.x) / q1, 1.0);
    if (!(q2 > 0.0) || (q2 < 1.0 && rand() >= q2)) {
        return r;
    }
    let q = q1 * q2;
    let pr = manifold_project(oi, p + seed.x * dir, dist);
    if (pr.w == 0.0) {
        return r;
    }
    var x = pr.xyz;
    var n = object_normal_at(oi, x);
    let tol = 1e-5 * (n1 + n2);
    var ok = false;
    // The last iterate's frame and Jacobian, for the spreading.
    var fr: Frame;
    var ja = vec2<f32>(0.0);
    var jb = vec2<f32>(0.0);
    for (var it = 0u; it < 16u; it++) {
        fr = frame_from_normal(n);
        let c = manifold_constraint(n, x, p, light, n2, n1, fr);
        let norm = length(c);
        let jac = manifold_jacobian(oi, x, n, p, light, n2, n1, fr);
        ja = jac[0];
        jb = jac[1];
        if (norm < tol) {
            ok = true;
            break;
        }
        var step = -solve2(ja, jb, c);
        let cap = 0.25 * length(x - p);
        if (length(step) > cap) {
            step *= cap / length(step);
        }
        var moved = false;
        for (var h = 0u; h < 8u; h++) {
            let y = manifold_project(oi, x + step.x * fr.s + step.y * fr.t, dist);
            if (y.w != 0.0) {
                let ny = object_normal_at(oi, y.xyz);
                let cy = manifold_constraint(ny, y.xyz, p, light, n2, n1, frame_from_normal(ny));
                if (length(cy) < norm) {
                    x = y.xyz;
                    n = ny;
                    moved = true;
                    break;
                }
            }
            step *= 0.5;
        }
        if (!moved) {
            // No step reduces the constraint: no solution nearby (p
            // beyond the refracted rays' reach, near the shadow's edge
            // of a convex boundary), as on the CPU.
            break;
        }
    }
    if (!ok) {
        return r;
    }
    // On the surface as its box clips it (a quadric with `bounds`), as on
    // the CPU.
    if (!in_box(ob, x)) {
        return r;
    }
    let to_x = x - p;
    let lx = length(to_x);
    let cos_out = dot(normalize(light - x), n);
    if (!(lx > 0.0) || !(cos_out > 0.0)) {
        return r;
    }
    // The spreading: the solution's motion for p moved across the ray.
    let wi = -to_x / lx;
    let across = frame_from_normal(wi);
    var dx: array<vec3<f32>, 2>;
    for (var k = 0u; k < 2u; k++) {
        let u = select(across.t, across.s, k == 0u);
        // dC/dp u (only w_i moves with p), exact.
        let dwi = n2 * (u - dot(wi, u) * wi) / lx;
        let m = solve2(ja, jb, vec2<f32>(dot(dwi, fr.s), dot(dwi, fr.t)));
        dx[k] = -(m.x * fr.s + m.y * fr.t);
    }
    let to_l = x - light;
    let d2 = dot(to_l, to_l);
    let spread = abs(dot(cross(dx[0], dx[1]), to_l)) / (sqrt(d2) * d2);
    let factor = (1.0 - fresnel_dielectric(cos_out, n2 / n1)) * spread / q;
    if (!(factor > 0.0) || !finite(factor)) {
        return r;
    }
    return Refraction(to_x / lx, lx, x, factor, n, object_floor(oi));
}

// ---- Caustics: point lights through glass (manifold.rs `connect_through`)
//
// With `integrator.caustics = "manifold"` (`CAUSTICS`, source.rs
// `Features::caustics`), a point light whose shadow ray from p first enters
// a `dielectric` object and leaves it again short of the light lights p
// through it (integrator/refraction.rs `caustic`): the path p -> x0 -> x1 -> light
// obeying Snell's law at both crossings, by Newton's method on the two
// crossings' four tangential constraint components together (the
// Jacobian's diagonal blocks `manifold_jacobian`'s, the off-diagonal ones
// moving only the direction toward the other crossing), seeded with the
// straight segment's crossings; the spreading from the same Jacobian.

// A solved path through glass: `wi` from p toward the exit crossing `x0`
// at distance `inside`, the entry crossing `x1` (outward normal `n1`) from
// where the last leg runs to the light, and `factor`, the two Fresnel
// transmittances times the spreading (0: none).
struct Caustic {
    wi: vec3<f32>,
    inside: f32,
    x0: vec3<f32>,
    factor: f32,
    x1: vec3<f32>,
    n1: vec3<f32>,
    floor: f32, // the glass's spawn floor (render.wgsl `object_floor`)
}

// m^-1 v for the 4 x 4 matrix of rows m, by Gaussian elimination with
// partial pivoting; w of the result's `ok` false if singular.
struct Solved4 {
    x: vec4<f32>,
    ok: bool,
}

fn solve4(m_in: array<vec4<f32>, 4>, v_in: vec4<f32>) -> Solved4 {
    var m = m_in;
    var v = v_in;
    var size = 0.0;
    for (var r = 0u; r < 4u; r++) {
        size = max(size, max3(abs(m[r].xyz)));
        size = max(size, abs(m[r].w));
    }
    if (!(size > 0.0) || !finite(size)) {
        return Solved4(vec4<f32>(0.0), false);
    }
    for (var c = 0u; c < 4u; c++) {
        var piv = c;
        for (var r = c + 1u; r < 4u; r++) {
            if (abs(m[r][c]) > abs(m[piv][c])) {
                piv = r;
            }
        }
        if (!(abs(m[piv][c]) > 1e-7 * size)) {
            return Solved4(vec4<f32>(0.0), false);
        }
        let row = m[piv];
        m[piv] = m[c];
        m[c] = row;
        let vp = v[piv];
        v[piv] = v[c];
        v[c] = vp;
        for (var r = c + 1u; r < 4u; r++) {
            let f = m[r][c] / row[c];
            m[r] -= f * row;
            v[r] -= f * vp;
        }
    }
    var x = vec4<f32>(0.0);
    for (var k = 0u; k < 4u; k++) {
        let r = 3u - k;
        x[r] = (v[r] - dot(m[r], x)) / m[r][r];
    }
    return Solved4(x, finite3(x.xyz) && finite(x.w));
}

// The two crossings' constraints (vertex 0: neighbours p, outside, and
// x1, inside; vertex 1: x0, inside, and the light, outside) in their
// frames f0, f1 (normals f0.n, f1.n), as one vec4.
fn chain_constraints(x0: vec3<f32>, x1: vec3<f32>, f0: Frame, f1: Frame, p: vec3<f32>,
                     light: vec3<f32>, n_in: f32, n_out: f32) -> vec4<f32> {
    let c0 = manifold_constraint(f0.n, x0, p, x1, n_out, n_in, f0);
    let c1 = manifold_constraint(f1.n, x1, x0, light, n_in, n_out, f1);
    return vec4<f32>(c0, c1);
}

// The 4 x 4 Jacobian of `chain_constraints` by rows, for the crossings
// moved along their frames' tangents (columns: x0 along f0.s, f0.t, then
// x1 along f1.s, f1.t).
fn chain_jacobian(oi: u32, x0: vec3<f32>, x1: vec3<f32>, f0: Frame, f1: Frame, p: vec3<f32>,
                  light: vec3<f32>, n_in: f32, n_out: f32) -> array<vec4<f32>, 4> {
    let j00 = manifold_jacobian(oi, x0, f0.n, p, x1, n_out, n_in, f0);
    let j11 = manifold_jacobian(oi, x1, f1.n, x0, light, n_in, n_out, f1);
    let inner = x1 - x0;
    let r = length(inner);
    let w = inner / r;
    // dC0/dx1: only x0's direction toward x1 moves; dC1/dx0 likewise (its
    // direction toward x0 is -w, and (u - (w.u) w) is even in w).
    let a0 = n_in * (f1.s - dot(w, f1.s) * w) / r;
    let a1 = n_in * (f1.t - dot(w, f1.t) * w) / r;
    let b0 = n_in * (f0.s - dot(w, f0.s) * w) / r;
    let b1 = n_in * (f0.t - dot(w, f0.t) * w) / r;
    return array<vec4<f32>, 4>(
        vec4<f32>(j00[0].x, j00[1].x, dot(a0, f0.s), dot(a1, f0.s)),
        vec4<f32>(j00[0].y, j00[1].y, dot(a0, f0.t), dot(a1, f0.t)),
        vec4<f32>(dot(b0, f1.s), dot(b1, f1.s), j11[0].x, j11[1].x),
        vec4<f32>(dot(b0, f1.t), dot(b1, f1.t), j11[0].y, j11[1].y),
    );
}

// Point light k's path to p (geometric normal ng) through a glass object,
// where its shadow ray meets one first (integrator/refraction.rs `caustic`).
fn caustic(k: u32, p: vec3<f32>, ng: vec3<f32>) -> Caustic {
    var r = Caustic(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0, vec3<f32>(0.0), vec3<f32>(0.0), 0.0);
    let light = lights[k].position.xyz;
    let origin = offset_origin(p, ng, light - p);
    let to = light - origin;
    let dist = length(to);
    if (!(dist > 0.0)) {
        return r;
    }
    let dir = to / dist;
    let h = scene_hit(origin, dir, dist);
    if (!(h.x >= 0.0)) {
        return r;
    }
    let oi = hit_object;
    let glass = object_floor(oi);
    let mm = materials[objects[oi].range.z];
    let e0 = origin + h.x * dir;
    // A dielectric entered (against the hit's outward normal) ...
    if (mm.tag.x != MAT_DIELECTRIC || !(dot(dir, h.yzw) < 0.0)) {
        return r;
    }
    // ... and left short of the light.
    let beyond = offset_from(e0, h.yzw, dir, glass);
    let h2 = scene_hit(beyond, dir, dot(light - beyond, dir));
    if (!(h2.x >= 0.0) || hit_object != oi) {
        return r;
    }
    let e1 = beyond + h2.x * dir;
    let n_in = mm.a.x;
    var n_out = 1.0;
    let top = medium_top();
    if (SUBSURFACE && top != 0u) {
        n_out = materials[top - 1u].a.x;
    }
    let p0 = manifold_project(oi, e0, dist);
    let p1 = manifold_project(oi, e1, dist);
    if (p0.w == 0.0 || p1.w == 0.0) {
        return r;
    }
    var x0 = p0.xyz;
    var x1 = p1.xyz;
    // Their normals, carried from the step that found them.
    var n0 = object_normal_at(oi, x0);
    var n1 = object_normal_at(oi, x1);
    let tol = 1e-5 * (n_in + n_out);
    var ok = false;
    var f0: Frame;
    var f1: Frame;
    var jac: array<vec4<f32>, 4>;
    for (var it = 0u; it < 16u; it++) {
        f0 = frame_from_normal(n0);
        f1 = frame_from_normal(n1);
        let c = chain_constraints(x0, x1, f0, f1, p, light, n_in, n_out);
        let norm = length(c);
        jac = chain_jacobian(oi, x0, x1, f0, f1, p, light, n_in, n_out);
        if (norm < tol) {
            ok = true;
            break;
        }
        let sol = solve4(jac, c);
        if (!sol.ok) {
            break;
        }
        var step = -sol.x;
        // Each crossing moves at most a quarter of the way to its nearest
        // neighbour per step.
        let gap = length(x1 - x0);
        let cap0 = 0.25 * min(length(p - x0), gap);
        let cap1 = 0.25 * min(length(light - x1), gap);
        if (length(step.xy) > cap0) {
            step = vec4<f32>(step.xy * (cap0 / length(step.xy)), step.zw);
        }
        if (length(step.zw) > cap1) {
            step = vec4<f32>(step.xy, step.zw * (cap1 / length(step.zw)));
        }
        var moved = false;
        for (var hh = 0u; hh < 8u; hh++) {
            let y0 = manifold_project(oi, x0 + step.x * f0.s + step.y * f0.t, dist);
            let y1 = manifold_project(oi, x1 + step.z * f1.s + step.w * f1.t, dist);
            if (y0.w != 0.0 && y1.w != 0.0) {
                let m0 = object_normal_at(oi, y0.xyz);
                let m1 = object_normal_at(oi, y1.xyz);
                let cy = chain_constraints(y0.xyz, y1.xyz, frame_from_normal(m0),
                                           frame_from_normal(m1), p, light, n_in, n_out);
                if (length(cy) < norm) {
                    x0 = y0.xyz;
                    x1 = y1.xyz;
                    n0 = m0;
                    n1 = m1;
                    moved = true;
                    break;
                }
            }
            step *= 0.5;
        }
        if (!moved) {
            break;
        }
    }
    let ob = objects[oi];
    if (!ok || !in_box(ob, x0) || !in_box(ob, x1)) {
        return r;
    }
    let to_x0 = x0 - p;
    let lp = length(to_x0);
    let inner = normalize(x1 - x0);
    let to_p = -to_x0 / lp;
    let cos0 = dot(to_p, f0.n);
    let cos1 = dot(normalize(light - x1), f1.n);
    if (!(lp > 0.0) || !(cos0 > 0.0) || !(cos1 > 0.0) || !(dot(inner, f0.n) < 0.0)
        || !(dot(inner, f1.n) > 0.0)) {
        return r;
    }
    // Nothing inside the glass between the crossings.
    let o_in = offset_from(x0, f0.n, inner, glass);
    let t_in = dot(x1 - o_in, inner) * (1.0 - 1e-4) - spawn_offset_at(x1, glass);
    if (t_in > 0.0 && occluded(o_in, inner, t_in)) {
        return r;
    }
    // The leg from p to the exit crossing: the first surface it meets is
    // the glass, at x0 (as on the CPU). A test of the segment short of x0
    // instead lost light at grazing exits (the caustic's outer rim),
    // where f32's x0, a little off the surface, lies a hundred times
    // farther along the ray. The ray aims at x0 from the spawned point
    // itself: along `-to_p`, from p, it ran parallel to the leg, the
    // spawn offset off it, and met a grazing crossing that offset over
    // the cosine from x0 (the CPU lost 12% of the rim's light so, its
    // offset 1e-6 rather than 1e-7; `caustic` in integrator/refraction.rs).
    let o_p = offset_origin(p, ng, -to_p);
    let leg = length(x0 - o_p);
    let to_x0_o = (x0 - o_p) / leg;
    let h0 = scene_hit(o_p, to_x0_o, leg * (1.0 + 1e-3) + spawn_offset_at(x0, glass));
    if (!(leg > 0.0) || !(h0.x >= 0.0) || hit_object != oi
        || length(o_p + h0.x * to_x0_o - x0) > 1e-3 * (objects[oi].origin.w + leg)) {
        return r;
    }
    // The spreading: the entry crossing's motion for p moved across the
    // arriving ray (only C0 moves with p).
    let across = frame_from_normal(to_p);
    var dx: array<vec3<f32>, 2>;
    for (var j = 0u; j < 2u; j++) {
        let u = select(across.t, across.s, j == 0u);
        let dw = n_out * (u - dot(to_p, u) * to_p) / lp;
        let sol = solve4(jac, vec4<f32>(dot(dw, f0.s), dot(dw, f0.t), 0.0, 0.0));
        if (!sol.ok) {
            return r;
        }
        dx[j] = -(sol.x.z * f1.s + sol.x.w * f1.t);
    }
    let l = x1 - light;
    let d2 = dot(l, l);
    let spread = abs(dot(cross(dx[0], dx[1]), l)) / (sqrt(d2) * d2);
    let eta = n_in / n_out;
    let factor = (1.0 - fresnel_dielectric(cos0, eta)) * (1.0 - fresnel_dielectric(cos1, eta)) * spread;
    if (!(factor > 0.0) || !finite(factor)) {
        return r;
    }
    return Caustic(-to_p, lp, x0, factor, x1, f1.n, glass);
}
