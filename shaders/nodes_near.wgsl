// Nodes near a blade: one invocation per node slot forms the node's current position (rest +
// displacement) and, when it lies in the box, appends its displacement and slot index to
// `found` through an atomic counter. Past `capacity` nothing is written but the counter keeps
// counting, so the host sees the true number, grows the buffer and runs again: nothing is
// dropped silently. A cut then reads back these few entries instead of every node. The twin
// is `twin::nodes_near` (the float64 scan of a full readback, `cut::AllPositions::near`, is what
// it must not miss).

// Mirrors `engine::gpu::nodes_near::NearParams` (48 bytes).
struct NearParams {
    lo: vec4<f32>,
    hi: vec4<f32>,
    slots: u32,
    capacity: u32,
    row: u32,    // invocations per dispatch row (2D dispatch of large meshes)
    _pad: u32,
}

// The counter, then the entries: one buffer, so one readback brings both.
struct Found {
    count: atomic<u32>,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    // xyz: the displacement's bits; w: the slot index. Kept as integers: a slot index carried
    // in a float would be a subnormal, which a device may flush to zero.
    entries: array<vec4<u32>>,
}

@group(0) @binding(0) var<uniform> np: NearParams;
@group(0) @binding(1) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> disp: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> found: Found;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * np.row;
    if (i >= np.slots) {
        return;
    }
    let u = disp[i].xyz;
    let x = rest[i].xyz + u;
    if (all(np.lo.xyz <= x) && all(x <= np.hi.xyz)) {
        let slot = atomicAdd(&found.count, 1u);
        if (slot < np.capacity) {
            found.entries[slot] = vec4<u32>(bitcast<vec3<u32>>(u), i);
        }
    }
}
