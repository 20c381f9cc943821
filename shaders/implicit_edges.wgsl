// The edge layout's walk and product for `implicit_solve.wgsl`. The spring records
// (`EdgeSpring`: edge, rest, k, c, a, b) are bound as the solve's `slots`, whose record has
// the same layout (`other` reads `a`, `pad` reads `b`). A node's springs are its incidence row,
// each turned to be seen from the node (from the `b` end the rest vector is negated and the
// other end is `a`); the product is the edge layout's gather variant: `spring_multiply`, one
// invocation per spring, stores the spring's block times the difference of its ends' values
// for its `a` end, and `multiply` gathers them per node in the incidence row's order, adding
// at an `a` end and subtracting at a `b` end, as `gather_edges.wgsl` gathers forces. The twin
// is `twin::implicit_solve::edge_rows` and `twin::implicit_solve::multiply_edges_cpu`.

const B_END: u32 = 0x80000000u;
// Room a patch left at the end of a row (`lancet::layout::edges::NO_SPRING`).
const NO_SPRING: u32 = 0xffffffffu;

@group(0) @binding(9) var<storage, read> incidence_rows: array<vec2<u32>>;
@group(0) @binding(10) var<storage, read> incidence: array<u32>;
// One value per spring record: the spring's block product for its `a` end.
@group(0) @binding(11) var<storage, read_write> spring_values: array<vec4<f32>>;

struct Cursor {
    at: u32,
    end: u32,
}

fn cursor(i: u32) -> Cursor {
    let row = incidence_rows[i];
    return Cursor(row.x, row.y);
}

// The next spring of node i's incidence row, seen from node i; `other == EMPTY` at its end.
fn next_slot(c: ptr<function, Cursor>) -> Slot {
    if ((*c).at >= (*c).end) {
        return Slot(vec3<f32>(0.0), 0.0, 0.0, 0.0, EMPTY, 0u);
    }
    let e = incidence[(*c).at];
    if (e == NO_SPRING) {
        return Slot(vec3<f32>(0.0), 0.0, 0.0, 0.0, EMPTY, 0u);
    }
    (*c).at = (*c).at + 1u;
    let sp = slots[e & ~B_END];
    if ((e & B_END) != 0u) {
        return Slot(-sp.edge, sp.rest, sp.k, sp.c, sp.other, 0u);
    }
    return Slot(sp.edge, sp.rest, sp.k, sp.c, sp.pad, 0u);
}

// Per spring record: h D_s (p_b - p_a) + h^2 K_s (p_b - p_a), seen from its `a` end. Removed
// records (zero stiffness, both ends on one node) store zero.
@compute @workgroup_size(64)
fn spring_multiply(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * q.row;
    if (s >= q.springs || red.s.status != RUNNING) {
        return;
    }
    let sp = slots[s];
    let a = sp.other;
    let b = sp.pad;
    var out = vec3<f32>(0.0);
    let seen = Slot(sp.edge, sp.rest, sp.k, sp.c, b, 0u);
    let g = geometry(seen, cur[a].xyz);
    if (g.ok) {
        out = block_product(seen, g, vecs[at(P, b)].xyz - vecs[at(P, a)].xyz);
    }
    spring_values[s] = vec4<f32>(out, 0.0);
}

// (A w)_i for the direction p, gathered from `spring_multiply` (zero on fixed nodes). Only
// the direction is ever multiplied on this layout: `v` must be P.
fn product(i: u32, v: u32) -> vec3<f32> {
    let m_inv = inv_mass[i];
    if (m_inv == 0.0) {
        return vec3<f32>(0.0);
    }
    let wi = vecs[at(v, i)].xyz;
    var sum = vec3<f32>(0.0);
    let row = incidence_rows[i];
    for (var e = row.x; e < row.y; e = e + 1u) {
        let entry = incidence[e];
        if (entry == NO_SPRING) {
            break;
        }
        let term = spring_values[entry & ~B_END].xyz;
        if ((entry & B_END) != 0u) {
            sum = sum - term;
        } else {
            sum = sum + term;
        }
    }
    let m = (1.0 + q.h * q.alpha) / m_inv;
    return m * wi - sum;
}
