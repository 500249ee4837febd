// The path tracer on the GPU, mirroring crates/render/src/integrator.rs
// for surface materials (materials.wgsl) on exact perturbation-function
// geometry (geometry.wgsl):
//   * one thread per pixel and sample: a dispatch of `layers.x` layers
//     (z) writes sample `pass_info.x + z` of every pixel to layer z of
//     `layers`, then `resolve` adds the layers to the accumulation buffer
//     in sample order (so the sum is the same however the samples are
//     split into dispatches; one dispatch for many samples pays a GPU's
//     drain, the wait for its slowest workgroup, once instead of once a
//     sample; a loop over samples inside a thread lost some of them,
//     docs/gpu.md); the wavefront's paths add to the same layers, a run
//     of samples at a time (`add_sample`), which `resolve` then adds;
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
//
// This file declares the parameters, the bindings, the random numbers and
// the ray helpers; the rest of the path tracer follows it in the files of
// source.rs `RENDER_FILES` (environment, direct light, subsurface, manifold,
// media, integrator, camera, wavefront, AOVs), concatenated into one
// module, and realtime.wgsl after them.

struct Params {
    origin: vec4<f32>,    // camera position, 0
    forward: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    film: vec4<u32>,      // width, height, grid m, grid n
    pass_info: vec4<u32>, // first sample, samples per pixel of the frame (realtime.wgsl), seed (low, high)
    counts: vec4<u32>,    // objects, lights, max depth, environment kind
    env: vec4<f32>,       // constant radiance (rgb)
    env_size: vec4<u32>,  // map width, height, pyramid levels (realtime.wgsl)
    // The wavefront path tracer (`trace`, `trace_last`): step, 0, first
    // padded pixel of the tile, its paths.
    wave: vec4<u32>,
    // The sample layers of `main` and `realtime` (z of the dispatch) and
    // `resolve`: layer count, 1 when `resolve` replaces the sum (a
    // real-time frame's first layers) instead of adding to it.
    layers: vec4<u32>,
    // 1 + the material of the random-walk medium the camera is in (0:
    // none), 0, 0, 0: camera paths start in it.
    camera: vec4<u32>,
}

struct Light { position: vec4<f32>, intensity: vec4<f32>, plane: vec4<f32>, flat: vec4<u32> }

@group(0) @binding(0) var<storage, read> objects: array<Object>;
@group(0) @binding(1) var<storage, read> perturbations: array<Perturbation>;
@group(0) @binding(2) var<storage, read> materials: array<Material>;
@group(0) @binding(3) var<storage, read> lights: array<Light>;
@group(0) @binding(4) var<storage, read> env_texels: array<vec4<f32>>; // rgb, pdf_uv
@group(0) @binding(5) var<storage, read> env_cdf: array<f32>;          // marginal, then rows
@group(0) @binding(6) var<storage, read_write> accum: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> params: Params; // storage, not uniform: lib.rs params_buffer
@group(0) @binding(8) var<storage, read> material_data: array<f32>;
@group(0) @binding(9) var<storage, read> env_levels: array<vec4<u32>>; // realtime.wgsl
@group(0) @binding(10) var<storage, read> nodes: array<BvhNode>;
// AOVs (aov_main): per pixel (albedo, depth) then (normal, 0).
@group(0) @binding(11) var<storage, read_write> aov: array<vec4<f32>>;
@group(0) @binding(12) var<storage, read> albedos: array<vec4<f32>>; // per material
// The camera rays' tile lists, written by `cull_tiles` when the frame is
// prepared and when its camera moves: per 8 x 8 pixel tile (row by row),
// TILE_STRIDE words, the list's length (NO_NODE: more than TILE_LIST_MAX
// objects, the tile's rays walk the hierarchy), then its objects.
@group(0) @binding(13) var<storage, read_write> tile_lists: array<u32>;
// One sample of every pixel per layer (`sample_value`), layer z from z of
// the dispatch, added up by `resolve`.
@group(0) @binding(14) var<storage, read_write> layers: array<vec4<f32>>;

// The camera ray's tile (`use_tile`), as the index of its first word.
var<private> tile_base: u32;

fn tile_entry(k: u32) -> u32 {
    return tile_lists[tile_base + k];
}

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

fn min3(v: vec3<f32>) -> f32 {
    return min(v.x, min(v.y, v.z));
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

// The spawn offset's floor at the path's current vertex: its object's
// (`object_floor`), set where a vertex is shaded (`shade`, the real-time
// kernel, `trace_shadow`) for the rays `offset_origin` spawns there.
var<private> vertex_floor: f32;

// The part of the offset off object oi's surface that does not grow with
// the distance (lib.rs `SPAWN_OFFSET`): that constant times the object's
// length, its box's largest side at most 1 (`GpuObject::origin.w`; an
// unbounded object's the scene's, `isolux_geometry::Aggregate::length`),
// as the CPU's `Hit::offset`: a bead 1e-3 across on a floor 10 wide
// starts its rays 1e-7 off it, not the floor's 1e-4.
fn object_floor(oi: u32) -> f32 {
    return SPAWN_OFFSET * objects[oi].origin.w;
}

// How far a ray leaving a surface of floor `floor` (`object_floor`) at p
// starts off it: the floor plus `SPAWN_OFFSET_WORLD` of the distance, the
// world point's own f32 rounding.
fn spawn_offset_at(p: vec3<f32>, floor: f32) -> f32 {
    let a = abs(p);
    return floor + SPAWN_OFFSET_WORLD * max(a.x, max(a.y, a.z));
}

// The point p of a surface of floor `floor` moved off it along n to the
// side of w (f32: a wider margin than the CPU's 1e-7; lib.rs
// `SPAWN_OFFSET`).
fn offset_from(p: vec3<f32>, n: vec3<f32>, w: vec3<f32>, floor: f32) -> vec3<f32> {
    let eps = spawn_offset_at(p, floor);
    return select(p - n * eps, p + n * eps, dot(w, n) >= 0.0);
}

// The path's current vertex p moved off its surface (`offset_from`).
fn offset_origin(p: vec3<f32>, n: vec3<f32>, w: vec3<f32>) -> vec3<f32> {
    return offset_from(p, n, w, vertex_floor);
}
