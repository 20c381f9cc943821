// State moves of a patch, on every state buffer at once: state[to] = old[first], zero without
// a source, or the mix (1 - t) * old[first] + t * old[second] for a node a cut puts on an edge
// (it starts with the state interpolated along it). The twin is
// `twin::move_state` (`StateMove::apply_to`).
//
// Where no move's destination is another's source (a patch that only appends nodes), `direct`
// does it in one dispatch. Otherwise moves may permute nodes: `gather` copies every source
// into `temp` first and `scatter` writes the destinations from there (a later dispatch, so
// every source is read before any destination is written).
//
// The state buffers are bound one by one (`s0`..`s3`; `moves.buffers` of them are real, the
// rest a placeholder never touched): WGSL has no arrays of storage bindings without an
// optional feature.

struct Move {
    to: u32,
    // Source index in the state, or NONE to start at zero.
    first: u32,
    // Second source to mix in, or NONE.
    second: u32,
    t: f32,
}

struct Moves {
    count: u32,
    // Invocations per row of a folded dispatch (`engine::gpu::dispatch_size`).
    row: u32,
    // State buffers bound (at most four).
    buffers: u32,
    pad: u32,
    items: array<Move>,
}

const NONE: u32 = 0xffffffffu;
const MOST: u32 = 4u;

@group(0) @binding(0) var<storage, read> moves: Moves;
@group(0) @binding(1) var<storage, read_write> temp: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> s0: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> s1: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> s2: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> s3: array<vec4<f32>>;

fn load(b: u32, i: u32) -> vec4<f32> {
    switch b {
        case 0u: { return s0[i]; }
        case 1u: { return s1[i]; }
        case 2u: { return s2[i]; }
        default: { return s3[i]; }
    }
}

fn store(b: u32, i: u32, v: vec4<f32>) {
    switch b {
        case 0u: { s0[i] = v; }
        case 1u: { s1[i] = v; }
        case 2u: { s2[i] = v; }
        default: { s3[i] = v; }
    }
}

// The move of this invocation, or none past the count.
fn index(gid: vec3<u32>) -> u32 {
    return gid.y * moves.row + gid.x;
}

// What buffer `b` holds at the move's sources: the first and the second (zero where none).
fn sources(m: Move, b: u32) -> array<vec4<f32>, 2> {
    var a = vec4<f32>(0.0);
    var c = vec4<f32>(0.0);
    if (m.first != NONE) {
        a = load(b, m.first);
    }
    if (m.second != NONE) {
        c = load(b, m.second);
    }
    return array<vec4<f32>, 2>(a, c);
}

// The state a move writes from its sources.
fn mixed(m: Move, a: vec4<f32>, c: vec4<f32>) -> vec4<f32> {
    if (m.second == NONE) {
        return a;
    }
    return a * (1.0 - m.t) + c * m.t;
}

@compute @workgroup_size(64)
fn direct(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = index(gid);
    if (k >= moves.count) {
        return;
    }
    let m = moves.items[k];
    for (var b = 0u; b < min(moves.buffers, MOST); b = b + 1u) {
        let s = sources(m, b);
        store(b, m.to, mixed(m, s[0], s[1]));
    }
}

@compute @workgroup_size(64)
fn gather(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = index(gid);
    if (k >= moves.count) {
        return;
    }
    let m = moves.items[k];
    for (var b = 0u; b < min(moves.buffers, MOST); b = b + 1u) {
        let s = sources(m, b);
        temp[2u * (moves.buffers * k + b)] = s[0];
        temp[2u * (moves.buffers * k + b) + 1u] = s[1];
    }
}

@compute @workgroup_size(64)
fn scatter(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = index(gid);
    if (k >= moves.count) {
        return;
    }
    let m = moves.items[k];
    for (var b = 0u; b < min(moves.buffers, MOST); b = b + 1u) {
        let at = 2u * (moves.buffers * k + b);
        store(b, m.to, mixed(m, temp[at], temp[at + 1u]));
    }
}
