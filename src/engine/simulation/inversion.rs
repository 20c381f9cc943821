//! Inverted tets: the tets a simulation watches ([`Simulation::watch_mesh`]), checked for
//! orientation at the first divergence check at least [`INVERSION_CHECK_EVERY`] steps after
//! the last, and reported like a divergence ([`Error::Inverted`]) unless
//! [`SimConfig::allow_inverted`].
//!
//! A check reads the positions (on the GPU engine, the whole state back from the device: one
//! readback every [`INVERSION_CHECK_EVERY`] steps, no device-side reduction) and computes one
//! 3x3 determinant per tet, about the work of one step: a fraction of a per cent of the steps
//! between checks.

use super::*;
use crate::error::BadStep;
use crate::mesh::TetMesh;

/// Steps between checks for inverted tets: a check runs at the first divergence check at
/// least this many steps after the last one (with the default `check_every` of 10, every 500
/// steps).
pub const INVERSION_CHECK_EVERY: u64 = 500;

/// The tets watched for inversion, in dense model indices, with six times their signed rest
/// volumes.
pub(super) struct TetWatch {
    tets: Vec<[u32; 4]>,
    rest6: Vec<f64>,
    /// Nodes that a model change (a cut) touched since the tets were given. A cut removes or
    /// re-corners only tets at nodes whose springs it changes, so tets with such a node are
    /// skipped until the caller gives the tets again ([`Simulation::watch_mesh`]).
    touched: Vec<bool>,
    any_touched: bool,
}

/// What an inversion check found: how many tets, the first one and its volume ratio.
#[derive(Debug, Clone, Copy)]
pub(super) struct Inversion {
    pub count: usize,
    pub tet: usize,
    pub ratio: f64,
}

/// Six times the signed volume of the tet with corners `p`.
fn volume6(p: [[f64; 3]; 4]) -> f64 {
    let d = |i: usize| [0, 1, 2].map(|c| p[i][c] - p[0][c]);
    let (a, b, c) = (d(1), d(2), d(3));
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0])
}

impl TetWatch {
    fn new(tets: Vec<[u32; 4]>, rest: &[[f64; 3]]) -> Result<Self> {
        let n = rest.len();
        if let Some((i, t)) = tets
            .iter()
            .enumerate()
            .find(|(_, t)| t.iter().any(|&k| k as usize >= n))
        {
            return Err(Error::Mesh(format!(
                "tet {i} has corners {t:?}, past the model's {n} nodes: watch the tets of the mesh \
                 the model was packed from (or the cutter's mesh after its cuts were applied)"
            )));
        }
        let rest6 = tets
            .iter()
            .map(|t| volume6(t.map(|k| rest[k as usize])))
            .collect();
        Ok(TetWatch {
            tets,
            rest6,
            touched: vec![false; n],
            any_touched: false,
        })
    }

    /// Note the nodes a model change touched (`nodes` may include nodes it added).
    pub(super) fn touch(&mut self, nodes: &[u32], node_count: usize) {
        if self.touched.len() < node_count {
            self.touched.resize(node_count, false);
        }
        for &k in nodes {
            self.touched[k as usize] = true;
        }
        self.any_touched |= !nodes.is_empty();
    }

    /// The tets turned over relative to their rest shape in `x` (a tet flat at rest, which
    /// has no orientation, is never counted).
    pub(super) fn inverted(&self, x: &[[f64; 3]]) -> Option<Inversion> {
        let mut found: Option<Inversion> = None;
        for (i, (t, &r)) in self.tets.iter().zip(&self.rest6).enumerate() {
            if self.any_touched && t.iter().any(|&k| self.touched[k as usize]) {
                continue;
            }
            let ratio = volume6(t.map(|k| x[k as usize])) / r;
            if ratio < 0.0 {
                match &mut found {
                    Some(f) => f.count += 1,
                    None => {
                        found = Some(Inversion {
                            count: 1,
                            tet: i,
                            ratio,
                        })
                    }
                }
            }
        }
        found
    }
}

impl Simulation {
    /// Watch the tets of `mesh` for inversion: `mesh` must number its nodes as the model does
    /// (the mesh the model was packed from, or a cutter's mesh after its cuts were applied).
    /// Tets are reported by their index in the mesh's tet order. See [`Simulation::watch_tets`].
    pub fn watch_mesh(&mut self, mesh: &TetMesh) -> Result<()> {
        let dense = mesh.dense_nodes();
        let tets = mesh
            .tets()
            .map(|(_, t)| t.nodes.map(|k| dense.index[k]))
            .collect();
        self.watch_tets(tets)
    }

    /// Watch `tets` (corners in dense model indices) for inversion: from now on the checks of
    /// [`Simulation::run`] look at their orientation every [`INVERSION_CHECK_EVERY`] steps
    /// (at the first divergence check that many steps after the last) and fail with
    /// [`Error::Inverted`] when one has turned over relative to its rest shape, unless
    /// [`SimConfig::allow_inverted`]. A model change ([`Simulation::apply`]) may remove or
    /// re-corner tets: the watched tets at the nodes it touched are skipped until the tets are
    /// given again. Replaces any tets watched before.
    pub fn watch_tets(&mut self, tets: Vec<[u32; 4]>) -> Result<()> {
        self.watch = Some(TetWatch::new(tets, &self.model.rest)?);
        Ok(())
    }

    /// Whether a model change touched watched tets since they were given (give them again,
    /// from the changed mesh, to watch them all).
    pub fn watched_tets_touched(&self) -> bool {
        self.watch.as_ref().is_some_and(|w| w.any_touched)
    }

    /// Check the watched tets now, whatever the cadence: the first inverted one, if any, as
    /// [`Error::Inverted`] at the current step. Does nothing under
    /// [`SimConfig::allow_inverted`] or with no tets watched.
    pub fn check_inverted(&self) -> Result<()> {
        match self.watch.as_ref().filter(|_| !self.config.allow_inverted) {
            Some(w) => match w.inverted(&self.engine.positions()) {
                Some(f) => Err(inverted_error(f, self.steps, None)),
                None => Ok(()),
            },
            None => Ok(()),
        }
    }

    /// The periodic check of [`Simulation::run`]: every [`INVERSION_CHECK_EVERY`] steps, look
    /// at the watched tets in the state the divergence check just kept (or read it), keep that
    /// state as the last upright one, or replay from the last upright state to the first step
    /// with an inverted tet.
    pub(super) fn check_inversion_due(&mut self) -> Result<()> {
        if self.steps_since_inversion < INVERSION_CHECK_EVERY {
            return Ok(());
        }
        self.steps_since_inversion = 0;
        if self.config.allow_inverted || self.watch.is_none() {
            return Ok(());
        }
        let snap = match self.good_energy.take() {
            Some(s) if s.step == self.steps && s.changes == self.changes => s,
            other => {
                self.good_energy = other;
                let (x, v) = self.engine.state();
                Snapshot {
                    step: self.steps,
                    changes: self.changes,
                    x,
                    v,
                }
            }
        };
        let found = self.watch.as_ref().and_then(|w| w.inverted(&snap.x));
        match found {
            None => {
                self.last_upright = self.steps;
                self.good_shape = Some(snap.clone());
                self.good_energy = Some(snap);
                Ok(())
            }
            Some(f) => Err(self.place_inversion(f)),
        }
    }

    /// Replay from the last upright state, one step at a time, to the first step with an
    /// inverted tet; where the run changed since that state, report the check's finding.
    fn place_inversion(&mut self, seen: Inversion) -> Error {
        let found_at = self.steps;
        let bad = |replayed, last_good| BadStep {
            found_at,
            last_good,
            replayed,
        };
        let Some(snap) = self.good_shape.take().filter(|s| s.changes == self.changes) else {
            return inverted_error(seen, found_at, Some(bad(false, self.last_upright)));
        };
        self.engine.set_state(&snap.x, &snap.v);
        self.steps = snap.step;
        while self.steps < found_at {
            self.engine.step(1);
            self.steps += 1;
            let first = self
                .watch
                .as_ref()
                .and_then(|w| w.inverted(&self.engine.positions()));
            if let Some(f) = first {
                return inverted_error(f, self.steps, Some(bad(true, snap.step)));
            }
        }
        inverted_error(seen, found_at, Some(bad(false, snap.step)))
    }
}

fn inverted_error(f: Inversion, step: u64, found: Option<BadStep>) -> Error {
    Error::Inverted {
        step,
        tet: f.tet,
        count: f.count,
        ratio: f.ratio,
        found,
    }
}
