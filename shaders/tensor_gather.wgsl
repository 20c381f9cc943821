// The tensor-mass update of the node-centric passes (connectivity, valence): the layout's slot
// table walked as `node_gather.wgsl` walks it, each slot's 3x3 blocks read from `blocks` at the
// slot's own index (`lancet::layout::tensor_blocks`). Prepended after common.wgsl and
// node_gather.wgsl (whose bindings it reads), with tensor_products.wgsl (the block products);
// each pass file adds only its entry point. The twin is `twin::tensor_mass`
// (`TensorBlocks::node_forces_cpu`, `step_cpu`).

// Per slot: the rows of K_ij (xyz), then of C_ij where p.damped is set.
@group(0) @binding(7) var<storage, read> blocks: array<vec4<f32>>;

// Sum -K_ij (u_j - u_i) - C_ij (v_j - v_i) over slots[first .. first + width) of node i
// (stopping at an empty slot, going on in row `pad` at a CONTINUE slot) and integrate it.
fn update_node_tensor(i: u32, first: u32, width: u32) {
    let m_inv = inv_mass[i];
    if (m_inv == 0.0) {
        next[i] = vec4<f32>(0.0);
        second_out[i] = vec4<f32>(0.0);
        return;
    }
    let ui = cur[i].xyz;
    let vi = velocity(p, ui, second_in[i].xyz);
    let stride = block_stride();
    var f = vec3<f32>(0.0);
    var base = first;
    var s = 0u;
    var hops = 0u;
    loop {
        if (s >= width) {
            break;
        }
        let at = base + s;
        let slot = slots[at];
        if (slot.other == EMPTY) {
            break;
        }
        if (slot.other == CONTINUE) {
            hops = hops + 1u;
            if (hops > p.n) {
                break;
            }
            base = slot.pad * width;
            s = 0u;
            continue;
        }
        s = s + 1u;
        let uj = cur[slot.other].xyz;
        var dv = vec3<f32>(0.0);
        if (p.damped != 0u) {
            dv = velocity(p, uj, second_in[slot.other].xyz) - vi;
        }
        f = f - tensor_force(at * stride, uj - ui, dv);
    }
    let r = integrate(p, cur[i], second_in[i], vi, f, m_inv);
    next[i] = r.u;
    second_out[i] = r.second;
}
