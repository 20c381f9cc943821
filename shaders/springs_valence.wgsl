// Valence layout: one dispatch per bucket of nodes with equal valence; the bucket's table is
// exactly `valence` slots wide (no padding). Prepended with common.wgsl and node_gather.wgsl.

// Mirrors `lancet::layout::valence::Bucket` (16 bytes), bound with a dynamic offset per
// dispatch.
struct Bucket {
    valence: u32,
    first: u32,    // first node of the bucket (layout order)
    count: u32,    // nodes in the bucket
    offset: u32,   // first slot of the bucket's table
}

@group(1) @binding(0) var<uniform> bucket: Bucket;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let local = gid.x + gid.y * p.row;
    if (local >= bucket.count) {
        return;
    }
    update_node(bucket.first + local, bucket.offset + local * bucket.valence, bucket.valence);
}
