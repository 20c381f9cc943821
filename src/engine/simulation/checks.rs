//! Divergence checks and energies: non-finite state and energy growth, measured where the state
//! lives, against a reference that model changes and position corrections move. A check that
//! fails replays the steps since the last good state it kept, one at a time, to report the
//! first bad step ([`BadStep`]).

use super::*;
use crate::error::BadStep;

impl Simulation {
    /// Check the current state for divergence. Engines with a cheap probe
    /// ([`crate::engine::Engine::divergence_probe`]: the GPU engine's reads back a few bytes,
    /// the fast CPU engine's reads its state once): kinetic plus gravitational energy is a lower
    /// bound of the total (elastic energy is never negative), so when it is within the limit
    /// nothing more is read; otherwise, or when a node is not finite, the whole state is read
    /// and checked exactly, which names the node.
    pub fn check(&self) -> Result<()> {
        self.check_total().map(|_| ())
    }

    /// [`Simulation::check`], returning the total energy where it was computed exactly.
    pub(super) fn check_total(&self) -> Result<Option<f64>> {
        if self.probe_passes()? {
            return Ok(None);
        }
        self.check_exact().map(Some)
    }

    /// Whether the engine's cheap probe shows the state healthy: every node finite and
    /// the kinetic plus gravitational energy (a lower bound of the total) within the limit.
    /// `false` where it does not, or where the engine has no probe.
    fn probe_passes(&self) -> Result<bool> {
        let Some(h) = self.engine.divergence_probe() else {
            return Ok(false);
        };
        let h = h?;
        let lower = h.kinetic + h.gravity;
        Ok(h.non_finite.is_none()
            && lower.is_finite()
            && lower - self.start_energy <= ENERGY_GROWTH_LIMIT * self.energy_scale)
    }

    /// The exact check over the whole state; returns the total energy.
    pub(super) fn check_exact(&self) -> Result<f64> {
        let (x, v) = self.engine.state();
        self.judge(&x, &v, self.steps)
    }

    /// The check of [`Simulation::run`]: [`Simulation::check_total`], keeping the state of an
    /// exact check that passed (where a replay to the first bad step would start), and on a
    /// failure replaying from the last good state to the first bad step (see [`BadStep`]).
    /// `exact` forces an exact check where the probe would do.
    pub(super) fn check_run(&mut self, exact: bool) -> Result<Option<f64>> {
        if !exact && self.probe_passes()? {
            self.last_good = self.steps;
            return Ok(None);
        }
        let (x, v) = self.engine.state();
        match self.judge(&x, &v, self.steps) {
            Ok(total) => {
                self.last_good = self.steps;
                self.good_energy = Some(Snapshot {
                    step: self.steps,
                    changes: self.changes,
                    x,
                    v,
                });
                Ok(Some(total))
            }
            Err(e) => Err(self.place_divergence(e)),
        }
    }

    /// Replay from the newest good state kept by a check, one step at a time with an exact
    /// check after each, to the first bad step; where the run was changed since (or no state
    /// was kept), report the check's finding with the last good step.
    fn place_divergence(&mut self, seen: Error) -> Error {
        let found_at = self.steps;
        let with = |e: Error, replayed, last_good| match e {
            Error::Diverged {
                step, node, reason, ..
            } => Error::Diverged {
                step,
                node,
                reason,
                found: Some(BadStep {
                    found_at,
                    last_good,
                    replayed,
                }),
            },
            other => other,
        };
        let newest = match (self.good_energy.take(), self.good_shape.take()) {
            (Some(a), Some(b)) => Some(if a.step >= b.step { a } else { b }),
            (a, b) => a.or(b),
        };
        let Some(snap) = newest.filter(|s| s.changes == self.changes && s.step < found_at) else {
            return with(seen, false, self.last_good);
        };
        self.engine.set_state(&snap.x, &snap.v);
        self.steps = snap.step;
        while self.steps < found_at {
            self.engine.step(1);
            self.steps += 1;
            let (x, v) = self.engine.state();
            if let Err(e) = self.judge(&x, &v, self.steps) {
                return with(e, true, snap.step);
            }
        }
        with(seen, false, snap.step)
    }

    /// Whether the state `x`, `v` at `step` has diverged: a node not finite, or the total
    /// energy above the limit; returns the total energy.
    fn judge(&self, x: &[[f64; 3]], v: &[[f64; 3]], step: u64) -> Result<f64> {
        let bad = x
            .iter()
            .zip(v)
            .position(|(p, u)| !p.iter().chain(u).all(|c| c.is_finite()));
        if let Some(node) = bad {
            return Err(Error::Diverged {
                step,
                node,
                reason: "position or velocity is not finite".into(),
                found: None,
            });
        }
        let e = self.energy_of(x, v);
        let total = e.total();
        if !total.is_finite() || total - self.start_energy > ENERGY_GROWTH_LIMIT * self.energy_scale
        {
            let node = v
                .iter()
                .zip(&self.model.mass)
                .enumerate()
                .max_by(|(_, (a, ma)), (_, (b, mb))| {
                    let ka = *ma * (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
                    let kb = *mb * (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
                    ka.total_cmp(&kb)
                })
                .map_or(0, |(i, _)| i);
            return Err(Error::Diverged {
                step,
                node,
                reason: format!(
                    "total energy grew from {:.3e} J to {total:.3e} J (limit: +{:.0} x the \
                     energy scale {:.3e} J); the node shown moves fastest",
                    self.start_energy, ENERGY_GROWTH_LIMIT, self.energy_scale
                ),
                found: None,
            });
        }
        Ok(total)
    }

    /// Corrections raise the reference by their work, an upper bound of the energy (damping
    /// only takes energy out); where a check has measured the total exactly (every check on
    /// the reference engine; on the engines with a probe a failed lower bound, or every
    /// [`EXACT_CHECK_EVERY`] steps while the reference is up) and found it lower, the reference
    /// comes down to it, never below where it was last taken from the state. The scale keeps
    /// the growth of the reference above that level.
    pub(super) fn tighten_reference(&mut self, total: f64) {
        if total < self.start_energy {
            self.start_energy = total.max(self.base_energy.min(self.start_energy));
            self.energy_scale = self.base_scale + (self.start_energy - self.base_energy).max(0.0);
        }
    }

    pub(super) fn energy_of(&self, x: &[[f64; 3]], v: &[[f64; 3]]) -> Energy {
        Energy {
            kinetic: self.model.kinetic_energy(v),
            elastic: self.engine.elastic_energy(&self.model, x),
            gravity: self.model.gravity_energy(x),
        }
    }

    /// What the divergence check compares against: the reference total energy, J (the energy
    /// when the run started or its state was last set, plus the work of every position
    /// correction since), and the energy scale, J, of which [`ENERGY_GROWTH_LIMIT`] times is
    /// the allowed growth above the reference.
    pub fn energy_reference(&self) -> (f64, f64) {
        (self.start_energy, self.energy_scale)
    }

    /// Energies of the current state.
    pub fn energy(&self) -> Energy {
        let (x, v) = self.engine.state();
        self.energy_of(&x, &v)
    }
}
