//! GPU data layouts: `#[repr(C)]` mirrors of the WGSL structs in
//! `shaders/`, the single source of truth for both sides. Every struct is
//! a whole number of `vec4`s (16-byte aligned, no implicit padding), and a
//! unit test checks each size against the WGSL declaration's.

use bytemuck::{Pod, Zeroable};
use isolux_core::Rgb;
use isolux_geometry::{Object, Quadric};
use isolux_materials::{Fresnel, Material};

/// A quadric's ten coefficients `[a11, a22, a33, a12, a13, a23, a14, a24,
/// a34, a44]` (see `isolux_geometry::quadric`), two zeros of padding.
/// WGSL: `struct Quadric { c: array<vec4<f32>, 3> }`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuQuadric {
    /// Coefficients in the order above, then `[0, 0]`.
    pub c: [f32; 12],
}

impl GpuQuadric {
    /// From a CPU quadric (rounded to f32).
    pub fn new(q: &Quadric) -> Self {
        let mut c = [0.0f32; 12];
        for (d, s) in c.iter_mut().zip(q.coefficients()) {
            *d = s as f32;
        }
        Self { c }
    }
}

/// One perturbation `factor * Q^3 [Q >= 0]`.
/// WGSL: `struct Perturbation { q: Quadric, factor: vec4<f32> }` (`factor.x`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuPerturbation {
    /// Its quadric.
    pub q: GpuQuadric,
    /// `[factor, 0, 0, 0]`.
    pub factor: [f32; 4],
}

/// An object: base quadric, bounding box, and its range of perturbations.
/// WGSL: `struct Object { base: Quadric, bmin: vec4<f32>, bmax: vec4<f32>,
/// range: vec4<u32> }` (`range.x` first perturbation, `range.y` count).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuObject {
    /// Base quadric `F`.
    pub base: GpuQuadric,
    /// Box minimum (`w` unused).
    pub bmin: [f32; 4],
    /// Box maximum (`w` unused).
    pub bmax: [f32; 4],
    /// `[first perturbation, count, material index, 0]`.
    pub range: [u32; 4],
}

/// A ray: origin with `t_min` in `w`, direction with `t_max` in `w`.
/// WGSL: `struct Ray { o: vec4<f32>, d: vec4<f32> }`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuRay {
    /// `[x, y, z, t_min]`.
    pub o: [f32; 4],
    /// `[x, y, z, t_max]`.
    pub d: [f32; 4],
}

/// A hit: `[t, nx, ny, nz]`, `t < 0` for a miss.
/// WGSL: `vec4<f32>`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuHit {
    /// `[t, nx, ny, nz]`.
    pub v: [f32; 4],
}

/// Objects and their perturbations, flattened for upload.
#[derive(Clone, Debug, Default)]
pub struct GpuScene {
    /// Objects.
    pub objects: Vec<GpuObject>,
    /// All perturbations, each object's contiguous.
    pub perturbations: Vec<GpuPerturbation>,
}

impl GpuScene {
    /// Flattens `objects` (material index 0 for all). Unbounded boxes are
    /// clamped to +-1e30.
    pub fn new(objects: &[Object]) -> Self {
        Self::with_materials(objects, &vec![0; objects.len()])
    }

    /// Flattens `objects`, object `i` wearing material `material[i]`.
    pub fn with_materials(objects: &[Object], material: &[usize]) -> Self {
        let mut s = Self::default();
        for (o, &mi) in objects.iter().zip(material) {
            let first = s.perturbations.len() as u32;
            for p in o.perturbations() {
                s.perturbations.push(GpuPerturbation {
                    q: GpuQuadric::new(&p.quadric),
                    factor: [p.factor as f32, 0.0, 0.0, 0.0],
                });
            }
            let b = o.bbox();
            let clamp = |v: f64| v.clamp(-1e30, 1e30) as f32;
            s.objects.push(GpuObject {
                base: GpuQuadric::new(o.base()),
                bmin: [clamp(b.min.x), clamp(b.min.y), clamp(b.min.z), 0.0],
                bmax: [clamp(b.max.x), clamp(b.max.y), clamp(b.max.z), 0.0],
                range: [first, o.perturbations().len() as u32, mi as u32, 0],
            });
        }
        s
    }
}

/// Material tags (`Material.tag.x` in WGSL; constants `MAT_*` of the
/// generated prelude). The models on the GPU; see [`GpuMaterial::new`].
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
    /// Every tag with its WGSL name, for the prelude.
    pub const ALL: [(&str, u32); 8] = [
        ("MAT_DIFFUSE", DIFFUSE),
        ("MAT_PHONG", PHONG),
        ("MAT_BLINN_PHONG", BLINN_PHONG),
        ("MAT_GGX", GGX),
        ("MAT_BECKMANN", BECKMANN),
        ("MAT_CONDUCTOR", CONDUCTOR),
        ("MAT_DIELECTRIC", DIELECTRIC),
        ("MAT_PLASTIC", PLASTIC),
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

/// A material of the GPU library. WGSL: `struct Material { tag: vec4<u32>,
/// a: vec4<f32>, b: vec4<f32>, c: vec4<f32>, d: vec4<f32> }`; the meaning
/// of `a`..`d` per tag is in [`GpuMaterial::new`] and `materials.wgsl`.
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
    /// Tangent hint (`xyz`).
    pub d: [f32; 4],
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

impl GpuMaterial {
    /// The GPU mirror of `m`, or `None` for a model not on the GPU yet
    /// (`gaussian`, `cook_torrance`, `ward`, `heidrich_seidel`, `mix`,
    /// `factored`, `merl`, `subsurface`, `subsurface_brdf`, `wave`).
    ///
    /// | tag | a | b | c | d |
    /// |---|---|---|---|---|
    /// | diffuse | reflectance | | | |
    /// | phong, blinn_phong | reflectance | specular | exponent, p(lobe) | |
    /// | ggx, beckmann | alpha_x, alpha_y | Fresnel | Fresnel | tangent |
    /// | conductor | | Fresnel | Fresnel | |
    /// | dielectric | ior | | | |
    /// | plastic | reflectance | ior, coat alpha, F_dr(internal) | | |
    pub fn new(m: &Material) -> Option<Self> {
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
            _ => return None,
        }
        Some(g)
    }
}

/// A point light. WGSL: `struct Light { position: vec4<f32>, intensity:
/// vec4<f32> }`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLight {
    /// `[x, y, z, 0]`.
    pub position: [f32; 4],
    /// `[r, g, b, 0]` (W/sr).
    pub intensity: [f32; 4],
}

/// The render kernel's uniform block. WGSL: `struct Params` in
/// `render.wgsl` (field by field).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuParams {
    /// Camera position.
    pub origin: [f32; 4],
    /// Unit view direction.
    pub forward: [f32; 4],
    /// Right vector scaled by `tan(fov/2) aspect`.
    pub right: [f32; 4],
    /// Up vector scaled by `tan(fov/2)`.
    pub up: [f32; 4],
    /// `[width, height, grid m, grid n]`.
    pub film: [u32; 4],
    /// `[first sample, sample count, seed low, seed high]`.
    pub pass_info: [u32; 4],
    /// `[objects, lights, max depth, environment kind]`.
    pub counts: [u32; 4],
    /// Constant environment radiance.
    pub env: [f32; 4],
    /// `[map width, map height, 0, 0]`.
    pub env_size: [u32; 4],
}

/// A material conformance query: `f`, `pdf` at `(wo, wi)` and a sample for
/// `u = [uc, u0, u1]`, local frame. WGSL: `struct Query` in
/// `material_eval.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuQuery {
    /// `wo` (`w` unused).
    pub wo: [f32; 4],
    /// `wi` (`w` unused).
    pub wi: [f32; 4],
    /// `[uc, u0, u1, 0]`.
    pub u: [f32; 4],
    /// `[material index, 0, 0, 0]`.
    pub index: [u32; 4],
}

/// The answer to a [`GpuQuery`]: `f = [rgb, pdf]`, `s_wi = [wi, pdf]`
/// (`pdf < 0`: no sample), `s_f = [rgb, flags]`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuAnswer {
    /// `f(wo, wi)` and `pdf(wo, wi)`.
    pub f: [f32; 4],
    /// Sampled direction and its pdf.
    pub s_wi: [f32; 4],
    /// Sampled `f` and the lobe flags (as a float).
    pub s_f: [f32; 4],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_match_the_wgsl_declarations() {
        // Quadric: 3 vec4 = 48 bytes; Perturbation: Quadric + vec4 = 64;
        // Object: Quadric + 3 vec4 = 96; Ray: 2 vec4 = 32; hit: vec4 = 16.
        assert_eq!(std::mem::size_of::<GpuQuadric>(), 48);
        assert_eq!(std::mem::size_of::<GpuPerturbation>(), 64);
        assert_eq!(std::mem::size_of::<GpuObject>(), 96);
        assert_eq!(std::mem::size_of::<GpuRay>(), 32);
        assert_eq!(std::mem::size_of::<GpuHit>(), 16);
        assert_eq!(std::mem::size_of::<GpuMaterial>(), 80);
        assert_eq!(std::mem::size_of::<GpuLight>(), 32);
        assert_eq!(std::mem::size_of::<GpuParams>(), 144);
        assert_eq!(std::mem::size_of::<GpuQuery>(), 64);
        assert_eq!(std::mem::size_of::<GpuAnswer>(), 48);
        // And naga agrees (layouts computed from the shader sources).
        let mut seen = std::collections::BTreeSet::new();
        for src in [
            crate::intersect_source(),
            crate::render_source(),
            crate::material_eval_source(),
        ] {
            let module = naga::front::wgsl::parse_str(&src).unwrap();
            let mut layouter = naga::proc::Layouter::default();
            layouter.update(module.to_ctx()).unwrap();
            for (h, ty) in module.types.iter() {
                let want = match ty.name.as_deref() {
                    Some("Quadric") => std::mem::size_of::<GpuQuadric>(),
                    Some("Perturbation") => std::mem::size_of::<GpuPerturbation>(),
                    Some("Object") => std::mem::size_of::<GpuObject>(),
                    Some("Ray") => std::mem::size_of::<GpuRay>(),
                    Some("Material") => std::mem::size_of::<GpuMaterial>(),
                    Some("Light") => std::mem::size_of::<GpuLight>(),
                    Some("Params") => std::mem::size_of::<GpuParams>(),
                    Some("Query") => std::mem::size_of::<GpuQuery>(),
                    Some("Answer") => std::mem::size_of::<GpuAnswer>(),
                    _ => continue,
                };
                assert_eq!(layouter[h].size as usize, want, "{:?}", ty.name);
                seen.insert(ty.name.clone().unwrap());
            }
        }
        assert_eq!(seen.len(), 9, "{seen:?}");
    }
}
