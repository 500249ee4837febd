// The environment (crates/render/src/environment.rs): a direction's
// texel of the map, its radiance and its pdf over the sphere, and the
// map's importance sampling by its marginal and conditional CDFs. Part of
// the path tracer's module (source.rs `RENDER_FILES`: the files are
// concatenated after render.wgsl, which declares the bindings).

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
