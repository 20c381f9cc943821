//! Random models shared by the layout and GPU tests. Included with `#[path]` so the CPU tests do
//! not pull in the GPU helpers of `common/mod.rs`.
#![allow(dead_code)] // each test file uses a different subset

use lancet::mesh::generate::BoxGrid;
use lancet::model::{
    FixedSelector, Material, ModelConfig, PackedModel, SpringDamping, SpringModel,
};

/// A small xorshift generator: reproducible random inputs without another dependency.
pub struct Rng(pub u64);
impl Rng {
    /// The next value, uniform in [0, 1).
    pub fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A box with random per-spring stiffness, damping and masses, gravity, mass damping and a
/// fixed base: every term of the force law is exercised, and corner, edge, face and inner nodes
/// differ in valence.
pub fn random_box(seed: u64, damped: bool) -> PackedModel {
    random_box_of([5, 4, 3], [0.0, 0.0, 1.0], seed, damped)
}

/// [`random_box`] on a box of `cells` of 1 cm, its nodes on the plane through the origin with
/// normal `fixed_normal` fixed.
pub fn random_box_of(
    cells: [usize; 3],
    fixed_normal: [f64; 3],
    seed: u64,
    damped: bool,
) -> PackedModel {
    let mut rng = Rng(seed);
    let mesh = BoxGrid::cube_cells(cells, 0.01).build().unwrap();
    let mut config = ModelConfig::new(Material::elastic(5e3, 0.25, 1000.0).with_damping(
        if damped {
            SpringDamping::StiffnessProportional(2e-4)
        } else {
            SpringDamping::None
        },
    ));
    config.gravity = [0.3, -0.2, -9.81];
    config.mass_damping = 3.0;
    config.fixed.push(FixedSelector::Plane {
        point: [0.0; 3],
        normal: fixed_normal,
        tolerance: 1e-9,
    });
    let mut model = SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap();
    for s in model.springs_mut().iter_mut() {
        let f = 0.5 + rng.next();
        s.stiffness *= f;
        s.damping *= f;
    }
    for m in &mut model.mass {
        *m *= 0.5 + rng.next();
    }
    model
}

/// [`random_box`] plus two springless nodes (a valence bucket of width 0).
pub fn random_model(seed: u64, damped: bool) -> PackedModel {
    let mut model = random_box(seed, damped);
    for p in [[0.05, 0.05, 0.05], [-0.02, 0.01, 0.03]] {
        model.rest.push(p);
        model.mass.push(1e-4);
        model.fixed.push(false);
        model.node_keys.push(model.node_keys[0]);
    }
    model
}

/// `model` with one spring material: every spring the mean stiffness and mean damping of
/// `model`'s, its rest length the length of its rest edge (as a scene of one spring material
/// built at rest has, and the fast engine then stores its springs' constants once).
pub fn one_material(mut model: PackedModel) -> PackedModel {
    let count = model.springs().len() as f64;
    let k = model.springs().iter().map(|s| s.stiffness).sum::<f64>() / count;
    let c = model.springs().iter().map(|s| s.damping).sum::<f64>() / count;
    let rest = model.rest.clone();
    for s in model.springs_mut().iter_mut() {
        s.stiffness = k;
        s.damping = c;
        s.rest_length = rest_length(&rest, s.nodes);
    }
    model
}

/// The distance between nodes `a` and `b` of `rest`.
pub fn rest_length(rest: &[[f64; 3]], [a, b]: [u32; 2]) -> f64 {
    let (ra, rb) = (rest[a as usize], rest[b as usize]);
    (0..3).map(|c| (rb[c] - ra[c]).powi(2)).sum::<f64>().sqrt()
}

/// A random box around a random one of the positions `x` (1-21 mm half-widths), and a box
/// holding it, grown by up to 5 mm a side: what a cut asks for and what was read ahead.
pub fn boxes_near(rng: &mut Rng, x: &[[f64; 3]]) -> ([[f64; 3]; 2], [[f64; 3]; 2]) {
    let p = x[(rng.next() * x.len() as f64) as usize];
    let half = [0, 1, 2].map(|_| 1e-3 * (1.0 + 20.0 * rng.next()));
    let lo = [0, 1, 2].map(|c| p[c] - half[c]);
    let hi = [0, 1, 2].map(|c| p[c] + half[c]);
    let grow = [0, 1, 2, 3, 4, 5].map(|_| 5e-3 * rng.next());
    let outer = [
        [0, 1, 2].map(|c| lo[c] - grow[c]),
        [0, 1, 2].map(|c| hi[c] + grow[3 + c]),
    ];
    ([lo, hi], outer)
}

/// Random displacements of about 5% of a cell and random velocities, model order, with fixed
/// nodes at rest.
pub fn random_state(model: &PackedModel, seed: u64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let mut rng = Rng(seed);
    let mut x = Vec::new();
    let mut v = Vec::new();
    for (i, r) in model.rest.iter().enumerate() {
        let mut u = [0.0; 3];
        let mut w = [0.0; 3];
        if !model.fixed[i] {
            for c in 0..3 {
                u[c] = (rng.next() - 0.5) * 1e-3;
                w[c] = (rng.next() - 0.5) * 0.1;
            }
        }
        x.push([r[0] + u[0], r[1] + u[1], r[2] + u[2]]);
        v.push(w);
    }
    (x, v)
}

/// A cut-like random change of `model`: some springs removed (as across a cut plane), a few
/// nodes split (a copy takes half the mass and some of the springs, starting from the
/// original's state), a few springs split by a node put on them (starting between their ends,
/// as subdividing does), some springs re-parameterised, a few new springs (raising valences)
/// and a node freed or fixed.
pub fn random_diff(model: &PackedModel, seed: u64) -> lancet::model::ModelDiff {
    use lancet::model::PackedSpring;
    use lancet::model::{AddedNode, ModelDiff, NodeChange, StateBlend};
    use std::collections::BTreeSet;
    let mut rng = Rng(seed ^ 0x9e37_79b9_7f4a_7c15);
    let n = model.node_count();
    let pick = |rng: &mut Rng, len: usize| ((rng.next() * len as f64) as usize).min(len - 1);
    let mut diff = ModelDiff::default();
    let mut gone: BTreeSet<[u32; 2]> = BTreeSet::new();
    for _ in 0..1 + pick(&mut rng, 6) {
        let s = model.springs()[pick(&mut rng, model.springs().len())].nodes;
        if gone.insert(s) {
            diff.removed_springs.push(s);
        }
    }
    let mut mass = model.mass.clone();
    for _ in 0..pick(&mut rng, 4) {
        let orig = pick(&mut rng, n) as u32;
        let copy = (n + diff.added_nodes.len()) as u32;
        let half = mass[orig as usize] / 2.0;
        mass[orig as usize] = half;
        diff.added_nodes.push(AddedNode {
            key: model.node_keys[orig as usize],
            rest: model.rest[orig as usize],
            mass: half,
            fixed: model.fixed[orig as usize],
            state_from: Some(orig),
            blend: None,
        });
        diff.changed_nodes.retain(|c| c.node != orig);
        diff.changed_nodes.push(NodeChange {
            node: orig,
            mass: half,
            fixed: model.fixed[orig as usize],
        });
        // Every other spring of the original moves to the copy.
        let springs: Vec<&PackedSpring> = model
            .springs()
            .iter()
            .filter(|s| s.nodes.contains(&orig) && !gone.contains(&s.nodes))
            .collect();
        for s in springs.into_iter().step_by(2) {
            let other = if s.nodes[0] == orig {
                s.nodes[1]
            } else {
                s.nodes[0]
            };
            gone.insert(s.nodes);
            diff.removed_springs.push(s.nodes);
            diff.added_springs.push(PackedSpring {
                nodes: [other.min(copy), other.max(copy)],
                ..*s
            });
        }
    }
    // Springs split by a node at parameter t along them; the node starts between the ends.
    for _ in 0..pick(&mut rng, 4) {
        let s = model.springs()[pick(&mut rng, model.springs().len())];
        if !gone.insert(s.nodes) {
            continue;
        }
        diff.removed_springs.push(s.nodes);
        let [a, b] = s.nodes;
        let (ra, rb) = (model.rest[a as usize], model.rest[b as usize]);
        let t = 0.2 + 0.6 * rng.next();
        let k = (n + diff.added_nodes.len()) as u32;
        diff.added_nodes.push(AddedNode {
            key: Default::default(),
            rest: [0, 1, 2].map(|c| ra[c] + t * (rb[c] - ra[c])),
            mass: 0.5 * (mass[a as usize] + mass[b as usize]),
            fixed: false,
            state_from: Some(a),
            blend: Some(StateBlend { with: b, t }),
        });
        for (end, share) in [(a, t), (b, 1.0 - t)] {
            diff.added_springs.push(PackedSpring {
                nodes: [end, k],
                rest_length: share * s.rest_length,
                ..s
            });
        }
    }
    for s in model.springs() {
        if !gone.contains(&s.nodes) && rng.next() < 0.03 {
            diff.changed_springs.push(PackedSpring {
                stiffness: s.stiffness * (0.5 + rng.next()),
                damping: s.damping * (0.5 + rng.next()),
                ..*s
            });
        }
    }
    // New springs from a node to nodes two hops away: valences rise past the widest row.
    for _ in 0..pick(&mut rng, 3) {
        let a = pick(&mut rng, n) as u32;
        let near: BTreeSet<u32> = model
            .springs()
            .iter()
            .filter(|s| s.nodes.contains(&a))
            .map(|s| {
                if s.nodes[0] == a {
                    s.nodes[1]
                } else {
                    s.nodes[0]
                }
            })
            .collect();
        let two: Vec<u32> = model
            .springs()
            .iter()
            .filter(|s| near.contains(&s.nodes[0]) || near.contains(&s.nodes[1]))
            .flat_map(|s| s.nodes)
            .filter(|b| *b != a && !near.contains(b))
            .collect();
        for &b in two.iter().take(1 + pick(&mut rng, 6)) {
            let key = [a.min(b), a.max(b)];
            if gone.contains(&key) || diff.added_springs.iter().any(|s| s.nodes == key) {
                continue;
            }
            let d: f64 = (0..3)
                .map(|c| (model.rest[a as usize][c] - model.rest[b as usize][c]).powi(2))
                .sum::<f64>()
                .sqrt();
            diff.added_springs.push(PackedSpring {
                nodes: key,
                rest_length: d,
                stiffness: 100.0 * (0.5 + rng.next()),
                damping: 0.01,
            });
        }
    }
    let t = pick(&mut rng, n) as u32;
    if !diff.changed_nodes.iter().any(|c| c.node == t) {
        diff.changed_nodes.push(NodeChange {
            node: t,
            mass: mass[t as usize],
            fixed: !model.fixed[t as usize],
        });
    }
    diff
}

/// The patched layout packed from scratch in the same arrangement (same node order, row width,
/// buckets and room): what a patch must equal, or step like.
pub fn fresh(
    model: &PackedModel,
    patched: &lancet::layout::PackedLayout,
) -> lancet::layout::PackedLayout {
    use lancet::layout::connectivity::ConnectivityLayout;
    use lancet::layout::edges::EdgeLayout;
    use lancet::layout::valence::ValenceLayout;
    use lancet::layout::PackedLayout;
    match patched {
        PackedLayout::Connectivity(c) => PackedLayout::Connectivity(
            ConnectivityLayout::new(model, c.order.clone(), Some(c.capacity)).unwrap(),
        ),
        PackedLayout::Valence(v) => {
            let mut fresh =
                ValenceLayout::arranged(model, v.order.clone(), v.buckets.clone(), v.room.clone())
                    .unwrap();
            fresh.packing = v.packing;
            PackedLayout::Valence(fresh)
        }
        PackedLayout::Edges(e) => PackedLayout::Edges(EdgeLayout::new(model, e.order.clone())),
    }
}

/// A diff joining node 0 to nodes it is not joined to until it has `more` springs beyond `k`.
pub fn widen_node_0(
    model: &lancet::model::PackedModel,
    k: u32,
    more: u32,
) -> lancet::model::ModelDiff {
    let mut diff = lancet::model::ModelDiff::default();
    let mut valence = model
        .springs()
        .iter()
        .filter(|s| s.nodes.contains(&0))
        .count() as u32;
    for b in 1..model.node_count() as u32 {
        if valence >= k + more {
            break;
        }
        if model.spring_index(0, b).is_none() {
            diff.added_springs.push(lancet::model::PackedSpring {
                nodes: [0, b],
                rest_length: 0.01,
                stiffness: 10.0,
                damping: 0.0,
            });
            valence += 1;
        }
    }
    assert_eq!(valence, k + more, "the model has room to widen node 0");
    diff
}

/// A diff joining model node `a` to the `k` nearest nodes it has no spring to: `a`'s valence
/// rises by `k` and each partner's by one, so rows outgrow their room (a crack front gains
/// neighbours the same way, one spring per split neighbour).
pub fn join_nearest(model: &PackedModel, a: u32, k: usize) -> lancet::model::ModelDiff {
    use lancet::model::{ModelDiff, PackedSpring};
    let dist = |b: u32| -> f64 {
        (0..3)
            .map(|c| (model.rest[a as usize][c] - model.rest[b as usize][c]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let mut others: Vec<u32> = (0..model.node_count() as u32)
        .filter(|&b| b != a && model.spring_index(a, b).is_none())
        .collect();
    others.sort_by(|&x, &y| dist(x).total_cmp(&dist(y)).then(x.cmp(&y)));
    assert!(
        others.len() >= k,
        "node {a} has only {} nodes to join",
        others.len()
    );
    let mut added: Vec<PackedSpring> = others[..k]
        .iter()
        .map(|&b| PackedSpring {
            nodes: [a.min(b), a.max(b)],
            rest_length: dist(b),
            stiffness: 50.0,
            damping: 0.01,
        })
        .collect();
    added.sort_by_key(|s| s.nodes);
    ModelDiff {
        added_springs: added,
        ..ModelDiff::default()
    }
}

/// A diff adding `n` nodes joined in a ring only to each other, each to the next `reach` nodes
/// along it (valence `2 * reach`; `n > 2 * reach`): every array a layout uploads grows with `n`
/// (rows, slots, springs, incidence), at rates set by `reach`, while no existing node's row
/// changes. Each new node starts from the state of an existing one.
pub fn floating_ring(model: &PackedModel, n: usize, reach: usize) -> lancet::model::ModelDiff {
    use lancet::model::{AddedNode, ModelDiff, PackedSpring};
    assert!(
        n > 2 * reach,
        "a ring of {n} nodes cannot join each to the next {reach}"
    );
    let before = model.node_count();
    let rest = |k: usize| {
        let r = model.rest[k % before];
        [r[0] + 0.1, r[1], r[2]]
    };
    let added_nodes = (0..n)
        .map(|k| AddedNode {
            key: model.node_keys[0],
            rest: rest(k),
            mass: 1e-4,
            fixed: false,
            state_from: Some((k % before) as u32),
            blend: None,
        })
        .collect();
    let mut added_springs: Vec<PackedSpring> = (0..n)
        .flat_map(|k| (1..=reach).map(move |j| (k, (k + j) % n)))
        .map(|(a, b)| {
            let length = (0..3)
                .map(|c| (rest(a)[c] - rest(b)[c]).powi(2))
                .sum::<f64>()
                .sqrt();
            let (a, b) = ((before + a) as u32, (before + b) as u32);
            PackedSpring {
                nodes: [a.min(b), a.max(b)],
                rest_length: length,
                stiffness: 50.0,
                damping: 0.01,
            }
        })
        .collect();
    added_springs.sort_by_key(|s| s.nodes);
    ModelDiff {
        added_nodes,
        added_springs,
        ..ModelDiff::default()
    }
}

/// `model` packed by valence as patches would leave it after a long run of cuts that changed
/// many valences: the packing's buckets (rising valences) hold the first quarter of each
/// valence's nodes, and the rest follow in buckets of one node, valences taken in turn, every
/// third of them with a hole after its node and every fifth with room for one more, so the
/// layout dispatches more buckets than its bound and its next patch regroups
/// that tail (dropping the holes and the room: the node slots shrink). Nodes keep `base` order
/// within each valence.
pub fn fragmented_valence(
    model: &PackedModel,
    base: &lancet::layout::NodeOrder,
) -> lancet::layout::valence::ValenceLayout {
    use lancet::layout::valence::{Bucket, ValenceLayout};
    use lancet::layout::NodeOrder;
    let packed = ValenceLayout::new(model, base);
    let mut head: Vec<(u32, Vec<u32>)> = Vec::new();
    let mut tail: Vec<(u32, Vec<u32>)> = Vec::new();
    for b in &packed.buckets {
        let nodes = &packed.order.order[b.first as usize..(b.first + b.count) as usize];
        let keep = nodes.len().div_ceil(4);
        head.push((b.valence, nodes[..keep].to_vec()));
        tail.push((b.valence, nodes[keep..].to_vec()));
    }
    let (mut order, mut buckets, mut room) = (Vec::new(), Vec::new(), Vec::new());
    let mut offset = 0u32;
    // A bucket of `nodes` and `holes` holes dispatched, with room for `spare` more.
    let mut push = |valence: u32, nodes: &[u32], holes: usize, spare: usize| {
        let count = nodes.len() + holes;
        buckets.push(Bucket {
            valence,
            first: order.len() as u32,
            count: count as u32,
            offset,
        });
        room.push((count + spare) as u32);
        order.extend_from_slice(nodes);
        order.extend(std::iter::repeat_n(NodeOrder::HOLE, holes + spare));
        offset += valence * (count + spare) as u32;
    };
    for (v, nodes) in &head {
        push(*v, nodes, 0, 0);
    }
    let mut piece = 0;
    while tail.iter().any(|(_, n)| !n.is_empty()) {
        for (v, nodes) in &mut tail {
            if !nodes.is_empty() {
                let rest = nodes.split_off(1);
                push(
                    *v,
                    nodes,
                    usize::from(piece % 3 == 0),
                    usize::from(piece % 5 == 0),
                );
                piece += 1;
                *nodes = rest;
            }
        }
    }
    let layout = ValenceLayout::arranged(model, NodeOrder::from_order(order), buckets, room)
        .expect("every node in a bucket of its valence");
    assert!(
        layout.dispatched_buckets() > layout.bucket_limit(),
        "{} buckets, bound {}",
        layout.dispatched_buckets(),
        layout.bucket_limit()
    );
    layout
}
