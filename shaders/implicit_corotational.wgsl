// The corotational force for `implicit_solve.wgsl`'s setup, in place of the blocks' own
// (implicit_tensor_force.wgsl): the blocks hold this step's R K R^T, whose product with the
// displacements misses the rotated rest state's term, so the right-hand side takes the
// element force itself, f = -R K (R^T x - X) - beta R K R^T v per tet, which the tet pass
// (`corotational_tets.wgsl`) has just written into its corner records: each node sums its
// records in table order, as the explicit gather (`corotational_gather.wgsl`) does. The
// twin is `twin::implicit_tensor::setup_forced` with `TetTable::gather_cpu`.

// Each node's records, [start, end) in `tet_incidence`; the records (`4 t + corner`); the
// corner forces.
@group(1) @binding(1) var<storage, read> tet_rows: array<vec2<u32>>;
@group(1) @binding(2) var<storage, read> tet_incidence: array<u32>;
@group(1) @binding(3) var<storage, read> tet_forces: array<vec4<f32>>;

fn element_force(i: u32, f: vec3<f32>) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    let row = tet_rows[i];
    for (var k = row.x; k < row.y; k = k + 1u) {
        sum = sum + tet_forces[tet_incidence[k]].xyz;
    }
    return sum;
}
