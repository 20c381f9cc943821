//! Patching the fast engine in place after a cut, instead of rebuilding it: a local cut on a
//! mesh of 100,000 tets rewrites the rows of a few dozen nodes rather than re-sorting a
//! million adjacency entries.
//!
//! New nodes are appended to the internal order (they sit apart from their neighbours in
//! memory, which costs a few cache misses for a few nodes). A touched node's row is rebuilt
//! from its old row (read out of its lane of the sliced springs) and the diff, and the slices
//! of the touched rows are rewritten (`sliced.rs`): a slice that does not widen where it is,
//! one that widens appended, its old place a hole. The slices are compacted in place (slid
//! down over the holes, nothing allocated) when holes reach a quarter of them, or before a
//! widened slice would outgrow their capacity: growing a vector of megabytes copies it into
//! fresh pages, a pause of 6-35 ms at 100,000 tets, where sliding the slices costs a memmove.

use std::collections::BTreeMap;

use super::sliced::{Row, LANES};
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
    fn capacities(&self) -> Vec<(usize, usize, usize)> {
        use super::pages::Room;
        let g = &self.graph;
        let mut out = g.springs.capacities().to_vec();
        out.extend([
            g.inv_mass.room(),
            g.fixed.room(),
            self.order.room(),
            self.rank.room(),
            self.rest.room(),
            self.rest_inner.room(),
            self.x.room(),
            self.second.room(),
            self.x_next.room(),
            self.second_next.room(),
        ]);
        out
    }

    /// How the patched springs differ from `model`'s built from scratch in the same internal
    /// order: each row's springs (in row order, bit for bit) and their damping, the slices
    /// the step reads, the inverse masses and the fixed flags. Empty when they agree.
    pub(super) fn graph_differences(&self, model: &PackedModel) -> Vec<String> {
        let fresh = build_graph(model, &self.order, &self.rank);
        let bits = |(e, c): (Entry, f32)| {
            (
                e.other,
                e.edge.map(f32::to_bits),
                e.rest.to_bits(),
                e.k.to_bits(),
                c.to_bits(),
            )
        };
        let mut out = Vec::new();
        let (a, b) = (&self.graph.springs, &fresh.springs);
        let n = a.nodes();
        if n != b.nodes() {
            out.push(format!(
                "fast engine: {n} rows, a rebuild has {}",
                b.nodes()
            ));
            return out;
        }
        let row_differs =
            |i: usize| a.len(i) != b.len(i) || !a.row(i).map(bits).eq(b.row(i).map(bits));
        if let Some(i) = (0..n).find(|&i| row_differs(i)) {
            out.push(format!(
                "fast engine: the row of node {} differs from a rebuild",
                self.order[i]
            ));
        } else if let Some(s) = a.first_difference(b) {
            // Rows agree but a slice's padding or layout does not.
            out.push(format!(
                "fast engine: the step's slice {s} (nodes from internal {}) differs from a rebuild",
                s * LANES
            ));
        }
        let mass = |g: &super::Graph| g.inv_mass.iter().map(|m| m.to_bits()).collect::<Vec<_>>();
        if mass(&self.graph) != mass(&fresh) {
            out.push("fast engine: inverse masses differ from a rebuild".into());
        }
        if self.graph.fixed != fresh.fixed {
            out.push("fast engine: fixed flags differ from a rebuild".into());
        }
        out
    }

    /// Apply `diff` (already applied to `model`) to the engine's arrays, keeping the state.
    /// `None` where the engine must be rebuilt instead (the first damped spring of an undamped
    /// model needs the damping array built for every row; a spring off a uniform layout's
    /// material needs every row's constants stored).
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
        if damped_now && !self.graph.springs.damped {
            return None;
        }
        // A uniform layout takes springs of its one material only: another stiffness or
        // damping (a subdividing cut's new springs, say) needs the constants per end, which a
        // rebuild lays out for every row. Checked before anything is changed.
        let ends: Vec<(Entry, f32)> = diff
            .added_springs
            .iter()
            .chain(&diff.changed_springs)
            .map(|s| entry_of(s, 0, 0, &model.rest))
            .collect();
        if !self.graph.springs.fits(ends.iter()) {
            return None;
        }
        let n0 = self.order.len();
        // Past the layout's reach, the rebuild reports it (`check_size`).
        if n0 + diff.added_nodes.len() >= super::sliced::MAX_NODES {
            return None;
        }
        // What the arrays hold now, to report any that must grow (a copy into a new
        // allocation: the pause the room they keep is there to avoid).
        let before = self.capacities();
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
            written += 2 * p + 9;
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
        let edited = edits.len();
        let mut rows: BTreeMap<usize, Row> = BTreeMap::new();
        for (node, list) in edits {
            let i = self.rank[node as usize] as usize;
            let mut row: BTreeMap<u32, (Entry, f32)> = self
                .graph
                .springs
                .row(i)
                .map(|(e, c)| (e.other, (e, c)))
                .collect();
            for (other, edit) in list {
                let j = self.rank[other as usize];
                match edit {
                    RowEdit::Remove => {
                        row.remove(&j);
                    }
                    RowEdit::Set(s) => {
                        let end = usize::from(s.nodes[0] != node);
                        row.insert(j, entry_of(&s, end, j, &model.rest));
                    }
                }
            }
            rows.insert(i, row.into_values().collect());
        }
        self.damped = damped_now;
        // The slices of the edited rows and of the new nodes.
        let springs = &mut self.graph.springs;
        let (lanes, moved_lanes, compacted) = springs.patch(self.order.len(), rows);
        written += (lanes * springs.group_bytes() / LANES) as u64 + edited as u64 * 4;
        // What a rebuild writes: every array the engine holds (as `memory` counts them) but
        // the holes and padding.
        let stats = crate::engine::Engine::memory(self).stats;
        let layout_bytes = stats.total - stats.padding;
        // Compaction moves groups within their array (and rewrites every slice record);
        // growth copies an array whole into its new allocation.
        let springs = &self.graph.springs;
        let mut copied = (moved_lanes * springs.group_bytes() / LANES) as u64;
        if compacted {
            written += springs.slices.len() as u64 * 8;
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
    /// rows and slices equal those of springs built from the cut model in the engine's order,
    /// and the patched engine steps bit for bit like one rebuilt that way with the same state.
    /// Some patches compact the slices (in place).
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
            let capacity = engine.graph.springs.groups.capacity();
            let compacted = engine.graph.springs.compactions;
            let cost = engine
                .patch_in_place(&packed, &outcome.diff)
                .expect("patched in place");
            // A compaction moves groups within their array, reallocating nothing.
            if engine.graph.springs.compactions > compacted && cost.buffers_grown == 0 {
                assert!(cost.copied_bytes > 0, "a compaction's moves are reported");
                compactions += 1;
                assert_eq!(
                    engine.graph.springs.groups.capacity(),
                    capacity,
                    "compacted in place"
                );
            }
            if engine.graph.springs.groups.capacity() != capacity {
                assert!(cost.buffers_grown > 0, "growth is reported");
            }
            assert_eq!(engine.graph_differences(&packed), Vec::<String>::new());
            let fresh = build_graph(&packed, &engine.order, &engine.rank);
            let (a, b) = (&engine.graph.springs, &fresh.springs);
            assert_eq!(a.nodes(), b.nodes());
            for i in 0..a.nodes() {
                let bits = |(e, c): (super::Entry, f32)| {
                    (
                        e.other,
                        e.edge.map(f32::to_bits),
                        e.rest.to_bits(),
                        e.k.to_bits(),
                        c.to_bits(),
                    )
                };
                let (x, y): (Vec<_>, Vec<_>) =
                    (a.row(i).map(bits).collect(), b.row(i).map(bits).collect());
                assert_eq!(x, y, "row {i} after cut {k}");
            }
            assert_eq!(a.first_difference(b), None, "slices after cut {k}");
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
        // The check that `lancet run --check` makes sees one wrong edge.
        let sl = &mut engine.graph.springs;
        assert!(sl.len(0) > 0);
        let start = sl.slices[0][0] as usize;
        sl.groups[start].edge[0][0] += 1e-3;
        assert_eq!(engine.graph_differences(&packed).len(), 1);
    }

    /// Slices moved to the end (as widened slices are), leaving holes, then compacted: every
    /// row keeps its springs and damping bit for bit, the holes are gone, nothing is
    /// reallocated, and the engine steps exactly like one that never moved a slice.
    #[test]
    fn compaction_keeps_every_slice_in_place_of_the_holes() {
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
            let sl = &e.graph.springs;
            (0..sl.nodes())
                .map(|i| {
                    sl.row(i)
                        .map(|(x, c)| (x.other, x.k.to_bits(), c.to_bits()))
                        .collect()
                })
                .collect()
        };
        let before = rows(&moved);
        let g = &mut moved.graph.springs;
        assert!(
            g.uniform.is_none(),
            "the elastic material's stiffness varies"
        );
        g.groups.reserve(g.groups.len());
        g.material.reserve(g.material.len());
        g.damping.reserve(g.damping.len());
        for b in (0..g.slices.len()).rev().step_by(3) {
            let [s, e] = g.slices[b];
            let at = g.groups.len() as u32;
            g.groups.extend_from_within(s as usize..e as usize);
            g.material.extend_from_within(s as usize..e as usize);
            g.damping.extend_from_within(s as usize..e as usize);
            g.slices[b] = [at, at + e - s];
            g.holes += (e - s) as usize;
        }
        let (len, holes, capacity, at) = (
            g.groups.len(),
            g.holes,
            g.groups.capacity(),
            g.groups.as_ptr(),
        );
        assert!(holes > 0);
        assert!(g.compact() > 0);
        assert_eq!(g.holes, 0);
        assert_eq!(g.groups.len(), len - holes);
        assert_eq!(g.material.len(), len - holes);
        assert_eq!(g.damping.len(), len - holes);
        assert_eq!((g.groups.capacity(), g.groups.as_ptr()), (capacity, at));
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
        engine.graph.springs.groups.shrink_to_fit();
        engine.x.shrink_to_fit();
        let adj_bytes = (engine.graph.springs.groups.len()
            * std::mem::size_of::<super::super::sliced::Group>()) as u64;
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
