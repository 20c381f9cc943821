// State moves that start a node between two others (a node a cut puts on an edge starts with
// the state interpolated along it): state[to] = first * (1 - t) + second * t, per record. The
// sources were copied into `temp` before any move wrote, so moves may overwrite each other's
// sources. The twin is `layout::patch::StateMove::apply_to`.

struct Blend {
    // Destination index in `state`; 0xffffffff pads the records to the smallest binding.
    to: u32,
    // Indices of the two sources in `temp`.
    first: u32,
    second: u32,
    t: f32,
}

@group(0) @binding(0) var<storage, read> blends: array<Blend>;
@group(0) @binding(1) var<storage, read> temp: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> state: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if (k >= arrayLength(&blends)) {
        return;
    }
    let b = blends[k];
    if (b.to == 0xffffffffu) {
        return;
    }
    state[b.to] = temp[b.first] * (1.0 - b.t) + temp[b.second] * b.t;
}
