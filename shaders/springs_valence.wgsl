// Valence layout: nodes grouped in buckets of equal valence, each bucket's table exactly
// `valence` slots wide (no padding). One dispatch covers every bucket: each invocation finds
// the bucket holding its node by a binary search of the bucket table (a few reads of a small
// table every invocation shares), so patches that append buckets add no dispatches.
// Prepended with common.wgsl and node_gather.wgsl; the twin is `twin::springs_valence`.

// Mirrors `lancet::layout::valence::Bucket` (16 bytes).
struct Bucket {
    valence: u32,
    first: u32,    // first node of the bucket (layout order)
    count: u32,    // nodes in the bucket
    offset: u32,   // first slot of the bucket's table
}

// The buckets in increasing `first`, after their count (a 16-byte header).
struct BucketTable {
    count: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
    buckets: array<Bucket>,
}

@group(1) @binding(0) var<storage, read> table: BucketTable;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * p.row;
    if (i >= p.n || table.count == 0u) {
        return;
    }
    // The last bucket starting at or before i: buckets[lo].first <= i < buckets[hi].first.
    var lo = 0u;
    var hi = table.count;
    loop {
        if (hi - lo <= 1u) {
            break;
        }
        let mid = (lo + hi) / 2u;
        if (table.buckets[mid].first <= i) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let b = table.buckets[lo];
    // Room at a bucket's end (and anything before the first bucket) holds no node.
    if (i < b.first || i - b.first >= b.count) {
        return;
    }
    update_node(i, b.offset + (i - b.first) * b.valence, b.valence);
}
