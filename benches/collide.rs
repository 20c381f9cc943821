//! Criterion benches of collision on the slabs of `lancet bench collide`
//! (`lancet::report::collide_bench::Slab`): the tool broad phase on the GPU and its CPU twin at
//! 10k and 50k boundary triangles with 1 and 3 tools (throughput: boundary triangles culled),
//! parry's narrow phase per candidate (tool against triangle, and triangle against triangle for
//! self-contact), and the end-to-end latency from a tool pose to its force on the fast CPU and
//! GPU engines (throughput: boundary triangles). GPU timings include the readback, which waits
//! for the device. Without an adapter the GPU benches print why and are skipped.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use lancet::collide::broad::ToolBox;
use lancet::collide::narrow::tool_triangle;
use lancet::collide::self_narrow::triangle_triangle;
use lancet::contact::response::{resolve_contacts, ContactSettings};
use lancet::engine::gpu::{GpuContext, GpuEngine};
use lancet::engine::{DeviceEngine, Engine, EngineKind, SimConfig, Simulation};
use lancet::layout::LayoutKind;
use lancet::report::collide_bench::Slab;
use lancet::twin::broad_tool::cull_cpu;
use nalgebra::Point3;

/// A triangle's corners, m.
type Tri = [Point3<f64>; 3];

const SIZES: [usize; 2] = [10_000, 50_000];
const TOOLS: [usize; 2] = [1, 3];

fn gpu_engine(slab: &Slab) -> Option<GpuEngine> {
    let made = GpuContext::new().and_then(|ctx| {
        let mut e = GpuEngine::with_context(
            ctx,
            &slab.model,
            SimConfig::new(1e-5),
            LayoutKind::Connectivity,
        )?;
        e.set_surface(&slab.surface.triangles)?;
        e.step(1);
        e.wait();
        Ok(e)
    });
    match made {
        Ok(e) => Some(e),
        Err(e) => {
            eprintln!("skipped the GPU collision benches: {e}");
            None
        }
    }
}

fn cull_tools(c: &mut Criterion) {
    let mut group = c.benchmark_group("cull_tools");
    group.sample_size(20);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(3));
    for want in SIZES {
        let slab = Slab::with_triangles(want).expect("slab builds");
        let triangles = slab.surface.triangles.len();
        group.throughput(Throughput::Elements(triangles as u64));
        let x = slab.model.rest.clone();
        let mut gpu = gpu_engine(&slab);
        // The twin's inputs, as the device holds them (a GPU-less run uses the rest shape).
        let (rest, disp, tris) = match &gpu {
            Some(e) => (
                e.rest_f32(),
                e.raw_state().expect("state reads back").0,
                e.surface_layout_order().unwrap_or_default(),
            ),
            None => (
                x.iter()
                    .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32, 0.0])
                    .collect(),
                vec![[0.0f32; 4]; x.len()],
                slab.surface.triangles.clone(),
            ),
        };
        for tools in TOOLS {
            let boxes: Vec<ToolBox> = slab.tool_boxes(&x, tools);
            let id = format!("{triangles}tri/{tools}tool");
            group.bench_function(BenchmarkId::new("cpu_twin", &id), |b| {
                b.iter(|| cull_cpu(&rest, &disp, &tris, &boxes))
            });
            if let Some(e) = gpu.as_mut() {
                e.cull_tools(&boxes).expect("culls"); // compiles the pipeline
                group.bench_function(BenchmarkId::new("gpu", &id), |b| {
                    b.iter(|| e.cull_tools(&boxes).expect("culls"))
                });
            }
        }
    }
    group.finish();
}

fn narrow(c: &mut Criterion) {
    let mut group = c.benchmark_group("narrow");
    group.sample_size(20);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(3));
    let slab = Slab::with_triangles(SIZES[0]).expect("slab builds");
    let x: Vec<Point3<f64>> = slab.model.rest.iter().map(|&p| p.into()).collect();
    let probe = slab.pressed_probe().expect("probe");
    let b = probe.step_bounds(1e-5);
    let probe_box = [ToolBox::containing(
        b.min.coords.into(),
        b.max.coords.into(),
    )];
    let f4: Vec<[f32; 4]> = slab
        .model
        .rest
        .iter()
        .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32, 0.0])
        .collect();
    let zero = vec![[0.0f32; 4]; f4.len()];
    let near = cull_cpu(&f4, &zero, &slab.surface.triangles, &probe_box);
    let corners: Vec<Tri> = near
        .iter()
        .map(|c| slab.surface.triangles[c[0] as usize].map(|i| x[i as usize]))
        .collect();
    group.throughput(Throughput::Elements(corners.len() as u64));
    group.bench_function(
        BenchmarkId::new("tool_triangle", format!("{}cand", corners.len())),
        |b| {
            b.iter(|| {
                for t in &corners {
                    std::hint::black_box(
                        tool_triangle(&probe.shape, probe.pose(), t, 1e-5).unwrap(),
                    );
                }
            })
        },
    );
    // Self-contact: each candidate against the triangle 0.3 mm above it, turned a little.
    let pairs: Vec<(Tri, Tri)> = corners
        .iter()
        .map(|t| {
            let r = nalgebra::Rotation3::from_euler_angles(0.1, -0.2, 0.3);
            let c = nalgebra::center(&t[0], &t[1]);
            let u = t.map(|p| c + r * (p - c) + nalgebra::Vector3::new(0.0, 0.0, 3e-4));
            (*t, u)
        })
        .collect();
    group.bench_function(
        BenchmarkId::new("triangle_triangle", format!("{}cand", pairs.len())),
        |b| {
            b.iter(|| {
                for (t, u) in &pairs {
                    std::hint::black_box(triangle_triangle(t, u, 1e-3).unwrap());
                }
            })
        },
    );
    group.finish();
}

fn pose_to_force(c: &mut Criterion) {
    let mut group = c.benchmark_group("pose_to_force");
    group.sample_size(20);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(3));
    for want in SIZES {
        let slab = Slab::with_triangles(want).expect("slab builds");
        let triangles = slab.surface.triangles.len();
        group.throughput(Throughput::Elements(triangles as u64));
        let probe = slab.pressed_probe().expect("probe");
        for kind in [EngineKind::Fast, EngineKind::Gpu] {
            let mut sim = match Simulation::new(slab.model.clone(), kind, SimConfig::new(1e-5)) {
                Ok(sim) => sim,
                Err(e) => {
                    eprintln!("skipped pose_to_force on {kind}: {e}");
                    continue;
                }
            };
            sim.set_surface(slab.surface.triangles.clone())
                .expect("surface");
            let settings = ContactSettings::default();
            let tools = std::slice::from_ref(&probe);
            resolve_contacts(&mut sim, tools, &settings).expect("resolves"); // warm-up
            group.bench_function(
                BenchmarkId::new(kind.to_string(), format!("{triangles}tri")),
                |b| b.iter(|| resolve_contacts(&mut sim, tools, &settings).expect("resolves")),
            );
        }
    }
    group.finish();
}

criterion_group!(benches, cull_tools, narrow, pose_to_force);
criterion_main!(benches);
