//! The GPU engine's side of its implicit step ([`super::implicit`]): binding the solver to the
//! layout's buffers at setup and after every patch, stepping, and the solve's single passes and
//! vectors for the tests that hold them against their twins.

use super::buffers;
use super::implicit::{ImplicitSolver, SolvePass};
use super::{GpuEngine, Passes};
use crate::error::{Error, Result};
use crate::layout::patch::LayoutArray;
use crate::layout::PackedLayout;
use crate::physics::SolverStats;
use crate::twin::implicit_solve::{SolveParams, SolveVectors};

impl GpuEngine {
    /// Bind the implicit solver (if any) to the buffers and sizes of now: at setup and after
    /// every patch.
    pub(super) fn rebind_implicit(&mut self) -> Result<()> {
        let Some(solver) = self.implicit.as_mut() else {
            return Ok(());
        };
        let buffer = |a: LayoutArray| {
            self.passes
                .buffer(a)
                .ok_or_else(|| Error::Gpu(format!("no device buffer holds the {a:?} array")))
        };
        let (width, records, tables) = match (&self.layout, &self.passes) {
            (PackedLayout::Connectivity(c), _) => (c.capacity, LayoutArray::Slots, vec![]),
            (PackedLayout::Valence(_), Passes::Valence(p)) => {
                (0, LayoutArray::Slots, vec![p.table()])
            }
            (PackedLayout::Edges(_), Passes::Edges(_)) => (
                0,
                LayoutArray::EdgeSprings,
                vec![
                    buffer(LayoutArray::IncidenceRows)?,
                    buffer(LayoutArray::Incidence)?,
                ],
            ),
            // The float-atomic variant sums into its own accumulators: no tables.
            (PackedLayout::Edges(_), Passes::AtomicEdges(_)) => {
                (0, LayoutArray::EdgeSprings, vec![])
            }
            (other, _) => {
                return Err(Error::Gpu(format!(
                    "the {:?} layout's passes do not match it",
                    other.kind()
                )))
            }
        };
        // Group 1: the tensor-mass blocks, or the corotational blocks with the tet table's
        // node rows, records and corner forces (the solve's force).
        let group_one: Vec<&wgpu::Buffer> = match (&self.tensor, &self.corot, &self.corot_blocks) {
            (Some(t), _, _) => vec![t.buffer()],
            (None, Some(c), Some(b)) => {
                let t = c.device_table();
                vec![b.buffer(), t.rows, t.incidence, t.forces]
            }
            _ => Vec::new(),
        };
        solver.set_damped(&self.ctx, self.uniform_data.damped != 0);
        solver.rebind(
            &self.ctx,
            buffer(records)?,
            buffer(LayoutArray::InvMass)?,
            &tables,
            &group_one,
            &self.state,
            self.layout.node_slots() as u32,
            width,
            self.dispatch.row,
            self.dispatch.nodes,
            (super::spring_records(&self.layout), self.dispatch.springs),
        )
    }

    /// `steps` implicit steps, each solved to its end before the next (the state rotates as
    /// for symplectic Euler); with the corotational force model each step first runs the tet
    /// pass (rotations, corner forces) and the block pass. A device failure is reported and
    /// stops the steps.
    pub(super) fn step_implicit(&mut self, steps: u32) {
        let Some(solver) = self.implicit.as_mut() else {
            return;
        };
        for _ in 0..steps {
            let phase = self.phase;
            let (corot, blocks) = (&self.corot, &self.corot_blocks);
            let prelude = |pass: &mut wgpu::ComputePass<'_>| {
                if let (Some(c), Some(b)) = (corot, blocks) {
                    c.record_tets(pass, phase);
                    b.record(pass);
                }
            };
            match solver.step(&self.ctx, self.phase, self.dispatch.nodes, &prelude) {
                Ok(_) => self.phase = (self.phase + 1) % self.state.phases(),
                Err(e) => {
                    eprintln!("lancet: the implicit step failed: {e}");
                    return;
                }
            }
        }
    }

    /// What the implicit solves did so far (`None` for an explicit integrator).
    pub fn implicit_stats(&self) -> Option<SolverStats> {
        self.implicit.as_ref().map(|s| s.stats())
    }

    /// The implicit solve's constants as its twin takes them (`None` for an explicit
    /// integrator).
    pub fn solve_params(&self) -> Option<SolveParams> {
        self.implicit.as_ref().map(|s| s.params())
    }

    fn solver(&self) -> Result<&ImplicitSolver> {
        self.implicit.as_ref().ok_or_else(|| {
            Error::Unsupported("this engine runs an explicit integrator: it has no solver".into())
        })
    }

    /// Run one pass of the implicit solve alone on the current state and solver vectors (for
    /// comparing each pass with its twin).
    pub fn run_solve_pass(&self, pass: SolvePass) -> Result<()> {
        self.solver()?
            .run_pass(&self.ctx, pass, self.phase, self.dispatch.nodes)
    }

    /// The solver vectors and scalars as the device holds them (layout order).
    pub fn solve_vectors(&self) -> Result<SolveVectors> {
        self.solver()?
            .read_vectors(&self.ctx, self.layout.node_slots())
    }

    /// Overwrite the solver vectors and scalars (layout order, one entry per node slot).
    pub fn set_solve_vectors(&self, v: &SolveVectors) -> Result<()> {
        let n = self.layout.node_slots();
        if [
            v.y.len(),
            v.r.len(),
            v.z.len(),
            v.p.len(),
            v.ap.len(),
            v.minv.len(),
        ]
        .iter()
        .any(|&l| l != n)
        {
            return Err(Error::LengthMismatch {
                given: v.y.len(),
                expected: n,
                message: format!("solver vectors for a layout of {n} node slots"),
            });
        }
        self.solver()?.write_vectors(&self.ctx, v);
        Ok(())
    }

    /// The next displacements and velocities a [`SolvePass::Finish`] wrote (the buffers the
    /// next phase reads), layout order.
    pub fn finished_state(&self) -> Result<crate::twin::implicit_solve::NextState> {
        let b = self.state.bindings(self.phase);
        let n = self.layout.node_slots();
        let mut next = buffers::read_vec4(&self.ctx, b.next)?;
        let mut vel = buffers::read_vec4(&self.ctx, b.second_out)?;
        next.truncate(n);
        vel.truncate(n);
        Ok((next, vel))
    }
}
