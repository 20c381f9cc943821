// Broad phase, tool against tissue: one invocation per boundary triangle forms its bounding box
// from the current positions (rest + displacement) and appends (triangle, tool) for every tool
// box it overlaps to `candidates` through an atomic counter. Past `capacity` nothing is
// written but the counter keeps counting, so the host sees the true number, grows the buffer by
// size class and runs again: nothing is dropped silently. Stand-alone (no common.wgsl); the twin
// is `twin::broad_tool::cull_cpu`.

// Mirrors `engine::gpu::broad_tool::CullParams` (16 bytes).
struct CullParams {
    triangles: u32,
    tools: u32,
    capacity: u32,
    row: u32,    // invocations per dispatch row (2D dispatch of large surfaces)
}

// Mirrors `collide::broad::ToolBox` (32 bytes).
struct ToolBox {
    lo: vec4<f32>,
    hi: vec4<f32>,
}

@group(0) @binding(0) var<uniform> cp: CullParams;
@group(0) @binding(1) var<storage, read> triangles: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> disp: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> boxes: array<ToolBox>;
@group(0) @binding(5) var<storage, read_write> candidates: array<vec2<u32>>;
@group(0) @binding(6) var<storage, read_write> count: atomic<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = gid.x + gid.y * cp.row;
    if (t >= cp.triangles) {
        return;
    }
    let tri = triangles[t];
    let a = rest[tri.x].xyz + disp[tri.x].xyz;
    let b = rest[tri.y].xyz + disp[tri.y].xyz;
    let c = rest[tri.z].xyz + disp[tri.z].xyz;
    let lo = min(min(a, b), c);
    let hi = max(max(a, b), c);
    for (var k = 0u; k < cp.tools; k = k + 1u) {
        let bx = boxes[k];
        if (all(lo <= bx.hi.xyz) && all(bx.lo.xyz <= hi)) {
            let slot = atomicAdd(&count, 1u);
            if (slot < cp.capacity) {
                candidates[slot] = vec2<u32>(t, k);
            }
        }
    }
}
