// The fixed point of the edge layout's integer accumulators, shared by the passes that use
// them (the springs' `accumulate_fixed.wgsl`, the tensors' `tensor_accumulate_fixed.wgsl`, the
// node pass `integrate_fixed.wgsl`); the twin is `lancet::layout::edges::FixedPoint::quantize`.

// Mirrors `lancet::layout::edges::FixedPoint` (16 bytes).
struct FixedPoint {
    scale: f32,       // units per newton, a power of two
    inv_scale: f32,
    limit: f32,       // largest |quantized component| of one force, a power of two
    pad: u32,
}

// A force in units of `unit`, clamped to its limit, and whether the clamp changed it.
struct Quantized {
    q: vec3<i32>,
    saturated: bool,
}

fn quantize(f: vec3<f32>, unit: FixedPoint) -> Quantized {
    let q = round(f * unit.scale);
    let c = clamp(q, vec3<f32>(-unit.limit), vec3<f32>(unit.limit));
    return Quantized(vec3<i32>(c), any(c != q));
}
