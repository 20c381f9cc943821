// Corotational finite elements, pass 2: one invocation per node sums the corner forces its
// tets' records hold (`corotational_tets.wgsl`; each node's list of 4 tet + corner, tets
// ascending, so the sum is deterministic) and integrates the node with the shared node update
// (`integrate`: gravity, mass damping, compensated summation). Prepended with common.wgsl; the
// twin is `twin::corotational` (`TetTable::gather_cpu`, `step_cpu`).

@group(0) @binding(0) var<uniform> p: Params;
// Each node's records, [start, end) in `incidence`.
@group(0) @binding(1) var<storage, read> rows: array<vec2<u32>>;
@group(0) @binding(2) var<storage, read> incidence: array<u32>;
@group(0) @binding(3) var<storage, read> forces: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> inv_mass: array<f32>;
@group(0) @binding(5) var<storage, read> second_in: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> cur: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> next: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> second_out: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * p.row;
    if (i >= p.n) {
        return;
    }
    let m_inv = inv_mass[i];
    if (m_inv == 0.0) {
        next[i] = vec4<f32>(0.0);
        second_out[i] = vec4<f32>(0.0);
        return;
    }
    var f = vec3<f32>(0.0);
    let row = rows[i];
    for (var k = row.x; k < row.y; k = k + 1u) {
        f = f + forces[incidence[k]].xyz;
    }
    let ui = cur[i].xyz;
    let vi = velocity(p, ui, second_in[i].xyz);
    let r = integrate(p, cur[i], second_in[i], vi, f, m_inv);
    next[i] = r.u;
    second_out[i] = r.second;
}
