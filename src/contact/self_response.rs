//! Self-contact response between steps: surfaces of the tissue that come closer than a
//! thickness, or have passed a little into each other (a fold, a cut closing, two lobes), are
//! pushed apart by equal and opposite position corrections.
//!
//! # Why not the triangle–triangle depth
//!
//! [`crate::collide::self_narrow::triangle_triangle`] gives parry's signed distance between two surface
//! triangles, right to a nanometre separated or intersecting (`tests/contact/collide_self_narrow.rs`;
//! EPA was not degenerate on any of the measured pairs, nearly coplanar ones included). But
//! once two triangles cross, their depth is that of the Minkowski difference of two flat
//! triangles, which is the wrong quantity for two solids: it has no inside or outside (a
//! triangle more than half way through another is separated fastest by pushing it on through,
//! deeper into the other body), it is bounded by how far each triangle reaches across the
//! other's plane rather than by how deep one body is in the other, and its direction jumps
//! between the two normals and the edge-edge directions as the pair moves, so neighbouring
//! pairs push against each other. So, as cloth and shell
//! codes do (Bridson, Fedkiw and Anderson, "Robust treatment of collisions, contact and
//! friction for cloth animation", 2002), the response works on proximity of the primitives,
//! in float64, with a thickness: each node against each triangle of the other surface, and each
//! edge against each edge. Unlike cloth, the tissue is a solid with an outward oriented
//! surface, which gives the sides: a node is pushed out along the outward normal of the
//! triangle it faces, whether it is in front of it by less than the thickness or behind it
//! (inside the other body) by less than [`SelfContactSettings::max_depth`]. A primitive pair
//! counts only when the two surfaces face each other (their outward normals at least
//! `acos(-FACING)` apart), which keeps the triangles around a convex edge of one body (close,
//! sharing no node, one behind the other's plane) from pushing each other. An edge pair counts
//! only when the edges are well away from parallel and their common normal lies near the
//! direction the surfaces face each other in: for nearly parallel edges of two nearly parallel
//! surfaces the common normal is ill-conditioned and may lie along the surfaces, which pushed
//! whole layers sideways by up to `max_depth` per step and blew up the first version of the
//! drop test; the nodes' contacts hold such pairs apart.
//!
//! # The correction
//!
//! Each contact is a constraint `C = gap - thickness >= 0` on its four nodes (a node and the
//! three corners of a triangle with the barycentric weights of its projection, or two edges
//! with the parameters of their closest points), with the gap measured along a fixed unit
//! direction `n`. It is enforced as in position-based dynamics: `lambda = -C / sum w_i^2 / m_i`
//! and node `i` moves by `w_i lambda n / m_i`, with weights of opposite signs on the two sides
//! summing to zero. So every contact moves the mass-weighted sum of its nodes by nothing: the
//! correction carries no linear momentum. A fixed node has no inverse mass: it never moves and
//! the other side takes the whole correction. Contacts are resolved one after the other
//! (Gauss–Seidel, in a fixed order) for a few sweeps, so that each keeps the momentum balance
//! exactly; a node shared by several contacts takes each in turn.

use nalgebra::{Point3, Vector3};

use crate::collide::self_narrow::{edge_edge, point_triangle};
use crate::engine::Simulation;
use crate::error::{Error, Result};

type P = Point3<f64>;
type V = Vector3<f64>;

/// Two surfaces face each other when their unit outward normals have a dot product below
/// `-FACING` (an angle of more than about 104° between them).
pub const FACING: f64 = 0.25;

/// Edge-edge contacts need the edges at least this far from parallel (the sine of their angle,
/// about 6 degrees).
pub const EDGE_ANGLE: f64 = 0.1;

/// Edge-edge contacts push along the edges' common normal only where it is within 60 degrees
/// of the direction the two surfaces face each other in (cosine).
pub const EDGE_ALIGNMENT: f64 = 0.5;

/// How self-contacts are resolved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelfContactSettings {
    /// Surfaces are kept this far apart, m.
    pub thickness: f64,
    /// A node behind a facing triangle of the surface (or an edge behind a facing edge) by up
    /// to this much is pushed back out, m; deeper ones are taken to belong elsewhere. Keep it
    /// below the size of a surface element.
    pub max_depth: f64,
    /// Sweeps over the contacts per call.
    pub iterations: usize,
}

impl Default for SelfContactSettings {
    fn default() -> Self {
        SelfContactSettings {
            thickness: 1e-4,
            max_depth: 1e-3,
            iterations: 8,
        }
    }
}

impl SelfContactSettings {
    /// The broad-phase margin that finds every pair this can act on: a node within the
    /// thickness in front of a triangle, or within `max_depth` behind it, lies that close to
    /// the triangle's box.
    pub fn margin(&self) -> f64 {
        self.thickness.max(self.max_depth)
    }

    fn validate(&self) -> Result<()> {
        let ok = |x: f64| x.is_finite() && x >= 0.0;
        if !(ok(self.thickness) && ok(self.max_depth)) {
            return Err(Error::Options(format!(
                "self-contact thickness and max_depth must be zero or positive and finite, got \
                 {} m and {} m",
                self.thickness, self.max_depth
            )));
        }
        Ok(())
    }
}

/// What one call found and did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SelfContactReport {
    /// Candidate triangle pairs from the broad phase.
    pub pairs: usize,
    /// Node–triangle contacts active in the first sweep.
    pub vertex_face: usize,
    /// Edge–edge contacts active in the first sweep.
    pub edge_edge: usize,
    /// Deepest penetration found in the first sweep, m (0 when every contact was only closer
    /// than the thickness).
    pub deepest: f64,
    /// Nodes moved.
    pub moved: usize,
    /// `sum m_i dx_i` over the moved nodes, kg m (zero to rounding unless fixed nodes took part).
    pub momentum: V,
    /// `sum m_i |dx_i|` over the moved nodes, kg m: the scale `momentum` is small against.
    pub moved_mass_distance: f64,
}

/// The nodes and primitives of one self-contact resolution, in local slots: the nodes of the
/// candidate triangles and of the triangles around them (for the normals).
#[derive(Debug, Clone)]
pub struct SelfContactProblem {
    /// Model indices of the slots, sorted.
    pub nodes: Vec<u32>,
    /// Positions per slot, m (moved by [`SelfContactProblem::solve`]).
    pub positions: Vec<P>,
    /// Positions as gathered.
    pub original: Vec<P>,
    /// Masses per slot, kg.
    pub mass: Vec<f64>,
    /// Inverse masses per slot, zero for fixed nodes.
    pub inv_mass: Vec<f64>,
    /// Unit outward vertex normals per slot (area-weighted over the surface triangles around
    /// the node, at the gathered positions), zero where not needed.
    pub normals: Vec<V>,
    /// (node slot, triangle corner slots) pairs.
    pub vertex_face: Vec<(usize, [usize; 3])>,
    /// (edge, edge) pairs, each edge as two slots.
    pub edge_edge: Vec<([usize; 2], [usize; 2])>,
}

impl SelfContactProblem {
    /// Gather the primitives of `pairs` (indices into `surface`, outward oriented triangles of
    /// model nodes), with `read` giving the positions of a sorted list of model nodes and
    /// `mass` and `fixed` the model's per-node arrays. Only primitives whose surfaces face each
    /// other (by the normals at the gathered positions) are kept.
    pub fn gather(
        surface: &[[u32; 3]],
        pairs: &[[u32; 2]],
        mass: &[f64],
        fixed: &[bool],
        read: impl FnOnce(&[u32]) -> Result<Vec<[f64; 3]>>,
    ) -> Result<Self> {
        if let Some(&t) = pairs
            .iter()
            .flatten()
            .find(|&&t| t as usize >= surface.len())
        {
            return Err(Error::Model(format!(
                "self-contact pair names triangle {t} of a surface of {}",
                surface.len()
            )));
        }
        // Each paired triangle once, marked over the surface (which the search for the
        // triangles around is walking anyway), then its nodes: the pairs name each triangle
        // many times (4,144 pairs of 928 triangles in the drop fixture), which sorting every
        // pair's nodes with their repeats paid for.
        let mut paired = vec![false; surface.len()];
        for &t in pairs.iter().flatten() {
            paired[t as usize] = true;
        }
        let mut contact_nodes: Vec<u32> = surface
            .iter()
            .zip(&paired)
            .filter(|(_, &p)| p)
            .flat_map(|(t, _)| *t)
            .collect();
        contact_nodes.sort_unstable();
        contact_nodes.dedup();
        // The triangles around the contact nodes, for their normals.
        let around: Vec<usize> = surface
            .iter()
            .enumerate()
            .filter(|(_, t)| t.iter().any(|n| contact_nodes.binary_search(n).is_ok()))
            .map(|(i, _)| i)
            .collect();
        let mut nodes: Vec<u32> = around.iter().flat_map(|&i| surface[i]).collect();
        nodes.extend(&contact_nodes);
        nodes.sort_unstable();
        nodes.dedup();
        if let Some(&n) = nodes
            .iter()
            .find(|&&n| n as usize >= mass.len().min(fixed.len()))
        {
            return Err(crate::engine::bad_node(n, mass.len()));
        }
        let positions: Vec<P> = read(&nodes)?.into_iter().map(P::from).collect();
        if positions.len() != nodes.len() {
            return Err(Error::LengthMismatch {
                given: positions.len(),
                expected: nodes.len(),
                message: format!(
                    "{} positions read for {} nodes",
                    positions.len(),
                    nodes.len()
                ),
            });
        }
        let slot = |n: u32| nodes.binary_search(&n).expect("every node was collected");
        let mut normals = vec![V::zeros(); nodes.len()];
        for &i in &around {
            let s = surface[i].map(slot);
            let n = (positions[s[1]] - positions[s[0]]).cross(&(positions[s[2]] - positions[s[0]]));
            for k in s {
                normals[k] += n;
            }
        }
        for n in &mut normals {
            *n = n.try_normalize(0.0).unwrap_or_else(V::zeros);
        }
        // Primitives of the pairs whose surfaces face each other, in slots.
        let faces = |a: V, b: V| a.dot(&b) < -FACING;
        let unit = |v: V| v.try_normalize(0.0).unwrap_or_else(V::zeros);
        // Each primitive pair as one integer, its slots the digits in base `slots`, so that
        // the keys sort as the pairs do: a pair of triangles repeats a node or edge pair that another pair of
        // triangles has (an edge pair up to four times), and sorting these keys to drop the
        // repeats costs far less than sorting the tuples.
        let slots = nodes.len() as u128;
        let vf_key = |s: usize, t: [usize; 3]| {
            ((s as u128 * slots + t[0] as u128) * slots + t[1] as u128) * slots + t[2] as u128
        };
        let edge_key = |e: [usize; 2]| e[0] as u128 * slots + e[1] as u128;
        let mut vf_keys: Vec<u128> = Vec::new();
        let mut ee_keys: Vec<u128> = Vec::new();
        let edges = |t: [usize; 3]| {
            [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]].map(|[a, b]| [a.min(b), a.max(b)])
        };
        for &[t, u] in pairs {
            let (a, b) = (surface[t as usize].map(slot), surface[u as usize].map(slot));
            for (nodes_of, tri) in [(a, b), (b, a)] {
                let p = &positions;
                let n = unit((p[tri[1]] - p[tri[0]]).cross(&(p[tri[2]] - p[tri[0]])));
                vf_keys.extend(
                    nodes_of
                        .iter()
                        .filter(|&&s| faces(normals[s], n))
                        .map(|&s| vf_key(s, tri)),
                );
            }
            for ea in edges(a) {
                let na = unit(normals[ea[0]] + normals[ea[1]]);
                for eb in edges(b) {
                    if faces(na, unit(normals[eb[0]] + normals[eb[1]])) {
                        let (ka, kb) = (edge_key(ea), edge_key(eb));
                        ee_keys.push(ka.min(kb) * slots * slots + ka.max(kb));
                    }
                }
            }
        }
        vf_keys.sort_unstable();
        vf_keys.dedup();
        ee_keys.sort_unstable();
        ee_keys.dedup();
        let digit = |k: u128, place: u32| (k / slots.pow(place) % slots) as usize;
        let vf: Vec<(usize, [usize; 3])> = vf_keys
            .iter()
            .map(|&k| (digit(k, 3), [digit(k, 2), digit(k, 1), digit(k, 0)]))
            .collect();
        let ee: Vec<([usize; 2], [usize; 2])> = ee_keys
            .iter()
            .map(|&k| ([digit(k, 3), digit(k, 2)], [digit(k, 1), digit(k, 0)]))
            .collect();
        let node_mass: Vec<f64> = nodes.iter().map(|&n| mass[n as usize]).collect();
        let inv_mass = nodes
            .iter()
            .zip(&node_mass)
            .map(|(&n, &m)| {
                if fixed[n as usize] || m.is_nan() || m <= 0.0 {
                    0.0
                } else {
                    1.0 / m
                }
            })
            .collect();
        Ok(SelfContactProblem {
            vertex_face: vf,
            edge_edge: ee,
            original: positions.clone(),
            positions,
            mass: node_mass,
            inv_mass,
            normals,
            nodes,
        })
    }

    /// Separate the surfaces: Gauss–Seidel sweeps over the contacts (see the module notes).
    pub fn solve(&mut self, settings: &SelfContactSettings) -> Result<SelfContactReport> {
        settings.validate()?;
        let (h, deep) = (settings.thickness, settings.max_depth);
        let mut report = SelfContactReport::default();
        // Only contacts within a thickness of acting can act within the sweeps (a correction
        // moves a node by about the violation it removes): drop the rest once.
        let slack = h.max(1e-9);
        let x = &self.positions;
        self.vertex_face.retain(|&(p, t)| {
            point_triangle(&x[p], &t.map(|s| x[s]))
                .is_some_and(|f| f.height < h + slack && f.height > -deep - slack)
        });
        self.edge_edge.retain(|&(a, b)| {
            let (p1, q1, p2, q2) = (x[a[0]], x[a[1]], x[b[0]], x[b[1]]);
            let (c1, c2, _, _) =
                crate::collide::self_narrow::closest_segment_segment(&p1, &q1, &p2, &q2);
            (c1 - c2).norm() < h.max(deep) + slack
        });
        for sweep in 0..settings.iterations.max(1) {
            let mut active = 0;
            for k in 0..self.vertex_face.len() {
                let (p, t) = self.vertex_face[k];
                let corners = t.map(|s| self.positions[s]);
                let Some(face) = point_triangle(&self.positions[p], &corners) else {
                    continue;
                };
                if face.weights.iter().any(|&w| w < 0.0)
                    || self.normals[p].dot(&face.normal) > -FACING
                    || face.height >= h
                    || face.height <= -deep
                {
                    continue;
                }
                let mut w = [1.0, 0.0, 0.0, 0.0];
                w[1..].copy_from_slice(&face.weights.map(|x| -x));
                if self.push([p, t[0], t[1], t[2]], w, face.normal, h - face.height) {
                    active += 1;
                    if sweep == 0 {
                        report.vertex_face += 1;
                        report.deepest = report.deepest.max(-face.height);
                    }
                }
            }
            for k in 0..self.edge_edge.len() {
                let (a, b) = self.edge_edge[k];
                let x = |s: usize| self.positions[s];
                let Some(e) = edge_edge(&x(a[0]), &x(a[1]), &x(b[0]), &x(b[1])) else {
                    continue;
                };
                let (na, nb) = (
                    self.normals[a[0]] + self.normals[a[1]],
                    self.normals[b[0]] + self.normals[b[1]],
                );
                let (Some(na), Some(nb)) = (na.try_normalize(0.0), nb.try_normalize(0.0)) else {
                    continue;
                };
                if na.dot(&nb) > -FACING {
                    continue;
                }
                // The common normal of nearly parallel edges is ill-conditioned and may lie
                // along the surfaces; their contacts are the nodes' (vertex-face) business.
                let (d1, d2) = (x(a[1]) - x(a[0]), x(b[1]) - x(b[0]));
                let facing = (nb - na).normalize();
                if d1.cross(&d2).norm() < EDGE_ANGLE * d1.norm() * d2.norm()
                    || e.direction.dot(&facing).abs() < EDGE_ALIGNMENT
                {
                    continue;
                }
                // Orient the direction from the second edge's body toward the first's.
                let (n, gap) = if e.direction.dot(&(nb - na)) >= 0.0 {
                    (e.direction, e.gap)
                } else {
                    (-e.direction, -e.gap)
                };
                if gap >= h || gap <= -deep {
                    continue;
                }
                let w = [1.0 - e.s, e.s, -(1.0 - e.t), -e.t];
                if self.push([a[0], a[1], b[0], b[1]], w, n, h - gap) {
                    active += 1;
                    if sweep == 0 {
                        report.edge_edge += 1;
                        report.deepest = report.deepest.max(-gap);
                    }
                }
            }
            if active == 0 {
                break;
            }
        }
        for s in 0..self.nodes.len() {
            let dx = self.positions[s] - self.original[s];
            if dx != V::zeros() {
                report.moved += 1;
                report.momentum += self.mass[s] * dx;
                report.moved_mass_distance += self.mass[s] * dx.norm();
            }
        }
        Ok(report)
    }

    /// Enforce `sum w_i x_i . n >= current + violation` on four slots (weights summing to
    /// zero); false when none of them can move.
    fn push(&mut self, slots: [usize; 4], w: [f64; 4], n: V, violation: f64) -> bool {
        let denom: f64 = (0..4).map(|k| w[k] * w[k] * self.inv_mass[slots[k]]).sum();
        if denom.is_nan() || denom <= 0.0 {
            return false;
        }
        let lambda = violation / denom;
        for k in 0..4 {
            let s = slots[k];
            self.positions[s] += n * (w[k] * lambda * self.inv_mass[s]);
        }
        true
    }

    /// The moved nodes (model indices) and their new positions.
    pub fn corrections(&self) -> (Vec<u32>, Vec<[f64; 3]>) {
        (0..self.nodes.len())
            .filter(|&s| self.positions[s] != self.original[s])
            .map(|s| {
                let p = self.positions[s];
                (self.nodes[s], [p.x, p.y, p.z])
            })
            .unzip()
    }
}

/// Resolve the self-contacts of the surface given to [`Simulation::set_surface`]: the broad
/// phase ([`Simulation::cull_self`], on the device for the GPU engine) at the settings'
/// margin, a readback of only the candidate triangles' nodes and their neighbours, the
/// correction of [`SelfContactProblem::solve`], and [`Simulation::correct_positions`] for the
/// moved nodes.
pub fn resolve_self_contacts(
    sim: &mut Simulation,
    settings: &SelfContactSettings,
) -> Result<SelfContactReport> {
    settings.validate()?;
    let pairs = sim.cull_self(settings.margin())?;
    if pairs.is_empty() {
        return Ok(SelfContactReport::default());
    }
    let surface = sim
        .surface()
        .ok_or_else(|| Error::NoSurface("no surface: call set_surface first".into()))?;
    let model = sim.model();
    let mut problem =
        SelfContactProblem::gather(surface, &pairs, &model.mass, &model.fixed, |nodes| {
            sim.node_positions(nodes)
        })?;
    let mut report = problem.solve(settings)?;
    report.pairs = pairs.len();
    let (ids, to) = problem.corrections();
    if !ids.is_empty() {
        sim.correct_positions(&ids, &to)?;
    }
    Ok(report)
}
