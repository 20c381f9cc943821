// The connectivity table's rows for `implicit_solve.wgsl`: node i's row is row i, `width`
// slots, continuing in overflow rows. The twin walks `ConnectivityLayout::row`.

fn row_of(i: u32) -> Row {
    return Row(i * q.width, q.width);
}
