// Corotational finite elements, pass 1: one invocation per tet. The tet's rotation R is the
// rotational part of its deformation gradient F, found by the quaternion iteration of Müller,
// Bender, Chentanez and Macklin ("A robust method to extract the rotational part of
// deformations", MIG 2016), warm-started from the tet's rotation of the last step (stored per
// tet in `rotations`); then its four corner forces f_a = -R (V sigma) b_a, sigma the stress of
// the rotated strain sym(R^T F) - I (plus Rayleigh's beta times that of the rotated velocity
// gradient), are written to forces[4 t + a] for `corotational_gather.wgsl` to sum per node.
// Prepended with common.wgsl; the twin is `twin::corotational` (`TetTable::tet_pass_cpu`),
// which repeats every operation below in the same order (no cross, normalize or matrix
// builtin, whose lowering could differ).

// Iterations at most per step, and the squared rotation update below which the rotation has
// converged (|omega| < 1e-6 rad: below that the update is rounding noise). Twins: `ROTATION_ITERATIONS`,
// `ROTATION_CONVERGED`.
const ROTATION_ITERATIONS: u32 = 24u;
const ROTATION_CONVERGED: f32 = 1e-12;

// Mirrors `engine::gpu::corotational::TetUniform` (16 bytes).
struct TetParams {
    tets: u32,   // tets in the table
    row: u32,    // invocations per dispatch row
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<uniform> tp: TetParams;
@group(0) @binding(2) var<storage, read> corners: array<vec4<u32>>;
// Per tet: (b1, V lambda), (b2, 2 V mu), (b3, beta) (`lancet::layout::tet_table`).
@group(0) @binding(3) var<storage, read> shape: array<vec4<f32>>;
// Per tet: its rotation as a unit quaternion (x, y, z, w), read and written back.
@group(0) @binding(4) var<storage, read_write> rotations: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> second_in: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> cur: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> forces: array<vec4<f32>>;

// A 3x3 matrix by rows.
struct Rows {
    r0: vec3<f32>,
    r1: vec3<f32>,
    r2: vec3<f32>,
}

// Every sum of products below is a `dot`: a compiler may fuse a written a * b + c into one
// rounding (lavapipe does on a CPU with FMA), which the twin could not follow, while `dot` is
// lowered as separate products summed left to right (the tensor-mass twins rely on it too).

// a x b, each lane a two-term dot.
fn cross3(a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        dot(vec2<f32>(a.y, a.z), vec2<f32>(b.z, -b.y)),
        dot(vec2<f32>(a.z, a.x), vec2<f32>(b.x, -b.z)),
        dot(vec2<f32>(a.x, a.y), vec2<f32>(b.y, -b.x))
    );
}

// R - I of the unit quaternion q: the small entries of a small rotation keep their precision.
fn rotation_minus_identity(q: vec4<f32>) -> Rows {
    var m: Rows;
    m.r0 = vec3<f32>(
        -2.0 * dot(q.yz, q.yz),
        2.0 * dot(vec2<f32>(q.x, q.w), vec2<f32>(q.y, -q.z)),
        2.0 * dot(vec2<f32>(q.x, q.w), vec2<f32>(q.z, q.y))
    );
    m.r1 = vec3<f32>(
        2.0 * dot(vec2<f32>(q.x, q.w), vec2<f32>(q.y, q.z)),
        -2.0 * dot(q.xz, q.xz),
        2.0 * dot(vec2<f32>(q.y, q.w), vec2<f32>(q.z, -q.x))
    );
    m.r2 = vec3<f32>(
        2.0 * dot(vec2<f32>(q.x, q.w), vec2<f32>(q.z, -q.y)),
        2.0 * dot(vec2<f32>(q.y, q.w), vec2<f32>(q.z, q.x)),
        -2.0 * dot(q.xy, q.xy)
    );
    return m;
}

// sum_a d_a b_a^T over corners 1..3 (d_a the corner's difference from corner 0), given the
// gradients' lanes by column: bx = (b1.x, b2.x, b3.x), ...
fn gradient(d1: vec3<f32>, d2: vec3<f32>, d3: vec3<f32>, bx: vec3<f32>, by: vec3<f32>, bz: vec3<f32>) -> Rows {
    let dx = vec3<f32>(d1.x, d2.x, d3.x);
    let dy = vec3<f32>(d1.y, d2.y, d3.y);
    let dz = vec3<f32>(d1.z, d2.z, d3.z);
    var g: Rows;
    g.r0 = vec3<f32>(dot(dx, bx), dot(dx, by), dot(dx, bz));
    g.r1 = vec3<f32>(dot(dy, bx), dot(dy, by), dot(dy, bz));
    g.r2 = vec3<f32>(dot(dz, bx), dot(dz, by), dot(dz, bz));
    return g;
}

// The columns of R (m = R - I).
fn columns(m: Rows) -> Rows {
    var c: Rows;
    c.r0 = vec3<f32>(m.r0.x + 1.0, m.r1.x, m.r2.x);
    c.r1 = vec3<f32>(m.r0.y, m.r1.y + 1.0, m.r2.y);
    c.r2 = vec3<f32>(m.r0.z, m.r1.z, m.r2.z + 1.0);
    return c;
}

// The rotation of F = I + D (rows of D) from the warm start q0: Müller et al.'s iteration,
// omega = sum_j r_j x a_j / (|sum_j r_j . a_j| + 1e-9) over the columns r_j of R and a_j of F,
// q <- (omega / 2, 1) q normalised (the exact axis-angle quaternion to first order: only
// arithmetic and a square root, which lavapipe rounds as the CPU does). Each update turns R
// towards the maximum of tr(R^T F) over rotations, which is the polar rotation where det F > 0
// and, for an inverted tet, the rotation that flips its smallest principal stretch (Irving et
// al. 2004): R stays a rotation whatever F is, and a degenerate F leaves the warm start.
fn polar_rotation(d: Rows, q0: vec4<f32>) -> vec4<f32> {
    let a0 = vec3<f32>(d.r0.x + 1.0, d.r1.x, d.r2.x);
    let a1 = vec3<f32>(d.r0.y, d.r1.y + 1.0, d.r2.y);
    let a2 = vec3<f32>(d.r0.z, d.r1.z, d.r2.z + 1.0);
    var q = q0;
    for (var it = 0u; it < ROTATION_ITERATIONS; it = it + 1u) {
        let c = columns(rotation_minus_identity(q));
        let num = cross3(c.r0, a0) + cross3(c.r1, a1) + cross3(c.r2, a2);
        let den = abs(dot(c.r0, a0) + dot(c.r1, a1) + dot(c.r2, a2)) + 1e-9;
        let omega = vec3<f32>(num.x / den, num.y / den, num.z / den);
        if (dot(omega, omega) < ROTATION_CONVERGED) {
            break;
        }
        let h = omega * 0.5;
        let v = q.xyz;
        let x = cross3(h, v);
        // v + h w + h x v, lane by lane.
        let nv = vec3<f32>(
            dot(vec3<f32>(v.x, h.x, x.x), vec3<f32>(1.0, q.w, 1.0)),
            dot(vec3<f32>(v.y, h.y, x.y), vec3<f32>(1.0, q.w, 1.0)),
            dot(vec3<f32>(v.z, h.z, x.z), vec3<f32>(1.0, q.w, 1.0))
        );
        let nw = q.w - dot(h, v);
        let n = vec4<f32>(nv, nw);
        let len = sqrt(dot(n, n));
        q = vec4<f32>(n.x / len, n.y / len, n.z / len, n.w / len);
    }
    return q;
}

// Rows of R^T g (plus R^T - I where with_identity; m = R - I): row i is column i of R dotted
// with each column of g.
fn rotated(m: Rows, g: Rows, with_identity: bool) -> Rows {
    let c = columns(m);
    let g0 = vec3<f32>(g.r0.x, g.r1.x, g.r2.x);
    let g1 = vec3<f32>(g.r0.y, g.r1.y, g.r2.y);
    let g2 = vec3<f32>(g.r0.z, g.r1.z, g.r2.z);
    var e: Rows;
    e.r0 = vec3<f32>(dot(c.r0, g0), dot(c.r0, g1), dot(c.r0, g2));
    e.r1 = vec3<f32>(dot(c.r1, g0), dot(c.r1, g1), dot(c.r1, g2));
    e.r2 = vec3<f32>(dot(c.r2, g0), dot(c.r2, g1), dot(c.r2, g2));
    if (with_identity) {
        e.r0 = vec3<f32>(m.r0.x, m.r1.x, m.r2.x) + e.r0;
        e.r1 = vec3<f32>(m.r0.y, m.r1.y, m.r2.y) + e.r1;
        e.r2 = vec3<f32>(m.r0.z, m.r1.z, m.r2.z) + e.r2;
    }
    return e;
}

// e + beta ev, lane by lane.
fn plus_scaled(e: vec3<f32>, ev: vec3<f32>, beta: f32) -> vec3<f32> {
    let s = vec2<f32>(1.0, beta);
    return vec3<f32>(dot(vec2<f32>(e.x, ev.x), s), dot(vec2<f32>(e.y, ev.y), s), dot(vec2<f32>(e.z, ev.z), s));
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = gid.x + gid.y * tp.row;
    if (t >= tp.tets) {
        return;
    }
    let c = corners[t];
    let s0 = shape[3u * t];
    let s1 = shape[3u * t + 1u];
    let s2 = shape[3u * t + 2u];
    let bx = vec3<f32>(s0.x, s1.x, s2.x);
    let by = vec3<f32>(s0.y, s1.y, s2.y);
    let bz = vec3<f32>(s0.z, s1.z, s2.z);
    let u0 = cur[c.x].xyz;
    let d = gradient(cur[c.y].xyz - u0, cur[c.z].xyz - u0, cur[c.w].xyz - u0, bx, by, bz);
    let q = polar_rotation(d, rotations[t]);
    rotations[t] = q;
    let m = rotation_minus_identity(q);
    var e = rotated(m, d, true);
    if (p.damped != 0u) {
        let v0 = velocity(p, u0, second_in[c.x].xyz);
        let v1 = velocity(p, cur[c.y].xyz, second_in[c.y].xyz);
        let v2 = velocity(p, cur[c.z].xyz, second_in[c.z].xyz);
        let v3 = velocity(p, cur[c.w].xyz, second_in[c.w].xyz);
        let ev = rotated(m, gradient(v1 - v0, v2 - v0, v3 - v0, bx, by, bz), false);
        e.r0 = plus_scaled(e.r0, ev.r0, s2.w);
        e.r1 = plus_scaled(e.r1, ev.r1, s2.w);
        e.r2 = plus_scaled(e.r2, ev.r2, s2.w);
    }
    // V sigma = 2 V mu sym(e) + V lambda tr(e) I.
    let lam = s0.w;
    let mu2 = s1.w;
    let tr = lam * (e.r0.x + e.r1.y + e.r2.z);
    let e01 = mu2 * (0.5 * (e.r0.y + e.r1.x));
    let e02 = mu2 * (0.5 * (e.r0.z + e.r2.x));
    let e12 = mu2 * (0.5 * (e.r1.z + e.r2.y));
    let k = vec2<f32>(mu2, 1.0);
    let sg0 = vec3<f32>(dot(k, vec2<f32>(e.r0.x, tr)), e01, e02);
    let sg1 = vec3<f32>(e01, dot(k, vec2<f32>(e.r1.y, tr)), e12);
    let sg2 = vec3<f32>(e02, e12, dot(k, vec2<f32>(e.r2.z, tr)));
    // f_a = -R (V sigma b_a); rows of R.
    let rr0 = vec3<f32>(m.r0.x + 1.0, m.r0.y, m.r0.z);
    let rr1 = vec3<f32>(m.r1.x, m.r1.y + 1.0, m.r1.z);
    let rr2 = vec3<f32>(m.r2.x, m.r2.y, m.r2.z + 1.0);
    let g1 = vec3<f32>(dot(sg0, s0.xyz), dot(sg1, s0.xyz), dot(sg2, s0.xyz));
    let g2 = vec3<f32>(dot(sg0, s1.xyz), dot(sg1, s1.xyz), dot(sg2, s1.xyz));
    let g3 = vec3<f32>(dot(sg0, s2.xyz), dot(sg1, s2.xyz), dot(sg2, s2.xyz));
    let f1 = -vec3<f32>(dot(rr0, g1), dot(rr1, g1), dot(rr2, g1));
    let f2 = -vec3<f32>(dot(rr0, g2), dot(rr1, g2), dot(rr2, g2));
    let f3 = -vec3<f32>(dot(rr0, g3), dot(rr1, g3), dot(rr2, g3));
    let f0 = -(f1 + f2 + f3);
    forces[4u * t] = vec4<f32>(f0, 0.0);
    forces[4u * t + 1u] = vec4<f32>(f1, 0.0);
    forces[4u * t + 2u] = vec4<f32>(f2, 0.0);
    forces[4u * t + 3u] = vec4<f32>(f3, 0.0);
}
