//! The fast engine's divergence probe ([`crate::engine::Engine::divergence_probe`]): one read
//! of its own state arrays, in blocks on the step's threads, for the first node that is not finite, the
//! kinetic energy and the change of gravitational energy. The simulation's checks (every 10
//! steps by default) read this instead of copying the whole state to float64 in model order
//! and summing every spring's energy, which cost 10-25% of the steps it checked; the exact
//! check still runs at the cadence the GPU engine's probe has.

use super::{FastEngine, Integrator, P};
use crate::engine::Health;

/// Nodes per task of the probe.
const PROBE_BLOCK: usize = 8192;

/// A block's findings: its first non-finite node (internal index), kinetic energy and change
/// of gravitational energy, J.
type Partial = (Option<usize>, f64, f64);

impl FastEngine {
    /// The probe over every node; its sums are taken block by block in node order, so they do
    /// not depend on the number of threads.
    pub(super) fn probe(&self) -> Health {
        let v_scale = match self.integrator {
            Integrator::Verlet => 1.0 / self.params.h as f64,
            Integrator::SymplecticEuler | Integrator::BackwardEuler => 1.0,
        };
        let g = self.params.gravity.map(f64::from);
        let block = |start: usize, x: &[P], s: &[P]| -> Partial {
            let mut out: Partial = (None, 0.0, 0.0);
            for (k, (u, w)) in x.iter().zip(s).enumerate() {
                let i = start + k;
                if !u[..3].iter().chain(&w[..3]).all(|c| c.is_finite()) {
                    out.0 = out.0.or(Some(i));
                    continue;
                }
                if self.graph.fixed[i] {
                    continue;
                }
                let m = 1.0 / self.graph.inv_mass[i] as f64;
                let v = [0, 1, 2].map(|c| w[c] as f64 * v_scale);
                out.1 += 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
                out.2 -= m * (0..3).map(|c| g[c] * u[c] as f64).sum::<f64>();
            }
            out
        };
        #[cfg(feature = "parallel")]
        let parts: Vec<Partial> = {
            use rayon::prelude::*;
            self.x
                .par_chunks(PROBE_BLOCK)
                .zip(self.second.par_chunks(PROBE_BLOCK))
                .enumerate()
                .map(|(b, (x, s))| block(b * PROBE_BLOCK, x, s))
                .collect()
        };
        #[cfg(not(feature = "parallel"))]
        let parts: Vec<Partial> = self
            .x
            .chunks(PROBE_BLOCK)
            .zip(self.second.chunks(PROBE_BLOCK))
            .enumerate()
            .map(|(b, (x, s))| block(b * PROBE_BLOCK, x, s))
            .collect();
        let first = parts.iter().find_map(|p| p.0);
        Health {
            non_finite: first.map(|i| self.order[i] as usize),
            kinetic: parts.iter().map(|p| p.1).sum(),
            gravity: parts.iter().map(|p| p.2).sum(),
        }
    }
}
