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

use super::certify::Certificate;
use super::direct::Direct;
use super::free_contact::FreeContact;
use super::global::{GlobalSolver, GlobalStats, InnerControl, SolverKind};
use super::hessian::ElasticHessian;
use super::newton_contact::NewtonContacts;
use super::observer::{SolveInfo, StepObserver};
use super::simulator::{GlobalStep, Simulator};
use super::system::GlobalSystem;
use super::{Settings, SolverError, StepStats};
use crate::constraint::{Constraints, Linearize, ParamGrads, TetSvd};
use crate::model::Model;

use super::newton_rules::{accepts, forcing, ABSOLUTE_FRACTION, MAX_HALVINGS};

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
    if model.cloth.is_some() {
        return unsupported("cloth");
    }
    if settings.anderson > 0 {
        return unsupported("Anderson acceleration (anderson > 0; Newton needs none)");
    }
    Ok(())
}

/// Check the model, build the Newton solver and its certificate (no spectral certification:
/// the line search makes every iteration descend).
pub(crate) fn build(
    model: &Model,
    settings: &Settings,
    system: &GlobalSystem,
    control: InnerControl,
) -> Result<(GlobalStep, Certificate), SolverError> {
    check_supported(model, settings)?;
    if model.skeleton.is_some() {
        return super::newton_skeletal::build(model, settings, system, control);
    }
    let t0 = Instant::now();
    let newton = Newton::new(model, system, control)?;
    let mut cert = Certificate::unchecked(SolverKind::Newton, settings.certify, settings.dt);
    cert.message = "Newton's method on the step energy (Eqs. S3-S5): projected Hessian, conjugate gradients preconditioned with the factored M/h^2 + L, Armijo line search; no spectral certification needed".into();
    cert.elapsed_ms = t0.elapsed().as_secs_f64() * 1e3;
    Ok((GlobalStep::Free(Box::new(newton)), cert))
}

/// Newton's method's factor, Hessian and buffers (free numbering unless noted).
pub(crate) struct Newton {
    /// Sparse Cholesky of `A = M/h^2 + L` (the preconditioner).
    direct: Direct,
    /// The projected elastic Hessian at the current iterate.
    hessian: ElasticHessian,
    /// Every tet's decomposition at the last local step.
    record: Vec<TetSvd>,
    /// Inner iteration cap.
    control: InnerControl,
    /// `grad E` at the current iterate.
    grad: Vec<Vector3<f64>>,
    /// The Newton direction.
    dir: Vec<Vector3<f64>>,
    /// Conjugate gradients' residual, preconditioned residual, search direction, `H p`, `A p`.
    r: Vec<Vector3<f64>>,
    z: Vec<Vector3<f64>>,
    p: Vec<Vector3<f64>>,
    hp: Vec<Vector3<f64>>,
    ap: Vec<Vector3<f64>>,
    /// The iterate at the start of the line search.
    x0: Vec<Vector3<f64>>,
    /// Every vertex: a free vector scattered (zero at fixed vertices) and `J K~ J^T` of it.
    y_full: Vec<Vector3<f64>>,
    out_full: Vec<Vector3<f64>>,
    /// With actuators: the exact `K` of every constraint set (the backward pass's linearization)
    /// for the unprojected Hessian; `None` without (the elastic one serves).
    exact: Option<Box<ExactK>>,
    /// Whether the direction solve uses the unprojected Hessian.
    unprojected: bool,
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

/// Every constraint set's linearization `K` at the iterate (actuated models), with scratch for
/// the parameter adjoints its application also produces (discarded).
struct ExactK {
    constraints: Constraints,
    w_rot: Vec<f64>,
    w_vol: Vec<f64>,
    activations: Vec<f64>,
}

/// What one direction solve did.
#[derive(Debug, Clone, Copy)]
struct Direction {
    /// Conjugate-gradient iterations.
    iterations: usize,
    /// Whether the stopping rule was met before the cap.
    met: bool,
    /// `|A^-1 grad E|` (RMS): the length of the projective-dynamics step from this iterate.
    z0: f64,
    /// The Hessian showed non-positive curvature along a search direction (the unprojected
    /// Hessian is indefinite there).
    indefinite: bool,
}

/// What the Newton loop reads from the simulator besides its own buffers.
struct Ctx<'a> {
    model: &'a Model,
    sys: &'a GlobalSystem,
    activations: &'a [f64],
    /// The inertial target `s_n` (every vertex).
    s: &'a [Vector3<f64>],
    /// `1/h^2`.
    ih2: f64,
    /// The right-hand side's constant part `M s / h^2 + fixed pull + attachments` (free).
    base: &'a [Vector3<f64>],
    /// The step's contacts (obstacle contacts on free vertices).
    contacts: &'a [FreeContact],
}

impl Newton {
    /// Factor `A` and allocate every buffer.
    pub(crate) fn new(model: &Model, sys: &GlobalSystem, control: InnerControl) -> Result<Self, SolverError> {
        let (n, nf) = (model.n(), sys.n());
        let free = || vec![Vector3::zeros(); nf];
        Ok(Self {
            direct: Direct::new(sys, control)?,
            hessian: ElasticHessian::new(model),
            record: vec![TetSvd::default(); model.tets.len()],
            control,
            grad: free(),
            dir: free(),
            r: free(),
            z: free(),
            p: free(),
            hp: free(),
            ap: free(),
            x0: free(),
            y_full: vec![Vector3::zeros(); n],
            out_full: vec![Vector3::zeros(); n],
            exact: model.actuators.as_ref().map(|a| {
                Box::new(ExactK {
                    constraints: Constraints::new(model),
                    w_rot: vec![0.0; model.tets.len()],
                    w_vol: vec![0.0; model.tets.len()],
                    activations: vec![0.0; a.groups.len()],
                })
            }),
            unprojected: true,
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
        for (k, &v) in cx.sys.free.iter().enumerate() {
            full[v] = x[k];
        }
        let elastic = constraints.project(cx.model, full, cx.activations, Some(&mut self.record))?;
        let mut e = elastic;
        for ((qi, si), m) in full.iter().zip(cx.s).zip(&cx.model.mass) {
            e += 0.5 * cx.ih2 * m * (qi - si).norm_squared();
        }
        for a in &cx.model.attachments {
            e += a.energy(&full[a.vertex]);
        }
        e -= self.contacts.friction_work(cx.contacts, x);
        Ok((e, elastic))
    }

    /// `grad E = A x - b - J p` at `x` (Eq. S3) from the last local step, gathered into
    /// `gathered` (every vertex); with contacts, their impulses are recorded and the gradient
    /// becomes the held problem's, `P (grad E - f)` (Eq. S6).
    fn gradient(&mut self, cx: &Ctx<'_>, constraints: &Constraints, x: &[Vector3<f64>], gathered: &mut [Vector3<f64>]) {
        constraints.gather(cx.model, gathered);
        cx.sys.apply(x, &mut self.grad);
        for (k, &v) in cx.sys.free.iter().enumerate() {
            self.grad[k] -= cx.base[k] + gathered[v];
        }
        if !cx.contacts.is_empty() {
            self.contacts.constrain_gradient(cx.contacts, &mut self.grad);
        }
    }

    /// Prepare the Hessian at the iterate `q` (every vertex; `rec` its decompositions):
    /// unprojected (`K~_t = K_t`; with actuators every set's `K`) or projected (Eq. S4; the
    /// actuators' `K` is then left out, i.e. their blocks are the projective-dynamics
    /// `w A^T A`). Returns whether the unprojected one could be linearized.
    fn prepare(&mut self, model: &Model, q: &[Vector3<f64>], unprojected: bool) -> bool {
        self.unprojected = unprojected;
        self.hessian.build(model, &self.record, !unprojected);
        if let (true, Some(ex)) = (unprojected, self.exact.as_mut()) {
            return ex.constraints.linearize(model, q).is_ok();
        }
        true
    }

    /// `hp = H p = A p - J K~ J^T p` (Eq. S4) for the search direction `p` (`q`: the iterate,
    /// every vertex). `false` where an actuator's projection is not differentiable.
    fn apply_hessian(&mut self, cx: &Ctx<'_>, q: &[Vector3<f64>]) -> bool {
        cx.sys.apply(&self.p, &mut self.ap);
        for (k, &v) in cx.sys.free.iter().enumerate() {
            self.y_full[v] = self.p[k];
        }
        match (self.unprojected, self.exact.as_mut()) {
            (true, Some(ex)) => {
                let grads = ParamGrads {
                    w_rot: &mut ex.w_rot,
                    w_vol: &mut ex.w_vol,
                    activations: &mut ex.activations,
                };
                let r = ex.constraints.adjoint(
                    cx.model,
                    q,
                    &self.y_full,
                    None,
                    cx.activations,
                    Linearize::Cached,
                    &mut self.out_full,
                    grads,
                );
                if r.is_err() {
                    return false;
                }
            }
            _ => self.hessian.apply(cx.model, &self.y_full, &mut self.out_full),
        }
        for (k, &v) in cx.sys.free.iter().enumerate() {
            self.hp[k] = self.ap[k] - self.out_full[v];
        }
        self.contacts.project(cx.contacts, &mut self.hp);
        true
    }

    /// `H d = -grad E` by conjugate gradients preconditioned with `A^-1` from `d = 0` (Eq. S5):
    /// stop when the preconditioned residual's RMS is below `max(eta |A^-1 grad E|, floor)`,
    /// with the forcing term `eta` of [`forcing`] (`min(0.1, sqrt(|A^-1 grad E| / z_first))`, `z_first`:
    /// that length at the step's first iterate, `NaN` there).
    fn direction(
        &mut self,
        cx: &Ctx<'_>,
        q: &[Vector3<f64>],
        z_first: f64,
        floor: f64,
    ) -> Result<Direction, SolverError> {
        for (r, g) in self.r.iter_mut().zip(&self.grad) {
            *r = -g;
        }
        self.dir.iter_mut().for_each(|d| *d = Vector3::zeros());
        self.direct.solve_free(&self.r, &mut self.z)?;
        self.contacts.project(cx.contacts, &mut self.z);
        let z0 = rms(&self.z);
        let eta = forcing(z0, z_first);
        let stop = (eta * z0).max(floor);
        if z0 <= floor {
            // Already within the floor: the preconditioned gradient step is the direction.
            self.dir.copy_from_slice(&self.z);
            return Ok(Direction {
                iterations: 0,
                met: true,
                z0,
                indefinite: false,
            });
        }
        self.p.copy_from_slice(&self.z);
        let mut rz = dot(&self.r, &self.z);
        for it in 1..=self.control.max_iterations {
            let ok = self.apply_hessian(cx, q);
            let php = dot(&self.p, &self.hp);
            if !ok || php.is_nan() || php <= 0.0 {
                // Only the unprojected Hessian can get here (the projected one is positive
                // definite up to round-off): keep what was found, or the projective-dynamics
                // step if nothing was, and tell the caller.
                if it == 1 {
                    self.dir.copy_from_slice(&self.z);
                }
                return Ok(Direction {
                    iterations: it,
                    met: false,
                    z0,
                    indefinite: true,
                });
            }
            let alpha = rz / php;
            for k in 0..self.dir.len() {
                self.dir[k] += self.p[k] * alpha;
                self.r[k] -= self.hp[k] * alpha;
            }
            self.direct.solve_free(&self.r, &mut self.z)?;
            self.contacts.project(cx.contacts, &mut self.z);
            if rms(&self.z) <= stop {
                return Ok(Direction {
                    iterations: it,
                    met: true,
                    z0,
                    indefinite: false,
                });
            }
            let rz_new = dot(&self.r, &self.z);
            let beta = rz_new / rz;
            rz = rz_new;
            for (p, z) in self.p.iter_mut().zip(&self.z) {
                *p = z + *p * beta;
            }
        }
        Ok(Direction {
            iterations: self.control.max_iterations,
            met: false,
            z0,
            indefinite: false,
        })
    }
}

impl Simulator {
    /// Phase 3 with `solver: newton`: Newton iterations (see the module docs) from the first
    /// iterate `begin_step` set, until the RMS change of the free positions is below
    /// `tolerance x length scale` (with contacts: and no contact changed state, Eq. S6) or
    /// `max_iterations`. With contacts, the first iteration is a projective-dynamics one, whose
    /// impulses seed the contacts' states; the last iterate's impulses go to `observer`.
    pub(super) fn newton_iterate(
        &mut self,
        stats: &mut StepStats,
        observer: &mut dyn StepObserver,
    ) -> Result<(), SolverError> {
        let Simulator {
            model,
            settings,
            integrator,
            system,
            global,
            constraints,
            activations,
            contacts,
            work: w,
            ..
        } = self;
        let GlobalStep::Free(solver) = global else {
            unreachable!("Newton runs without a skeleton");
        };
        let nw = solver.as_newton().expect("solver newton holds the Newton solver");
        let cs = &contacts.free[..];
        let cx = Ctx {
            model,
            sys: system,
            activations,
            s: &w.s,
            ih2: integrator.inv_h2(),
            base: &w.base,
            contacts: cs,
        };
        let tol = settings.tolerance * model.length_scale;
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
            // The projected Hessian at the iterate and the Newton direction.
            let tg = Instant::now();
            // The exact Hessian first (quadratic convergence near the minimum); where it shows
            // negative curvature, the projected one (Eq. S4).
            let mut dir = if nw.prepare(model, &w.full, true) {
                nw.direction(&cx, &w.full, z_first, floor)?
            } else {
                Direction {
                    iterations: 0,
                    met: false,
                    z0: f64::NAN,
                    indefinite: true,
                }
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
            let gd = dot(&nw.grad, &nw.dir);
            nw.x0.copy_from_slice(&w.x);
            let block = nw.contacts.blocking(cs, &nw.x0, &nw.dir);
            let mut alpha = block.map_or(1.0, |(a, _)| a);
            let mut accepted = false;
            // Only a full Newton step can end the iteration: a step shortened by the line
            // search says nothing about the distance to the minimum.
            let mut full_step = true;
            let mut state_changed = false;
            if rms(&nw.dir) <= floor && block.is_none() {
                // A direction below what the step resolves (the iterate is the minimiser up to
                // round-off, e.g. a rigid motion with no elastic force): take it as it is.
                for k in 0..nf {
                    w.x[k] = nw.x0[k] + nw.dir[k];
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
                        w.x[k] = nw.x0[k] + nw.dir[k] * alpha;
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
            stats.relative_change = change / model.length_scale;
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
}

impl GlobalSolver for Newton {
    fn kind(&self) -> SolverKind {
        SolverKind::Newton
    }

    /// The projective-dynamics global step with the factored `A` (Newton's own step runs in
    /// [`Simulator::newton_iterate`] instead of the local-global iteration).
    fn solve(
        &mut self,
        sys: &GlobalSystem,
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
        contacts: &[FreeContact],
    ) -> Result<GlobalStats, SolverError> {
        self.direct.solve(sys, b, x, contacts)
    }

    fn parallel_inside(&self) -> bool {
        self.direct.parallel_inside()
    }

    fn as_newton(&mut self) -> Option<&mut Newton> {
        Some(self)
    }

    /// The impulses of the step's contacts at Newton's last iterate.
    fn impulses(&self) -> Option<&[Vector3<f64>]> {
        Some(self.contacts.impulses())
    }
}
