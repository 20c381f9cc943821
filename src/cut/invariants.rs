//! What a cut mesh must satisfy, checked after every cut by tests and by `lancet run --check`:
//!
//! - rest volume conserved, or reduced by exactly the removed tets;
//! - every node a tet uses has a positive mass, and with `Mass::Density` each node's mass is
//!   `rho V / 4` summed over its tets (so the total is density times volume);
//! - every fragment's boundary is closed and consistently outward oriented (each directed
//!   boundary edge meets its reverse), and encloses its tet volume;
//! - the mesh is conforming: every boundary triangle is on the uncut surface or has a twin at
//!   the same rest corners (the other lip of a cut), so the triangles without a twin add up to
//!   the uncut surface's area (checked where nothing was carved);
//! - no tet is inverted or below the quality floor;
//! - copies of a fixed node are fixed;
//! - the spring model equals one built from scratch on the cut mesh (material stiffness and
//!   density parameterisations, which do not depend on how many tets share an edge or node).

use std::collections::HashMap;

use serde::Serialize;

use super::Cutter;
use crate::mesh::topology::components;
use crate::mesh::{NodeKey, TET_FACES};
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

        // Masses of the nodes tets use.
        let mut expected_mass: HashMap<NodeKey, f64> = HashMap::new();
        let density = |region: i32| match model.config().material_of(region).mass {
            Mass::Density(rho) => Some(rho),
            Mass::PerNode(_) => None,
        };
        let mut by_density = true;
        for (tk, t) in mesh.tets() {
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
        let mut mass = 0.0;
        let mut bad_mass = 0;
        for (n, _) in mesh.nodes() {
            if self.faces.tets_at(n).is_empty() {
                continue;
            }
            let m = model.mass(n).unwrap_or(0.0);
            mass += m;
            let wrong = !(m > 0.0 && m.is_finite())
                || (by_density && !close(m, expected_mass.get(&n).copied().unwrap_or(0.0)));
            if wrong {
                bad_mass += 1;
            }
        }
        if bad_mass > 0 {
            violations.push(format!(
                "{bad_mass} nodes have a mass that is not positive or not the density share of \
                 their tets"
            ));
        }

        // Fragments, their closed surfaces and enclosed volumes.
        let (of_tet, fragments) = components(mesh);
        let mut tet_volume = vec![0.0; fragments];
        let mut enclosed = vec![0.0; fragments];
        let mut half_edges: HashMap<(NodeKey, NodeKey), i64> = HashMap::new();
        for (tk, _) in mesh.tets() {
            tet_volume[of_tet[tk] as usize] += mesh.tet_volume(tk);
        }
        for (tk, local) in self.faces.boundary() {
            let t = mesh.tet(tk).expect("boundary faces belong to tets");
            let f = TET_FACES[local as usize].map(|i| t.nodes[i]);
            let [a, b, c] = f.map(|k| mesh.rest(k).coords);
            enclosed[of_tet[tk] as usize] += a.dot(&b.cross(&c)) / 6.0;
            for k in 0..3 {
                let (p, q) = (f[k], f[(k + 1) % 3]);
                // +1 for p->q, -1 for q->p, keyed by the ordered pair: a closed, consistently
                // oriented surface cancels to zero on every edge.
                if p < q {
                    *half_edges.entry((p, q)).or_insert(0) += 1;
                } else {
                    *half_edges.entry((q, p)).or_insert(0) -= 1;
                }
            }
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
        let open_edges = half_edges.values().filter(|&&c| c != 0).count();
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
            open_edges,
            worst_enclosed_volume_error: worst,
            untwinned_area,
            untwinned_area_expected,
            min_quality,
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
