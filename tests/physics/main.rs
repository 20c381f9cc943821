//! Physics against physics: analytic oscillators, beams, energy, stability bounds, the model.
//!
//! One test binary per area (linking each binary costs more than its tests on a 2-core
//! machine); each module is one behaviour, named as the file it was.

#[path = "../common/models.rs"]
mod models;

mod fem_simulation;
mod fem_validation;
mod implicit;
mod model_error;
mod model_springs;
mod physics_beam;
mod physics_energy;
mod physics_oscillator;
mod run_checks;
mod stability;
