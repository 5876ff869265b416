//! The contact problem of a factored global solve, in contact space (docs/method.md section 4,
//! Eqs. C1-C3): contact `j`'s relative coordinate moves as `r_j = f_j + sum_k D_jk lambda_k`
//! under the impulses `lambda_k`, with `f` the contact-free solution and `D` the Delassus matrix
//! (one scalar per pair of contacts: the three axes share `A^-1`). The impulses must satisfy
//! every contact's Coulomb cone ([`crate::contact::project`]).
//!
//! Two methods share one solution:
//!
//! * **projected Gauss-Seidel** ([`ContactSpace::sweeps`]): one contact at a time, robust from
//!   any start, but its rate is set by the conditioning of `D`, which is poor when contacts
//!   share vertices (a cloth draped over a body: condition numbers of `1e7` and thousands of
//!   sweeps);
//! * **active set** ([`ContactSpace::active_set`]): with each contact's state fixed (separate,
//!   stick, or slide), the conditions are a small system of equations, linear except for the
//!   slip direction of a sliding contact, which is linearized (a semismooth Newton step). One
//!   dense solve of the active contacts' equations gives the impulses; the states are taken
//!   again from the result. The equations carry a small proximal term that pulls each active
//!   impulse towards its current value: it leaves the solution unchanged (it vanishes at a fixed
//!   point) but keeps the system solvable when contacts restate one another (a cloth vertex
//!   against a face corner and that corner against a face around the vertex act on almost the
//!   same relative coordinate with different planes). While the states still change from one
//!   step to the next, a sliding contact whose slip direction barely reacts to its own impulse
//!   keeps that direction fixed for the step (one unknown and one row instead of two, see
//!   [`DIRECTION_GAIN`]); once the states repeat, every slip direction is linearized again,
//!   so the end game stays quadratic. Each step is damped (halved until the
//!   residual decreases); when no damping helps, a few full steps are taken anyway
//!   (non-monotone), and the best iterate is kept. The method is quadratic once the states are
//!   right, and starts after a few Gauss-Seidel sweeps (Gauss-Seidel goes on if it fails).
//!
//! A solution of either passes the other's test: the caller confirms an active-set solution
//! with one Gauss-Seidel sweep whose largest change must be within the tolerance.

use nalgebra::Vector3;

use super::dense_lu::DenseLu;
use super::free_contact::FreeContact;
use crate::contact::{project, ContactState};

/// Dense solves per active-set attempt before giving up (Gauss-Seidel then continues); a
/// contact solve makes at most [`MAX_ATTEMPTS`] attempts, later ones only while the dense work
/// stays within [`DENSE_WORK_RATIO`] times the sweeps'.
const ACTIVE_SET_SOLVES: usize = 30;

/// Later active-set attempts are made while the dense work so far is at most this many times
/// the sweeps' (measured on the paper's cloth_ball: a retry from an iterate the sweeps improved
/// mostly succeeds, and a failed attempt costs about 30 sweeps of a hundred contacts).
const DENSE_WORK_RATIO: f64 = 32.0;

/// Active-set attempts per contact solve.
const MAX_ATTEMPTS: usize = 12;

/// Gauss-Seidel sweeps between two checks of whether the run was asked to stop
/// ([`crate::base::cancel`]): a batch of sweeps of a large contact set can take seconds.
const CANCEL_CHECK_SWEEPS: usize = 64;

/// Full Newton steps an active-set attempt may take that raise the residual (when no damped
/// step lowers it); the attempt keeps its best iterate.
const NON_MONOTONE_STEPS: usize = 5;

/// A batch of at least this many sweeps that lowers the largest change by less than
/// [`STALL_RATIO`] ends the solve as stalled.
const STALL_SWEEPS: usize = 128;
/// See [`STALL_SWEEPS`].
const STALL_RATIO: f64 = 0.99;

/// Gauss-Seidel sweeps at most in a solve with [`Effort::AfterStall`].
const AFTER_STALL_SWEEPS: usize = 64;
/// In a solve with [`Effort::AfterStall`], a batch of at least this many sweeps that lowers the
/// largest change by less than [`STALL_RATIO`] ends the solve as stalled.
const AFTER_STALL_CHECK: usize = 16;

/// How hard a contact solve tries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Effort {
    /// Gauss-Seidel with active-set attempts, until the tolerance, the cap or a stall.
    Full,
    /// The same contact set's previous solve in this step stalled (or was itself a solve of
    /// this kind that did not converge): a set that stalled once has stalled again in nearly
    /// every later local-global iteration measured (the ball thrown at the cloth at 1000 m/s:
    /// 4 of 581 such solves converged, and each spent about 140 ms in active-set attempts
    /// and sweeps before it was declared stalled again), so only Gauss-Seidel runs from the
    /// warm start, at most [`AFTER_STALL_SWEEPS`] sweeps, with the stall check from
    /// [`AFTER_STALL_CHECK`] sweeps. It still reports converged when it meets the tolerance.
    AfterStall,
}

/// Shortest step along a Newton direction the line search tries.
const MIN_STEP: f64 = 1e-6;

/// Proximal weight on the active contacts' own entries (relative to `D_jj`): each Newton system
/// adds `PROXIMAL D_jj (lambda_j - lambda_j^current)` to a contact's constrained rows, so that
/// redundant contacts (several on almost the same vertices, a nearly singular `D`) still give
/// a well-posed system. The term is zero at a fixed point: the solution is not regularized.
const PROXIMAL: f64 = 1e-6;

/// While the active set's states change between its Newton steps, a sliding contact with
/// `mu lambda_N D_jj / |slip| <= DIRECTION_GAIN` keeps its slip direction fixed for the step
/// (its impulse is `t (n + mu dir)`: one unknown and one row) instead of linearizing it (two).
/// That product is the gain of the direction's own feedback (the slip moves by about `D_jj`
/// per unit of tangential impulse, and the impulse's direction turns by that over `|slip|`),
/// so below 1 fixing the direction converges by itself, and the dense system shrinks by up to
/// a third. Measured on the same contact problems (every contact solve of 400 steps, each
/// solved both ways): the paper's cloth_ball 0.83x the contact solve time and 14 instead of
/// 22 unconverged solves, Baymax on the ground 0.94x, the ball on the cloth 0.98x; fixing
/// every direction while the states change (any gain) made the ground 1.5x and cloth_ball
/// 1.6x slower, and fixing those below the gain in every step, not only while the states
/// change, made the ground 3.2x slower (linear convergence all the way to the tolerance);
/// docs/performance.md.
const DIRECTION_GAIN: f64 = 1.0;

/// A contact's state in the active-set method.
#[derive(Debug, Clone, Copy, PartialEq)]
enum State {
    Separate,
    Stick,
    /// Sliding, the tangential impulse along the unit direction `dir` (against the slip); `c`
    /// is `mu lambda_N / |slip|` at the current iterate (0: the direction is held fixed), the
    /// slip direction's sensitivity in the Newton linearization.
    Slide {
        dir: Vector3<f64>,
        c: f64,
    },
}

/// Buffers of the contact-space methods (they grow to the largest contact set seen).
#[derive(Debug, Clone, Default)]
pub(crate) struct ContactSpace {
    state: Vec<State>,
    /// Unknowns of the active-set system: `(contact, direction)`, the contact's impulse being
    /// the sum of its directions times their unknowns (the three axes for a sticking contact;
    /// `n + mu dir` and `n x dir` for a sliding one, which puts it on its cone's boundary).
    unknowns: Vec<(usize, Vector3<f64>)>,
    /// Equations of the active-set system: `(contact, row)` (rows 0-2 of a sticking contact;
    /// 0 and 2 of a sliding one).
    rows: Vec<(usize, u8)>,
    matrix: Vec<f64>,
    rhs: Vec<f64>,
    /// `r = f + D lambda` at the active-set iterate, kept up to date along the line search.
    r: Vec<Vector3<f64>>,
    trial: Vec<Vector3<f64>>,
    /// A Newton step: `trial - lambda`, and `D` times it.
    delta: Vec<Vector3<f64>>,
    d_delta: Vec<Vector3<f64>>,
    /// A point of the line search, and its `r` (`r + step D delta`: `r` is linear in the step,
    /// so a point costs `O(m)` instead of a product with `D`).
    candidate: Vec<Vector3<f64>>,
    candidate_r: Vec<Vector3<f64>>,
    /// The best iterate of a non-monotone active-set attempt.
    best: Vec<Vector3<f64>>,
    /// The dense solver of the active-set systems.
    lu: DenseLu,
    /// Work of the current solve's dense steps, in multiply-adds (LU and residuals).
    dense_work: f64,
    /// The kinds of the previous Newton step's states (separate, stick or slide).
    previous_states: Vec<std::mem::Discriminant<State>>,
    /// Whether the current Newton step fixes the slip directions below [`DIRECTION_GAIN`].
    fix_directions: bool,
    /// Linearize every slip direction in every step (the method before
    /// [`DIRECTION_GAIN`], for comparisons in tests).
    #[cfg(test)]
    always_linearize: bool,
}

/// What a contact-space solve did.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct ContactSolve {
    /// Gauss-Seidel sweeps.
    pub sweeps: usize,
    /// Dense active-set solves.
    pub active_set_solves: usize,
    /// Largest change of the last sweep (m).
    pub last_change: f64,
    /// Whether the last sweep changed no contact by more than the tolerance.
    pub converged: bool,
    /// Whether the solve stopped early for lack of progress (not converged).
    pub stalled: bool,
}

/// The contact problem: `m` contacts, `D` row-major `m x m`, the contact-free relative
/// coordinates `f`.
pub(crate) struct Problem<'a> {
    pub d: &'a [f64],
    pub f: &'a [Vector3<f64>],
    pub contacts: &'a [FreeContact],
}

impl Problem<'_> {
    fn m(&self) -> usize {
        self.f.len()
    }

    /// `out = D lambda`.
    fn apply_d(&self, lambda: &[Vector3<f64>], out: &mut Vec<Vector3<f64>>) {
        let m = self.m();
        out.clear();
        out.extend(self.d.chunks_exact(m).map(|row| {
            row.iter()
                .zip(lambda)
                .fold(Vector3::zeros(), |acc, (d, l)| acc + l * *d)
        }));
    }

    /// `out = f + D lambda`: every contact's relative coordinate under the impulses.
    fn positions(&self, lambda: &[Vector3<f64>], out: &mut Vec<Vector3<f64>>) {
        self.apply_d(lambda, out);
        for (r, f) in out.iter_mut().zip(self.f) {
            *r += f;
        }
    }

    /// `r_j` with contact `j`'s own impulse left out.
    fn x_hat(&self, j: usize, lambda: &[Vector3<f64>]) -> Vector3<f64> {
        let m = self.m();
        let row = &self.d[j * m..(j + 1) * m];
        let mut x = self.f[j];
        for (k, (l, d)) in lambda.iter().zip(row).enumerate() {
            if k != j {
                x += l * *d;
            }
        }
        x
    }
}

impl ContactSpace {
    /// Solve to `tolerance` (largest change of a contact's position in a sweep, m) within
    /// `max_sweeps` Gauss-Seidel sweeps, starting from `lambda` and trying the active-set
    /// method after a few sweeps and then at doubling intervals. Stops early, not converged,
    /// when a long batch of sweeps makes no progress (`stalled`). With
    /// [`Effort::AfterStall`] only Gauss-Seidel runs, within [`AFTER_STALL_SWEEPS`] sweeps.
    pub(crate) fn solve(
        &mut self,
        p: &Problem<'_>,
        lambda: &mut [Vector3<f64>],
        tolerance: f64,
        max_sweeps: usize,
        effort: Effort,
    ) -> ContactSolve {
        let (max_sweeps, stall_sweeps, max_attempts) = match effort {
            Effort::Full => (max_sweeps, STALL_SWEEPS, MAX_ATTEMPTS),
            Effort::AfterStall => (max_sweeps.min(AFTER_STALL_SWEEPS), AFTER_STALL_CHECK, 0),
        };
        let mut out = ContactSolve {
            last_change: f64::INFINITY,
            ..ContactSolve::default()
        };
        let m = p.m();
        self.dense_work = 0.0;
        let mut budget = 2usize;
        let mut attempts = 0;
        while out.sweeps < max_sweeps {
            if crate::base::cancel::requested() {
                // Asked to stop: the step is abandoned (the iteration above returns
                // `Interrupted`), so the iterate so far serves.
                break;
            }
            let n = budget.min(max_sweeps - out.sweeps);
            let before = out.last_change;
            let (done, change) = Self::sweeps(p, lambda, tolerance, n);
            out.sweeps += done;
            out.last_change = change;
            if change <= tolerance {
                out.converged = true;
                return out;
            }
            if out.sweeps >= max_sweeps {
                break;
            }
            if n >= stall_sweeps && change > STALL_RATIO * before {
                // No progress over a long batch: an infeasible set (contacts on the same
                // vertices with opposed normals, e.g. two surfaces already crossed) or a rate
                // that could not reach the tolerance within the cap anyway.
                out.stalled = true;
                break;
            }
            // The first attempt always; later ones (from the iterate the sweeps improved) while
            // the dense work stays within DENSE_WORK_RATIO times the sweeps', so a problem the
            // active-set method cannot solve costs a bounded multiple of Gauss-Seidel alone.
            let sweep_work = (out.sweeps * m * m) as f64;
            if (attempts == 0 && max_attempts > 0)
                || (attempts < max_attempts && self.dense_work <= DENSE_WORK_RATIO * sweep_work)
            {
                attempts += 1;
                let (solved, solves) = self.active_set(p, lambda, tolerance);
                out.active_set_solves += solves;
                if solved {
                    // The confirming sweep is the next round's first.
                    budget = 1;
                    continue;
                }
            }
            budget = (budget.max(2) * 2).min(1 << 14);
        }
        out
    }

    /// Up to `max` projected Gauss-Seidel sweeps; stops after a sweep whose largest change is
    /// within `tolerance`. Returns the sweeps and the last sweep's largest change.
    fn sweeps(p: &Problem<'_>, lambda: &mut [Vector3<f64>], tolerance: f64, max: usize) -> (usize, f64) {
        let m = p.m();
        let mut change = f64::INFINITY;
        for sweep in 0..max {
            if sweep % CANCEL_CHECK_SWEEPS == CANCEL_CHECK_SWEEPS - 1 && crate::base::cancel::requested() {
                return (sweep, change);
            }
            change = 0.0f64;
            for j in 0..m {
                let djj = p.d[j * m + j];
                let x_hat = p.x_hat(j, lambda);
                let (l, _) = project(&x_hat, 1.0 / djj, &p.contacts[j].contact);
                change = change.max(((l - lambda[j]) * djj).amax());
                lambda[j] = l;
            }
            if change <= tolerance {
                return (sweep + 1, change);
            }
        }
        (max, change)
    }

    /// The active-set method: the states `lambda` implies (by each contact's cone projection)
    /// fix a system of equations; one Newton step of it ([`ContactSpace::solve_states`]) gives
    /// the next impulses, whose states are taken again (a contact whose solution pulls is
    /// separate at the next step). Returns whether the residual ([`ContactSpace::residual`])
    /// reached `tolerance` within [`ACTIVE_SET_SOLVES`] steps, and the steps made. Each step
    /// is damped so the residual decreases; where no damped step does, up to
    /// [`NON_MONOTONE_STEPS`] full steps are taken anyway. `lambda` ends at the best iterate
    /// seen, so it only improves.
    fn active_set(&mut self, p: &Problem<'_>, lambda: &mut [Vector3<f64>], tolerance: f64) -> (bool, usize) {
        let m = p.m();
        let mut r = std::mem::take(&mut self.r);
        p.positions(lambda, &mut r);
        self.r = r;
        self.dense_work += (m * m) as f64;
        let mut res = Self::residual_at(p, &self.r, lambda);
        let mut best_res = res;
        self.best.clear();
        self.best.extend_from_slice(lambda);
        let mut non_monotone = NON_MONOTONE_STEPS;
        let mut solves = 0;
        let solved = loop {
            if solves == ACTIVE_SET_SOLVES {
                break false;
            }
            self.classify(p, lambda);
            self.note_states(solves == 0);
            self.trial.clear();
            self.trial.resize(lambda.len(), Vector3::zeros());
            let mut trial = std::mem::take(&mut self.trial);
            solves += 1;
            let ok = self.solve_states(p, lambda, &mut trial);
            self.trial = trial;
            if !ok {
                break false;
            }
            self.delta.clear();
            self.delta
                .extend(self.trial.iter().zip(lambda.iter()).map(|(t, l)| t - l));
            let mut d_delta = std::mem::take(&mut self.d_delta);
            p.apply_d(&self.delta, &mut d_delta);
            self.d_delta = d_delta;
            self.dense_work += (m * m) as f64;
            // Damped: the longest step (halving from the full Newton step) that lowers the
            // residual; none lowers it: the full step while the non-monotone budget lasts.
            let mut step = 1.0;
            let mut moved = true;
            loop {
                self.candidate.clear();
                self.candidate
                    .extend(lambda.iter().zip(&self.delta).map(|(l, d)| l + d * step));
                self.candidate_r.clear();
                self.candidate_r
                    .extend(self.r.iter().zip(&self.d_delta).map(|(r, d)| r + d * step));
                let r = Self::residual_at(p, &self.candidate_r, &self.candidate);
                self.dense_work += m as f64;
                if r < res {
                    res = r;
                    lambda.copy_from_slice(&self.candidate);
                    self.r.copy_from_slice(&self.candidate_r);
                    break;
                }
                step *= 0.5;
                if step < MIN_STEP {
                    if non_monotone == 0 {
                        moved = false;
                    } else {
                        non_monotone -= 1;
                        lambda.copy_from_slice(&self.trial);
                        for (r, d) in self.r.iter_mut().zip(&self.d_delta) {
                            *r += d;
                        }
                        res = Self::residual_at(p, &self.r, lambda);
                        self.dense_work += m as f64;
                    }
                    break;
                }
            }
            if res < best_res {
                best_res = res;
                self.best.copy_from_slice(lambda);
            }
            if res <= tolerance {
                break true;
            }
            if !moved {
                break false;
            }
        };
        if !solved {
            lambda.copy_from_slice(&self.best);
        }
        (solved, solves)
    }

    /// The largest change a projection of each contact (the others held) would make, in
    /// position (m), given `r = f + D lambda`: 0 exactly at a solution.
    fn residual_at(p: &Problem<'_>, r: &[Vector3<f64>], lambda: &[Vector3<f64>]) -> f64 {
        let m = p.m();
        let mut worst = 0.0f64;
        for j in 0..m {
            let djj = p.d[j * m + j];
            let x_hat = r[j] - lambda[j] * djj;
            let (l, _) = project(&x_hat, 1.0 / djj, &p.contacts[j].contact);
            worst = worst.max(((l - lambda[j]) * djj).amax());
        }
        worst
    }

    /// [`ContactSpace::residual_at`] from `lambda` alone.
    #[cfg(test)]
    fn residual(p: &Problem<'_>, lambda: &[Vector3<f64>]) -> f64 {
        let mut r = Vec::new();
        p.positions(lambda, &mut r);
        Self::residual_at(p, &r, lambda)
    }

    /// Record the states just classified and decide whether the next Newton step fixes slip
    /// directions ([`DIRECTION_GAIN`]): it does unless the states equal the previous step's
    /// (`first`: there is no previous step in this attempt).
    fn note_states(&mut self, first: bool) {
        let kinds = self.state.iter().map(std::mem::discriminant);
        let settled = !first && self.previous_states.iter().copied().eq(kinds.clone());
        self.previous_states.clear();
        self.previous_states.extend(kinds);
        self.fix_directions = !settled;
        #[cfg(test)]
        if self.always_linearize {
            self.fix_directions = false;
        }
    }

    /// Each contact's state at `lambda` (with `self.r` its `f + D lambda`), by its cone
    /// projection, with what the Newton linearization of a sliding contact needs.
    fn classify(&mut self, p: &Problem<'_>, lambda: &[Vector3<f64>]) {
        let m = p.m();
        self.state.clear();
        for (j, (&r, lambda_j)) in self.r.iter().zip(lambda).enumerate() {
            let c = &p.contacts[j].contact;
            let djj = p.d[j * m + j];
            let x_hat = r - lambda_j * djj;
            let (l, s) = project(&x_hat, 1.0 / djj, c);
            self.state.push(match s {
                ContactState::Separate => State::Separate,
                ContactState::Stick => State::Stick,
                ContactState::Slide => {
                    let lt = l - c.normal * c.normal.dot(&l);
                    let dir = lt / lt.norm();
                    let rel = r - c.anchor;
                    let slip = rel - c.normal * c.normal.dot(&rel);
                    let sn = slip.norm();
                    let ln = c.normal.dot(lambda_j).max(c.normal.dot(&l));
                    if sn > 0.0 && slip.dot(&dir) < 0.0 {
                        State::Slide {
                            dir: -slip / sn,
                            c: c.friction * ln / sn,
                        }
                    } else {
                        State::Slide { dir, c: 0.0 }
                    }
                }
            });
        }
    }

    /// One Newton step of the contact conditions with the states fixed: sticking contacts sit
    /// at their target, sliding ones on the plane with the impulse on the cone's boundary
    /// against the slip, whose direction is linearized at the current iterate (`self.r`). A
    /// sliding contact's impulse is written on the cone's boundary (two unknowns, not three),
    /// so the system has three unknowns per sticking contact and two per sliding one (one
    /// while its direction is held, [`DIRECTION_GAIN`]).
    /// `current` is the iterate the states were taken at (the proximal term's centre); the
    /// result goes into `lambda`. Returns false when the system is singular.
    fn solve_states(&mut self, p: &Problem<'_>, current: &[Vector3<f64>], lambda: &mut [Vector3<f64>]) -> bool {
        let m = p.m();
        self.unknowns.clear();
        self.rows.clear();
        for (j, s) in self.state.iter().enumerate() {
            let c = &p.contacts[j].contact;
            match *s {
                State::Separate => {}
                State::Stick => {
                    self.unknowns.extend((0..3).map(|a| (j, Vector3::ith(a, 1.0))));
                    self.rows.extend((0..3).map(|a| (j, a)));
                }
                State::Slide { dir, c: sens } => {
                    // On the cone's boundary along `dir` by construction: the impulse is
                    // `t (n + mu dir) + u (n x dir)`, with `u = 0` while the direction is
                    // held (DIRECTION_GAIN).
                    self.unknowns.push((j, c.normal + dir * c.friction));
                    self.rows.push((j, 0));
                    if !(self.fix_directions && sens * p.d[j * m + j] <= DIRECTION_GAIN) {
                        self.unknowns.push((j, c.normal.cross(&dir)));
                        self.rows.push((j, 2));
                    }
                }
            }
        }
        let k = self.unknowns.len();
        self.matrix.clear();
        self.matrix.resize(k * k, 0.0);
        self.rhs.clear();
        for (row, &(j, a)) in self.rows.iter().enumerate() {
            let c = &p.contacts[j].contact;
            let drow = &p.d[j * m..(j + 1) * m];
            let djj = drow[j];
            // Row `a` of contact `j`: `sum_k coupling D_jk (test . lambda_k) + own . lambda_j = rhs`
            // (a constrained row's proximal part of `own` has its `current` value in `rhs`).
            let (test, coupling, own, rhs) = match (self.state[j], a) {
                (State::Stick, _) => {
                    // On the plane at the anchor's tangential position.
                    let e = Vector3::ith(a as usize, 1.0);
                    let target = c.anchor + c.normal * c.normal.dot(&(c.point - c.anchor));
                    let own = e * (PROXIMAL * djj);
                    (e, 1.0, own, e.dot(&(target - p.f[j])) + own.dot(&current[j]))
                }
                (State::Slide { .. }, 0) => {
                    let own = c.normal * (PROXIMAL * djj);
                    (
                        c.normal,
                        1.0,
                        own,
                        c.normal.dot(&(c.point - p.f[j])) + own.dot(&current[j]),
                    )
                }
                (State::Slide { dir, c: sens }, _) => {
                    // No impulse across the slip direction `b`, linearized:
                    // `b . lambda_j + sens b . (r_j - r0_j) = 0`, scaled to D's size.
                    let b = c.normal.cross(&dir);
                    let scale = djj / (1.0 + sens * djj);
                    (b, sens * scale, b * scale, sens * scale * b.dot(&(self.r[j] - p.f[j])))
                }
                (State::Separate, _) => unreachable!("separate contacts have no equations"),
            };
            self.rhs.push(rhs);
            let out = &mut self.matrix[row * k..(row + 1) * k];
            for (col, (kc, v)) in self.unknowns.iter().enumerate() {
                let mut e = coupling * drow[*kc] * test.dot(v);
                if *kc == j {
                    e += own.dot(v);
                }
                out[col] = e;
            }
        }
        self.dense_work += (k * k * k) as f64 / 3.0 + (k * m) as f64;
        if !self.lu.solve(&mut self.matrix, &mut self.rhs, k) {
            return false;
        }
        lambda.iter_mut().for_each(|l| *l = Vector3::zeros());
        for ((j, v), u) in self.unknowns.iter().zip(&self.rhs) {
            lambda[*j] += v * *u;
        }
        lambda.iter().all(|l| l.iter().all(|v| v.is_finite()))
    }
}

#[cfg(test)]
mod tests;
