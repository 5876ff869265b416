//! One step of projective dynamics (docs/method.md section 2; implicit Euler or BDF2, Eqs.
//! T1-T3, which differ only in the explicit phases 1 and 4), as named phases:
//!
//! 1. [`Simulator::begin_step`]: the inertial target `s_n` (Eq. 2 / T1), the right-hand side's
//!    constant part, the step's activations and torques, the first iterate `x_0 = s_n`;
//! 2. the contact phase ([`StepContacts`](super::contacts::StepContacts)): candidates before the
//!    iterations, new penetrations after each round (Eqs. C2-C3);
//! 3. [`Simulator::iterate`]: local-global iterations for one contact set, each a local step
//!    ([`Simulator::local_phase`], Eq. 3, with Anderson's safeguard) and a global step
//!    ([`Simulator::global_phase`], Eq. 5, or the skeleton's reduced step, Eqs. 17-18);
//! 4. [`Simulator::finish`]: the velocity update (Eq. 4 / T3), energies and divergence checks.
//!
//! A [`StepObserver`] watches every phase (the backward pass records through one).

use std::time::Instant;

use nalgebra::Vector3;

use super::global::{GlobalSolver, InnerControl};
use super::observer::{NoObserver, SolveInfo, StepObserver};
use super::simulator::{GlobalStep, Simulator};
use super::{warm, SolverError, StepStats};
use crate::contact;
use crate::model::Model;
use crate::skeleton::Skeleton;

impl Simulator {
    /// Advance one time step.
    pub fn step(&mut self) -> Result<StepStats, SolverError> {
        self.step_observed(&mut NoObserver)
    }

    /// Advance one time step with `observer` watching its phases.
    pub(crate) fn step_observed(&mut self, observer: &mut dyn StepObserver) -> Result<StepStats, SolverError> {
        let t0 = Instant::now();
        self.prepare_scheme()?;
        self.begin_step();
        let margin = self.settings.contact_margin * self.model.length_scale;
        self.contacts
            .candidates(&self.model, &self.system, &self.work.q_start, &self.work.s, margin);
        observer.begin();
        let mut stats = StepStats::new(self.state.step + 1, self.state.time + self.integrator.h());
        for round in 0..self.settings.contact_rounds.max(1) {
            stats.contact_rounds = round + 1;
            stats.converged = false;
            observer.contact_set(&self.contacts.free);
            self.iterate(&mut stats, observer)?;
            if self.model.obstacles.is_empty() && self.model.collision.is_none() {
                break;
            }
            // New penetrations: add them as contacts and resume.
            self.scatter_iterate();
            let w = &self.work;
            if !self
                .contacts
                .add_violations(&self.model, &self.system, &w.q_start, &w.full)
            {
                break;
            }
        }
        stats.contacts = self.contacts.obstacle.len();
        stats.pair_contacts = self.contacts.pairs.len();
        stats.bone_contacts = self.contacts.rigid.len();
        observer.end(&self.work.x, self.skeleton.as_ref());
        self.finish(&mut stats, t0)?;
        Ok(stats)
    }

    /// Phase 1: the inertial target (Eq. 2), the constant part of the right-hand side
    /// `M s_n / h^2 + fixed pull + attachments`, the first iterate, the step's activations (at
    /// the end of the step, implicit Euler) and the joint torques.
    fn begin_step(&mut self) {
        let (model, sys, w, st) = (&self.model, &self.system, &mut self.work, &self.state);
        let ih2 = self.integrator.inv_h2();
        w.q_start.copy_from_slice(&st.q);
        let previous = self
            .previous
            .valid
            .then_some((&self.previous.q[..], &self.previous.v[..]));
        self.integrator.inertial_target(model, &st.q, &st.v, previous, &mut w.s);
        for (k, &v) in sys.free.iter().enumerate() {
            w.base[k] = w.s[v] * (model.mass[v] * ih2) + sys.coupling[k];
            w.x[k] = w.s[v];
        }
        self.constraints.constant_rhs(model, &mut |v, b| {
            let k = sys.index[v];
            if k != usize::MAX {
                w.base[k] += b;
            }
        });
        w.full.copy_from_slice(&w.s);
        if let GlobalStep::Skeletal { reduced, .. } = &mut self.global {
            // Bone vertices start where the skeleton is.
            for &v in &sys.rigid {
                w.full[v] = st.q[v];
            }
            reduced.reset_impulses();
        }
        let t_end = st.time + self.integrator.h();
        if let Some(act) = model.actuators.as_ref() {
            for (g, group) in act.groups.iter().enumerate() {
                self.activations[g] = self.activation_override[g].unwrap_or_else(|| group.activation.at(t_end));
            }
        }
        // Joint coordinates at the start of the step, for the torques' potential.
        if let Some(sk) = &self.skeleton {
            joint_scalars(sk, &mut w.coords0);
            sk.torques(t_end, &mut w.torque);
        }
    }

    /// Phase 3: local-global iterations for the current contact set, until the RMS change of the
    /// free positions is below `tolerance x length scale` or the iteration cap.
    fn iterate(&mut self, stats: &mut StepStats, observer: &mut dyn StepObserver) -> Result<(), SolverError> {
        if self.global.kind() == super::SolverKind::Newton {
            if self.skeleton.is_some() {
                return self.newton_skeletal_iterate(stats, observer);
            }
            return self.newton_iterate(stats, observer);
        }
        if let Some(aa) = self.anderson.as_mut() {
            aa.reset();
        }
        let tol = self.settings.tolerance * self.model.length_scale;
        let nf = self.system.n();
        let rms = (nf.max(1) as f64).sqrt();
        let mut energy_prev = f64::INFINITY;
        let mut accelerated = false;
        for _ in 0..self.settings.max_iterations {
            observer.iterate(&self.work.x, self.skeleton.as_ref());
            self.scatter_iterate();
            let tl = Instant::now();
            self.local_phase(stats, observer, &mut energy_prev, accelerated)?;
            stats.local_ms += tl.elapsed().as_secs_f64() * 1e3;
            let tg = Instant::now();
            let g = self.global_phase(observer)?;
            stats.global_ms += tg.elapsed().as_secs_f64() * 1e3;
            stats.iterations += 1;
            stats.global_iterations += g.iterations;
            stats.contact_iterations += g.contact_iterations;
            if !g.converged {
                stats.capped_solves += 1;
            }
            let w = &mut self.work;
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
            stats.relative_change = change / self.model.length_scale;
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

    /// The local step (Eq. 3) at the current iterate and the gather of `J p`; with Anderson
    /// acceleration, an accelerated iterate that raises the step's objective is replaced by the
    /// plain one (and the history forgotten).
    pub(super) fn local_phase(
        &mut self,
        stats: &mut StepStats,
        observer: &mut dyn StepObserver,
        energy_prev: &mut f64,
        accelerated: bool,
    ) -> Result<(), SolverError> {
        let model = &self.model;
        let record = observer.decompositions(model.tets.len(), false);
        stats.elastic_energy = self
            .constraints
            .project(model, &self.work.full, &self.activations, record)?;
        if let Some(aa) = self.anderson.as_mut() {
            let w = &mut self.work;
            let sk = self.skeleton.as_ref();
            let ih2 = self.integrator.inv_h2();
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
                for (k, &v) in self.system.free.iter().enumerate() {
                    w.full[v] = w.x[k];
                }
                let record = observer.decompositions(model.tets.len(), true);
                stats.elastic_energy = self.constraints.project(model, &w.full, &self.activations, record)?;
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
        self.constraints.gather(model, &mut self.work.gathered);
        Ok(())
    }

    /// The global step (Eq. 5) from the gathered local step, with the step's contacts; with a
    /// skeleton the reduced step (Eqs. 17-18), which also moves the bone vertices.
    pub(super) fn global_phase(&mut self, observer: &mut dyn StepObserver) -> Result<super::GlobalStats, SolverError> {
        let (model, sys, w, contacts) = (&self.model, &self.system, &mut self.work, &self.contacts);
        for (k, &v) in sys.free.iter().enumerate() {
            w.rhs[k] = w.base[k] + w.gathered[v];
        }
        w.x_prev.copy_from_slice(&w.x);
        let ih2 = self.integrator.inv_h2();
        let time = self.state.time + self.integrator.h();
        let control = InnerControl {
            tolerance: self.settings.inner_tolerance * model.length_scale,
            max_iterations: self.settings.inner_max_iterations,
        };
        let (constraints, skeleton) = (&self.constraints, &mut self.skeleton);
        let g = match &mut self.global {
            GlobalStep::Free(solver) => {
                let direct = solver.kind() == super::SolverKind::Direct && !solver.parallel_inside();
                let mut solve = || solver.solve(sys, &w.rhs, &mut w.x, &contacts.free);
                // A direct solve has no parallel section inside: keep the workers warm for
                // the next local step meanwhile (see `warm`).
                if direct {
                    warm::keep_warm(solve)?
                } else {
                    solve()?
                }
            }
            GlobalStep::Skeletal { direct, reduced, .. } => {
                let sk = skeleton.as_mut().expect("a skeletal step has a skeleton");
                let parallel = direct.parallel_inside();
                warm::keep_warm_unless(parallel, || -> Result<_, SolverError> {
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
                })?
            }
        };
        observer.solved(SolveInfo {
            contacts: &contacts.free,
            impulses: self.global.impulses(),
            skeletal: match &self.global {
                GlobalStep::Skeletal { reduced, .. } => Some((&**reduced, &contacts.rigid)),
                GlobalStep::Free(_) => None,
            },
        });
        Ok(g)
    }

    /// Phase 4: positions and velocities (Eq. 4), energies, penetration, divergence checks.
    fn finish(&mut self, stats: &mut StepStats, t0: Instant) -> Result<(), SolverError> {
        self.scatter_iterate();
        let (model, w, st) = (&self.model, &self.work, &mut self.state);
        if !model.obstacles.is_empty() {
            stats.max_penetration = contact::max_penetration(&model.obstacles, &w.q_start, &w.full).0;
        }
        let mut kinetic = 0.0;
        let mut potential = 0.0;
        let prev = &mut self.previous;
        let keep = !prev.q.is_empty();
        for i in 0..model.n() {
            let q = w.full[i];
            // BDF2 reads q_{n-1}; implicit Euler ignores it (and keeps no history).
            let before = if keep { prev.q[i] } else { w.q_start[i] };
            let v = self.integrator.velocity(&w.q_start[i], &before, &q);
            if keep {
                prev.q[i] = st.q[i];
                prev.v[i] = st.v[i];
            }
            st.q[i] = q;
            st.v[i] = v;
            kinetic += 0.5 * model.mass[i] * v.norm_squared();
            potential -= model.mass[i] * model.accel[i].dot(&q);
        }
        if let Some(sk) = &self.skeleton {
            stats.bone_length_error = sk.bone_length_error(&st.q);
        }
        prev.valid = keep;
        st.time += self.integrator.h();
        st.step += 1;
        stats.kinetic_energy = kinetic;
        stats.potential_energy = potential;
        stats.wall_ms = t0.elapsed().as_secs_f64() * 1e3;
        if !(kinetic.is_finite() && stats.elastic_energy.is_finite()) {
            return Err(SolverError::NonFinite(format!(
                "step {}: energy is not finite",
                stats.step
            )));
        }
        if kinetic > 1e8 * self.energy_scale {
            return Err(SolverError::Diverged(format!(
                "step {}: kinetic energy {kinetic:.3e} J exceeds 1e8 x the scene's energy scale {:.3e} J",
                stats.step, self.energy_scale
            )));
        }
        Ok(())
    }

    /// Copy the free iterate into the full positions.
    pub(super) fn scatter_iterate(&mut self) {
        let w = &mut self.work;
        for (k, &v) in self.system.free.iter().enumerate() {
            w.full[v] = w.x[k];
        }
    }
}

/// The one-DoF joints' coordinates into `c` (indexed by DoF offset; other entries untouched).
fn joint_scalars(sk: &Skeleton, c: &mut [f64]) {
    for b in &sk.bones {
        if let Some(x) = b.joint.scalar() {
            c[b.dof_offset] = x;
        }
    }
}

/// The objective the local-global iteration of one step minimises:
/// `1/(2h^2) |q - s|_M^2 + E_constraints(q) + attachments - tau . (z - z_start)`.
#[allow(clippy::too_many_arguments)]
pub(super) fn step_objective(
    model: &Model,
    q: &[Vector3<f64>],
    s: &[Vector3<f64>],
    ih2: f64,
    elastic: f64,
    skeleton: Option<&Skeleton>,
    coords0: &[f64],
    torque: &[f64],
) -> f64 {
    let mut e = elastic;
    for ((qi, si), m) in q.iter().zip(s).zip(&model.mass) {
        e += 0.5 * ih2 * m * (qi - si).norm_squared();
    }
    for a in &model.attachments {
        e += a.energy(&q[a.vertex]);
    }
    if let Some(sk) = skeleton {
        for b in &sk.bones {
            let (Some(c), k) = (b.joint.scalar(), b.dof_offset) else {
                continue;
            };
            if torque[k] != 0.0 {
                // Angles wrap: take the difference on the circle.
                let mut d = c - coords0[k];
                if d > std::f64::consts::PI {
                    d -= 2.0 * std::f64::consts::PI;
                } else if d < -std::f64::consts::PI {
                    d += 2.0 * std::f64::consts::PI;
                }
                e -= torque[k] * d;
            }
        }
    }
    e
}
