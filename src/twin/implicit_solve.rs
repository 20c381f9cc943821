//! Twin of `shaders/implicit_solve.wgsl` (pass `engine::gpu::implicit`): one linearised
//! backward Euler step solved by block-Jacobi conjugate gradients in float32, pass by pass in
//! the order and rounding of the shader, with its two-level reductions (a 64-wide tree per
//! workgroup, then one workgroup adding the partials in a fixed order). The float64
//! specification is [`crate::physics::BackwardEuler`].
//!
//! A node's springs are given as the slots it gathers, in the order the layout walks them
//! ([`rows`]), so the twin serves every layout; the edge layout's product, a spring pass and a
//! gather (`shaders/implicit_edges.wgsl`), has its own twins ([`spring_multiply_cpu`],
//! [`gather_multiply_cpu`], [`implicit_step_edges_cpu`]).

use crate::layout::edges::{EdgeLayout, B_END};
use crate::layout::{PackedLayout, Slot};

/// Each node slot's springs in the order the device walks them: the connectivity row with its
/// continuations, the node's row in its valence bucket up to the first empty slot (holes and
/// room: none), or the node's incidence row with each spring seen from the node
/// ([`edge_rows`]). Always `Some` (kept an option for the callers).
pub fn rows(layout: &PackedLayout) -> Option<Vec<Vec<Slot>>> {
    let n = layout.node_slots();
    match layout {
        PackedLayout::Connectivity(c) => Some((0..n).map(|i| c.row(i)).collect()),
        PackedLayout::Valence(v) => {
            let mut rows = vec![Vec::new(); n];
            for b in &v.buckets {
                for local in 0..b.count {
                    let base = (b.offset + local * b.valence) as usize;
                    rows[(b.first + local) as usize] = v.slots[base..base + b.valence as usize]
                        .iter()
                        .take_while(|s| s.other != Slot::EMPTY)
                        .copied()
                        .collect();
                }
            }
            Some(rows)
        }
        PackedLayout::Edges(e) => Some(edge_rows(e)),
    }
}

/// Each node's incidence row as `next_slot` in `shaders/implicit_edges.wgsl` turns it: the
/// spring seen from the node (from its `b` end the rest vector negated and the other end `a`).
pub fn edge_rows(layout: &EdgeLayout) -> Vec<Vec<Slot>> {
    (0..layout.node_count())
        .map(|i| {
            layout
                .row(i)
                .iter()
                .map(|&e| {
                    let s = &layout.springs[(e & !B_END) as usize];
                    let (edge, other) = if e & B_END != 0 {
                        (s.edge.map(|x| -x), s.a)
                    } else {
                        (s.edge, s.b)
                    };
                    Slot {
                        edge,
                        rest: s.rest,
                        k: s.k,
                        c: s.c,
                        other,
                        pad: 0,
                    }
                })
                .collect()
        })
        .collect()
}

/// The constants of a solve, as the shader's `Solve` uniform holds them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolveParams {
    /// Time step, s.
    pub h: f32,
    /// Mass-proportional damping, 1/s.
    pub alpha: f32,
    /// Gravity, m/s^2.
    pub gravity: [f32; 3],
    /// Relative residual the solve stops at.
    pub tolerance: f32,
    /// Iteration cap.
    pub max_iterations: u32,
    /// Whether any spring has damping (the damping terms are skipped otherwise).
    pub damped: bool,
    /// Whether the transverse term of compressed springs is clamped at zero
    /// ([`crate::physics::Linearization::Definite`]).
    pub definite: bool,
}

/// Why a solve ended (the shader's status word).
pub mod status {
    /// Still iterating.
    pub const RUNNING: u32 = 0;
    /// The relative residual reached the tolerance.
    pub const CONVERGED: u32 = 1;
    /// The iteration cap was reached.
    pub const CAPPED: u32 = 2;
    /// A direction of non-positive curvature (possible only under the exact linearisation).
    pub const INDEFINITE: u32 = 3;
    /// The right-hand side is zero: nothing to solve.
    pub const ZERO_RHS: u32 = 4;
}

/// The scalars of an iteration; mirrors `struct Scalars` in the shader (32 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Scalars {
    /// `r . z` of the current residual.
    pub rz: f32,
    /// `p . A p` of the current direction.
    pub pap: f32,
    /// `rz / pap`.
    pub step: f32,
    /// The next direction's weight of the last one.
    pub beta: f32,
    /// `|b|`.
    pub b_norm: f32,
    /// `|r| / |b|` after the last update.
    pub residual: f32,
    /// A [`status`] code.
    pub status: u32,
    /// Iterations begun.
    pub iterations: u32,
}

/// The solver's vectors (layout order, one entry per node slot) and its reduction buffer.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SolveVectors {
    /// The solution: the change of velocity.
    pub y: Vec<[f32; 4]>,
    /// The residual.
    pub r: Vec<[f32; 4]>,
    /// The preconditioned residual.
    pub z: Vec<[f32; 4]>,
    /// The search direction.
    pub p: Vec<[f32; 4]>,
    /// `A p`.
    pub ap: Vec<[f32; 4]>,
    /// The inverse diagonal block, symmetric: (xx, xy, xz, yy) and (yz, zz, 0, 0).
    pub minv: Vec<[[f32; 4]; 2]>,
    /// The scalars.
    pub scalars: Scalars,
    /// One partial sum pair per workgroup of 64 nodes.
    pub partials: Vec<[f32; 2]>,
}

impl SolveVectors {
    /// Zero vectors for `n` nodes.
    pub fn zeros(n: usize) -> Self {
        let z = vec![[0.0f32; 4]; n];
        SolveVectors {
            y: z.clone(),
            r: z.clone(),
            z: z.clone(),
            p: z.clone(),
            ap: z,
            minv: vec![[[0.0; 4]; 2]; n],
            scalars: Scalars::default(),
            partials: vec![[0.0; 2]; n.div_ceil(64)],
        }
    }
}

pub(crate) fn v3(a: [f32; 4]) -> [f32; 3] {
    [a[0], a[1], a[2]]
}

pub(crate) fn v4(a: [f32; 3]) -> [f32; 4] {
    [a[0], a[1], a[2], 0.0]
}

pub(crate) fn dot3(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn add(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub(crate) fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn scale(s: f32, a: [f32; 3]) -> [f32; 3] {
    [s * a[0], s * a[1], s * a[2]]
}

/// A slot's spring at displacements `cur`: direction, length and transverse term, as the
/// shader's `geometry`; `None` at zero length.
pub(crate) fn geometry(
    p: &SolveParams,
    s: &Slot,
    cur: &[[f32; 4]],
    ui: [f32; 3],
) -> Option<([f32; 3], f32, f32)> {
    let uj = v3(cur[s.other as usize]);
    let d = add(s.edge, sub(uj, ui));
    let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if l <= 0.0 {
        return None;
    }
    let mut t = 1.0 - s.rest / l;
    if p.definite {
        t = t.max(0.0);
    }
    Some(([d[0] / l, d[1] / l, d[2] / l], l, t))
}

/// `h D_s w + h^2 K_s w`, as the shader's `block_product`.
pub(crate) fn block_product(
    p: &SolveParams,
    s: &Slot,
    u: [f32; 3],
    t: f32,
    w: [f32; 3],
) -> [f32; 3] {
    let uw = dot3(u, w);
    let kw = scale(s.k, add(scale(t, w), scale((1.0 - t) * uw, u)));
    let mut out = scale(p.h * p.h, kw);
    if p.damped {
        out = add(out, scale(p.h, scale(s.c * uw, u)));
    }
    out
}

/// `(A w)_i` for node `i` gathering `slots`, as the shader's `product`.
pub fn product(
    p: &SolveParams,
    slots: &[Slot],
    inv_mass: f32,
    cur: &[[f32; 4]],
    w: &[[f32; 4]],
    i: usize,
) -> [f32; 3] {
    if inv_mass == 0.0 {
        return [0.0; 3];
    }
    let ui = v3(cur[i]);
    let wi = v3(w[i]);
    let mut sum = [0.0f32; 3];
    for s in slots {
        if let Some((u, _, t)) = geometry(p, s, cur, ui) {
            let wj = v3(w[s.other as usize]);
            sum = add(sum, block_product(p, s, u, t, sub(wj, wi)));
        }
    }
    let m = (1.0 + p.h * p.alpha) / inv_mass;
    sub(scale(m, wi), sum)
}

/// The shader's `workgroup_sum`: the tree over 64 values.
pub fn workgroup_sum(mut acc: [[f32; 2]; 64]) -> [f32; 2] {
    let mut stride = 32;
    while stride > 0 {
        for l in 0..stride {
            acc[l] = [
                acc[l][0] + acc[l + stride][0],
                acc[l][1] + acc[l + stride][1],
            ];
        }
        stride /= 2;
    }
    acc[0]
}

/// Per-workgroup partial sums of per-node pairs (zero past the nodes).
pub fn partials(values: &[[f32; 2]]) -> Vec<[f32; 2]> {
    values
        .chunks(64)
        .map(|c| {
            let mut acc = [[0.0f32; 2]; 64];
            acc[..c.len()].copy_from_slice(c);
            workgroup_sum(acc)
        })
        .collect()
}

/// The shader's `total`: invocation `l` adds partials `l, l + 64, ...`, then the tree.
pub fn total(partials: &[[f32; 2]]) -> [f32; 2] {
    let mut acc = [[0.0f32; 2]; 64];
    for (k, v) in partials.iter().enumerate() {
        let a = &mut acc[k % 64];
        *a = [a[0] + v[0], a[1] + v[1]];
    }
    workgroup_sum(acc)
}

pub(crate) fn apply_inverse(m: &[[f32; 4]; 2], r: [f32; 3]) -> [f32; 3] {
    let (a, b) = (m[0], m[1]);
    [
        a[0] * r[0] + a[1] * r[1] + a[2] * r[2],
        a[1] * r[0] + a[3] * r[1] + b[0] * r[2],
        a[2] * r[0] + b[0] * r[1] + b[1] * r[2],
    ]
}

/// The right-hand side `h (F + h K v)` of node `i` and its inverse diagonal block, as the
/// shader's `setup` computes them.
fn node_setup(
    p: &SolveParams,
    slots: &[Slot],
    inv_mass: f32,
    cur: &[[f32; 4]],
    vel: &[[f32; 4]],
    i: usize,
) -> ([f32; 3], [[f32; 4]; 2]) {
    let identity = [[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 0.0]];
    if inv_mass == 0.0 {
        return ([0.0; 3], identity);
    }
    let (ui, vi) = (v3(cur[i]), v3(vel[i]));
    let (mut f, mut kv) = ([0.0f32; 3], [0.0f32; 3]);
    let mut iso = 0.0f32;
    let (mut da, mut db) = ([0.0f32; 4], [0.0f32; 2]);
    for s in slots {
        let Some((u, l, t)) = geometry(p, s, cur, ui) else {
            continue;
        };
        let dv = sub(v3(vel[s.other as usize]), vi);
        let mut mag = s.k * (l - s.rest);
        if p.damped {
            mag += s.c * dot3(dv, u);
        }
        f = add(f, scale(mag, u));
        let uw = dot3(u, dv);
        kv = add(kv, scale(s.k, add(scale(t, dv), scale((1.0 - t) * uw, u))));
        let h2k = (p.h * p.h) * s.k;
        iso += h2k * t;
        let mut along = h2k * (1.0 - t);
        if p.damped {
            along += p.h * s.c;
        }
        let e = [u[0] * u[0], u[0] * u[1], u[0] * u[2], u[1] * u[1]];
        for c in 0..4 {
            da[c] += along * e[c];
        }
        let e = [u[1] * u[2], u[2] * u[2]];
        for c in 0..2 {
            db[c] += along * e[c];
        }
    }
    let terms = Terms { f, kv, iso, da, db };
    finish_setup(p, inv_mass, vi, &terms)
}

/// What a node's force model gives its setup, as the shader's `struct Terms`: the elastic and
/// damping force, `K v`, and the negated diagonal block of `h D + h^2 K` as an isotropic part
/// and the symmetric entries (xx, xy, xz, yy) and (yz, zz).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Terms {
    pub f: [f32; 3],
    pub kv: [f32; 3],
    pub iso: f32,
    pub da: [f32; 4],
    pub db: [f32; 2],
}

/// The rest of the shader's `setup` for a free node of velocity `vi` and terms `t`: the
/// right-hand side and the inverse diagonal block.
pub(crate) fn finish_setup(
    p: &SolveParams,
    inv_mass: f32,
    vi: [f32; 3],
    t: &Terms,
) -> ([f32; 3], [[f32; 4]; 2]) {
    let identity = [[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 0.0]];
    let (da, db) = (t.da, t.db);
    let mass = 1.0 / inv_mass;
    let force = sub(add(t.f, scale(mass, p.gravity)), scale(p.alpha * mass, vi));
    let b = scale(p.h, add(force, scale(p.h, t.kv)));
    let diag = (1.0 + p.h * p.alpha) * mass + t.iso;
    let (a00, a01, a02, a11, a12, a22) = (
        diag + da[0],
        da[1],
        da[2],
        diag + da[3],
        db[0],
        diag + db[1],
    );
    let c00 = a11 * a22 - a12 * a12;
    let c01 = a02 * a12 - a01 * a22;
    let c02 = a01 * a12 - a02 * a11;
    let c11 = a00 * a22 - a02 * a02;
    let c12 = a01 * a02 - a00 * a12;
    let c22 = a00 * a11 - a01 * a01;
    let det = a00 * c00 + a01 * c01 + a02 * c02;
    if det == 0.0 {
        return (b, identity);
    }
    let inv = 1.0 / det;
    let m = [
        [c00 * inv, c01 * inv, c02 * inv, c11 * inv],
        [c12 * inv, c22 * inv, 0.0, 0.0],
    ];
    (b, m)
}

/// The `setup` pass: the right-hand side as the first residual, the inverse diagonal blocks,
/// `z = p = M^-1 b`, `y = 0`, and partials `(b . b, b . z)`.
pub fn setup_cpu(
    p: &SolveParams,
    rows: &[Vec<Slot>],
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    vel: &[[f32; 4]],
) -> SolveVectors {
    setup_with(cur.len(), |i| {
        node_setup(p, &rows[i], inv_mass[i], cur, vel, i)
    })
}

/// The `setup` pass over `n` nodes, each node's right-hand side and inverse diagonal block
/// from `node`.
pub(crate) fn setup_with(
    n: usize,
    mut node: impl FnMut(usize) -> ([f32; 3], [[f32; 4]; 2]),
) -> SolveVectors {
    let mut out = SolveVectors::zeros(n);
    let pairs: Vec<[f32; 2]> = (0..n)
        .map(|i| {
            let (b, m) = node(i);
            let z = apply_inverse(&m, b);
            out.minv[i] = m;
            out.r[i] = v4(b);
            out.z[i] = v4(z);
            out.p[i] = v4(z);
            [dot3(b, b), dot3(b, z)]
        })
        .collect();
    out.partials = partials(&pairs);
    out
}

/// The `start` pass: `|b|`, the first `r . z` and the status.
pub fn start_cpu(p: &SolveParams, v: &mut SolveVectors) {
    let sum = total(&v.partials);
    let mut s = Scalars {
        rz: sum[1],
        b_norm: sum[0].sqrt(),
        residual: 1.0,
        status: status::RUNNING,
        ..Scalars::default()
    };
    if s.b_norm == 0.0 {
        s.residual = 0.0;
        s.status = status::ZERO_RHS;
    } else if p.max_iterations == 0 {
        s.status = status::CAPPED;
    }
    v.scalars = s;
}

/// The `multiply` pass: `A p` and partials `(p . A p, 0)`.
pub fn multiply_cpu(
    p: &SolveParams,
    rows: &[Vec<Slot>],
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    v: &mut SolveVectors,
) {
    product_pass(v, |i, w| product(p, &rows[i], inv_mass[i], cur, w, i));
}

/// A `multiply` pass: `A p` at each node from `ap(i, p)`, written to `v.ap`, and the partials
/// `(p . A p, 0)`; nothing once the solve has ended. Shared by every layout's and force
/// model's product.
pub fn product_pass(v: &mut SolveVectors, ap: impl Fn(usize, &[[f32; 4]]) -> [f32; 3]) {
    if v.scalars.status != status::RUNNING {
        return;
    }
    let pairs: Vec<[f32; 2]> = (0..v.p.len())
        .map(|i| {
            let a = ap(i, &v.p);
            v.ap[i] = v4(a);
            [dot3(v3(v.p[i]), a), 0.0]
        })
        .collect();
    v.partials = partials(&pairs);
}

/// The edge layout's `spring_multiply` pass: per spring record, `h D_s (p_b - p_a) +
/// h^2 K_s (p_b - p_a)` seen from its `a` end (nothing while the solve is not running: the
/// values are then returned as `previous`).
pub fn spring_multiply_cpu(
    p: &SolveParams,
    layout: &EdgeLayout,
    cur: &[[f32; 4]],
    v: &SolveVectors,
    previous: &[[f32; 4]],
) -> Vec<[f32; 4]> {
    if v.scalars.status != status::RUNNING {
        return previous.to_vec();
    }
    layout
        .springs
        .iter()
        .map(|s| {
            let seen = Slot {
                edge: s.edge,
                rest: s.rest,
                k: s.k,
                c: s.c,
                other: s.b,
                pad: 0,
            };
            let (a, b) = (s.a as usize, s.b as usize);
            match geometry(p, &seen, cur, v3(cur[a])) {
                Some((u, _, t)) => v4(block_product(p, &seen, u, t, sub(v3(v.p[b]), v3(v.p[a])))),
                None => [0.0; 4],
            }
        })
        .collect()
}

/// The edge layout's `multiply` pass: `A p` gathered from the spring values in incidence
/// order (added at an `a` end, subtracted at a `b` end), and partials `(p . A p, 0)`.
pub fn gather_multiply_cpu(
    p: &SolveParams,
    layout: &EdgeLayout,
    inv_mass: &[f32],
    spring_values: &[[f32; 4]],
    v: &mut SolveVectors,
) {
    product_pass(v, |i, w| {
        if inv_mass[i] == 0.0 {
            return [0.0; 3];
        }
        let mut sum = [0.0f32; 3];
        for &e in layout.row(i) {
            let term = v3(spring_values[(e & !B_END) as usize]);
            sum = if e & B_END != 0 {
                sub(sum, term)
            } else {
                add(sum, term)
            };
        }
        let m = (1.0 + p.h * p.alpha) / inv_mass[i];
        sub(scale(m, v3(w[i])), sum)
    });
}

/// The `step_length` pass.
pub fn step_length_cpu(v: &mut SolveVectors) {
    let sum = total(&v.partials);
    let s = &mut v.scalars;
    if s.status != status::RUNNING {
        return;
    }
    s.iterations += 1;
    s.pap = sum[0];
    if sum[0] <= 0.0 {
        s.status = status::INDEFINITE;
    } else {
        s.step = s.rz / sum[0];
    }
}

/// The `update` pass: `y += step p`, `r -= step A p`, `z = M^-1 r`; partials
/// `(r . r, r . z)`.
pub fn update_cpu(v: &mut SolveVectors) {
    if v.scalars.status != status::RUNNING {
        return;
    }
    let a = v.scalars.step;
    let pairs: Vec<[f32; 2]> = (0..v.y.len())
        .map(|i| {
            let y = add(v3(v.y[i]), scale(a, v3(v.p[i])));
            let r = sub(v3(v.r[i]), scale(a, v3(v.ap[i])));
            let z = apply_inverse(&v.minv[i], r);
            (v.y[i], v.r[i], v.z[i]) = (v4(y), v4(r), v4(z));
            [dot3(r, r), dot3(r, z)]
        })
        .collect();
    v.partials = partials(&pairs);
}

/// The `residual` pass: converged, capped, or the next `beta`.
pub fn residual_cpu(p: &SolveParams, v: &mut SolveVectors) {
    let sum = total(&v.partials);
    let s = &mut v.scalars;
    if s.status != status::RUNNING {
        return;
    }
    s.residual = sum[0].sqrt() / s.b_norm;
    if s.residual <= p.tolerance {
        s.status = status::CONVERGED;
    } else if s.iterations >= p.max_iterations {
        s.status = status::CAPPED;
    } else {
        s.beta = sum[1] / s.rz;
        s.rz = sum[1];
    }
}

/// The `direction` pass: `p = z + beta p`.
pub fn direction_cpu(v: &mut SolveVectors) {
    if v.scalars.status != status::RUNNING {
        return;
    }
    let beta = v.scalars.beta;
    for i in 0..v.p.len() {
        v.p[i] = v4(add(v3(v.z[i]), scale(beta, v3(v.p[i]))));
    }
}

/// The next displacements and velocities, `vec4` per node, layout order.
pub type NextState = (Vec<[f32; 4]>, Vec<[f32; 4]>);

/// The `finish` pass: once the solve has ended, the next displacements and velocities
/// (`None` while it runs: the pass writes nothing).
pub fn finish_cpu(
    p: &SolveParams,
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    vel: &[[f32; 4]],
    v: &SolveVectors,
) -> Option<NextState> {
    if v.scalars.status == status::RUNNING {
        return None;
    }
    let n = cur.len();
    let (mut next, mut vel_out) = (vec![[0.0f32; 4]; n], vec![[0.0f32; 4]; n]);
    for i in (0..n).filter(|&i| inv_mass[i] != 0.0) {
        let w = add(v3(vel[i]), v3(v.y[i]));
        next[i] = v4(add(v3(cur[i]), scale(p.h, w)));
        vel_out[i] = v4(w);
    }
    Some((next, vel_out))
}

/// One conjugate-gradient iteration: the passes `multiply`, `step_length`, `update`,
/// `residual`, `direction` (each a no-op once the solve has ended).
pub fn iteration_cpu(
    p: &SolveParams,
    rows: &[Vec<Slot>],
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    v: &mut SolveVectors,
) {
    multiply_cpu(p, rows, inv_mass, cur, v);
    after_product_cpu(p, v);
}

/// The passes of an iteration after its product: `step_length`, `update`, `residual`,
/// `direction`.
fn after_product_cpu(p: &SolveParams, v: &mut SolveVectors) {
    step_length_cpu(v);
    update_cpu(v);
    residual_cpu(p, v);
    direction_cpu(v);
}

/// Iterations until the solve ends, each `multiply` (a variant's product passes) and then
/// the passes every variant shares.
pub(crate) fn iterate_cpu(
    p: &SolveParams,
    v: &mut SolveVectors,
    mut multiply: impl FnMut(&mut SolveVectors),
) {
    while v.scalars.status == status::RUNNING {
        multiply(v);
        after_product_cpu(p, v);
    }
}

/// [`implicit_step_cpu`] on the edge layout: the setup over its incidence rows
/// ([`edge_rows`]), each iteration's product as the spring pass and the gather.
pub fn implicit_step_edges_cpu(
    p: &SolveParams,
    layout: &EdgeLayout,
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    vel: &[[f32; 4]],
) -> (Vec<[f32; 4]>, Vec<[f32; 4]>, Scalars) {
    let mut v = setup_cpu(p, &edge_rows(layout), inv_mass, cur, vel);
    start_cpu(p, &mut v);
    let mut values = vec![[0.0f32; 4]; layout.springs.len()];
    iterate_cpu(p, &mut v, |v| {
        values = spring_multiply_cpu(p, layout, cur, v, &values);
        gather_multiply_cpu(p, layout, inv_mass, &values, v);
    });
    let (next, vel_out) = finish_cpu(p, inv_mass, cur, vel, &v).expect("the solve ended");
    (next, vel_out, v.scalars)
}

/// One implicit step as the device takes it: `setup`, `start`, iterations until the solve
/// ends, `finish`. Returns the next displacements and velocities and the final scalars.
pub fn implicit_step_cpu(
    p: &SolveParams,
    rows: &[Vec<Slot>],
    inv_mass: &[f32],
    cur: &[[f32; 4]],
    vel: &[[f32; 4]],
) -> (Vec<[f32; 4]>, Vec<[f32; 4]>, Scalars) {
    let mut v = setup_cpu(p, rows, inv_mass, cur, vel);
    start_cpu(p, &mut v);
    iterate_cpu(p, &mut v, |v| multiply_cpu(p, rows, inv_mass, cur, v));
    let (next, vel_out) = finish_cpu(p, inv_mass, cur, vel, &v).expect("the solve ended");
    (next, vel_out, v.scalars)
}
