//! The blocks of the implicit step's system as its passes read them (row by row, the springs'
//! symmetric blocks or the elements' full ones), each node's own system (`node_system`), and
//! the small 3x3 kernels of those passes.

use super::{Block, FullBlock, Lanes, NodeSystem, Sym};
use crate::engine::fast::{Params, P};

/// The system's off-diagonal blocks: the springs' symmetric ones or the elements' full ones.
#[derive(Clone, Copy)]
pub(super) enum Entries<'a> {
    Springs(&'a [Block]),
    Elements(&'a [FullBlock]),
}

/// The blocks, read row by row.
#[derive(Clone, Copy)]
pub(super) struct Rows<'a> {
    starts: &'a [u32],
    pub(super) entries: Entries<'a>,
    /// The springs' blocks lane by lane, for the product (empty for the elements).
    pub(super) lanes: &'a [Lanes],
    /// Whether the product may use the AVX2 and FMA build.
    pub(super) wide: bool,
}

impl Rows<'_> {
    /// How many blocks node `i`'s row has.
    #[inline(always)]
    pub(super) fn len(&self, i: usize) -> usize {
        (self.starts[i + 1] - self.starts[i]) as usize
    }

    /// `f(j, A_ij)` for each block of node `i`'s row, in row order: the system's own block
    /// (the negated spring block, or the negated element block, row major), in float64.
    #[cfg(feature = "factor")]
    pub(super) fn for_each_block(&self, i: usize, mut f: impl FnMut(usize, [[f64; 3]; 3])) {
        let range = self.starts[i] as usize..self.starts[i + 1] as usize;
        match self.entries {
            Entries::Springs(b) => {
                for b in &b[range] {
                    let s = b.s.map(|v| -f64::from(v));
                    f(
                        b.other as usize,
                        [[s[0], s[3], s[4]], [s[3], s[1], s[5]], [s[4], s[5], s[2]]],
                    );
                }
            }
            Entries::Elements(b) => {
                for b in &b[range] {
                    let m = b.m.map(|v| -f64::from(v));
                    f(
                        b.other as usize,
                        [[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]],
                    );
                }
            }
        }
    }

    /// `acc + sum B_ij w_j` (or `-`, with `subtract`) over the blocks `part` of node `i`'s row
    /// (offsets within it), in row order, skipping those where `w(j)` is `None`.
    #[inline(always)]
    pub(super) fn accumulate(
        &self,
        i: usize,
        part: std::ops::Range<usize>,
        mut acc: [f32; 3],
        subtract: bool,
        w: impl Fn(usize) -> Option<P>,
    ) -> [f32; 3] {
        let first = self.starts[i] as usize;
        let range = first + part.start..first + part.end;
        let mut add = |q: [f32; 3]| {
            for c in 0..3 {
                if subtract {
                    acc[c] -= q[c];
                } else {
                    acc[c] += q[c];
                }
            }
        };
        match self.entries {
            Entries::Springs(b) => {
                for b in &b[range] {
                    if let Some(wj) = w(b.other as usize) {
                        add(sym_mul(&b.s, wj));
                    }
                }
            }
            Entries::Elements(b) => {
                for b in &b[range] {
                    if let Some(wj) = w(b.other as usize) {
                        add(full_mul(&b.m, wj));
                    }
                }
            }
        }
        acc
    }
}

/// The rows of the springs' `blocks` (and their `lanes`) or, with `elements`, of the
/// elements' `full` blocks.
pub(super) fn rows_of<'a>(
    starts: &'a [u32],
    blocks: &'a [Block],
    full: &'a [FullBlock],
    lanes: &'a [Lanes],
    elements: bool,
    wide: bool,
) -> Rows<'a> {
    Rows {
        starts,
        entries: if elements {
            Entries::Elements(full)
        } else {
            Entries::Springs(blocks)
        },
        lanes,
        wide,
    }
}

/// A free node's system: its diagonal block and preconditioner, and the right-hand side from
/// its row's force `f` and `K v` (`kv`) with gravity and the mass damping, `h (F + h K v)` at the
/// step's start or `h F - M dv` at a Newton iterate (`dv` its velocity change so far); returns
/// it with `b . b`. Shared by the springs' and the finite elements' assembly.
pub(super) fn node_system(
    p: Params,
    m: f32,
    vi: P,
    (f, kv): ([f32; 3], [f32; 3]),
    dv: Option<P>,
    diag: Sym,
    lower: usize,
) -> (NodeSystem, f64) {
    let h = p.h;
    let mut b = [0.0f32; 4];
    for a in 0..3 {
        let total = f[a] + m * p.gravity[a] - p.alpha * m * vi[a];
        b[a] = match dv {
            None => h * (total + h * kv[a]),
            Some(dv) => h * total - m * dv[a],
        };
    }
    let system = NodeSystem {
        diag,
        inverse: inverse(&diag),
        b,
        lower: lower as u32,
    };
    (system, dot64(b, b))
}

/// An array of row blocks, written row by row from the assembly's tasks.
#[derive(Clone, Copy)]
pub(super) struct SharedRows<T>(pub(super) *mut T, pub(super) usize);

// SAFETY: the pointer is only used to write disjoint rows (see `SharedRows::row`), while the
// `Vec` it points into is borrowed mutably by the assembly and not otherwise touched.
unsafe impl<T> Send for SharedRows<T> {}
unsafe impl<T> Sync for SharedRows<T> {}

impl<T> SharedRows<T> {
    /// The blocks `first..end`.
    ///
    /// # Safety
    /// No two live calls may have overlapping ranges, and `first <= end <= len`.
    #[allow(clippy::mut_from_ref)]
    pub(super) unsafe fn row(&self, first: usize, end: usize) -> &mut [T] {
        assert!(first <= end && end <= self.1, "a row past the adjacency");
        std::slice::from_raw_parts_mut(self.0.add(first), end - first)
    }
}

pub(super) const IDENTITY: Sym = [1.0, 1.0, 1.0, 0.0, 0.0, 0.0];

/// `s w` for the symmetric `s`.
#[inline(always)]
pub(super) fn sym_mul(s: &Sym, w: P) -> [f32; 3] {
    [
        s[0] * w[0] + s[3] * w[1] + s[4] * w[2],
        s[3] * w[0] + s[1] * w[1] + s[5] * w[2],
        s[4] * w[0] + s[5] * w[1] + s[2] * w[2],
    ]
}

/// `m w` for the row-major `m`.
#[inline(always)]
pub(super) fn full_mul(m: &[f32; 9], w: P) -> [f32; 3] {
    [
        m[0] * w[0] + m[1] * w[1] + m[2] * w[2],
        m[3] * w[0] + m[4] * w[1] + m[5] * w[2],
        m[6] * w[0] + m[7] * w[1] + m[8] * w[2],
    ]
}

/// `a . b` over three components, in float64.
#[inline(always)]
pub(super) fn dot64(a: P, b: P) -> f64 {
    a[0] as f64 * b[0] as f64 + a[1] as f64 * b[1] as f64 + a[2] as f64 * b[2] as f64
}

/// The inverse of a symmetric block, formed in float64; the identity where it is singular (a
/// massless node with no springs), as the float64 integrator does.
pub(super) fn inverse(s: &Sym) -> Sym {
    let [a, b, c, d, e, f] = s.map(|v| v as f64);
    let cof = [
        b * c - f * f,
        a * c - e * e,
        a * b - d * d,
        e * f - d * c,
        d * f - b * e,
        d * e - a * f,
    ];
    let det = a * cof[0] + d * cof[3] + e * cof[4];
    if det == 0.0 || !det.is_finite() {
        return IDENTITY;
    }
    cof.map(|v| (v / det) as f32)
}
