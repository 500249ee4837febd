// Entry point of the intersection conformance kernel: first hits of a
// batch of rays (geometry.wgsl does the work).

@group(0) @binding(0) var<storage, read> objects: array<Object>;
@group(0) @binding(1) var<storage, read> perturbations: array<Perturbation>;
@group(0) @binding(2) var<storage, read> rays: array<Ray>;
@group(0) @binding(3) var<storage, read_write> hits: array<vec4<f32>>;
@group(0) @binding(4) var<uniform> counts: vec4<u32>; // rays, objects

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= counts.x) {
        return;
    }
    let ray = rays[i];
    var best = vec4<f32>(MISS, 0.0, 0.0, 0.0);
    var t1 = ray.d.w;
    for (var k = 0u; k < counts.y; k++) {
        let h = object_hit(k, ray.o.xyz, ray.d.xyz, ray.o.w, t1);
        if (h.x >= 0.0 && h.x <= t1) {
            best = h;
            t1 = h.x;
        }
    }
    hits[i] = best;
}
