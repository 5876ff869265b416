//! Direct global solve: `M/h^2 + L` on the free vertices factored once by faer's sparse
//! Cholesky (symbolic analysis and numeric factor reused every step; refactored only when the
//! time step or the weights change), with a preallocated solve workspace so a step allocates
//! nothing.
//!
//! Contacts: with `A x = b + sum_c e_c lambda_c`, the contact vertices move as
//! `x_c = x_free_c + sum_d (A^-1)_{cd} lambda_d`. The columns of `A^-1` at contact vertices are
//! cached (they only change with the factor), and the contact problem is solved in contact space
//! ([`super::contact_space`]: projected Gauss-Seidel with the same Coulomb cone projection as
//! the iterative solvers, effective weight `1 / (A^-1)_{cc}`, finished by an active-set method).

use rustc_hash::FxHashMap;
use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky};
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use faer::{Conj, Mat, Par, Side};
use nalgebra::Vector3;

use super::assembled::GlobalSystem;
use super::contact_space::{ContactSpace, Effort, Problem};
use super::free_contact::{FreeContact, Stencil};
use super::global::{GlobalSolver, GlobalStats, InnerControl, SolverKind};
use super::tree_solve::{TreePlan, TreeWork};
use super::SolverError;

/// Free vertices from which the three axes are solved concurrently (below it, a one-column
/// solve is too short to pay for the handoff between threads).
const AXIS_PARALLEL_MIN: usize = 4000;

/// The sparse Cholesky factor of `M/h^2 + L` on the free vertices: computed once per
/// [`System`](super::system::System) and shared by every solver that solves with it (the run's
/// iterations, its backward pass, other runs on the same system).
pub(crate) struct CholeskyFactor {
    symbolic: SymbolicCholesky<usize>,
    numeric: Vec<f64>,
    /// The supernodal tree of the tree solve (`None` for a simplicial factor).
    plan: Option<TreePlan>,
}

impl CholeskyFactor {
    /// Analyse and factor the system.
    pub(crate) fn new(sys: &GlobalSystem) -> Result<Self, SolverError> {
        let n = sys.n();
        let mut values = sys.l.values.clone();
        for j in 0..n {
            let (lo, hi) = (sys.l.col_ptr[j], sys.l.col_ptr[j + 1]);
            for (r, v) in sys.l.row_idx[lo..hi].iter().zip(&mut values[lo..hi]) {
                if *r == j {
                    *v += sys.mass_h2[j];
                }
            }
        }
        let symbolic_a = SymbolicSparseColMat::new_checked(n, n, sys.l.col_ptr.clone(), None, sys.l.row_idx.clone());
        let a = SparseColMat::new(symbolic_a, values);
        let symbolic = factorize_symbolic_cholesky(a.symbolic(), Side::Lower, Default::default(), Default::default())
            .map_err(|e| SolverError::Factorization(format!("symbolic analysis failed: {e}")))?;
        let mut numeric = vec![0.0; symbolic.len_val()];
        let par = Par::Seq;
        let mut mem = MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
        symbolic
            .factorize_numeric_llt(
                &mut numeric,
                a.as_ref(),
                Side::Lower,
                Default::default(),
                par,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .map_err(|e| {
                let faer::linalg::solvers::LltError::NonPositivePivot { index } = e;
                let why = format!("pivot {index} of {n} in the factor's ordering is not positive");
                SolverError::Factorization(format!(
                    "M/h^2 + L is not positive definite ({why}): check masses, stiffness and time step"
                ))
            })?;
        let plan = TreePlan::new(&symbolic);
        Ok(Self {
            symbolic,
            numeric,
            plan,
        })
    }

    fn llt(&self) -> LltRef<'_, usize, f64> {
        LltRef::new(&self.symbolic, &self.numeric)
    }
}

/// Sparse Cholesky solves of `M/h^2 + L` with a shared factor, and the contact solve on it.
pub(crate) struct Direct {
    factor: Arc<CholeskyFactor>,
    solve_mem: MemBuffer,
    /// Scratch of the two- or one-column solves when the axes are solved concurrently.
    axis_mem: [MemBuffer; 3],
    /// How the three axes are solved: 1 (together, on this thread), 2 (two on this thread,
    /// one on another) or 3 (each on its own thread): large systems with several worker threads.
    axis_split: usize,
    /// Buffers of the tree solve, used instead of faer's solve (and the axis split) when the
    /// factor is supernodal and the system large: on several threads it runs subtrees and
    /// large fronts in parallel; on one its kernels for three right-hand sides are faster.
    tree_work: Option<TreeWork>,
    rhs: Mat<f64>,
    /// Columns of `A^-1` at contact vertices (free index -> column).
    delassus: FxHashMap<usize, Vec<f64>>,
    control: InnerControl,
    lambda: Vec<Vector3<f64>>,
    // Contact buffers, reused across solves.
    stencils: Vec<Stencil>,
    dmat: Vec<f64>,
    x_free: Vec<Vector3<f64>>,
    space: ContactSpace,
    /// Whether this step's last contact solve stalled (or, after one that did, on the same
    /// contact set, did not converge): the next solve of the same set runs with
    /// [`Effort::AfterStall`]. Reset by [`Direct::begin_step`].
    stalled: bool,
    /// The previous solve's impulses by contact vertices (warm starts).
    previous: FxHashMap<(u8, [usize; 4]), Vector3<f64>>,
}

impl std::fmt::Debug for Direct {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Direct")
            .field("n", &self.rhs.nrows())
            .field("factor_nnz", &self.factor.numeric.len())
            .finish()
    }
}

impl Direct {
    /// Solves with a shared `factor` of a system with `n` free vertices; every buffer is
    /// allocated here.
    pub(crate) fn with_factor(factor: Arc<CholeskyFactor>, n: usize, control: InnerControl) -> Self {
        let par = Par::Seq;
        let symbolic = &factor.symbolic;
        let solve_mem = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(3, par));
        let axis_mem = [2, 1, 1].map(|k| MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(k, par)));
        let axis_split = if n < AXIS_PARALLEL_MIN {
            1
        } else {
            rayon::current_num_threads().clamp(1, 3)
        };
        let tree_work = match &factor.plan {
            Some(plan) if n >= AXIS_PARALLEL_MIN => Some(plan.work(3)),
            _ => None,
        };
        Self {
            factor,
            solve_mem,
            axis_mem,
            axis_split,
            tree_work,
            rhs: Mat::zeros(n, 3),
            delassus: FxHashMap::default(),
            control,
            lambda: Vec::new(),
            stencils: Vec::new(),
            dmat: Vec::new(),
            x_free: Vec::new(),
            space: ContactSpace::default(),
            stalled: false,
            previous: FxHashMap::default(),
        }
    }

    fn solve_rhs(&mut self) {
        if let (Some(plan), Some(work)) = (&self.factor.plan, &mut self.tree_work) {
            plan.solve(&self.factor.numeric, self.rhs.as_mut(), work);
            return;
        }
        let llt = self.factor.llt();
        let [m2, m1, m0] = &mut self.axis_mem;
        if self.axis_split == 2 {
            // The three axes share the factor: two axes on this thread (one pass over the
            // factor serves both), the third on another.
            let (xy, z) = self.rhs.as_mut().split_at_col_mut(2);
            rayon::join(
                || llt.solve_in_place_with_conj(Conj::No, xy, Par::Seq, MemStack::new(m2)),
                || llt.solve_in_place_with_conj(Conj::No, z, Par::Seq, MemStack::new(m1)),
            );
        } else if self.axis_split == 3 {
            // Three threads or more: an axis each (the solves are bound by memory traffic,
            // which more cores share out).
            let (x, yz) = self.rhs.as_mut().split_at_col_mut(1);
            let (y, z) = yz.split_at_col_mut(1);
            rayon::join(
                || llt.solve_in_place_with_conj(Conj::No, x, Par::Seq, MemStack::new(m2)),
                || {
                    rayon::join(
                        || llt.solve_in_place_with_conj(Conj::No, y, Par::Seq, MemStack::new(m1)),
                        || llt.solve_in_place_with_conj(Conj::No, z, Par::Seq, MemStack::new(m0)),
                    )
                },
            );
        } else {
            llt.solve_in_place_with_conj(
                Conj::No,
                self.rhs.as_mut(),
                Par::Seq,
                MemStack::new(&mut self.solve_mem),
            );
        }
    }

    /// Make sure the `A^-1` columns of every contact vertex are cached.
    fn ensure_columns(&mut self, contacts: &[FreeContact]) {
        let missing: Vec<usize> = {
            let mut m: Vec<usize> = contacts
                .iter()
                .flat_map(|c| c.stencil.entries().map(|(i, _)| i))
                .filter(|i| !self.delassus.contains_key(i))
                .collect();
            m.sort_unstable();
            m.dedup();
            m
        };
        if missing.is_empty() {
            return;
        }
        let n = self.rhs.nrows();
        let mut e = Mat::<f64>::zeros(n, missing.len());
        for (k, &i) in missing.iter().enumerate() {
            e[(i, k)] = 1.0;
        }
        let mut mem = MemBuffer::new(
            self.factor
                .symbolic
                .solve_in_place_scratch::<f64>(missing.len(), Par::Seq),
        );
        self.factor
            .llt()
            .solve_in_place_with_conj(Conj::No, e.as_mut(), Par::Seq, MemStack::new(&mut mem));
        for (k, &i) in missing.iter().enumerate() {
            self.delassus.insert(i, (0..n).map(|r| e[(r, k)]).collect());
        }
    }
}

impl Direct {
    /// `x = (M/h^2 + L)^-1 b` on the free vertices (no contacts).
    pub(crate) fn solve_free(&mut self, b: &[Vector3<f64>], x: &mut [Vector3<f64>]) -> Result<(), SolverError> {
        for (i, bi) in b.iter().enumerate() {
            for d in 0..3 {
                self.rhs[(i, d)] = bi[d];
            }
        }
        self.solve_rhs();
        for (i, xi) in x.iter_mut().enumerate() {
            *xi = Vector3::new(self.rhs[(i, 0)], self.rhs[(i, 1)], self.rhs[(i, 2)]);
        }
        if x.iter().all(|v| v.iter().all(|c| c.is_finite())) {
            Ok(())
        } else {
            Err(SolverError::NonFinite(
                "direct global solve produced a non-finite position".into(),
            ))
        }
    }

    /// Solve with several right-hand sides given per axis as columns (`n x k`), in place.
    pub(crate) fn solve_columns(&self, cols: &mut Mat<f64>) {
        let mut mem = MemBuffer::new(
            self.factor
                .symbolic
                .solve_in_place_scratch::<f64>(cols.ncols(), Par::Seq),
        );
        self.factor
            .llt()
            .solve_in_place_with_conj(Conj::No, cols.as_mut(), Par::Seq, MemStack::new(&mut mem));
    }

    /// The column of `A^-1` at free vertex `i` (cached; computed on first use).
    pub(crate) fn inverse_column(&mut self, i: usize) -> &[f64] {
        if !self.delassus.contains_key(&i) {
            let n = self.rhs.nrows();
            let mut e = Mat::<f64>::zeros(n, 1);
            e[(i, 0)] = 1.0;
            self.solve_columns(&mut e);
            self.delassus.insert(i, (0..n).map(|r| e[(r, 0)]).collect());
        }
        &self.delassus[&i]
    }

    /// The contact impulses of the last [`Direct::apply_contacts`], with the free index of
    /// each contact's first stencil entry.
    pub(crate) fn indexed_impulses(&self) -> impl Iterator<Item = (usize, Vector3<f64>)> + '_ {
        self.stencils
            .iter()
            .map(|s| s.index[0])
            .zip(self.lambda.iter().copied())
    }

    /// The Delassus matrix of contacts with these stencils, row-major into `out`: entry
    /// `(j, k)` is `sum_a sum_b c_a c_b (A^-1)_{i_a i_b}` over stencil `j`'s entries `a` and
    /// stencil `k`'s entries `b` (the columns must be cached). Each row looks its columns up
    /// once.
    pub(crate) fn delassus_matrix<'s>(&self, stencils: impl Iterator<Item = &'s Stencil> + Clone, out: &mut Vec<f64>) {
        out.clear();
        for a in stencils.clone() {
            let mut cols: [(&[f64], f64); 4] = [(&[], 0.0); 4];
            for (slot, (i, c)) in cols.iter_mut().zip(a.entries()) {
                *slot = (&self.delassus[&i], c);
            }
            let cols = &cols[..a.len as usize];
            out.extend(stencils.clone().map(|b| {
                let mut d = 0.0;
                for &(col, ci) in cols {
                    for (k, ck) in b.entries() {
                        d += ci * ck * col[k];
                    }
                }
                d
            }));
        }
    }

    /// `x += sum_k c_k (A^-1)_{:, i_k} l` for a contact's stencil (columns cached on demand).
    pub(crate) fn add_inverse_columns(&mut self, stencil: &Stencil, l: &Vector3<f64>, x: &mut [Vector3<f64>]) {
        if *l == Vector3::zeros() {
            return;
        }
        for (i, c) in stencil.entries() {
            let col = self.inverse_column(i);
            let lc = l * c;
            for (xi, a) in x.iter_mut().zip(col) {
                *xi += lc * *a;
            }
        }
    }

    /// Forget the last step's stalled contact solves (a new step's first solve of any set runs
    /// with [`Effort::Full`]).
    pub(crate) fn begin_step(&mut self) {
        self.stalled = false;
    }

    /// Contacts on a contact-free solution `x`: projected Gauss-Seidel on the contact-space
    /// operator for the impulses (same cone projection as the iterative solvers), then
    /// `x += sum_c (A^-1)_{:,c} lambda_c`.
    pub(crate) fn apply_contacts(&mut self, x: &mut [Vector3<f64>], contacts: &[FreeContact]) -> GlobalStats {
        let mut stats = GlobalStats {
            converged: true,
            ..Default::default()
        };
        if contacts.is_empty() {
            self.stencils.clear();
            self.lambda.clear();
            return stats;
        }
        self.ensure_columns(contacts);
        let m = contacts.len();
        // The same contact stencils as the previous call (the usual case between two
        // local-global iterations): warm-start the impulses and keep the Delassus matrix.
        let same = self.stencils.len() == m && self.stencils.iter().zip(contacts).all(|(s, c)| *s == c.stencil);
        if !same {
            // Warm start: a contact on the same vertices as one of the previous solve (the
            // same pair in the previous contact round or the previous step) starts from its
            // impulse; the rest start from zero.
            self.previous.clear();
            for (st, l) in self.stencils.iter().zip(&self.lambda) {
                self.previous.insert(stencil_key(st), *l);
            }
            self.stencils.clear();
            self.stencils.extend(contacts.iter().map(|c| c.stencil));
            self.lambda.clear();
            let previous = &self.previous;
            self.lambda.extend(
                self.stencils
                    .iter()
                    .map(|st| previous.get(&stencil_key(st)).copied().unwrap_or_else(Vector3::zeros)),
            );
            // Delassus entries D[j][k] = e_j^T A^-1 e_k (for single vertices (A^-1)_{c_j c_k}).
            let mut dmat = std::mem::take(&mut self.dmat);
            dmat.clear();
            if self.stencils.iter().all(|s| s.len == 1) {
                for j in 0..m {
                    let col = &self.delassus[&self.stencils[j].index[0]];
                    dmat.extend(self.stencils.iter().map(|s| col[s.index[0]]));
                }
            } else {
                self.delassus_matrix(self.stencils.iter(), &mut dmat);
            }
            self.dmat = dmat;
        }
        self.x_free.clear();
        self.x_free.extend(self.stencils.iter().map(|s| s.apply(x)));
        let problem = Problem {
            d: &self.dmat,
            f: &self.x_free,
            contacts,
        };
        let solve = self.space.solve(
            &problem,
            &mut self.lambda,
            self.control.tolerance,
            self.control.max_iterations,
            if same && self.stalled {
                Effort::AfterStall
            } else {
                Effort::Full
            },
        );
        // Kept while the set stays and its solves do not converge (see `Effort::AfterStall`).
        self.stalled = solve.stalled || (same && self.stalled && !solve.converged);
        stats.contact_iterations = solve.sweeps + solve.active_set_solves;
        stats.converged = solve.converged;
        stats.last_update = solve.last_change;
        for j in 0..m {
            let l = self.lambda[j];
            let st = self.stencils[j];
            self.add_inverse_columns(&st, &l, x);
        }
        stats
    }
}

/// A contact's identity across solves: its stencil's vertices.
fn stencil_key(s: &Stencil) -> (u8, [usize; 4]) {
    (s.len, s.index)
}

impl GlobalSolver for Direct {
    fn kind(&self) -> SolverKind {
        SolverKind::Direct
    }

    fn solve(
        &mut self,
        _sys: &GlobalSystem,
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
        contacts: &[FreeContact],
    ) -> Result<GlobalStats, SolverError> {
        self.solve_free(b, x)?;
        Ok(self.apply_contacts(x, contacts))
    }

    fn begin_step(&mut self) {
        Direct::begin_step(self);
    }

    fn impulses(&self) -> Option<&[Vector3<f64>]> {
        Some(&self.lambda)
    }

    fn parallel_inside(&self) -> bool {
        self.axis_split > 1 || (self.tree_work.is_some() && rayon::current_num_threads() > 1)
    }
}
