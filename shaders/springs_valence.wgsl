// Valence layout: nodes grouped in buckets of equal valence, each bucket's table exactly
// `valence` slots wide (no padding). One dispatch covers every bucket: each invocation finds
// the bucket holding its node by a binary search of the bucket table (a few reads of a small
// table every invocation shares), so patches that append buckets add no dispatches.
// Prepended with common.wgsl, node_gather.wgsl and valence_buckets.wgsl; the twin is `twin::springs_valence`.

@group(1) @binding(0) var<storage, read> table: BucketTable;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * p.row;
    if (i >= p.n || table.count == 0u) {
        return;
    }
    let row = valence_row(i);
    // Room at a bucket's end (and anything before the first bucket) holds no node.
    if (row.z == 0u) {
        return;
    }
    update_node(i, row.x, row.y);
}
