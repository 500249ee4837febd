// Subsurface scattering on the GPU: the dipole BSSRDF's profile, its
// entry points and single scattering, the random walk's phase function,
// and point lights refracted into a medium through its flat boundary
// (`refraction`); also Russian roulette (`roulette`), which every path
// takes. Part of the path tracer's module (source.rs `RENDER_FILES`).

// ---- Subsurface scattering (integrator.rs and integrator/) -----------------
//
// `SUBSURFACE` (a constant the Rust side writes before this file,
// `render_source_variant`) is false in kernels for scenes without a
// `subsurface` material: every branch below that only a medium reaches is
// then dead code, which the driver drops with the functions it calls
// (among them a third inlined copy of the intersection, in the dipole's
// probe rays).

// Henyey-Greenstein cosine for u in [0, 1), as subsurface::phase.
fn sample_hg_cos(g: f32, u: f32) -> f32 {
    if (abs(g) < 1e-3) {
        return 1.0 - 2.0 * u;
    }
    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
    return clamp((1.0 + g * g - s * s) / (2.0 * g), -1.0, 1.0);
}

fn sss_albedo(m: Material) -> vec3<f32> {
    let st = m.b.rgb + m.c.rgb;
    return select(vec3<f32>(0.0), m.b.rgb / st, st > vec3<f32>(0.0));
}

// The scale of the single-scattering term per channel
// (Subsurface::single_scattering_scale), after the three dipoles.
fn sss_scale(m: Material) -> vec3<f32> {
    let at = m.idx.x + 12u;
    return vec3<f32>(material_data[at], material_data[at + 1u], material_data[at + 2u]);
}

// R_d(r) per channel (dipoles at material_data[idx.x]: sigma_tr, z_r,
// z_v, alpha' per channel), as subsurface::Dipole::r_d.
fn sss_profile(m: Material, r: f32) -> vec3<f32> {
    var out = vec3<f32>(0.0);
    for (var c = 0u; c < 3u; c++) {
        let at = m.idx.x + 4u * c;
        let s_tr = material_data[at];
        var sum = 0.0;
        for (var k = 1u; k < 3u; k++) {
            let z = material_data[at + k];
            let d = sqrt(r * r + z * z);
            sum += z * (s_tr * d + 1.0) * exp(-s_tr * d) / (d * d * d);
        }
        out[c] = material_data[at + 3u] / (4.0 * PI) * sum;
    }
    return out;
}

// Density of the radial sampler of channel c at radius r.
fn sss_radial_pdf(m: Material, c: u32, r: f32) -> f32 {
    let r_max = m.a.z;
    if (!(r > 0.0 && r < r_max)) {
        return 0.0;
    }
    let x = sqrt(r / r_max);
    return table_pdf(m.idx[1u + c], x) / (2.0 * r_max * x);
}

fn sss_sw(m: Material, cos_i: f32) -> f32 {
    return (1.0 - fresnel_dielectric(abs(cos_i), m.a.x)) * INV_PI / m.a.w;
}

// Russian roulette on beta with the refraction scale undone (survivors
// reweighted); a zero vector ends the path.
fn roulette(beta: vec3<f32>) -> vec3<f32> {
    let q = max3(beta * path.eta_scale);
    if (q < 1.0) {
        if (rand() >= q) {
            return vec3<f32>(0.0);
        }
        return beta / q;
    }
    return beta;
}

// The single-scattering lobe of dipole medium m at its exit point x_o
// (integrator/dipole.rs single_scattering_light): `bounce` gathers its light
// samples and one cosine-sampled direction toward the environment through
// it.
fn sss_single_lobe(m: Material) -> Material {
    var lobe = m;
    lobe.tag.x = MAT_SSS_SINGLE_LOBE;
    lobe.a = vec4<f32>(0.0, 0.0, 0.0, m.a.x);
    lobe.b = vec4<f32>(sss_albedo(m) * sss_scale(m), m.a.y);
    return lobe;
}

// Projection axis j of a dipole's entry-point sampling (probability 1/2
// for the normal, j = 0, and 1/4 for each tangent) and the two axes of the
// disk around it, as columns: (n; s, t), (s; t, n), (t; n, s).
fn sss_axis(fr: Frame, j: u32) -> mat3x3<f32> {
    if (j == 1u) {
        return mat3x3<f32>(fr.s, fr.t, fr.n);
    }
    if (j == 2u) {
        return mat3x3<f32>(fr.t, fr.n, fr.s);
    }
    return mat3x3<f32>(fr.n, fr.s, fr.t);
}

// Light refracted into a dipole medium at p re-emerges at an entry point
// x_i sampled around it (integrator/dipole.rs bssrdf_entry): a channel, a
// projection axis (the normal 1/2, each tangent 1/4), a radius from the
// channel's table, a probe ray along the axis through object oi of which
// one of the k hits is kept (reservoir sampling), the pdf summing every
// axis and channel. x_i becomes the path's next vertex, with the entry
// lobe S_w as its material: `bounce` gathers light through the boundary
// there and samples a cosine-weighted continuation. (The choice of
// transmission, probability 1 - F(cos_o), cancels the factor 1 - F(cos_o)
// of S.) mi: the record of m (the entry lobe's), which may be the
// medium's as seen from inside a random-walk one.
fn sss_dipole_bounce(oi: u32, p: vec3<f32>, n: vec3<f32>, m: Material, mi: u32) -> bool {
    let fr = frame_from_normal(n);
    let c = min(u32(rand() * 3.0), 2u);
    let ua = rand();
    let axes = sss_axis(fr, select(0u, select(1u, 2u, ua >= 0.75), ua >= 0.5));
    let axis = axes[0];
    let a1 = axes[1];
    let a2 = axes[2];
    let r_max = m.a.z;
    let x = table_sample(m.idx[1u + c], rand());
    let r = r_max * x * x;
    if (!(r < r_max)) {
        return false;
    }
    let phi = 2.0 * PI * rand();
    let hh = sqrt(r_max * r_max - r * r);
    let start = p + r * (cos(phi) * a1 + sin(phi) * a2) + hh * axis;
    let dir = -axis;
    var k = 0u;
    var chosen = vec4<f32>(MISS, 0.0, 0.0, 0.0);
    var t0 = 0.0;
    let floor = object_floor(oi);
    for (var i = 0u; i < 64u; i++) {
        let x = object_first_hit(oi, start, dir, t0, 2.0 * hh);
        if (x.x < 0.0) {
            break;
        }
        k += 1u;
        if (rand() * f32(k) < 1.0) {
            chosen = x;
        }
        t0 = x.x + spawn_offset_at(start + x.x * dir, floor);
    }
    if (k == 0u) {
        return false;
    }
    let xp = start + chosen.x * dir;
    let xn = chosen.yzw;
    let dv = xp - p;
    var pdf = 0.0;
    for (var j = 0u; j < 3u; j++) {
        let ax = sss_axis(fr, j)[0];
        let p_axis = select(0.25, 0.5, j == 0u);
        let along = dot(dv, ax);
        let r_proj = sqrt(max(dot(dv, dv) - along * along, 0.0));
        if (r_proj <= 0.0 || r_proj >= r_max) {
            continue;
        }
        let cos_a = abs(dot(ax, xn));
        for (var ch = 0u; ch < 3u; ch++) {
            pdf += p_axis / 3.0 * sss_radial_pdf(m, ch, r_proj) / (2.0 * PI * r_proj) * cos_a;
        }
    }
    pdf /= f32(k);
    if (!(pdf > 0.0) || !finite(pdf)) {
        return false;
    }
    let w = sss_profile(m, length(dv)) / pdf;
    if (!finite3(w)) {
        return false;
    }
    path.beta *= w;
    path.o = xp;
    path.entry_n = xn;
    path.entry_m = mi;
    path.entry_o = oi;
    path.entry = true;
    return max3(path.beta) > 0.0;
}

// A point light's connection into the innermost medium through its
// boundary (integrator/refraction.rs `refraction`, in f32): through a flat one by
// the same Newton steps (the light's record's `intensity.w` names the
// medium, layout.rs `GpuLight`), through a curved one by
// `manifold_refraction` (the medium's record's `c.w` lists its objects).
// The direction wi from the point inside toward the crossing point c,
// the distance `inside` to it, `factor`, the Fresnel transmittance times
// the refracted inverse square law (0 where light i does not reach p
// so), and the boundary's outward normal at c.
struct Refraction {
    wi: vec3<f32>,
    inside: f32,
    c: vec3<f32>,
    factor: f32,
    n: vec3<f32>, // the boundary's outward normal at c
    floor: f32,   // the boundary's spawn floor (render.wgsl `object_floor`)
}

// Whether a crossing point c lies in the box of object ob that clips its
// boundary (in the object's frame, the faces rounded outward; integrator/refraction.rs
// `in_box`).
fn in_box(ob: Object, c: vec3<f32>) -> bool {
    let lc = c - ob.origin.xyz;
    let tol = 1e-5 * (ob.origin.w + max3(abs(lc)));
    return !(any(lc < ob.bmin.xyz - tol) || any(lc > ob.bmax.xyz + tol));
}

fn refraction(i: u32, p: vec3<f32>) -> Refraction {
    var r = Refraction(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0);
    let light = lights[i];
    let id = medium_top();
    if (!REFRACTION || !SUBSURFACE || id == 0u) {
        return r;
    }
    let outside = medium_outside(path.medium, id);
    if (u32(light.position.w) != outside) {
        return r;
    }
    // Flat (the light's record names the medium) or found among the
    // objects the medium's record lists (render/media.rs `manifold_media`): a
    // curved one by manifold next-event estimation, a flat one the light's
    // record cannot name (its material shared, or the light above two) by
    // the same closed form as through the record.
    let flat = u32(light.intensity.w) == id;
    let objs = u32(materials[id - 1u].c.w);
    if (!flat && (!MANIFOLD || objs == 0u)) {
        return r;
    }
    let n2 = materials[id - 1u].a.x;
    var n1 = 1.0;
    if (outside != 0u) {
        n1 = materials[outside - 1u].a.x;
    }
    if (n1 == n2) {
        return r;
    }
    // The plane (outward normal, offset), 1 + the object whose box clips
    // it (0: none), and the object it bounds, whose floor the crossing
    // takes (`GpuLight::flat`); where the record names no plane, those of
    // the plane found in the medium's list of objects (below).
    var plane = light.plane;
    var boxed = light.flat.x;
    var bounding = light.flat.y - 1u;
    if (MANIFOLD && !flat) {
        let oi = medium_object(objs - 1u, p);
        if (oi == NO_OBJECT) {
            return r;
        }
        let ob = objects[oi];
        let q = ob.base.c;
        if (ob.range.y != 0u || any(q[0] != vec4<f32>(0.0)) || q[1].x != 0.0 || q[1].y != 0.0) {
            return manifold_refraction(oi, id, p, light.position.xyz, n1, n2);
        }
        // F = 2 b . x + c > 0 inside (x from the base's anchor, in the
        // object's frame): outward normal -b (scene.rs `flat_boundary`).
        let b = vec3<f32>(q[1].z, q[1].w, q[2].x);
        let lb = length(b);
        let nrm = -b / lb;
        plane = vec4<f32>(nrm, dot(nrm, ob.origin.xyz + ob.anchor.xyz) + q[2].y / (2.0 * lb));
        boxed = oi + 1u;
        bounding = oi;
    }
    let n = plane.xyz;
    let lp = light.position.xyz;
    let h1 = dot(n, lp) - plane.w;
    let h2 = plane.w - dot(n, p);
    if (!(h1 > 0.0) || !(h2 > 0.0)) {
        return r;
    }
    let u = (lp - p) - dot(n, lp - p) * n;
    let d = length(u);
    var along = vec3<f32>(0.0);
    if (d > 0.0) {
        along = u / d;
    }
    // Snell's law along the feet's line (the mismatch grows with s, the
    // crossing's distance from the foot of p): Newton steps from the
    // straight line's crossing, bisection where one would leave the
    // bracket.
    var lo = 0.0;
    var hi = d;
    var s = d * h2 / (h1 + h2);
    let tol = 1e-6 * (d + h1 + h2);
    for (var k = 0u; k < 40u; k++) {
        let a = s * s + h2 * h2;
        let b = (d - s) * (d - s) + h1 * h1;
        let ra = sqrt(a);
        let rb = sqrt(b);
        let f = n2 * s / ra - n1 * (d - s) / rb;
        let df = n2 * h2 * h2 / (a * ra) + n1 * h1 * h1 / (b * rb);
        let step = f / df;
        if (!(abs(step) > tol)) {
            if (finite(step)) {
                s -= step;
            }
            break;
        }
        if (f < 0.0) {
            lo = s;
        } else {
            hi = s;
        }
        let next = s - step;
        s = select(0.5 * (lo + hi), next, next > lo && next < hi);
    }
    let l1 = sqrt((d - s) * (d - s) + h1 * h1);
    let l2 = sqrt(s * s + h2 * h2);
    if (!(l2 > 0.0)) {
        return r;
    }
    let cos1 = h1 / l1;
    let sin1 = (d - s) / l1;
    let cos2 = h2 / l2;
    var g = 1.0 / ((h1 + h2 * n1 / n2) * (h1 + h2 * n1 / n2));
    if (d > 1e-6 * (h1 + h2)) {
        let dr = h1 / (cos1 * cos1) + h2 / (cos2 * cos2) * (n1 * cos1) / (n2 * cos2);
        g = sin1 / (d * cos2 * dr);
    }
    let factor = (1.0 - fresnel_dielectric(cos1, n2 / n1)) * g;
    if (!(factor > 0.0) || !finite(factor)) {
        return r;
    }
    let c = p + s * along + h2 * n;
    if (boxed != 0u) {
        // A plane with bounds: the crossing must lie in its box.
        if (!in_box(objects[boxed - 1u], c)) {
            return r;
        }
    }
    return Refraction((c - p) / l2, l2, c, factor, n, object_floor(bounding));
}
