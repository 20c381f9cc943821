// The tensor-mass force for `implicit_solve.wgsl`'s setup: the blocks' own, as node_terms
// summed it (f = -K u - C v, exact for the linear model). The corotational solve puts
// implicit_corotational.wgsl here instead.

fn element_force(i: u32, f: vec3<f32>) -> vec3<f32> {
    return f;
}
