// The `wave` material on the GPU: wave-optics diffraction from a
// heightfield of Gabor kernels, mirroring crates/materials/src/wave.rs and
// crates/wave/src/gabor.rs (formulas and symbols: docs/wave-optics.md).
// The CPU's kernel loops run in f32 too; phases are reduced to a fraction
// of a cycle before any sine, so that no driver's range reduction matters.
//
// Layout (layout/materials.rs, `GpuMaterials::wave`):
//   tag.y Fresnel per wavelength: ONE, DIELECTRIC (ior) or CONDUCTOR (a
//         measured metal's rows)
//   tag.z 1 once placed (d.xyz is then the heightfield's +x)
//   tag.w bit 0: model ohs (else ghs); bit 1: obliquity seed (else 1)
//   a     texel_um, coherence_um, um_per_unit, wavelengths
//   b     mapping centre xyz, mapping code (0-2 planar axis, 3 spherical,
//         4 cylindrical)
//   c     columns, rows, leaf columns, leaf rows
//   d     tangent (placed)
//   e     footprint centre x, y (um), sigma (um), comb offset (placed)
//   idx   x kernels [h, gx, gy] per texel, y leaf slope boxes, z header
//         [eps, ior, metal rows, 81 sRGB nodes (380..780 nm by 5), metal
//         rows (lambda um, n, k)], w 1 when culling by the leaves

// The material placed at world point `p` (Material::at_point): a `wave`
// (alone, or a mix's component) maps `p` to its heightfield and narrows
// its coherence area to half the pixel footprint `footprint` (scene
// units; <= 0: none) when smaller, with the comb offset `xi`; every other
// model is returned as is.
fn place_material(m: Material, p: vec3<f32>, footprint: f32, xi: f32) -> Material {
    if (m.tag.x == MAT_MIX && m.tag.w > 0u) {
        // A mix's `wave` leaves (`tag.w` the first's position + 1; `a`
        // their summed weight W, probability P and count, layout/materials.rs
        // `GpuMaterials::mix`): one is placed per hit, leaf j with
        // probability w_j / W, xi rescaled for its comb offset (one leaf:
        // j the first, xi as it is). `tag.w` then names j, which
        // `wave_weights` gives W and P: f is sum_k w_k f_k in expectation.
        // Its state `e` is kept in the mix's free `e` for `mix_wave`; the
        // frame's tangent is the first `wave`'s when the first leaf with
        // a tangent is that one (`idx.w` 1).
        let first = m.tag.w - 1u;
        var j = first;
        var u = xi;
        if (m.a.z > 1.0 && m.a.x > 0.0) {
            var acc = 0.0;
            for (var k = first; k < m.idx.z; k++) {
                if (materials[m.idx.y + k].tag.x != MAT_WAVE) {
                    continue;
                }
                let pk = mix_w(m, k) / m.a.x;
                if (pk <= 0.0) {
                    continue;
                }
                j = k;
                u = clamp((xi - acc) / pk, 0.0, 0.99999994);
                if (xi < acc + pk) {
                    break;
                }
                acc += pk;
            }
        }
        let w = place_wave(materials[m.idx.y + j], p, footprint, u);
        var out = m;
        out.e = w.e;
        out.tag.w = j + 1u;
        if (m.idx.w == 1u) {
            out.d = place_wave(materials[m.idx.y + first], p, footprint, u).d;
            out.tag.z = 1u;
        }
        return out;
    }
    if (m.tag.x != MAT_WAVE) {
        return m;
    }
    return place_wave(m, p, footprint, xi);
}

fn place_wave(m: Material, p: vec3<f32>, footprint: f32, xi: f32) -> Material {
    var out = m;
    let code = u32(m.b.w);
    var s = vec2<f32>(0.0);
    var t = vec3<f32>(1.0, 0.0, 0.0);
    if (code < 3u) {
        if (code == 0u) {
            s = p.yz;
            t = vec3<f32>(0.0, 1.0, 0.0);
        } else if (code == 1u) {
            s = p.xz;
        } else {
            s = p.xy;
        }
    } else {
        let d = p - m.b.xyz;
        let phi = wave_atan2(d.z, d.x);
        let rh = length(d.xz);
        if (rh > 0.0) {
            t = vec3<f32>(-d.z, 0.0, d.x) / rh;
        }
        if (code == 3u) {
            // acos(d.y / r), better conditioned.
            let theta = wave_atan2(rh, d.y);
            s = vec2<f32>(phi, theta) * length(d);
        } else {
            s = vec2<f32>(phi * rh, d.y);
        }
    }
    var sigma = m.a.y;
    if (footprint > 0.0) {
        let pix = 0.5 * footprint * m.a.z;
        if (pix < 3.0e38) {
            sigma = min(sigma, max(pix, 2.0 * m.a.x));
        }
    }
    out.e = vec4<f32>(s * m.a.z, sigma, xi);
    out.d = vec4<f32>(t, 0.0);
    out.tag.z = 1u;
    return out;
}

// atan2 to a few f32 ulps whatever the driver's (whose precision Vulkan
// leaves loose: lavapipe's moved coherence areas by 0.1 um, changing the
// interference): octant reduction, then atan(z) = atan(1/sqrt 3) + atan((z
// sqrt 3 - 1) / (z + sqrt 3)) above tan(pi/12), then the series to z^11.
fn wave_atan2(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    let hi = max(ax, ay);
    if (hi == 0.0) {
        return 0.0;
    }
    var z = min(ax, ay) / hi;
    var base = 0.0;
    if (z > 0.26794919) {
        z = (z * 1.7320508 - 1.0) / (z + 1.7320508);
        base = PI / 6.0;
    }
    let z2 = z * z;
    var a = base + z * (1.0 + z2 * (-1.0 / 3.0 + z2 * (0.2 + z2 * (-1.0 / 7.0 + z2 * (1.0 / 9.0 - z2 / 11.0)))));
    if (ay > ax) {
        a = 0.5 * PI - a;
    }
    if (x < 0.0) {
        a = PI - a;
    }
    return select(a, -a, y < 0.0);
}

// The hero comb: (k0, dk, n), wavenumbers in 1/um (Comb::shifted).
fn wave_comb(m: Material) -> vec3<f32> {
    let n = clamp(u32(m.a.w), 1u, WAVE_MAX_COMB);
    let dk = (WAVE_KMAX - WAVE_KMIN) / f32(n);
    return vec3<f32>(WAVE_KMIN + clamp(m.e.w, 0.0, 0.99999994) * dk, dk, f32(n));
}

// The window square: columns i0..=i1, rows j0..=j1, and the footprint's
// centre in texels relative to column i0 and row j0 (kept small, so that
// kernel positions relative to the centre stay exact in f32).
struct WaveWindow { i0: i32, i1: i32, j0: i32, j1: i32, o: vec2<f32>, radius: f32 }

fn wave_window(m: Material) -> WaveWindow {
    let l = m.a.x;
    let eps = material_data[m.idx.z];
    let radius = m.e.z * sqrt(max(2.0 * log(1.0 / eps), 0.0));
    let u = m.e.xy / l;
    let rt = radius / l;
    let i0 = i32(ceil(u.x - rt - 0.5));
    let j0 = i32(ceil(u.y - rt - 0.5));
    let i1 = max(i32(floor(u.x + rt - 0.5)), i0);
    let j1 = max(i32(floor(u.y + rt - 0.5)), j0);
    return WaveWindow(i0, i1, j0, j1, u - vec2<f32>(f32(i0), f32(j0)), radius);
}

// exp(-i 2 pi c) for a phase of c cycles, reduced first.
fn wave_cis_cycles(c: f32) -> vec2<f32> {
    let a = 2.0 * PI * (c - round(c));
    return vec2<f32>(cos(a), -sin(a));
}

// f / F at wavenumber k (1/um) of a comb starting at k0 (GaborSurface::eval
// at one of its wavelengths): the kernels inside the window's disk whose
// amplitude w_k exp(-B_k k0^2) reaches eps (one set for the whole comb,
// as on the CPU); a leaf's run of kernels is skipped when the bound over
// its slope box says none can. One wavelength per pass, with no array:
// the CPU's recurrence across the comb kept the comb in an indexed array,
// and Mesa 22's lavapipe lost loop iterations in a second inlined copy of
// that code (docs/gpu.md, the loop defect).
fn wave_spectrum(m: Material, wi: vec3<f32>, wo: vec3<f32>, k0: f32, k: f32) -> f32 {
    let l = m.a.x;
    let sigma = m.e.z;
    let eps = material_data[m.idx.z];
    let c3 = select(wi.z + wo.z, 2.0, (m.tag.w & 1u) != 0u);
    let psi = wi.xy + wo.xy;
    let win = wave_window(m);
    let inv2s2 = 1.0 / (2.0 * sigma * sigma);
    let a0 = 2.0 * PI * PI * (0.25 * l * l);
    let g0 = k0 * k0;
    let gk = k * k - g0;
    let ln_eps = log(eps);
    let w = i32(m.c.x);
    let hgt = i32(m.c.y);
    let nx = u32(m.c.z);
    let cull = m.idx.w == 1u;
    let gstar = -psi / c3;
    let r2 = win.radius * win.radius;
    var acc = vec2<f32>(0.0);
    for (var j = win.j0; j <= win.j1; j++) {
        let y = (f32(j - win.j0) + 0.5 - win.o.y) * l;
        let h2 = r2 - y * y;
        if (h2 < 0.0) {
            continue;
        }
        let wy = exp(-y * y * inv2s2);
        let hx = sqrt(h2) / l;
        let ia = max(win.i0 + i32(ceil(win.o.x - 0.5 - hx)), win.i0);
        let ib = min(win.i0 + i32(floor(win.o.x - 0.5 + hx)), win.i1);
        let r = wrap_index(j, hgt);
        let row = m.idx.x + 3u * u32(r * w);
        let yc = y * psi.y;
        var i = ia;
        loop {
            if (i > ib) {
                break;
            }
            let c = wrap_index(i, w);
            let end = min(ib, i + min(WAVE_LEAF - c % WAVE_LEAF, w - c) - 1);
            var skip = false;
            if (cull) {
                let b = m.idx.y + 4u * (u32(r / WAVE_LEAF) * nx + u32(c / WAVE_LEAF));
                let x_lo = (f32(i - win.i0) + 0.5 - win.o.x) * l;
                let x_hi = (f32(end - win.i0) + 0.5 - win.o.x) * l;
                let dx = max(max(x_lo, -x_hi), 0.0);
                let g = vec2<f32>(
                    clamp(gstar.x, material_data[b], material_data[b + 1u]),
                    clamp(gstar.y, material_data[b + 2u], material_data[b + 3u]),
                );
                let dd = psi + c3 * g;
                let log_bound = -(dx * dx + y * y) * inv2s2 - a0 * dot(dd, dd) * g0;
                skip = log_bound < ln_eps - 1e-3;
            }
            if (!skip) {
                for (var kk = i; kk <= end; kk++) {
                    let at = row + 3u * u32(c + (kk - i));
                    let h = material_data[at];
                    let gr = vec2<f32>(material_data[at + 1u], material_data[at + 2u]);
                    let x = (f32(kk - win.i0) + 0.5 - win.o.x) * l;
                    let dd = psi + c3 * gr;
                    let bk = a0 * dot(dd, dd);
                    let e = exp(-x * x * inv2s2) * wy * exp(-bk * g0);
                    if (e >= eps) {
                        // Theta_k / (2 pi) = c3 h + (c_k - x_c).psi, in
                        // cycles per 1/um.
                        let cyc = c3 * h + x * psi.x + yc;
                        acc += e * exp(-bk * gk) * wave_cis_cycles(cyc * k);
                    }
                }
            }
            i = end + 1;
        }
    }
    let l2 = l * l;
    let o = select(1.0, wo.z / wi.z, (m.tag.w & 2u) != 0u);
    return k * k * o * l2 * l2 / (PI * sigma * sigma) * dot(acc, acc);
}

// The normalized sRGB weight of wavelength lambda_nm (spectral.rs: the
// CIE table's nodes, linearly interpolated), zero outside the band.
fn wave_srgb(m: Material, lambda_nm: f32) -> vec3<f32> {
    let t = (lambda_nm - 380.0) / 5.0;
    if (!(t >= 0.0 && t <= 80.0)) {
        return vec3<f32>(0.0);
    }
    let i = min(u32(floor(t)), 79u);
    let f = t - f32(i);
    let at = m.idx.z + 3u + 3u * i;
    let a = vec3<f32>(material_data[at], material_data[at + 1u], material_data[at + 2u]);
    let b = vec3<f32>(material_data[at + 3u], material_data[at + 4u], material_data[at + 5u]);
    return a + (b - a) * f;
}

// Fresnel reflectance at lambda_nm (WaveFresnel::reflectance); a metal's
// rows are interpolated linearly and clamped at their ends (Metal::nk).
fn wave_fresnel(m: Material, lambda_nm: f32, cos_h: f32) -> f32 {
    let z = m.idx.z;
    if (m.tag.y == FRESNEL_DIELECTRIC) {
        return fresnel_dielectric(cos_h, material_data[z + 1u]);
    }
    if (m.tag.y != FRESNEL_CONDUCTOR) {
        return 1.0;
    }
    let rows = u32(material_data[z + 2u]);
    let at = z + 3u + 243u;
    let lu = lambda_nm * 1e-3;
    var nk = vec2<f32>(material_data[at + 1u], material_data[at + 2u]);
    if (lu > material_data[at]) {
        let last = at + 3u * (rows - 1u);
        nk = vec2<f32>(material_data[last + 1u], material_data[last + 2u]);
        for (var r = 1u; r < rows; r++) {
            let b = at + 3u * r;
            if (lu <= material_data[b]) {
                let a = b - 3u;
                let s = (lu - material_data[a]) / (material_data[b] - material_data[a]);
                nk = vec2<f32>(
                    material_data[a + 1u] + s * (material_data[b + 1u] - material_data[a + 1u]),
                    material_data[a + 2u] + s * (material_data[b + 2u] - material_data[a + 2u]),
                );
                break;
            }
        }
    }
    return fresnel_conductor1(cos_h, nk.x, nk.y);
}

fn wave_f(m: Material, wo: vec3<f32>, wi: vec3<f32>) -> vec3<f32> {
    if (wo.z <= 0.0 || wi.z <= 0.0 || !(m.e.z > 0.0)) {
        return vec3<f32>(0.0);
    }
    let comb = wave_comb(m);
    let n = u32(comb.z);
    let cos_h = abs(dot(wi, try_normalize(wi + wo)));
    var rgb = vec3<f32>(0.0);
    for (var t = 0u; t < n; t++) {
        let k = comb.x + f32(t) * comb.y;
        let lambda_nm = 1000.0 / k;
        let jac = lambda_nm * lambda_nm / 1000.0 * comb.y;
        let v = wave_spectrum(m, wi, wo, comb.x, k) * wave_fresnel(m, lambda_nm, cos_h);
        rgb += v * jac * wave_srgb(m, lambda_nm);
    }
    return max(rgb, vec3<f32>(0.0));
}

// Squared window weight exp(-d^2 / sigma^2) of offset k from the first
// cell, o the centre relative to it (texels).
fn wave_w2(k: i32, o: f32, l: f32, sigma: f32) -> f32 {
    let d = (f32(k) + 0.5 - o) * l;
    return exp(-d * d / (sigma * sigma));
}

// An offset in 0..=count-1 drawn in proportion to the squared weights.
fn wave_pick(count: i32, o: f32, l: f32, sigma: f32, u: f32) -> i32 {
    var total = 0.0;
    for (var k = 0; k < count; k++) {
        total += wave_w2(k, o, l, sigma);
    }
    var t = u * total;
    var picked = count - 1;
    for (var k = 0; k < count; k++) {
        let x = wave_w2(k, o, l, sigma);
        if (t < x) {
            picked = k;
            break;
        }
        t -= x;
    }
    return picked;
}

// Per-axis standard deviations in u (1/um) of the proposal lobes: one
// kernel's, and the coherence window's.
fn wave_lobe_sigmas(m: Material) -> vec2<f32> {
    let k = 1.0 / (2.0 * sqrt(2.0) * PI);
    return vec2<f32>(k / (0.5 * m.a.x), k / m.e.z);
}

// The direction `Wave::sample` draws (`xyz`), with `w` 1 when there is
// one (0: none). Its `f` and `pdf` are evaluated by the caller
// (`material_sample`), pdf first: `wave_pdf` after `wave_f` in one
// function met Mesa 22's loop miscompile (docs/gpu.md), and one call
// site each keeps the kernel's compile time down.
fn wave_sample_dir(m: Material, wo: vec3<f32>, uc: f32, u: vec2<f32>) -> vec4<f32> {
    if (wo.z <= 0.0 || !(m.e.z > 0.0)) {
        return vec4<f32>(0.0);
    }
    let k0 = wave_comb(m).x;
    let win = wave_window(m);
    let l = m.a.x;
    // uc picks the row, its remainder the column (Wave::sample).
    let jy = wave_pick(win.j1 - win.j0 + 1, win.o.y, l, m.e.z, uc);
    let ix = wave_pick(win.i1 - win.i0 + 1, win.o.x, l, m.e.z, fract(uc * 4096.0));
    let r = wrap_index(win.j0 + jy, i32(m.c.y));
    let c = wrap_index(win.i0 + ix, i32(m.c.x));
    let at = m.idx.x + 3u * u32(r * i32(m.c.x) + c);
    let g = vec2<f32>(material_data[at + 1u], material_data[at + 2u]);
    let c3 = select(2.0 * wo.z, 2.0, (m.tag.w & 1u) != 0u);
    let sig = wave_lobe_sigmas(m);
    var s = sig.y;
    var ur = (u.x - WAVE_WIDE_LOBE) / (1.0 - WAVE_WIDE_LOBE);
    if (u.x < WAVE_WIDE_LOBE) {
        s = sig.x;
        ur = u.x / WAVE_WIDE_LOBE;
    }
    let rad = sqrt(-2.0 * log(1.0 - ur)) * s;
    let a = 2.0 * PI * u.y;
    let uv = -c3 * k0 * g + rad * vec2<f32>(cos(a), sin(a));
    let xy = uv / k0 - wo.xy;
    let r2 = dot(xy, xy);
    if (!(r2 < 1.0)) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(xy, sqrt(1.0 - r2), 1.0);
}

// The solid-angle density of wave_sample_dir (GaborSurface::pdf): the lobe
// mixture summed over the window square with the kernels' weights.
fn wave_pdf(m: Material, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    if (!(wo.z > 0.0 && wi.z > 0.0 && m.e.z > 0.0)) {
        return 0.0;
    }
    let k0 = wave_comb(m).x;
    let win = wave_window(m);
    let l = m.a.x;
    let sigma = m.e.z;
    let c3 = select(2.0 * wo.z, 2.0, (m.tag.w & 1u) != 0u);
    let sig = wave_lobe_sigmas(m);
    let u = (wo.xy + wi.xy) * k0;
    let mk = c3 * k0;
    let ia = 1.0 / (2.0 * sig.x * sig.x);
    let ib = 1.0 / (2.0 * sig.y * sig.y);
    let na = WAVE_WIDE_LOBE / (2.0 * PI * sig.x * sig.x);
    let nb = (1.0 - WAVE_WIDE_LOBE) / (2.0 * PI * sig.y * sig.y);
    let w = i32(m.c.x);
    let hgt = i32(m.c.y);
    var sx = 0.0;
    for (var i = win.i0; i <= win.i1; i++) {
        sx += wave_w2(i - win.i0, win.o.x, l, sigma);
    }
    var sy = 0.0;
    var total = 0.0;
    for (var j = win.j0; j <= win.j1; j++) {
        let wy2 = wave_w2(j - win.j0, win.o.y, l, sigma);
        sy += wy2;
        let row = m.idx.x + 3u * u32(wrap_index(j, hgt) * w);
        var acc = 0.0;
        for (var i = win.i0; i <= win.i1; i++) {
            let at = row + 3u * u32(wrap_index(i, w));
            let d = u + mk * vec2<f32>(material_data[at + 1u], material_data[at + 2u]);
            let d2 = dot(d, d);
            acc += wave_w2(i - win.i0, win.o.x, l, sigma) * (na * exp(-d2 * ia) + nb * exp(-d2 * ib));
        }
        total += acc * wy2;
    }
    return total / (sx * sy) * k0 * k0 * wi.z;
}
