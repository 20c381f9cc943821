//! Tool contact inside the fast engine's implicit solve: the float32 twin of the float64
//! integrator's filtering ([`crate::physics::contact_constraint`]).
//!
//! The constrained nodes are few (a tool's footprint), so they are kept as a list sorted by the
//! engine's internal node order, and each pass over a block of nodes finds its own by a binary
//! search: the product and the preconditioner project their normal parts out of the block's
//! constrained nodes, the right-hand side loses `A z` (the prescribed normal velocity changes'
//! product) before the solve and the solution gains `z` after it, and one more product gives
//! each constraint's impulse `n . (A dv - b)`.

use super::{dot64, over_blocks, product, rows_of, Implicit};
use crate::engine::fast::{Graph, Params, P};
use crate::physics::NodeConstraint;

/// One constrained node in internal order.
#[derive(Debug, Clone, Copy)]
pub(super) struct Hold {
    /// Internal node index.
    pub(super) rank: u32,
    /// The plane's unit normal.
    pub(super) normal: [f32; 3],
    /// The plane `normal . u = offset` in displacements from rest, m.
    pub(super) offset: f64,
    /// The normal velocity change that puts the node on the plane this step, m/s.
    pub(super) z: f32,
    /// The node's right-hand side before the filtering, for its impulse.
    pub(super) b: [f32; 3],
    /// Where the constraint was in the list given.
    pub(super) index: u32,
}

/// The constrained nodes and the force each constraint put on its node in the last step.
#[derive(Debug, Clone, Default)]
pub(in crate::engine::fast) struct Held {
    pub(super) list: Vec<Hold>,
    /// Per constraint as given, N (zero for one skipped: a fixed node, a node given twice).
    pub(in crate::engine::fast) forces: Vec<f64>,
}

impl Held {
    /// The constraints of `given` (model indices) in internal order, `rank` mapping model to
    /// internal indices and `rest` giving model rest positions; fixed nodes and repeats are
    /// skipped.
    pub(in crate::engine::fast) fn new(
        given: &[NodeConstraint],
        rank: &[u32],
        fixed: &[bool],
        rest: &[[f64; 3]],
    ) -> Self {
        let mut list: Vec<Hold> = given
            .iter()
            .enumerate()
            .filter(|(_, c)| !fixed[rank[c.node as usize] as usize])
            .map(|(k, c)| {
                let r = rest[c.node as usize];
                let n = c.normal;
                Hold {
                    rank: rank[c.node as usize],
                    normal: n.map(|a| a as f32),
                    offset: c.offset - (n[0] * r[0] + n[1] * r[1] + n[2] * r[2]),
                    z: 0.0,
                    b: [0.0; 3],
                    index: k as u32,
                }
            })
            .collect();
        list.sort_by_key(|h| (h.rank, h.index));
        list.dedup_by_key(|h| h.rank);
        Held {
            list,
            forces: vec![0.0; given.len()],
        }
    }

    /// The constrained nodes among internal nodes `start..end`.
    pub(super) fn within(&self, start: usize, end: usize) -> &[Hold] {
        let a = self.list.partition_point(|h| (h.rank as usize) < start);
        let b = self.list.partition_point(|h| (h.rank as usize) < end);
        &self.list[a..b]
    }

    /// Remove the normal parts of the constrained nodes among those of `out`, which holds
    /// internal nodes from `start` on, read through `at`.
    pub(super) fn filter<T>(&self, start: usize, out: &mut [T], at: impl Fn(&mut T) -> &mut P) {
        for h in self.within(start, start + out.len()) {
            project(at(&mut out[h.rank as usize - start]), h.normal);
        }
    }
}

/// `a - n (n . a)` in place.
pub(super) fn project(a: &mut P, n: [f32; 3]) {
    let d = a[0] * n[0] + a[1] * n[1] + a[2] * n[2];
    for c in 0..3 {
        a[c] -= d * n[c];
    }
}

/// Before a solve, with constraints: each constrained node's right-hand side kept for its
/// impulse, then, at the step's first solve (`start` is the step's `(u, v)`), its normal
/// velocity change `z` prescribed, `b -= A z` and the warm start's normal parts removed; the
/// constrained nodes' normal parts filtered out of `b`. Returns the new `b . b` (`bb` itself
/// without constraints).
pub(super) fn constrain(
    imp: &mut Implicit,
    g: &Graph,
    p: Params,
    start: Option<(&[P], &[P])>,
    bb: f64,
) -> f64 {
    if imp.held.list.is_empty() {
        return bb;
    }
    let h = p.h as f64;
    for hold in &mut imp.held.list {
        let i = hold.rank as usize;
        let n = hold.normal.map(f64::from);
        hold.b = [0, 1, 2].map(|c| imp.nodes[i].b[c]);
        hold.z = match start {
            Some((x, v)) => {
                let along = |a: P| (0..3).map(|c| n[c] * a[c] as f64).sum::<f64>();
                ((hold.offset - along(x[i])) / h - along(v[i])) as f32
            }
            None => 0.0,
        };
    }
    if start.is_some() {
        imp.p.iter_mut().for_each(|q| *q = [0.0; 4]);
        for hold in &imp.held.list {
            let z = hold.normal.map(|a| a * hold.z);
            imp.p[hold.rank as usize] = [z[0], z[1], z[2], 0.0];
        }
        let rows = rows_of(
            &imp.starts,
            &imp.blocks,
            &imp.full,
            &imp.lanes,
            imp.elements,
            imp.wide,
        );
        product(
            g,
            rows,
            &imp.nodes,
            &imp.p,
            &mut imp.ap,
            &mut imp.partials,
            None,
        );
        let ap = &imp.ap[..];
        over_blocks(&mut imp.nodes, &mut imp.partials, |start, out| {
            for (node, a) in out.iter_mut().zip(&ap[start..]) {
                for (b, a) in node.b.iter_mut().zip(a).take(3) {
                    *b -= a;
                }
            }
            [0.0; 2]
        });
        for hold in &imp.held.list {
            project(&mut imp.dv[hold.rank as usize], hold.normal);
        }
    }
    for hold in &imp.held.list {
        project(&mut imp.nodes[hold.rank as usize].b, hold.normal);
    }
    let [bb, _] = over_blocks(&mut imp.nodes, &mut imp.partials, |_, out| {
        [out.iter().map(|node| dot64(node.b, node.b)).sum(), 0.0]
    });
    bb
}

/// After a solve, with constraints: the prescribed normal velocity changes added to the
/// solution (at the step's first solve), and each constraint's force read from its impulse,
/// `n . (A y - b) / h` with the right-hand side kept before the filtering.
pub(super) fn impulses(imp: &mut Implicit, g: &Graph, p: Params, first: bool) {
    if imp.held.list.is_empty() {
        return;
    }
    if first {
        for hold in &imp.held.list {
            let y = &mut imp.cg[hold.rank as usize].y;
            for (y, n) in y.iter_mut().zip(hold.normal) {
                *y += n * hold.z;
            }
        }
    }
    let cg = &imp.cg[..];
    over_blocks(&mut imp.p, &mut imp.partials, |start, out| {
        for (k, q) in out.iter_mut().enumerate() {
            *q = cg[start + k].y;
        }
        [0.0; 2]
    });
    product(
        g,
        rows_of(
            &imp.starts,
            &imp.blocks,
            &imp.full,
            &imp.lanes,
            imp.elements,
            imp.wide,
        ),
        &imp.nodes,
        &imp.p,
        &mut imp.ap,
        &mut imp.partials,
        None,
    );
    let Held { list, forces } = &mut imp.held;
    forces.iter_mut().for_each(|f| *f = 0.0);
    for hold in list.iter() {
        let a = imp.ap[hold.rank as usize];
        let impulse: f64 = (0..3)
            .map(|c| hold.normal[c] as f64 * (a[c] as f64 - hold.b[c] as f64))
            .sum();
        forces[hold.index as usize] = impulse / p.h as f64;
    }
}
