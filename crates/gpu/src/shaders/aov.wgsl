// ---- AOVs -----------------------------------------------------------------
//
// Part of the path tracer's module (source.rs `RENDER_FILES`).

// AOVs of the first hit for sample `pass_info.x`, at the same sub-pixel
// position as in `main`, added to the pixel's sums: the material's albedo
// and the distance (0 on a miss), the outward normal. One sample per
// dispatch: a loop over the samples around the intersection lost some of
// its iterations (the defect of docs/gpu.md); the host divides.
@compute @workgroup_size(8, 8)
fn aov_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let width = params.film.x;
    let height = params.film.y;
    if (gid.x >= width || gid.y >= height) {
        return;
    }
    use_tile(gid);
    let pixel = gid.y * width + gid.x;
    let h = scene_hit(params.origin.xyz, camera_sample(gid), 3.0e38);
    if (h.x >= 0.0) {
        let a = albedos[objects[hit_object].range.z].rgb;
        aov[2u * pixel] += vec4<f32>(a, h.x);
        aov[2u * pixel + 1u] += vec4<f32>(h.yzw, 0.0);
    }
}
