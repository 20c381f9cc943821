//! Binding a render surface to the simulation mesh, and evaluating it from the node positions.
//!
//! Every vertex gets four mesh nodes and four weights, and its deformed position is the
//! weighted sum of those nodes' positions:
//!
//! - a vertex **inside** the mesh: the tet that holds it and its barycentric coordinates there
//!   (the weights are in `0..=1` and sum to one), so it moves linearly with that tet, and a
//!   vertex at a node moves exactly as the node (weights exactly one and zero);
//! - a vertex **outside** (a render surface a little larger than the simulation mesh, as
//!   modelled surfaces are): the offset mapping of Mosegaard & Sørensen (2005), from the
//!   nearest point of the nearest boundary face. The offset is expressed in a frame of that
//!   face: its two edges from one corner and the edge from that corner to the fourth node of the
//!   face's tet. Written out, that is the tet's barycentric coordinates extended outside it (one
//!   or more weights negative), so the offset turns with the face under a rotation, like the
//!   seed's tangent frame, and also stretches and shears with the tet, so that any affine motion
//!   of the mesh moves the vertex by the same affine map. An orthonormal frame (normal and
//!   tangent) rotates too but leaves the offset's length fixed when the tissue is compressed
//!   under it, pulling the surface off the tissue.
//!
//! Finding the tets and faces goes through [`Grid`]: linear in vertices plus tets.

use nalgebra::Point3;

use super::grid::Grid;
use super::RenderSurface;
use crate::error::{Error, Result};
use crate::mesh::{signed_volume6, TetKey, TetMesh, Topology};

/// Where one vertex is bound.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Binding {
    /// Inside (or on) this tet.
    Inside(TetKey),
    /// Outside the mesh, `distance` from its nearest boundary face, face `face` (the index of
    /// the node opposite it) of tet `tet`.
    Outside {
        /// The tet of the nearest boundary face.
        tet: TetKey,
        /// Which face of that tet.
        face: u8,
        /// Rest distance from the vertex to the face.
        distance: f64,
    },
}

impl Binding {
    /// The tet whose nodes move the vertex.
    pub fn tet(&self) -> TetKey {
        match *self {
            Binding::Inside(t) | Binding::Outside { tet: t, .. } => t,
        }
    }
}

/// A render surface bound to a tet mesh: per vertex four nodes (dense indices of
/// [`TetMesh::dense_nodes`], the model's node order) and their weights.
#[derive(Debug, Clone)]
pub struct Embedding {
    /// The four nodes moving each vertex, dense indices.
    pub nodes: Vec<[u32; 4]>,
    /// Their weights (sum one; all in `0..=1` for a vertex inside).
    pub weights: Vec<[f64; 4]>,
    /// Each vertex's rest position (the surface's).
    pub rest: Vec<[f64; 3]>,
    /// How each vertex is bound.
    pub bindings: Vec<Binding>,
    /// Vertices a cut left with nothing on their side to bind to (carving): weights zero,
    /// their triangles not drawn ([`Embedding::drawn_triangles`]).
    pub dropped: Vec<bool>,
}

/// How far outside a tet (in barycentric weight) a vertex may lie and still count as in it:
/// rounding, for vertices on a face or at a node.
pub(super) const INSIDE_TOLERANCE: f64 = 1e-10;

/// The four barycentric coordinates of `p` in the tet `t` (extended outside it: negative
/// where `p` lies beyond a face), each a ratio of signed volumes; a vertex at a node gets
/// exactly one there and zero elsewhere.
pub fn barycentric(t: &[Point3<f64>; 4], p: &Point3<f64>) -> [f64; 4] {
    // At a corner the ratio with the corner repeated (`(b-a) x (c-a) . (c-a)`) rounds to a few
    // ulps, not zero: a vertex at a node takes exactly that node's position.
    if let Some(k) = t.iter().position(|c| c == p) {
        let mut w = [0.0; 4];
        w[k] = 1.0;
        return w;
    }
    let v = signed_volume6(&t[0], &t[1], &t[2], &t[3]);
    [
        signed_volume6(p, &t[1], &t[2], &t[3]) / v,
        signed_volume6(&t[0], p, &t[2], &t[3]) / v,
        signed_volume6(&t[0], &t[1], p, &t[3]) / v,
        signed_volume6(&t[0], &t[1], &t[2], p) / v,
    ]
}

/// The point of the triangle `a b c` nearest `p` (Ericson, Real-Time Collision Detection 5.1.5).
pub fn closest_on_triangle(
    p: &Point3<f64>,
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
) -> Point3<f64> {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// The axis-aligned box of some points.
pub(super) fn bounds(points: &[Point3<f64>]) -> ([f64; 3], [f64; 3]) {
    let mut lo = points[0].coords;
    let mut hi = lo;
    for p in &points[1..] {
        lo = lo.inf(&p.coords);
        hi = hi.sup(&p.coords);
    }
    (lo.into(), hi.into())
}

impl Embedding {
    /// Bind every vertex of `surface` to `mesh` at rest.
    pub fn new(mesh: &TetMesh, surface: &RenderSurface) -> Result<Self> {
        if mesh.tet_count() == 0 {
            return Err(Error::Mesh(
                "a render surface needs a mesh with tets to embed it in".into(),
            ));
        }
        let dense = mesh.dense_nodes();
        let tets: Vec<(TetKey, [Point3<f64>; 4])> =
            mesh.tets().map(|(k, t)| (k, mesh.tet_points(t))).collect();
        let tet_grid = Grid::new(&tets.iter().map(|(_, p)| bounds(p)).collect::<Vec<_>>());
        let boundary = Topology::of(mesh).boundary;
        let face_points: Vec<[Point3<f64>; 3]> = boundary
            .iter()
            .map(|f| f.nodes.map(|k| mesh.rest(k)))
            .collect();
        let face_grid = Grid::new(&face_points.iter().map(|p| bounds(p)).collect::<Vec<_>>());
        let mut out = Embedding {
            nodes: Vec::with_capacity(surface.vertex_count()),
            weights: Vec::with_capacity(surface.vertex_count()),
            rest: surface.positions.clone(),
            bindings: Vec::with_capacity(surface.vertex_count()),
            dropped: vec![false; surface.vertex_count()],
        };
        for (v, x) in surface.positions.iter().enumerate() {
            let p = Point3::from(*x);
            // The holding tet whose smallest weight is largest: on a shared face or at a node,
            // the choice does not change the position, only which tet moves it.
            let inside = tet_grid
                .at(*x)
                .iter()
                .map(|&i| (i, barycentric(&tets[i as usize].1, &p)))
                .filter(|(_, w)| w.iter().all(|&w| w >= -INSIDE_TOLERANCE))
                .max_by(|a, b| min4(&a.1).total_cmp(&min4(&b.1)).then(b.0.cmp(&a.0)));
            let (tet, weights, binding) = match inside {
                Some((i, w)) => {
                    let key = tets[i as usize].0;
                    (key, w, Binding::Inside(key))
                }
                None => {
                    let (f, distance) = face_grid
                        .nearest(*x, |f| {
                            let [a, b, c] = &face_points[f as usize];
                            (closest_on_triangle(&p, a, b, c) - p).norm()
                        })
                        .ok_or_else(|| {
                            Error::Mesh(format!(
                                "render vertex {v}: the mesh has no boundary face to bind it to"
                            ))
                        })?;
                    let face = boundary[f as usize];
                    let t = mesh
                        .tet(face.tet)
                        .expect("a boundary face's tet is in the mesh");
                    let w = barycentric(&mesh.tet_points(t), &p);
                    (
                        face.tet,
                        w,
                        Binding::Outside {
                            tet: face.tet,
                            face: face.local,
                            distance,
                        },
                    )
                }
            };
            let t = mesh.tet(tet).expect("a bound tet is in the mesh");
            out.nodes.push(t.nodes.map(|k| dense.index[k]));
            out.weights.push(weights);
            out.bindings.push(binding);
        }
        Ok(out)
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Whether there are no vertices.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The deformed vertex positions, from the node positions `x` (dense order, as
    /// [`crate::engine::Engine::positions`] gives them, or float32 positions), each the weighted
    /// sum of its four nodes in float64.
    pub fn evaluate<T: Copy + Into<f64>>(&self, x: &[[T; 3]]) -> Vec<[f64; 3]> {
        self.nodes
            .iter()
            .zip(&self.weights)
            .map(|(n, w)| {
                let mut p = [0.0; 3];
                for k in 0..4 {
                    let xn = x[n[k] as usize];
                    for c in 0..3 {
                        p[c] += w[k] * xn[c].into();
                    }
                }
                p
            })
            .collect()
    }

    /// The triangles of `triangles` (the surface's) whose vertices are all still drawn.
    pub fn drawn_triangles(&self, triangles: &[[u32; 3]]) -> Vec<[u32; 3]> {
        triangles
            .iter()
            .filter(|t| t.iter().all(|&v| !self.dropped[v as usize]))
            .copied()
            .collect()
    }

    /// Append a vertex at rest position `x`, not bound yet (its weights zero: it stays at the
    /// origin until bound), and return its index. (The caps a cut adds.)
    #[cfg(feature = "cut")]
    pub(super) fn push(&mut self, x: Point3<f64>) -> u32 {
        self.nodes.push([0; 4]);
        self.weights.push([0.0; 4]);
        self.rest.push(x.into());
        self.bindings.push(Binding::Inside(TetKey::default()));
        self.dropped.push(false);
        (self.nodes.len() - 1) as u32
    }

    /// Keep only the first `n` vertices.
    #[cfg(feature = "cut")]
    pub(super) fn truncate(&mut self, n: usize) {
        self.nodes.truncate(n);
        self.weights.truncate(n);
        self.rest.truncate(n);
        self.bindings.truncate(n);
        self.dropped.truncate(n);
    }

    /// Vertices dropped by cuts.
    pub fn dropped_count(&self) -> usize {
        self.dropped.iter().filter(|&&d| d).count()
    }

    /// The vertices bound outside the mesh.
    pub fn outside_count(&self) -> usize {
        self.bindings
            .iter()
            .filter(|b| matches!(b, Binding::Outside { .. }))
            .count()
    }
}

/// The smallest of four weights.
fn min4(w: &[f64; 4]) -> f64 {
    w.iter().copied().fold(f64::INFINITY, f64::min)
}
