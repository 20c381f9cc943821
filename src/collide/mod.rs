//! Surgical tools against the tissue: broad-phase culling of boundary triangles against tool
//! bounds (on the GPU, with a CPU twin), then exact queries on the few survivors.

pub mod broad;
pub mod self_broad;
