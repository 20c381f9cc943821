//! Helpers shared by the GPU tests.
#![allow(dead_code)] // each test file uses a different subset

use lancet::engine::gpu::GpuContext;

/// The GPU to test on. Without one the test prints why and is skipped, except when
/// `LANCET_REQUIRE_GPU=1` (CI, with lavapipe installed), where a missing GPU fails the test.
pub fn gpu() -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(ctx) => Some(ctx),
        Err(e) if std::env::var("LANCET_REQUIRE_GPU").as_deref() == Ok("1") => {
            panic!("LANCET_REQUIRE_GPU=1 but no GPU is usable: {e}")
        }
        Err(e) => {
            eprintln!("skipped: no GPU adapter ({e})");
            None
        }
    }
}

/// A multiply-add, a division and a square root per entry, in the arithmetic the passes use.
const ROUNDING_PROBE: &str = r"
@group(0) @binding(0) var<uniform> n: vec4<u32>;
@group(0) @binding(1) var<storage, read> input: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> output: array<vec4<f32>>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= n.x { return; }
    let v = input[i];
    output[i] = vec4<f32>(v.x * v.y + v.z, v.x / v.y, sqrt(v.w), 0.0);
}
";

/// Whether `ctx`'s float32 arithmetic rounds exactly like this CPU's: every multiply and add
/// rounded on its own (no fused multiply-add), division and square root correctly rounded.
/// Lavapipe does; real GPUs fuse multiply-adds and divide through a reciprocal, which WGSL
/// allows, so their passes differ from the CPU twins by a few ulps per step. Measured once per
/// process on random inputs chosen so that a fused multiply-add rounds differently.
pub fn rounds_like_cpu() -> bool {
    static SAME: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *SAME.get_or_init(|| {
        use lancet::engine::gpu::buffers;
        use wgpu::util::DeviceExt;
        let ctx = &gpu().expect("a GPU to probe");
        // SplitMix64: seeded, so a failure reproduces.
        let mut state = 0x05ee_d0ff_10a7_u64;
        let mut next = move || {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
        };
        let input: Vec<[f32; 4]> = (0..4096)
            .map(|_| {
                // a * b close to -c, so the product's rounding decides the sum's low bits.
                let a = 1.0 + next();
                let b = 1.0 + next();
                [a, b, -(a * b) * (1.0 + 1e-6), 1e-3 + next()]
            })
            .collect();
        let want: Vec<[f32; 4]> = input
            .iter()
            .map(|v| [v[0] * v[1] + v[2], v[0] / v[1], v[3].sqrt(), 0.0])
            .collect();
        let n = [input.len() as u32, 0, 0, 0];
        let uniform = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("rounding probe n"),
                contents: bytemuck::cast_slice(&n),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let sizing = buffers::Sizing::Exact;
        let inp =
            buffers::storage_buffer(ctx, "probe in", bytemuck::cast_slice(&input), sizing).unwrap();
        let out =
            buffers::storage_buffer(ctx, "probe out", bytemuck::cast_slice(&want), sizing).unwrap();
        let layout = buffers::pass_layout(ctx, "rounding probe", &[true, false]);
        let pipeline =
            buffers::compute_pipeline(ctx, "rounding probe", ROUNDING_PROBE, &[&layout]).unwrap();
        let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("rounding probe"),
            layout: &layout,
            entries: &buffers::entries(&[&uniform, &inp, &out]),
        });
        let groups = (input.len() as u32).div_ceil(64);
        let enc = buffers::encode_dispatch(ctx, "rounding probe", &pipeline, &group, (groups, 1));
        ctx.queue.submit([enc.finish()]);
        let got = buffers::read_vec4(ctx, &out).unwrap();
        let bits =
            |v: &[[f32; 4]]| -> Vec<[u32; 4]> { v.iter().map(|x| x.map(f32::to_bits)).collect() };
        let same = bits(&got[..want.len()]) == bits(&want);
        if !same {
            eprintln!(
                "note: {} rounds float32 differently from the CPU (fused multiply-add or \
                 approximate division); device and CPU twin are compared within a tolerance",
                ctx.describe()
            );
        }
        same
    })
}

/// The largest difference between `got` (from the device) and `want` (from its CPU twin),
/// relative to how far the twin moved from `start` (scaled by the largest magnitude instead,
/// a state far from rest would hide what its steps changed), in the first three lanes.
pub fn relative_difference(got: &[[f32; 4]], want: &[[f32; 4]], start: &[[f32; 4]]) -> f64 {
    assert_eq!(got.len(), want.len(), "as many entries");
    assert_eq!(start.len(), want.len(), "as many entries");
    let lanes = |a: &[[f32; 4]], b: &[[f32; 4]]| -> f64 {
        a.iter()
            .zip(b)
            .flat_map(|(x, y)| (0..3).map(move |c| (f64::from(x[c]) - f64::from(y[c])).abs()))
            .fold(0.0f64, f64::max)
    };
    let motion = lanes(want, start);
    let worst = lanes(got, want);
    if motion == 0.0 {
        worst
    } else {
        worst / motion
    }
}

/// Assert that `got`, from the device after `steps` steps from `start`, is what the CPU twin
/// computed (`want`): bit for bit where the device rounds like the CPU (lavapipe, CI), else
/// within 1e-5 of the twin's motion per step, the bound `tests/gpu/gpu_edges.rs` holds on an H100.
/// A spring left out still shows: `tests/gpu/twin_tolerance.rs` (1 of 504 dropped springs within
/// the bound; scaled by the largest magnitude instead, 94 under Verlet).
#[track_caller]
pub fn assert_twin(
    got: &[[f32; 4]],
    want: &[[f32; 4]],
    start: &[[f32; 4]],
    steps: usize,
    what: &str,
) {
    if rounds_like_cpu() {
        let bits =
            |v: &[[f32; 4]]| -> Vec<[u32; 4]> { v.iter().map(|x| x.map(f32::to_bits)).collect() };
        assert_eq!(bits(got), bits(want), "{what}: device and CPU twin differ");
    } else {
        let d = relative_difference(got, want, start);
        assert!(
            d <= 1e-5 * steps.max(1) as f64,
            "{what}: device and CPU twin differ by {d:e} of the twin's motion after {steps} \
             steps"
        );
    }
}
