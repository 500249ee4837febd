// ---- The wavefront path tracer (`trace`) ---------------------------------
//
// The same paths as `main`, bounce for bounce, with the loop over bounces
// split into dispatches (render/wavefront.rs `dispatch_wavefront`): step 0 runs over
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
    ratio: vec4<f32>,   // ratio, entry_o (bits)
}

@group(1) @binding(0) var<storage, read_write> wf_paths: array<WfPath>;
// Two queues of `params.wave.w` slots: step k reads queue k mod 2 and
// fills the other (the sorted wavefront's two lists follow them).
@group(1) @binding(1) var<storage, read_write> wf_queue: array<u32>;
// Per step k: the workgroups of its indirect dispatch, 1, 1, and the
// number of queued paths (filled by step k - 1, cleared by the host).
// Its last four words, which the host clears with the frame's sums only,
// count the paths ended at MAX_MEDIUM_EVENTS (`count_capped`) in the
// first. The megakernel binds four words of its own here (`main`).
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
        vec4<f32>(path.ratio, bitcast<f32>(path.entry_o)),
    );
}

// Loads slot's path into `path` and `rng_state`; returns its pixel.
fn wf_load(slot: u32) -> u32 {
    let w = wf_paths[slot];
    path = Path(w.o.xyz, w.d.xyz, w.l.xyz, w.beta.xyz, w.o.w, w.d.w, w.info.x, w.info.y,
        w.info.z & 255u, w.info.w, (w.info.z & 256u) != 0u, (w.info.z & 512u) != 0u,
        w.entry_n.xyz, bitcast<u32>(w.entry_n.w), bitcast<u32>(w.ratio.w), w.ratio.xyz);
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
        path.entry_o = 0u;
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
    count_capped();
}

// Counts `path` if it ended at the cap of its medium events (`bounce`,
// `medium_scatter`: its light beyond lost), as the CPU's `Media::capped`
// (render.rs `GpuFrame::image`), in the first of `wf_ctl`'s last four
// words: the wavefront's counters' (`wf_end`), or the megakernel's own
// four (`main`, render.rs `MegaCount`). Only media raise `events`, and
// the sorted wavefront runs no scene with media.
fn count_capped() {
    if (SUBSURFACE && path.events > MAX_MEDIUM_EVENTS) {
        atomicAdd(&wf_ctl[arrayLength(&wf_ctl) - 4u], 1u);
    }
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

// Every step of the wavefront but the last (render/wavefront.rs `dispatch_wavefront`).
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
// one (render/wavefront.rs `dispatch_wavefront`, docs/gpu.md "The sorted
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
    let ns = facing(ng, wo, flags);
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
    let oi = bitcast<u32>(info.x);
    let mi = objects[oi].range.z;
    vertex_floor = object_floor(oi);
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
