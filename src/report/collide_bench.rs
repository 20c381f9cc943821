//! `lancet bench collide`: the broad phases against surface size and tool count. Per surface
//! (a thin slab, so that the boundary is large for its volume): the tool broad phase on the GPU
//! and its CPU twin, with the culling ratio (candidates over all triangle-tool pairs), and the
//! self-contact broad phase on the GPU and its CPU twin. Times are medians over repeated runs
//! and include the readback of the candidates (the latency a haptic loop sees).

use std::time::Instant;

use serde::Serialize;

use nalgebra::{Isometry3, Point3};

use crate::collide::broad::{Surface, ToolBox};
use crate::collide::narrow::tool_triangle;
use crate::collide::self_broad::GridParams;
use crate::collide::{Tool, ToolShape};
use crate::contact::response::{resolve_contacts, ContactSettings};
use crate::engine::gpu::{GpuContext, GpuEngine};
use crate::engine::{DeviceEngine, Engine, EngineKind, SimConfig, Simulation};
use crate::error::Result;
use crate::layout::LayoutKind;
use crate::mesh::generate::BoxGrid;
use crate::model::{Material, ModelConfig, PackedModel, SpringModel};
use crate::twin::broad_self::self_pairs_cpu;
use crate::twin::broad_tool::cull_cpu;

/// One row: a surface size and a tool count.
#[derive(Debug, Clone, Serialize)]
pub struct CollideRow {
    /// Boundary triangles.
    pub triangles: usize,
    /// Tools culled against.
    pub tools: usize,
    /// Median wall time of the GPU tool broad phase, readback included, ms.
    pub gpu_tool_ms: f64,
    /// Median wall time of its CPU twin (one thread), ms.
    pub cpu_tool_ms: f64,
    /// Median wall time of the baseline: parry's own BVH over the triangle boxes, every leaf
    /// updated and the tree refitted, then queried with each tool box (one thread), ms.
    pub bvh_tool_ms: f64,
    /// Mean candidates per cull.
    pub candidates: f64,
    /// Candidates over all triangle-tool pairs.
    pub culling_ratio: f64,
    /// Median wall time of the GPU self-contact broad phase, readback included, ms.
    pub gpu_self_ms: f64,
    /// Median wall time of its CPU twin (one thread), ms.
    pub cpu_self_ms: f64,
    /// Self-contact pairs found (margin 0.5 mm, at rest).
    pub self_pairs: usize,
    /// Median narrow-phase time per candidate (parry, tool against triangle), µs.
    pub narrow_us_per_candidate: f64,
    /// Median end-to-end latency from a tool pose to its force (broad phase, readback of the
    /// candidates' nodes, narrow phase, position correction) on the GPU engine, ms.
    pub gpu_pose_to_force_ms: f64,
    /// The same on the fast CPU engine, ms.
    pub cpu_pose_to_force_ms: f64,
}

/// A benchmark surface: a thin slab of `cells x cells x 1` cells of 2 mm (so that the boundary
/// is large for its volume), its model and its boundary.
pub struct Slab {
    /// Cells along x and y.
    pub cells: usize,
    /// The spring model (soft tissue, no gravity, nothing fixed).
    pub model: PackedModel,
    /// Its boundary triangles.
    pub surface: Surface,
}

impl Slab {
    /// The slab with about `triangles` boundary triangles (about `4 n^2` for `n x n` cells).
    pub fn with_triangles(triangles: usize) -> Result<Self> {
        let n = ((triangles as f64 / 4.0).sqrt().ceil() as usize).max(2);
        let mesh = BoxGrid::cube_cells([n, n, 1], 0.002).build()?;
        let model = SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(5e3, 0.3, 1e3)))?
            .pack(&mesh)?;
        Ok(Slab {
            cells: n,
            model,
            surface: Surface::of(&mesh),
        })
    }

    /// `k` tool boxes of 2 mm half-size at spread-out surface points of positions `x` (a
    /// probe's contact region).
    pub fn tool_boxes(&self, x: &[[f64; 3]], k: usize) -> Vec<ToolBox> {
        let tris = &self.surface.triangles;
        (0..k)
            .map(|i| {
                let t = tris[(i * 7919 + 13) % tris.len()];
                let p = x[t[0] as usize];
                ToolBox::containing(p.map(|c| c - 2e-3), p.map(|c| c + 2e-3))
            })
            .collect()
    }

    /// A 3 mm sphere pressed 0.5 mm into the slab's top, over its centre.
    pub fn pressed_probe(&self) -> Result<Tool> {
        let centre = 0.5 * self.cells as f64 * 0.002;
        Tool::new(
            ToolShape::Sphere { radius: 3e-3 },
            Isometry3::translation(centre, centre, 0.002 + 2.5e-3),
        )
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Run the collision broad-phase benchmark on slabs of about `triangles` boundary triangles,
/// with each tool count in `tools`, `repeats` timed runs each.
pub fn run(
    triangles: &[usize],
    tools: &[usize],
    repeats: usize,
) -> Result<(String, Vec<CollideRow>)> {
    let mut rows = Vec::new();
    let mut device = String::new();
    for &want in triangles {
        let slab = Slab::with_triangles(want)?;
        let (model, surface) = (&slab.model, &slab.surface);
        let ctx = GpuContext::new()?;
        device = ctx.describe();
        let mut engine =
            GpuEngine::with_context(ctx, model, SimConfig::new(1e-5), LayoutKind::Connectivity)?;
        engine.set_surface(&surface.triangles)?;
        engine.step(1);
        engine.wait();
        let (disp, _) = engine.raw_state()?;
        let rest = engine.rest_f32();
        let tris = engine.surface_layout_order().unwrap_or_default();
        let x = engine.positions();
        for &k in tools {
            // Tools of 2 mm half-size at spread-out surface points: a probe's contact region.
            let boxes = slab.tool_boxes(&x, k);
            let (mut gpu, mut cpu, mut found) = (Vec::new(), Vec::new(), 0usize);
            engine.cull_tools(&boxes)?; // warm-up: pipeline compilation
            for _ in 0..repeats {
                let t = Instant::now();
                found += engine.cull_tools(&boxes)?.candidates.len();
                gpu.push(t.elapsed().as_secs_f64() * 1e3);
                let t = Instant::now();
                std::hint::black_box(cull_cpu(&rest, &disp, &tris, &boxes));
                cpu.push(t.elapsed().as_secs_f64() * 1e3);
            }
            // Baseline: parry's BVH, refitted to the current boxes and queried, as a CPU
            // simulator without a GPU broad phase would do every step.
            let leaf_boxes: Vec<parry3d::bounding_volume::Aabb> = tris
                .iter()
                .map(|&t| {
                    let p = t.map(|i| {
                        let (r, u) = (rest[i as usize], disp[i as usize]);
                        parry3d::math::Vector::new(r[0] + u[0], r[1] + u[1], r[2] + u[2])
                    });
                    parry3d::bounding_volume::Aabb::new(
                        p[0].min(p[1]).min(p[2]),
                        p[0].max(p[1]).max(p[2]),
                    )
                })
                .collect();
            let mut bvh = parry3d::partitioning::Bvh::from_leaves(Default::default(), &leaf_boxes);
            let mut workspace = parry3d::partitioning::BvhWorkspace::default();
            let queries: Vec<parry3d::bounding_volume::Aabb> = boxes
                .iter()
                .map(|b| {
                    parry3d::bounding_volume::Aabb::new(
                        parry3d::math::Vector::new(b.lo[0], b.lo[1], b.lo[2]),
                        parry3d::math::Vector::new(b.hi[0], b.hi[1], b.hi[2]),
                    )
                })
                .collect();
            let mut bvh_times = Vec::new();
            for _ in 0..repeats {
                let t = Instant::now();
                for (i, aabb) in leaf_boxes.iter().enumerate() {
                    bvh.insert_or_update_partially(*aabb, i as u32, 0.0);
                }
                bvh.refit(&mut workspace);
                let mut hits = 0usize;
                for q in &queries {
                    hits += bvh.intersect_aabb(q).count();
                }
                std::hint::black_box(hits);
                bvh_times.push(t.elapsed().as_secs_f64() * 1e3);
            }
            let margin = 5e-4;
            let grid = GridParams::for_surface(&model.rest, &surface.triangles, margin);
            engine.cull_self(margin)?; // warm-up
            let (mut gpu_self, mut cpu_self, mut pairs) = (Vec::new(), Vec::new(), 0);
            for _ in 0..repeats {
                let t = Instant::now();
                pairs = engine.cull_self(margin)?.pairs.len();
                gpu_self.push(t.elapsed().as_secs_f64() * 1e3);
                let t = Instant::now();
                std::hint::black_box(self_pairs_cpu(&grid, &rest, &disp, &tris));
                cpu_self.push(t.elapsed().as_secs_f64() * 1e3);
            }
            // A 3 mm sphere pressed 0.5 mm into the slab's top: time the narrow phase per
            // candidate and the whole response, from pose to force.
            let probe = slab.pressed_probe()?;
            let b = probe.step_bounds(1e-5);
            let probe_box = [ToolBox::containing(
                b.min.coords.into(),
                b.max.coords.into(),
            )];
            let near = cull_cpu(&rest, &disp, &tris, &probe_box);
            let corners: Vec<[Point3<f64>; 3]> = near
                .iter()
                .map(|c| surface.triangles[c[0] as usize].map(|i| Point3::from(x[i as usize])))
                .collect();
            let mut narrow = Vec::new();
            for _ in 0..repeats {
                let t = Instant::now();
                for tri in &corners {
                    std::hint::black_box(tool_triangle(&probe.shape, probe.pose(), tri, 1e-5)?);
                }
                narrow.push(t.elapsed().as_secs_f64() * 1e6 / corners.len().max(1) as f64);
            }
            let pose_to_force = |kind: EngineKind| -> Result<f64> {
                let mut sim = Simulation::new(model.clone(), kind, SimConfig::new(1e-5))?;
                sim.set_surface(surface.triangles.clone())?;
                let settings = ContactSettings::default();
                resolve_contacts(&mut sim, std::slice::from_ref(&probe), &settings)?;
                let mut times = Vec::new();
                for _ in 0..repeats {
                    let t = Instant::now();
                    resolve_contacts(&mut sim, std::slice::from_ref(&probe), &settings)?;
                    times.push(t.elapsed().as_secs_f64() * 1e3);
                }
                Ok(median(times))
            };
            let candidates = found as f64 / repeats as f64;
            rows.push(CollideRow {
                triangles: surface.triangles.len(),
                tools: k,
                gpu_tool_ms: median(gpu),
                cpu_tool_ms: median(cpu),
                bvh_tool_ms: median(bvh_times),
                candidates,
                culling_ratio: candidates / (surface.triangles.len() * k) as f64,
                gpu_self_ms: median(gpu_self),
                cpu_self_ms: median(cpu_self),
                self_pairs: pairs,
                narrow_us_per_candidate: median(narrow),
                gpu_pose_to_force_ms: pose_to_force(EngineKind::Gpu)?,
                cpu_pose_to_force_ms: pose_to_force(EngineKind::Fast)?,
            });
        }
    }
    Ok((device, rows))
}
