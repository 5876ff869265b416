//! Solves with a supernodal sparse Cholesky factor `L L^T` on one or several threads:
//! independent subtrees of the supernodal elimination tree run concurrently, and inside the
//! large dense fronts at the top of the tree the triangular solves and products are split by
//! rows. On one thread the same code runs in order; its kernels for one to three right-hand
//! sides (`few_rhs`) make it faster than faer's general solve there too.
//!
//! faer's own supernodal solve visits the supernodes in order, pushing each supernode's update
//! `L_bot x_top` into the rows of its ancestors; two subtrees doing that at once would race on
//! the rows they share. Here the forward solve is multifrontal: each supernode keeps its update
//! in its own buffer (one entry per row of its pattern), and its parent pulls its children's
//! buffers (the part on its own columns into `x`, the rest into its own buffer, since a child's
//! pattern outside the parent's columns lies in the parent's pattern). The backward solve
//! `L^T x = y` only reads rows of ancestors, which are final before a supernode starts, so the
//! children of a supernode run concurrently once it is done. A supernode writes only its own
//! columns of `x` and its own buffer: that is what makes the shared writes below disjoint.
//!
//! The result equals faer's solve up to rounding (the sums are the same, grouped differently);
//! a test compares them on a 3D grid Laplacian with every parallel path forced.

use faer::prelude::{Reborrow, ReborrowMut};
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use faer::{MatMut, MatRef};
use rayon::prelude::*;

use super::few_rhs::{add_product, add_transposed_product, lower_solve, lower_transposed_solve};

/// Subtrees whose factor holds fewer values than this run on one thread, in order.
const SERIAL_SUBTREE_VALUES: usize = 40_000;
/// Dense products with fewer factor values than this are not split between threads.
const SPLIT_PRODUCT_VALUES: usize = 24_000;
/// The most pieces a product is split into.
const MAX_PIECES: usize = 16;
/// Width of the column blocks of a large front's triangular solve.
const TRIANGLE_BLOCK: usize = 64;
/// Fronts with at least this many columns have their triangular solves blocked (so that the
/// products between the blocks can be split between threads).
const BLOCKED_TRIANGLE_COLUMNS: usize = 2 * TRIANGLE_BLOCK;

/// The supernodal elimination tree of a factor and the index maps the solve needs, computed
/// once per factor.
#[derive(Debug)]
pub(crate) struct TreePlan {
    n: usize,
    /// `x_perm[i] = b[perm[i]]` (faer's fill-reducing permutation, forward array).
    perm: Option<Vec<usize>>,
    /// First column of each supernode (length `supernodes + 1`).
    begin: Vec<usize>,
    /// Offsets of each supernode's values (column-major `(ncols + rows) x ncols`).
    val_ptr: Vec<usize>,
    /// Offsets of each supernode's pattern (rows below its diagonal block).
    row_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// For each pattern entry of a supernode with a parent: its position among the parent's
    /// columns (below the parent's column count) or, shifted by that count, in its pattern.
    rel: Vec<u32>,
    child_ptr: Vec<usize>,
    children: Vec<usize>,
    roots: Vec<usize>,
    /// The lowest-numbered supernode of each supernode's subtree (subtrees are contiguous
    /// ranges `first[s]..=s`).
    first: Vec<usize>,
    /// Factor values in each supernode's subtree.
    subtree_values: Vec<usize>,
}

/// Raw views of the solve's shared buffers, handed to concurrent tasks that write disjoint
/// parts of them (each supernode its own columns of `x` and its own update buffer).
#[derive(Clone, Copy)]
struct Shared {
    x: *mut f64,
    n: usize,
    k: usize,
    u: *mut f64,
}

// SAFETY: the pointers are only dereferenced through `Shared::top`/`Shared::update`, whose
// callers (the tree traversals below) give every concurrent task disjoint ranges; see there.
unsafe impl Send for Shared {}
unsafe impl Sync for Shared {}

impl Shared {
    /// Rows `begin..begin + rows` of `x` (all `k` columns).
    ///
    /// # Safety
    /// No other live view may overlap these rows.
    #[allow(clippy::mut_from_ref)]
    unsafe fn top(&self, begin: usize, rows: usize) -> MatMut<'_, f64> {
        MatMut::from_raw_parts_mut(self.x.add(begin), rows, self.k, 1, self.n as isize)
    }

    /// Read-only view of `x`.
    ///
    /// # Safety
    /// The rows read must not be written concurrently.
    unsafe fn x_at(&self, row: usize, col: usize) -> f64 {
        *self.x.add(row + col * self.n)
    }

    /// The update buffer at pattern offset `offset` with `rows` rows (column-major, `k`
    /// columns).
    ///
    /// # Safety
    /// No other live view may overlap this buffer.
    #[allow(clippy::mut_from_ref)]
    unsafe fn update(&self, offset: usize, rows: usize) -> MatMut<'_, f64> {
        MatMut::from_raw_parts_mut(self.u.add(offset * self.k), rows, self.k, 1, rows as isize)
    }
}

/// The buffers of [`TreePlan::solve`], sized once: the permuted right-hand sides and one
/// update buffer per supernode.
#[derive(Debug)]
pub(crate) struct TreeWork {
    k: usize,
    x: Vec<f64>,
    u: Vec<f64>,
}

impl TreePlan {
    /// The plan of a supernodal factor; `None` for a simplicial one, or if the factor's tree is
    /// not in the form this solve relies on (subtrees numbered contiguously, each pattern
    /// within its parent's columns and pattern) -- faer's own solve is used then.
    pub(crate) fn new(symbolic: &SymbolicCholesky<usize>) -> Option<Self> {
        let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
            return None;
        };
        let n = symbolic.nrows();
        let ns = sn.n_supernodes();
        let mut begin = sn.supernode_begin().to_vec();
        begin.push(n);
        let val_ptr = sn.col_ptr_for_val()[..=ns].to_vec();
        let mut row_ptr = Vec::with_capacity(ns + 1);
        let mut row_idx = Vec::new();
        for s in 0..ns {
            row_ptr.push(row_idx.len());
            row_idx.extend_from_slice(sn.supernode(s).pattern());
        }
        row_ptr.push(row_idx.len());
        let mut owner = vec![0usize; n];
        for s in 0..ns {
            owner[begin[s]..begin[s + 1]].fill(s);
        }
        let mut parent = vec![usize::MAX; ns];
        let mut rel = vec![0u32; row_idx.len()];
        for s in 0..ns {
            let pattern = &row_idx[row_ptr[s]..row_ptr[s + 1]];
            let Some(&r0) = pattern.first() else { continue };
            let p = owner[r0];
            if p <= s {
                return None;
            }
            parent[s] = p;
            let ncols_p = begin[p + 1] - begin[p];
            let pattern_p = &row_idx[row_ptr[p]..row_ptr[p + 1]];
            for (e, &r) in rel[row_ptr[s]..row_ptr[s + 1]].iter_mut().zip(pattern) {
                let pos = if r < begin[p + 1] {
                    r.checked_sub(begin[p])?
                } else {
                    ncols_p + pattern_p.binary_search(&r).ok()?
                };
                *e = u32::try_from(pos).ok()?;
            }
        }
        let mut counts = vec![0usize; ns + 1];
        for &p in parent.iter().filter(|p| **p != usize::MAX) {
            counts[p + 1] += 1;
        }
        let mut child_ptr = counts;
        for s in 0..ns {
            child_ptr[s + 1] += child_ptr[s];
        }
        let mut fill = child_ptr.clone();
        let mut children = vec![0usize; child_ptr[ns]];
        let mut roots = Vec::new();
        for (s, &p) in parent.iter().enumerate() {
            match p {
                usize::MAX => roots.push(s),
                p => {
                    children[fill[p]] = s;
                    fill[p] += 1;
                }
            }
        }
        let mut first: Vec<usize> = (0..ns).collect();
        let mut size = vec![1usize; ns];
        let mut subtree_values: Vec<usize> = (0..ns).map(|s| val_ptr[s + 1] - val_ptr[s]).collect();
        for s in 0..ns {
            if parent[s] != usize::MAX {
                let p = parent[s];
                first[p] = first[p].min(first[s]);
                size[p] += size[s];
                subtree_values[p] += subtree_values[s];
            }
        }
        if (0..ns).any(|s| s + 1 - first[s] != size[s]) {
            return None;
        }
        let perm = symbolic.perm().map(|p| p.arrays().0.to_vec());
        Some(Self {
            n,
            perm,
            begin,
            val_ptr,
            row_ptr,
            row_idx,
            rel,
            child_ptr,
            children,
            roots,
            first,
            subtree_values,
        })
    }

    /// Buffers for solves with up to `k` right-hand sides.
    pub(crate) fn work(&self, k: usize) -> TreeWork {
        TreeWork {
            k,
            x: vec![0.0; self.n * k],
            u: vec![0.0; self.row_idx.len() * k],
        }
    }

    /// Solve `L L^T x = b` in place (`rhs` is `n x k`, `k` at most the buffers' width) with the
    /// factor's `values`, on the current rayon pool's threads.
    pub(crate) fn solve(&self, values: &[f64], mut rhs: MatMut<'_, f64>, work: &mut TreeWork) {
        let (n, k) = (self.n, rhs.ncols());
        assert!(
            rhs.nrows() == n && k <= work.k,
            "tree solve: right-hand side of the wrong shape"
        );
        let x = &mut work.x[..n * k];
        for j in 0..k {
            let col = &mut x[j * n..(j + 1) * n];
            match &self.perm {
                Some(p) => col.iter_mut().zip(p).for_each(|(xi, &pi)| *xi = rhs[(pi, j)]),
                None => col.iter_mut().enumerate().for_each(|(i, xi)| *xi = rhs[(i, j)]),
            }
        }
        let shared = Shared {
            x: x.as_mut_ptr(),
            n,
            k,
            u: work.u.as_mut_ptr(),
        };
        self.roots.par_iter().for_each(|&r| self.forward(r, values, shared));
        self.roots.par_iter().for_each(|&r| self.backward(r, values, shared));
        let x = &work.x[..n * k];
        for j in 0..k {
            let col = &x[j * n..(j + 1) * n];
            match &self.perm {
                Some(p) => p.iter().zip(col).for_each(|(&pi, xi)| rhs[(pi, j)] = *xi),
                None => col.iter().enumerate().for_each(|(i, xi)| rhs[(i, j)] = *xi),
            }
        }
    }

    fn child_list(&self, s: usize) -> &[usize] {
        &self.children[self.child_ptr[s]..self.child_ptr[s + 1]]
    }

    /// `L[s]`: the supernode's values, `(ncols + rows) x ncols` column-major.
    fn panel<'a>(&self, values: &'a [f64], s: usize) -> MatRef<'a, f64> {
        let nc = self.begin[s + 1] - self.begin[s];
        let m = self.row_ptr[s + 1] - self.row_ptr[s];
        MatRef::from_column_major_slice(&values[self.val_ptr[s]..self.val_ptr[s + 1]], nc + m, nc)
    }

    /// Forward solve of the subtree of `s` (children before parents).
    fn forward(&self, s: usize, values: &[f64], sh: Shared) {
        if self.subtree_values[s] <= SERIAL_SUBTREE_VALUES {
            for t in self.first[s]..=s {
                self.forward_node(t, values, sh, false);
            }
            return;
        }
        self.child_list(s).par_iter().for_each(|&c| self.forward(c, values, sh));
        self.forward_node(s, values, sh, true);
    }

    /// Backward solve of the subtree of `s` (parents before children).
    fn backward(&self, s: usize, values: &[f64], sh: Shared) {
        if self.subtree_values[s] <= SERIAL_SUBTREE_VALUES {
            for t in (self.first[s]..=s).rev() {
                self.backward_node(t, values, sh, false);
            }
            return;
        }
        self.backward_node(s, values, sh, true);
        self.child_list(s)
            .par_iter()
            .for_each(|&c| self.backward(c, values, sh));
    }

    /// One supernode of `L y = b`: its children's updates pulled in, its triangle solved, its
    /// own update `L_bot y_top` formed.
    fn forward_node(&self, s: usize, values: &[f64], sh: Shared, split: bool) {
        let (b, nc) = (self.begin[s], self.begin[s + 1] - self.begin[s]);
        let m = self.row_ptr[s + 1] - self.row_ptr[s];
        let k = sh.k;
        // SAFETY: supernode `s` is the only task that writes its columns of `x` and its update
        // buffer; its children (which wrote theirs) have finished, and nothing else reads
        // these until `s` is done (its parent runs after it).
        let mut top = unsafe { sh.top(b, nc) };
        let mut update = unsafe { sh.update(self.row_ptr[s], m) };
        update.fill(0.0);
        for &c in self.child_list(s) {
            let mc = self.row_ptr[c + 1] - self.row_ptr[c];
            // SAFETY: the child's buffer is final and only `s` reads it.
            let uc = unsafe { sh.update(self.row_ptr[c], mc) };
            let rel = &self.rel[self.row_ptr[c]..self.row_ptr[c + 1]];
            for j in 0..k {
                for (i, &r) in rel.iter().enumerate() {
                    let (r, v) = (r as usize, uc[(i, j)]);
                    if r < nc {
                        top[(r, j)] -= v;
                    } else {
                        update[(r - nc, j)] += v;
                    }
                }
            }
        }
        let panel = self.panel(values, s);
        let (l_top, l_bot) = panel.split_at_row(nc);
        if split && nc >= BLOCKED_TRIANGLE_COLUMNS {
            lower_solve_blocked(l_top, top.rb_mut());
        } else {
            lower_solve(l_top, top.rb_mut());
        }
        if m > 0 {
            product(Op::Plain, update, l_bot, top.rb(), 1.0, split);
        }
    }

    /// One supernode of `L^T x = y`: the rows of its pattern (final) gathered, `L_bot^T` of
    /// them subtracted, its triangle solved.
    fn backward_node(&self, s: usize, values: &[f64], sh: Shared, split: bool) {
        let (b, nc) = (self.begin[s], self.begin[s + 1] - self.begin[s]);
        let m = self.row_ptr[s + 1] - self.row_ptr[s];
        // SAFETY: `s` writes only its own columns of `x` and its own buffer (reused as the
        // gather buffer); the rows it reads belong to its ancestors, which finished before `s`
        // started and are not written again.
        let mut top = unsafe { sh.top(b, nc) };
        let panel = self.panel(values, s);
        let (l_top, l_bot) = panel.split_at_row(nc);
        if m > 0 {
            let mut g = unsafe { sh.update(self.row_ptr[s], m) };
            let pattern = &self.row_idx[self.row_ptr[s]..self.row_ptr[s + 1]];
            for j in 0..sh.k {
                for (i, &r) in pattern.iter().enumerate() {
                    g[(i, j)] = unsafe { sh.x_at(r, j) };
                }
            }
            product(Op::Transposed, top.rb_mut(), l_bot, g.rb(), -1.0, split);
        }
        if split && nc >= BLOCKED_TRIANGLE_COLUMNS {
            lower_transposed_solve_blocked(l_top, top);
        } else {
            lower_transposed_solve(l_top, top);
        }
    }
}

/// Which product: `a src` or `a^T src`.
#[derive(Clone, Copy)]
enum Op {
    Plain,
    Transposed,
}

/// `dst += alpha op(a) src`, split by rows of `dst` into pieces for the pool's threads when
/// `split` and large. The pieces depend on the product's size only, never on the number of
/// threads, and each entry's sum is formed in the same order in any piece, so the result is
/// the same on any pool.
fn product(op: Op, dst: MatMut<'_, f64>, a: MatRef<'_, f64>, src: MatRef<'_, f64>, alpha: f64, split: bool) {
    let values = a.nrows() * a.ncols();
    if !split || values < SPLIT_PRODUCT_VALUES || dst.nrows() < 2 {
        apply(op, dst, a, src, alpha);
        return;
    }
    // Pieces of at least SPLIT_PRODUCT_VALUES / 2 values, at most MAX_PIECES.
    let pieces = (2 * values / SPLIT_PRODUCT_VALUES)
        .clamp(2, MAX_PIECES)
        .min(dst.nrows());
    let rows = dst.nrows().div_ceil(pieces);
    split_rows(op, dst, a, src, alpha, rows);
}

fn apply(op: Op, dst: MatMut<'_, f64>, a: MatRef<'_, f64>, src: MatRef<'_, f64>, alpha: f64) {
    match op {
        Op::Plain => add_product(dst, a, src, alpha),
        Op::Transposed => add_transposed_product(dst, a, src, alpha),
    }
}

fn split_rows(op: Op, dst: MatMut<'_, f64>, a: MatRef<'_, f64>, src: MatRef<'_, f64>, alpha: f64, rows: usize) {
    if dst.nrows() <= rows {
        apply(op, dst, a, src, alpha);
        return;
    }
    let mid = (dst.nrows() / 2).div_ceil(rows) * rows;
    let (d0, d1) = dst.split_at_row_mut(mid);
    // The rows of `dst` are rows of `a`, or its columns when transposed.
    let (a0, a1) = match op {
        Op::Plain => a.split_at_row(mid),
        Op::Transposed => a.split_at_col(mid),
    };
    rayon::join(
        || split_rows(op, d0, a0, src, alpha, rows),
        || split_rows(op, d1, a1, src, alpha, rows),
    );
}

/// `L y = b` for a large dense lower triangle: blocks of columns solved in turn, the product of
/// each block with the rows below it split between threads.
fn lower_solve_blocked(l: MatRef<'_, f64>, mut x: MatMut<'_, f64>) {
    let nc = l.nrows();
    let mut j0 = 0;
    while j0 < nc {
        let j1 = (j0 + TRIANGLE_BLOCK).min(nc);
        let (_, rest) = x.rb_mut().split_at_row_mut(j0);
        let (mut block, below) = rest.split_at_row_mut(j1 - j0);
        lower_solve(l.submatrix(j0, j0, j1 - j0, j1 - j0), block.rb_mut());
        if j1 < nc {
            product(
                Op::Plain,
                below,
                l.submatrix(j1, j0, nc - j1, j1 - j0),
                block.rb(),
                -1.0,
                true,
            );
        }
        j0 = j1;
    }
}

/// `L^T x = y` for a large dense lower triangle: blocks of rows from the last, each first
/// reduced by the solved rows after it (split between threads), then solved.
fn lower_transposed_solve_blocked(l: MatRef<'_, f64>, mut x: MatMut<'_, f64>) {
    let nc = l.nrows();
    let mut j1 = nc;
    while j1 > 0 {
        let j0 = j1.saturating_sub(TRIANGLE_BLOCK);
        let (head, after) = x.rb_mut().split_at_row_mut(j1);
        let (_, mut block) = head.split_at_row_mut(j0);
        if j1 < nc {
            product(
                Op::Transposed,
                block.rb_mut(),
                l.submatrix(j1, j0, nc - j1, j1 - j0),
                after.rb(),
                -1.0,
                true,
            );
        }
        lower_transposed_solve(l.submatrix(j0, j0, j1 - j0, j1 - j0), block);
        j1 = j0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef};
    use faer::sparse::{SparseColMat, Triplet};
    use faer::{Conj, Mat, Par, Side};

    /// A 3D grid graph Laplacian plus a diagonal shift (SPD), lower triangle, `g^3` unknowns.
    fn grid_laplacian(g: usize) -> SparseColMat<usize, f64> {
        let id = |i: usize, j: usize, l: usize| (i * g + j) * g + l;
        let mut t = Vec::new();
        for i in 0..g {
            for j in 0..g {
                for l in 0..g {
                    let a = id(i, j, l);
                    t.push(Triplet::new(a, a, 10.5 + 0.01 * (a % 7) as f64));
                    for (di, dj, dl) in [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (0, 1, 1)] {
                        let (i2, j2, l2) = (i + di, j + dj, l + dl);
                        if i2 < g && j2 < g && l2 < g {
                            t.push(Triplet::new(id(i2, j2, l2), a, -1.0));
                        }
                    }
                }
            }
        }
        SparseColMat::try_new_from_triplets(g * g * g, g * g * g, &t).unwrap()
    }

    /// The tree solve equals faer's solve (relative 1e-12) for one and three right-hand sides,
    /// with every parallel path taken (a grid large enough that its top fronts are split and
    /// blocked), and gives the same bits on 1, 2 and 4 threads and on a second solve with the
    /// same buffers.
    #[test]
    fn matches_faers_solve_and_gives_the_same_bits_on_any_number_of_threads() {
        let a = grid_laplacian(22);
        let n = a.nrows();
        let symbolic =
            factorize_symbolic_cholesky(a.symbolic(), Side::Lower, Default::default(), Default::default()).unwrap();
        let mut values = vec![0.0; symbolic.len_val()];
        let mut mem = MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()));
        symbolic
            .factorize_numeric_llt(
                &mut values,
                a.as_ref(),
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .unwrap();
        let plan = TreePlan::new(&symbolic).expect("a supernodal factor with a usable tree");
        let big = (0..plan.begin.len() - 1)
            .map(|s| plan.begin[s + 1] - plan.begin[s])
            .max()
            .unwrap();
        assert!(
            big >= BLOCKED_TRIANGLE_COLUMNS,
            "largest front {big} columns: blocked path not taken"
        );
        assert!(
            plan.subtree_values.iter().any(|&v| v > SERIAL_SUBTREE_VALUES),
            "no subtree large enough to run in parallel"
        );
        for k in [1, 3] {
            let b = Mat::<f64>::from_fn(n, k, |i, j| ((i * 7 + j * 13) % 17) as f64 - 8.0);
            let mut want = b.clone();
            let mut mem = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(k, Par::Seq));
            LltRef::new(&symbolic, &values).solve_in_place_with_conj(
                Conj::No,
                want.as_mut(),
                Par::Seq,
                MemStack::new(&mut mem),
            );
            let scale = want.norm_max();
            let mut first: Option<Mat<f64>> = None;
            for threads in [1, 2, 4] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let mut work = plan.work(3);
                for _ in 0..2 {
                    let mut got = b.clone();
                    pool.install(|| plan.solve(&values, got.as_mut(), &mut work));
                    let err = (&got - &want).norm_max() / scale;
                    assert!(err < 1e-12, "k = {k}, {threads} threads: relative difference {err:e}");
                    let first = first.get_or_insert_with(|| got.clone());
                    assert!(
                        got == *first,
                        "k = {k}: {threads} threads give other bits than one thread"
                    );
                }
            }
        }
    }
}
