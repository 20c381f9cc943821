//! The fast float32 CPU engine (placeholder: runs the reference engine until written).

use super::reference::ReferenceEngine;
use super::{Engine, SimConfig};
use crate::model::PackedModel;

/// Float32 engine.
pub struct FastEngine(ReferenceEngine);

impl FastEngine {
    /// Start at rest.
    pub fn new(model: &PackedModel, config: SimConfig) -> Self {
        FastEngine(ReferenceEngine::new(model, config))
    }
}

impl Engine for FastEngine {
    fn step(&mut self, steps: u32) {
        self.0.step(steps)
    }
    fn positions(&self) -> Vec<[f64; 3]> {
        self.0.positions()
    }
    fn velocities(&self) -> Vec<[f64; 3]> {
        self.0.velocities()
    }
    fn set_state(&mut self, p: &[[f64; 3]], v: &[[f64; 3]]) {
        self.0.set_state(p, v)
    }
}
