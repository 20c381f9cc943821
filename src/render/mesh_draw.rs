//! Triangle meshes as the renderer's vertex buffer: three vertices per triangle, each with its
//! triangle's normal (flat shading, which shows the facets of a cut as they are) and a colour.

use bytemuck::{Pod, Zeroable};
use nalgebra::{Point3, Vector3};

/// One vertex as `shaders/render_mesh.wgsl` reads it (36 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct DrawVertex {
    /// Offset from the drawing's origin, m.
    pub position: [f32; 3],
    /// The triangle's unit normal (counter-clockwise corners).
    pub normal: [f32; 3],
    /// Linear RGB in `[0, 1]`.
    pub colour: [f32; 3],
}

/// How a mesh is coloured.
#[derive(Debug, Clone, Copy)]
pub enum Paint<'a> {
    /// One colour per vertex (the tissue by displacement); each triangle's corners keep their
    /// own, interpolated across it.
    PerVertex(&'a [[f32; 3]]),
    /// One colour for the whole mesh (a tool).
    Solid([f32; 3]),
}

/// A mesh to draw.
#[derive(Debug, Clone, Copy)]
pub struct DrawMesh<'a> {
    /// Vertex positions, m.
    pub positions: &'a [[f64; 3]],
    /// Triangles as vertex indices.
    pub triangles: &'a [[u32; 3]],
    /// Its colours.
    pub paint: Paint<'a>,
}

/// The vertices of `meshes`' triangles, positions as offsets from `origin`. Triangles of no
/// area (no normal) and those naming a missing vertex or colour are left out: they cover no
/// pixel.
pub fn vertices(meshes: &[DrawMesh], origin: Point3<f64>) -> Vec<DrawVertex> {
    let mut out = Vec::new();
    for m in meshes {
        for t in m.triangles {
            let Some(corners) = t
                .iter()
                .map(|&v| m.positions.get(v as usize).map(|p| Point3::from(*p)))
                .collect::<Option<Vec<_>>>()
            else {
                continue;
            };
            let colours = match m.paint {
                Paint::Solid(c) => [c; 3],
                Paint::PerVertex(cs) => match t.map(|v| cs.get(v as usize).copied()) {
                    [Some(a), Some(b), Some(c)] => [a, b, c],
                    _ => continue,
                },
            };
            let n: Vector3<f64> = (corners[1] - corners[0]).cross(&(corners[2] - corners[0]));
            let Some(n) = n.try_normalize(0.0) else {
                continue;
            };
            let normal = [n.x as f32, n.y as f32, n.z as f32];
            for (p, colour) in corners.iter().zip(colours) {
                let d = p - origin;
                out.push(DrawVertex {
                    position: [d.x as f32, d.y as f32, d.z as f32],
                    normal,
                    colour,
                });
            }
        }
    }
    out
}

/// Axis-aligned bounds of the meshes' vertices, `None` without any.
pub fn bounds(meshes: &[DrawMesh]) -> Option<([f64; 3], [f64; 3])> {
    let mut it = meshes.iter().flat_map(|m| m.positions.iter());
    let first = *it.next()?;
    Some(it.fold((first, first), |(lo, hi), p| {
        (
            [0, 1, 2].map(|c| lo[c].min(p[c])),
            [0, 1, 2].map(|c| hi[c].max(p[c])),
        )
    }))
}
