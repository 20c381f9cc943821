// The render surface from the node state: one invocation per render vertex forms its position
// as its rest position plus the weighted displacements of its four nodes (the tet that holds
// it, or the tet of its nearest boundary face for a vertex outside the mesh; see
// `surface::embed`), and writes it to a buffer a host binds as a vertex buffer (16 bytes per
// vertex, w = 1). The twin is `twin::embed_surface`: the same adds in the same order.

// Mirrors `engine::gpu::embed_surface::EmbedParams` (16 bytes).
struct EmbedParams {
    count: u32,
    row: u32,    // invocations per dispatch row (2D dispatch of large surfaces)
    _pad0: u32,
    _pad1: u32,
}

// Mirrors `twin::embed_surface::BoundVertex` (48 bytes).
struct BoundVertex {
    nodes: vec4<u32>,    // layout slots of the four nodes
    weights: vec4<f32>,
    rest: vec4<f32>,     // xyz: the vertex's rest position
}

@group(0) @binding(0) var<uniform> ep: EmbedParams;
@group(0) @binding(1) var<storage, read> disp: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> bound: array<BoundVertex>;
@group(0) @binding(3) var<storage, read_write> vertices: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * ep.row;
    if (i >= ep.count) {
        return;
    }
    let b = bound[i];
    // Displacements, not positions, are summed: a vertex at rest stays exactly at its rest
    // position, and the sum is small next to the coordinates (less float32 rounding).
    var x = b.rest.xyz;
    x = x + b.weights.x * disp[b.nodes.x].xyz;
    x = x + b.weights.y * disp[b.nodes.y].xyz;
    x = x + b.weights.z * disp[b.nodes.z].xyz;
    x = x + b.weights.w * disp[b.nodes.w].xyz;
    vertices[i] = vec4<f32>(x, 1.0);
}
