//! The valence layout on the CPU: the node permutation, the per-valence tables, the memory it
//! reports, and its CPU twin (the arithmetic of `shaders/springs_valence.wgsl`) against the
//! float32 CPU engine. No GPU needed.

use crate::models;
use lancet::engine::fast::FastEngine;
use lancet::engine::{Engine, Integrator, SimConfig};
use lancet::layout::valence::ValenceLayout;
use lancet::layout::NodeOrder;
use lancet::model::{stable_time_step, PackedModel};
use lancet::physics::StepParams;
use rstest::rstest;

use models::{random_model, random_state};

fn valences(model: &PackedModel) -> Vec<u32> {
    let mut v = vec![0u32; model.node_count()];
    for s in model.springs() {
        v[s.nodes[0] as usize] += 1;
        v[s.nodes[1] as usize] += 1;
    }
    v
}

fn layout_of(model: &PackedModel) -> ValenceLayout {
    ValenceLayout::new(model, &NodeOrder::locality(model))
}

#[test]
fn the_permutation_and_its_inverse_are_inverse() {
    let model = random_model(1, false);
    let base = NodeOrder::locality(&model);
    let layout = ValenceLayout::new(&model, &base);
    let n = model.node_count();
    assert_eq!(layout.order.order.len(), n);
    assert_eq!(layout.order.rank.len(), n);
    for (new, &old) in layout.order.order.iter().enumerate() {
        assert_eq!(layout.order.rank[old as usize] as usize, new);
    }
    for (old, &new) in layout.order.rank.iter().enumerate() {
        assert_eq!(layout.order.order[new as usize] as usize, old);
    }
    // Nodes are sorted by valence, and within equal valence they keep the base (locality)
    // order.
    let v = valences(&model);
    for pair in layout.order.order.windows(2) {
        let (a, b) = (pair[0] as usize, pair[1] as usize);
        assert!(v[a] <= v[b]);
        if v[a] == v[b] {
            assert!(base.rank[a] < base.rank[b], "nodes {a} and {b} swapped");
        }
    }
}

#[test]
fn every_spring_appears_exactly_twice_across_all_buckets_with_the_right_other_end() {
    let model = random_model(2, true);
    let layout = layout_of(&model);
    let rank = &layout.order.rank;
    let mut seen = vec![0u32; model.springs().len()];
    for b in &layout.buckets {
        for local in 0..b.count {
            let i = b.first + local;
            let at = (b.offset + local * b.valence) as usize;
            let from = layout.order.order[i as usize];
            for slot in &layout.slots[at..at + b.valence as usize] {
                let to = layout.order.order[slot.other as usize];
                let key = [from.min(to), from.max(to)];
                let s = model
                    .spring_index(key[0], key[1])
                    .unwrap_or_else(|| panic!("no spring {key:?} for a slot of node {i}"));
                seen[s] += 1;
                let spring = &model.springs()[s];
                assert_eq!(rank[to as usize], slot.other);
                assert_eq!(slot.rest, spring.rest_length as f32);
                assert_eq!(slot.k, spring.stiffness as f32);
                assert_eq!(slot.c, spring.damping as f32);
                // The rest vector points from this node to the other.
                let (a, c) = (model.rest[from as usize], model.rest[to as usize]);
                for d in 0..3 {
                    assert_eq!(slot.edge[d], (c[d] - a[d]) as f32);
                }
            }
        }
    }
    assert!(
        seen.iter().all(|&c| c == 2),
        "some spring is not seen twice"
    );
}

#[test]
fn bucket_widths_equal_valences_and_buckets_cover_all_nodes_without_padding() {
    let model = random_model(3, false);
    let layout = layout_of(&model);
    let v = valences(&model);
    // Dropping springs and adding springless nodes spreads the valences.
    assert!(
        layout.buckets.len() >= 5,
        "{} buckets",
        layout.buckets.len()
    );
    assert_eq!(layout.buckets[0].valence, 0);
    assert_eq!(layout.buckets[0].count, 2);
    let (mut next_node, mut next_slot) = (0u32, 0u32);
    for pair in layout.buckets.windows(2) {
        assert!(pair[0].valence < pair[1].valence);
    }
    for b in &layout.buckets {
        assert!(b.count > 0);
        assert_eq!(b.first, next_node);
        assert_eq!(b.offset, next_slot);
        for i in b.first..b.first + b.count {
            assert_eq!(v[layout.order.order[i as usize] as usize], b.valence);
        }
        next_node += b.count;
        next_slot += b.count * b.valence;
    }
    assert_eq!(next_node as usize, model.node_count());
    assert_eq!(next_slot as usize, layout.slots.len());
    assert_eq!(layout.slots.len(), 2 * model.springs().len());
    assert!(layout.slots.iter().all(|s| s.other != u32::MAX));
    // Within a row, neighbours ascend (the order the twin and the shader sum in).
    for b in &layout.buckets {
        for local in 0..b.count {
            let at = (b.offset + local * b.valence) as usize;
            let row = &layout.slots[at..at + b.valence as usize];
            assert!(row.windows(2).all(|w| w[0].other < w[1].other));
        }
    }
    // Per-node inverse masses in layout order, 0 for fixed nodes.
    for (new, &old) in layout.order.order.iter().enumerate() {
        let old = old as usize;
        let want = if model.fixed[old] {
            0.0
        } else {
            (1.0 / model.mass[old]) as f32
        };
        assert_eq!(layout.nodes.inv_mass[new], want);
    }
}

#[rstest]
fn memory_stats_sum_to_the_buffers_they_list(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let model = random_model(4, false);
    let layout = layout_of(&model);
    let (n, m, b) = (
        model.node_count() as u64,
        model.springs().len() as u64,
        layout.buckets.len() as u64,
    );
    let (stats, per_step) = layout.memory(integrator);
    let get = |name: &str| {
        stats
            .buffers
            .iter()
            .find(|(k, _)| k.starts_with(name))
            .unwrap_or_else(|| panic!("no buffer {name} in {:?}", stats.buffers))
            .1
    };
    assert_eq!(get("slots"), 2 * m * 32);
    assert_eq!(get("inverse masses"), n * 4);
    assert_eq!(get("bucket table"), 16 + b * 16);
    assert_eq!(get("displacements"), 2 * n * 16);
    let second = match integrator {
        Integrator::Verlet => "steps",
        Integrator::SymplecticEuler | Integrator::BackwardEuler => "velocities",
    };
    assert_eq!(get(second), 2 * n * 16);
    let state = 4 * n * 16;
    let total = 2 * m * 32 + n * 4 + 16 + b * 16 + state;
    assert_eq!(stats.total, total);
    assert_eq!(
        stats.total,
        stats.buffers.iter().map(|(_, s)| s).sum::<u64>()
    );
    assert_eq!(stats.padding, 0);
    assert_eq!(stats.bytes_per_node, total as f64 / n as f64);
    assert_eq!(stats.bytes_per_spring, total as f64 / m as f64);
    // A step reads every slot, mass and the bucket table once and the state once.
    assert_eq!(per_step, 2 * m * 32 + n * 4 + 16 + b * 16 + state);
}

#[rstest]
fn the_cpu_twin_over_the_valence_layout_equals_the_fast_engine_after_many_steps(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
    #[values(false, true)] damped: bool,
) {
    let model = random_model(5, damped);
    let layout = layout_of(&model);
    let dt = 0.8 * stable_time_step(&model).dt;
    let steps = 300;
    let config = SimConfig {
        integrator,
        ..SimConfig::new(dt)
    };
    let (x0, v0) = random_state(&model, 6);
    let mut fast = FastEngine::new(&model, config);
    fast.set_state(&x0, &v0);
    fast.step(steps);
    let expected = fast.positions();

    // The twin's state: displacements and, for Verlet, the last step `h v`,
    // both rounded once from float64 as the fast engine does.
    let p = StepParams {
        h: dt as f32,
        gravity: model.gravity.map(|g| g as f32),
        alpha: model.mass_damping as f32,
        integrator,
        damped,
    };
    let h = p.h as f64;
    let mut u = vec![[0.0f32; 4]; model.node_count()];
    let mut s = vec![[0.0f32; 4]; model.node_count()];
    for (new, &old) in layout.order.order.iter().enumerate() {
        let old = old as usize;
        if model.fixed[old] {
            continue;
        }
        for c in 0..3 {
            let d = x0[old][c] - model.rest[old][c];
            u[new][c] = d as f32;
            s[new][c] = match integrator {
                Integrator::Verlet => (v0[old][c] * h) as f32,
                Integrator::SymplecticEuler | Integrator::BackwardEuler => v0[old][c] as f32,
            };
        }
    }
    let (u, _) = lancet::twin::steps(&p, (u, s), steps as usize, |p, u, s| {
        layout.step_cpu(p, u, s)
    });
    let (mut num, mut den, mut worst) = (0.0f64, 0.0f64, 0.0f64);
    for (new, &old) in layout.order.order.iter().enumerate() {
        let old = old as usize;
        for c in 0..3 {
            let twin = u[new][c] as f64;
            let want = expected[old][c] - model.rest[old][c];
            num += (twin - want).powi(2);
            den += want.powi(2);
            worst = worst.max((twin - want).abs());
        }
        if model.fixed[old] {
            assert_eq!(u[new], [0.0; 4], "fixed node {old} moved");
        }
    }
    let err = (num / den).sqrt();
    eprintln!("{integrator:?} damped={damped}: relative L2 {err:e}, worst {worst:e}");
    // Both are float32 with the same force law and integrator; they differ only in rounding
    // (the fast engine multiplies by an inverse length and sums in SIMD lanes, in its own node
    // order), measured at about 1e-7 after 300 steps: 1e-5 leaves room for other compilers
    // while staying far below the 1e-3 bar both meet against the float64 reference.
    assert!(den.sqrt() > 1e-4, "the nodes must move");
    assert!(
        err < 1e-5,
        "twin and fast engine differ: relative L2 {err:e}"
    );
}

#[test]
fn a_springless_node_falls_freely_in_the_twin() {
    let model = random_model(7, true);
    let layout = layout_of(&model);
    let p = StepParams {
        h: 1e-4,
        gravity: model.gravity.map(|g| g as f32),
        alpha: 0.0,
        integrator: Integrator::Verlet,
        damped: true,
    };
    let n = model.node_count();
    let rest = (vec![[0.0f32; 4]; n], vec![[0.0f32; 4]; n]);
    let steps = 20;
    let (u, _) = lancet::twin::steps(&p, rest, steps, |p, u, s| layout.step_cpu(p, u, s));
    // From rest, Verlet gives u_k = g h^2 k (k + 1) / 2.
    let (k, h2) = (steps as f64, (p.h as f64).powi(2));
    for old in [n - 1, n - 2] {
        let got = u[layout.order.rank[old] as usize];
        for (c, g) in model.gravity.iter().enumerate() {
            let want = g * h2 * k * (k + 1.0) / 2.0;
            assert!(
                (got[c] as f64 - want).abs() <= 1e-5 * want.abs(),
                "node {old} axis {c}: {:e} vs {want:e}",
                got[c]
            );
        }
    }
}
