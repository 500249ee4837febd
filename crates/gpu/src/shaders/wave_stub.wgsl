// Stand-in for wave.wgsl in kernels for scenes without a `wave` material
// (`render_source_variant`): the same functions, never reached (no
// material carries MAT_WAVE). The wave code inlined at every material
// call site made the path tracer's kernel compile for minutes on
// lavapipe, so scenes that do not use it do not pay for it.
fn place_material(m: Material, p: vec3<f32>, footprint: f32, xi: f32) -> Material {
    return m;
}

fn wave_f(m: Material, wo: vec3<f32>, wi: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(0.0);
}

fn wave_pdf(m: Material, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    return 0.0;
}

fn wave_sample_dir(m: Material, wo: vec3<f32>, uc: f32, u: vec2<f32>) -> vec4<f32> {
    return vec4<f32>(0.0);
}
