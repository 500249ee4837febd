// ---- Camera rays and the megakernel (camera.rs) -----------------------------
//
// The camera ray of a pixel's sample on the sub-pixel grid, the camera
// rays' tile lists (`cull_tiles`, `use_tile`), the megakernel `main` (a
// thread per pixel and sample, each path to its end), the sample layers
// and `resolve`, which adds them to the image in sample order. Part of the
// path tracer's module (source.rs `RENDER_FILES`).

// The camera ray of sample s = `pass_info.x + gid.z` of pixel gid (one
// sample per thread, in every entry point): seeds the random stream of (seed,
// pixel, s) and returns the ray's direction from `params.origin`. Sample s
// takes cell (s + offset) mod (m n) of the m x n sub-pixel grid (offset
// random per pixel), jittered inside the cell.
fn camera_sample(gid: vec3<u32>) -> vec3<f32> {
    let width = params.film.x;
    let height = params.film.y;
    let pixel = gid.y * width + gid.x;
    let gm = params.film.z;
    let gn = params.film.w;
    let cells = gm * gn;
    let seed = params.pass_info.z;
    let offset = pcg_hash(pixel ^ pcg_hash(seed)) % cells;
    let s = params.pass_info.x + gid.z;
    rng_state = pcg_hash(seed ^ pcg_hash(pixel ^ pcg_hash(s ^ params.pass_info.w)));
    let c = (s + offset) % cells;
    let j = rand2();
    let fx = f32(gid.x) + (f32(c % gm) + j.x) / f32(gm);
    let fy = f32(gid.y) + (f32(c / gm) + j.y) / f32(gn);
    return normalize(film_dir(fx, fy));
}

// The direction toward film position (x, y) in pixels (`camera_sample`'s,
// before normalizing).
fn film_dir(x: f32, y: f32) -> vec3<f32> {
    let sx = 2.0 * x / f32(params.film.x) - 1.0;
    let sy = 1.0 - 2.0 * y / f32(params.film.y);
    return params.forward.xyz + sx * params.right.xyz + sy * params.up.xyz;
}

// Whether the box [lo, hi] (relative to the camera) lies wholly on the
// negative side of the plane through the camera with normal n: its corner
// farthest along n is behind it. Corners, not centre and half extent: a
// box clamped to 1e30 on one side keeps its other side exact.
fn behind(n: vec3<f32>, lo: vec3<f32>, hi: vec3<f32>) -> bool {
    return dot(n, select(lo, hi, n >= vec3<f32>(0.0))) < 0.0;
}

// A side plane of the tile's pyramid through edge (a, b), oriented toward
// the pyramid's axis `mid`.
fn side(a: vec3<f32>, b: vec3<f32>, mid: vec3<f32>) -> vec3<f32> {
    let n = cross(a, b);
    return select(n, -n, dot(n, mid) < 0.0);
}

// Film tiles per row.
fn tiles_x() -> u32 {
    return (params.film.x + TILE - 1u) / TILE;
}

// The camera ray of pixel gid tests its tile's list (geometry.wgsl
// `tile_rays`) in kernels with TILE_LISTS (generated, source.rs
// `Features::tiles`), unless the list overflowed.
fn use_tile(gid: vec3<u32>) {
    if (TILE_LISTS) {
        tile_base = ((gid.y / TILE) * tiles_x() + gid.x / TILE) * TILE_STRIDE;
        tile_rays = tile_lists[tile_base] != NO_NODE;
    }
}

// The tile lists (`tile_lists`), one invocation per 8 x 8 (TILE) pixel
// tile: the object hierarchy walked against the pyramid from the camera
// through the tile's pixels, widened by half a pixel on each side (the
// rays' jitter stays inside their pixels; half a pixel is some 1e3 times
// the rounding of the rays' directions and of the planes' tests at any
// film size up to 1e5 pixels), keeping the leaves' objects of the nodes
// that no side plane (nor the camera's own plane) has wholly behind it.
// Run when the frame is prepared and when its camera moves (render.rs
// `GpuFrame::cull_tiles`), not per sample: a barrier-free pre-pass.
@compute @workgroup_size(64)
fn cull_tiles(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let tx = tiles_x();
    let ty = (params.film.y + TILE - 1u) / TILE;
    let t = gid.y * groups.x * 64u + gid.x;
    if (t >= tx * ty) {
        return;
    }
    let base = t * TILE_STRIDE;
    let wx = t % tx;
    let wy = t / tx;
    let xa = f32(wx * TILE) - 0.5;
    let xb = f32(min(wx * TILE + TILE, params.film.x)) + 0.5;
    let ya = f32(wy * TILE) - 0.5;
    let yb = f32(min(wy * TILE + TILE, params.film.y)) + 0.5;
    let c00 = film_dir(xa, ya);
    let c10 = film_dir(xb, ya);
    let c11 = film_dir(xb, yb);
    let c01 = film_dir(xa, yb);
    let mid = c00 + c10 + c11 + c01;
    let n0 = side(c00, c10, mid);
    let n1 = side(c10, c11, mid);
    let n2 = side(c11, c01, mid);
    let n3 = side(c01, c00, mid);
    let o = params.origin.xyz;
    var len = 0u;
    var node = select(0u, NO_NODE, params.counts.x == 0u);
    loop {
        if (node == NO_NODE) {
            break;
        }
        let nd = nodes[node];
        let lo = nd.bmin.xyz - o;
        let hi = nd.bmax.xyz - o;
        var next = nd.link.x;
        if (!(behind(n0, lo, hi) || behind(n1, lo, hi) || behind(n2, lo, hi) || behind(n3, lo, hi)
            || behind(params.forward.xyz, lo, hi))) {
            if (nd.link.y == 0u) {
                next = node + 1u;
            } else if (len + nd.link.y > TILE_LIST_MAX) {
                len = NO_NODE;
                break;
            } else {
                tile_lists[base + 1u + len] = nd.link.z;
                if (nd.link.y == 2u) {
                    tile_lists[base + 2u + len] = nd.link.w;
                }
                len += nd.link.y;
            }
        }
        node = next;
    }
    tile_lists[base] = len;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let width = params.film.x;
    let height = params.film.y;
    if (gid.x >= width || gid.y >= height) {
        return;
    }
    use_tile(gid);
    store_sample(gid, radiance(params.origin.xyz, camera_sample(gid)));
    count_capped();
}

// What a sample's radiance v adds to its pixel's sum: (v, 0), or
// (0, 0, 0, 1) when v is not finite or is negative (`.w` counts the
// samples dropped).
fn sample_value(v: vec3<f32>) -> vec4<f32> {
    if (finite3(v) && v.x >= 0.0 && v.y >= 0.0 && v.z >= 0.0) {
        return vec4<f32>(v, 0.0);
    }
    return vec4<f32>(0.0, 0.0, 0.0, 1.0);
}

// Sample v of pixel gid.xy into layer gid.z (`main`, `realtime`).
fn store_sample(gid: vec3<u32>, v: vec3<f32>) {
    let width = params.film.x;
    layers[(gid.z * params.film.y + gid.y) * width + gid.x] = sample_value(v);
}

// Adds a sample's radiance v to its layer's pixel (`wf_camera`'s index:
// the wavefront's paths, which end in any order of pixels; the run's
// layers, cleared before it, are added to the sums after it by
// `resolve`, in sample order).
fn add_sample(pixel: u32, v: vec3<f32>) {
    layers[pixel] = layers[pixel] + sample_value(v);
}

// The layers of one dispatch of `main` or `realtime`, added in sample
// order to each pixel's sum (replacing it when `layers.y` is 1): the same
// floating-point sums as one dispatch per sample adding to the pixel.
@compute @workgroup_size(8, 8)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>) {
    let width = params.film.x;
    let height = params.film.y;
    if (gid.x >= width || gid.y >= height) {
        return;
    }
    let pixel = gid.y * width + gid.x;
    var acc = vec4<f32>(0.0);
    if (params.layers.y == 0u) {
        acc = accum[pixel];
    }
    for (var z = 0u; z < params.layers.x; z++) {
        acc += layers[z * width * height + pixel];
    }
    accum[pixel] = acc;
}
