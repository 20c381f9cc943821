//! Twin of `shaders/broad_tool.wgsl` (pass `engine::gpu::broad_tool`): the tool broad phase,
//! every (triangle, tool) pair whose float32 boxes overlap. Also the broad phase of the CPU
//! benchmarks (`report::collide_bench`).

use crate::collide::broad::{Candidate, ToolBox};

/// Float32 position of a node from its rest position and displacement, as the GPU pass forms
/// it.
#[inline]
fn position(rest: &[[f32; 4]], disp: &[[f32; 4]], i: u32) -> [f32; 3] {
    let (r, u) = (rest[i as usize], disp[i as usize]);
    [r[0] + u[0], r[1] + u[1], r[2] + u[2]]
}

/// The bounds of triangle `t` at float32 positions `rest + disp`, as the GPU pass computes
/// them.
fn triangle_box(rest: &[[f32; 4]], disp: &[[f32; 4]], t: [u32; 3]) -> ([f32; 3], [f32; 3]) {
    let [a, b, c] = t.map(|i| position(rest, disp, i));
    let lo = [0, 1, 2].map(|k| a[k].min(b[k]).min(c[k]));
    let hi = [0, 1, 2].map(|k| a[k].max(b[k]).max(c[k]));
    (lo, hi)
}

/// Every (triangle, tool) pair whose float32 boxes overlap (touching counts), in triangle then
/// tool order: the CPU twin of the GPU pass, whose list is the same set in some order.
/// `rest` and `disp` are indexed by the triangles' node indices.
pub fn cull_cpu(
    rest: &[[f32; 4]],
    disp: &[[f32; 4]],
    triangles: &[[u32; 3]],
    boxes: &[ToolBox],
) -> Vec<Candidate> {
    let mut out = Vec::new();
    for (t, &tri) in triangles.iter().enumerate() {
        let (lo, hi) = triangle_box(rest, disp, tri);
        for (k, b) in boxes.iter().enumerate() {
            if (0..3).all(|c| lo[c] <= b.hi[c] && b.lo[c] <= hi[c]) {
                out.push([t as u32, k as u32]);
            }
        }
    }
    out
}
