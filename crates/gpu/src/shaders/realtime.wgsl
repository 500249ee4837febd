// The real-time mode on the GPU, mirroring crates/render/src/realtime.rs
// (appended to the path tracer's files, source.rs `RENDER_FILES`: the same
// bindings, random numbers, geometry and environment helpers):
//   * one thread per pixel and sample, `pass_info.y` samples (4-25) of
//     the pixel on the stratified sub-pixel grid, which `resolve` writes
//     (not accumulates) to `accum`: each run is one whole frame;
//   * at the first hit: point lights with shadow rays (the seed's eq. 2),
//     plus one BSDF sample reading the prefiltered environment pyramid
//     (`env_levels`) at the level of detail of the sample's density
//     (filtered importance sampling); delta lobes read level 0;
//   * environment light is neither shadowed nor bounced.
// `env_levels`: 16 headers (level offset, width, height), then the levels'
// texels (f32 bits: a u32 buffer, since header integers read as f32 would
// be denormals that a driver may flush to zero); `params.env_size.z` levels.

const ENV_LEVEL_HEADERS: u32 = 16u;

fn level_texel(k: u32, x: u32, y: u32) -> vec3<f32> {
    let hd = env_levels[k];
    return bitcast<vec4<f32>>(env_levels[ENV_LEVEL_HEADERS + hd.x + y * hd.y + x]).rgb;
}

fn level_bilinear(k: u32, uv: vec2<f32>) -> vec3<f32> {
    let hd = env_levels[k];
    let w = hd.y;
    let h = hd.z;
    let x = uv.x * f32(w) - 0.5;
    let y = clamp(uv.y * f32(h) - 0.5, 0.0, f32(h - 1u));
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let wi = i32(w);
    let xa = u32(wrap_index(i32(x0), wi));
    let xb = (xa + 1u) % w;
    let ya = u32(y0);
    let yb = min(ya + 1u, h - 1u);
    let top = mix(level_texel(k, xa, ya), level_texel(k, xb, ya), fx);
    let bottom = mix(level_texel(k, xa, yb), level_texel(k, xb, yb), fx);
    return mix(top, bottom, fy);
}

// Level of detail for a sample of density `pdf` (< 0: delta) toward d.
fn env_lod(d: vec3<f32>, pdf: f32) -> f32 {
    if (!(pdf > 0.0)) {
        return 0.0;
    }
    let w = f32(params.env_size.x);
    let h = f32(params.env_size.y);
    let sin_t = max(sqrt(max(1.0 - d.y * d.y, 0.0)), PI / h);
    let omega_p = 2.0 * PI * PI * sin_t / (w * h);
    let omega_s = 1.0 / (f32(params.pass_info.y) * pdf);
    let lod = 0.5 * log2(omega_s / omega_p) + LOD_BIAS;
    let top = f32(params.env_size.z - 1u);
    if (!(lod >= 0.0)) {
        return 0.0;
    }
    return min(lod, top);
}

fn env_filtered(d: vec3<f32>, pdf: f32) -> vec3<f32> {
    if (params.counts.w != ENV_MAP) {
        return params.env.rgb;
    }
    let lod = env_lod(d, pdf);
    let k = u32(floor(lod));
    let t = lod - f32(k);
    let uv = env_uv(d);
    let a = level_bilinear(k, uv);
    if (t > 0.0 && k + 1u < params.env_size.z) {
        return mix(a, level_bilinear(k + 1u, uv), t);
    }
    return a;
}

fn realtime_shade(o: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    let h = scene_hit(o, d, 3.0e38);
    if (h.x < 0.0) {
        return env_eval(d);
    }
    let mi = objects[hit_object].range.z;
    vertex_floor = object_floor(hit_object);
    let p = o + h.x * d;
    let ng = h.yzw;
    // The point lights' shadow rays before the material is loaded
    // (direct.wgsl `trace_shadows`).
    if (SHADOWS_FIRST) {
        trace_shadows(p, ng);
    }
    var m = materials[mi];
    if (has_wave(m)) {
        m = place_material(m, p, pixel_footprint(h.x), rand());
    }
    // A translucent medium is shaded with its local approximation (the
    // seed's eq. 19), as on the CPU (realtime.rs).
    if (has_model(MAT_SUBSURFACE) && m.tag.x == MAT_SUBSURFACE) {
        m = sss_local_brdf(m);
    }
    let wo = -d;
    let fr = bsdf_frame(m, ng, wo);
    let wo_l = to_local(fr, wo);
    if (wo_l.z == 0.0) {
        return vec3<f32>(0.0);
    }
    var l = direct_light(p, ng, fr, m, wo_l, GATHER_LIGHTS, vec4<f32>(0.0), m, mi, SHADOWS_FIRST);
    let s = bsdf;
    if (s.ok && s.pdf > 0.0 && finite(s.pdf) && finite3(s.f) && s.wi.z != 0.0) {
        let wi = to_world(fr, s.wi);
        let pdf = select(s.pdf, -1.0, (s.flags & FLAG_SPECULAR) != 0u);
        l += s.f * (abs(s.wi.z) / s.pdf) * env_filtered(wi, pdf);
    }
    return l;
}

// One sample per thread (`pass_info.x + gid.z`, of `pass_info.y` per
// pixel), written to its layer for `resolve` (camera.wgsl), which
// replaces the pixel's sum with the frame's first layers: no loop around
// the shading (see the known defect in docs/gpu.md).
@compute @workgroup_size(8, 8)
fn realtime(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.film.x || gid.y >= params.film.y) {
        return;
    }
    use_tile(gid);
    store_sample(gid, realtime_shade(params.origin.xyz, camera_sample(gid)));
}
