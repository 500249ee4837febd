// Entry point of the intersection conformance kernel: first hits of a
// batch of rays, or with `counts.z` any hits (shadow rays; geometry.wgsl
// does the work).

@group(0) @binding(0) var<storage, read> objects: array<Object>;
@group(0) @binding(1) var<storage, read> perturbations: array<Perturbation>;
@group(0) @binding(2) var<storage, read> rays: array<Ray>;
@group(0) @binding(3) var<storage, read_write> hits: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> counts: vec4<u32>; // rays, objects, any
@group(0) @binding(5) var<storage, read> nodes: array<BvhNode>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= counts.x) {
        return;
    }
    let ray = rays[i];
    hits[i] = scene_first_hit(ray.o.xyz, ray.d.xyz, ray.o.w, ray.d.w, counts.y, counts.z != 0u);
}

// No tile lists here: geometry.wgsl's hooks.
const TILE_LISTS: bool = false;
fn tile_entry(k: u32) -> u32 {
    return 0u;
}
