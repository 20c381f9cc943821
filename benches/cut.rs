//! Criterion bench of one cut event: a blade drawn along the top of a box of 1 cm cells, 1 cm
//! deep, a fifth of a cell per event; each iteration is the next event of the incision (the
//! box is rebuilt, untimed, when the blade reaches its far side). Timed: reading the positions
//! near the blade from the engine, classifying and editing (the cutter), patching the engine
//! and editing its surface, as `lancet bench cut` times them. Fast CPU engine (the GPU rows
//! are in `lancet bench cut`). Boxes of 3,000, 24,000 and 104,544 tets: a local cut's cost
//! should not grow with the mesh.

use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use lancet::collide::ToolShape;
use lancet::cut::{CutMethod, Cutter, Sweep};
use lancet::engine::{EngineKind, SimConfig, Simulation};
use lancet::mesh::generate::BoxGrid;
use lancet::model::{stable_time_step, FixedSelector, Material, ModelConfig, SpringModel};
use nalgebra::Isometry3;

const H: f64 = 0.01;

struct Incision {
    cutter: Cutter,
    sim: Simulation,
    x: f64,
    n: usize,
}

impl Incision {
    fn new(n: usize, method: CutMethod) -> Self {
        let nz = (n / 2).max(2);
        let mesh = BoxGrid::cube_cells([n, n, nz], H)
            .build()
            .expect("box builds");
        let mut config = ModelConfig::new(Material::elastic(5e3, 0.3, 1000.0));
        config.fixed = vec![FixedSelector::Box {
            min: [-1.0; 3],
            max: [1.0, 1.0, 1e-9],
        }];
        let model = SpringModel::build(&mesh, &config).expect("model builds");
        let packed = model.pack(&mesh).expect("model packs");
        let dt = 0.5 * stable_time_step(&packed).dt;
        let config = SimConfig {
            allow_unstable: true,
            ..SimConfig::new(dt)
        };
        let mut sim = Simulation::new(packed, EngineKind::Fast, config).expect("engine builds");
        let cutter = Cutter::new(mesh, model, method).expect("cutter builds");
        sim.set_surface(cutter.surface()).expect("surface");
        Incision {
            cutter,
            sim,
            x: 0.5 * H,
            n,
        }
    }

    /// The next event; `None` when the blade has reached the far side.
    fn event(&mut self) -> Option<Duration> {
        if self.x > (self.n as f64 - 1.0) * H {
            return None;
        }
        let blade = ToolShape::Blade {
            width: 0.5 * H,
            length: 0.1,
            thickness: 2e-4,
        };
        let (y, z) = (
            (0.5 * self.n as f64 + 0.3) * H,
            (self.n / 2).max(2) as f64 * H - H,
        );
        let from = Isometry3::translation(self.x, y, z);
        self.x += 0.2 * H;
        let to = Isometry3::translation(self.x, y, z);
        let sweep = Sweep::of_blade(&blade, &from, &to).expect("a blade sweeps");
        self.sim.step_unchecked(1);
        self.sim.wait();
        let start = Instant::now();
        let outcome = self.cutter.cut_from(&sweep, &mut self.sim).expect("cut");
        if !outcome.is_empty() {
            let positions = self.cutter.positions_read().positions();
            self.sim
                .apply_at(&outcome.diff, true, positions)
                .expect("patch");
            self.sim.edit_surface(&outcome.surface).expect("surface");
        }
        Some(start.elapsed())
    }
}

fn cut_events(c: &mut Criterion) {
    let mut group = c.benchmark_group("cut_event");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(3));
    for n in [10usize, 20, 33] {
        for method in [CutMethod::Separate, CutMethod::Remove, CutMethod::Subdivide] {
            let mut incision = Incision::new(n, method);
            group.bench_with_input(
                BenchmarkId::new(method.to_string(), format!("box{n}")),
                &n,
                |b, &n| {
                    b.iter_custom(|iters| {
                        let mut total = Duration::ZERO;
                        for _ in 0..iters {
                            total += match incision.event() {
                                Some(t) => t,
                                None => {
                                    incision = Incision::new(n, method);
                                    incision.event().expect("a fresh box has room")
                                }
                            };
                        }
                        total
                    })
                },
            );
        }
    }
    group.finish();
}

/// Applying a small diff to the packed model (three springs removed, as a carving cut removes
/// some) at the start of its spring array and near its end. A removed spring's place takes the
/// last spring, so both cost what the diff holds; when the array was kept sorted by end pair,
/// an edit near the start moved the whole array, which grows with the mesh (4 MB at 104,544
/// tets, 14 MB at 375,000).
fn packed_apply(c: &mut Criterion) {
    let mut group = c.benchmark_group("packed_apply");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(2));
    for n in [33usize, 50] {
        let mesh = BoxGrid::cube_cells([n, n, n / 2], H)
            .build()
            .expect("box builds");
        let model = SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(5e3, 0.3, 1e3)))
            .expect("model builds");
        let packed = model.pack(&mesh).expect("model packs");
        let last = packed.springs().len() - 1;
        for (place, at) in [("start", 0), ("end", last - 40)] {
            let diff = lancet::model::ModelDiff {
                removed_springs: packed.springs()[at..at + 3]
                    .iter()
                    .map(|s| s.nodes)
                    .collect(),
                ..Default::default()
            };
            group.bench_function(
                BenchmarkId::new(place, format!("{} tets", mesh.tet_count())),
                |b| {
                    b.iter_batched(
                        || packed.clone(),
                        |mut p| {
                            p.apply(&diff).expect("the springs exist");
                            p
                        },
                        criterion::BatchSize::LargeInput,
                    )
                },
            );
        }
    }
    group.finish();
}

criterion_group!(benches, cut_events, packed_apply);
criterion_main!(benches);
