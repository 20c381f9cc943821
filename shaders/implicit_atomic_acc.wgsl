// The float accumulators of the edge layout's float-atomic implicit solve, shared by the
// springs' (implicit_atomic.wgsl) and the finite elements' (implicit_atomic_tensor.wgsl)
// record passes.

// Sixteen accumulators per node slot: f (0..3), K v (3..6), iso (6), da (7..11), db (11..13);
// the product reuses 0..3 once the setup has read them.
@group(0) @binding(9) var<storage, read_write> terms_acc: array<atomic<f32>>;

const TERMS: u32 = 16u;

fn acc_add(i: u32, k: u32, x: f32) {
    atomicAdd(&terms_acc[TERMS * i + k], x);
}

fn acc_take(i: u32, k: u32) -> f32 {
    let x = atomicLoad(&terms_acc[TERMS * i + k]);
    atomicStore(&terms_acc[TERMS * i + k], 0.0);
    return x;
}

