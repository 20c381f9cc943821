// The valence buckets' rows for `implicit_solve.wgsl`: node i's row is in the table of the
// bucket holding it, exactly its valence wide, found by a binary search of the bucket table as
// `springs_valence.wgsl` finds it. Holes and room hold no node: no slots (their inverse mass is
// zero, so they stay at rest like fixed nodes). The twin walks the same rows
// (`ValenceLayout::slots` by bucket).

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

@group(0) @binding(9) var<storage, read> table: BucketTable;

fn row_of(i: u32) -> Row {
    if (table.count == 0u) {
        return Row(0u, 0u);
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
        return Row(0u, 0u);
    }
    return Row(b.offset + (i - b.first) * b.valence, b.valence);
}
