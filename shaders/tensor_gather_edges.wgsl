// Tensor-mass on the edge layout, pass 2: one invocation per node sums the forces its incident
// records computed for its end (2 r for the a end, 2 r + 1 for the b end; in the incidence
// table's fixed order, so the result is deterministic) and integrates the node. Prepended with
// common.wgsl; the twin is `twin::tensor_mass` (`TensorBlocks::gather_edges_cpu`).

const B_END: u32 = 0x80000000u;
// Room a patch left at the end of a row (`lancet::layout::edges::NO_SPRING`).
const NO_SPRING: u32 = 0xffffffffu;

@group(0) @binding(0) var<uniform> p: Params;
// Each node's row, [start, end) in `incidence` (room included): rows need not be contiguous,
// since a patch moves a row that outgrew its room to the end of the table.
@group(0) @binding(1) var<storage, read> incidence_rows: array<vec2<u32>>;
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
    let row = incidence_rows[i];
    for (var e = row.x; e < row.y; e = e + 1u) {
        let entry = incidence[e];
        if (entry == NO_SPRING) {
            break;
        }
        let end = select(0u, 1u, (entry & B_END) != 0u);
        f = f + forces[2u * (entry & ~B_END) + end].xyz;
    }
    let ui = cur[i].xyz;
    let vi = velocity(p, ui, second_in[i].xyz);
    let r = integrate(p, cur[i], second_in[i], vi, f, m_inv);
    next[i] = r.u;
    second_out[i] = r.second;
}
