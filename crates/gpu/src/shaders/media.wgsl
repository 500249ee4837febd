// ---- Media (integrator.rs and integrator/) ---------------------------------
//
// Light along rays that cross media and their boundaries: a connection's
// and a shadow ray's transmittance, the lamps in a medium gathered along a
// free flight (equiangular sampling, `medium_light`), the stack of media a
// path is in (`medium_outside`, `medium_crossed`), and a free flight's
// scattering event (`medium_scatter`). Part of the path tracer's module
// (source.rs `RENDER_FILES`).

// The transmittance of a light's connection from o along d to t_max
// (`as_light`: a point light's shadow ray, `shadow_transmittance`), and
// where `refracted` (a `Refraction`'s, to light i, ending at c on the
// innermost medium's boundary, flat or curved, of outward normal cn and
// spawn floor c_floor, short of it) also beyond the boundary, from c to the light in the
// media after crossing (`crosses`; a `Caustic`'s second leg, from the
// glass's entry crossing c, stays in the same media). One call site of
// `shadow_transmittance` per caller.
fn connection_transmittance(o: vec3<f32>, d: vec3<f32>, t_max: f32, as_light: bool,
                            refracted: bool, crosses: bool, c: vec3<f32>, cn: vec3<f32>,
                            c_floor: f32, i: u32) -> vec3<f32> {
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
            oo = c + cn * spawn_offset_at(c, c_floor);
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
// (integrator/medium.rs `medium_lights`): every light in a scene with null
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
// (integrator/medium.rs `medium_light` and `equiangular_light`): where
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
        // that blocked its shadow ray (`caustic`, integrator/medium.rs
        // `caustic_scattered_at`), unweighted: the scattering points alone
        // sample that light.
        for (var k = 0u; k < select(3u, 4u, CAUSTICS); k++) {
            var tk = t;
            var w = vec3<f32>(0.0);
            var refr = Refraction(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0);
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
                refr = Refraction(c.wi, c.inside, c.x1, c.factor, c.n1, c.floor);
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
                dist = refr.inside * (1.0 - 1e-4) - spawn_offset_at(refr.c, refr.floor);
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
            let tr = connection_transmittance(p, wl, dist, k < 2u, k >= 2u, leaves, refr.c, refr.n, refr.floor, i);
            if (k == 1u) {
                blocked = !(max3(tr) > 0.0);
            }
            l += rad * tr * w * hg_phase(dot(wl, d), g);
        }
    }
    return l;
}

// The medium on the outer side of the surface of medium id (1 + its
// material) for a path in the packed media med (integrator/media.rs
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
// (integrator/media.rs `MediumStack::cross`): out of it if med holds it (in any
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
    // Kernels for scenes without null boundaries (`NULL_BOUNDARIES`, source.rs
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
        o = offset_from(o + h.x * d, h.yzw, d, object_floor(hit_object));
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
