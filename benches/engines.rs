//! Criterion benches of the CPU engines over generated cubes, throughput in springs per step
//! (the same matrix as `lancet bench`, with criterion's statistics).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use lancet::engine::{EngineKind, SimConfig, Simulation};
use lancet::mesh::generate::BoxGrid;
use lancet::model::stable_time_step;
use lancet::report::bench::bench_model;

fn engines(c: &mut Criterion) {
    let mut group = c.benchmark_group("step");
    group.sample_size(20);
    for n in [10usize, 26] {
        let mesh = BoxGrid::cube_cells([n; 3], 0.01)
            .build()
            .expect("cube builds");
        let model = bench_model(&mesh).expect("model builds");
        let dt = 0.9 * stable_time_step(&model).dt;
        group.throughput(Throughput::Elements(model.springs().len() as u64));
        for kind in [EngineKind::Reference, EngineKind::Fast] {
            let mut sim =
                Simulation::new(model.clone(), kind, SimConfig::new(dt)).expect("stable dt");
            group.bench_with_input(
                BenchmarkId::new(kind.to_string(), format!("cube{n}")),
                &n,
                |b, _| b.iter(|| sim.step_unchecked(1)),
            );
        }
    }
    group.finish();
}

criterion_group!(benches, engines);
criterion_main!(benches);
