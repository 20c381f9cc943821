//! Criterion benches of the GPU engine in each spring layout over generated cubes, throughput
//! in springs per step. Each sample records its steps into one submission and waits for the
//! device inside the timed region (submitting alone returns before the work is done). Without
//! an adapter the benches print why and do nothing.

use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use lancet::engine::gpu::{GpuContext, GpuEngine};
use lancet::engine::{DeviceEngine, Engine, GpuOptions, SimConfig};
use lancet::layout::edges::Accumulation;
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::model::stable_time_step;
use lancet::report::bench::bench_model;

/// Steps per submission at most: long command buffers are fine, but a sample of millions of
/// steps would hold one submission for minutes on lavapipe.
const MAX_STEPS_PER_SUBMIT: u64 = 1000;

fn gpu_layouts(c: &mut Criterion) {
    if let Err(e) = GpuContext::new() {
        eprintln!("skipped the GPU layout benches: {e}");
        return;
    }
    let mut group = c.benchmark_group("gpu_step");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(5));
    let variants = [
        (
            "connectivity",
            LayoutKind::Connectivity,
            Accumulation::Gather,
        ),
        ("valence", LayoutKind::Valence, Accumulation::Gather),
        ("edges", LayoutKind::Edges, Accumulation::Gather),
        (
            "edges-atomic-fixed",
            LayoutKind::Edges,
            Accumulation::AtomicFixed,
        ),
        // Skipped with the reason on adapters without float atomics.
        (
            "edges-atomic-float",
            LayoutKind::Edges,
            Accumulation::AtomicFloat,
        ),
    ];
    for n in [10usize, 26] {
        let mesh = BoxGrid::cube_cells([n; 3], 0.01)
            .build()
            .expect("cube builds");
        let model = bench_model(&mesh).expect("model builds");
        let dt = 0.9 * stable_time_step(&model).dt;
        group.throughput(Throughput::Elements(model.springs().len() as u64));
        for (name, layout, accumulation) in variants {
            let config = SimConfig::new(dt);
            let options = GpuOptions {
                layout,
                accumulation,
            };
            let ctx = match GpuContext::new() {
                Ok(ctx) => ctx,
                Err(e) => {
                    eprintln!("skipped {name} on cube {n}: {e}");
                    continue;
                }
            };
            let mut engine = match GpuEngine::with_context(ctx, &model, config, options) {
                Ok(engine) => engine,
                Err(e) => {
                    eprintln!("skipped {name} on cube {n}: {e}");
                    continue;
                }
            };
            // Warm-up outside criterion's own: the first dispatch compiles the shaders.
            engine.step(10);
            engine.wait();
            group.bench_with_input(BenchmarkId::new(name, format!("cube{n}")), &n, |b, _| {
                b.iter_custom(|iters| {
                    let start = Instant::now();
                    let mut left = iters;
                    while left > 0 {
                        let steps = left.min(MAX_STEPS_PER_SUBMIT);
                        engine.step(steps as u32);
                        left -= steps;
                    }
                    // Submission returns at once; the steps are done only once the device
                    // is idle, so the wait belongs to the timed region.
                    engine.wait();
                    start.elapsed()
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, gpu_layouts);
criterion_main!(benches);
