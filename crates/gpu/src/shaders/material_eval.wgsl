// Entry point of the material conformance kernel: for each query, the
// material's f and pdf at (wo, wi) and its sample for (uc, u), all in the
// local frame, the material placed at `point` (materials.wgsl and
// wave.wgsl do the work).

struct Query { wo: vec4<f32>, wi: vec4<f32>, u: vec4<f32>, index: vec4<u32>, point: vec4<f32> }
struct Answer { f: vec4<f32>, s_wi: vec4<f32>, s_f: vec4<f32> }

@group(0) @binding(0) var<storage, read> materials: array<Material>;
@group(0) @binding(1) var<storage, read> queries: array<Query>;
@group(0) @binding(2) var<storage, read_write> answers: array<Answer>;
@group(0) @binding(3) var<storage, read> counts: vec4<u32>; // queries
@group(0) @binding(4) var<storage, read> material_data: array<f32>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= counts.x) {
        return;
    }
    let q = queries[i];
    let m = place_material(materials[q.index.x], q.point.xyz, q.point.w, q.u.w);
    let wo = q.wo.xyz;
    let wi = q.wi.xyz;
    let f = material_f(m, wo, wi);
    let pdf = material_pdf(m, wo, wi);
    let s = material_sample(m, wo, q.u.x, q.u.yz);
    var a: Answer;
    a.f = vec4<f32>(f, pdf);
    if (s.ok) {
        a.s_wi = vec4<f32>(s.wi, s.pdf);
        a.s_f = vec4<f32>(s.f, f32(s.flags));
    } else {
        a.s_wi = vec4<f32>(0.0, 0.0, 0.0, -1.0);
        a.s_f = vec4<f32>(0.0);
    }
    answers[i] = a;
}
