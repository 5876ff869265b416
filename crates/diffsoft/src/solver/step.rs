//! One step of projective dynamics (docs/method.md section 2; implicit Euler or BDF2, Eqs.
//! T1-T3, which differ only in the explicit phases 1 and 4), as named phases:
//!
//! 1. [`Simulator::begin_step`]: the inertial target `s_n` (Eq. 2 / T1), the right-hand side's
//!    constant part, the step's activations and torques, the first iterate `x_0 = s_n`;
//! 2. the contact phase ([`StepContacts`](super::contacts::StepContacts)): candidates before the
//!    iterations, new penetrations after each round (Eqs. C2-C3);
//! 3. the run's [`StepIteration`](super::iteration::StepIteration) for one contact set:
//!    local-global iterations (Eqs. 3, 5, or the skeleton's reduced step, Eqs. 17-18) or
//!    Newton's method (Eqs. S3-S9), handed the run's state;
//! 4. [`Simulator::finish`]: the velocity update (Eq. 4 / T3), energies and divergence checks.
//!
//! A [`StepObserver`] watches every phase (the backward pass records through one).

use std::time::Instant;

use super::iteration::StepContext;
use super::observer::{NoObserver, StepObserver};
use super::problem::constant_rhs;
use super::simulator::Simulator;
use super::{SolverError, StepStats};
use crate::contact;
use crate::skeleton::Skeleton;

impl Simulator {
    /// Advance one time step.
    pub fn step(&mut self) -> Result<StepStats, SolverError> {
        self.step_observed(&mut NoObserver)
    }

    /// Advance one time step with `observer` watching its phases.
    pub(crate) fn step_observed(&mut self, observer: &mut dyn StepObserver) -> Result<StepStats, SolverError> {
        if crate::base::cancel::requested() {
            return Err(SolverError::Interrupted);
        }
        let t0 = Instant::now();
        self.prepare_scheme()?;
        self.begin_step();
        let margin = self.settings.absolute_contact_margin(&self.model);
        self.contacts
            .candidates(&self.model, &self.system, &self.work.q_start, &self.work.s, margin);
        observer.begin();
        let mut stats = StepStats::new(self.state.step + 1, self.state.time + self.integrator.h());
        let rounds = self.settings.contact_rounds.max(1);
        for round in 0..rounds.max(self.settings.crossing_rounds) {
            stats.contact_rounds = round + 1;
            stats.converged = false;
            observer.contact_set(&self.contacts.free);
            self.iterate(&mut stats, observer)?;
            if crate::base::cancel::requested() {
                return Err(SolverError::Interrupted);
            }
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
            // Past the ordinary rounds, only while the surfaces of two bodies cross.
            if round + 1 >= rounds && self.contacts.crossings_at(&self.model, &self.work.full) == 0 {
                break;
            }
        }
        stats.contacts = self.contacts.obstacle.len();
        stats.pair_contacts = self.contacts.pairs.len();
        stats.swept_pairs = self.contacts.pairs.iter().filter(|p| p.swept).count();
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
        constant_rhs(model, sys, &self.constraints, &w.s, ih2, &mut w.base);
        for (k, &v) in sys.free.iter().enumerate() {
            w.x[k] = w.s[v];
        }
        w.full.copy_from_slice(&w.s);
        // Bone vertices start where the skeleton is.
        for &v in &sys.rigid {
            w.full[v] = st.q[v];
        }
        self.iteration.begin_step();
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

    /// Phase 3: the run's iteration (local-global or Newton) for the current contact set, with
    /// the run's state lent to it.
    fn iterate(&mut self, stats: &mut StepStats, observer: &mut dyn StepObserver) -> Result<(), SolverError> {
        let mut cx = StepContext {
            model: &self.model,
            settings: &self.settings,
            scheme: &self.integrator,
            system: &self.system,
            constraints: &mut self.constraints,
            activations: &self.activations,
            contacts: &self.contacts,
            work: &mut self.work,
            skeleton: self.skeleton.as_mut(),
            time: self.state.time + self.integrator.h(),
        };
        self.iteration.iterate(&mut cx, stats, observer)
    }

    /// Phase 4: positions and velocities (Eq. 4), energies, penetration, divergence checks.
    fn finish(&mut self, stats: &mut StepStats, t0: Instant) -> Result<(), SolverError> {
        self.scatter_iterate();
        stats.pair_crossings = self.contacts.crossings_at(&self.model, &self.work.full);
        stats.inverted_tets = crate::fem::inverted_tets(&self.model.tets, &self.work.full);
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
            // A step so short that the positions' round-off alone, over one step, is a velocity
            // with that much energy: the time step, not the dynamics, is what failed.
            let h = self.integrator.h();
            let v_roundoff = f64::EPSILON * model.length_scale() / h;
            let mass: f64 = model.mass.iter().sum();
            let cause = if 0.5 * mass * v_roundoff * v_roundoff > 1e8 * self.energy_scale {
                format!(
                    "; the time step {} s is below what double precision resolves for this scene (a position's round-off over one step is a velocity of {v_roundoff:.1e} m/s)",
                    crate::base::number(h)
                )
            } else {
                String::new()
            };
            return Err(SolverError::Diverged(format!(
                "step {}: kinetic energy {kinetic:.3e} J exceeds 1e8 x the scene's energy scale {:.3e} J{cause}",
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
