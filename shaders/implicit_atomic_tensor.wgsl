// The edge layout's float-atomic variant of the finite elements' implicit solve (tensor-mass,
// and corotational on the blocks its block pass writes), for `implicit_solve.wgsl` with
// implicit_tensor.wgsl, the force model's `element_force` and implicit_atomic_acc.wgsl: no
// incidence table. The edge records are bound as the solve's `slots` (`other` reads `a`,
// `pad` reads `b`), each record's block (K_ab, from its `a` end) at its own index.
// - `setup_records`, one invocation per record before `setup`: the record's share of the
//   setup terms seen from each end (`tensor_terms`, the block transposed at `b`, as the
//   gather variant's walk reads it), added to that end's accumulators; `node_terms` reads a
//   node's sums and clears them, then takes the force model's force.
// - `spring_multiply`, one invocation per record, d = p_b - p_a: (h^2 K + h C) d added at
//   `a`, its transpose times -d at `b` (a tensor's two shares are not opposite); `product`
//   reads and clears a node's sum.
// Fixed nodes get no adds, so their accumulators stay zero. The order of the float adds
// varies between runs. The twin is `twin::implicit_atomic_tensor` (one of the orders).

// Add `t` to node i's setup accumulators.
fn add_tensor_terms(i: u32, t: Terms) {
    if (inv_mass[i] == 0.0) {
        return;
    }
    acc_add(i, 0u, t.f.x);
    acc_add(i, 1u, t.f.y);
    acc_add(i, 2u, t.f.z);
    acc_add(i, 3u, t.kv.x);
    acc_add(i, 4u, t.kv.y);
    acc_add(i, 5u, t.kv.z);
    acc_add(i, 6u, t.iso);
    acc_add(i, 7u, t.da.x);
    acc_add(i, 8u, t.da.y);
    acc_add(i, 9u, t.da.z);
    acc_add(i, 10u, t.da.w);
    acc_add(i, 11u, t.db.x);
    acc_add(i, 12u, t.db.y);
}

@compute @workgroup_size(64)
fn setup_records(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * q.row;
    if (s >= q.springs) {
        return;
    }
    let a = slots[s].other;
    let b = slots[s].pad;
    let du = cur[b].xyz - cur[a].xyz;
    let dv = vel[b].xyz - vel[a].xyz;
    let row = s * block_stride();
    var ta = no_terms();
    tensor_terms(&ta, row, false, du, dv);
    add_tensor_terms(a, ta);
    var tb = no_terms();
    tensor_terms(&tb, row, true, -du, -dv);
    add_tensor_terms(b, tb);
}

fn node_terms(i: u32, ui: vec3<f32>, vi: vec3<f32>) -> Terms {
    let f = vec3<f32>(acc_take(i, 0u), acc_take(i, 1u), acc_take(i, 2u));
    let kv = vec3<f32>(acc_take(i, 3u), acc_take(i, 4u), acc_take(i, 5u));
    let iso = acc_take(i, 6u);
    let da = vec4<f32>(acc_take(i, 7u), acc_take(i, 8u), acc_take(i, 9u), acc_take(i, 10u));
    let db = vec2<f32>(acc_take(i, 11u), acc_take(i, 12u));
    // The force model's force (implicit_tensor_force.wgsl, implicit_corotational.wgsl).
    return Terms(element_force(i, f), kv, iso, da, db);
}

@compute @workgroup_size(64)
fn spring_multiply(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * q.row;
    if (s >= q.springs || red.s.status != RUNNING) {
        return;
    }
    let a = slots[s].other;
    let b = slots[s].pad;
    let d = vecs[at(P, b)].xyz - vecs[at(P, a)].xyz;
    let row = s * block_stride();
    if (inv_mass[a] != 0.0) {
        let out = tensor_product_term(row, false, d);
        acc_add(a, 0u, out.x);
        acc_add(a, 1u, out.y);
        acc_add(a, 2u, out.z);
    }
    if (inv_mass[b] != 0.0) {
        let out = tensor_product_term(row, true, -d);
        acc_add(b, 0u, out.x);
        acc_add(b, 1u, out.y);
        acc_add(b, 2u, out.z);
    }
}

// (A w)_i for the direction p, summed by `spring_multiply` (zero on fixed nodes). Only the
// direction is ever multiplied on this layout: `v` must be P.
fn product(i: u32, v: u32) -> vec3<f32> {
    let m_inv = inv_mass[i];
    if (m_inv == 0.0) {
        return vec3<f32>(0.0);
    }
    let wi = vecs[at(v, i)].xyz;
    let sum = vec3<f32>(acc_take(i, 0u), acc_take(i, 1u), acc_take(i, 2u));
    let m = (1.0 + q.h * q.alpha) / m_inv;
    return m * wi + sum;
}
