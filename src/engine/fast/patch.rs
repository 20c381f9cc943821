//! Patching the fast engine in place after a cut, instead of rebuilding it: a local cut on a
//! mesh of 100,000 tets rewrites the rows of a few dozen nodes rather than re-sorting a
//! million adjacency entries.
//!
//! New nodes are appended to the internal order (they sit apart from their neighbours in
//! memory, which costs a few cache misses for a few nodes). A touched node's row is rebuilt
//! from its old row and the diff; a row that does not grow is rewritten where it is, one that
//! grows is appended to the adjacency and its old place becomes a hole. The adjacency is
//! compacted in place (rows slid down over the holes, nothing allocated) when holes reach a
//! quarter of it, or before a grown row would outgrow its capacity: growing a vector of
//! megabytes copies it into fresh pages, a pause of 6-35 ms at 100,000 tets, where sliding
//! the rows costs a memmove.

use std::collections::BTreeMap;

use super::{build_graph, entry_of, Entry, FastEngine, P};
use crate::engine::PatchCost;
use crate::model::{ModelDiff, PackedModel, PackedSpring};
use crate::twin::move_state::mix_state;

/// What happens to one spring at one of its ends.
enum RowEdit {
    Remove,
    Set(PackedSpring),
}

impl FastEngine {
    /// (capacity, length, bytes per entry) of every array a patch can grow.
    fn capacities(&self) -> [(usize, usize, usize); 16] {
        fn of<T>(v: &Vec<T>) -> (usize, usize, usize) {
            (v.capacity(), v.len(), std::mem::size_of::<T>())
        }
        let g = &self.graph;
        [
            of(&g.adj),
            of(&g.damping),
            of(&g.rows),
            of(&g.inv_mass),
            of(&g.fixed),
            of(&self.sliced.slices),
            of(&self.sliced.groups),
            of(&self.sliced.damping),
            of(&self.order),
            of(&self.rank),
            of(&self.rest),
            of(&self.rest_inner),
            of(&self.x),
            of(&self.second),
            of(&self.x_next),
            of(&self.second_next),
        ]
    }

    /// How the patched graph differs from `model`'s built from scratch in the same internal
    /// order: each row's springs (in row order, bit for bit), their damping, the inverse masses
    /// and the fixed flags. Empty when they agree.
    pub(super) fn graph_differences(&self, model: &PackedModel) -> Vec<String> {
        let fresh = build_graph(model, &self.order, &self.rank);
        let bits = |e: &Entry| {
            (
                e.other,
                e.edge.map(f32::to_bits),
                e.rest.to_bits(),
                e.k.to_bits(),
            )
        };
        let damping = |g: &super::Graph, i: usize| -> Vec<u32> {
            let [s, e] = g.rows[i];
            g.damping
                .get(s as usize..e as usize)
                .map_or(Vec::new(), |d| d.iter().map(|c| c.to_bits()).collect())
        };
        let mut out = Vec::new();
        let n = self.graph.rows.len();
        if n != fresh.rows.len() {
            out.push(format!(
                "fast engine: {n} rows, a rebuild has {}",
                fresh.rows.len()
            ));
            return out;
        }
        let row_differs = |i: usize| {
            let (a, b) = (self.graph.row(i), fresh.row(i));
            a.len() != b.len()
                || a.iter().zip(b).any(|(x, y)| bits(x) != bits(y))
                || damping(&self.graph, i) != damping(&fresh, i)
        };
        if let Some(i) = (0..n).find(|&i| row_differs(i)) {
            out.push(format!(
                "fast engine: the row of node {} differs from a rebuild",
                self.order[i]
            ));
        }
        let mass = |g: &super::Graph| g.inv_mass.iter().map(|m| m.to_bits()).collect::<Vec<_>>();
        if mass(&self.graph) != mass(&fresh) {
            out.push("fast engine: inverse masses differ from a rebuild".into());
        }
        if self.graph.fixed != fresh.fixed {
            out.push("fast engine: fixed flags differ from a rebuild".into());
        }
        if let Some(b) = self
            .sliced
            .first_difference(&super::sliced::Sliced::build(&fresh))
        {
            out.push(format!(
                "fast engine: the step's slice {b} (nodes from internal {}) differs from a rebuild",
                b * super::sliced::LANES
            ));
        }
        out
    }

    /// Apply `diff` (already applied to `model`) to the engine's arrays, keeping the state.
    /// `None` where the engine must be rebuilt instead (the first damped spring of an undamped
    /// model needs the damping array built for every row).
    pub(in crate::engine) fn patch_in_place(
        &mut self,
        model: &PackedModel,
        diff: &ModelDiff,
    ) -> Option<PatchCost> {
        // Springs that lose their damping leave zeros behind, which the damped kernel handles;
        // the first damped spring of an undamped model needs a damping array for every row.
        let damped_now = self.damped
            || diff
                .added_springs
                .iter()
                .chain(&diff.changed_springs)
                .any(|s| s.damping != 0.0);
        if damped_now && self.graph.damping.is_empty() {
            return None;
        }
        let n0 = self.order.len();
        // What the arrays hold now, to report any that must grow (a copy into a new
        // allocation: the pause the room they keep is there to avoid).
        let before = self.capacities();
        let entry = std::mem::size_of::<Entry>() as u64;
        let p = std::mem::size_of::<P>() as u64;
        let mut written = 0u64;

        // Nodes: appended in model order, starting with the state of the node they copy.
        for (k, a) in diff.added_nodes.iter().enumerate() {
            let m = (n0 + k) as u32;
            let i = self.order.len();
            self.order.push(m);
            self.rank.push(i as u32);
            self.rest.push(a.rest);
            self.rest_inner.push(super::rest_f32(a.rest));
            // `second` is the last step (Verlet) or the velocity (symplectic Euler): either way
            // a copy keeps its source's velocity, and a blend the blend of them (its `w`, a
            // packed rounding residual, blends into a residual of at most half an ulp).
            let (x, second) = match a.state_from {
                // A fixed node is held at rest: neighbours read its displacement.
                _ if a.fixed => ([0.0; 4], [0.0; 4]),
                Some(s) => {
                    let j = self.rank[s as usize] as usize;
                    match a.blend {
                        None => (self.x[j], self.second[j]),
                        Some(b) => {
                            let (k, t) = (self.rank[b.with as usize] as usize, b.t as f32);
                            (
                                mix_state(self.x[j], self.x[k], t),
                                mix_state(self.second[j], self.second[k], t),
                            )
                        }
                    }
                }
                None => ([0.0; 4], [0.0; 4]),
            };
            self.x.push(x);
            self.second.push(second);
            self.x_next.push([0.0; 4]);
            self.second_next.push([0.0; 4]);
            self.graph.inv_mass.push((1.0 / a.mass) as f32);
            self.graph.fixed.push(a.fixed);
            let end = self.graph.adj.len() as u32;
            self.graph.rows.push([end, end]);
            written += 2 * p + 13;
        }
        for c in &diff.changed_nodes {
            let i = self.rank[c.node as usize] as usize;
            self.graph.inv_mass[i] = (1.0 / c.mass) as f32;
            if c.fixed && !self.graph.fixed[i] {
                // Held at rest from now on, as a rebuilt engine would start it.
                self.x[i] = [0.0; 4];
                self.second[i] = [0.0; 4];
                written += 2 * p;
            }
            self.graph.fixed[i] = c.fixed;
            written += 5;
        }

        // Rows: the diff's springs by end.
        let mut edits: BTreeMap<u32, Vec<(u32, RowEdit)>> = BTreeMap::new();
        for &[a, b] in &diff.removed_springs {
            edits.entry(a).or_default().push((b, RowEdit::Remove));
            edits.entry(b).or_default().push((a, RowEdit::Remove));
        }
        for s in diff.added_springs.iter().chain(&diff.changed_springs) {
            let [a, b] = s.nodes;
            edits.entry(a).or_default().push((b, RowEdit::Set(*s)));
            edits.entry(b).or_default().push((a, RowEdit::Set(*s)));
        }
        let damped = !self.graph.damping.is_empty();
        let mut moved = 0usize;
        let edited = edits.len();
        let mut touched = Vec::with_capacity(edited);
        for (node, list) in edits {
            let i = self.rank[node as usize] as usize;
            touched.push(i);
            let mut row: BTreeMap<u32, (Entry, f32)> = {
                let [start, end] = self.graph.rows[i];
                (start as usize..end as usize)
                    .map(|e| {
                        let c = if damped { self.graph.damping[e] } else { 0.0 };
                        (self.graph.adj[e].other, (self.graph.adj[e], c))
                    })
                    .collect()
            };
            for (other, edit) in list {
                let j = self.rank[other as usize];
                match edit {
                    RowEdit::Remove => {
                        row.remove(&j);
                    }
                    RowEdit::Set(s) => {
                        let end = usize::from(s.nodes[0] != node);
                        let (e, c) = entry_of(&s, end, j, &model.rest);
                        row.insert(j, (e, c));
                    }
                }
            }
            let [start, end] = self.graph.rows[i];
            let (old_len, new_len) = ((end - start) as usize, row.len());
            let at = if new_len <= old_len {
                self.graph.holes += old_len - new_len;
                start as usize
            } else {
                self.graph.holes += old_len;
                let full = self.graph.adj.len() + new_len > self.graph.adj.capacity();
                // Compact only where that makes real room: else grow (live rows outgrew it).
                if full && self.graph.holes >= new_len.max(self.graph.adj.len() / 16) {
                    // This row's old place becomes a hole too.
                    self.graph.rows[i] = [start, start];
                    moved += self.graph.compact();
                }
                let at = self.graph.adj.len();
                let filler = Entry {
                    other: 0,
                    edge: [0.0; 3],
                    rest: 0.0,
                    k: 0.0,
                };
                self.graph.adj.resize(at + new_len, filler);
                if damped {
                    self.graph.damping.resize(at + new_len, 0.0);
                }
                at
            };
            for (slot, (e, c)) in row.into_values().enumerate() {
                self.graph.adj[at + slot] = e;
                if damped {
                    self.graph.damping[at + slot] = c;
                }
            }
            self.graph.rows[i] = [at as u32, (at + new_len) as u32];
            written += new_len as u64 * (entry + if damped { 4 } else { 0 }) + 8;
        }
        self.damped = damped_now;

        if self.graph.holes * 4 > self.graph.adj.len() {
            moved += self.graph.compact();
        }
        // The step's layout: the slices of the edited rows and of the new nodes.
        let (groups, _) = self.sliced.patch(&self.graph, touched);
        written += groups as u64 * self.sliced.group_bytes() as u64;
        // What a rebuild writes: every array the engine holds (as `memory` counts them) but
        // the holes.
        let per_entry = entry + if damped { 4 } else { 0 };
        let stats = crate::engine::Engine::memory(self).stats;
        let layout_bytes = stats.total - stats.padding;
        // Compaction moves entries within their arrays (and rewrites every row record);
        // growth copies an array whole into its new allocation.
        let mut copied = moved as u64 * per_entry;
        if moved > 0 {
            // The records of the rows not edited (the edited ones are counted above).
            written += self.graph.rows.len().saturating_sub(edited) as u64 * 8;
        }
        let after = self.capacities();
        let mut grown = 0;
        for ((cap0, len0, size), (cap1, _, _)) in before.iter().zip(&after) {
            if cap1 != cap0 {
                grown += 1;
                copied += (*len0 * *size) as u64;
            }
        }
        Some(PatchCost {
            uploaded_bytes: written,
            copied_bytes: copied,
            buffers_grown: grown,
            layout_bytes,
            state_moves: diff.added_nodes.len(),
            reallocated: false,
        })
    }
}

#[cfg(all(test, feature = "cut"))]
mod tests {
    use nalgebra::Isometry3;

    use super::super::{build_graph, FastEngine};
    use crate::collide::ToolShape;
    use crate::cut::{CutMethod, Cutter, Sweep};
    use crate::engine::{Engine, Integrator, SimConfig};
    use crate::mesh::generate::BoxGrid;
    use crate::model::{stable_time_step, Material, ModelConfig, SpringModel};

    /// Cut a damped box with `method` in several strokes; after each, the patched engine's
    /// rows equal those of a graph built from the cut model in the engine's order, and the
    /// patched engine steps bit for bit like one rebuilt that way with the same state. Some
    /// patches compact the adjacency (in place).
    fn patched_equals_rebuilt(method: CutMethod, integrator: Integrator) {
        let h = 0.01;
        let mesh = BoxGrid::cube_cells([6, 6, 3], h).build().unwrap();
        let mut material = Material::elastic(5e3, 0.3, 1000.0);
        material.damping = crate::model::SpringDamping::StiffnessProportional(1e-4);
        let mut config = ModelConfig::new(material);
        config.mass_damping = 0.5;
        config.gravity = [0.0, 0.0, -9.81];
        config.fixed = vec![crate::model::FixedSelector::Box {
            min: [-1.0; 3],
            max: [1.0, 1.0, 1e-9],
        }];
        let model = SpringModel::build(&mesh, &config).unwrap();
        let mut packed = model.pack(&mesh).unwrap();
        let mut sim_config = SimConfig::new(0.3 * stable_time_step(&packed).dt);
        sim_config.integrator = integrator;
        let mut engine = FastEngine::new(&packed, sim_config);
        let mut cutter = Cutter::new(mesh, model, method).unwrap();
        let blade = ToolShape::Blade {
            width: 0.01,
            length: 0.1,
            thickness: 2e-4,
        };
        // Drawn along x, its edge 1.5 cm deep, off the grid, in three rows: enough rows grow
        // for the holes they leave to be compacted.
        let (mut cuts, mut compactions) = (0, 0);
        for k in 0..24 {
            let pose = |x: f64| Isometry3::translation(x, 0.0117 + 0.01 * (k / 8) as f64, 0.0153);
            engine.step(20);
            let x0 = 0.0069 * (k % 8) as f64;
            let sweep = Sweep::of_blade(&blade, &pose(x0), &pose(x0 + 0.0069)).unwrap();
            let outcome = cutter.cut(&sweep, &engine.positions()).unwrap();
            if outcome.diff.is_empty() {
                continue;
            }
            cuts += 1;
            packed.apply(&outcome.diff).unwrap();
            let capacity = engine.graph.adj.capacity();
            let cost = engine
                .patch_in_place(&packed, &outcome.diff)
                .expect("patched in place");
            // A compaction moves entries within the adjacency, reallocating nothing.
            if cost.copied_bytes > 0 && cost.buffers_grown == 0 {
                compactions += 1;
                assert_eq!(engine.graph.adj.capacity(), capacity, "compacted in place");
            }
            if engine.graph.adj.capacity() != capacity {
                assert!(cost.buffers_grown > 0, "growth is reported");
            }
            assert_eq!(engine.graph_differences(&packed), Vec::<String>::new());
            let fresh = build_graph(&packed, &engine.order, &engine.rank);
            for i in 0..engine.order.len() {
                let (a, b) = (engine.graph.row(i), fresh.row(i));
                assert_eq!(a.len(), b.len(), "row {i} after cut {k}");
                for (e, f) in a.iter().zip(b) {
                    assert_eq!(
                        (
                            e.other,
                            e.edge.map(f32::to_bits),
                            e.rest.to_bits(),
                            e.k.to_bits()
                        ),
                        (
                            f.other,
                            f.edge.map(f32::to_bits),
                            f.rest.to_bits(),
                            f.k.to_bits()
                        ),
                        "row {i} after cut {k}"
                    );
                }
                let [s, _] = engine.graph.rows[i];
                let [t, _] = fresh.rows[i];
                for l in 0..a.len() {
                    assert_eq!(
                        engine.graph.damping[s as usize + l].to_bits(),
                        fresh.damping[t as usize + l].to_bits()
                    );
                }
            }
            assert_eq!(engine.graph.inv_mass, fresh.inv_mass);
            assert_eq!(engine.graph.fixed, fresh.fixed);
            // Same state in a rebuilt graph: the next steps agree bit for bit.
            let mut rebuilt = FastEngine::new(&packed, sim_config);
            rebuilt.graph = fresh;
            rebuilt.order = engine.order.clone();
            rebuilt.rank = engine.rank.clone();
            rebuilt.x = engine.x.clone();
            rebuilt.second = engine.second.clone();
            engine.step(15);
            rebuilt.step(15);
            assert_eq!(engine.positions(), rebuilt.positions(), "after cut {k}");
        }
        assert!(cuts >= 3, "the blade cut {cuts} times");
        // Carving only shrinks rows (rewritten in place); the other methods grow some.
        if method != CutMethod::Remove {
            assert!(compactions >= 1, "{cuts} cuts compacted nothing");
        }
        // The check that `lancet run --check` makes sees one wrong stiffness.
        let [start, _] = engine.graph.rows[0];
        engine.graph.adj[start as usize].k *= 1.5;
        assert_eq!(engine.graph_differences(&packed).len(), 1);
    }

    /// Rows moved to the end (as grown rows are), leaving holes, then compacted: every row
    /// keeps its springs and damping bit for bit, the holes are gone, nothing is reallocated,
    /// and the engine steps exactly like one that never moved a row.
    #[test]
    fn compaction_keeps_every_row_in_place_of_the_holes() {
        let mesh = BoxGrid::cube_cells([5, 4, 3], 0.01).build().unwrap();
        let mut material = Material::elastic(5e3, 0.3, 1000.0);
        material.damping = crate::model::SpringDamping::StiffnessProportional(1e-4);
        let mut config = ModelConfig::new(material);
        config.gravity = [0.0, 0.0, -9.81];
        config.fixed = vec![crate::model::FixedSelector::Box {
            min: [-1.0; 3],
            max: [1.0, 1.0, 1e-9],
        }];
        let packed = SpringModel::build(&mesh, &config)
            .unwrap()
            .pack(&mesh)
            .unwrap();
        let sim_config = SimConfig::new(0.3 * stable_time_step(&packed).dt);
        let mut moved = FastEngine::new(&packed, sim_config);
        let mut still = FastEngine::new(&packed, sim_config);
        let rows = |e: &FastEngine| -> Vec<Vec<(u32, u32, u32)>> {
            (0..e.graph.rows.len())
                .map(|i| {
                    let [s, _] = e.graph.rows[i];
                    e.graph
                        .row(i)
                        .iter()
                        .enumerate()
                        .map(|(l, x)| {
                            (
                                x.other,
                                x.k.to_bits(),
                                e.graph.damping[s as usize + l].to_bits(),
                            )
                        })
                        .collect()
                })
                .collect()
        };
        let before = rows(&moved);
        let g = &mut moved.graph;
        g.adj.reserve(g.adj.len());
        g.damping.reserve(g.damping.len());
        for i in (0..g.rows.len()).rev().step_by(3) {
            let [s, e] = g.rows[i];
            let at = g.adj.len() as u32;
            g.adj.extend_from_within(s as usize..e as usize);
            g.damping.extend_from_within(s as usize..e as usize);
            g.rows[i] = [at, at + e - s];
            g.holes += (e - s) as usize;
        }
        let (len, holes, capacity, at) = (g.adj.len(), g.holes, g.adj.capacity(), g.adj.as_ptr());
        assert!(holes > 0);
        assert!(g.compact() > 0);
        assert_eq!(g.holes, 0);
        assert_eq!(g.adj.len(), len - holes);
        assert_eq!(g.damping.len(), len - holes);
        assert_eq!((g.adj.capacity(), g.adj.as_ptr()), (capacity, at));
        assert_eq!(g.compact(), 0, "nothing left to slide");
        assert_eq!(rows(&moved), before);
        moved.step(40);
        still.step(40);
        assert_eq!(moved.positions(), still.positions());
    }

    /// A patch that must grow arrays with no room left says so: which grew and the bytes
    /// their growth copied, beside what it wrote.
    #[test]
    fn a_patch_that_grows_arrays_reports_it() {
        let h = 0.01;
        let mesh = BoxGrid::cube_cells([4, 4, 2], h).build().unwrap();
        let model =
            SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(5e3, 0.3, 1e3))).unwrap();
        let mut packed = model.pack(&mesh).unwrap();
        let config = SimConfig::new(0.3 * stable_time_step(&packed).dt);
        let mut engine = FastEngine::new(&packed, config);
        let mut cutter = Cutter::new(mesh, model, CutMethod::Subdivide).unwrap();
        let blade = ToolShape::Blade {
            width: 0.05,
            length: 0.1,
            thickness: 2e-4,
        };
        let pose = |z: f64| Isometry3::translation(0.02, 0.0213, z);
        let sweep = Sweep::of_blade(&blade, &pose(0.025), &pose(0.003)).unwrap();
        let outcome = cutter.cut(&sweep, &engine.positions()).unwrap();
        assert!(!outcome.diff.added_nodes.is_empty());
        packed.apply(&outcome.diff).unwrap();
        // No room anywhere.
        engine.graph.adj.shrink_to_fit();
        engine.x.shrink_to_fit();
        let adj_bytes = (engine.graph.adj.len() * std::mem::size_of::<super::Entry>()) as u64;
        let cost = engine.patch_in_place(&packed, &outcome.diff).unwrap();
        assert!(cost.buffers_grown >= 2, "{cost:?}");
        assert!(cost.copied_bytes >= adj_bytes, "{cost:?}");
        assert_eq!(engine.graph_differences(&packed), Vec::<String>::new());
        // With room again, the next cut grows nothing.
        let sweep = Sweep::of_blade(&blade, &pose(0.003), &pose(0.001)).unwrap();
        let outcome = cutter.cut(&sweep, &engine.positions()).unwrap();
        if !outcome.diff.is_empty() {
            packed.apply(&outcome.diff).unwrap();
            let cost = engine.patch_in_place(&packed, &outcome.diff).unwrap();
            assert_eq!(cost.buffers_grown, 0, "{cost:?}");
        }
    }

    #[test]
    fn separating_patch_equals_a_rebuild() {
        patched_equals_rebuilt(CutMethod::Separate, Integrator::Verlet);
    }

    #[test]
    fn subdividing_patch_equals_a_rebuild() {
        patched_equals_rebuilt(CutMethod::Subdivide, Integrator::SymplecticEuler);
    }

    #[test]
    fn carving_patch_equals_a_rebuild() {
        patched_equals_rebuilt(CutMethod::Remove, Integrator::Verlet);
    }
}
