// The edge layout's float-atomic variant of the springs' implicit solve, for
// `implicit_solve.wgsl` (with implicit_spring_block.wgsl): no incidence table. The spring
// records (`EdgeSpring`) are bound as the solve's `slots` (`other` reads `a`, `pad` reads `b`).
// - `setup_records`, one invocation per record before `setup`: the spring's setup terms
//   (force, K v, the diagonal block's parts) seen from its `a` end, added to both ends'
//   accumulators (force and K v negated at `b`: seen from `b` the direction and the velocity
//   difference turn, the blocks do not); `node_terms` reads a node's sums and clears them.
// - `spring_multiply`, one invocation per record: h D_s (p_b - p_a) + h^2 K_s (p_b - p_a),
//   added at `a` and subtracted at `b`; `product` reads and clears a node's sum.
// Fixed nodes get no adds (their rows are projected out), so their accumulators stay zero.
// Float atomics: the order of the adds, hence the rounding of the sums, varies between runs;
// needs SHADER_FLOAT32_ATOMIC. The twin is `twin::implicit_atomic` (one of the orders). The
// accumulators are implicit_atomic_acc.wgsl's.

// Add `t` to node i's setup accumulators (f and K v times `sign`).
fn add_terms(i: u32, t: Terms, sign: f32) {
    if (inv_mass[i] == 0.0) {
        return;
    }
    let f = sign * t.f;
    let kv = sign * t.kv;
    acc_add(i, 0u, f.x);
    acc_add(i, 1u, f.y);
    acc_add(i, 2u, f.z);
    acc_add(i, 3u, kv.x);
    acc_add(i, 4u, kv.y);
    acc_add(i, 5u, kv.z);
    acc_add(i, 6u, t.iso);
    acc_add(i, 7u, t.da.x);
    acc_add(i, 8u, t.da.y);
    acc_add(i, 9u, t.da.z);
    acc_add(i, 10u, t.da.w);
    acc_add(i, 11u, t.db.x);
    acc_add(i, 12u, t.db.y);
}

// One spring's setup terms seen from node i (the body of implicit_springs.wgsl's walk).
fn spring_terms(s: Slot, ui: vec3<f32>, vi: vec3<f32>) -> Terms {
    let g = geometry(s, ui);
    if (!g.ok) {
        return Terms(vec3<f32>(0.0), vec3<f32>(0.0), 0.0, vec4<f32>(0.0), vec2<f32>(0.0));
    }
    let dv = vel[s.other].xyz - vi;
    var mag = s.k * (g.l - s.rest);
    if (q.damped != 0u) {
        mag = mag + s.c * dot3(dv, g.u);
    }
    let uw = dot3(g.u, dv);
    let kv = s.k * (g.t * dv + (1.0 - g.t) * uw * g.u);
    let h2k = (q.h * q.h) * s.k;
    var along = h2k * (1.0 - g.t);
    if (q.damped != 0u) {
        along = along + q.h * s.c;
    }
    let da = along * vec4<f32>(g.u.x * g.u.x, g.u.x * g.u.y, g.u.x * g.u.z, g.u.y * g.u.y);
    let db = along * vec2<f32>(g.u.y * g.u.z, g.u.z * g.u.z);
    return Terms(mag * g.u, kv, h2k * g.t, da, db);
}

@compute @workgroup_size(64)
fn setup_records(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * q.row;
    if (s >= q.springs) {
        return;
    }
    let sp = slots[s];
    let a = sp.other;
    let b = sp.pad;
    let seen = Slot(sp.edge, sp.rest, sp.k, sp.c, b, 0u);
    let t = spring_terms(seen, cur[a].xyz, vel[a].xyz);
    add_terms(a, t, 1.0);
    add_terms(b, t, -1.0);
}

fn node_terms(i: u32, ui: vec3<f32>, vi: vec3<f32>) -> Terms {
    let f = vec3<f32>(acc_take(i, 0u), acc_take(i, 1u), acc_take(i, 2u));
    let kv = vec3<f32>(acc_take(i, 3u), acc_take(i, 4u), acc_take(i, 5u));
    let iso = acc_take(i, 6u);
    let da = vec4<f32>(acc_take(i, 7u), acc_take(i, 8u), acc_take(i, 9u), acc_take(i, 10u));
    let db = vec2<f32>(acc_take(i, 11u), acc_take(i, 12u));
    return Terms(f, kv, iso, da, db);
}

@compute @workgroup_size(64)
fn spring_multiply(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * q.row;
    if (s >= q.springs || red.s.status != RUNNING) {
        return;
    }
    let sp = slots[s];
    let a = sp.other;
    let b = sp.pad;
    let seen = Slot(sp.edge, sp.rest, sp.k, sp.c, b, 0u);
    let g = geometry(seen, cur[a].xyz);
    if (!g.ok) {
        return;
    }
    let out = block_product(seen, g, vecs[at(P, b)].xyz - vecs[at(P, a)].xyz);
    if (inv_mass[a] != 0.0) {
        acc_add(a, 0u, out.x);
        acc_add(a, 1u, out.y);
        acc_add(a, 2u, out.z);
    }
    if (inv_mass[b] != 0.0) {
        acc_add(b, 0u, -out.x);
        acc_add(b, 1u, -out.y);
        acc_add(b, 2u, -out.z);
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
    return m * wi - sum;
}
