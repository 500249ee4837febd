//! The material records of the GPU ([`GpuMaterials`]): the library's
//! models as tags and packed parameters, mixes flattened to their leaves,
//! the media's tables and the wave surfaces' kernels; mirrored by
//! `shaders/materials.wgsl`.

use bytemuck::{Pod, Zeroable};
use isolux_core::Rgb;
use isolux_materials::{Fresnel, Material};

/// Material tags (`Material.tag.x` in WGSL; constants `MAT_*` of the
/// generated prelude). The models on the GPU; see [`GpuMaterials::new`].
pub mod tag {
    /// Lambertian.
    pub const DIFFUSE: u32 = 0;
    /// Normalized Phong over a Lambertian base.
    pub const PHONG: u32 = 1;
    /// Bounded Blinn-Phong over a Lambertian base.
    pub const BLINN_PHONG: u32 = 2;
    /// GGX microfacet reflection.
    pub const GGX: u32 = 3;
    /// Beckmann microfacet reflection.
    pub const BECKMANN: u32 = 4;
    /// Smooth conductor mirror.
    pub const CONDUCTOR: u32 = 5;
    /// Smooth dielectric (glass).
    pub const DIELECTRIC: u32 = 6;
    /// Dielectric-coated diffuse.
    pub const PLASTIC: u32 = 7;
    /// Bounded Ward over a Lambertian base.
    pub const WARD: u32 = 8;
    /// Cook-Torrance over a Fresnel-weighted Lambertian base.
    pub const COOK_TORRANCE: u32 = 9;
    /// The seed's Gaussian highlight over a Lambertian base.
    pub const GAUSSIAN: u32 = 10;
    /// Heidrich-Seidel fibres, isotropic Phong lobe, Lambertian base.
    pub const HEIDRICH_SEIDEL: u32 = 11;
    /// A weighted mixture of other GPU materials (flattened).
    pub const MIX: u32 = 12;
    /// A factored BRDF `scale p(wo) q(h) p(wi)` from its texel maps.
    pub const FACTORED: u32 = 13;
    /// The local (BRDF) approximation of a translucent medium: dipole
    /// diffuse reflectance, single scattering, a smooth Fresnel mirror.
    pub const SUBSURFACE_BRDF: u32 = 14;
    /// A MERL measured BRDF, its table in the material data.
    pub const MERL: u32 = 15;
    /// A translucent medium behind a smooth dielectric boundary (dipole
    /// BSSRDF or random walk, in the integrator).
    pub const SUBSURFACE: u32 = 16;
    /// Internal (never in a scene): the single-scattering lobe at the exit
    /// point of a `subsurface` material, which the integrator builds from
    /// it for next-event estimation (`a.w` eta, `b` albedo and g).
    pub const SSS_SINGLE_LOBE: u32 = 17;
    /// Internal: the entry side's angular factor `S_w` of the dipole
    /// BSSRDF at the entry point (`a.x` ior, `a.w` `1 - F_dr,ext`).
    pub const SSS_ENTRY_LOBE: u32 = 18;
    /// Wave-optics diffraction from a heightfield (`wave.wgsl`).
    pub const WAVE: u32 = 19;
    /// Every tag with its WGSL name, for the prelude.
    pub const ALL: [(&str, u32); 20] = [
        ("MAT_DIFFUSE", DIFFUSE),
        ("MAT_PHONG", PHONG),
        ("MAT_BLINN_PHONG", BLINN_PHONG),
        ("MAT_GGX", GGX),
        ("MAT_BECKMANN", BECKMANN),
        ("MAT_CONDUCTOR", CONDUCTOR),
        ("MAT_DIELECTRIC", DIELECTRIC),
        ("MAT_PLASTIC", PLASTIC),
        ("MAT_WARD", WARD),
        ("MAT_COOK_TORRANCE", COOK_TORRANCE),
        ("MAT_GAUSSIAN", GAUSSIAN),
        ("MAT_HEIDRICH_SEIDEL", HEIDRICH_SEIDEL),
        ("MAT_MIX", MIX),
        ("MAT_FACTORED", FACTORED),
        ("MAT_SUBSURFACE_BRDF", SUBSURFACE_BRDF),
        ("MAT_MERL", MERL),
        ("MAT_SUBSURFACE", SUBSURFACE),
        ("MAT_SSS_SINGLE_LOBE", SSS_SINGLE_LOBE),
        ("MAT_SSS_ENTRY_LOBE", SSS_ENTRY_LOBE),
        ("MAT_WAVE", WAVE),
    ];
}

/// Microfacet distributions of `cook_torrance` and `gaussian`
/// (`Material.tag.w & 3`; prelude constants `DIST_*`); bit 2 of `tag.w`
/// selects Smith masking over the V-groove term.
pub mod distribution {
    /// GGX.
    pub const GGX: u32 = 0;
    /// Beckmann.
    pub const BECKMANN: u32 = 1;
    /// The seed's Gaussian, tabulated (table in the material data).
    pub const GAUSSIAN: u32 = 2;
    /// The Smith masking bit.
    pub const SMITH: u32 = 4;
    /// Every constant with its WGSL name.
    pub const ALL: [(&str, u32); 4] = [
        ("DIST_GGX", GGX),
        ("DIST_BECKMANN", BECKMANN),
        ("DIST_GAUSSIAN", GAUSSIAN),
        ("DIST_SMITH", SMITH),
    ];
}

/// Fresnel kinds (`Material.tag.y`; prelude constants `FRESNEL_*`),
/// mirroring [`isolux_materials::Fresnel`].
pub mod fresnel_kind {
    /// `F = 1`.
    pub const ONE: u32 = 0;
    /// Dielectric of index `b.x`.
    pub const DIELECTRIC: u32 = 1;
    /// Conductor `eta = b.rgb`, `k = c.rgb`.
    pub const CONDUCTOR: u32 = 2;
    /// Schlick with `f0 = b.rgb`.
    pub const SCHLICK: u32 = 3;
    /// Every kind with its WGSL name.
    pub const ALL: [(&str, u32); 4] = [
        ("FRESNEL_ONE", ONE),
        ("FRESNEL_DIELECTRIC", DIELECTRIC),
        ("FRESNEL_CONDUCTOR", CONDUCTOR),
        ("FRESNEL_SCHLICK", SCHLICK),
    ];
}

/// A material of the GPU library. WGSL: `struct Material { tag:
/// vec4<u32>, a: vec4<f32>, b: vec4<f32>, c: vec4<f32>, d: vec4<f32>, e:
/// vec4<f32>, idx: vec4<u32> }`; the meaning of the blocks per tag is in
/// [`GpuMaterials::new`] and `materials.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMaterial {
    /// `[model tag, Fresnel kind, has tangent, model flag]`.
    pub tag: [u32; 4],
    /// First parameter block.
    pub a: [f32; 4],
    /// Second parameter block.
    pub b: [f32; 4],
    /// Third parameter block.
    pub c: [f32; 4],
    /// Tangent hint (`xyz`), or parameters for models without a tangent.
    pub d: [f32; 4],
    /// Fifth parameter block.
    pub e: [f32; 4],
    /// `[material data offset, first mix component, mix components, the
    /// mix's wave component + 1 (0: none)]`.
    pub idx: [u32; 4],
}

fn rgb4(c: Rgb, w: f64) -> [f32; 4] {
    [c.r as f32, c.g as f32, c.b as f32, w as f32]
}

/// Sets the Fresnel kind and blocks `b`, `c` of `m`.
fn put_fresnel(m: &mut GpuMaterial, f: &Fresnel) {
    match *f {
        Fresnel::One => m.tag[1] = fresnel_kind::ONE,
        Fresnel::Dielectric { ior } => {
            m.tag[1] = fresnel_kind::DIELECTRIC;
            m.b = [ior as f32, 0.0, 0.0, 0.0];
        }
        Fresnel::Conductor { eta, k } => {
            m.tag[1] = fresnel_kind::CONDUCTOR;
            m.b = rgb4(eta, 0.0);
            m.c = rgb4(k, 0.0);
        }
        Fresnel::Schlick { f0 } => {
            m.tag[1] = fresnel_kind::SCHLICK;
            m.b = rgb4(f0, 0.0);
        }
    }
}

/// The probability with which a diffuse + lobe model samples its lobe
/// (`DiffuseLobe::p_lobe`, computed here in f64 once).
fn p_lobe(reflectance: Rgb, specular: Rgb) -> f64 {
    let d = reflectance.luminance().max(0.0);
    let s = specular.luminance().max(0.0);
    if d + s > 0.0 {
        s / (d + s)
    } else {
        0.5
    }
}

/// Whether `m` has a GPU implementation: a `mix` when all its components
/// have (with any number of `wave` leaves, of which the kernels evaluate
/// one per hit, chosen at random: docs/gpu.md, "Inside a `mix`").
pub fn supported(m: &Material) -> bool {
    match m {
        // A medium inside a mix is its boundary alone ([`flatten_mix`]).
        Material::Mix(_) => {
            let c = flatten_mix(m, 1.0, 1.0);
            c.iter().all(|(m, ..)| is_void(m) || supported(m))
        }
        // Without copying its kernels.
        Material::Wave(_) => true,
        _ => GpuMaterials::default().leaf(m).is_some(),
    }
}

/// The leaf [`flatten_mix`] puts in the place of a mix whose weights are
/// all zero: an empty mix (which scene files cannot write).
fn void_leaf() -> Material {
    Material::Mix(isolux_materials::Mix { components: vec![] })
}

fn is_void(m: &Material) -> bool {
    matches!(m, Material::Mix(x) if x.components.is_empty())
}

/// The leaves of a (nested) mix with their weight in `f` and their
/// selection probability: `f = sum w_i f_i`, component `i` sampled with
/// probability `p_i`, exactly as the CPU's nested choice. A `subsurface`
/// leaf becomes its boundary (a smooth `dielectric`): the CPU's integrator
/// enters a medium only through a material that is one, and evaluates a
/// medium inside a mix as its boundary's BSDF (`Subsurface`'s
/// `BxdfModel`), so a path refracted through it carries on as through
/// glass, on both back ends.
///
/// A mix whose weights are all zero is black and draws no sample on the
/// CPU (`Mix::sample`): in its place comes a *void* leaf (an empty mix, see
/// [`GpuMaterials::mix`]) of weight 0 and of the mix's selection
/// probability, which draws nothing, then its own leaves with weight and
/// probability 0, which keep their place in the order that gives the
/// shading frame its tangent (the first leaf's that has one, on the CPU
/// too).
fn flatten_mix(m: &Material, w: f64, p: f64) -> Vec<(Material, f64, f64)> {
    let Material::Mix(mix) = m else {
        let leaf = match m {
            Material::Subsurface(s) => Material::Dielectric(s.boundary),
            _ => m.clone(),
        };
        return vec![(leaf, w, p)];
    };
    let total: f64 = mix.components.iter().map(|c| c.1).sum();
    if !(total > 0.0) {
        let mut out = vec![(void_leaf(), 0.0, p)];
        for (c, _) in &mix.components {
            out.extend(flatten_mix(c, 0.0, 0.0));
        }
        return out;
    }
    let mut out = Vec::new();
    for (c, cw) in &mix.components {
        out.extend(flatten_mix(c, w * cw, p * cw / total));
    }
    out
}

/// The materials of a scene on the GPU: one [`GpuMaterial`] per scene
/// material at the same index, then the components of mixtures, and the
/// material data (sampling tables) they point into.
#[derive(Clone, Debug, Default)]
pub struct GpuMaterials {
    /// Materials; the first ones mirror the scene's, index for index.
    pub materials: Vec<GpuMaterial>,
    /// Tables (`f32`), addressed by `GpuMaterial::idx[0]`.
    pub data: Vec<f32>,
    /// Kernel and leaf-box offsets of the wave surfaces already copied,
    /// by address: materials sharing a heightfield share its copy.
    surfaces: Vec<(usize, u32, u32)>,
}

impl GpuMaterials {
    /// The GPU mirror of `materials`, or the index of the first one not on
    /// the GPU (see [`supported`]).
    ///
    /// | tag | a | b | c | d | e |
    /// |---|---|---|---|---|---|
    /// | diffuse | reflectance | | | | |
    /// | phong, blinn_phong | reflectance | specular | exponent, p(lobe) | | |
    /// | ward | reflectance | specular | alpha_x, p(lobe), alpha_y | tangent | |
    /// | ggx, beckmann | alpha_x, alpha_y | Fresnel | Fresnel | tangent | |
    /// | cook_torrance | reflectance, p(specular) | Fresnel | Fresnel | alpha_x, alpha_y, m, norm | |
    /// | gaussian | reflectance, p(specular) | specular | | alpha, alpha, m, norm | |
    /// | heidrich_seidel | reflectance, exponent | specular, norm | isotropic | tangent | p(diffuse), p(fibre), p(isotropic), sigma |
    /// | conductor | | Fresnel | Fresnel | | |
    /// | dielectric | ior | | | | |
    /// | plastic | reflectance | ior, coat alpha, F_dr(internal) | | | |
    /// | mix | | | | the frame's tangent (fixed, or the `wave`'s, placed) | the `wave` component's `e` (placed) |
    /// | factored | scale | | | | |
    /// | subsurface_brdf | R_d, eta | single-scattering albedo, g | | | |
    /// | merl | | | | | |
    /// | subsurface | ior, g, r_max, `1 - F_dr,ext` | sigma_s, single scattering (0/1) | sigma_a | | |
    /// | wave | texel_um, coherence_um, um_per_unit, wavelengths | mapping centre, mapping code | columns, rows, leaf columns, leaf rows | tangent (placed) | centre x, y (um), sigma (um), comb offset (placed) |
    ///
    /// `cook_torrance` and `gaussian` keep the distribution in `tag.w`
    /// ([`distribution`]); the Gaussian's sampling table is `[n, cdf (n +
    /// 1), pdf per bin (n)]` at `idx[0]` of `data`. A mix's components are
    /// `idx[2]` materials from `idx[1]`, their weights `(w_k, p_k)` in
    /// `f` and in the choice of a sample at `idx[0]` of `data`; `tag[3] -
    /// 1` is its `wave` component (0: none), placed once per hit into the
    /// mix's `e`; `idx[3]` is 1 when the frame's tangent is the placed
    /// `wave`'s (else a fixed tangent, if any, is in `d`, with `tag[2]`
    /// 1). A `factored` material's data at
    /// `idx[0]`: `res`, then `ln p` and `ln q` per texel (3 floats each,
    /// row-major, stand-ins substituted), then the half-vector density's
    /// marginal table and its `res` conditional tables (each `[n, cdf,
    /// pdf]`, `2 res + 2` floats); at `idx[1]`: `n`, the side of the `r(theta_h,
    /// theta_d)` table (0: none), then `ln r` per texel (3 floats each,
    /// row-major, rows `theta_h`). A `subsurface` material keeps its mode
    /// in `tag.w` (0 dipole, 1 random walk; in random-walk mode `tag.y - 1` is
    /// the offset of its table of the materials seen from inside it,
    /// `GpuMaterials::relative_in_media`), its per-channel dipoles at
    /// `idx[0]` (`sigma_tr, z_r, z_v, alpha'` for r, g, b, then the
    /// scale of the single-scattering term per channel,
    /// `Subsurface::single_scattering_scale`, then the real-time mode's local
    /// BRDF, `Subsurface::local_brdf`: `R_d` and the single-scattering
    /// albedo per channel) and the radial
    /// sampling tables of the channels at `idx[1..4]` (each `[n, cdf,
    /// pdf]`), all in scene units. A `wave` material keeps `model |
    /// obliquity << 1` in `tag.w` and its Fresnel kind in `tag.y` (ONE,
    /// DIELECTRIC or CONDUCTOR: a measured metal); its kernels `[h, gx,
    /// gy]` per texel (row-major) at `idx[0]`, the leaf slope boxes at
    /// `idx[1]` (4 floats each), at `idx[2]` `[eps, ior, metal rows, the
    /// 81 normalized sRGB nodes of the CIE table (3 floats each), the metal's
    /// rows (lambda um, n, k)]`, and `idx[3]` 1 when culling by the leaves.
    /// The mapping code is the planar axis (0, 1, 2), 3 spherical or 4
    /// cylindrical; `d` and `e` are filled per shading point by
    /// `place_material` (`wave.wgsl`), as `Wave::at_point` does on the CPU.
    pub fn new(materials: &[Material]) -> Result<Self, usize> {
        let mut out = GpuMaterials {
            materials: vec![GpuMaterial::default(); materials.len()],
            ..Default::default()
        };
        for (i, m) in materials.iter().enumerate() {
            if !supported(m) {
                return Err(i);
            }
            out.materials[i] = match m {
                Material::Mix(_) => out.mix(m).ok_or(i)?,
                _ => out.leaf(m).ok_or(i)?,
            };
        }
        out.relative_in_media(materials)?;
        Ok(out)
    }

    /// The materials seen from inside each random-walk medium of
    /// `materials` (a surface under water meets water): for each, a table
    /// in `data` of one material index per scene material, that
    /// material's record with its indices relative to the medium's
    /// (`Material::relative_to`, a record of its own after the others) or
    /// the material itself where nothing changes. The medium's `tag[1]`
    /// holds the table's offset + 1 (0: no table); the path tracer's
    /// `bounce` looks up every hit of a path inside the medium through it.
    fn relative_in_media(&mut self, materials: &[Material]) -> Result<(), usize> {
        use isolux_materials::subsurface_material::SubsurfaceMode;
        for (j, m) in materials.iter().enumerate() {
            let Material::Subsurface(s) = m else {
                continue;
            };
            if s.mode != SubsurfaceMode::RandomWalk {
                continue;
            }
            let mut table = Vec::with_capacity(materials.len());
            for (i, x) in materials.iter().enumerate() {
                let k = match x.relative_to(s.boundary.ior) {
                    Some(r) => {
                        let g = match r {
                            Material::Mix(_) => self.mix(&r),
                            _ => self.leaf(&r),
                        };
                        self.materials.push(g.ok_or(i)?);
                        self.materials.len() - 1
                    }
                    None => i,
                };
                table.push(k as f32);
            }
            self.materials[j].tag[1] = self.data.len() as u32 + 1;
            self.data.extend(table);
        }
        Ok(())
    }

    /// A mix: its flattened leaves as records of their own after the
    /// scene's, their weights `(w_k, p_k)` in `data` (any number of
    /// leaves), its first `wave` leaf + 1 in `tag[3]` (0: none), the sums
    /// of its `wave` leaves' weights and probabilities and their count in
    /// `a` (`[W, P, count, 0]`), and the frame's tangent: the first leaf's
    /// that has one, as on the CPU, written here, or placed per hit when
    /// that leaf is the first `wave` (`idx[3]` 1; `place_material`).
    ///
    /// With several `wave` leaves the kernels evaluate one per hit:
    /// `place_material` chooses leaf `j` with probability `w_j / W` and
    /// gives it the weight `W` and probability `P` of them all (the
    /// others count zero), so that `f` is `sum_k w_k f_k` in expectation
    /// (docs/gpu.md, "Inside a `mix`").
    fn mix(&mut self, m: &Material) -> Option<GpuMaterial> {
        let parts = flatten_mix(m, 1.0, 1.0);
        let mut g = GpuMaterial::default();
        g.tag[0] = tag::MIX;
        // The weights first: a leaf may append tables of its own.
        let weights = self.data.len() as u32;
        for (_, cw, cp) in &parts {
            self.data.extend([*cw as f32, *cp as f32]);
        }
        let first = self.materials.len();
        for (c, ..) in &parts {
            // A void leaf (a mix of zero weights, [`flatten_mix`]): a
            // record of the mix tag, which no case of the kernels' switches
            // over the leaves' models takes, so its f, pdf and flags are 0
            // and it draws no sample.
            let leaf = if is_void(c) {
                GpuMaterial {
                    tag: [tag::MIX, 0, 0, 0],
                    ..Default::default()
                }
            } else {
                self.leaf(c)?
            };
            self.materials.push(leaf);
        }
        let is_wave = |c: &Material| matches!(c, Material::Wave(_));
        if let Some(k) = parts.iter().position(|(c, ..)| is_wave(c)) {
            g.tag[3] = k as u32 + 1;
        }
        let waves = parts.iter().filter(|(c, ..)| is_wave(c));
        let (w, p, n) = waves.fold((0.0, 0.0, 0), |(w, p, n), (_, cw, cp)| {
            (w + cw, p + cp, n + 1)
        });
        g.a = [w as f32, p as f32, n as f32, 0.0];
        let mut tangent_is_wave = 0;
        match parts.iter().find_map(|(c, ..)| Some((c, c.tangent()?))) {
            Some((c, _)) if is_wave(c) => tangent_is_wave = 1,
            Some((_, t)) => {
                g.tag[2] = 1;
                g.d = [t.x as f32, t.y as f32, t.z as f32, 0.0];
            }
            None => {}
        }
        g.idx = [weights, first as u32, parts.len() as u32, tangent_is_wave];
        Some(g)
    }

    /// Appends a sampling table; returns its offset.
    fn table(&mut self, t: &isolux_core::Distribution1D) -> u32 {
        let at = self.data.len() as u32;
        let n = t.len();
        self.data.push(n as f32);
        self.data.extend(t.cdf().iter().map(|&c| c as f32));
        self.data.extend((0..n).map(|i| t.pdf_bin(i) as f32));
        at
    }

    fn leaf(&mut self, m: &Material) -> Option<GpuMaterial> {
        use isolux_materials::cook_torrance::{Masking, NormalDistribution};
        let mut g = GpuMaterial::default();
        let tangent = |g: &mut GpuMaterial, t: Option<glam::DVec3>| {
            if let Some(t) = t {
                g.tag[2] = 1;
                g.d = [t.x as f32, t.y as f32, t.z as f32, 0.0];
            }
        };
        match m {
            Material::Diffuse(d) => {
                g.tag[0] = tag::DIFFUSE;
                g.a = rgb4(d.reflectance, 0.0);
            }
            Material::Phong(p) => {
                g.tag[0] = tag::PHONG;
                g.a = rgb4(p.0.reflectance, 0.0);
                g.b = rgb4(p.0.specular, 0.0);
                let pl = p_lobe(p.0.reflectance, p.0.specular);
                g.c = [p.0.lobe.exponent as f32, pl as f32, 0.0, 0.0];
            }
            Material::BlinnPhong(p) => {
                g.tag[0] = tag::BLINN_PHONG;
                g.a = rgb4(p.0.reflectance, 0.0);
                g.b = rgb4(p.0.specular, 0.0);
                let pl = p_lobe(p.0.reflectance, p.0.specular);
                g.c = [p.0.lobe.exponent as f32, pl as f32, 0.0, 0.0];
            }
            Material::Ward(w) => {
                g.tag[0] = tag::WARD;
                let i = &w.inner;
                g.a = rgb4(i.reflectance, 0.0);
                g.b = rgb4(i.specular, 0.0);
                let pl = p_lobe(i.reflectance, i.specular);
                g.c = [i.lobe.alpha_x as f32, pl as f32, i.lobe.alpha_y as f32, 0.0];
                tangent(&mut g, w.tangent);
            }
            Material::Ggx(x) => {
                g.tag[0] = tag::GGX;
                let d = &x.lobe.distribution;
                g.a = [d.alpha_x as f32, d.alpha_y as f32, 0.0, 0.0];
                put_fresnel(&mut g, &x.lobe.fresnel);
                tangent(&mut g, x.tangent);
            }
            Material::Beckmann(x) => {
                g.tag[0] = tag::BECKMANN;
                let d = &x.lobe.distribution;
                g.a = [d.alpha_x as f32, d.alpha_y as f32, 0.0, 0.0];
                put_fresnel(&mut g, &x.lobe.fresnel);
                tangent(&mut g, x.tangent);
            }
            Material::CookTorrance(_) | Material::Gaussian(_) => {
                let (ct, specular) = match m {
                    Material::CookTorrance(ct) => (ct, None),
                    Material::Gaussian(ga) => (&ga.inner, Some(ga.specular)),
                    _ => unreachable!(),
                };
                put_fresnel(&mut g, &ct.fresnel);
                g.a = rgb4(ct.reflectance, ct.p_specular());
                let mut flag = match (&ct.distribution, ct.masking) {
                    (_, Masking::Smith) => distribution::SMITH,
                    _ => 0,
                };
                match &ct.distribution {
                    NormalDistribution::Analytic(d) => {
                        flag |= match d.kind {
                            isolux_materials::microfacet::Kind::Ggx => distribution::GGX,
                            isolux_materials::microfacet::Kind::Beckmann => distribution::BECKMANN,
                        };
                        g.d = [d.alpha_x as f32, d.alpha_y as f32, 0.0, 0.0];
                    }
                    NormalDistribution::Gaussian(gd) => {
                        // Smith is defined for Beckmann and GGX only: the
                        // CPU falls back to the V-groove term.
                        flag = distribution::GAUSSIAN;
                        g.d = [1.0, 1.0, gd.m as f32, gd.normalization() as f32];
                        g.idx[0] = self.table(gd.table());
                    }
                }
                g.tag[3] = flag;
                match specular {
                    None => g.tag[0] = tag::COOK_TORRANCE,
                    Some(s) => {
                        g.tag[0] = tag::GAUSSIAN;
                        g.b = rgb4(s, 0.0);
                    }
                }
            }
            Material::HeidrichSeidel(h) => {
                g.tag[0] = tag::HEIDRICH_SEIDEL;
                g.a = rgb4(h.reflectance, h.exponent);
                g.b = rgb4(h.specular, h.normalization());
                g.c = rgb4(h.isotropic, 0.0);
                let [pd, ps, pi] = h.weights();
                g.e = [pd as f32, ps as f32, pi as f32, h.sigma() as f32];
                tangent(&mut g, h.tangent);
            }
            Material::Factored(f) => {
                g.tag[0] = tag::FACTORED;
                g.a = rgb4(f.scale(), 0.0);
                g.idx[0] = self.data.len() as u32;
                self.data.push(f.res() as f32);
                for map in [f.log_p_texels(), f.log_q_texels()] {
                    self.data
                        .extend(map.iter().flat_map(|t| t.map(|v| v as f32)));
                }
                let h = f.h_distribution();
                self.table(h.marginal());
                for c in h.conditionals() {
                    self.table(c);
                }
                // The r(theta_h, theta_d) table: n, then ln r per texel.
                g.idx[1] = self.data.len() as u32;
                self.data.push(f.r_res() as f32);
                self.data
                    .extend(f.log_r_texels().iter().flat_map(|t| t.map(|v| v as f32)));
            }
            Material::Conductor(c) => {
                g.tag[0] = tag::CONDUCTOR;
                put_fresnel(&mut g, &c.fresnel);
            }
            Material::Dielectric(d) => {
                g.tag[0] = tag::DIELECTRIC;
                g.a = [d.ior as f32, 0.0, 0.0, 0.0];
            }
            Material::Plastic(p) => {
                g.tag[0] = tag::PLASTIC;
                g.a = rgb4(p.reflectance, 0.0);
                let alpha = p.coat.map_or(0.0, |c| c.distribution.alpha_x);
                g.b = [p.ior as f32, alpha as f32, p.f_dr_internal() as f32, 0.0];
                g.tag[3] = p.coat.is_some() as u32;
            }
            Material::Merl(t) => {
                g.tag[0] = tag::MERL;
                g.idx[0] = self.data.len() as u32;
                self.data.extend_from_slice(t.table());
            }
            Material::SubsurfaceBrdf(b) => {
                g.tag[0] = tag::SUBSURFACE_BRDF;
                g.a = rgb4(b.r_d, b.eta);
                g.b = rgb4(b.single_albedo, b.g);
            }
            Material::Subsurface(m) => {
                use isolux_materials::subsurface_material::SubsurfaceMode;
                g.tag[0] = tag::SUBSURFACE;
                g.tag[3] = (m.mode == SubsurfaceMode::RandomWalk) as u32;
                g.a = [
                    m.boundary.ior as f32,
                    m.g as f32,
                    m.r_max() as f32,
                    m.sw_norm as f32,
                ];
                g.b = rgb4(m.sigma_s, m.single_scattering as u32 as f64);
                g.c = rgb4(m.sigma_a, 0.0);
                g.idx[0] = self.data.len() as u32;
                for d in &m.dipoles {
                    self.data
                        .extend([d.sigma_tr, d.z_r, d.z_v, d.albedo_reduced].map(|v| v as f32));
                }
                self.data
                    .extend(m.single_scattering_scale().to_array().map(|v| v as f32));
                let local = m.local_brdf();
                self.data.extend(local.r_d.to_array().map(|v| v as f32));
                self.data
                    .extend(local.single_albedo.to_array().map(|v| v as f32));
                for c in 0..3 {
                    g.idx[1 + c] = self.table(m.radial_table(c));
                }
            }
            Material::Wave(w) => self.wave(w, &mut g),
            _ => return None,
        }
        Some(g)
    }

    fn wave(&mut self, w: &isolux_materials::Wave, g: &mut GpuMaterial) {
        use isolux_materials::wave::{Mapping, WaveFresnel};
        let s = &w.surface;
        g.tag[0] = tag::WAVE;
        g.tag[3] = (w.model == isolux_wave::Model::Ohs) as u32
            | ((w.settings.obliquity == isolux_wave::Obliquity::Seed) as u32) << 1;
        g.a = [
            s.texel_um as f32,
            w.coherence_um as f32,
            w.um_per_unit as f32,
            w.wavelengths as f32,
        ];
        g.b = match w.mapping {
            Mapping::Planar(a) => [0.0, 0.0, 0.0, a as f32],
            Mapping::Spherical(c) => [c.x as f32, c.y as f32, c.z as f32, 3.0],
            Mapping::Cylindrical(c) => [c.x as f32, c.y as f32, c.z as f32, 4.0],
        };
        let (nx, ny, boxes) = s.leaf_boxes();
        g.c = [s.width as f32, s.height as f32, nx as f32, ny as f32];
        let key = std::sync::Arc::as_ptr(s) as usize;
        let (kernels, leaves) = match self.surfaces.iter().find(|e| e.0 == key) {
            Some(&(_, k, l)) => (k, l),
            None => {
                let (h, gx, gy) = s.kernels();
                let k = self.data.len() as u32;
                self.data.reserve(3 * h.len() + 4 * boxes.len());
                for i in 0..h.len() {
                    self.data.extend([h[i], gx[i], gy[i]]);
                }
                let l = self.data.len() as u32;
                self.data.extend(boxes.iter().flatten());
                self.surfaces.push((key, k, l));
                (k, l)
            }
        };
        let header = self.data.len() as u32;
        let (ior, rows): (f64, &[(f64, f64, f64)]) = match w.fresnel {
            WaveFresnel::None => {
                g.tag[1] = fresnel_kind::ONE;
                (1.0, &[])
            }
            WaveFresnel::Dielectric(eta) => {
                g.tag[1] = fresnel_kind::DIELECTRIC;
                (eta, &[])
            }
            WaveFresnel::Metal(m) => {
                g.tag[1] = fresnel_kind::CONDUCTOR;
                (1.0, m.table())
            }
        };
        self.data
            .extend([w.settings.eps as f32, ior as f32, rows.len() as f32]);
        for c in isolux_wave::spectral::normalized_srgb_nodes() {
            self.data.extend(c.map(|v| v as f32));
        }
        for r in rows {
            self.data.extend([r.0 as f32, r.1 as f32, r.2 as f32]);
        }
        g.idx = [kernels, leaves, header, w.settings.hierarchy as u32];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use isolux_materials::{Diffuse, Mix};

    fn grey(r: f64) -> Material {
        Material::Diffuse(Diffuse {
            reflectance: Rgb::splat(r),
        })
    }

    fn mix(parts: Vec<(Material, f64)>) -> Material {
        Material::Mix(Mix { components: parts })
    }

    #[test]
    fn nested_mixes_flatten_to_the_cpus_weights_and_choice() {
        // (a 2, (b 1, c 3) 2): f weights 2, 2 * 1, 2 * 3; selection
        // probabilities 2/4, 2/4 * 1/4, 2/4 * 3/4.
        let m = mix(vec![
            (grey(0.1), 2.0),
            (mix(vec![(grey(0.2), 1.0), (grey(0.3), 3.0)]), 2.0),
        ]);
        let g = GpuMaterials::new(&[grey(0.9), m]).unwrap();
        assert_eq!(g.materials.len(), 5);
        let top = g.materials[1];
        assert_eq!(top.tag[0], tag::MIX);
        assert_eq!(top.idx[1..3], [2, 3]);
        let at = top.idx[0] as usize;
        assert_eq!(
            g.data[at..at + 6],
            [2.0, 0.5, 2.0, 0.125, 6.0, 0.375],
            "(w, p) per leaf"
        );
        let leaf_r: Vec<f32> = g.materials[2..].iter().map(|m| m.a[0]).collect();
        assert_eq!(leaf_r, [0.1, 0.2, 0.3]);
    }

    #[test]
    fn mixes_of_any_size_and_of_zero_weights_are_supported() {
        // Two mixes of 40 leaves: each one's weights at its own offset.
        let big = |r: f64| mix((0..40).map(|i| (grey(r), 1.0 + i as f64)).collect());
        let g = GpuMaterials::new(&[big(0.1), grey(0.5), big(0.2)]).unwrap();
        assert_eq!(g.materials.len(), 83);
        for (m, first) in [(g.materials[0], 3), (g.materials[2], 43)] {
            assert_eq!(m.idx[1..3], [first, 40]);
            let w = &g.data[m.idx[0] as usize..][..80];
            assert_eq!((w[78], w[79]), (40.0, 40.0 / 820.0));
        }
        // Zero weights: black, and no sample beyond the other leaves'
        // probabilities.
        let zero = mix(vec![(grey(0.5), 0.0), (grey(0.7), 0.0)]);
        let inside = mix(vec![(grey(0.5), 0.25), (zero.clone(), 0.75)]);
        let g = GpuMaterials::new(&[zero, inside]).unwrap();
        let (z, i) = (g.materials[0], g.materials[1]);
        // A void leaf each in the zero mix's place, then its leaves with
        // weight and probability 0.
        assert_eq!((z.idx[1], z.idx[2], i.idx[1], i.idx[2]), (2, 3, 5, 4));
        assert_eq!(
            g.data[z.idx[0] as usize..][..6],
            [0.0, 1.0, 0.0, 0.0, 0.0, 0.0]
        );
        assert_eq!(
            g.data[i.idx[0] as usize..][..8],
            [0.25, 0.25, 0.0, 0.75, 0.0, 0.0, 0.0, 0.0]
        );
        let void = GpuMaterial {
            tag: [tag::MIX, 0, 0, 0],
            ..Default::default()
        };
        assert_eq!((g.materials[2], g.materials[6]), (void, void));
        let kinds: Vec<u32> = g.materials[2..].iter().map(|m| m.tag[0]).collect();
        let (d, x) = (tag::DIFFUSE, tag::MIX);
        assert_eq!(kinds, [x, d, d, d, x, d, d]);
        // Its leaves' tangents still count, as on the CPU: a ward inside a
        // zero mix gives the frame its tangent.
        let mut ward = isolux_materials::Ward::new(0.1, 0.3, Rgb::splat(0.2), Rgb::splat(0.3));
        ward.tangent = Some(glam::DVec3::Y);
        let hidden = mix(vec![
            (mix(vec![(Material::Ward(ward), 0.0)]), 0.5),
            (grey(0.5), 0.5),
        ]);
        assert!(hidden.tangent().is_some());
        let g = GpuMaterials::new(&[hidden]).unwrap();
        assert_eq!(
            (g.materials[0].tag[2], g.materials[0].d),
            (1, [0.0, 1.0, 0.0, 0.0])
        );
        // A medium alone runs on the GPU; inside a mix, its boundary.
        let milk = Material::Subsurface(isolux_materials::Subsurface::new(
            Rgb::new(2.0, 2.5, 3.0),
            Rgb::new(0.01, 0.02, 0.05),
            0.5,
            1.3,
            isolux_materials::subsurface_material::SubsurfaceMode::Dipole,
        ));
        assert!(supported(&milk));
        let half = mix(vec![(milk.clone(), 1.0), (grey(0.5), 1.0)]);
        assert!(supported(&half));
        let g = GpuMaterials::new(&[half]).unwrap();
        assert_eq!(g.materials[1].tag[0], tag::DIELECTRIC);
        assert_eq!(g.materials[1].a[0], 1.3);
        let Material::Subsurface(medium) = &milk else {
            unreachable!()
        };
        let scale = medium.single_scattering_scale();
        let local = medium.local_brdf();
        let g = GpuMaterials::new(&[milk]).unwrap();
        let m = g.materials[0];
        assert_eq!((m.tag[0], m.tag[3]), (tag::SUBSURFACE, 0));
        // Dipoles, the single-scattering scale, the local BRDF, then three tables of
        // 4096 bins ([n, cdf, pdf]).
        assert_eq!(m.idx, [0, 21, 21 + 8194, 21 + 2 * 8194]);
        assert_eq!(g.data[12..15], scale.to_array().map(|v| v as f32));
        assert_eq!(g.data[15..18], local.r_d.to_array().map(|v| v as f32));
        assert_eq!(
            g.data[18..21],
            local.single_albedo.to_array().map(|v| v as f32)
        );
        assert_eq!(g.data[21], 4096.0);
        assert_eq!(g.data.len(), 21 + 3 * 8194);
    }

    #[test]
    fn random_walk_media_list_the_materials_seen_from_inside() {
        use isolux_materials::subsurface_material::SubsurfaceMode;
        let medium = |mode| {
            Material::Subsurface(isolux_materials::Subsurface::new(
                Rgb::splat(0.1),
                Rgb::splat(0.01),
                0.0,
                1.25,
                mode,
            ))
        };
        let glass = Material::Dielectric(isolux_materials::Dielectric { ior: 1.5 });
        let water = medium(SubsurfaceMode::RandomWalk);
        let g = GpuMaterials::new(&[
            grey(0.5),
            water.clone(),
            glass.clone(),
            medium(SubsurfaceMode::Dipole),
        ])
        .unwrap();
        // The water (another object of it: a medium in the medium), the
        // glass and the dipole medium seen from the water: records of
        // their own, at 1.25 / 1.25, 1.5 / 1.25 and 1.25 / 1.25; the grey
        // itself.
        assert_eq!(g.materials.len(), 7);
        assert_eq!(g.materials[4].tag[0], tag::SUBSURFACE);
        assert_eq!(g.materials[4].a[0], 1.0);
        assert_eq!(g.materials[5].tag[0], tag::DIELECTRIC);
        assert_eq!(g.materials[5].a[0], 1.2);
        assert_eq!(g.materials[6].tag[0], tag::SUBSURFACE);
        assert_eq!(g.materials[6].a[0], 1.0);
        let at = g.materials[1].tag[1] as usize - 1;
        assert_eq!(g.data[at..at + 4], [0.0, 4.0, 5.0, 6.0]);
        // Only random-walk media have a table.
        assert_eq!(g.materials[3].tag[1], 0);
        // Nothing changes without such a medium.
        let g = GpuMaterials::new(&[grey(0.5), glass]).unwrap();
        assert_eq!(g.materials.len(), 2);
        assert!(g.data.is_empty());
    }

    #[test]
    fn wave_surfaces_are_copied_once_and_fit_mixes() {
        use isolux_materials::metals::Metal;
        use isolux_materials::wave::{Wave, WaveFresnel};
        let heights: Vec<f32> = (0..40 * 24).map(|i| (i % 7) as f32 * 0.01).collect();
        let field = isolux_wave::Heightfield::new(40, 24, 0.5, heights).unwrap();
        let surface = std::sync::Arc::new(isolux_wave::GaborSurface::new(field));
        let silver = Wave::new(
            surface.clone(),
            isolux_wave::Model::Ghs,
            WaveFresnel::Metal(Metal::by_name("Ag").unwrap()),
        );
        let plain = Wave::new(surface, isolux_wave::Model::Ohs, WaveFresnel::None);
        let (a, b) = (Material::Wave(silver), Material::Wave(plain));
        assert!(supported(&a));
        // Inside mixes: one `wave` component among any number of others;
        // the frame's tangent is the first component's that has one, as on
        // the CPU. Two `wave` components are refused.
        let along = Some(glam::DVec3::X);
        let ggx = |tangent: Option<glam::DVec3>| {
            let mut g = isolux_materials::Ggx::new(
                0.2,
                0.4,
                isolux_materials::Fresnel::Schlick {
                    f0: Rgb::splat(0.04),
                },
            );
            g.tangent = tangent;
            Material::Ggx(g)
        };
        let five: Vec<_> = (0..5).map(|i| (grey(0.1 * i as f64), 1.0)).collect();
        let mixes = [
            // (mix, (fixed tangent, tangent is the wave's), wave + 1)
            (
                mix(vec![(grey(0.5), 1.0), (a.clone(), 2.0), (ggx(along), 1.0)]),
                (0, 1),
                2,
            ),
            (
                mix(vec![(ggx(along), 1.0), (grey(0.5), 1.0), (a.clone(), 1.0)]),
                (1, 0),
                3,
            ),
            (mix(vec![(ggx(None), 1.0), (b.clone(), 1.0)]), (0, 1), 2),
            (
                mix([five.clone(), vec![(a.clone(), 1.0)]].concat()),
                (0, 1),
                6,
            ),
            (mix(vec![(grey(0.5), 1.0), (ggx(along), 1.0)]), (1, 0), 0),
        ];
        for (i, (m, tangent, wave)) in mixes.iter().enumerate() {
            assert!(supported(m), "mix {i}");
            let g = GpuMaterials::new(std::slice::from_ref(m)).unwrap();
            let top = g.materials[0];
            assert_eq!((top.tag[2], top.idx[3]), *tangent, "mix {i}");
            assert_eq!(top.tag[3], *wave, "mix {i}");
            if *wave > 0 {
                assert_eq!(g.materials[*wave as usize].tag[0], tag::WAVE);
            }
            if tangent.0 == 1 {
                assert_eq!(top.d, [1.0, 0.0, 0.0, 0.0]);
            }
        }
        // Two `wave` leaves (one placed per hit): their summed weight and
        // probability and their count in `a`, the first named in `tag[3]`.
        let nested = mix(vec![
            (a.clone(), 1.0),
            (mix([five, vec![(b.clone(), 1.0)]].concat()), 1.0),
        ]);
        assert!(supported(&nested));
        let g = GpuMaterials::new(std::slice::from_ref(&nested)).unwrap();
        let top = g.materials[0];
        // f weights 1 and 1 (a mix's f is its weighted sum, unnormalized),
        // probabilities 1/2 and a sixth of the inner mix's 1/2.
        assert_eq!(top.tag[3], 1);
        let (w, p) = (2.0, 0.5 + 0.5 / 6.0);
        assert!(
            (top.a[0] - w as f32).abs() < 1e-6 && (top.a[1] - p as f32).abs() < 1e-6,
            "{:?}",
            top.a
        );
        assert_eq!(top.a[2], 2.0);
        let g = GpuMaterials::new(&[a, b]).unwrap();
        let (m0, m1) = (g.materials[0], g.materials[1]);
        assert_eq!(
            (m0.tag[0], m0.tag[1], m0.tag[3]),
            (tag::WAVE, fresnel_kind::CONDUCTOR, 0)
        );
        assert_eq!((m1.tag[1], m1.tag[3]), (fresnel_kind::ONE, 1));
        // One copy of the kernels (3 floats per texel) and of the leaf
        // boxes (3 x 2 leaves of 16 texels, 4 floats each).
        assert_eq!((m0.idx[0], m0.idx[1]), (m1.idx[0], m1.idx[1]));
        assert_eq!(m0.idx[1], 3 * 40 * 24);
        assert_eq!(m0.idx[2], m0.idx[1] + 4 * 3 * 2);
        assert_eq!(m0.c, [40.0, 24.0, 3.0, 2.0]);
        // Header: eps, ior, metal rows, 81 colour nodes, then the rows.
        let h = m0.idx[2] as usize;
        let rows = g.data[h + 2] as usize;
        assert!(rows > 2);
        assert_eq!(m1.idx[2] as usize, h + 3 + 243 + 3 * rows);
        assert_eq!(g.data.len(), m1.idx[2] as usize + 3 + 243);
    }
}
