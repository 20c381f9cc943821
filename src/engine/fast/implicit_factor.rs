//! The factored preconditioner ([`Preconditioner::Factored`]): a sparse Cholesky factor
//! `L L^T` (faer's supernodal factorisation after an approximate-minimum-degree ordering, in
//! float64) of the implicit step's system `A` as it was at some step, applied as `z = (L
//! L^T)^-1 r` by two triangular solves (`implicit_factor_solve.rs`: over a float32 copy of
//! the factor for [`Preconditioner::Factored`], the float64 factor itself for
//! [`Preconditioner::FactoredDouble`]). Conjugate gradients judge each residual before they
//! precondition it, so a solve converged in `k` iterations applies the factor `k` times.
//!
//! On stiff tissue at small strains the system changes little from step to step, so a factor
//! of an earlier step's `A` is close to the inverse of the current one and conjugate gradients
//! converge in a few iterations (one or two with a fresh factor: the product is float32, the
//! factor float64). A stale factor stays symmetric positive definite, so conjugate gradients
//! still converge to the same answer, only in more iterations; the refresh policy
//! ([`Factor::observe`]) refactors once a solve needs more than [`REFRESH_ITERATIONS`].
//!
//! Through cuts: the factor covers the nodes that existed when it was taken. A cut appends
//! nodes and changes rows, and the step goes on without refactoring: the old nodes keep the
//! old factor and the new nodes their inverse diagonal blocks (block Jacobi), a block-diagonal
//! composition of two symmetric positive definite parts, so still symmetric positive definite.
//! The refresh policy replaces it when the iterations grow (a cut's changed rows raise them).
//!
//! [`Preconditioner::Factored`]: crate::physics::Preconditioner::Factored
//! [`Preconditioner::FactoredDouble`]: crate::physics::Preconditioner::FactoredDouble

use super::passes::over_blocks;
use super::rows::{dot64, Rows};
use super::{Held, Iterate, NodeSystem};
use crate::engine::fast::Graph;
use crate::physics::SolverStats;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Par, Side};

#[path = "implicit_factor_solve.rs"]
mod triangular;
use triangular::Triangular;

/// A solve that needs more conjugate-gradient iterations than this marks the factor stale:
/// the next solve refactors first. A fresh factor takes one or two; each further iteration
/// costs a product and two triangular solves, and on the SOFA cylinder (3,668 nodes) a
/// factorisation costs about as much as ten to twenty of them, so past this many the drift
/// costs more per step than refactoring every few steps would.
pub(super) const REFRESH_ITERATIONS: u32 = 6;

/// The factorisation's arithmetic: float64, so that the factor of a stiff system (its
/// diagonal blocks 1e3 to 1e5 times its mass, the 1 MPa cylinder's at 1 ms) keeps the digits
/// the float32 product resolves. The solves may still read the finished factor rounded to
/// float32: half the bytes, for at most about one more iteration a solve (the float32 and
/// float64 factors' steps are compared in `tests/engine/fast_implicit.rs`).
type Real = f64;

/// The factor, the system it was taken of, and the scratch of its solves.
pub(super) struct Factor {
    /// How many nodes the factor covers: those that existed when it was taken.
    nodes: usize,
    /// The lower triangle of the system the factor was taken of (scalar rows and columns,
    /// `3 i + c` for node `i`'s component `c`), column by column.
    col_ptr: Vec<u32>,
    row_idx: Vec<u32>,
    values: Vec<Real>,
    /// The symbolic factorisation of that pattern (kept while the pattern stays the same:
    /// only a cut changes it).
    symbolic: SymbolicCholesky<u32>,
    /// The numeric factor `L`, as faer's factorisation leaves it.
    l: Vec<Real>,
    /// The factor in the precision the triangular solves stream, with their schedule.
    solves: Solves,
    /// Whether the solves stream the factor in float32.
    single: bool,
    /// The solves' output in the original order.
    z: Vec<f32>,
    /// Whether the next solve should refactor first.
    stale: bool,
    /// Factorisations so far.
    pub(super) factorisations: u64,
}

/// The triangular solves in the precision asked for.
enum Solves {
    Single(Triangular<f32>),
    Double(Triangular<f64>),
}

impl Solves {
    fn new(symbolic: &SymbolicCholesky<u32>, single: bool) -> Option<Solves> {
        Some(if single {
            Solves::Single(Triangular::new(symbolic)?)
        } else {
            Solves::Double(Triangular::new(symbolic)?)
        })
    }
}

/// The lower triangle of the system `A` (the diagonal blocks of `nodes`, the off-diagonal
/// ones of `rows`), fixed nodes projected out (an identity row and column), as a scalar
/// compressed-column pattern and values.
fn lower_triangle(
    nodes: &[NodeSystem],
    rows: Rows,
    g: &Graph,
    col_ptr: &mut Vec<u32>,
    row_idx: &mut Vec<u32>,
    values: &mut Vec<Real>,
) {
    col_ptr.clear();
    row_idx.clear();
    values.clear();
    col_ptr.push(0);
    let mut below: Vec<(usize, [[f64; 3]; 3])> = Vec::new();
    for (j, node) in nodes.iter().enumerate() {
        if g.fixed[j] {
            for c in 0..3 {
                row_idx.push((3 * j + c) as u32);
                values.push(1.0);
                col_ptr.push(row_idx.len() as u32);
            }
            continue;
        }
        // Row `j`'s blocks `A_ji` for free `i > j`, by `i`, a pair coupled twice summed: the
        // column `j` below the diagonal holds `A_ij = A_ji^T`.
        below.clear();
        rows.for_each_block(j, |i, a| {
            if i > j && !g.fixed[i] {
                below.push((i, a));
            }
        });
        below.sort_by_key(|&(i, _)| i);
        below.dedup_by(|later, kept| {
            let same = later.0 == kept.0;
            if same {
                for r in 0..3 {
                    for c in 0..3 {
                        kept.1[r][c] += later.1[r][c];
                    }
                }
            }
            same
        });
        let d = node.diag.map(f64::from);
        let diag = [[d[0], d[3], d[4]], [d[3], d[1], d[5]], [d[4], d[5], d[2]]];
        for c in 0..3 {
            for (r, row) in diag.iter().enumerate().skip(c) {
                row_idx.push((3 * j + r) as u32);
                values.push(row[c] as Real);
            }
            for (i, a) in &below {
                // Row `3 i + r` of column `3 j + c`: `A_ij[r][c] = A_ji[c][r]`.
                for (r, v) in a[c].iter().enumerate() {
                    row_idx.push((3 * i + r) as u32);
                    values.push(*v as Real);
                }
            }
            col_ptr.push(row_idx.len() as u32);
        }
    }
}

impl Factor {
    /// The factor of the current system (`nodes`' diagonal blocks, `rows`' couplings), or
    /// `None` where it is not positive definite (it is, with [`Linearization::Definite`]
    /// and positive masses) or faer could not take it.
    ///
    /// [`Linearization::Definite`]: crate::physics::Linearization::Definite
    pub(super) fn new(nodes: &[NodeSystem], rows: Rows, g: &Graph, single: bool) -> Option<Factor> {
        let (mut col_ptr, mut row_idx, mut values) = (Vec::new(), Vec::new(), Vec::new());
        lower_triangle(nodes, rows, g, &mut col_ptr, &mut row_idx, &mut values);
        let symbolic = analyse(nodes.len(), &col_ptr, &row_idx)?;
        let mut factor = Factor {
            nodes: nodes.len(),
            col_ptr,
            row_idx,
            values,
            solves: Solves::new(&symbolic, single)?,
            single,
            z: Vec::new(),
            l: vec![0.0; symbolic.len_val()],
            symbolic,
            stale: false,
            factorisations: 0,
        };
        let ok = factor.numeric();
        ok.then_some(factor)
    }

    /// Refactor where the last solve marked the factor stale, from the current system; on
    /// failure the factor is dropped (`false`).
    pub(super) fn refresh(&mut self, nodes: &[NodeSystem], rows: Rows, g: &Graph) -> bool {
        if !self.stale {
            return true;
        }
        let pattern = (self.col_ptr.clone(), self.row_idx.clone());
        lower_triangle(
            nodes,
            rows,
            g,
            &mut self.col_ptr,
            &mut self.row_idx,
            &mut self.values,
        );
        if self.nodes != nodes.len() || pattern != (self.col_ptr.clone(), self.row_idx.clone()) {
            // A cut changed the pattern: a new ordering and symbolic factorisation.
            let Some(symbolic) = analyse(nodes.len(), &self.col_ptr, &self.row_idx) else {
                return false;
            };
            let Some(solves) = Solves::new(&symbolic, self.single) else {
                return false;
            };
            self.solves = solves;
            self.l.resize(symbolic.len_val(), 0.0);
            self.symbolic = symbolic;
            self.nodes = nodes.len();
        }
        self.stale = false;
        self.numeric()
    }

    /// The numeric factorisation of the stored values; `false` where it failed.
    fn numeric(&mut self) -> bool {
        let n = 3 * self.nodes;
        // `lower_triangle` builds each column's rows sorted and without duplicates; the
        // checked constructor verifies it.
        let pattern =
            SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let a = SparseColMatRef::new(pattern, &self.values);
        let mut stack = MemBuffer::new(
            self.symbolic
                .factorize_numeric_llt_scratch::<Real>(Par::Seq, Default::default()),
        );
        self.factorisations += 1;
        let ok = self
            .symbolic
            .factorize_numeric_llt(
                &mut self.l,
                a,
                Side::Lower,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut stack),
                Default::default(),
            )
            .is_ok();
        match &mut self.solves {
            Solves::Single(t) => t.set(&self.l),
            Solves::Double(t) => t.set(&self.l),
        }
        ok
    }

    /// Whether the factor covers no more than `nodes` nodes (a cut only adds nodes; a
    /// factor of more nodes than the system has is dropped).
    pub(super) fn covers_at_most(&self, nodes: usize) -> bool {
        self.nodes <= nodes
    }

    /// After a solve of `iterations`: past [`REFRESH_ITERATIONS`] the next solve refactors.
    pub(super) fn observe(&mut self, iterations: u32) {
        if iterations > REFRESH_ITERATIONS {
            self.stale = true;
        }
    }

    /// `z = (L L^T)^-1 r` on the nodes the factor covers (`z` on the others, and on fixed
    /// nodes zero, left as the caller set it).
    pub(super) fn apply(&mut self, cg: &mut [Iterate], g: &Graph) {
        let n = self.nodes.min(cg.len());
        // Rows past the iterates (none: the factor covers at most the system's nodes) and
        // fixed nodes' rows (identity rows, their residual zero) read zero.
        let rhs = |k: usize| {
            let i = k / 3;
            if i < n {
                f64::from(cg[i].r[k % 3])
            } else {
                0.0
            }
        };
        let mut z = std::mem::take(&mut self.z);
        z.resize(3 * self.nodes, 0.0);
        let out = |k: usize, v: f64| z[k] = v as f32;
        match &mut self.solves {
            Solves::Single(t) => t.solve(rhs, out),
            Solves::Double(t) => t.solve(rhs, out),
        }
        for (i, it) in cg[..n].iter_mut().enumerate() {
            if g.fixed[i] {
                it.z = [0.0; 4];
                continue;
            }
            it.z = [z[3 * i], z[3 * i + 1], z[3 * i + 2], 0.0];
        }
        self.z = z;
    }

    /// The stored factor's nonzeros (for the memory report).
    pub(super) fn bytes(&self) -> u64 {
        let solves = match &self.solves {
            Solves::Single(t) => t.bytes(),
            Solves::Double(t) => t.bytes(),
        };
        (self.l.len() * 8 + self.values.len() * 12 + self.col_ptr.len() * 4) as u64 + solves
    }
}

/// The fill-reducing ordering and symbolic factorisation of a pattern.
fn analyse(nodes: usize, col_ptr: &[u32], row_idx: &[u32]) -> Option<SymbolicCholesky<u32>> {
    let n = 3 * nodes;
    let pattern = SymbolicSparseColMatRef::new_checked(n, n, col_ptr, None, row_idx);
    factorize_symbolic_cholesky(
        pattern,
        Side::Lower,
        SymmetricOrdering::Amd,
        CholeskySymbolicParams {
            // The solves read faer's supernodal structure (`implicit_factor_solve.rs`).
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
            ..Default::default()
        },
    )
    .ok()
}

/// The factor to precondition this solve with: taken where there is none (or a cut removed
/// nodes it covers), refactored where the last solve marked it stale; `None` where the
/// factorisation failed. Counts the factorisations and their time in `stats`.
pub(super) fn prepare<'a>(
    slot: &'a mut Option<Factor>,
    stats: &mut SolverStats,
    nodes: &[NodeSystem],
    blocks: Rows,
    g: &Graph,
    single: bool,
) -> Option<&'a mut Factor> {
    let started = std::time::Instant::now();
    let before = slot.as_ref().map_or(0, |f| f.factorisations);
    let kept = match slot {
        Some(f) => {
            f.single == single && f.covers_at_most(nodes.len()) && f.refresh(nodes, blocks, g)
        }
        None => false,
    };
    let mut taken = slot.as_ref().map_or(0, |f| f.factorisations) - before;
    if !kept {
        *slot = Factor::new(nodes, blocks, g, single);
        taken += 1;
    }
    if taken > 0 {
        stats.factorisations += taken;
        stats.factor_seconds += started.elapsed().as_secs_f64();
    }
    slot.as_mut()
}

/// `z = (L L^T)^-1 r` on the nodes the factor covers (block Jacobi's `z`, already in place,
/// on the others), filtered; returns `(r . r, r . z)`. Counts the application in `stats`.
pub(super) fn apply_factor(
    f: &mut Factor,
    cg: &mut [Iterate],
    partials: &mut [[f64; 2]],
    g: &Graph,
    held: &Held,
    stats: &mut SolverStats,
) -> [f64; 2] {
    stats.factor_solves += 1;
    f.apply(cg, g);
    over_blocks(cg, partials, |start, out| {
        held.filter(start, out, |it| &mut it.z);
        out.iter().fold([0.0; 2], |s, it| {
            [s[0] + dot64(it.r, it.r), s[1] + dot64(it.r, it.z)]
        })
    })
}
