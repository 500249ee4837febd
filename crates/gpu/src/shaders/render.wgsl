// The path tracer on the GPU, mirroring crates/render/src/integrator.rs
// for surface materials (materials.wgsl) on exact perturbation-function
// geometry (geometry.wgsl):
//   * one thread per pixel; a pass adds samples [start, start + count) of
//     every pixel to the accumulation buffer, one by one in sample order,
//     so the sum is the same however the samples are split into passes;
//   * sample s of a pixel takes cell (s + offset) mod (m n) of the m x n
//     sub-pixel grid (offset random per pixel), jittered inside the cell:
//     distinct cells for distinct samples, each sample uniform over the
//     pixel;
//   * point lights by next-event estimation, kept apart from the
//     environment; an environment map by light sampling with MIS (power
//     heuristic) against BSDF sampling; a constant environment by BSDF
//     sampling only;
//   * Russian roulette after three bounces, survival min(1, max(beta
//     eta_scale));
//   * a sample that is not finite or is negative is dropped and counted
//     (accumulation .w): no NaN or Inf reaches a pixel.
// Random numbers: a PCG hash of (seed, pixel, sample) seeds a 32-bit PCG
// stream per sample, so the image depends on the seed only.

struct Params {
    origin: vec4<f32>,
    forward: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    film: vec4<u32>,      // width, height, grid m, grid n
    pass_info: vec4<u32>, // first sample, sample count, seed (low, high)
    counts: vec4<u32>,    // objects, lights, max depth, environment kind
    env: vec4<f32>,       // constant radiance (rgb)
    env_size: vec4<u32>,  // map width, height, pyramid levels (realtime.wgsl)
}

struct Light { position: vec4<f32>, intensity: vec4<f32> }

@group(0) @binding(0) var<storage, read> objects: array<Object>;
@group(0) @binding(1) var<storage, read> perturbations: array<Perturbation>;
@group(0) @binding(2) var<storage, read> materials: array<Material>;
@group(0) @binding(3) var<storage, read> lights: array<Light>;
@group(0) @binding(4) var<storage, read> env_texels: array<vec4<f32>>; // rgb, pdf_uv
@group(0) @binding(5) var<storage, read> env_cdf: array<f32>;          // marginal, then rows
@group(0) @binding(6) var<storage, read_write> accum: array<vec4<f32>>;
@group(0) @binding(7) var<uniform> params: Params;
@group(0) @binding(8) var<storage, read> material_data: array<f32>;
@group(0) @binding(9) var<storage, read> env_levels: array<vec4<u32>>; // realtime.wgsl
@group(0) @binding(10) var<storage, read> nodes: array<BvhNode>;
// AOVs (aov_main): per pixel (albedo, depth) then (normal, 0).
@group(0) @binding(11) var<storage, read_write> aov: array<vec4<f32>>;
@group(0) @binding(12) var<storage, read> albedos: array<vec4<f32>>; // per material

var<private> rng_state: u32;

fn pcg_hash(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

fn rand() -> f32 {
    rng_state = rng_state * 747796405u + 2891336453u;
    let s = rng_state;
    let word = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    return f32(((word >> 22u) ^ word) >> 8u) * (1.0 / 16777216.0);
}

fn rand2() -> vec2<f32> {
    let a = rand();
    return vec2<f32>(a, rand());
}

fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn finite3(v: vec3<f32>) -> bool {
    return finite(v.x) && finite(v.y) && finite(v.z);
}

fn max3(v: vec3<f32>) -> f32 {
    return max(v.x, max(v.y, v.z));
}

fn power_heuristic(a: f32, b: f32) -> f32 {
    let a2 = a * a;
    if (a2 == 0.0) {
        return 0.0;
    }
    if (!finite(a2)) {
        return 1.0;
    }
    return a2 / (a2 + b * b);
}

// ---- Geometry ---------------------------------------------------------------

// Nearest hit over all objects on [0, t_max]: (t, normal), object in
// `hit_object` (geometry.wgsl).
fn scene_hit(o: vec3<f32>, d: vec3<f32>, t_max: f32) -> vec4<f32> {
    return scene_first_hit(o, d, 0.0, t_max, params.counts.x, false);
}

fn occluded(o: vec3<f32>, d: vec3<f32>, t_max: f32) -> bool {
    return scene_first_hit(o, d, 0.0, t_max, params.counts.x, true).x >= 0.0;
}

// The hit point moved off the surface along n to the side of w (f32: a
// wider margin than the CPU's 1e-7).
fn offset_origin(p: vec3<f32>, n: vec3<f32>, w: vec3<f32>) -> vec3<f32> {
    let a = abs(p);
    let eps = SPAWN_OFFSET * (1.0 + max(a.x, max(a.y, a.z)));
    return select(p - n * eps, p + n * eps, dot(w, n) >= 0.0);
}

// ---- Environment --------------------------------------------------------

fn env_uv(d: vec3<f32>) -> vec2<f32> {
    let u = 0.5 + atan2(d.x, -d.z) / (2.0 * PI);
    let v = acos(clamp(d.y, -1.0, 1.0)) / PI;
    return vec2<f32>(fract(u), min(v, 0.99999994));
}

fn env_texel(uv: vec2<f32>) -> vec4<f32> {
    let w = params.env_size.x;
    let h = params.env_size.y;
    let x = min(u32(uv.x * f32(w)), w - 1u);
    let y = min(u32(uv.y * f32(h)), h - 1u);
    return env_texels[y * w + x];
}

fn env_eval(d: vec3<f32>) -> vec3<f32> {
    if (params.counts.w == ENV_MAP) {
        return env_texel(env_uv(d)).rgb;
    }
    return params.env.rgb;
}

fn env_pdf(d: vec3<f32>) -> f32 {
    if (params.counts.w != ENV_MAP) {
        return 0.0;
    }
    let uv = env_uv(d);
    let sin_t = sin(uv.y * PI);
    if (!(sin_t > 0.0)) {
        return 0.0;
    }
    return env_texel(uv).w / (2.0 * PI * PI * sin_t);
}

// Largest i with cdf[base + i] <= u, i in [0, n).
fn cdf_find(base: u32, n: u32, u: f32) -> u32 {
    var lo = 0u;
    var hi = n;
    while (hi - lo > 1u) {
        let mid = (lo + hi) / 2u;
        if (env_cdf[base + mid] <= u) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// (direction, pdf in solid angle); pdf 0 when no sample.
fn env_sample(u: vec2<f32>) -> vec4<f32> {
    let w = params.env_size.x;
    let h = params.env_size.y;
    let y = cdf_find(0u, h, u.x);
    let c0 = env_cdf[y];
    let c1 = env_cdf[y + 1u];
    let dv = select(0.5, (u.x - c0) / (c1 - c0), c1 > c0);
    let row = h + 1u + y * (w + 1u);
    let x = cdf_find(row, w, u.y);
    let r0 = env_cdf[row + x];
    let r1 = env_cdf[row + x + 1u];
    let du = select(0.5, (u.y - r0) / (r1 - r0), r1 > r0);
    let uv = vec2<f32>((f32(x) + clamp(du, 0.0, 1.0)) / f32(w), (f32(y) + clamp(dv, 0.0, 1.0)) / f32(h));
    let sin_t = sin(uv.y * PI);
    let pdf_uv = env_texels[y * w + x].w;
    if (!(sin_t > 0.0) || !(pdf_uv > 0.0)) {
        return vec4<f32>(0.0);
    }
    let phi = (uv.x - 0.5) * 2.0 * PI;
    let theta = uv.y * PI;
    let dir = vec3<f32>(sin_t * sin(phi), cos(theta), -sin_t * cos(phi));
    return vec4<f32>(dir, pdf_uv / (2.0 * PI * PI * sin_t));
}

// ---- Integrator -----------------------------------------------------------

// Point lights with shadow rays at p (geometric normal ng) for material m
// in frame fr.
fn point_lights(p: vec3<f32>, ng: vec3<f32>, fr: Frame, m: Material, wo_l: vec3<f32>) -> vec3<f32> {
    var l = vec3<f32>(0.0);
    for (var i = 0u; i < params.counts.y; i++) {
        let light = lights[i];
        let origin = offset_origin(p, ng, light.position.xyz - p);
        let d = light.position.xyz - origin;
        let dist2 = dot(d, d);
        if (!(dist2 > 0.0)) {
            continue;
        }
        let dist = sqrt(dist2);
        let wi = d / dist;
        let wl = to_local(fr, wi);
        let fc = material_f(m, wo_l, wl) * abs(wl.z);
        if (max3(fc) <= 0.0) {
            continue;
        }
        if (!occluded(origin, wi, dist)) {
            l += fc * light.intensity.rgb / dist2;
        }
    }
    return l;
}

// Next-event estimation at p (geometric normal ng) for material m in frame fr.
fn direct_light(p: vec3<f32>, ng: vec3<f32>, fr: Frame, m: Material, wo_l: vec3<f32>) -> vec3<f32> {
    var l = point_lights(p, ng, fr, m, wo_l);
    if (params.counts.w == ENV_MAP) {
        let s = env_sample(rand2());
        if (s.w > 0.0) {
            let wi = s.xyz;
            let wl = to_local(fr, wi);
            let fc = material_f(m, wo_l, wl) * abs(wl.z);
            let rad = env_eval(wi);
            if (max3(fc) > 0.0 && max3(rad) > 0.0) {
                let origin = offset_origin(p, ng, wi);
                if (!occluded(origin, wi, 3.0e38)) {
                    let w = power_heuristic(s.w, material_pdf(m, wo_l, wl));
                    l += fc * rad * (w / s.w);
                }
            }
        }
    }
    return l;
}

// The state of a path between bounces (module-private, one per thread).
struct Path {
    o: vec3<f32>,
    d: vec3<f32>,
    l: vec3<f32>,
    beta: vec3<f32>,
    prev_pdf: f32, // < 0: camera ray or delta lobe
    eta_scale: f32,
    depth: u32,
}

var<private> path: Path;

// One bounce of the path: false when it ends. (The loop lives in
// `radiance`, the body here: one large loop body miscompiled on lavapipe.)
fn bounce() -> bool {
    let o = path.o;
    let d = path.d;
    let h = scene_hit(o, d, 3.0e38);
    if (h.x < 0.0) {
        var w = 1.0;
        if (path.prev_pdf > 0.0 && params.counts.w == ENV_MAP) {
            w = power_heuristic(path.prev_pdf, env_pdf(d));
        }
        path.l += path.beta * env_eval(d) * w;
        return false;
    }
    if (path.depth >= params.counts.z) {
        return false;
    }
    let obj = objects[hit_object];
    let m = materials[obj.range.z];
    let p = o + h.x * d;
    let ng = h.yzw;
    let wo = -d;
    let flags = material_flags(m);
    var ns = ng;
    if (dot(wo, ng) < 0.0 && (flags & FLAG_TRANSMISSION) == 0u) {
        ns = -ng;
    }
    var fr: Frame;
    if (m.tag.z == 1u) {
        fr = frame_from_normal_tangent(ns, m.d.xyz);
    } else {
        fr = frame_from_normal(ns);
    }
    let wo_l = to_local(fr, wo);
    if (wo_l.z == 0.0) {
        return false;
    }
    path.l += path.beta * direct_light(p, ng, fr, m, wo_l);
    let uc = rand();
    let s = material_sample(m, wo_l, uc, rand2());
    if (!s.ok || !(s.pdf > 0.0) || !finite(s.pdf) || !finite3(s.f) || s.wi.z == 0.0) {
        return false;
    }
    let wi = to_world(fr, s.wi);
    var beta = path.beta * s.f * (abs(s.wi.z) / s.pdf);
    path.eta_scale *= s.eta * s.eta;
    path.prev_pdf = select(s.pdf, -1.0, (s.flags & FLAG_SPECULAR) != 0u);
    path.o = offset_origin(p, ng, wi);
    path.d = wi;
    path.depth += 1u;
    if (path.depth >= 3u) {
        let q = max3(beta * path.eta_scale);
        if (q < 1.0) {
            if (rand() >= q) {
                return false;
            }
            beta = beta / q;
        }
    }
    path.beta = beta;
    return max3(beta) > 0.0;
}

fn radiance(o: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    path = Path(o, d, vec3<f32>(0.0), vec3<f32>(1.0), -1.0, 1.0, 0u);
    // Every bounce either ends the path or raises its depth, which ends
    // it at max_depth: the bound only guards against the unforeseen.
    for (var i = 0u; i <= params.counts.z + 1u; i++) {
        if (!bounce()) {
            break;
        }
    }
    return path.l;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let width = params.film.x;
    let height = params.film.y;
    if (gid.x >= width || gid.y >= height) {
        return;
    }
    let pixel = gid.y * width + gid.x;
    let gm = params.film.z;
    let gn = params.film.w;
    let cells = gm * gn;
    let seed = params.pass_info.z;
    let offset = pcg_hash(pixel ^ pcg_hash(seed)) % cells;
    var acc = accum[pixel];
    for (var k = 0u; k < params.pass_info.y; k++) {
        let s = params.pass_info.x + k;
        rng_state = pcg_hash(seed ^ pcg_hash(pixel ^ pcg_hash(s ^ params.pass_info.w)));
        let c = (s + offset) % cells;
        let j = rand2();
        let fx = f32(gid.x) + (f32(c % gm) + j.x) / f32(gm);
        let fy = f32(gid.y) + (f32(c / gm) + j.y) / f32(gn);
        let sx = 2.0 * fx / f32(width) - 1.0;
        let sy = 1.0 - 2.0 * fy / f32(height);
        let dir = normalize(params.forward.xyz + sx * params.right.xyz + sy * params.up.xyz);
        let v = radiance(params.origin.xyz, dir);
        if (finite3(v) && v.x >= 0.0 && v.y >= 0.0 && v.z >= 0.0) {
            acc = vec4<f32>(acc.rgb + v, acc.w);
        } else {
            acc.w += 1.0;
        }
    }
    accum[pixel] = acc;
}

// AOVs of the first hit for sample `pass_info.x`, at the same sub-pixel
// position as in `main`, added to the pixel's sums: the material's albedo
// and the distance (0 on a miss), the outward normal. One sample per
// dispatch: a loop over the samples around the intersection lost some of
// its iterations (the defect of docs/gpu.md); the host divides.
@compute @workgroup_size(8, 8)
fn aov_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let width = params.film.x;
    let height = params.film.y;
    if (gid.x >= width || gid.y >= height) {
        return;
    }
    let pixel = gid.y * width + gid.x;
    let gm = params.film.z;
    let gn = params.film.w;
    let cells = gm * gn;
    let seed = params.pass_info.z;
    let offset = pcg_hash(pixel ^ pcg_hash(seed)) % cells;
    let s = params.pass_info.x;
    rng_state = pcg_hash(seed ^ pcg_hash(pixel ^ pcg_hash(s ^ params.pass_info.w)));
    let c = (s + offset) % cells;
    let j = rand2();
    let fx = f32(gid.x) + (f32(c % gm) + j.x) / f32(gm);
    let fy = f32(gid.y) + (f32(c / gm) + j.y) / f32(gn);
    let sx = 2.0 * fx / f32(width) - 1.0;
    let sy = 1.0 - 2.0 * fy / f32(height);
    let dir = normalize(params.forward.xyz + sx * params.right.xyz + sy * params.up.xyz);
    let h = scene_hit(params.origin.xyz, dir, 3.0e38);
    if (h.x >= 0.0) {
        let a = albedos[objects[hit_object].range.z].rgb;
        aov[2u * pixel] += vec4<f32>(a, h.x);
        aov[2u * pixel + 1u] += vec4<f32>(h.yzw, 0.0);
    }
}
