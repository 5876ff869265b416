//! Projective dynamics' local-global iterations (docs/method.md section 2): each iteration is
//! a local step (Eq. 3, every constraint projected in parallel, with Anderson's safeguard) and
//! a global step (Eq. 5) with the chosen global solver on the free vertices, or with a
//! skeleton the reduced step (Eqs. 17-18); stop when the RMS change of the free positions is
//! below `tolerance x length scale` or at the iteration cap.

use std::time::Instant;

use nalgebra::Vector3;

use super::{StepContext, StepIteration};
use crate::skeleton::Skeleton;
use crate::solver::anderson::Anderson;
use crate::solver::direct::Direct;
use crate::solver::global::{GlobalSolver, GlobalStats, InnerControl, SolverKind};
use crate::solver::observer::{SolveInfo, StepObserver};
use crate::solver::problem::step_objective;
use crate::solver::skeletal::Skeletal;
use crate::solver::system::System;
use crate::solver::{warm, SolverError, StepStats};

/// The skeleton's reduced step (Eqs. 17-18): the factored free block and the Schur complement
/// of the bone vertices.
pub(crate) struct ReducedStep {
    /// Sparse Cholesky of the free block.
    pub direct: Box<Direct>,
    /// Schur complement and buffers of the reduced step.
    pub reduced: Box<Skeletal>,
}

impl ReducedStep {
    /// Factor the free block of `system` and reduce the bone block of `sk` to its Schur
    /// complement.
    pub(crate) fn new(system: &System, sk: &Skeleton, control: InnerControl) -> Result<Self, SolverError> {
        let direct = Box::new(system.direct(control)?);
        let reduced = Box::new(Skeletal::new(system, &direct, sk));
        Ok(Self { direct, reduced })
    }
}

/// The global step of a local-global iteration.
pub(crate) enum GlobalPhase {
    /// Any [`GlobalSolver`] on the free vertices.
    Free(Box<dyn GlobalSolver>),
    /// The skeleton's reduced step.
    Reduced(ReducedStep),
}

impl GlobalPhase {
    /// The phase, borrowed.
    pub(crate) fn as_mut(&mut self) -> PhaseRef<'_> {
        match self {
            GlobalPhase::Free(s) => PhaseRef::Free(&mut **s),
            GlobalPhase::Reduced(r) => PhaseRef::Reduced(r),
        }
    }
}

/// A borrowed global phase (Newton with a skeleton runs the reduced one without owning a
/// [`GlobalPhase`]).
pub(crate) enum PhaseRef<'a> {
    /// A global solver on the free vertices.
    Free(&'a mut dyn GlobalSolver),
    /// The skeleton's reduced step.
    Reduced(&'a mut ReducedStep),
}

/// Local-global iterations with a global phase and, optionally, Anderson acceleration.
pub(crate) struct LocalGlobal {
    global: GlobalPhase,
    /// Anderson acceleration of the iteration (`None`: the paper's plain iteration).
    anderson: Option<Anderson>,
}

impl LocalGlobal {
    /// Iterations with `global` as the global step.
    pub(crate) fn new(global: GlobalPhase, anderson: Option<Anderson>) -> Self {
        Self { global, anderson }
    }
}

impl StepIteration for LocalGlobal {
    fn kind(&self) -> SolverKind {
        match &self.global {
            GlobalPhase::Free(s) => s.kind(),
            GlobalPhase::Reduced(_) => SolverKind::Direct,
        }
    }

    fn begin_step(&mut self) {
        match &mut self.global {
            GlobalPhase::Free(s) => s.begin_step(),
            GlobalPhase::Reduced(r) => {
                r.reduced.reset_impulses();
                r.direct.begin_step();
            }
        }
    }

    /// Local-global iterations for the current contact set, until the RMS change of the free
    /// positions is below `tolerance x length scale` or the iteration cap.
    fn iterate(
        &mut self,
        cx: &mut StepContext<'_>,
        stats: &mut StepStats,
        observer: &mut dyn StepObserver,
    ) -> Result<(), SolverError> {
        if let Some(aa) = self.anderson.as_mut() {
            aa.reset();
        }
        let tol = cx.tolerance();
        let nf = cx.system.n();
        let rms = (nf.max(1) as f64).sqrt();
        stats.begin_round();
        let mut energy_prev = f64::INFINITY;
        let mut accelerated = false;
        for _ in 0..cx.settings.max_iterations {
            observer.iterate(&cx.work.x, cx.skeleton.as_deref());
            cx.scatter_iterate();
            let tl = Instant::now();
            local_phase(
                cx,
                self.anderson.as_mut(),
                stats,
                observer,
                &mut energy_prev,
                accelerated,
            )?;
            stats.local_ms += tl.elapsed().as_secs_f64() * 1e3;
            let tg = Instant::now();
            let g = global_phase(cx, self.global.as_mut(), observer)?;
            stats.global_ms += tg.elapsed().as_secs_f64() * 1e3;
            // A step whose iterations or contact solves run long still stops when asked (its
            // state stays the one it started from).
            if crate::base::cancel::requested() {
                return Err(SolverError::Interrupted);
            }
            stats.iterations += 1;
            stats.global_iterations += g.iterations;
            stats.contact_iterations += g.contact_iterations;
            if !g.converged {
                stats.capped_solves += 1;
            }
            let w = &mut *cx.work;
            let mut sq = 0.0;
            for k in 0..nf {
                sq += (w.x[k] - w.x_prev[k]).norm_squared();
            }
            let change = sq.sqrt() / rms;
            if !change.is_finite() {
                return Err(SolverError::NonFinite(format!(
                    "step {}: positions became non-finite in local-global iteration {}",
                    stats.step, stats.iterations
                )));
            }
            stats.record_change(change / cx.model.length_scale);
            if change <= tol {
                stats.converged = true;
                break;
            }
            if let Some(aa) = self.anderson.as_mut() {
                // w.x = G(x_prev): mix into the next iterate (the plain update is kept).
                w.x_plain.copy_from_slice(&w.x);
                aa.mix(&w.x_prev, &w.x_plain, &mut w.x);
                accelerated = true;
            }
        }
        Ok(())
    }

    fn impulses(&self) -> Option<&[Vector3<f64>]> {
        match &self.global {
            GlobalPhase::Free(s) => s.impulses(),
            GlobalPhase::Reduced(r) => r.direct.impulses(),
        }
    }

    fn contact_impulses(&self) -> Option<&[Vector3<f64>]> {
        match &self.global {
            GlobalPhase::Free(s) => s.contact_impulses(),
            GlobalPhase::Reduced(r) => r.direct.contact_impulses(),
        }
    }
}

/// The local step (Eq. 3) at the current iterate and the gather of `J p`; with Anderson
/// acceleration, an accelerated iterate that raises the step's objective is replaced by the
/// plain one (and the history forgotten).
pub(crate) fn local_phase(
    cx: &mut StepContext<'_>,
    anderson: Option<&mut Anderson>,
    stats: &mut StepStats,
    observer: &mut dyn StepObserver,
    energy_prev: &mut f64,
    accelerated: bool,
) -> Result<(), SolverError> {
    let model = cx.model;
    let record = observer.decompositions(model.tets.len(), false);
    stats.elastic_energy = cx.constraints.project(model, &cx.work.full, cx.activations, record)?;
    if let Some(aa) = anderson {
        let w = &mut *cx.work;
        let sk = cx.skeleton.as_deref();
        let ih2 = cx.scheme.inv_h2();
        let mut e = step_objective(
            model,
            &w.full,
            &w.s,
            ih2,
            stats.elastic_energy,
            sk,
            &w.coords0,
            &w.torque,
        );
        if accelerated && e > *energy_prev + 1e-12 * energy_prev.abs() {
            w.x.copy_from_slice(aa.last_plain());
            for (k, &v) in cx.system.free.iter().enumerate() {
                w.full[v] = w.x[k];
            }
            let record = observer.decompositions(model.tets.len(), true);
            stats.elastic_energy = cx.constraints.project(model, &w.full, cx.activations, record)?;
            e = step_objective(
                model,
                &w.full,
                &w.s,
                ih2,
                stats.elastic_energy,
                sk,
                &w.coords0,
                &w.torque,
            );
            aa.reset();
            stats.anderson_rejections += 1;
        }
        *energy_prev = e;
    }
    cx.constraints.gather(model, &mut cx.work.gathered);
    Ok(())
}

/// The global step (Eq. 5) from the gathered local step, with the step's contacts; with a
/// skeleton the reduced step (Eqs. 17-18), which also moves the bone vertices.
pub(crate) fn global_phase(
    cx: &mut StepContext<'_>,
    global: PhaseRef<'_>,
    observer: &mut dyn StepObserver,
) -> Result<GlobalStats, SolverError> {
    let (model, sys, w, contacts) = (cx.model, cx.system, &mut *cx.work, cx.contacts);
    for (k, &v) in sys.free.iter().enumerate() {
        w.rhs[k] = w.base[k] + w.gathered[v];
    }
    w.x_prev.copy_from_slice(&w.x);
    let ih2 = cx.scheme.inv_h2();
    let time = cx.time;
    let control = InnerControl {
        tolerance: cx.settings.inner_absolute_tolerance(model),
        max_iterations: cx.settings.inner_max_iterations,
    };
    let constraints = &*cx.constraints;
    match global {
        PhaseRef::Free(solver) => {
            let direct = solver.kind() == SolverKind::Direct && !solver.parallel_inside();
            let mut solve = || solver.solve(sys, &w.rhs, &mut w.x, &contacts.free);
            // A direct solve has no parallel section inside: keep the workers warm for the
            // next local step meanwhile (see `warm`).
            let g = if direct { warm::keep_warm(solve)? } else { solve()? };
            observer.solved(SolveInfo {
                contacts: &contacts.free,
                impulses: solver.impulses(),
                skeletal: None,
            });
            Ok(g)
        }
        PhaseRef::Reduced(ReducedStep { direct, reduced }) => {
            let sk = cx.skeleton.as_deref_mut().expect("a reduced step has a skeleton");
            let parallel = direct.parallel_inside();
            let g = warm::keep_warm_unless(parallel, || -> Result<_, SolverError> {
                for (r, &v) in sys.rigid.iter().enumerate() {
                    w.b_rigid[r] = w.s[v] * (model.mass[v] * ih2) + w.gathered[v] + sys.coupling_rigid[r];
                }
                constraints.constant_rhs(model, &mut |v, b| {
                    let r = sys.rigid_index[v];
                    if r != usize::MAX {
                        w.b_rigid[r] += b;
                    }
                });
                let g = reduced.solve(
                    sys,
                    direct,
                    sk,
                    &w.rhs,
                    &w.b_rigid,
                    time,
                    &mut w.x,
                    &mut w.q_rigid,
                    &contacts.free,
                    &contacts.rigid,
                    control,
                )?;
                for (r, &v) in sys.rigid.iter().enumerate() {
                    w.full[v] = w.q_rigid[r];
                }
                Ok(g)
            })?;
            observer.solved(SolveInfo {
                contacts: &contacts.free,
                impulses: direct.impulses(),
                skeletal: Some((&**reduced, &contacts.rigid)),
            });
            Ok(g)
        }
    }
}
