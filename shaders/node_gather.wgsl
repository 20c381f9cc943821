// The node-centric update shared by the connectivity and valence passes: bindings of group 0
// and the gather-and-integrate of one node over a run of slots. Prepended (after common.wgsl)
// by the Rust side of each pass; each pass file adds only its entry point. The twin is `twin::node_gather`.

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> slots: array<Slot>;
@group(0) @binding(2) var<storage, read> inv_mass: array<f32>;
// Verlet: last steps u - u_prev. Symplectic Euler: velocities.
@group(0) @binding(3) var<storage, read> second_in: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> cur: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> next: array<vec4<f32>>;
// Symplectic Euler: next velocities. Verlet: unused.
@group(0) @binding(6) var<storage, read_write> second_out: array<vec4<f32>>;

// Sum the forces of slots[base .. base + width) on node i (stopping at an empty slot, going on
// in row `pad` at a CONTINUE slot) and integrate it; the twin is
// `layout::connectivity::node_update`.
fn update_node(i: u32, first: u32, width: u32) {
    let m_inv = inv_mass[i];
    if (m_inv == 0.0) {
        // Fixed node: stays at rest.
        next[i] = vec4<f32>(0.0);
        second_out[i] = vec4<f32>(0.0);
        return;
    }
    let ui = cur[i].xyz;
    let vi = velocity(p, ui, second_in[i].xyz);
    var f = vec3<f32>(0.0);
    var base = first;
    var s = 0u;
    // A chain is never longer than the table; the bound keeps a corrupt one from hanging.
    var hops = 0u;
    loop {
        if (s >= width) {
            break;
        }
        let slot = slots[base + s];
        if (slot.other == EMPTY) {
            break;
        }
        if (slot.other == CONTINUE) {
            // Only the connectivity layout continues rows, always in rows of `width` slots.
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
        f = f + slot_force(p, slot, slot.edge + (uj - ui), dv);
    }
    let r = integrate(p, cur[i], second_in[i], vi, f, m_inv);
    next[i] = r.u;
    second_out[i] = r.second;
}
