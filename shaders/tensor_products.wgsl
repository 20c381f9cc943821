// A tensor-mass slot's or record's 3x3 block products, shared by every tensor-mass force pass
// (the node-centric `tensor_gather.wgsl` and the edge layout's `tensor_block.wgsl`), which
// declare `p` and `blocks` (the rows of K, then of C where `p.damped` is set, at the slot's or
// record's own index, `lancet::layout::tensor_blocks`).

// Rows of blocks per slot or record.
fn block_stride() -> u32 {
    if (p.damped != 0u) {
        return 6u;
    }
    return 3u;
}

// K du + C dv; twin `TensorBlocks::force_cpu`.
fn tensor_force(b: u32, du: vec3<f32>, dv: vec3<f32>) -> vec3<f32> {
    var f = vec3<f32>(dot(blocks[b].xyz, du), dot(blocks[b + 1u].xyz, du), dot(blocks[b + 2u].xyz, du));
    if (p.damped != 0u) {
        let g = vec3<f32>(dot(blocks[b + 3u].xyz, dv), dot(blocks[b + 4u].xyz, dv), dot(blocks[b + 5u].xyz, dv));
        f = f + g;
    }
    return f;
}

// K^T du + C^T dv, the rows scaled and summed; twin `TensorBlocks::force_t_cpu`.
fn tensor_force_t(b: u32, du: vec3<f32>, dv: vec3<f32>) -> vec3<f32> {
    var f = blocks[b].xyz * du.x + blocks[b + 1u].xyz * du.y + blocks[b + 2u].xyz * du.z;
    if (p.damped != 0u) {
        let g = blocks[b + 3u].xyz * dv.x + blocks[b + 4u].xyz * dv.y + blocks[b + 5u].xyz * dv.z;
        f = f + g;
    }
    return f;
}
