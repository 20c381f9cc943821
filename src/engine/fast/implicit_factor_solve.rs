//! The triangular solves of the factored preconditioner (`implicit_factor.rs`): `z = (L
//! L^T)^-1 r` over faer's supernodal factor, read out of faer's symbolic structure into a copy
//! of the factor in the precision the solve streams (float32 by default: half the bytes of
//! float64, and the solves are bound by the bytes they read), and split over two threads along
//! the elimination tree.
//!
//! A supernode's columns update only the rows of its ancestors, so two disjoint subtrees of
//! the elimination tree are independent: the forward solve runs two groups of subtrees on two
//! threads, each collecting its updates to the rows above the subtrees (the "top": the
//! separators the ordering put last) in a scratch of its own, adds both scratches to the top
//! rows in a fixed order, and finishes the top on one thread; the backward solve runs the top
//! first and the two groups after it, which read the top's final rows and write only their
//! own. The groups are chosen once per symbolic factorisation by splitting the heaviest
//! subtree until the two groups' nonzeros balance. The arithmetic of each row does not depend
//! on the threads (the two scratches are added in the same order either way), so one thread and
//! two give the same bits.

use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};

/// The scalar the solve streams: float32 or float64.
pub(super) trait Real: Copy + Default + Send + Sync + 'static {
    /// The value of a float64.
    fn of(v: f64) -> Self;
    /// As a float64.
    fn get(self) -> f64;
    /// `self - a * b`.
    fn sub_mul(self, a: Self, b: Self) -> Self;
    /// `self + a * b`.
    fn add_mul(self, a: Self, b: Self) -> Self;
    /// `self / d`.
    fn div(self, d: Self) -> Self;
    /// `self + a`.
    fn add(self, a: Self) -> Self;
}

macro_rules! real {
    ($t:ty) => {
        impl Real for $t {
            #[inline(always)]
            fn of(v: f64) -> Self {
                v as $t
            }
            #[inline(always)]
            fn get(self) -> f64 {
                self as f64
            }
            #[inline(always)]
            fn sub_mul(self, a: Self, b: Self) -> Self {
                self - a * b
            }
            #[inline(always)]
            fn add_mul(self, a: Self, b: Self) -> Self {
                self + a * b
            }
            #[inline(always)]
            fn div(self, d: Self) -> Self {
                self / d
            }
            #[inline(always)]
            fn add(self, a: Self) -> Self {
                self + a
            }
        }
    };
}
real!(f32);
real!(f64);

/// Which group of subtrees a supernode belongs to; [`TOP`] the supernodes above the groups.
const TOP: u8 = 2;

/// A supernodal factor `L` in the permuted order, with the permutation, the schedule of the
/// two groups and the scratch of the solves.
pub(super) struct Triangular<T: Real> {
    /// `fwd[i]`: the original row of permuted row `i`.
    fwd: Vec<u32>,
    /// The factor: its supernodes' structure and values.
    factor: Factor<T>,
    /// The supernodes of each group, ascending, and those of the top.
    groups: [Vec<u32>; 2],
    top: Vec<u32>,
    /// The permuted right-hand side and solution, and the groups' scratches for the top rows.
    x: Vec<T>,
    acc: [Vec<T>; 2],
    /// Each thread's gathered rows below a supernode (the longest list of them).
    tmp: [Vec<T>; 2],
}

/// The supernodal structure of `symbolic` (`None` for a simplicial one).
fn supernodal(
    symbolic: &SymbolicCholesky<u32>,
) -> Option<&faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky<u32>> {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Supernodal(s) => Some(s),
        SymbolicCholeskyRaw::Simplicial(_) => None,
    }
}

impl<T: Real> Triangular<T> {
    /// The structure and schedule of `symbolic` (supernodal; `None` otherwise), the values
    /// not yet set ([`Triangular::set`]).
    pub(super) fn new(symbolic: &SymbolicCholesky<u32>) -> Option<Self> {
        let s = supernodal(symbolic)?;
        let n = s.nrows();
        let fwd = match symbolic.perm() {
            Some(p) => p.arrays().0.to_vec(),
            None => (0..n as u32).collect(),
        };
        let ns = s.n_supernodes();
        let begin: Vec<u32> = s
            .supernode_begin()
            .iter()
            .copied()
            .chain([n as u32])
            .collect();
        let pat = s.col_ptr_for_row_idx().to_vec();
        let val: Vec<usize> = s.col_ptr_for_val().iter().map(|&v| v as usize).collect();
        let rows = s.row_idx().to_vec();
        // The parent of a supernode: the one holding its first row below the diagonal block.
        let mut owner_of_col = vec![0u32; n];
        for sn in 0..ns {
            for c in begin[sn]..begin[sn + 1] {
                owner_of_col[c as usize] = sn as u32;
            }
        }
        let parent: Vec<Option<u32>> = (0..ns)
            .map(|sn| {
                let (a, b) = (pat[sn] as usize, pat[sn + 1] as usize);
                (a < b).then(|| owner_of_col[rows[a] as usize])
            })
            .collect();
        let weight: Vec<u64> = (0..ns).map(|sn| (val[sn + 1] - val[sn]) as u64).collect();
        let (groups, top) = schedule(&parent, &weight);
        let longest = (0..ns).map(|sn| (pat[sn + 1] - pat[sn]) as usize).max();
        let longest = longest.unwrap_or(0);
        Some(Triangular {
            fwd,
            factor: Factor {
                begin,
                pat,
                rows,
                l: vec![T::default(); *val.last().unwrap_or(&0)],
                val,
                #[cfg(target_arch = "x86_64")]
                wide: std::is_x86_feature_detected!("avx2"),
                #[cfg(not(target_arch = "x86_64"))]
                wide: false,
            },
            groups,
            top,
            x: vec![T::default(); n],
            acc: [vec![T::default(); n], vec![T::default(); n]],
            tmp: [vec![T::default(); longest], vec![T::default(); longest]],
        })
    }

    /// Take the numeric factor's values (faer's, in float64) in this precision.
    pub(super) fn set(&mut self, values: &[f64]) {
        for (l, v) in self.factor.l.iter_mut().zip(values) {
            *l = T::of(*v);
        }
    }

    /// The bytes the factor and its structure take.
    pub(super) fn bytes(&self) -> u64 {
        let f = &self.factor;
        (f.l.len() * std::mem::size_of::<T>() + (f.rows.len() + 3 * self.fwd.len()) * 4) as u64
    }

    /// `out = (L L^T)^-1 b` (`b`, `out` in the original order, `b` read through `rhs(i)`).
    pub(super) fn solve(&mut self, rhs: impl Fn(usize) -> f64, mut out: impl FnMut(usize, f64)) {
        for (x, &f) in self.x.iter_mut().zip(&self.fwd) {
            *x = T::of(rhs(f as usize));
        }
        self.forward();
        self.backward();
        for (x, &f) in self.x.iter().zip(&self.fwd) {
            out(f as usize, x.get());
        }
    }

    /// `L y = x` in place.
    fn forward(&mut self) {
        let Triangular {
            factor: f,
            groups,
            top,
            x,
            acc,
            tmp,
            ..
        } = self;
        let f = &*f;
        let shared = Shared(x.as_mut_ptr());
        let [acc0, acc1] = acc;
        let [tmp0, tmp1] = tmp;
        let run = |group: &[u32], acc: &mut [T], tmp: &mut [T]| {
            // SAFETY: a group writes its own supernodes' rows of `x` and its own `acc`; the
            // two groups' subtrees are disjoint, so the two threads never touch the same row
            // of `x`.
            unsafe { f.forward_list(group, shared, Some(acc), tmp) };
        };
        join(
            || run(&groups[0], acc0, tmp0),
            || run(&groups[1], acc1, tmp1),
        );
        let shared = Shared(x.as_mut_ptr());
        for &sn in top.iter() {
            let (c0, c1) = (
                f.begin[sn as usize] as usize,
                f.begin[sn as usize + 1] as usize,
            );
            for i in c0..c1 {
                // SAFETY: one thread, and `shared` is `x`'s only pointer in use.
                unsafe {
                    *shared.0.add(i) = (*shared.0.add(i)).sub_mul(acc0[i].add(acc1[i]), T::of(1.0))
                };
                acc0[i] = T::default();
                acc1[i] = T::default();
            }
        }
        // SAFETY: one thread.
        unsafe { f.forward_list(top, shared, None, tmp0) };
    }

    /// `L^T z = y` in place.
    fn backward(&mut self) {
        let Triangular {
            factor: f,
            groups,
            top,
            x,
            tmp,
            ..
        } = self;
        let f = &*f;
        let shared = Shared(x.as_mut_ptr());
        let [tmp0, tmp1] = tmp;
        // SAFETY: one thread.
        unsafe { f.backward_list(top, shared, tmp0) };
        let run = |group: &[u32], tmp: &mut [T]| {
            // SAFETY: a group writes only its own supernodes' rows and reads those and the
            // top's (final by now); the groups' rows are disjoint.
            unsafe { f.backward_list(group, shared, tmp) };
        };
        join(|| run(&groups[0], tmp0), || run(&groups[1], tmp1));
    }
}

/// The factor's supernodes: their structure and values, which the solves read (the
/// solution and scratch vectors, which they write, are [`Triangular`]'s own fields).
struct Factor<T> {
    /// Supernode `s` holds columns `begin[s]..begin[s + 1]`.
    begin: Vec<u32>,
    /// Supernode `s`'s rows below its diagonal block: `rows[pat[s]..pat[s + 1]]`, ascending.
    pat: Vec<u32>,
    rows: Vec<u32>,
    /// Supernode `s`'s values, column major (its columns' rows, the diagonal block's first):
    /// `l[val[s]..val[s + 1]]`.
    val: Vec<usize>,
    l: Vec<T>,
    /// Whether the CPU has AVX2: the solves are compiled a second time for it (the same
    /// operations in the same order, on wider vectors: the same bits).
    wide: bool,
}

/// The solution vector, shared by the two groups, which write disjoint rows.
#[derive(Clone, Copy)]
struct Shared<T>(*mut T);
// SAFETY: the groups write disjoint rows (see `forward` and `backward`).
unsafe impl<T: Send> Send for Shared<T> {}
// SAFETY: as above.
unsafe impl<T: Send> Sync for Shared<T> {}

impl<T: Real> Factor<T> {
    /// [`Factor::forward_one`] over `list` in order, compiled for AVX2 where the CPU has it.
    ///
    /// # Safety
    /// As [`Factor::forward_one`], for every supernode of `list`.
    unsafe fn forward_list(
        &self,
        list: &[u32],
        x: Shared<T>,
        acc: Option<&mut [T]>,
        tmp: &mut [T],
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.wide {
            // SAFETY: `wide` only where the CPU reported AVX2; the caller's contract.
            return unsafe { self.forward_list_wide(list, x, acc, tmp) };
        }
        // SAFETY: the caller's contract.
        unsafe { self.forward_list_in(list, x, acc, tmp) }
    }

    /// [`Factor::forward_list`] for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn forward_list_wide(
        &self,
        list: &[u32],
        x: Shared<T>,
        acc: Option<&mut [T]>,
        tmp: &mut [T],
    ) {
        // SAFETY: the caller's contract.
        unsafe { self.forward_list_in(list, x, acc, tmp) }
    }

    #[inline(always)]
    unsafe fn forward_list_in(
        &self,
        list: &[u32],
        x: Shared<T>,
        mut acc: Option<&mut [T]>,
        tmp: &mut [T],
    ) {
        for &sn in list {
            // SAFETY: the caller's contract.
            unsafe { self.forward_one(sn as usize, x, acc.as_deref_mut(), tmp) };
        }
    }

    /// [`Factor::backward_one`] over `list` in reverse order, compiled for AVX2 where the CPU
    /// has it.
    ///
    /// # Safety
    /// As [`Factor::backward_one`], for every supernode of `list`.
    unsafe fn backward_list(&self, list: &[u32], x: Shared<T>, tmp: &mut [T]) {
        #[cfg(target_arch = "x86_64")]
        if self.wide {
            // SAFETY: `wide` only where the CPU reported AVX2; the caller's contract.
            return unsafe { self.backward_list_wide(list, x, tmp) };
        }
        // SAFETY: the caller's contract.
        unsafe { self.backward_list_in(list, x, tmp) }
    }

    /// [`Factor::backward_list`] for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn backward_list_wide(&self, list: &[u32], x: Shared<T>, tmp: &mut [T]) {
        // SAFETY: the caller's contract.
        unsafe { self.backward_list_in(list, x, tmp) }
    }

    #[inline(always)]
    unsafe fn backward_list_in(&self, list: &[u32], x: Shared<T>, tmp: &mut [T]) {
        for &sn in list.iter().rev() {
            // SAFETY: the caller's contract.
            unsafe { self.backward_one(sn as usize, x, tmp) };
        }
    }

    /// Supernode `sn`'s forward step: the updates its descendants gathered for its rows in
    /// `acc` (where given) subtracted, its diagonal block's solve, then its rows below updated:
    /// in `acc` (a group's: the rows below are its own subtree's or the top's, and `acc` is
    /// the group's own), or in `x` directly (the top, on one thread). The update is formed in
    /// `tmp`, column after column (contiguous reads the compiler vectorises), and scattered
    /// once.
    ///
    /// # Safety
    /// No other thread may touch supernode `sn`'s rows, nor, without `acc`, its rows below.
    #[inline(always)]
    unsafe fn forward_one(&self, sn: usize, x: Shared<T>, acc: Option<&mut [T]>, tmp: &mut [T]) {
        let (c0, c1) = (self.begin[sn] as usize, self.begin[sn + 1] as usize);
        let size = c1 - c0;
        let below = &self.rows[self.pat[sn] as usize..self.pat[sn + 1] as usize];
        let m = below.len();
        let nrows = size + m;
        let l = &self.l[self.val[sn]..self.val[sn + 1]];
        // SAFETY: rows `c0..c1` are this supernode's, owned by the caller's thread.
        let xs = unsafe { std::slice::from_raw_parts_mut(x.0.add(c0), size) };
        if let Some(acc) = &acc {
            for (x, a) in xs.iter_mut().zip(&acc[c0..c1]) {
                *x = x.sub_mul(*a, T::of(1.0));
            }
        }
        let tmp = &mut tmp[..m];
        tmp.fill(T::default());
        for j in 0..size {
            let col = &l[j * nrows..(j + 1) * nrows];
            let xj = xs[j].div(col[j]);
            xs[j] = xj;
            for (x, c) in xs[j + 1..].iter_mut().zip(&col[j + 1..size]) {
                *x = x.sub_mul(*c, xj);
            }
            for (t, c) in tmp.iter_mut().zip(&col[size..]) {
                *t = t.add_mul(*c, xj);
            }
        }
        match acc {
            Some(acc) => {
                acc[c0..c1].fill(T::default());
                for (&r, t) in below.iter().zip(tmp.iter()) {
                    acc[r as usize] = acc[r as usize].add(*t);
                }
            }
            None => {
                for (&r, t) in below.iter().zip(tmp.iter()) {
                    // SAFETY: one thread (the caller's contract).
                    unsafe {
                        let x = x.0.add(r as usize);
                        *x = (*x).sub_mul(*t, T::of(1.0));
                    }
                }
            }
        }
    }

    /// Supernode `sn`'s backward step: its rows below (final) gathered into `tmp` and
    /// subtracted, then its diagonal block's transposed solve.
    ///
    /// # Safety
    /// Supernode `sn`'s rows below must be final and no other thread may write them or
    /// touch `sn`'s own rows.
    #[inline(always)]
    unsafe fn backward_one(&self, sn: usize, x: Shared<T>, tmp: &mut [T]) {
        let (c0, c1) = (self.begin[sn] as usize, self.begin[sn + 1] as usize);
        let size = c1 - c0;
        let below = &self.rows[self.pat[sn] as usize..self.pat[sn + 1] as usize];
        let m = below.len();
        let nrows = size + m;
        let l = &self.l[self.val[sn]..self.val[sn + 1]];
        let tmp = &mut tmp[..m];
        for (t, &r) in tmp.iter_mut().zip(below) {
            // SAFETY: rows below `sn` are final and written by no one now.
            *t = unsafe { *x.0.add(r as usize) };
        }
        // SAFETY: rows `c0..c1` are this supernode's, owned by the caller's thread.
        let xs = unsafe { std::slice::from_raw_parts_mut(x.0.add(c0), size) };
        for j in (0..size).rev() {
            let col = &l[j * nrows..(j + 1) * nrows];
            let s = xs[j]
                .sub_mul(dot(&col[size..], tmp), T::of(1.0))
                .sub_mul(dot(&col[j + 1..size], &xs[j + 1..]), T::of(1.0));
            xs[j] = s.div(col[j]);
        }
    }
}

/// `a . b` in eight interleaved partial sums (so that the compiler vectorises it; the order is
/// fixed, so the bits are too).
#[inline(always)]
fn dot<T: Real>(a: &[T], b: &[T]) -> T {
    let mut acc = [T::default(); 8];
    let (a8, b8) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ar, br) = (a8.remainder(), b8.remainder());
    for (a, b) in a8.zip(b8) {
        for k in 0..8 {
            acc[k] = acc[k].add_mul(a[k], b[k]);
        }
    }
    let mut s = T::default();
    for (a, b) in ar.iter().zip(br) {
        s = s.add_mul(*a, *b);
    }
    let [a0, a1, a2, a3, a4, a5, a6, a7] = acc;
    s.add(a0.add(a4).add(a1.add(a5)).add(a2.add(a6).add(a3.add(a7))))
}

/// Two groups of subtrees with balanced weights, and the supernodes above them (run on one
/// thread): starting from the roots, the heaviest subtree is split again and again (its root
/// goes to the top, its children become candidates), the candidates dealt heaviest first to
/// the lighter group; of all the splits tried, the one with the least `top + max(group)` (the
/// solve's time on two threads, in nonzeros) is kept.
fn schedule(parent: &[Option<u32>], weight: &[u64]) -> ([Vec<u32>; 2], Vec<u32>) {
    let ns = parent.len();
    let mut children: Vec<Vec<u32>> = vec![Vec::new(); ns];
    let mut subtree = weight.to_vec();
    // Children come before their parents (faer's supernodes are in a topological order).
    for sn in 0..ns {
        if let Some(p) = parent[sn] {
            children[p as usize].push(sn as u32);
            subtree[p as usize] += subtree[sn];
        }
    }
    let deal = |candidates: &[u32]| {
        let mut sorted = candidates.to_vec();
        sorted.sort_by_key(|&sn| (std::cmp::Reverse(subtree[sn as usize]), sn));
        let mut bins = [0u64; 2];
        let mut dealt = Vec::with_capacity(sorted.len());
        for sn in sorted {
            let b = usize::from(bins[1] < bins[0]);
            bins[b] += subtree[sn as usize];
            dealt.push((sn, b as u8));
        }
        (bins[0].max(bins[1]), dealt)
    };
    let mut candidates: Vec<u32> = (0..ns as u32)
        .filter(|&sn| parent[sn as usize].is_none())
        .collect();
    let mut expanded: Vec<u32> = Vec::new();
    let mut top_weight = 0u64;
    let (heavier, dealt) = deal(&candidates);
    let mut best = (heavier, 0usize, dealt);
    while let Some((at, _)) = candidates
        .iter()
        .enumerate()
        .max_by_key(|(_, &sn)| (subtree[sn as usize], sn))
    {
        let heaviest = candidates.swap_remove(at);
        expanded.push(heaviest);
        top_weight += weight[heaviest as usize];
        if top_weight >= best.0 {
            break;
        }
        candidates.extend(&children[heaviest as usize]);
        let (heavier, dealt) = deal(&candidates);
        if top_weight + heavier < best.0 {
            best = (top_weight + heavier, expanded.len(), dealt);
        }
    }
    let (_, tops, dealt) = best;
    // Each supernode's group: its subtree root's, inherited downwards (parents come later).
    let mut group = vec![TOP; ns];
    let mut is_top = vec![false; ns];
    for &sn in &expanded[..tops] {
        is_top[sn as usize] = true;
    }
    for (sn, b) in dealt {
        group[sn as usize] = b;
    }
    for sn in (0..ns).rev() {
        if is_top[sn] || group[sn] != TOP {
            continue;
        }
        if let Some(p) = parent[sn] {
            group[sn] = group[p as usize];
        }
    }
    let mut groups = [Vec::new(), Vec::new()];
    let mut top = Vec::new();
    for (sn, &g) in group.iter().enumerate() {
        match g {
            TOP => top.push(sn as u32),
            g => groups[g as usize].push(sn as u32),
        }
    }
    (groups, top)
}

/// Run `a` and `b`, on two threads where the pool has them.
fn join(a: impl FnOnce() + Send, b: impl FnOnce() + Send) {
    #[cfg(feature = "parallel")]
    if rayon::current_num_threads() > 1 {
        rayon::join(a, b);
        return;
    }
    a();
    b();
}
