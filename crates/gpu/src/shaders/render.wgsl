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

struct Params {
    origin: vec4<f32>,
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

// How far a ray leaving the surface at p starts off it (lib.rs
// `SPAWN_OFFSET`).
fn spawn_offset(p: vec3<f32>) -> f32 {
    let a = abs(p);
    return SPAWN_OFFSET + SPAWN_OFFSET_WORLD * max(a.x, max(a.y, a.z));
}

// The hit point moved off the surface along n to the side of w (f32: a
// wider margin than the CPU's 1e-7; lib.rs `SPAWN_OFFSET`).
fn offset_origin(p: vec3<f32>, n: vec3<f32>, w: vec3<f32>) -> vec3<f32> {
    let eps = spawn_offset(p);
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

// What `direct_light` gathers (bits of its `what`).
const GATHER_LIGHTS: u32 = 1u; // the point lights
const GATHER_ENV: u32 = 2u;    // one sample of an environment map, MIS against the BSDF
const GATHER_COSINE: u32 = 4u; // one cosine-sampled direction toward the environment, MIS against the map

// Light gathered at p (geometric normal ng) by shadow rays, for material m
// in frame fr (integrator.rs): next-event estimation to the point lights
// and an environment map's light sample, a cosine-sampled direction toward
// the environment (the single scattering of a dipole medium), and the
// environment mirrored by a subsurface boundary (`mirror`: the world
// direction and its Fresnel weight; none when the weight is 0). The
// real-time kernel gathers the point lights only. Then, last, the
// vertex's BSDF sample of material sm (`material_draw` with a fresh uc
// and u), left in `bsdf`.
//
// One loop, one `material_f`, one `material_pdf` and one shadow ray for
// all of them, the BSDF sample's scoring included, called once per
// bounce: NIR and the NVIDIA driver inline every call site of the exact
// intersection and of the material library, whose switches over every
// model are the bulk of the kernel (docs/gpu.md, "One call site per
// switch over the library").
//
// The materials: `m` and `sm` as given where the kernel may shade with a
// material that differs from its record (`OWN_MATERIALS`: a `wave` placed
// at the hit, the subsurface integrator's lobes); otherwise both are the
// record `materials[mi]`, reloaded at each use (`shading_material`), so
// that no copy of it (7 vec4) stays live across the loop's shadow rays:
// the exact intersection is the kernels' register peak, and on RADV the
// gallery's path tracer then needs 163 VGPRs before scheduling instead of
// 189 (6 waves per SIMD instead of 4; docs/gpu.md, "Register pressure").
var<private> bsdf: BsdfSample;

// Whether a vertex may shade with a material other than its record.
const OWN_MATERIALS: bool = (MODELS & (1u << MAT_WAVE)) != 0u || SUBSURFACE;

// The material to shade with: `m` where it may differ from its record,
// else the record `materials[mi]` (a load, not a value kept live).
fn shading_material(m: Material, mi: u32) -> Material {
    if (OWN_MATERIALS) {
        return m;
    }
    return materials[mi];
}

// The real-time kernel traces a vertex's shadow rays before it shades it
// (`trace_shadows`), so that the shading state (material, frame,
// directions) is not live across an intersection, the kernel's register
// peak (RADV: the gallery's real-time kernel 138 -> 109 VGPRs before
// scheduling, 8 waves per SIMD instead of 6; docs/gpu.md "Register
// pressure"): bit i of `shadow_lights`, point light i is visible from the
// vertex. `direct_light` reads it when its caller traced them (`first`).
// Not in kernels of more than MASK_LIGHTS lights, nor in kernels with the
// candidate list, which Mesa 22.3's lavapipe miscompiled this way (a
// sphere of 600 bumps 0.9% dark; Mesa 25 exact). The path tracer keeps
// its shadow rays in `direct_light`'s loop: the same change took its
// peak from 162 to 160 only (what its loop carries across bounces is
// live anyway), and it would trace rays toward lights below the
// horizon, which the shading skips.
var<private> shadow_lights: u32;
const SHADOWS_FIRST: bool = !MANY_LIGHTS && !CANDIDATE_LIST;
// With `first` in the sorted wavefront's `trace_shade`, whether the
// environment's sample is visible too (`shadows_ahead`).
var<private> shadow_env: bool;

// The point lights' shadow rays from vertex p (geometric normal ng), into
// `shadow_lights`: the rays `direct_light` would trace, in one loop with
// one call site of the intersection.
fn trace_shadows(p: vec3<f32>, ng: vec3<f32>) {
    let n_lights = min(params.counts.y, MASK_LIGHTS);
    var vis = 0u;
    for (var i = 0u; i < n_lights; i++) {
        let light = lights[i].position.xyz;
        let origin = offset_origin(p, ng, light - p);
        let d = light - origin;
        let dist2 = dot(d, d);
        if (dist2 > 0.0) {
            let t_max = sqrt(dist2);
            if (!occluded(origin, d / t_max, t_max)) {
                vis |= 1u << i;
            }
        }
    }
    shadow_lights = vis;
}

// Direct light at vertex p: with `first` (a constant at each call site),
// its shadow rays were traced by the caller: by `trace_shadows` where it
// gathers only point lights (the real-time kernel), by `shadows_ahead`
// with the environment's sample (the sorted wavefront's `trace_shade`);
// else they are traced here.
fn direct_light(p: vec3<f32>, ng: vec3<f32>, fr: Frame, m: Material, wo_l: vec3<f32>, what: u32, mirror: vec4<f32>, sm: Material, mi: u32, first: bool) -> vec3<f32> {
    var l = vec3<f32>(0.0);
    let env_map = params.counts.w == ENV_MAP;
    let n_lights = select(0u, params.counts.y, (what & GATHER_LIGHTS) != 0u);
    // The point lights again, through the flat boundary of the medium
    // around p (`refraction`).
    let n_refr = select(0u, n_lights, REFRACTION && SUBSURFACE && !first && path.medium != 0u);
    // With caustics each light's gather is followed by one through the
    // glass that blocked its shadow ray, if glass did (`caustic`; tried,
    // as on the CPU, only where the shadow ray was traced and blocked).
    let caus = CAUSTICS && !first;
    let n_pl = select(n_lights, 2u * n_lights, caus);
    let k_env = n_pl + n_refr;
    let n_env = select(0u, 1u, (what & GATHER_ENV) != 0u && env_map);
    let n_cos = select(0u, 1u, (what & GATHER_COSINE) != 0u);
    let n_mirror = select(0u, 1u, mirror.w > 0.0);
    let n = k_env + n_env + n_cos + n_mirror;
    bsdf = no_sample();
    var blocked = false; // the last light's shadow ray met something
    for (var i = 0u; i <= n; i++) {
        var wi: vec3<f32>;
        var wl: vec3<f32>;
        var origin: vec3<f32>;
        var t_max = 3.0e38;
        var rad: vec3<f32>;
        var light_pdf = 0.0; // > 0: the map's sample, weighted by MIS here
        var cos_factor = true; // false: rad already holds the cosine / pdf
        var with_f = true;     // false: the mirror, weighted by Fresnel alone
        var mm = shading_material(m, mi);
        var flags = 0u;
        var refracted = false;
        var refr_c = vec3<f32>(0.0);
        var refr_n = vec3<f32>(0.0);
        var refr_cross = true; // the second leg starts beyond a medium's boundary
        var plain = false;     // a point light's straight shadow ray
        var li = 0u;           // the light of a light's gather
        if (i == n) {
            // The BSDF sample, scored below unless its draw was (a plain
            // material's specular or closed-form sample) or failed.
            let uc = rand();
            let u = rand2();
            let d = material_draw(shading_material(sm, mi), wo_l, uc, u);
            if (!d.ok || d.pdf >= 0.0) {
                bsdf = d;
                break;
            }
            mm = shading_material(sm, mi);
            wl = d.wi;
            flags = d.flags;
        } else if (i < n_pl && caus && (i & 1u) == 1u) {
            li = i >> 1u;
            if (!blocked) {
                continue;
            }
            let c = caustic(li, p, ng);
            if (!(c.factor > 0.0)) {
                continue;
            }
            wi = c.wi;
            origin = offset_origin(p, ng, wi);
            // The way to the exit crossing is clear (`caustic` found the
            // glass first there); from the entry crossing to the light, in
            // the same media, the shadow ray's second leg.
            t_max = 0.0;
            rad = lights[li].intensity.rgb * c.factor * medium_extinction(path.medium, c.inside);
            refracted = true;
            refr_cross = false;
            refr_c = c.x1;
            refr_n = c.n1;
        } else if (i < n_pl) {
            li = select(i, i >> 1u, caus);
            plain = true;
            blocked = false;
            let light = lights[li];
            origin = offset_origin(p, ng, light.position.xyz - p);
            let d = light.position.xyz - origin;
            let dist2 = dot(d, d);
            if (!(dist2 > 0.0)) {
                continue;
            }
            t_max = sqrt(dist2);
            wi = d / t_max;
            rad = light.intensity.rgb / dist2;
            if (first) {
                // Occluded: no need to shade it.
                if (((shadow_lights >> li) & 1u) == 0u) {
                    continue;
                }
            }
        } else if (i < k_env) {
            li = i - n_pl;
            let r = refraction(li, p);
            if (!(r.factor > 0.0)) {
                continue;
            }
            wi = r.wi;
            origin = offset_origin(p, ng, wi);
            // To the crossing point, short of the boundary; the medium
            // attenuates the way there.
            t_max = dot(r.c - origin, wi) * (1.0 - 1e-4) - spawn_offset(r.c);
            rad = lights[li].intensity.rgb * r.factor
                * medium_extinction(path.medium, r.inside);
            refracted = true;
            refr_c = r.c;
            refr_n = r.n;
        } else if (i < k_env + n_env) {
            let s = env_sample(rand2());
            if (!(s.w > 0.0)) {
                continue;
            }
            if (first && !shadow_env) {
                continue;
            }
            wi = s.xyz;
            origin = offset_origin(p, ng, wi);
            rad = env_eval(wi);
            light_pdf = s.w;
        } else if (i < k_env + n_env + n_cos) {
            let local = cosine_hemisphere(rand2());
            if (local.z <= 0.0) {
                continue;
            }
            wi = to_world(fr, local);
            origin = offset_origin(p, ng, wi);
            var w = 1.0;
            if (env_map) {
                w = power_heuristic(local.z * INV_PI, env_pdf(wi));
            }
            rad = env_eval(wi) * (PI * w);
            cos_factor = false;
        } else {
            wi = mirror.xyz;
            origin = offset_origin(p, ng, wi);
            rad = env_eval(wi) * mirror.w;
            with_f = false;
        }
        if (i < n) {
            wl = to_local(fr, wi);
        }
        var fc = vec3<f32>(1.0);
        var pdf = 0.0;
        if (with_f) {
            // pdf before f (docs/gpu.md: Mesa 22's loop miscompile hit a
            // `wave` pdf evaluated after f).
            if (light_pdf > 0.0 || i == n) {
                pdf = material_pdf(mm, wo_l, wl);
            }
            fc = material_f(mm, wo_l, wl);
        }
        if (i == n) {
            bsdf = BsdfSample(wl, fc, pdf, flags, 1.0, true);
            break;
        }
        if (with_f) {
            fc *= select(1.0, abs(wl.z), cos_factor);
        }
        if (light_pdf > 0.0) {
            rad *= power_heuristic(light_pdf, pdf) / light_pdf;
        }
        if (max3(fc) <= 0.0 || max3(rad) <= 0.0) {
            continue;
        }
        // The shadow ray here unless `trace_shadows` traced them all (then
        // every gather still here is a visible light): dead code where
        // `first` is. (An `if` on the constant, not `first ||
        // !occluded(..)`: naga emits a call inside an expression
        // unconditionally, and RADV kept the intersection there, 160 ->
        // 188 VGPRs before scheduling.)
        // A point light's shadow ray is attenuated by the media the path
        // is in and passes null boundaries (`shadow_transmittance`).
        var lit = true;
        if (!first) {
            let tr = connection_transmittance(origin, wi, t_max, plain, refracted, refr_cross,
                                              refr_c, refr_n, li);
            rad *= tr;
            lit = max3(tr) > 0.0;
            blocked = plain && !lit;
        }
        if (lit) {
            l += fc * rad;
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
    // Subsurface media (random walk): the media the path is inside, each
    // as 1 + its material (0: none) in a slot of `medium_bits()` bits, the
    // innermost in the lowest slot and each around it in the next
    // (`medium_top`; eight media deep in 4-bit slots, four in 8-bit ones,
    // two in 16-bit ones, render.rs `medium_bits`); the hero channel
    // whose coefficients its free flights sample (3: none yet; `ratio`
    // below), the scattering events and boundary crossings so far.
    medium: u32,
    channel: u32,
    events: u32,
    // The environment along the current ray was already counted (the
    // mirror reflection of a subsurface boundary).
    env_counted: bool,
    // The next vertex is the entry point x_i of a dipole medium chosen by
    // `sss_dipole_bounce` (at `o`, normal `entry_n`, medium material
    // `entry_m`): no ray to trace.
    entry: bool,
    entry_n: vec3<f32>,
    entry_m: u32,
    // Each channel's path density relative to their mean (spectral MIS,
    // integrator.rs `Spectral`): 1 outside chromatic media.
    ratio: vec3<f32>,
}

var<private> path: Path;

// The width in bits of a packed medium's slot (`params.camera.w`, render.rs
// `medium_bits`): 4, so that media nest eight deep (as on the CPU), where
// every medium's 1 + material fits below the slot's mask; else 8 (four
// deep) or 16 (two deep).
fn medium_bits() -> u32 {
    return params.camera.w;
}

// The mask of a packed medium's slot.
fn medium_mask() -> u32 {
    return (1u << medium_bits()) - 1u;
}

// 1 + the material of the innermost medium the path is in (0: none).
fn medium_top() -> u32 {
    return path.medium & medium_mask();
}

// ---- Subsurface scattering (integrator.rs) ---------------------------------
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
// (integrator.rs single_scattering_light): `bounce` gathers its light
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
// x_i sampled around it (integrator.rs bssrdf_entry): a channel, a
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
    for (var i = 0u; i < 64u; i++) {
        let x = object_first_hit(oi, start, dir, t0, 2.0 * hh);
        if (x.x < 0.0) {
            break;
        }
        k += 1u;
        if (rand() * f32(k) < 1.0) {
            chosen = x;
        }
        t0 = x.x + spawn_offset(start + x.x * dir);
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
    path.entry = true;
    return max3(path.beta) > 0.0;
}

// A point light's connection into the innermost medium through its
// boundary (integrator.rs `refraction`, in f32): through a flat one by
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
}

// Whether a crossing point c lies in the box of object ob that clips its
// boundary (in the object's frame, the faces rounded outward; integrator.rs
// `in_box`).
fn in_box(ob: Object, c: vec3<f32>) -> bool {
    let lc = c - ob.origin.xyz;
    let tol = 1e-5 * (1.0 + max3(abs(lc)));
    return !(any(lc < ob.bmin.xyz - tol) || any(lc > ob.bmax.xyz + tol));
}

fn refraction(i: u32, p: vec3<f32>) -> Refraction {
    var r = Refraction(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0, vec3<f32>(0.0));
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
    // objects the medium's record lists (render.rs `manifold_media`): a
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
    // The plane (outward normal, offset) and 1 + the object whose box
    // clips it (0: none).
    var plane = light.plane;
    var boxed = light.flat.x;
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
        // F = 2 b . x + c > 0 inside (x from the object's origin): outward
        // normal -b (scene.rs `flat_boundary`).
        let b = vec3<f32>(q[1].z, q[1].w, q[2].x);
        let lb = length(b);
        let nrm = -b / lb;
        plane = vec4<f32>(nrm, dot(nrm, ob.origin.xyz) + q[2].y / (2.0 * lb));
        boxed = oi + 1u;
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
    return Refraction((c - p) / l2, l2, c, factor, n);
}

// ---- Manifold next-event estimation (manifold.rs) --------------------------
//
// A point light reaching a point p inside a random-walk medium through its
// curved boundary (integrator.rs `manifold_refraction`): Newton's method
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
    var v = vec4<real>(q_eval(obj.base, x), q_grad(obj.base, x));
    let first = obj.range.x;
    for (var k = first; k < first + obj.range.y; k++) {
        let pert = perturbations[k];
        let qv = q_eval(pert.q, x);
        if (qv > 0.0) {
            let f = real(pert.factor.x);
            v += vec4<real>(f * qv * qv * qv, 3.0 * f * qv * qv * q_grad(pert.q, x));
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
    var g = q_grad(obj.base, x);
    var hs = 2.0 * q_m(obj.base, sr);
    var ht = 2.0 * q_m(obj.base, tr);
    let first = obj.range.x;
    for (var k = first; k < first + obj.range.y; k++) {
        let pert = perturbations[k];
        let qv = q_eval(pert.q, x);
        if (qv > 0.0) {
            let f = real(pert.factor.x);
            let gq = q_grad(pert.q, x);
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
    let base = q_along(ob.base, lo, d);
    if (!(base.z > 0.0)) {
        return 0.0;
    }
    var t = first_root_below(base, t_max);
    for (var k = ob.range.x; k < ob.range.x + ob.range.y; k++) {
        let pert = perturbations[k];
        if (pert.factor.x < 0.0) {
            let dent = q_along(pert.q, lo, d);
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
// material; index n2 inside, n1 outside): integrator.rs
// `manifold_refraction`, manifold.rs `connect_from`.
fn manifold_refraction(oi: u32, id: u32, p: vec3<f32>, light: vec3<f32>, n1: f32, n2: f32) -> Refraction {
    var r = Refraction(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0, vec3<f32>(0.0));
    let to_light = light - p;
    let dist = length(to_light);
    if (!(dist > 0.0)) {
        return r;
    }
    // Russian roulette by the attenuation of the straight way out, in two
    // stages (integrator.rs `manifold_refraction`): first by d1, a lower
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
    return Refraction(to_x / lx, lx, x, factor, n);
}

// ---- Caustics: point lights through glass (manifold.rs `connect_through`)
//
// With `integrator.caustics = "manifold"` (`CAUSTICS`, lib.rs
// `Features::caustics`), a point light whose shadow ray from p first enters
// a `dielectric` object and leaves it again short of the light lights p
// through it (integrator.rs `caustic`): the path p -> x0 -> x1 -> light
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
// where its shadow ray meets one first (integrator.rs `caustic`).
fn caustic(k: u32, p: vec3<f32>, ng: vec3<f32>) -> Caustic {
    var r = Caustic(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0, vec3<f32>(0.0), vec3<f32>(0.0));
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
    let mm = materials[objects[oi].range.z];
    let e0 = origin + h.x * dir;
    // A dielectric entered (against the hit's outward normal) ...
    if (mm.tag.x != MAT_DIELECTRIC || !(dot(dir, h.yzw) < 0.0)) {
        return r;
    }
    // ... and left short of the light.
    let beyond = offset_origin(e0, h.yzw, dir);
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
    let o_in = offset_origin(x0, f0.n, inner);
    let t_in = dot(x1 - o_in, inner) * (1.0 - 1e-4) - spawn_offset(x1);
    if (t_in > 0.0 && occluded(o_in, inner, t_in)) {
        return r;
    }
    // The leg from p to the exit crossing: the first surface it meets is
    // the glass, at x0 (as on the CPU). A test of the segment short of x0
    // instead lost light at grazing exits (the caustic's outer rim),
    // where f32's x0, a little off the surface, lies a hundred times
    // farther along the ray.
    let o_p = offset_origin(p, ng, -to_p);
    let leg = dot(x0 - o_p, -to_p);
    let h0 = scene_hit(o_p, -to_p, leg * (1.0 + 1e-3) + spawn_offset(x0));
    if (!(h0.x >= 0.0) || hit_object != oi || length(o_p - h0.x * to_p - x0) > 1e-3 * (1.0 + leg)) {
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
    return Caustic(-to_p, lp, x0, factor, x1, f1.n);
}

// The transmittance of a light's connection from o along d to t_max
// (`as_light`: a point light's shadow ray, `shadow_transmittance`), and
// where `refracted` (a `Refraction`'s, to light i, ending at c on the
// innermost medium's boundary, flat or curved, of outward normal cn,
// short of it) also beyond the boundary, from c to the light in the
// media after crossing (`crosses`; a `Caustic`'s second leg, from the
// glass's entry crossing c, stays in the same media). One call site of
// `shadow_transmittance` per caller.
fn connection_transmittance(o: vec3<f32>, d: vec3<f32>, t_max: f32, as_light: bool,
                            refracted: bool, crosses: bool, c: vec3<f32>, cn: vec3<f32>,
                            i: u32) -> vec3<f32> {
    let med = path.medium;
    var tr = vec3<f32>(1.0);
    var oo = o;
    var dd = d;
    var tt = t_max;
    var lit = as_light;
    let legs = select(1u, 2u, (REFRACTION || CAUSTICS) && refracted);
    for (var leg = 0u; leg < legs; leg++) {
        if (leg == 1u) {
            if (crosses) {
                path.medium = medium_crossed(med, medium_top());
            }
            oo = c + cn * spawn_offset(c);
            let to = lights[i].position.xyz - oo;
            tt = length(to);
            dd = to / tt;
            lit = true;
        }
        tr *= shadow_transmittance(oo, dd, tt, lit);
        if (!(max3(tr) > 0.0)) {
            break;
        }
    }
    path.medium = med;
    return tr;
}

// Whether scattering events in the path's media try point light i
// (integrator.rs `medium_lights`): every light in a scene with null
// boundaries, else only the lights of the innermost medium's material
// (`position.w`, layout.rs `GpuLight`): one outside it is occluded by
// its boundary, and no shadow ray is traced to it.
fn medium_tries(i: u32) -> bool {
    return params.camera.y != 0u || u32(lights[i].position.w) == medium_top();
}

// Equiangular sampling toward point c on the segment [0, t_end) of the
// ray o + t d (core sampling.rs `Equiangular`, Kulla and Fajardo 2012):
// `(delta, D, theta_a, theta_b)`, with D = 0 where c lies on the ray's
// line and the density is not defined.
fn equiangular(o: vec3<f32>, d: vec3<f32>, t_end: f32, c: vec3<f32>) -> vec4<f32> {
    let to = c - o;
    let delta = dot(to, d);
    let dd = length(to - delta * d);
    if (!(t_end > 0.0) || !(dd > 1e-6 * length(to))) {
        return vec4<f32>(0.0);
    }
    let ta = atan2(-delta, dd);
    let tb = atan2(t_end - delta, dd);
    if (!(tb > ta)) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(delta, dd, ta, tb);
}

fn equiangular_pdf(e: vec4<f32>, t: f32) -> f32 {
    let x = t - e.x;
    return e.y / ((e.w - e.z) * (e.y * e.y + x * x));
}

// The point lights' light scattered toward the path along its flight
// from o along d through the innermost medium, which meets the next
// surface at t_end, per channel and unit of the path's throughput at o
// (integrator.rs `medium_light` and `equiangular_light`): where
// `scatter`, next-event estimation at the flight's scattering point t,
// `sigma_s T(t) / density(t) I p T_l / r^2` per light (the scattering
// point's weight, `Spectral`; with the lights through the medium's flat
// boundary, `refraction`); where `equi` (`params.camera.z`, scene key
// `medium_light_sampling`), one equiangular sample per light along the
// flight, `sigma_s T(t') I p T_l / r^2 / pdf(t')`, the two weighted by
// the power heuristic against the flight's density over the channels,
// `mean(ratio sigma_t T(t))`. One call site of `connection_transmittance`
// (docs/gpu.md, "One call site per switch").
fn medium_light(o: vec3<f32>, d: vec3<f32>, t: f32, t_end: f32, equi: bool, scatter: bool) -> vec3<f32> {
    let mm = materials[medium_top() - 1u];
    let ss = mm.b.rgb;
    let st = mm.b.rgb + mm.c.rgb;
    let g = mm.a.y;
    let tr_t = exp(-st * t);
    let density_t = dot(path.ratio, st * tr_t) / 3.0;
    var l = vec3<f32>(0.0);
    for (var i = 0u; i < params.counts.y; i++) {
        let light = lights[i];
        var e = vec4<f32>(0.0);
        if (equi && medium_tries(i)) {
            e = equiangular(o, d, t_end, light.position.xyz);
        }
        // Whether the scattering point's shadow ray met something.
        var blocked = false;
        // k = 0: the equiangular sample; k = 1: the scattering point; k =
        // 2: the scattering point lit through the medium's flat boundary;
        // k = 3 (with CAUSTICS): the scattering point lit through glass
        // that blocked its shadow ray (`caustic`, integrator.rs
        // `caustic_scattered_at`), unweighted: the scattering points alone
        // sample that light.
        for (var k = 0u; k < select(3u, 4u, CAUSTICS); k++) {
            var tk = t;
            var w = vec3<f32>(0.0);
            var refr = Refraction(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0, vec3<f32>(0.0));
            var leaves = true; // the second leg starts beyond the boundary
            if (k == 3u) {
                if (!blocked) {
                    continue;
                }
                let c = caustic(i, o + t * d, vec3<f32>(0.0));
                if (!(c.factor > 0.0)) {
                    continue;
                }
                // As a refraction: to the exit crossing (checked by
                // `caustic`), then from the entry crossing to the light in
                // the same media.
                refr = Refraction(c.wi, c.inside, c.x1, c.factor, c.n1);
                leaves = false;
                w = ss * tr_t / density_t;
            } else if (k == 2u) {
                if (!REFRACTION || !scatter || !(density_t > 0.0)) {
                    continue;
                }
                refr = refraction(i, o + t * d);
                if (!(refr.factor > 0.0)) {
                    continue;
                }
                w = ss * tr_t / density_t;
            } else if (!medium_tries(i)) {
                continue;
            } else if (k == 0u) {
                let u = rand();
                if (e.y == 0.0) {
                    continue;
                }
                tk = e.x + e.y * tan(e.z + u * (e.w - e.z));
                let pdf = equiangular_pdf(e, tk);
                if (!(tk >= 0.0 && tk < t_end) || !(pdf > 0.0) || !finite(pdf)) {
                    continue;
                }
                let tr = exp(-st * tk);
                let density = dot(path.ratio, st * tr) / 3.0;
                w = ss * tr * (power_heuristic(pdf, density) / pdf);
            } else {
                if (!scatter || !(density_t > 0.0)) {
                    continue;
                }
                w = ss * tr_t / density_t;
                if (e.y != 0.0) {
                    w *= power_heuristic(density_t, equiangular_pdf(e, t));
                }
            }
            if (!(max3(w) > 0.0) || !finite3(w)) {
                continue;
            }
            let p = o + tk * d;
            var wl: vec3<f32>;
            var dist: f32;
            var rad: vec3<f32>;
            if (k == 3u) {
                wl = refr.wi;
                dist = 0.0;
                rad = light.intensity.rgb * refr.factor * exp(-st * refr.inside);
            } else if (k == 2u) {
                // To the crossing point, short of the boundary; the medium
                // attenuates the way there.
                wl = refr.wi;
                dist = refr.inside * (1.0 - 1e-4) - spawn_offset(refr.c);
                rad = light.intensity.rgb * refr.factor * exp(-st * refr.inside);
            } else {
                let dl = light.position.xyz - p;
                let dist2 = dot(dl, dl);
                if (!(dist2 > 0.0)) {
                    continue;
                }
                dist = sqrt(dist2);
                wl = dl / dist;
                rad = light.intensity.rgb / dist2;
            }
            let tr = connection_transmittance(p, wl, dist, k < 2u, k >= 2u, leaves, refr.c, refr.n, i);
            if (k == 1u) {
                blocked = !(max3(tr) > 0.0);
            }
            l += rad * tr * w * hg_phase(dot(wl, d), g);
        }
    }
    return l;
}

// The medium on the outer side of the surface of medium id (1 + its
// material) for a path in the packed media med (integrator.rs
// `MediumStack::outside_of`): the innermost, or where id is the innermost
// (the path leaving it) the one around it.
fn medium_outside(med: u32, id: u32) -> u32 {
    let mask = medium_mask();
    if ((med & mask) == id) {
        return (med >> medium_bits()) & mask;
    }
    return med & mask;
}

// The packed media med after crossing the boundary of medium id
// (integrator.rs `MediumStack::cross`): out of it if med holds it (in any
// slot: media may overlap), else into it; MEDIA_TOO_DEEP for one more
// than the slots hold (refused before the render, render.rs
// `nested_too_deep`).
const MEDIA_TOO_DEEP: u32 = 0xffffffffu;
fn medium_crossed(med: u32, id: u32) -> u32 {
    let b = medium_bits();
    let mask = medium_mask();
    for (var k = 0u; k < 8u; k++) {
        let s = k * b;
        if (s >= 32u) {
            break;
        }
        if (((med >> s) & mask) == id) {
            // The slots below it stay, those above move down one.
            let above = select(0u, (med >> (s + b)) << s, s + b < 32u);
            return (med & ((1u << s) - 1u)) | above;
        }
    }
    if ((med >> (32u - b)) != 0u) {
        return MEDIA_TOO_DEEP;
    }
    return (med << b) | id;
}

// Extinction over a distance t in the innermost of the packed media med
// (`path.medium`'s packing), per channel.
fn medium_extinction(med: u32, t: f32) -> vec3<f32> {
    let top = med & medium_mask();
    if (!SUBSURFACE || top == 0u) {
        return vec3<f32>(1.0);
    }
    let mm = materials[top - 1u];
    return exp(-(mm.b.rgb + mm.c.rgb) * t);
}

// The transmittance of a shadow ray from o along d to distance t_max
// (integrator.rs `light_transmittance`), 0 where a surface is in the way.
// Toward a point light (`light`) it is attenuated by the media the path
// is in and, in a scene with null boundaries (`params.camera.y`: a
// random-walk medium whose index equals the index on its other side,
// fog of index 1), passes through them into or out of their media; the
// environment's rays stop at every surface. One call site of the
// intersection, in the loop (docs/gpu.md, "One call site per switch").
fn shadow_transmittance(o0: vec3<f32>, d: vec3<f32>, t_max: f32, light: bool) -> vec3<f32> {
    // Kernels for scenes without null boundaries (`NULL_BOUNDARIES`, lib.rs
    // `Features::null_boundaries`): one occlusion test, no loop.
    if (!SUBSURFACE || !NULL_BOUNDARIES) {
        if (occluded(o0, d, t_max)) {
            return vec3<f32>(0.0);
        }
        return medium_extinction(select(0u, path.medium, light), t_max);
    }
    let through = light && params.camera.y != 0u;
    let goal = o0 + t_max * d;
    var o = o0;
    var left = t_max;
    var med = select(0u, path.medium, light);
    var tr = vec3<f32>(1.0);
    for (var k = 0u; k < 16u; k++) {
        let h = scene_first_hit(o, d, 0.0, left, params.counts.x, !through);
        if (h.x < 0.0) {
            return tr * medium_extinction(med, left);
        }
        if (!through) {
            return vec3<f32>(0.0);
        }
        // A null boundary: a random-walk medium of the index outside it.
        let mi = objects[hit_object].range.z;
        let mm = materials[mi];
        if (mm.tag.x != MAT_SUBSURFACE || mm.tag.w != 1u) {
            return vec3<f32>(0.0);
        }
        let id = mi + 1u;
        let outside = medium_outside(med, id);
        var n_out = 1.0;
        if (outside != 0u) {
            n_out = materials[outside - 1u].a.x;
        }
        if (mm.a.x != n_out) {
            return vec3<f32>(0.0);
        }
        tr *= medium_extinction(med, h.x);
        med = medium_crossed(med, id);
        if (med == MEDIA_TOO_DEEP) {
            return vec3<f32>(0.0);
        }
        o = offset_origin(o + h.x * d, h.yzw, d);
        left = dot(goal - o, d);
        if (!(left > 0.0)) {
            return tr;
        }
    }
    return vec3<f32>(0.0);
}

// A scattering event at distance t along the flight from o along d
// inside the medium (random walk): its weight per channel (`Spectral`),
// roulette, a Henyey-Greenstein direction about d (its point lights were
// gathered by `bounce`'s `medium_light`).
fn medium_scatter(o: vec3<f32>, d: vec3<f32>, t: f32) -> bool {
    path.events += 1u;
    if (path.events > MAX_MEDIUM_EVENTS) {
        return false;
    }
    let mm = materials[medium_top() - 1u];
    let sigma_t = mm.b.rgb + mm.c.rgb;
    let tr = exp(-sigma_t * t);
    spectral_update(mm.b.rgb * tr, sigma_t * tr);
    let p = o + t * d;
    let beta = roulette(path.beta);
    if (!(max3(beta) > 0.0)) {
        return false;
    }
    path.beta = beta;
    let cos_t = sample_hg_cos(mm.a.y, rand());
    let sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
    let phi = 2.0 * PI * rand();
    let f = frame_from_normal(d);
    path.o = p;
    path.d = normalize(to_world(f, vec3<f32>(sin_t * cos(phi), sin_t * sin(phi), cos_t)));
    path.prev_pdf = -1.0;
    path.env_counted = false;
    return true;
}

// One bounce of the path: false when it ends. (The loop lives in
// `radiance`, the body here: one large loop body miscompiled on lavapipe.)
// Each bounce finds its vertex (a traced ray, or the entry point of a
// dipole medium), gathers direct light there and samples the
// continuation with one `direct_light` call.
fn bounce() -> bool {
    let entry = path.entry;
    path.entry = false;
    var p: vec3<f32>;
    var ng: vec3<f32>;
    var wo: vec3<f32>;
    var m: Material;
    var oi = 0u;
    var mi = 0u;
    if (SUBSURFACE && entry) {
        p = path.o;
        ng = path.entry_n;
        wo = ng;
        m = materials[path.entry_m];
        m.tag.x = MAT_SSS_ENTRY_LOBE;
        m.tag.z = 0u;
    } else {
        let o = path.o;
        let d = path.d;
        // Free flight inside a medium limits the search for the surface,
        // unless equiangular sampling of its lights needs the whole flight
        // (`params.camera.z`, integrator.rs `MediumLightSampling`).
        var t_max = 3.0e38;
        var flight = false;
        var equi = false;
        var any_lights = false;
        var refracts = false;
        if (SUBSURFACE && path.medium != 0u) {
            let mm = materials[medium_top() - 1u];
            let sigma_t = mm.b.rgb + mm.c.rgb;
            flight = max3(sigma_t) > 0.0;
            if (flight) {
                // The hero channel's free flight (drawn at the path's
                // first chromatic medium; a grey medium's are all alike).
                if (path.channel > 2u && !grey_medium(mm)) {
                    path.channel = min(u32(rand() * 3.0), 2u);
                }
                let st = sigma_t[min(path.channel, 2u)];
                if (st > 0.0) {
                    t_max = -log(1.0 - rand()) / st;
                }
                for (var i = 0u; i < params.counts.y; i++) {
                    any_lights = any_lights || medium_tries(i);
                    refracts = refracts
                        || (REFRACTION && (u32(lights[i].intensity.w) == medium_top()
                            || (MANIFOLD && mm.c.w != 0.0
                                && u32(lights[i].position.w)
                                    == medium_outside(path.medium, medium_top()))));
                }
                // (A medium that does not scatter has nothing to gather.)
                equi = any_lights && params.camera.z != 0u && max3(mm.b.rgb) > 0.0;
            }
        }
        let h = scene_hit(o, d, select(t_max, 3.0e38, equi));
        if (SUBSURFACE && flight) {
            let t_end = select(3.0e38, h.x, h.x >= 0.0);
            let scatter = t_max < t_end;
            if ((any_lights && (equi || scatter)) || (refracts && scatter)) {
                let hit = hit_object;
                path.l += path.beta * medium_light(o, d, t_max, t_end, equi, scatter);
                hit_object = hit;
            }
            if (scatter) {
                return medium_scatter(o, d, t_max);
            }
            // The flight passed the surface (or left for good): its
            // transmittance is its probability and its contribution.
            let tr = medium_extinction(path.medium, t_end);
            spectral_update(tr, tr);
        }
        if (h.x < 0.0) {
            escaped(d);
            return false;
        }
        oi = hit_object;
        mi = objects[oi].range.z;
        // A surface inside a random-walk medium meets the medium: its
        // record with its indices relative to the medium's, through the
        // medium's table (tag.y - 1; layout.rs `relative_in_media`). The
        // boundary of the innermost medium, met from inside, meets the
        // medium around it (integrator.rs `MediumStack::outside_of`).
        if (SUBSURFACE && path.medium != 0u) {
            let seen = medium_outside(path.medium, mi + 1u);
            if (seen != 0u) {
                let table = materials[seen - 1u].tag.y;
                if (table != 0u) {
                    mi = u32(material_data[table - 1u + mi]);
                }
            }
        }
        m = materials[mi];
        // A surface inside a medium ends the path at max depth like any
        // other; the medium's boundary, met from inside, lets it out.
        if (path.depth >= params.counts.z
            && (!SUBSURFACE || path.medium == 0u || m.tag.x != MAT_SUBSURFACE)) {
            return false;
        }
        p = o + h.x * d;
        m = placed(m, p, h.x);
        ng = h.yzw;
        wo = -d;
    }
    return shade(p, ng, wo, m, oi, mi, false);
}

// The path's light from the environment along d, where its ray escaped:
// MIS-weighted against the light sample of the vertex before.
fn escaped(d: vec3<f32>) {
    var w = 1.0;
    if (path.env_counted) {
        w = 0.0;
    } else if (path.prev_pdf > 0.0 && params.counts.w == ENV_MAP) {
        w = power_heuristic(path.prev_pdf, env_pdf(d));
    }
    path.l += path.beta * env_eval(d) * w;
}

// Material m as it is at hit p, t along the path's ray: spatially varying
// materials (wave) are placed at the hit, camera rays with the pixel
// footprint (the angle of one pixel times the distance), as on the CPU;
// the comb offset is drawn only for them.
fn placed(m: Material, p: vec3<f32>, t: f32) -> Material {
    if (has_wave(m)) {
        let fp = select(-1.0, pixel_footprint(t), path.depth == 0u);
        return place_material(m, p, fp, rand());
    }
    return m;
}

// The rest of a bounce at surface point p (geometric normal ng, toward
// the ray's origin wo) of object oi with material m (record mi): direct
// light, the BSDF's sample, the next ray in `path`. Whether the path goes
// on. With `traced` (a constant at each call site) the direct light's
// shadow rays were traced ahead (`shadows_ahead`), and the intersection
// is not in the caller's kernel.
fn shade(p: vec3<f32>, ng: vec3<f32>, wo: vec3<f32>, m: Material, oi: u32, mi: u32, traced: bool) -> bool {
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
    let is_medium = SUBSURFACE && m.tag.x == MAT_SUBSURFACE;
    // Direct light: the material's own lobes, or for a dipole medium seen
    // from outside its single scattering at x_o; a medium's boundary lobes
    // are specular (no light sampling for them).
    let single = is_medium && m.tag.w == 0u && m.b.w > 0.0 && dot(wo, ng) > 0.0;
    var nee_m = m;
    var what = GATHER_LIGHTS | GATHER_ENV;
    if (single) {
        nee_m = sss_single_lobe(m);
        what |= GATHER_COSINE;
    } else if (is_medium) {
        what = 0u;
    }
    // The environment mirrored by a subsurface boundary, seen from
    // outside, with its Fresnel weight on every path; a sampled reflection
    // then only carries what the mirror ray meets in the scene.
    var mirror = vec4<f32>(0.0);
    var mirror_env = false;
    if (is_medium) {
        let cos_o = dot(wo, ns);
        if (cos_o > 0.0) {
            mirror = vec4<f32>(2.0 * cos_o * ns - wo, fresnel_dielectric(cos_o, m.a.x));
            mirror_env = true;
        }
    }
    path.l += path.beta * direct_light(p, ng, fr, nee_m, wo_l, what, mirror, m, mi, traced);
    path.env_counted = false;
    let s = bsdf;
    if (!s.ok || !(s.pdf > 0.0) || !finite(s.pdf) || !finite3(s.f) || s.wi.z == 0.0) {
        return false;
    }
    let transmitted = (s.flags & FLAG_TRANSMISSION) != 0u;
    if (mirror_env && (s.flags & FLAG_REFLECTION) != 0u) {
        path.env_counted = true;
    }
    if (is_medium && m.tag.w == 0u && transmitted) {
        return sss_dipole_bounce(oi, p, ng, m, mi);
    }
    let wi = to_world(fr, s.wi);
    var beta = path.beta * s.f * (abs(s.wi.z) / s.pdf);
    path.eta_scale *= s.eta * s.eta;
    // Crossing a medium's boundary leaves it if the path is inside it,
    // and else enters it, inside the one the path is in (media nest four
    // deep, or two: `path.medium`).
    if (is_medium && transmitted) {
        let id = objects[oi].range.z + 1u;
        let next = medium_crossed(path.medium, id);
        if (next == MEDIA_TOO_DEEP) {
            return false;
        }
        path.medium = next;
    }
    path.prev_pdf = select(s.pdf, -1.0, (s.flags & FLAG_SPECULAR) != 0u);
    path.o = offset_origin(p, ng, wi);
    path.d = wi;
    // Meetings with a medium's boundary are medium events; a bounce on
    // any other surface counts toward the depth, also inside a medium.
    if (is_medium && (path.medium != 0u || transmitted)) {
        path.events += 1u;
        if (path.events > MAX_MEDIUM_EVENTS) {
            return false;
        }
    } else {
        path.depth += 1u;
    }
    if (path.depth >= 3u) {
        beta = roulette(beta);
    }
    path.beta = beta;
    return max3(beta) > 0.0;
}

// The width of one pixel at distance t along a camera ray (scene units).
fn pixel_footprint(t: f32) -> f32 {
    return t * 2.0 * length(params.up.xyz) / f32(params.film.y);
}

// The most bounces a path takes (`radiance`'s loop, `trace`'s steps).
fn bounce_bound() -> u32 {
    return 2u * params.counts.z + MAX_MEDIUM_EVENTS + 3u;
}

// Spectral MIS over the colour channels (integrator.rs `Spectral`): a
// flight event of densities p and contribution f per channel weighs the
// throughput by f / mean(ratio p) and updates the ratios.
fn spectral_update(f: vec3<f32>, p: vec3<f32>) {
    let m = dot(path.ratio, p) / 3.0;
    if (m > 0.0) {
        path.beta *= f / m;
        path.ratio = path.ratio * p / m;
    } else {
        path.beta = vec3<f32>(0.0);
    }
}

// Whether medium m scatters and absorbs every channel alike (grey fog):
// its flights need no hero channel and change no ratio, as on the CPU
// (`Subsurface::is_grey`).
fn grey_medium(m: Material) -> bool {
    return all(m.b.rgb == m.b.rrr) && all(m.c.rgb == m.c.rrr);
}

// A camera path from o along d, in `path`.
// A camera inside random-walk media starts in them (integrator.rs).
fn start_path(o: vec3<f32>, d: vec3<f32>) {
    path = Path(o, d, vec3<f32>(0.0), vec3<f32>(1.0), -1.0, 1.0, 0u, 0u, 3u, 0u, false, false, vec3<f32>(0.0), 0u, vec3<f32>(1.0));
    if (SUBSURFACE && params.camera.x != 0u) {
        path.medium = params.camera.x;
    }
}

// Up to n bounces of `path`: whether it is still alive after them.
fn bounces(n: u32) -> bool {
    for (var i = 0u; i < n; i++) {
        if (!bounce()) {
            return false;
        }
    }
    return true;
}

fn radiance(o: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    start_path(o, d);
    // Every bounce either ends the path or raises its depth (ending it at
    // max_depth) or its medium events (ending it at MAX_MEDIUM_EVENTS), or
    // chooses a dipole entry point whose bounce raises the depth: the
    // bound only guards against the unforeseen.
    bounces(bounce_bound());
    return path.l;
}

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
// `tile_rays`) in kernels with TILE_LISTS (generated, lib.rs
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

// ---- The wavefront path tracer (`trace`) ---------------------------------
//
// The same paths as `main`, bounce for bounce, with the loop over bounces
// split into dispatches (render.rs `dispatch_wavefront`): step 0 runs over
// every pixel of a tile, starts its camera ray and takes one bounce; each
// path still alive is stored in `wf_paths` and its slot queued; step k > 0
// runs (an indirect dispatch) over step k - 1's queue only, so a workgroup
// holds live paths instead of lanes idle since their path ended. The last
// step takes every remaining bounce of `radiance`'s bound. A path's random
// stream travels with it, so its radiance, and the image, are `main`'s.

struct WfPath {
    o: vec4<f32>,       // o, prev_pdf
    d: vec4<f32>,       // d, eta_scale
    l: vec4<f32>,       // l, rng_state (bits)
    beta: vec4<f32>,    // beta, pixel (bits)
    entry_n: vec4<f32>, // entry_n, entry_m (bits)
    info: vec4<u32>,    // depth, medium, channel | env_counted << 8 | entry << 9, events
    ratio: vec4<f32>,   // ratio, 0
}

@group(1) @binding(0) var<storage, read_write> wf_paths: array<WfPath>;
// Two queues of `params.wave.w` slots: step k reads queue k mod 2 and
// fills the other (the sorted wavefront's two lists follow them).
@group(1) @binding(1) var<storage, read_write> wf_queue: array<u32>;
// Per step k: the workgroups of its indirect dispatch, 1, 1, and the
// number of queued paths (filled by step k - 1, cleared by the host).
@group(1) @binding(2) var<storage, read_write> wf_ctl: array<atomic<u32>>;

fn wf_store(slot: u32, pixel: u32) {
    let flags = path.channel | select(0u, 256u, path.env_counted) | select(0u, 512u, path.entry);
    wf_paths[slot] = WfPath(
        vec4<f32>(path.o, path.prev_pdf),
        vec4<f32>(path.d, path.eta_scale),
        vec4<f32>(path.l, bitcast<f32>(rng_state)),
        vec4<f32>(path.beta, bitcast<f32>(pixel)),
        vec4<f32>(path.entry_n, bitcast<f32>(path.entry_m)),
        vec4<u32>(path.depth, path.medium, flags, path.events),
        vec4<f32>(path.ratio, 0.0),
    );
}

// Loads slot's path into `path` and `rng_state`; returns its pixel.
fn wf_load(slot: u32) -> u32 {
    let w = wf_paths[slot];
    path = Path(w.o.xyz, w.d.xyz, w.l.xyz, w.beta.xyz, w.o.w, w.d.w, w.info.x, w.info.y,
        w.info.z & 255u, w.info.w, (w.info.z & 256u) != 0u, (w.info.z & 512u) != 0u,
        w.entry_n.xyz, bitcast<u32>(w.entry_n.w), w.ratio.xyz);
    // Without the subsurface integrator its fields keep `start_path`'s
    // values (every write to them is behind SUBSURFACE): constants, not
    // values loaded and carried through the bounce to `wf_store` (RADV:
    // the gallery's wavefront step needs 165 VGPRs before scheduling
    // instead of 171, 6 waves per SIMD instead of 4).
    if (!SUBSURFACE) {
        path.medium = 0u;
        path.channel = 3u;
        path.events = 0u;
        path.entry = false;
        path.entry_n = vec3<f32>(0.0);
        path.entry_m = 0u;
        path.ratio = vec3<f32>(1.0);
    }
    rng_state = bitcast<u32>(w.l.w);
    return bitcast<u32>(w.beta.w);
}

// The camera path of slot `slot` on step 0 started in `path` and
// `rng_state` (the run's padded pixel `params.wave.z + slot`: of sample
// `pass_info.x + z` where a tile holds the run's `layers.x` samples, z
// padded films after the first): the pixel's (x, y) and z, or `NO_SLOT`
// in x where the slot has none. The same path and random numbers each
// time, so `trace_shade` starts it again on step 0 instead of loading
// what `trace_extend` would have stored.
const NO_SLOT: u32 = 0xffffffffu;
fn wf_camera(slot: u32) -> vec3<u32> {
    if (slot >= params.wave.w) {
        return vec3<u32>(NO_SLOT, 0u, 0u);
    }
    // Padded pixel index q in 8 x 8 blocks, row by row of blocks, so a
    // workgroup's camera rays are one block (as `main`'s 8 x 8 groups).
    let width = params.film.x;
    let blocks = (width + 7u) / 8u;
    let padded = blocks * ((params.film.y + 7u) / 8u) * 64u;
    let qz = params.wave.z + slot;
    let z = qz / padded;
    let q = qz % padded;
    let b = q / 64u;
    let x = (b % blocks) * 8u + q % 8u;
    let y = (b / blocks) * 8u + (q % 64u) / 8u;
    if (x >= width || y >= params.film.y || z >= params.layers.x) {
        return vec3<u32>(NO_SLOT, 0u, 0u);
    }
    start_path(params.origin.xyz, camera_sample(vec3<u32>(x, y, z)));
    return vec3<u32>(x, y, z);
}

// The index of sample layer z's pixel (x, y) (`store_sample`'s), where the
// wavefront's path of that pixel and sample adds its radiance.
fn wf_pixel(c: vec3<u32>) -> u32 {
    return (c.z * params.film.y + c.y) * params.film.x + c.x;
}

// The path of slot `gid.x` at the start of step `params.wave.x` (of the
// tile's pixels on step 0: its camera path started; of the last step's
// queue after: loaded) in `path` and `rng_state`: (slot, pixel), or
// `NO_SLOT` in x where the thread has none.
fn wf_begin(gid: vec3<u32>) -> vec2<u32> {
    let step = params.wave.x;
    let tile = params.wave.w;
    let slot = gid.x;
    if (step == 0u) {
        let c = wf_camera(slot);
        if (c.x == NO_SLOT) {
            return vec2<u32>(NO_SLOT, 0u);
        }
        // (Not in `wf_camera`: the tile's list serves the next
        // intersection, which only here is the camera ray's.)
        use_tile(vec3<u32>(c.xy, 0u));
        return vec2<u32>(slot, wf_pixel(c));
    }
    if (gid.x >= atomicLoad(&wf_ctl[4u * step + 3u])) {
        return vec2<u32>(NO_SLOT, 0u);
    }
    let queued = wf_queue[(step % 2u) * tile + gid.x];
    return vec2<u32>(queued, wf_load(queued));
}

// Appends `slot` to the list that starts at `wf_queue[list]` and whose
// counters `[workgroups, 1, 1, length]` start at `wf_ctl[counters]`: one
// workgroup of the indirect dispatch over the list per 64 paths.
fn wf_push(counters: u32, list: u32, slot: u32) {
    let at = atomicAdd(&wf_ctl[counters + 3u], 1u);
    if (at % 64u == 0u) {
        atomicAdd(&wf_ctl[counters], 1u);
    }
    wf_queue[list + at] = slot;
}

// The end of a step's bounce for the path of `slot`: queued for the next
// step if `alive`, else its radiance added to its pixel.
fn wf_end(slot: u32, pixel: u32, alive: bool) {
    if (alive) {
        let next = params.wave.x + 1u;
        wf_store(slot, pixel);
        wf_push(4u * next, (next % 2u) * params.wave.w, slot);
        return;
    }
    add_sample(pixel, path.l);
}

// Step `params.wave.x` of the wavefront for the path in slot `gid.x` (of
// the tile's pixels on step 0, of the last step's queue after). `last`, a
// constant at each entry point: the step takes every bounce left, in a
// loop; otherwise exactly one bounce and no loop, so that nothing is
// carried around a loop across the bounce's intersections (RADV, the
// gallery's step 163 -> 144 VGPRs before scheduling; docs/gpu.md
// "Register pressure").
fn wf_step(gid: vec3<u32>, last: bool) {
    let sp = wf_begin(gid);
    if (sp.x == NO_SLOT) {
        return;
    }
    var alive: bool;
    if (last) {
        alive = bounces(bounce_bound() - params.wave.x);
    } else {
        alive = bounce();
    }
    wf_end(sp.x, sp.y, alive && !last);
}

// Every step of the wavefront but the last (render.rs `dispatch_wavefront`).
@compute @workgroup_size(64)
fn trace(@builtin(global_invocation_id) gid: vec3<u32>) {
    wf_step(gid, false);
}

// The wavefront's last step.
@compute @workgroup_size(64)
fn trace_last(@builtin(global_invocation_id) gid: vec3<u32>) {
    wf_step(gid, true);
}

// ---- The sorted wavefront (`PathKernel::Sorted`) ---------------------------
//
// Each step but the last in three or four dispatches instead of `trace`'s
// one (render.rs `dispatch_wavefront`, docs/gpu.md "The sorted
// wavefront"): `trace_extend` finds each queued path's next surface (a
// path that escapes or reaches max depth ends there), lists the path
// with its hit and counts the list by material; `trace_scatter`
// reorders it by material; `trace_shadow` (where
// SHADOWS_AHEAD) traces each hit's shadow rays in that order;
// `trace_shade` shades each hit in that order and queues the path for
// the next step as `trace` does. So a SIMT group
// shades one material where `trace`'s groups shade whatever their rays
// met, and the intersection runs in a kernel without the material code.
// The same paths, bounce for bounce and random number for random number,
// as `trace`: the same image. Surfaces only: a scene with the subsurface
// integrator (media, dipoles) runs `trace` (render.rs).
//
// Per slot, `wf_hits` holds the hit (t, ng) and (object, bin, stamp,
// point lights visible) of the last step that listed it (the stamp: 1 +
// the step in bits 0-6, the environment's sample visible in bit 7, the
// tile's index in bits 8-15 and the sample's in 16-31, for diagnostics;
// the visibility from `shadows_ahead`); the
// queue buffer's third and fourth quarters the step's list as found and
// as sorted; `wf_ctl` after the steps' counters, per step, the list's
// [workgroups, 1, 1, length], then `WF_BINS` counts, then `WF_BINS`
// cursors.

@group(1) @binding(3) var<storage, read_write> wf_hits: array<vec4<f32>>;

// The sort's bins (`WF_BINS`, lib.rs): material records 0 .. WF_BINS - 2
// their own, the rest the last.

// Where step `params.wave.x`'s list counters start in `wf_ctl`
// (`params.wave.y` steps in all).
fn sort_base() -> u32 {
    return 4u * params.wave.y + params.wave.x * (4u + 2u * WF_BINS);
}

@compute @workgroup_size(64)
fn trace_extend(@builtin(global_invocation_id) gid: vec3<u32>) {
    let sp = wf_begin(gid);
    if (sp.x == NO_SLOT) {
        return;
    }
    let slot = sp.x;
    let h = scene_hit(path.o, path.d, 3.0e38);
    if (h.x < 0.0) {
        escaped(path.d);
        add_sample(sp.y, path.l);
        return;
    }
    if (path.depth >= params.counts.z) {
        add_sample(sp.y, path.l);
        return;
    }
    // The sort key: the material record, or one bin for every hit where
    // the sort keeps their order (`params.layers.z`, 0: comparisons).
    let oi = hit_object;
    let mi = objects[oi].range.z;
    let bin = select(0u, min(mi, WF_BINS - 1u), params.layers.z != 0u);
    wf_hits[2u * slot] = h;
    // The stamp (`sorted_steps`): 1 + the step, the tile, the sample (bit
    // 7 and the fourth word: `trace_shadow`'s answers).
    let tile_bits = ((params.wave.z / params.wave.w) & 255u) << 8u;
    let sample_bits = (params.pass_info.x & 65535u) << 16u;
    let stamp = (params.wave.x + 1u) | (tile_bits | sample_bits);
    wf_hits[2u * slot + 1u] = vec4<f32>(bitcast<f32>(oi), bitcast<f32>(bin),
                                        bitcast<f32>(stamp), 0.0);
    let base = sort_base();
    atomicAdd(&wf_ctl[base + 4u + bin], 1u);
    wf_push(base, 2u * params.wave.w, slot);
}

// The path of entry `gid.x` of the step's sorted list (`trace_shadow`,
// `trace_shade`) in `path` and `rng_state`: (slot, pixel), or `NO_SLOT`
// in x past the list's end. On step 0 its camera path started again
// (`trace_extend` stored nothing), on later steps loaded.
fn wf_listed(gid: vec3<u32>) -> vec2<u32> {
    if (gid.x >= atomicLoad(&wf_ctl[sort_base() + 3u])) {
        return vec2<u32>(NO_SLOT, 0u);
    }
    let slot = wf_queue[3u * params.wave.w + gid.x];
    if (params.wave.x == 0u) {
        return vec2<u32>(slot, wf_pixel(wf_camera(slot)));
    }
    return vec2<u32>(slot, wf_load(slot));
}

// Kernels in which `trace_shadow` traces the shadow rays of each listed
// hit (`shadows_ahead`) before `trace_shade` shades it, so that
// `trace_shade` holds no intersection (render.rs runs `trace_shadow`
// where `Features::shadows_ahead`, which mirrors this):
// a scene of at most MASK_LIGHTS point lights and no candidate list (as
// `trace_shadows`), without glass that bends the lamps' light
// (`caustic`) or the subsurface integrator (which the sorted wavefront
// leaves out). RADV, the gallery: `trace_shade` 168 -> 128 VGPRs, 6 -> 8
// waves per SIMD (docs/gpu.md, "Shadow rays ahead").
const SHADOWS_AHEAD: bool = SHADOWS_FIRST && !CAUSTICS && !SUBSURFACE;

// The shadow rays that `direct_light` will trace from the vertex p of a
// listed hit (geometric normal ng, toward the ray's origin wo; base
// material m), into `shadow_lights` and `shadow_env`: each point light,
// and the environment's sample, drawn from the path's random numbers
// as `trace_shade` will draw it (after `placed`'s comb offset of a
// `wave` material). `trace_shadow` stores neither the path nor its
// random numbers, so `trace_shade` draws the same again. Rays that
// `direct_light` would not trace are left out where the material's
// value is 0 for every direction (delta lobes alone) or for this one (a
// direction clearly below a surface that transmits nothing); the rest
// it skips (a sky or a value of 0 there) cost time, never change the
// image.
fn shadows_ahead(p: vec3<f32>, ng: vec3<f32>, wo: vec3<f32>, m: Material) {
    let flags = material_flags(m);
    shadow_lights = 0u;
    shadow_env = false;
    // Delta lobes alone (mirrors, glass): no light to sample, no ray.
    if ((flags & (FLAG_DIFFUSE | FLAG_GLOSSY)) == 0u) {
        return;
    }
    let transmits = (flags & FLAG_TRANSMISSION) != 0u;
    let ns = select(ng, -ng, dot(wo, ng) < 0.0 && !transmits);
    if (has_wave(m)) {
        _ = rand();
    }
    let n_lights = min(params.counts.y, MASK_LIGHTS);
    var env = vec4<f32>(0.0);
    if (params.counts.w == ENV_MAP) {
        env = env_sample(rand2());
    }
    var vis = 0u;
    var env_vis = false;
    // One call site of the intersection for all the rays.
    for (var i = 0u; i <= n_lights; i++) {
        var origin: vec3<f32>;
        var d: vec3<f32>;
        var t_max = 3.0e38;
        if (i < n_lights) {
            let light = lights[i].position.xyz;
            origin = offset_origin(p, ng, light - p);
            let to = light - origin;
            let dist2 = dot(to, to);
            if (!(dist2 > 0.0)) {
                continue;
            }
            t_max = sqrt(dist2);
            d = to / t_max;
        } else {
            if (!(env.w > 0.0)) {
                continue;
            }
            d = env.xyz;
            origin = offset_origin(p, ng, d);
        }
        if (!transmits && dot(d, ns) < -1e-4) {
            continue;
        }
        if (!occluded(origin, d, t_max)) {
            if (i < n_lights) {
                vis |= 1u << i;
            } else {
                env_vis = true;
            }
        }
    }
    shadow_lights = vis;
    shadow_env = env_vis;
}

// The shadow rays of each hit of the sorted list (`shadows_ahead`), their
// answers beside the hit for `trace_shade`: over the list in shading
// order, as `trace_shade`, so that its SIMT groups trace rays from one
// material's hits each, and none of a path that ended in `trace_extend`
// (traced there, they ran in groups of mostly ended paths: lavapipe,
// the gallery path traced 0.85 -> 0.97 of the wavefront's time).
@compute @workgroup_size(64)
fn trace_shadow(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (!SHADOWS_AHEAD) {
        return;
    }
    let slot = wf_listed(gid).x;
    if (slot == NO_SLOT) {
        return;
    }
    let h = wf_hits[2u * slot];
    let info = wf_hits[2u * slot + 1u];
    let mi = objects[bitcast<u32>(info.x)].range.z;
    shadows_ahead(path.o + h.x * path.d, h.yzw, -path.d, materials[mi]);
    let stamp = bitcast<u32>(info.z) | select(0u, 128u, shadow_env);
    wf_hits[2u * slot + 1u] = vec4<f32>(info.x, info.y, bitcast<f32>(stamp),
                                        bitcast<f32>(shadow_lights));
}

// The bins' first places in the sorted list (the counts' exclusive prefix
// sums), which each workgroup of `trace_scatter` takes itself, a bin per
// thread: until 2026-12-05 a kernel of one thread, `trace_prefix`, took
// them between `trace_extend` and `trace_scatter`, a dispatch and a
// barrier more per step.
const_assert WF_BINS == 64u;
var<workgroup> wf_first: array<u32, WF_BINS>;

// Each listed path to its place in the sorted list: its bin's first place
// and, after the paths placed there before it, the bin's cursor (from 0).
@compute @workgroup_size(64)
fn trace_scatter(@builtin(global_invocation_id) gid: vec3<u32>,
                 @builtin(local_invocation_index) li: u32) {
    let base = sort_base();
    let count = atomicLoad(&wf_ctl[base + 4u + li]);
    wf_first[li] = count;
    workgroupBarrier();
    // The inclusive sums (Hillis and Steele), then less the bin's own.
    for (var o = 1u; o < WF_BINS; o <<= 1u) {
        var v = 0u;
        if (li >= o) {
            v = wf_first[li - o];
        }
        workgroupBarrier();
        wf_first[li] += v;
        workgroupBarrier();
    }
    wf_first[li] -= count;
    workgroupBarrier();
    if (gid.x >= atomicLoad(&wf_ctl[base + 3u])) {
        return;
    }
    let tile = params.wave.w;
    let slot = wf_queue[2u * tile + gid.x];
    let bin = bitcast<u32>(wf_hits[2u * slot + 1u].y);
    let at = wf_first[bin] + atomicAdd(&wf_ctl[base + 4u + WF_BINS + bin], 1u);
    wf_queue[3u * tile + at] = slot;
}

@compute @workgroup_size(64)
fn trace_shade(@builtin(global_invocation_id) gid: vec3<u32>) {
    let sp = wf_listed(gid);
    if (sp.x == NO_SLOT) {
        return;
    }
    let slot = sp.x;
    let h = wf_hits[2u * slot];
    let info = wf_hits[2u * slot + 1u];
    let oi = bitcast<u32>(info.x);
    let mi = objects[oi].range.z;
    shadow_lights = bitcast<u32>(info.w);
    shadow_env = (bitcast<u32>(info.z) & 128u) != 0u;
    let p = path.o + h.x * path.d;
    let m = placed(materials[mi], p, h.x);
    wf_end(slot, sp.y, shade(p, h.yzw, -path.d, m, oi, mi, SHADOWS_AHEAD));
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
    use_tile(gid);
    let pixel = gid.y * width + gid.x;
    let h = scene_hit(params.origin.xyz, camera_sample(gid), 3.0e38);
    if (h.x >= 0.0) {
        let a = albedos[objects[hit_object].range.z].rgb;
        aov[2u * pixel] += vec4<f32>(a, h.x);
        aov[2u * pixel + 1u] += vec4<f32>(h.yzw, 0.0);
    }
}
