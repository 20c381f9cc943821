// State moves of a patch, on one state buffer: state[to] = old[first], zero without a source,
// or the mix (1 - t) * old[first] + t * old[second] for a node a cut puts on an edge (it starts
// with the state interpolated along it). `gather` copies every source into `temp` first and
// `scatter` writes the destinations from there (a later dispatch, so every source is read
// before any destination is written: moves may permute nodes). The twin is
// `layout::patch::StateMove::apply_to`.

struct Move {
    to: u32,
    // Source index in `state`, or NONE to start at zero.
    first: u32,
    // Second source to mix in, or NONE.
    second: u32,
    t: f32,
}

struct Moves {
    count: u32,
    // Invocations per row of a folded dispatch (`engine::gpu::dispatch_size`).
    row: u32,
    pad1: u32,
    pad2: u32,
    items: array<Move>,
}

const NONE: u32 = 0xffffffffu;

@group(0) @binding(0) var<storage, read> moves: Moves;
@group(0) @binding(1) var<storage, read_write> temp: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> state: array<vec4<f32>>;

@compute @workgroup_size(64)
fn gather(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.y * moves.row + gid.x;
    if (k >= moves.count) {
        return;
    }
    let m = moves.items[k];
    var a = vec4<f32>(0.0);
    var b = vec4<f32>(0.0);
    if (m.first != NONE) {
        a = state[m.first];
    }
    if (m.second != NONE) {
        b = state[m.second];
    }
    temp[2u * k] = a;
    temp[2u * k + 1u] = b;
}

@compute @workgroup_size(64)
fn scatter(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.y * moves.row + gid.x;
    if (k >= moves.count) {
        return;
    }
    let m = moves.items[k];
    if (m.second == NONE) {
        state[m.to] = temp[2u * k];
    } else {
        state[m.to] = temp[2u * k] * (1.0 - m.t) + temp[2u * k + 1u] * m.t;
    }
}
