//! GPU data layouts: `#[repr(C)]` mirrors of the WGSL structs in
//! `shaders/`, the single source of truth for both sides. Every struct is
//! a whole number of `vec4`s (16-byte aligned, no implicit padding), and a
//! unit test checks each size against the WGSL declaration's.

use bytemuck::{Pod, Zeroable};
use isolux_geometry::{Object, Quadric};

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
    /// `[first perturbation, count, 0, 0]`.
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
    /// Flattens `objects`. Unbounded boxes are clamped to +-1e30.
    pub fn new(objects: &[Object]) -> Self {
        let mut s = Self::default();
        for o in objects {
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
                range: [first, o.perturbations().len() as u32, 0, 0],
            });
        }
        s
    }
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
        // And naga agrees (layouts computed from the shader source).
        let module = naga::front::wgsl::parse_str(&crate::intersect_source()).unwrap();
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).unwrap();
        for (h, ty) in module.types.iter() {
            let want = match ty.name.as_deref() {
                Some("Quadric") => 48,
                Some("Perturbation") => 64,
                Some("Object") => 96,
                Some("Ray") => 32,
                _ => continue,
            };
            assert_eq!(layouter[h].size, want, "{:?}", ty.name);
        }
    }
}
