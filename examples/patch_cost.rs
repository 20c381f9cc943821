//! What a planar cut costs each GPU layout: the springs crossing a plane through a box are
//! removed and the nodes on one side of it split off (a copy takes the springs on one side),
//! then the engine is patched. Prints the bytes uploaded against the layout's size, the patch
//! time, and the time to build the engine from scratch instead.
//!
//! `cargo run --release --example patch_cost [cells_per_side]`

use std::time::Instant;

use lancet::engine::gpu::{GpuContext, GpuEngine};
use lancet::engine::{DeviceEngine, Engine};
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{AddedNode, Material, ModelDiff, NodeChange, PackedModel, PackedSpring};
use lancet::{ModelConfig, SimConfig, SpringModel};

/// Cut along the plane `x = at` through the middle of a row of cells: springs crossing it are
/// removed; nodes within half a cell of it... none lie on it, so the cut only removes springs.
/// Then split the nodes on the plane `x = split` (a grid plane): each gets a copy that takes
/// its springs to the +x side.
fn cut(model: &PackedModel, split: f64) -> ModelDiff {
    let mut diff = ModelDiff::default();
    let n = model.node_count();
    let on = |i: u32| (model.rest[i as usize][0] - split).abs() < 1e-9;
    let mut copy = vec![u32::MAX; n];
    for i in 0..n as u32 {
        if on(i) && !model.fixed[i as usize] {
            copy[i as usize] = (n + diff.added_nodes.len()) as u32;
            let half = model.mass[i as usize] / 2.0;
            diff.added_nodes.push(AddedNode {
                key: model.node_keys[i as usize],
                rest: model.rest[i as usize],
                mass: half,
                fixed: false,
                state_from: Some(i),
                blend: None,
            });
            diff.changed_nodes.push(NodeChange {
                node: i,
                mass: half,
                fixed: false,
            });
        }
    }
    for s in model.springs() {
        let [a, b] = s.nodes;
        let (xa, xb) = (model.rest[a as usize][0], model.rest[b as usize][0]);
        // A spring from a split node to the +x side moves to the copy; springs lying in the
        // plane stay with the original.
        let moved = |i: u32, other_x: f64| copy[i as usize] != u32::MAX && other_x > split + 1e-9;
        let new_ends = if moved(a, xb) {
            Some([copy[a as usize], b])
        } else if moved(b, xa) {
            Some([a, copy[b as usize]])
        } else {
            None
        };
        if let Some([p, q]) = new_ends {
            diff.removed_springs.push(s.nodes);
            diff.added_springs.push(PackedSpring {
                nodes: [p.min(q), p.max(q)],
                ..*s
            });
        }
    }
    diff
}

fn main() -> lancet::Result<()> {
    let cells: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(26);
    let h = 0.01;
    let mesh = BoxGrid::cube_cells([cells; 3], h).build()?;
    let model = SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(3e4, 0.25, 1e3)))?
        .pack(&mesh)?;
    let diff = cut(&model, h * (cells / 2) as f64);
    let mut next = model.clone();
    next.apply(&diff)?;
    println!(
        "cube {cells}^3: {} nodes, {} springs; the cut splits {} nodes and moves {} springs",
        model.node_count(),
        model.springs().len(),
        diff.added_nodes.len(),
        diff.added_springs.len()
    );
    println!(
        "{:<14} {:>12} {:>12} {:>8} {:>10} {:>10} {:>12} {:>8}",
        "layout", "uploaded B", "layout B", "share", "patch ms", "moves", "rebuild ms", "buckets"
    );
    for kind in [
        LayoutKind::Connectivity,
        LayoutKind::Valence,
        LayoutKind::Edges,
    ] {
        let config = SimConfig::new(1e-5);
        let mut engine = GpuEngine::with_context(GpuContext::new()?, &model, config, kind)?;
        engine.step(10);
        engine.wait();
        let mut cpu = engine.layout().clone();
        let t = Instant::now();
        cpu.patch(&next, &diff)?;
        let cpu_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let cost = engine.patch(&next, &diff)?;
        engine.wait();
        let patch_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let mut fresh = GpuEngine::with_context(GpuContext::new()?, &next, config, kind)?;
        fresh.step(1);
        fresh.wait();
        let rebuild_ms = t.elapsed().as_secs_f64() * 1e3;
        println!(
            "{:<14} {:>12} {:>12} {:>7.1}% {:>10.2} {:>10} {:>12.2} {:>8}{}",
            format!("{kind:?}").to_lowercase(),
            cost.uploaded_bytes,
            cost.layout_bytes,
            100.0 * cost.uploaded_bytes as f64 / cost.layout_bytes as f64,
            patch_ms,
            cost.state_moves,
            rebuild_ms,
            match engine.layout() {
                lancet::layout::PackedLayout::Valence(v) => v.buckets.len().to_string(),
                _ => "-".into(),
            },
            if cost.reallocated {
                " (reallocated)"
            } else {
                ""
            }
        );
        println!("  (of which the CPU patch of the layout: {cpu_ms:.2} ms)");
    }
    Ok(())
}
