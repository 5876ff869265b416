//! What the backward pass needs of a forward step, recorded by observing it
//! ([`StepObserver`]): the local-global iterates, the contact sets and the impulses each global
//! solve ended with, every tet's decomposition, and with a skeleton its joint states, increments,
//! residuals, active limits and contacts on bone vertices. Every list reuses its buffers from
//! step to step ([`Rows`]), so recording allocates nothing once warm.

use nalgebra::Vector3;

use crate::constraint::TetSvd;
use crate::contact::Contact;
use crate::skeleton::Skeleton;
use crate::solver::free_contact::FreeContact;
use crate::solver::observer::{SolveInfo, StepObserver};

/// A list of rows whose buffers are kept and reused after [`Rows::clear`].
#[derive(Debug, Clone)]
pub(crate) struct Rows<T> {
    rows: Vec<Vec<T>>,
    len: usize,
}

impl<T> Default for Rows<T> {
    fn default() -> Self {
        Self {
            rows: Vec::new(),
            len: 0,
        }
    }
}

impl<T: Clone> Rows<T> {
    /// Forget the rows (keeping their buffers).
    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }

    /// Number of rows.
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// Append a row filled by `fill` (given an empty buffer).
    pub(crate) fn push_with(&mut self, fill: impl FnOnce(&mut Vec<T>)) {
        if self.len == self.rows.len() {
            self.rows.push(Vec::new());
        }
        let r = &mut self.rows[self.len];
        r.clear();
        fill(r);
        self.len += 1;
    }

    /// Append a row of `len` entries whose contents the caller overwrites: a reused buffer keeps
    /// its stale entries (no fill), so only a new or shorter buffer is written here.
    pub(crate) fn push_uninit(&mut self, len: usize, fill: T) {
        if self.len == self.rows.len() {
            self.rows.push(Vec::new());
        }
        self.rows[self.len].resize(len, fill);
        self.len += 1;
    }

    /// Append a copy of `row`.
    pub(crate) fn push(&mut self, row: &[T]) {
        self.push_with(|r| r.extend_from_slice(row));
    }

    /// Drop the last row (keeping its buffer).
    pub(crate) fn pop(&mut self) {
        self.len = self.len.saturating_sub(1);
    }

    /// Row `i`.
    pub(crate) fn get(&self, i: usize) -> Option<&[T]> {
        (i < self.len).then(|| self.rows[i].as_slice())
    }

    /// The last row, mutable.
    pub(crate) fn last_mut(&mut self) -> Option<&mut [T]> {
        self.len.checked_sub(1).map(|i| self.rows[i].as_mut_slice())
    }

    /// A compact copy of the rows (no spare buffers).
    pub(crate) fn snapshot(&self) -> Self {
        Self {
            rows: self.rows[..self.len].to_vec(),
            len: self.len,
        }
    }

    /// Entries over all rows.
    pub(crate) fn entries(&self) -> usize {
        self.rows[..self.len].iter().map(|r| r.len()).sum()
    }
}

impl<T> std::ops::Index<usize> for Rows<T> {
    type Output = [T];

    fn index(&self, i: usize) -> &[T] {
        assert!(i < self.len, "row {i} of {}", self.len);
        &self.rows[i]
    }
}

/// A contact on a bone vertex as a reduced solve ended: `(bone-vertex index, contact, impulse,
/// projected Gauss-Seidel weight)`.
pub(crate) type RigidContact = (usize, Contact, Vector3<f64>, f64);

/// One step's local-global iterations, recorded for the backward pass.
#[derive(Debug, Clone, Default)]
pub(crate) struct Recording {
    /// Keep every iterate (unrolled differentiation); otherwise only the last solve's contacts.
    pub keep_iterates: bool,
    /// Whether `svds` are recorded (with `keep_iterates`).
    pub keep_decompositions: bool,
    /// Free-vertex iterates `x_0 .. x_N`: iteration `k` projects at `x_k` and solves for
    /// `x_{k+1}`; `x_N` is the step's result.
    pub iterates: Rows<Vector3<f64>>,
    /// Contact sets in use (one more per contact round that added contacts).
    pub contact_sets: Rows<FreeContact>,
    /// Per global solve: its contact set (index into `contact_sets`).
    pub solve_sets: Vec<usize>,
    /// Per global solve: the contact impulses it ended with (direct solver; empty without
    /// contacts).
    pub impulses: Rows<Vector3<f64>>,
    /// Whether an iterative global solver handled contacts (no impulses to record).
    pub iterative_contacts: bool,
    /// With a skeleton and `keep_iterates`: the raw joint state at every iterate (aligned with
    /// `iterates`, see [`Skeleton::save_state`]).
    pub skeleton_states: Rows<f64>,
    /// Per reduced solve: the joint increment `dz`.
    pub increments: Rows<f64>,
    /// Per reduced solve: the residual `g - Sigma q_R` per bone vertex.
    pub residuals: Rows<Vector3<f64>>,
    /// Per reduced solve: active joint limits `(coordinate, multiplier)`.
    pub active_limits: Rows<(usize, f64)>,
    /// Reduced solves that had contacts on bone vertices.
    pub rigid_contact_solves: usize,
    /// Per reduced solve: contacts on bone vertices, as the projected Gauss-Seidel in the
    /// reduced coordinates ended.
    pub rigid_contacts: Rows<RigidContact>,
    /// With `keep_iterates` and `keep_decompositions`: every tet's decomposition at each
    /// iterate's local step (aligned with `iterates`, one fewer), so the backward pass need not
    /// decompose again.
    pub svds: Rows<TetSvd>,
}

impl Recording {
    /// A recording that keeps every iterate (and every decomposition), or only the last solve's
    /// contacts.
    pub(crate) fn new(keep_iterates: bool) -> Self {
        Self {
            keep_iterates,
            keep_decompositions: keep_iterates,
            ..Default::default()
        }
    }

    /// Number of global solves recorded.
    pub(crate) fn solves(&self) -> usize {
        self.solve_sets.len()
    }

    /// Which recorded contact set solve `k` ran with (solves of one contact round share it).
    pub(crate) fn solve_set(&self, k: usize) -> usize {
        self.solve_sets[k]
    }

    /// Solve `k`'s contacts and impulses.
    pub(crate) fn solve(&self, k: usize) -> (&[FreeContact], &[Vector3<f64>]) {
        let set = self.solve_sets[k];
        (self.contact_sets.get(set).unwrap_or(&[]), &self.impulses[k])
    }

    /// The last solve's contacts and impulses (empty without contacts).
    pub(crate) fn last_solve(&self) -> (&[FreeContact], &[Vector3<f64>]) {
        match self.solve_sets.len() {
            0 => (&[], &[]),
            n => self.solve(n - 1),
        }
    }

    /// A compact copy (to keep a step's recording).
    pub(crate) fn snapshot(&self) -> Recording {
        Recording {
            keep_iterates: self.keep_iterates,
            keep_decompositions: self.keep_decompositions,
            iterates: self.iterates.snapshot(),
            contact_sets: self.contact_sets.snapshot(),
            solve_sets: self.solve_sets.clone(),
            impulses: self.impulses.snapshot(),
            iterative_contacts: self.iterative_contacts,
            skeleton_states: self.skeleton_states.snapshot(),
            increments: self.increments.snapshot(),
            residuals: self.residuals.snapshot(),
            active_limits: self.active_limits.snapshot(),
            rigid_contact_solves: self.rigid_contact_solves,
            rigid_contacts: self.rigid_contacts.snapshot(),
            svds: self.svds.snapshot(),
        }
    }

    /// Approximate heap size of the recorded data (bytes).
    pub(crate) fn bytes(&self) -> usize {
        use std::mem::size_of;
        let v3 = size_of::<Vector3<f64>>();
        self.iterates.entries() * v3
            + self.contact_sets.entries() * size_of::<FreeContact>()
            + self.impulses.entries() * v3
            + self.solve_sets.len() * 8
            + (self.skeleton_states.entries() + self.increments.entries()) * 8
            + self.residuals.entries() * v3
            + self.active_limits.entries() * 16
            + self.rigid_contacts.entries() * (size_of::<Contact>() + 40)
            + self.svds.entries() * size_of::<TetSvd>()
    }

    /// Record the iterate `x` (and the skeleton's state).
    fn push_iterate(&mut self, x: &[Vector3<f64>], skeleton: Option<&Skeleton>) {
        self.iterates.push(x);
        if let Some(sk) = skeleton {
            self.skeleton_states.push_with(|s| sk.save_state(s));
        }
    }
}

impl StepObserver for Recording {
    fn begin(&mut self) {
        self.iterates.clear();
        self.contact_sets.clear();
        self.solve_sets.clear();
        self.impulses.clear();
        self.iterative_contacts = false;
        self.skeleton_states.clear();
        self.increments.clear();
        self.residuals.clear();
        self.active_limits.clear();
        self.rigid_contact_solves = 0;
        self.rigid_contacts.clear();
        self.svds.clear();
    }

    fn contact_set(&mut self, contacts: &[FreeContact]) {
        let n = self.contact_sets.len();
        if n == 0 || self.contact_sets[n - 1].len() != contacts.len() {
            self.contact_sets.push(contacts);
        }
    }

    fn iterate(&mut self, x: &[Vector3<f64>], skeleton: Option<&Skeleton>) {
        if self.keep_iterates {
            self.push_iterate(x, skeleton);
        }
    }

    fn decompositions(&mut self, tets: usize, replace_last: bool) -> Option<&mut [TetSvd]> {
        if !(self.keep_iterates && self.keep_decompositions) {
            return None;
        }
        if replace_last {
            self.svds.pop();
        }
        // Every entry is written by the projection that follows: reuse the buffer unfilled.
        self.svds.push_uninit(tets, TetSvd::default());
        self.svds.last_mut()
    }

    fn records_iterations(&self) -> bool {
        self.keep_iterates
    }

    fn solved(&mut self, info: SolveInfo<'_>) {
        if !self.keep_iterates {
            self.solve_sets.clear();
            self.impulses.clear();
        }
        self.solve_sets.push(self.contact_sets.len() - 1);
        let mut iterative = false;
        self.impulses.push_with(|imp| {
            if !info.contacts.is_empty() {
                match info.impulses {
                    Some(l) => imp.extend_from_slice(l),
                    None => iterative = true,
                }
            }
        });
        self.iterative_contacts |= iterative;
        if let (true, Some((sp, rigid))) = (self.keep_iterates, info.skeletal) {
            self.increments.push(sp.last_increment());
            self.residuals.push(sp.last_residual());
            self.active_limits.push_with(|a| a.extend(sp.active_limits()));
            self.rigid_contact_solves += usize::from(!rigid.is_empty());
            self.rigid_contacts.push_with(|rc| {
                rc.extend(
                    rigid
                        .iter()
                        .zip(sp.rigid_contact_solution())
                        .map(|(&(i, c), (l, wt))| (i, c, l, wt)),
                );
            });
        }
    }

    fn end(&mut self, x: &[Vector3<f64>], skeleton: Option<&Skeleton>) {
        if self.keep_iterates {
            self.push_iterate(x, skeleton);
        }
    }
}
