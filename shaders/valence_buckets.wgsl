// The valence layout's bucket table and where a node's row lies in it, shared by the explicit
// step (`springs_valence.wgsl`) and the implicit solve (`implicit_valence.wgsl`). Each includer
// declares the table's binding as `table`.

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

// Node i's row: (first slot, width = its valence, 1), found by a binary search of the bucket
// table; (0, 0, 0) for room at a bucket's end, anything before the first bucket, or no bucket
// (a node of valence 0 has a row of width 0 and is still a node).
fn valence_row(i: u32) -> vec3<u32> {
    if (table.count == 0u) {
        return vec3<u32>(0u, 0u, 0u);
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
    if (i < b.first || i - b.first >= b.count) {
        return vec3<u32>(0u, 0u, 0u);
    }
    return vec3<u32>(b.offset + (i - b.first) * b.valence, b.valence, 1u);
}
