//! Broad phase, tool against tissue: the boundary triangles whose bounding boxes overlap a
//! tool's (swept, margin-inflated) box. The GPU pass (`shaders/broad_tool.wgsl`,
//! `engine::gpu::broad_tool`) appends the survivors to a candidate buffer through an atomic
//! counter; `twin::broad_tool::cull_cpu` is its twin, and [`cull_exact`] the brute-force float64 answer both
//! must contain.

use bytemuck::{Pod, Zeroable};

use crate::mesh::topology::Topology;
use crate::mesh::TetMesh;

/// The boundary surface of the tissue: triangles as dense node indices (the packed model's
/// order), outward oriented.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Surface {
    /// Corner nodes of each boundary triangle.
    pub triangles: Vec<[u32; 3]>,
}

impl Surface {
    /// The boundary triangles of `mesh`, in its dense node order.
    pub fn of(mesh: &TetMesh) -> Self {
        let dense = mesh.dense_nodes();
        let triangles = Topology::of(mesh)
            .boundary
            .iter()
            .map(|f| f.nodes.map(|k| dense.index[k]))
            .collect();
        Surface { triangles }
    }
}

/// A change to the boundary surface, as a cut produces it
/// ([`crate::cut::CutOutcome::surface`]): triangles (dense node indices, outward) that left
/// the boundary and triangles that joined it. [`crate::Simulation::edit_surface`] applies it in
/// place, so a local cut writes a few triangles rather than the whole surface.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SurfaceEdit {
    /// Triangles no longer on the boundary, as they were given.
    pub removed: Vec<[u32; 3]>,
    /// Triangles now on the boundary.
    pub added: Vec<[u32; 3]>,
}

impl SurfaceEdit {
    /// Whether the edit changes nothing.
    pub fn is_empty(&self) -> bool {
        self.removed.is_empty() && self.added.is_empty()
    }
}

/// An axis-aligned box, m. Mirrors `struct ToolBox` in `shaders/broad_tool.wgsl` (32 bytes:
/// the fourth lanes are padding).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct ToolBox {
    /// Lower corner.
    pub lo: [f32; 4],
    /// Upper corner.
    pub hi: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<ToolBox>() == 32);

impl ToolBox {
    /// The float32 box for the float64 box `lo..hi`, such that every triangle overlapping the
    /// exact box overlaps it when its corners are formed in float32 as the passes form them
    /// (rest position rounded to float32, plus the float32 displacement): each corner is
    /// widened by two float32 epsilons of its magnitude (half an ulp for rounding the rest
    /// position, half for the addition, with room to spare) and rounded outwards.
    pub fn containing(lo: [f64; 3], hi: [f64; 3]) -> Self {
        let pad = |x: f64| 2.0 * f32::EPSILON as f64 * x.abs();
        Self::rounded_outwards(lo.map(|x| x - pad(x)), hi.map(|x| x + pad(x)))
    }

    /// The smallest float32 box holding `lo..=hi` (each bound rounded outwards), without the
    /// pad [`ToolBox::containing`] adds for how the passes form node positions.
    pub fn rounded_outwards(lo: [f64; 3], hi: [f64; 3]) -> Self {
        let down = |x: f64| {
            let f = x as f32;
            if f as f64 > x {
                f.next_down()
            } else {
                f
            }
        };
        let up = |x: f64| {
            let f = x as f32;
            if (f as f64) < x {
                f.next_up()
            } else {
                f
            }
        };
        ToolBox {
            lo: [down(lo[0]), down(lo[1]), down(lo[2]), 0.0],
            hi: [up(hi[0]), up(hi[1]), up(hi[2]), 0.0],
        }
    }
}

/// A surviving pair: (triangle index, tool index).
pub type Candidate = [u32; 2];

/// The exact answer in float64: pairs whose triangle (at `positions`) and box `lo..hi`
/// overlap. Every broad phase must return a superset of this.
pub fn cull_exact(
    positions: &[[f64; 3]],
    triangles: &[[u32; 3]],
    boxes: &[([f64; 3], [f64; 3])],
) -> Vec<Candidate> {
    let mut out = Vec::new();
    for (t, tri) in triangles.iter().enumerate() {
        let p = tri.map(|i| positions[i as usize]);
        let lo = [0, 1, 2].map(|k| p[0][k].min(p[1][k]).min(p[2][k]));
        let hi = [0, 1, 2].map(|k| p[0][k].max(p[1][k]).max(p[2][k]));
        for (k, (blo, bhi)) in boxes.iter().enumerate() {
            if (0..3).all(|c| lo[c] <= bhi[c] && blo[c] <= hi[c]) {
                out.push([t as u32, k as u32]);
            }
        }
    }
    out
}
