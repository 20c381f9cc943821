// The valence buckets' rows for `implicit_solve.wgsl`: node i's row is in the table of the
// bucket holding it, exactly its valence wide, found by `valence_row` (`valence_buckets.wgsl`).
// Holes and room hold no node: no slots (their inverse mass is zero, so they stay at rest like
// fixed nodes). The twin walks the same rows
// (`ValenceLayout::slots` by bucket).

@group(0) @binding(9) var<storage, read> table: BucketTable;

fn row_of(i: u32) -> Row {
    let row = valence_row(i);
    return Row(row.x, row.y);
}
