//! Newton's method on the energy that projective dynamics minimises (docs/method.md section 6.5,
//! Eqs. S3-S5), selected with `solver: newton`.
//!
//! One implicit Euler step minimises `E(x)` over the free vertices (Eq. S3); projective
//! dynamics' local-global iteration is the fixed-Hessian descent `x <- x - A^-1 grad E(x)` with
//! `A = M/h^2 + L`. Newton's method replaces `A` by the projected Hessian `H = A - J K~ J^T`
//! ([`super::hessian`], Eq. S4):
//!
//! 1. at the iterate: the local step (every tet's projection and decomposition), the energy and
//!    `grad E = A x - b - J p` (the same quantities a local-global iteration computes);
//! 2. `H d = -grad E` by conjugate gradients preconditioned with the factored `A` (the
//!    [`Direct`] factor, per axis), stopped by an inexact-Newton forcing term (Eq. S5); first
//!    with the unprojected Hessian, which keeps Newton's quadratic convergence near the minimum,
//!    and with the projected one if conjugate gradients meet non-positive curvature;
//! 3. a backtracking (Armijo) line search on `E` along `d`; if it fails (it should not: `d` is a
//!    descent direction of an `E` that is smooth where the projections are), one
//!    projective-dynamics iteration from the same iterate, which never raises `E`;
//! 4. stop when the RMS change of the free positions is below `tolerance x length scale`, as
//!    projective dynamics does, or at `max_iterations`.
//!
//! Newton iterations are reported in `StepStats::iterations`, conjugate-gradient iterations in
//! `global_iterations`, direction solves that hit `inner_max_iterations` in `capped_solves`.
//!
//! Obstacle contacts (ground, obstacles) on free vertices are held as an active set
//! ([`super::newton_contact`], Eq. S6): directions and gradients are projected onto the held
//! contacts' constraints and the line search stops where a separated candidate meets its plane.
//!
//! Scope: tets (corotated elasticity and volume, actuators), fixed vertices, attachments,
//! gravity, obstacle contacts; skeletons in [`super::newton_skeletal`] (without obstacles).
//! Scenes with anything else (obstacles with a skeleton, collisions between bodies, cloth,
//! Anderson acceleration) are refused at [`super::Simulator::new`] by [`check_supported`].
//! Every buffer is allocated in [`Newton::new`] (the contact set's grow to the largest set
//! seen).

use std::time::Instant;

use nalgebra::Vector3;

use super::newton_cg::{self, CgWork, Direction, NewtonOperator};
use super::newton_contact::NewtonContacts;
use super::newton_rules::{accepts, ABSOLUTE_FRACTION, MAX_HALVINGS};
use super::{StepContext, StepIteration};
use crate::constraint::{Constraints, TetSvd};
use crate::model::Model;
use crate::solver::certificate::Certificate;
use crate::solver::direct::Direct;
use crate::solver::free_contact::FreeContact;
use crate::solver::global::{GlobalSolver, InnerControl, SolverKind};
use crate::solver::hessian::ConstraintHessian;
use crate::solver::observer::{SolveInfo, StepObserver};
use crate::solver::problem::StepProblem;
use crate::solver::system::System;
use crate::solver::{Settings, SolverError, StepStats};

/// Why Newton's method cannot run a model, or `Ok` (see the module docs' scope).
pub(crate) fn check_supported(model: &Model, settings: &Settings) -> Result<(), SolverError> {
    let unsupported = |what: &str| {
        Err(SolverError::input(format!(
            "solver newton does not support {what}; use solver: direct (--solver direct)"
        )))
    };
    if model.skeleton.is_some() && !model.obstacles.is_empty() {
        return unsupported("obstacle contacts with a skeleton (contacts on bone vertices in the reduced step)");
    }
    if model.collision.is_some() {
        return unsupported("collisions between bodies");
    }
    // Every constraint kind declares how it enters the Hessian; those that cannot are refused.
    if let Some(what) = ConstraintHessian::unsupported(model) {
        return unsupported(what);
    }
    if settings.anderson > 0 {
        return unsupported("Anderson acceleration (anderson > 0; Newton needs none)");
    }
    Ok(())
}

/// The certificate of a Newton run (no spectral certification: the line search makes every
/// iteration descend); `t0`: when its set-up began.
pub(crate) fn certificate(settings: &Settings, t0: Instant) -> Certificate {
    let mut cert = Certificate::unchecked(SolverKind::Newton, settings.certify, settings.dt);
    cert.message = "Newton's method on the step energy (Eqs. S3-S5): projected Hessian, conjugate gradients preconditioned with the factored M/h^2 + L, Armijo line search; no spectral certification needed".into();
    cert.elapsed_ms = t0.elapsed().as_secs_f64() * 1e3;
    cert
}

/// Newton's method's factor, Hessian and buffers (free numbering unless noted).
pub(crate) struct Newton {
    /// Sparse Cholesky of `A = M/h^2 + L` (the preconditioner).
    direct: Direct,
    /// The constraints' part of the Hessian at the current iterate.
    hessian: ConstraintHessian,
    /// Every tet's decomposition at the last local step.
    record: Vec<TetSvd>,
    /// Inner iteration cap.
    control: InnerControl,
    /// `grad E` at the current iterate.
    grad: Vec<Vector3<f64>>,
    /// Conjugate gradients' vectors; the Newton direction ends in `cg.dir`.
    cg: CgWork<Vec<Vector3<f64>>>,
    /// The iterate at the start of the line search.
    x0: Vec<Vector3<f64>>,
    /// Every vertex: a free vector scattered (zero at fixed vertices) and `J K~ J^T` of it.
    y_full: Vec<Vector3<f64>>,
    out_full: Vec<Vector3<f64>>,
    /// The active set of the step's obstacle contacts.
    contacts: NewtonContacts,
    /// Line searches that failed and were replaced by a projective-dynamics step (diagnostics).
    pub(crate) fallbacks: usize,
}

impl std::fmt::Debug for Newton {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Newton")
            .field("n", &self.grad.len())
            .field("fallbacks", &self.fallbacks)
            .finish()
    }
}

fn dot(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x.dot(y)).sum()
}

/// RMS length of a free vector.
fn rms(a: &[Vector3<f64>]) -> f64 {
    (dot(a, a) / a.len().max(1) as f64).sqrt()
}

/// What the Newton loop reads besides its own buffers: the step's problem and its contacts.
struct Ctx<'a> {
    /// The step's energy, gradient and Hessian.
    p: StepProblem<'a>,
    /// The step's contacts (obstacle contacts on free vertices).
    contacts: &'a [FreeContact],
}

impl Newton {
    /// Factor `A` and allocate every buffer.
    pub(crate) fn new(model: &Model, sys: &System, control: InnerControl) -> Result<Self, SolverError> {
        let (n, nf) = (model.n(), sys.n());
        let free = || vec![Vector3::zeros(); nf];
        Ok(Self {
            direct: sys.direct(control)?,
            hessian: ConstraintHessian::new(model),
            record: vec![TetSvd::default(); model.tets.len()],
            control,
            grad: free(),
            cg: CgWork::new(free()),
            x0: free(),
            y_full: vec![Vector3::zeros(); n],
            out_full: vec![Vector3::zeros(); n],
            contacts: NewtonContacts::default(),
            fallbacks: 0,
        })
    }

    /// The step energy `E` (Eq. S3) at the free iterate `x`, which is scattered into `full`:
    /// the local step (every tet decomposed into `record`), then inertia, constraints and
    /// attachments, less the held friction forces' work (Eq. S6). Returns `(E, constraint
    /// energy)`.
    fn energy(
        &mut self,
        cx: &Ctx<'_>,
        constraints: &mut Constraints,
        x: &[Vector3<f64>],
        full: &mut [Vector3<f64>],
    ) -> Result<(f64, f64), SolverError> {
        for (k, &v) in cx.p.sys.free.iter().enumerate() {
            full[v] = x[k];
        }
        let (mut e, elastic) = cx.p.energy(constraints, full, None, &mut self.record)?;
        e -= self.contacts.friction_work(cx.contacts, x);
        Ok((e, elastic))
    }

    /// `grad E = A x - b - J p` at `x` (Eq. S3) from the last local step, gathered into
    /// `gathered` (every vertex); with contacts, their impulses are recorded and the gradient
    /// becomes the held problem's, `P (grad E - f)` (Eq. S6).
    fn gradient(
        &mut self,
        cx: &Ctx<'_>,
        constraints: &mut Constraints,
        x: &[Vector3<f64>],
        gathered: &mut [Vector3<f64>],
    ) {
        cx.p.gradient(constraints, x, &[], &[], gathered, &mut self.grad, &mut []);
        if !cx.contacts.is_empty() {
            self.contacts.constrain_gradient(cx.contacts, &mut self.grad);
        }
    }

    /// Prepare the Hessian at the iterate `q` (every vertex; its decompositions are in
    /// `record`): unprojected (`K~_t = K_t`; with actuators every set's `K`) or projected
    /// (Eq. S4). Returns whether the unprojected one could be linearized.
    fn prepare(&mut self, model: &Model, q: &[Vector3<f64>], unprojected: bool) -> bool {
        self.hessian.prepare(model, &self.record, q, unprojected)
    }

    /// The Newton direction at the iterate `q` (every vertex) by conjugate gradients
    /// preconditioned with the factored `A` (Eq. S5, [`newton_cg::direction`]); in `cg.dir`.
    fn direction(
        &mut self,
        cx: &Ctx<'_>,
        q: &[Vector3<f64>],
        z_first: f64,
        floor: f64,
    ) -> Result<Direction, SolverError> {
        for (r, g) in self.cg.r.iter_mut().zip(&self.grad) {
            *r = -g;
        }
        let mut op = FreeOperator {
            cx,
            q,
            direct: &mut self.direct,
            hessian: &mut self.hessian,
            contacts: &self.contacts,
            y_full: &mut self.y_full,
            out_full: &mut self.out_full,
        };
        newton_cg::direction(&mut op, &mut self.cg, z_first, floor, self.control.max_iterations)
    }
}

/// Newton's system on the free vertices: `H = A - J K~ J^T` on the held contacts' complement,
/// preconditioned with the factored `A`.
struct FreeOperator<'a, 'c> {
    cx: &'a Ctx<'c>,
    /// The iterate (every vertex).
    q: &'a [Vector3<f64>],
    direct: &'a mut Direct,
    hessian: &'a mut ConstraintHessian,
    contacts: &'a NewtonContacts,
    y_full: &'a mut Vec<Vector3<f64>>,
    out_full: &'a mut Vec<Vector3<f64>>,
}

impl NewtonOperator for FreeOperator<'_, '_> {
    type V = Vec<Vector3<f64>>;

    fn precondition(&mut self, r: &Self::V, z: &mut Self::V) -> Result<(), SolverError> {
        self.direct.solve_free(r, z)?;
        self.contacts.project(self.cx.contacts, z);
        Ok(())
    }

    fn measure(&mut self, z: &Self::V) -> f64 {
        rms(z)
    }

    /// `hp = H p = A p - J K~ J^T p` (Eq. S4); `false` where an actuator's projection is not
    /// differentiable.
    fn apply(&mut self, p: &Self::V, hp: &mut Self::V) -> bool {
        let cx = self.cx;
        if !cx
            .p
            .hessian_product(self.hessian, self.q, p, &[], hp, &mut [], self.y_full, self.out_full)
        {
            return false;
        }
        self.contacts.project(cx.contacts, hp);
        true
    }
}

impl StepIteration for Newton {
    fn kind(&self) -> SolverKind {
        SolverKind::Newton
    }

    /// Newton iterations (see the module docs) from the first iterate `begin_step` set, until
    /// the RMS change of the free positions is below `tolerance x length scale` (with
    /// contacts: and no contact changed state, Eq. S6) or `max_iterations`. With contacts, the
    /// first iteration is a projective-dynamics one, whose impulses seed the contacts' states;
    /// the last iterate's impulses go to `observer`.
    fn iterate(
        &mut self,
        cx: &mut StepContext<'_>,
        stats: &mut StepStats,
        observer: &mut dyn StepObserver,
    ) -> Result<(), SolverError> {
        let (model, settings, system) = (cx.model, cx.settings, cx.system);
        stats.begin_round();
        let (constraints, w) = (&mut *cx.constraints, &mut *cx.work);
        let nw = self;
        let cs = &cx.contacts.free[..];
        let cx = Ctx {
            p: StepProblem {
                model,
                sys: system,
                activations: cx.activations,
                s: &w.s,
                ih2: cx.scheme.inv_h2(),
                base: &w.base,
                coords0: &[],
                torque: &[],
            },
            contacts: cs,
        };
        let tol = settings.absolute_tolerance(model);
        let floor = ABSOLUTE_FRACTION * tol;
        let nf = system.n();
        let tl = Instant::now();
        nw.contacts.seed(&[], &[]);
        if !cs.is_empty() {
            // One projective-dynamics iteration with the contacts: its impulses seed the
            // states, and its iterate satisfies every contact.
            nw.energy(&cx, constraints, &w.x, &mut w.full)?;
            constraints.gather(model, &mut w.gathered);
            for (k, &v) in system.free.iter().enumerate() {
                w.rhs[k] = w.base[k] + w.gathered[v];
            }
            w.x_prev.copy_from_slice(&w.x);
            let g = nw.direct.solve(system, &w.rhs, &mut w.x, cs)?;
            stats.iterations += 1;
            stats.global_iterations += g.iterations;
            stats.contact_iterations += g.contact_iterations;
            let impulses = GlobalSolver::impulses(&nw.direct).unwrap_or(&[]);
            let mut contacts_state = std::mem::take(&mut nw.contacts);
            contacts_state.seed(cs, impulses);
            contacts_state.enforce(cs, &mut w.x);
            nw.contacts = contacts_state;
        }
        let (mut e, mut elastic) = nw.energy(&cx, constraints, &w.x, &mut w.full)?;
        nw.gradient(&cx, constraints, &w.x, &mut w.gathered);
        stats.local_ms += tl.elapsed().as_secs_f64() * 1e3;
        let mut z_first = f64::NAN;
        // This round's budget (the seeding iteration counts).
        let iterations = settings.max_iterations.saturating_sub(usize::from(!cs.is_empty()));
        for _ in 0..iterations {
            if crate::base::cancel::requested() {
                return Err(SolverError::Interrupted);
            }
            // The projected Hessian at the iterate and the Newton direction.
            let tg = Instant::now();
            // The exact Hessian first (quadratic convergence near the minimum); where it shows
            // negative curvature, the projected one (Eq. S4).
            let mut dir = if nw.prepare(model, &w.full, true) {
                nw.direction(&cx, &w.full, z_first, floor)?
            } else {
                Direction::undefined()
            };
            if dir.indefinite {
                stats.global_iterations += dir.iterations;
                nw.prepare(model, &w.full, false);
                dir = nw.direction(&cx, &w.full, z_first, floor)?;
            }
            if z_first.is_nan() {
                z_first = dir.z0;
            }
            stats.global_iterations += dir.iterations;
            if !dir.met {
                stats.capped_solves += 1;
            }
            stats.global_ms += tg.elapsed().as_secs_f64() * 1e3;
            // Backtracking line search on E (Armijo), no further than where a separated
            // contact meets its plane.
            let tl = Instant::now();
            let gd = dot(&nw.grad, &nw.cg.dir);
            nw.x0.copy_from_slice(&w.x);
            let block = nw.contacts.blocking(cs, &nw.x0, &nw.cg.dir);
            let mut alpha = block.map_or(1.0, |(a, _)| a);
            let mut accepted = false;
            // Only a full Newton step can end the iteration: a step shortened by the line
            // search says nothing about the distance to the minimum.
            let mut full_step = true;
            let mut state_changed = false;
            if rms(&nw.cg.dir) <= floor && block.is_none() {
                // A direction below what the step resolves (the iterate is the minimiser up to
                // round-off, e.g. a rigid motion with no elastic force): take it as it is.
                for k in 0..nf {
                    w.x[k] = nw.x0[k] + nw.cg.dir[k];
                }
                (e, elastic) = nw.energy(&cx, constraints, &w.x, &mut w.full)?;
                accepted = true;
            } else if let Some((_, j)) = block.filter(|&(a, _)| a <= 0.0 && gd < 0.0) {
                // A separated contact on its plane blocks the direction at once: it joins.
                nw.contacts.activate(j);
                accepted = true;
                state_changed = true;
            } else if gd < 0.0 {
                for halving in 0..MAX_HALVINGS {
                    for k in 0..nf {
                        w.x[k] = nw.x0[k] + nw.cg.dir[k] * alpha;
                    }
                    let (et, el) = nw.energy(&cx, constraints, &w.x, &mut w.full)?;
                    if accepts(alpha, gd, e, et) {
                        (e, elastic) = (et, el);
                        accepted = true;
                        full_step = alpha == 1.0;
                        if let (0, Some((_, j))) = (halving, block) {
                            // The step went as far as the blocking contact: it joins.
                            nw.contacts.activate(j);
                            state_changed = true;
                        }
                        break;
                    }
                    alpha *= 0.5;
                }
            }
            if !accepted {
                full_step = false;
                // One projective-dynamics iteration from x0 instead: it never raises E (with
                // contacts, it also takes their states again).
                nw.fallbacks += 1;
                w.x.copy_from_slice(&nw.x0);
                nw.energy(&cx, constraints, &w.x, &mut w.full)?;
                constraints.gather(model, &mut w.gathered);
                for (k, &v) in system.free.iter().enumerate() {
                    w.rhs[k] = w.base[k] + w.gathered[v];
                }
                if cs.is_empty() {
                    nw.direct.solve_free(&w.rhs, &mut w.x)?;
                } else {
                    let g = nw.direct.solve(system, &w.rhs, &mut w.x, cs)?;
                    stats.contact_iterations += g.contact_iterations;
                    let impulses = GlobalSolver::impulses(&nw.direct).unwrap_or(&[]);
                    let mut contacts_state = std::mem::take(&mut nw.contacts);
                    contacts_state.seed(cs, impulses);
                    nw.contacts = contacts_state;
                    state_changed = true;
                }
                (e, elastic) = nw.energy(&cx, constraints, &w.x, &mut w.full)?;
            }
            let mut sq = 0.0;
            for k in 0..nf {
                sq += (w.x[k] - nw.x0[k]).norm_squared();
            }
            let change = (sq / nf.max(1) as f64).sqrt();
            nw.gradient(&cx, constraints, &w.x, &mut w.gathered);
            let mut friction_moved = 0.0;
            if !cs.is_empty() {
                // The contacts' states again from the impulses and the slip (Eq. S6).
                let mut contacts_state = std::mem::take(&mut nw.contacts);
                let direct = &mut nw.direct;
                let settled = change <= tol;
                let (changed, moved) = contacts_state.update(cs, &w.x, tol, settled, |v| direct.inverse_column(v)[v]);
                let displaced = contacts_state.enforce(cs, &mut w.x);
                nw.contacts = contacts_state;
                state_changed |= changed;
                friction_moved = moved;
                if displaced || changed || moved > 0.0 {
                    // New positions or held forces: the energy (its friction term) and the
                    // gradient again.
                    (e, elastic) = nw.energy(&cx, constraints, &w.x, &mut w.full)?;
                    nw.gradient(&cx, constraints, &w.x, &mut w.gathered);
                }
            }
            stats.local_ms += tl.elapsed().as_secs_f64() * 1e3;
            stats.iterations += 1;
            stats.elastic_energy = elastic;
            if !change.is_finite() || !e.is_finite() {
                return Err(SolverError::NonFinite(format!(
                    "step {}: positions became non-finite in Newton iteration {}",
                    stats.step, stats.iterations
                )));
            }
            stats.record_change(change / model.length_scale);
            if change <= tol && full_step && !state_changed && friction_moved <= tol {
                stats.converged = true;
                break;
            }
        }
        stats.elastic_energy = elastic;
        observer.solved(SolveInfo {
            contacts: cs,
            impulses: Some(nw.contacts.impulses()),
            skeletal: None,
        });
        Ok(())
    }

    /// The impulses of the step's contacts at Newton's last iterate.
    fn impulses(&self) -> Option<&[Vector3<f64>]> {
        Some(self.contacts.impulses())
    }
}
