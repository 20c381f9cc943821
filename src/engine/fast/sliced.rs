//! The springs as the explicit step reads them: slices of [`LANES`] consecutive nodes, each
//! slice's rows padded to its longest and stored column by column (a "sliced ELLPACK" layout),
//! so that one SIMD lane evaluates one node's springs and the lanes of a group are eight
//! nodes' k-th springs. A node's forces then sum in its own lane, in row order, with no
//! horizontal reduction, and the square roots and divisions of eight springs are one
//! instruction each; the row-wise adjacency (`Graph`) stays the source the patch path, the
//! implicit solve and the finite elements read, and a patch rewrites only the slices of the
//! rows it edited.
//!
//! Per spring end a group stores 24 bytes: the neighbour (u32), the rest edge vector and the
//! rest length and stiffness (f32), plus 4 bytes of damping in a parallel array when any spring
//! is damped. Padding lanes point at their own node with zero edge and zero stiffness, so
//! they contribute exactly nothing (a zero-length spring has no direction: see
//! [`group_force`]).

use super::{Graph, P};

/// Nodes per slice: one AVX2 vector of f32.
pub(super) const LANES: usize = 8;

/// The k-th spring of the eight nodes of a slice.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(32))]
pub(super) struct Group {
    /// The other end of each lane's spring, internal index (the lane's own node for padding).
    pub other: [u32; LANES],
    /// Rest vector from the lane's node to the other end, per axis, m.
    pub edge: [[f32; LANES]; 3],
    /// Rest length, m.
    pub rest: [f32; LANES],
    /// Stiffness, N/m (0 for padding).
    pub k: [f32; LANES],
}

/// The sliced layout of a [`Graph`]'s rows.
pub(super) struct Sliced {
    /// Each slice's groups, as (start, width): `groups[start..start + width]`. A patch
    /// rewrites a slice in place when it does not widen and appends it otherwise, leaving a
    /// hole until the layout is rebuilt.
    pub slices: Vec<[u32; 2]>,
    pub groups: Vec<Group>,
    /// Damping of each lane's spring, N s/m (empty when no spring is damped).
    pub damping: Vec<[f32; LANES]>,
    /// Groups no slice uses.
    pub holes: usize,
    /// Whether `damping` is kept (fixed for the layout's life: the first damped spring of an
    /// undamped model rebuilds the engine).
    damped: bool,
}

impl Sliced {
    /// The layout of every row of `g`.
    pub fn build(g: &Graph) -> Self {
        let n = g.rows.len();
        let count = n.div_ceil(LANES);
        let damped = !g.damping.is_empty();
        let mut s = Sliced {
            slices: Vec::with_capacity(count + crate::model::room::spare(count)),
            groups: Vec::new(),
            damping: Vec::new(),
            holes: 0,
            damped,
        };
        let width: usize = (0..count).map(|b| slice_width(g, b)).sum();
        let room = width + crate::model::room::spare(width);
        s.groups.reserve(room);
        if damped {
            s.damping.reserve(room);
        }
        for b in 0..count {
            let w = slice_width(g, b);
            let at = s.groups.len();
            s.append(w);
            s.write(g, b, at, w);
            s.slices.push([at as u32, (at + w) as u32]);
        }
        s
    }

    /// Bring the slices of the nodes in `touched` (internal indices; rows edited or added) up
    /// to date with `g`. Returns the groups written and whether the layout was rebuilt whole
    /// (when holes passed a quarter of it).
    pub fn patch(&mut self, g: &Graph, touched: impl IntoIterator<Item = usize>) -> (usize, bool) {
        let count = g.rows.len().div_ceil(LANES);
        let mut dirty: Vec<usize> = touched.into_iter().map(|i| i / LANES).collect();
        // Slices new nodes made or filled.
        dirty.extend(self.slices.len().saturating_sub(1)..count);
        dirty.sort_unstable();
        dirty.dedup();
        let mut written = 0;
        for b in dirty {
            let w = slice_width(g, b);
            let at = match self.slices.get(b) {
                Some(&[start, end]) if (end - start) as usize >= w => {
                    self.holes += (end - start) as usize - w;
                    start as usize
                }
                old => {
                    if let Some(&[start, end]) = old {
                        self.holes += (end - start) as usize;
                    }
                    let at = self.groups.len();
                    self.append(w);
                    at
                }
            };
            self.write(g, b, at, w);
            let range = [at as u32, (at + w) as u32];
            if b < self.slices.len() {
                self.slices[b] = range;
            } else {
                self.slices.push(range);
            }
            written += w;
        }
        if self.holes * 4 > self.groups.len() {
            *self = Sliced::build(g);
            return (self.groups.len(), true);
        }
        (written, false)
    }

    /// The first slice whose groups differ from `other`'s, bit for bit (damping missing on one
    /// side reads as zeros), or whose count differs.
    pub fn first_difference(&self, other: &Sliced) -> Option<usize> {
        let bits = |s: &Sliced, b: usize| -> Vec<u32> {
            let [start, end] = s.slices[b];
            (start as usize..end as usize)
                .flat_map(|k| {
                    let g = &s.groups[k];
                    let c = s.damping.get(k).copied().unwrap_or([0.0; LANES]);
                    let floats = g.edge.iter().chain([&g.rest, &g.k, &c]).flatten();
                    g.other
                        .into_iter()
                        .chain(floats.map(|f| f.to_bits()))
                        .collect::<Vec<_>>()
                })
                .collect()
        };
        let n = self.slices.len().max(other.slices.len());
        (0..n).find(|&b| {
            b >= self.slices.len() || b >= other.slices.len() || bits(self, b) != bits(other, b)
        })
    }

    /// Bytes of groups no slice uses and of padding lanes, given the live entries of the rows.
    pub fn padding_bytes(&self, entries: usize) -> u64 {
        let lanes = (self.groups.len() - self.holes) * LANES;
        let per_lane = (self.group_bytes() / LANES) as u64;
        (self.holes * self.group_bytes()) as u64 + lanes.saturating_sub(entries) as u64 * per_lane
    }

    /// Bytes per group, damping included where kept.
    pub fn group_bytes(&self) -> usize {
        std::mem::size_of::<Group>()
            + if self.damping.is_empty() {
                0
            } else {
                std::mem::size_of::<[f32; LANES]>()
            }
    }

    fn append(&mut self, w: usize) {
        let blank = Group {
            other: [0; LANES],
            edge: [[0.0; LANES]; 3],
            rest: [0.0; LANES],
            k: [0.0; LANES],
        };
        self.groups.resize(self.groups.len() + w, blank);
        if self.damped {
            self.damping.resize(self.groups.len(), [0.0; LANES]);
        }
    }

    /// Write slice `b`'s rows into `w` groups from `at`, padding lanes with null springs.
    fn write(&mut self, g: &Graph, b: usize, at: usize, w: usize) {
        let damped = self.damped;
        for k in 0..w {
            let grp = &mut self.groups[at + k];
            for l in 0..LANES {
                let i = b * LANES + l;
                // A node past the end points at node 0; its lane's result is never stored.
                let own = if i < g.rows.len() { i as u32 } else { 0 };
                let [start, end] = g.rows.get(i).copied().unwrap_or([0, 0]);
                let e = start as usize + k;
                if e < end as usize {
                    let a = &g.adj[e];
                    grp.other[l] = a.other;
                    for c in 0..3 {
                        grp.edge[c][l] = a.edge[c];
                    }
                    grp.rest[l] = a.rest;
                    grp.k[l] = a.k;
                    if damped {
                        self.damping[at + k][l] = g.damping[e];
                    }
                } else {
                    grp.other[l] = own;
                    for c in 0..3 {
                        grp.edge[c][l] = 0.0;
                    }
                    grp.rest[l] = 0.0;
                    grp.k[l] = 0.0;
                    if damped {
                        self.damping[at + k][l] = 0.0;
                    }
                }
            }
        }
    }
}

/// The longest row of slice `b`.
fn slice_width(g: &Graph, b: usize) -> usize {
    let end = ((b + 1) * LANES).min(g.rows.len());
    (b * LANES..end)
        .map(|i| (g.rows[i][1] - g.rows[i][0]) as usize)
        .max()
        .unwrap_or(0)
}

/// Eight lanes of three axes.
pub(super) type V3 = [[f32; LANES]; 3];

/// The spring force of one group on its eight nodes, added to `acc`: elastic `k (l - L) / l`
/// times the spring vector `e + (u_j - u_i)`, plus, when `DAMPED`, `c ((w_j - w_i) . d) / l^2`
/// times it, `w` scaled by `w_scale`. A zero-length spring (padding, or coincident nodes) has
/// no direction and gives nothing, as in the reference engine.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn group_force<const DAMPED: bool>(
    grp: &Group,
    c: &[f32; LANES],
    x: &[P],
    w: &[P],
    ui: &V3,
    wi: &V3,
    w_scale: f32,
    acc: &mut V3,
) {
    let mut d = [[0.0f32; LANES]; 3];
    let mut dw = [[0.0f32; LANES]; 3];
    for l in 0..LANES {
        let j = grp.other[l] as usize;
        let uj = x[j];
        for a in 0..3 {
            d[a][l] = grp.edge[a][l] + (uj[a] - ui[a][l]);
        }
        if DAMPED {
            let wj = w[j];
            for a in 0..3 {
                dw[a][l] = wj[a] - wi[a][l];
            }
        }
    }
    for l in 0..LANES {
        let l2 = d[0][l] * d[0][l] + d[1][l] * d[1][l] + d[2][l] * d[2][l];
        let inv_raw = 1.0 / l2.sqrt();
        let inv = if l2 > 0.0 { inv_raw } else { 0.0 };
        let mut s = grp.k[l] * (1.0 - grp.rest[l] * inv);
        if DAMPED {
            let along = dw[0][l] * d[0][l] + dw[1][l] * d[1][l] + dw[2][l] * d[2][l];
            s += c[l] * along * w_scale * inv * inv;
        }
        for a in 0..3 {
            acc[a][l] += s * d[a][l];
        }
    }
}
