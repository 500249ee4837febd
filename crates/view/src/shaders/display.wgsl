// Shows the renderer's accumulation buffer (`GpuFrame::accumulation`) in
// the viewer's central area: the mean of the samples, times 2^exposure,
// tone mapped as `isolux render` maps PNGs (`isolux_io::Tonemap`), then
// sRGB-encoded here unless the surface's format encodes it. The flag
// constants REINHARD and ENCODE_SRGB are generated from Rust (display.rs).

struct Display {
    origin: vec2<f32>,     // top-left corner of the area, framebuffer pixels
    size: vec2<f32>,       // its size, framebuffer pixels
    film: vec2<u32>,       // film width and height
    scale: f32,            // 2^exposure / samples
    flags: u32,            // bit 0: Reinhard (else clamp); bit 1: encode sRGB
}

@group(0) @binding(0) var<storage, read> accum: array<vec4<f32>>;
@group(0) @binding(1) var<uniform> display: Display;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the viewport.
    let x = f32(i32(i & 1u) * 4 - 1);
    let y = f32(i32(i >> 1u) * 4 - 1);
    return vec4<f32>(x, y, 0.0, 1.0);
}

fn srgb(c: f32) -> f32 {
    if (c <= 0.0031308) {
        return 12.92 * c;
    }
    return 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

@fragment
fn fs_main(@builtin(position) p: vec4<f32>) -> @location(0) vec4<f32> {
    let q = clamp((p.xy - display.origin) / display.size, vec2<f32>(0.0), vec2<f32>(1.0));
    let px = min(vec2<u32>(q * vec2<f32>(display.film)), display.film - vec2<u32>(1u));
    let a = accum[px.y * display.film.x + px.x];
    var c = max(a.rgb * display.scale, vec3<f32>(0.0));
    if ((display.flags & REINHARD) != 0u) {
        let l = dot(c, vec3<f32>(0.2126, 0.7152, 0.0722));
        c = select(vec3<f32>(0.0), c / (1.0 + l), l > 0.0);
    }
    c = clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
    if ((display.flags & ENCODE_SRGB) != 0u) {
        c = vec3<f32>(srgb(c.x), srgb(c.y), srgb(c.z));
    }
    return vec4<f32>(c, 1.0);
}
