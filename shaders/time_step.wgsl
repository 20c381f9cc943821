// A new time step for Verlet, on the device: the last steps d = u - u_prev move to
// d * rescale (rescale = h_new / h_old), so that the velocity d / h, which Verlet and its
// damping read, is the same at the new step; w (the compensation) is kept. Symplectic Euler
// stores the velocity and needs no pass. Prepended with common.wgsl; the twin is
// `twin::time_step` (`physics::rescale_previous`).

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> cur: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> prev: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * p.row;
    if (i >= p.n) {
        return;
    }
    let s = prev[i];
    prev[i] = vec4<f32>(s.xyz * p.rescale, s.w);
}
