//! Twin of `shaders/embed_surface.wgsl` (pass `engine::gpu::embed_surface`): each render
//! vertex's position from the node displacements, in float32, the adds in the shader's order.

use bytemuck::{Pod, Zeroable};

/// One render vertex as the pass reads it; mirrors `struct BoundVertex` in the shader (48
/// bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct BoundVertex {
    /// Layout slots of the four nodes that move the vertex.
    pub nodes: [u32; 4],
    /// Their weights.
    pub weights: [f32; 4],
    /// The vertex's rest position (w unused).
    pub rest: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<BoundVertex>() == 48);

/// The vertex positions (w = 1) the pass writes for displacements `disp` (layout order).
pub fn embed_surface_cpu(bound: &[BoundVertex], disp: &[[f32; 4]]) -> Vec<[f32; 4]> {
    bound
        .iter()
        .map(|b| {
            let mut x = [b.rest[0], b.rest[1], b.rest[2]];
            for k in 0..4 {
                let u = disp[b.nodes[k] as usize];
                for c in 0..3 {
                    x[c] += b.weights[k] * u[c];
                }
            }
            [x[0], x[1], x[2], 1.0]
        })
        .collect()
}
