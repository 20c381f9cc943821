//! What a cut mesh must satisfy, checked after every cut by tests and by `lancet run --check`:
//!
//! - rest volume conserved, or reduced by exactly the removed tets;
//! - every node a tet uses has a positive mass, the sum of what its tets give it, and with
//!   `Mass::Density` each node's mass is `rho V / 4` summed over its tets (so the total is
//!   density times volume); whatever the mass model, the total mass is the mass before cutting
//!   less what carving removed (a cut that splits or separates tets conserves mass);
//! - every fragment's boundary is closed and consistently outward oriented (each directed
//!   boundary edge meets its reverse), and encloses its tet volume;
//! - the mesh is conforming: every boundary triangle is on the uncut surface or has a twin at
//!   the same rest corners (the other lip of a cut), so the triangles without a twin add up to
//!   the uncut surface's area (checked where nothing was carved);
//! - no tet is inverted or below the quality floor;
//! - copies of a fixed node are fixed;
//! - the springs are exactly the tet edges: none joins two nodes that no tet joins (a spring
//!   across a completed cut), and no tet edge lacks one, whatever the stiffness model;
//! - the spring model equals one built from scratch on the cut mesh (material stiffness and
//!   density parameterisations, which do not depend on how many tets share an edge or node).

use std::collections::{HashMap, HashSet};

use serde::Serialize;

use super::Cutter;
use crate::mesh::topology::components;
use crate::mesh::{NodeKey, TET_EDGES, TET_FACES};
use crate::model::{Mass, SpringModel, Stiffness};

/// Relative tolerance of the volume and mass comparisons (sums in different orders).
const REL: f64 = 1e-9;

/// The measures behind the invariants, and what failed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InvariantReport {
    /// Connected pieces of the mesh.
    pub fragments: usize,
    /// Total rest volume now, m^3.
    pub volume: f64,
    /// What it must be: the volume before cutting minus what carving removed.
    pub volume_expected: f64,
    /// Total mass of the nodes tets use, kg.
    pub mass: f64,
    /// What it must be: the mass before cutting minus what carving removed.
    pub mass_expected: f64,
    /// Boundary edges without a matching reverse edge (0 for closed surfaces).
    pub open_edges: usize,
    /// Largest relative difference between a fragment's enclosed volume and its tet volume.
    pub worst_enclosed_volume_error: f64,
    /// Rest area of the boundary triangles with no twin at the same rest corners (the cut's
    /// two lips are twins), m^2; with nothing carved it is the uncut surface's.
    pub untwinned_area: f64,
    /// The uncut surface's rest area, m^2, where nothing was carved (`None` after carving,
    /// which exposes new surface).
    pub untwinned_area_expected: Option<f64>,
    /// Smallest volume-length ratio of any tet (1 regular, 0 flat, negative inverted).
    pub min_quality: f64,
    /// Springs between two nodes that no tet joins (across a completed cut, or left behind by
    /// a removed tet).
    pub springs_off_tet_edges: usize,
    /// Tet edges with no spring.
    pub tet_edges_without_spring: usize,
    /// Springs whose parameters differ from a model rebuilt from scratch (`None` where the
    /// parameterisation depends on incidence counts, so a rebuild differs by design).
    pub springs_differing_from_rebuild: Option<usize>,
    /// What failed, in words; empty when every invariant holds.
    pub violations: Vec<String>,
}

impl InvariantReport {
    /// Whether every invariant holds.
    pub fn passed(&self) -> bool {
        self.violations.is_empty()
    }
}

/// An end pair in ascending order.
fn ordered(a: NodeKey, b: NodeKey) -> (NodeKey, NodeKey) {
    (a.min(b), a.max(b))
}

/// Edges of `triangles` not matched by the same edge the other way round: 0 for surfaces
/// that are closed and consistently oriented. Each directed edge p->q counts +1 on the pair and
/// q->p counts -1, so a closed, consistently oriented surface cancels on every edge.
fn unmatched_edges(triangles: &[[NodeKey; 3]]) -> usize {
    let mut half_edges: HashMap<(NodeKey, NodeKey), i64> = HashMap::new();
    for f in triangles {
        for k in 0..3 {
            let (p, q) = (f[k], f[(k + 1) % 3]);
            *half_edges.entry(ordered(p, q)).or_insert(0) += if p < q { 1 } else { -1 };
        }
    }
    half_edges.values().filter(|&&c| c != 0).count()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= REL * a.abs().max(b.abs()).max(f64::MIN_POSITIVE)
}

impl Cutter {
    /// Check the invariants. `volume_before` is the rest volume before any cut; `quality_floor`
    /// the smallest volume-length ratio allowed.
    pub fn check_invariants(&self, volume_before: f64, quality_floor: f64) -> InvariantReport {
        let mesh = &self.mesh;
        let model = &self.model;
        let mut violations = Vec::new();

        let volume = mesh.volume();
        let volume_expected = volume_before - self.volume_removed;
        if !close(volume, volume_expected) {
            violations.push(format!(
                "rest volume {volume:e} m^3, expected {volume_expected:e} m^3"
            ));
        }

        // Masses of the nodes tets use: what their tets give them (the shares a cut moves,
        // removes and adds), and with a density, that density's share of their volume.
        let mut expected_mass: HashMap<NodeKey, f64> = HashMap::new();
        let mut given: HashMap<NodeKey, f64> = HashMap::new();
        let density = |region: i32| match model.config().material_of(region).mass {
            Mass::Density(rho) => Some(rho),
            Mass::PerNode(_) => None,
        };
        let mut by_density = true;
        let mut unshared = 0;
        for (tk, t) in mesh.tets() {
            match model.share(tk) {
                Some(share) => {
                    for (&n, m) in t.nodes.iter().zip(share.mass) {
                        *given.entry(n).or_insert(0.0) += m;
                    }
                }
                None => unshared += 1,
            }
            match density(t.region) {
                Some(rho) => {
                    let share = rho * mesh.tet_volume(tk) / 4.0;
                    for &n in &t.nodes {
                        *expected_mass.entry(n).or_insert(0.0) += share;
                    }
                }
                None => by_density = false,
            }
        }
        if unshared > 0 {
            violations.push(format!("{unshared} tets have no share in the spring model"));
        }
        let mut mass = 0.0;
        let mut bad_mass = 0;
        for (n, _) in mesh.nodes() {
            if self.faces.tets_at(n).is_empty() {
                continue;
            }
            let m = model.mass(n).unwrap_or(0.0);
            mass += m;
            let positive = m > 0.0 && m.is_finite();
            let as_given = close(m, given.get(&n).copied().unwrap_or(0.0));
            let as_density = !by_density || close(m, expected_mass.get(&n).copied().unwrap_or(0.0));
            let wrong = !(positive && as_given && as_density);
            if wrong {
                bad_mass += 1;
            }
        }
        if bad_mass > 0 {
            violations.push(format!(
                "{bad_mass} nodes have a mass that is not positive, not what their tets give \
                 them, or not the density share of their tets"
            ));
        }
        let mass_expected = self.mass_before - self.mass_removed;
        if !close(mass, mass_expected) {
            violations.push(format!(
                "total mass {mass:e} kg, expected {mass_expected:e} kg (the mass before cutting \
                 less what carving removed)"
            ));
        }

        // Fragments, their closed surfaces and enclosed volumes.
        let (of_tet, fragments) = components(mesh);
        let mut tet_volume = vec![0.0; fragments];
        let mut enclosed = vec![0.0; fragments];
        for (tk, _) in mesh.tets() {
            tet_volume[of_tet[tk] as usize] += mesh.tet_volume(tk);
        }
        let mut triangles = Vec::with_capacity(self.faces.boundary_len());
        for (tk, local) in self.faces.boundary() {
            let t = mesh.tet(tk).expect("boundary faces belong to tets");
            let f = TET_FACES[local as usize].map(|i| t.nodes[i]);
            let [a, b, c] = f.map(|k| mesh.rest(k).coords);
            enclosed[of_tet[tk] as usize] += a.dot(&b.cross(&c)) / 6.0;
            triangles.push(f);
        }
        // Faces split differently on their two sides leave triangles inside the tissue that
        // close up with each other (so the checks above pass) but have no twin.
        let mut twins: HashMap<[[u64; 3]; 3], usize> = HashMap::new();
        let mut areas: Vec<([[u64; 3]; 3], f64)> = Vec::with_capacity(self.faces.boundary_len());
        for (tk, local) in self.faces.boundary() {
            let t = mesh.tet(tk).expect("boundary faces belong to tets");
            let p = TET_FACES[local as usize].map(|i| mesh.rest(t.nodes[i]));
            let mut key = p.map(|x| [x.x, x.y, x.z].map(f64::to_bits));
            key.sort_unstable();
            *twins.entry(key).or_insert(0) += 1;
            areas.push((key, 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm()));
        }
        let untwinned_area: f64 = areas
            .iter()
            .filter(|(k, _)| twins[k] == 1)
            .map(|(_, a)| a)
            .sum();
        let untwinned_area_expected = (self.volume_removed == 0.0).then_some(self.surface_area);
        if let Some(expected) = untwinned_area_expected {
            if !close(untwinned_area, expected) {
                violations.push(format!(
                    "the boundary triangles without a twin cover {untwinned_area:e} m^2, not the \
                     uncut surface's {expected:e} m^2: a face is split differently on its two \
                     sides (the mesh is not conforming)"
                ));
            }
        }
        let open_edges = unmatched_edges(&triangles);
        if open_edges > 0 {
            violations.push(format!(
                "{open_edges} boundary edges are not matched by a reverse edge: a fragment \
                 surface is open or inconsistently oriented"
            ));
        }
        let mut worst = 0.0f64;
        for (v, e) in tet_volume.iter().zip(&enclosed) {
            worst = worst.max((v - e).abs() / v.abs().max(f64::MIN_POSITIVE));
        }
        if worst > 1e-8 {
            violations.push(format!(
                "a fragment's surface encloses a volume {worst:e} (relative) away from its tets'"
            ));
        }

        // Copies sit at the rest position of the node they copy and must share its fixed flag.
        let mut fixed_at: HashMap<[u64; 3], bool> = HashMap::new();
        let mut fixed_mismatch = 0;
        for (n, node) in mesh.nodes() {
            if self.faces.tets_at(n).is_empty() {
                continue;
            }
            let key = [node.rest.x, node.rest.y, node.rest.z].map(f64::to_bits);
            let f = model.is_fixed(n);
            if *fixed_at.entry(key).or_insert(f) != f {
                fixed_mismatch += 1;
            }
        }
        if fixed_mismatch > 0 {
            violations.push(format!(
                "{fixed_mismatch} copies of nodes do not share the fixed flag of the node they copy"
            ));
        }

        // Springs are the tet edges, so no spring crosses a cut: checked on the structure
        // alone, where the rebuild comparison below needs a stiffness model it can rebuild.
        let mut edges: HashSet<(NodeKey, NodeKey)> = HashSet::new();
        for (_, t) in mesh.tets() {
            for [i, j] in TET_EDGES {
                edges.insert(ordered(t.nodes[i], t.nodes[j]));
            }
        }
        let springs_off_tet_edges = model
            .springs()
            .filter(|(_, s)| !edges.contains(&ordered(s.nodes[0], s.nodes[1])))
            .count();
        let tet_edges_without_spring = edges
            .iter()
            .filter(|&&(a, b)| model.spring_between(a, b).is_none())
            .count();
        if springs_off_tet_edges > 0 {
            violations.push(format!(
                "{springs_off_tet_edges} springs join nodes that no tet joins (a spring across a \
                 cut)"
            ));
        }
        if tet_edges_without_spring > 0 {
            violations.push(format!(
                "{tet_edges_without_spring} tet edges have no spring"
            ));
        }

        let min_quality = mesh.min_volume_length_ratio();
        if mesh.tet_count() > 0 && !(min_quality > 0.0 && min_quality >= quality_floor) {
            violations.push(format!(
                "a tet has volume-length ratio {min_quality:.3e}, below the floor \
                 {quality_floor:.3e} (or inverted)"
            ));
        }

        let springs_differing_from_rebuild = self.compare_with_rebuild();
        if let Some(n) = springs_differing_from_rebuild.filter(|&n| n > 0) {
            violations.push(format!(
                "{n} springs differ from a model rebuilt from scratch on the cut mesh"
            ));
        }

        InvariantReport {
            fragments,
            volume,
            volume_expected,
            mass,
            mass_expected,
            open_edges,
            worst_enclosed_volume_error: worst,
            untwinned_area,
            untwinned_area_expected,
            min_quality,
            springs_off_tet_edges,
            tet_edges_without_spring,
            springs_differing_from_rebuild,
            violations,
        }
    }

    /// Springs whose presence or parameters differ from a model built from scratch, where the
    /// parameterisation allows the comparison.
    fn compare_with_rebuild(&self) -> Option<usize> {
        let config = self.model.config();
        let materials = std::iter::once(&config.material).chain(config.regions.values());
        let comparable = materials.clone().all(|m| {
            matches!(m.stiffness, Stiffness::Material { .. })
                && !matches!(m.damping, crate::model::SpringDamping::Absolute(_))
        });
        if !comparable {
            return None;
        }
        // A rebuild needs every node used; retired nodes are left out of the comparison.
        let mut mesh = self.mesh.clone();
        mesh.remove_unused_nodes();
        let fresh = SpringModel::build(&mesh, config).ok()?;
        let mut differing = 0;
        for (_, s) in self.model.springs() {
            match fresh.spring_between(s.nodes[0], s.nodes[1]) {
                Some(f)
                    if close(f.rest_length, s.rest_length)
                        && close(f.stiffness, s.stiffness)
                        && (f.damping == s.damping || close(f.damping, s.damping)) => {}
                _ => differing += 1,
            }
        }
        differing += fresh
            .spring_count()
            .saturating_sub(self.model.spring_count());
        Some(differing)
    }
}

#[cfg(test)]
mod tests {
    //! Each invariant reports a state that breaks it: a checker that flags nothing would pass
    //! every test that cuts correctly.

    use nalgebra::{Isometry3, Point3};

    use super::*;
    use crate::collide::ToolShape;
    use crate::cut::{CutMethod, Sweep};
    use crate::mesh::generate::BoxGrid;
    use crate::mesh::TetMesh;
    use crate::model::{FixedSelector, Material, ModelConfig};

    const H: f64 = 0.01;

    fn config() -> ModelConfig {
        ModelConfig::new(Material::elastic(3e3, 0.3, 1000.0))
    }

    /// A 3-cell box split in two along faces by an upright blade at y = 1.7 cells, its volume
    /// and the box before the cut.
    fn cut_box() -> (Cutter, f64, TetMesh) {
        cut_box_of(&config())
    }

    /// [`cut_box`] on a model of `config`.
    fn cut_box_of(config: &ModelConfig) -> (Cutter, f64, TetMesh) {
        let mesh = BoxGrid::cube_cells([3, 3, 3], H).build().unwrap();
        let volume = mesh.volume();
        let model = SpringModel::build(&mesh, config).unwrap();
        let mut cutter = Cutter::new(mesh.clone(), model, CutMethod::Separate).unwrap();
        let blade = ToolShape::Blade {
            width: 0.1,
            length: 0.1,
            thickness: 1e-4,
        };
        let at = |z: f64| Isometry3::translation(0.015, 1.7 * H, z);
        let sweep = Sweep::of_blade(&blade, &at(0.05), &at(-0.01)).unwrap();
        let rest: Vec<[f64; 3]> = cutter
            .mesh()
            .nodes()
            .map(|(_, n)| n.rest.coords.into())
            .collect();
        cutter.cut(&sweep, &rest).unwrap();
        (cutter, volume, mesh)
    }

    fn violated(report: &InvariantReport, what: &str) -> bool {
        report.violations.iter().any(|v| v.contains(what))
    }

    #[test]
    fn a_correct_cut_passes() {
        let (cutter, volume, _) = cut_box();
        let report = cutter.check_invariants(volume, 0.0);
        assert!(report.passed(), "{:?}", report.violations);
        assert_eq!(report.fragments, 2);
        assert_eq!(report.springs_off_tet_edges, 0);
        assert_eq!(report.tet_edges_without_spring, 0);
    }

    #[test]
    fn lost_volume_is_reported() {
        let (mut cutter, volume, _) = cut_box();
        cutter.volume_removed += 1e-3 * volume;
        assert!(violated(
            &cutter.check_invariants(volume, 0.0),
            "rest volume"
        ));
    }

    #[test]
    fn a_tet_without_its_share_of_mass_and_springs_is_reported() {
        let (mut cutter, volume, _) = cut_box();
        let (tk, _) = cutter.mesh.tets().next().unwrap();
        cutter.model.remove_tet(&cutter.mesh, tk).unwrap();
        let report = cutter.check_invariants(volume, 0.0);
        assert!(violated(&report, "mass"), "{:?}", report.violations);
        assert!(violated(&report, "differ from a model rebuilt"));
    }

    /// The cut box on a model with a mass per node (which tets share unequally: the box's
    /// nodes are held by different numbers of tets).
    fn per_node_cut_box() -> (Cutter, f64) {
        let mut config = config();
        config.material.mass = Mass::PerNode(0.01);
        let (cutter, volume, _) = cut_box_of(&config);
        (cutter, volume)
    }

    #[test]
    fn mass_made_or_lost_is_reported_whatever_the_mass_model() {
        let (mut cutter, volume) = per_node_cut_box();
        assert!(cutter.check_invariants(volume, 0.0).passed());
        cutter.mass_before *= 1.001;
        let report = cutter.check_invariants(volume, 0.0);
        assert!(violated(&report, "total mass"), "{:?}", report.violations);
    }

    #[test]
    fn a_share_of_mass_moved_to_the_wrong_node_is_reported() {
        // A tet's share for one corner moved to another corner's node and back the other way:
        // the total stays, each node's mass is no longer what its tets give it.
        let (mut cutter, volume) = per_node_cut_box();
        let (tk, t) = cutter
            .mesh
            .tets()
            .find(|(tk, _)| {
                let m = cutter.model.share(*tk).unwrap().mass;
                m[0] != m[1]
            })
            .map(|(tk, t)| (tk, *t))
            .expect("corners with unequal shares");
        let mut swapped = t.nodes;
        swapped.swap(0, 1);
        cutter.model.renode_tet(tk, t.nodes, swapped).unwrap();
        let report = cutter.check_invariants(volume, 0.0);
        assert!(
            violated(&report, "not what their tets give them"),
            "{:?}",
            report.violations
        );
        assert!(!violated(&report, "total mass"), "{:?}", report.violations);
    }

    #[test]
    fn springs_across_the_cut_are_reported_whatever_the_stiffness_model() {
        // The model of the uncut box keeps the springs the cut removed: its original nodes
        // keep their keys, so those springs join nodes on the two lips.
        let (mut cutter, volume, uncut) = cut_box();
        let mut config = config();
        // Stiffness per spring: no rebuild comparison is possible, the structure check stays.
        config.material.stiffness = crate::model::Stiffness::Spring(10.0);
        cutter.model = SpringModel::build(&uncut, &config).unwrap();
        let report = cutter.check_invariants(volume, 0.0);
        assert_eq!(report.springs_differing_from_rebuild, None);
        assert!(report.springs_off_tet_edges > 0, "{report:?}");
        assert!(report.tet_edges_without_spring > 0, "the copies have none");
        assert!(violated(&report, "across a cut"));
    }

    #[test]
    fn a_surface_around_a_tet_the_index_lost_does_not_enclose_its_tets() {
        let (mut cutter, volume, _) = cut_box();
        let (tk, _) = cutter.mesh.tets().next().unwrap();
        cutter.faces.remove(tk);
        let report = cutter.check_invariants(volume, 0.0);
        assert!(report.worst_enclosed_volume_error > 1e-3, "{report:?}");
        assert!(violated(&report, "encloses a volume"));
    }

    #[test]
    fn untwinned_area_other_than_the_uncut_surfaces_is_reported() {
        let (mut cutter, volume, _) = cut_box();
        cutter.surface_area *= 1.01;
        assert!(violated(
            &cutter.check_invariants(volume, 0.0),
            "not conforming"
        ));
    }

    #[test]
    fn tets_below_the_floor_are_reported() {
        let (cutter, volume, _) = cut_box();
        // The box's tets are far from regular.
        assert!(violated(
            &cutter.check_invariants(volume, 0.99),
            "below the floor"
        ));
    }

    #[test]
    fn open_or_misoriented_surfaces_have_unmatched_edges() {
        let mut mesh = TetMesh::new();
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ]
        .map(|c| mesh.add_node(Point3::from(c)));
        let tet = mesh.add_tet(p, 0).unwrap();
        let t = mesh.tet(tet).unwrap();
        let faces: Vec<[NodeKey; 3]> = TET_FACES.iter().map(|f| f.map(|i| t.nodes[i])).collect();
        assert_eq!(unmatched_edges(&faces), 0);
        assert_eq!(unmatched_edges(&faces[..3]), 3, "one face missing");
        let mut flipped = faces.clone();
        flipped[0].swap(1, 2);
        assert_eq!(unmatched_edges(&flipped), 3, "one face turned inward");
    }

    #[test]
    fn a_copy_that_lost_its_fixed_flag_is_reported() {
        // Two tets already apart at a shared face position: tet 0 (region 1, fixed) uses
        // nodes 1-3, tet 1 (region 2) their copies 5-7 at the same rest positions.
        let points = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let (mesh, _) =
            TetMesh::from_arrays(&points, &[[0, 1, 2, 3], [4, 7, 6, 5]], Some(&[1, 2])).unwrap();
        let mut config = config();
        config.fixed.push(FixedSelector::Region(1));
        let model = SpringModel::build(&mesh, &config).unwrap();
        let volume = mesh.volume();
        let cutter = Cutter::new(mesh, model, CutMethod::Separate).unwrap();
        let report = cutter.check_invariants(volume, 0.0);
        assert!(violated(&report, "3 copies"), "{:?}", report.violations);
    }
}
