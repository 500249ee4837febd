// ---- The path (integrator.rs) ----------------------------------------------
//
// A path's bounces (`bounce`), its escape to the environment (`escaped`),
// the shading of a surface vertex (`shade`) and a path's radiance from
// its camera ray (`radiance`), which the megakernel (`main`, camera.wgsl)
// runs whole and the wavefront (wavefront.wgsl) a bounce a step. Part of
// the path tracer's module (source.rs `RENDER_FILES`).

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
        oi = path.entry_o;
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
        // medium's table (tag.y - 1; layout/materials.rs `relative_in_media`). The
        // boundary of the innermost medium, met from inside, meets the
        // medium around it (integrator/media.rs `MediumStack::outside_of`).
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
    vertex_floor = object_floor(oi);
    let fr = bsdf_frame(m, ng, wo);
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
        let cos_o = dot(wo, fr.n);
        if (cos_o > 0.0) {
            mirror = vec4<f32>(2.0 * cos_o * fr.n - wo, fresnel_dielectric(cos_o, m.a.x));
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
    path = Path(o, d, vec3<f32>(0.0), vec3<f32>(1.0), -1.0, 1.0, 0u, 0u, 3u, 0u, false, false, vec3<f32>(0.0), 0u, 0u, vec3<f32>(1.0));
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
