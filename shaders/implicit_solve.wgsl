// Linearised backward Euler by block-Jacobi conjugate gradients on the device: the passes of
// one solve over a layout, each a twin of a function of `twin::implicit_solve` (the float64
// specification is `physics::backward_euler`). Prepended with common.wgsl, which gives the slot
// record and its markers, and followed by the force model's and the layout's parts: a node's
// setup terms (`node_terms`) and its product (`product`), and on the edge layout the record
// pass `spring_multiply`.
// - springs: implicit_springs.wgsl, then implicit_slots.wgsl (the walk) with
//   implicit_slots_springs.wgsl and the connectivity table's or the valence buckets' `row_of`,
//   or implicit_edges.wgsl;
// - tensor-mass: implicit_tensor.wgsl (the blocks) and implicit_tensor_force.wgsl (the force
//   from the blocks), then implicit_slots.wgsl with implicit_slots_tensor.wgsl and `row_of`, or
//   implicit_tensor_edges.wgsl;
// - corotational: the same with implicit_corotational.wgsl for the force (the tet pass's
//   corner forces gathered), on the blocks `corotational_blocks.wgsl` writes each step.
// Every pass reads the solve's status word first and does nothing once it is set, so that the
// host can record many iterations per submission and read back only that word.
//
// The system is A w = (1 + h alpha) M w - h D w - h^2 K w over the free nodes (fixed nodes,
// inverse mass 0, are projected out: every vector is zero there), K and D the force model's
// stiffness and damping derivatives (see its file).

// The solve's constants; mirrors `engine::gpu::implicit::SolveUniform` (64 bytes).
struct Solve {
    gravity: vec3<f32>,
    h: f32,
    alpha: f32,          // mass-proportional damping, 1/s
    tolerance: f32,      // relative residual to stop at
    n: u32,              // node slots
    width: u32,          // slots per connectivity row
    row: u32,            // invocations per dispatch row
    damped: u32,         // 1 when any spring has damping
    definite: u32,       // 1: the transverse term of compressed springs is clamped at 0
    max_iterations: u32,
    groups: u32,         // workgroups of a node dispatch: the per-workgroup partial sums
    stride: u32,         // entries per solver vector (the state buffers' capacity)
    springs: u32,        // spring records (edge layout)
    pad1: u32,
}

// The scalars of the iteration, then one partial sum pair per workgroup.
struct Scalars {
    rz: f32,         // r . z of the current residual
    pap: f32,        // p . A p of the current direction
    step: f32,       // rz / pap
    beta: f32,
    b_norm: f32,
    residual: f32,   // |r| / |b| after the last update
    status: u32,     // RUNNING until the solve ends, then why it ended
    iterations: u32,
}

struct Reduce {
    s: Scalars,
    partials: array<vec2<f32>>,
}

const RUNNING: u32 = 0u;
const CONVERGED: u32 = 1u;
const CAPPED: u32 = 2u;
const INDEFINITE: u32 = 3u;
const ZERO_RHS: u32 = 4u;

// Solver vectors, `stride` entries each, in one buffer (a pass may bind only eight storage
// buffers): the solution y, the residual r, the preconditioned residual z, the direction p,
// its product A p, and the inverse diagonal block as two vec4s (xx, xy, xz, yy), (yz, zz, -, -).
const Y: u32 = 0u;
const R: u32 = 1u;
const Z: u32 = 2u;
const P: u32 = 3u;
const AP: u32 = 4u;
const MINV_A: u32 = 5u;
const MINV_B: u32 = 6u;

@group(0) @binding(0) var<uniform> q: Solve;
@group(0) @binding(1) var<storage, read> slots: array<Slot>;
@group(0) @binding(2) var<storage, read> inv_mass: array<f32>;
@group(0) @binding(3) var<storage, read> vel: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> cur: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> next: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> vel_out: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> vecs: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> red: Reduce;

var<workgroup> acc: array<vec2<f32>, 64>;

fn at(v: u32, i: u32) -> u32 {
    return v * q.stride + i;
}

fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

// What a node's force model gives its setup: the elastic and damping force f, the stiffness
// times the velocities (K v), and the diagonal block of h D + h^2 K negated as an isotropic part
// `iso` plus the symmetric entries xx, xy, xz, yy (da) and yz, zz (db). Each force model's file
// gives `node_terms` (implicit_springs.wgsl, implicit_slots_tensor.wgsl,
// implicit_tensor_edges.wgsl).
struct Terms {
    f: vec3<f32>,
    kv: vec3<f32>,
    iso: f32,
    da: vec4<f32>,
    db: vec2<f32>,
}

// Workgroup sum of `value` over the 64 invocations, in a fixed tree order; every invocation
// must call it (it holds barriers). Returns the sum in invocation 0.
fn workgroup_sum(l: u32, value: vec2<f32>) -> vec2<f32> {
    acc[l] = value;
    workgroupBarrier();
    for (var stride = 32u; stride > 0u; stride = stride / 2u) {
        if (l < stride) {
            acc[l] = acc[l] + acc[l + stride];
        }
        workgroupBarrier();
    }
    return acc[0];
}

// The sum of every workgroup's partial pair, in one workgroup: invocation l adds partials
// l, l + 64, ... in order, then the tree.
fn total(l: u32) -> vec2<f32> {
    var s = vec2<f32>(0.0);
    // The bound is uniform (barriers follow); each invocation skips past the partials.
    for (var k = 0u; k < q.groups; k = k + 64u) {
        if (k + l < q.groups) {
            s = s + red.partials[k + l];
        }
    }
    return workgroup_sum(l, s);
}

fn node_index(gid: vec3<u32>) -> u32 {
    return gid.x + gid.y * q.row;
}

fn store_partial(l: u32, i: u32, sum: vec2<f32>) {
    if (l == 0u) {
        red.partials[i / 64u] = sum;
    }
}

fn apply_inverse(i: u32, r: vec3<f32>) -> vec3<f32> {
    let a = vecs[at(MINV_A, i)];
    let b = vecs[at(MINV_B, i)];
    return vec3<f32>(
        a.x * r.x + a.y * r.y + a.z * r.z,
        a.y * r.x + a.w * r.y + b.x * r.z,
        a.z * r.x + b.x * r.y + b.y * r.z,
    );
}

// Right-hand side h (F + h K v), the inverse diagonal blocks, and the first residual and
// direction; partials (b . b, r . z).
@compute @workgroup_size(64)
fn setup(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) l: u32) {
    let i = node_index(gid);
    var part = vec2<f32>(0.0);
    if (i < q.n) {
        var b = vec3<f32>(0.0);
        var ma = vec4<f32>(1.0, 0.0, 0.0, 1.0);
        var mb = vec4<f32>(0.0, 1.0, 0.0, 0.0);
        let m_inv = inv_mass[i];
        if (m_inv != 0.0) {
            let ui = cur[i].xyz;
            let vi = vel[i].xyz;
            let t = node_terms(i, ui, vi);
            let mass = 1.0 / m_inv;
            let force = t.f + mass * q.gravity - (q.alpha * mass) * vi;
            b = q.h * (force + q.h * t.kv);
            let diag = (1.0 + q.h * q.alpha) * mass + t.iso;
            let a00 = diag + t.da.x;
            let a01 = t.da.y;
            let a02 = t.da.z;
            let a11 = diag + t.da.w;
            let a12 = t.db.x;
            let a22 = diag + t.db.y;
            let c00 = a11 * a22 - a12 * a12;
            let c01 = a02 * a12 - a01 * a22;
            let c02 = a01 * a12 - a02 * a11;
            let c11 = a00 * a22 - a02 * a02;
            let c12 = a01 * a02 - a00 * a12;
            let c22 = a00 * a11 - a01 * a01;
            let det = a00 * c00 + a01 * c01 + a02 * c02;
            if (det != 0.0) {
                let inv = 1.0 / det;
                ma = vec4<f32>(c00 * inv, c01 * inv, c02 * inv, c11 * inv);
                mb = vec4<f32>(c12 * inv, c22 * inv, 0.0, 0.0);
            }
        }
        vecs[at(MINV_A, i)] = ma;
        vecs[at(MINV_B, i)] = mb;
        let z = apply_inverse(i, b);
        vecs[at(Y, i)] = vec4<f32>(0.0);
        vecs[at(R, i)] = vec4<f32>(b, 0.0);
        vecs[at(Z, i)] = vec4<f32>(z, 0.0);
        vecs[at(P, i)] = vec4<f32>(z, 0.0);
        part = vec2<f32>(dot3(b, b), dot3(b, z));
    }
    store_partial(l, i, workgroup_sum(l, part));
}

// |b| and the first r . z; the status word starts the solve (or ends it on a zero right-hand
// side or a zero iteration cap).
@compute @workgroup_size(64)
fn start(@builtin(local_invocation_index) l: u32) {
    let sum = total(l);
    if (l == 0u) {
        var s = Scalars(sum.y, 0.0, 0.0, 0.0, sqrt(sum.x), 1.0, RUNNING, 0u);
        if (s.b_norm == 0.0) {
            s.residual = 0.0;
            s.status = ZERO_RHS;
        } else if (q.max_iterations == 0u) {
            s.status = CAPPED;
        }
        red.s = s;
    }
}

// A p; partials (p . A p, 0).
@compute @workgroup_size(64)
fn multiply(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) l: u32) {
    let i = node_index(gid);
    var part = vec2<f32>(0.0);
    if (i < q.n && red.s.status == RUNNING) {
        let ap = product(i, P);
        vecs[at(AP, i)] = vec4<f32>(ap, 0.0);
        part = vec2<f32>(dot3(vecs[at(P, i)].xyz, ap), 0.0);
    }
    store_partial(l, i, workgroup_sum(l, part));
}

// The step length rz / pap; a direction of non-positive curvature ends the solve.
@compute @workgroup_size(64)
fn step_length(@builtin(local_invocation_index) l: u32) {
    let sum = total(l);
    if (l == 0u && red.s.status == RUNNING) {
        red.s.iterations = red.s.iterations + 1u;
        red.s.pap = sum.x;
        if (sum.x <= 0.0) {
            red.s.status = INDEFINITE;
        } else {
            red.s.step = red.s.rz / sum.x;
        }
    }
}

// y += step p, r -= step A p, z = M^-1 r; partials (r . r, r . z).
@compute @workgroup_size(64)
fn update(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) l: u32) {
    let i = node_index(gid);
    var part = vec2<f32>(0.0);
    if (i < q.n && red.s.status == RUNNING) {
        let a = red.s.step;
        let y = vecs[at(Y, i)].xyz + a * vecs[at(P, i)].xyz;
        let r = vecs[at(R, i)].xyz - a * vecs[at(AP, i)].xyz;
        let z = apply_inverse(i, r);
        vecs[at(Y, i)] = vec4<f32>(y, 0.0);
        vecs[at(R, i)] = vec4<f32>(r, 0.0);
        vecs[at(Z, i)] = vec4<f32>(z, 0.0);
        part = vec2<f32>(dot3(r, r), dot3(r, z));
    }
    store_partial(l, i, workgroup_sum(l, part));
}

// The relative residual: converged, capped, or beta for the next direction.
@compute @workgroup_size(64)
fn residual(@builtin(local_invocation_index) l: u32) {
    let sum = total(l);
    if (l == 0u && red.s.status == RUNNING) {
        red.s.residual = sqrt(sum.x) / red.s.b_norm;
        if (red.s.residual <= q.tolerance) {
            red.s.status = CONVERGED;
        } else if (red.s.iterations >= q.max_iterations) {
            red.s.status = CAPPED;
        } else {
            red.s.beta = sum.y / red.s.rz;
            red.s.rz = sum.y;
        }
    }
}

// p = z + beta p.
@compute @workgroup_size(64)
fn direction(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if (i < q.n && red.s.status == RUNNING) {
        let p = vecs[at(Z, i)].xyz + red.s.beta * vecs[at(P, i)].xyz;
        vecs[at(P, i)] = vec4<f32>(p, 0.0);
    }
}

// Once the solve has ended: v+ = v + y, u+ = u + h v+ (fixed nodes stay at rest).
@compute @workgroup_size(64)
fn finish(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if (i >= q.n || red.s.status == RUNNING) {
        return;
    }
    if (inv_mass[i] == 0.0) {
        next[i] = vec4<f32>(0.0);
        vel_out[i] = vec4<f32>(0.0);
        return;
    }
    let v = vel[i].xyz + vecs[at(Y, i)].xyz;
    next[i] = vec4<f32>(cur[i].xyz + q.h * v, 0.0);
    vel_out[i] = vec4<f32>(v, 0.0);
}
