// Next-event estimation (crates/render/src/integrator.rs): `direct_light`
// gathers the point lights, an environment map's light sample and, for a
// dipole medium's single scattering, a cosine-sampled direction, each
// weighted by MIS against the BSDF; the shadow rays a caller traced ahead
// (`trace_shadows`); and the state of the path a thread carries (`Path`,
// `path`) with the packing of the media it is in. Part of the path
// tracer's module (source.rs `RENDER_FILES`).

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
        var refr_floor = 0.0;
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
            refr_floor = c.floor;
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
            t_max = dot(r.c - origin, wi) * (1.0 - 1e-4) - spawn_offset_at(r.c, r.floor);
            rad = lights[li].intensity.rgb * r.factor
                * medium_extinction(path.medium, r.inside);
            refracted = true;
            refr_c = r.c;
            refr_n = r.n;
            refr_floor = r.floor;
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
                                              refr_c, refr_n, refr_floor, li);
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
    // two in 16-bit ones, render/media.rs `medium_bits`); the hero channel
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
    // `entry_m`, on object `entry_o`): no ray to trace.
    entry: bool,
    entry_n: vec3<f32>,
    entry_m: u32,
    entry_o: u32,
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
