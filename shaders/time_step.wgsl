// A new time step for Verlet, on the device: the previous displacements move to
// cur - (cur - prev) * rescale (rescale = h_new / h_old), so that the backward-difference
// velocity (cur - prev) / h, which Verlet and its damping read, is the same at the new step.
// Symplectic Euler stores the velocity and needs no pass. Prepended with common.wgsl; the twin
// is `twin::time_step` (`physics::rescale_previous`).

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> cur: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> prev: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * p.row;
    if (i >= p.n) {
        return;
    }
    let u = cur[i].xyz;
    let s = prev[i];
    prev[i] = vec4<f32>(u - (u - s.xyz) * p.rescale, s.w);
}
