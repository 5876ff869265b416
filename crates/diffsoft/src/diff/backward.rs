//! The backward pass's buffers and the adjoint of one step (docs/method.md section 7): the
//! velocity update (Eq. 4) and the inertial target (Eq. 2) through the integrator, and between
//! them either every recorded local-global iteration (unrolled mode, Eq. G1) or the converged
//! step (implicit mode, see `implicit.rs`), or with a skeleton the reduced step (`skeletal.rs`).

use std::sync::Arc;
use std::time::Instant;

use nalgebra::Vector3;

use super::contact::{self, ContactAdjoint, Reuse};
use super::recording::Recording;
use super::skeletal_state::SkeletalAdjoint;
use super::{DiffError, Gradient, Mode, Options};
use crate::constraint::{Constraints, Linearize, ParamGrads};
use crate::model::Model;
use crate::solver::anderson::Anderson;
use crate::solver::assembled::GlobalSystem;
use crate::solver::direct::Direct;
use crate::solver::free_contact::FreeContact;
use crate::solver::global::InnerControl;
use crate::solver::integrator::{Previous, Scheme};
use crate::solver::system::System;

/// The implicit adjoint's inner solves (its linearized contact systems) stop at this fraction of
/// its tolerance.
const INNER_FRACTION: f64 = 1e-2;

/// Buffers of the backward pass, sized once.
pub(crate) struct Backward<'a> {
    pub(super) model: &'a Model,
    pub(super) integrator: Scheme,
    pub(super) sys: Arc<System>,
    pub(super) direct: Direct,
    pub(super) local: Constraints,
    pub(super) contact: ContactAdjoint,
    /// The recorded contact set (of this step's recording) whose Delassus block `contact`
    /// holds; reset at every step.
    pub(super) contact_set: Option<usize>,
    /// Whether this step's contact systems may be solved densely ([`StepInputs::capped`]).
    pub(super) contact_dense: bool,
    pub(super) opts: Options,
    /// The implicit adjoint's tolerance ([`Options::implicit_tolerance_for`]).
    pub(super) implicit_tol: f64,
    /// Measure [`DiffStats::unrolled_leftover`](super::DiffStats::unrolled_leftover): unrolled
    /// mode on a forward stopped by its tolerance (at a fixed iteration count the unrolled
    /// gradient is the exact derivative of what ran, and nothing is left over).
    pub(super) measure_leftover: bool,
    pub(super) n: usize,
    pub(super) nf: usize,
    // adjoints in the free numbering
    pub(super) xbar: Vec<Vector3<f64>>,
    pub(super) z: Vec<Vector3<f64>>,
    pub(super) base_acc: Vec<Vector3<f64>>,
    // full numbering
    pub(super) y_full: Vec<Vector3<f64>>,
    pub(super) q_full: Vec<Vector3<f64>>,
    pub(super) xn_full: Vec<Vector3<f64>>,
    pub(super) out_full: Vec<Vector3<f64>>,
    pub(super) s: Vec<Vector3<f64>>,
    /// The adjoint of the step's inertial target `s` (Eq. 2 / T1), distributed to the states
    /// it was built from at the end of the step.
    pub(super) s_bar: Vec<Vector3<f64>>,
    pub(super) anchor_scratch: Vec<Vector3<f64>>,
    pub(super) scratch_rot: Vec<f64>,
    pub(super) scratch_vol: Vec<f64>,
    pub(super) scratch_act: Vec<f64>,
    /// Implicit mode: free-numbered work vectors (the converged positions, the right-hand
    /// side, the previous fixed-point iterate, and conjugate gradients' `x, r, z, p, Hp, Ap`).
    pub(super) implicit: [Vec<Vector3<f64>>; 10],
    /// Whether `implicit`'s conjugate-gradient slot holds the adjoint of the previous
    /// (later) step, the next solve's warm start.
    pub(super) implicit_warm: bool,
    /// Whether the implicit work vectors' last slot holds the adjoint of the step two after
    /// this one (conjugate gradients then start from the linear extrapolation of the two).
    pub(super) implicit_older: bool,
    /// Implicit mode: Anderson mixing of the adjoint fixed point (empty in unrolled mode).
    pub(super) accel: Anderson,
    /// The step's activation adjoints (swapped with the gradient's row).
    pub(super) act_grad: Vec<f64>,
    /// The skeleton's backward buffers (`None` without a skeleton).
    pub(super) skel: Option<SkeletalAdjoint>,
    /// Time in contact adjoints (ms).
    pub(super) contact_ms: f64,
}

/// One step's inputs to [`Backward::step`].
pub(crate) struct StepInputs<'r> {
    /// State before the step.
    pub q_n: &'r [Vector3<f64>],
    /// Velocities before the step.
    pub v_n: &'r [Vector3<f64>],
    /// Positions after the step.
    pub q_next: &'r [Vector3<f64>],
    /// The step's activations.
    pub activations: &'r [f64],
    /// The step's recording (unrolled mode and skeletons).
    pub replay: Option<&'r Recording>,
    /// The step's final contacts and impulses (implicit mode).
    pub final_contacts: Option<(&'r [FreeContact], &'r [Vector3<f64>])>,
    /// The state before `(q_n, v_n)`, which a two-step scheme (BDF2) reads.
    pub previous: Previous<'r>,
    /// Step index.
    pub step: usize,
    /// Whether the forward step stopped a global or contact solve unconverged (capped or
    /// stalled; gradients only with `allow_unconverged`): its linearized contact systems are
    /// then solved by Gauss-Seidel, whose truncation follows the forward's own, rather than
    /// exactly at a fixed point the forward did not reach.
    pub capped: bool,
}

impl<'a> Backward<'a> {
    /// The backward pass of steps of `scheme` (the time step and integrator of the steps it
    /// will differentiate) on `sys`, the forward pass's system of that scheme (its factor is
    /// shared, not recomputed), of a forward solved to `tolerance` (0: a fixed iteration
    /// count); every buffer is allocated here.
    pub(crate) fn new(
        model: &'a Model,
        scheme: Scheme,
        sys: Arc<System>,
        opts: Options,
        implicit_tol: f64,
        tolerance: f64,
    ) -> Result<Self, DiffError> {
        let direct = sys.direct(InnerControl {
            tolerance: 0.0,
            max_iterations: 1,
        })?;
        let (n, nf) = (model.n(), sys.n());
        let groups = model.actuators.as_ref().map_or(0, |a| a.groups.len());
        let mut b = Self {
            skel: None,
            contact_ms: 0.0,
            integrator: scheme,
            local: Constraints::new(model),
            contact: ContactAdjoint::with_length_scale(model.length_scale()),
            xbar: vec![Vector3::zeros(); nf],
            z: vec![Vector3::zeros(); nf],
            base_acc: vec![Vector3::zeros(); nf],
            y_full: vec![Vector3::zeros(); n],
            q_full: vec![Vector3::zeros(); n],
            xn_full: vec![Vector3::zeros(); n],
            out_full: vec![Vector3::zeros(); n],
            s: vec![Vector3::zeros(); n],
            s_bar: vec![Vector3::zeros(); n],
            anchor_scratch: vec![Vector3::zeros(); n],
            scratch_rot: vec![0.0; model.tets.len()],
            scratch_vol: vec![0.0; model.tets.len()],
            scratch_act: vec![0.0; groups],
            implicit: std::array::from_fn(|_| {
                if opts.mode == Mode::Implicit {
                    vec![Vector3::zeros(); nf]
                } else {
                    Vec::new()
                }
            }),
            implicit_warm: false,
            implicit_older: false,
            accel: Anderson::new(opts.implicit_anderson, if opts.mode == Mode::Implicit { nf } else { 0 }),
            act_grad: vec![0.0; groups],
            contact_set: None,
            contact_dense: true,
            model,
            sys,
            direct,
            opts,
            implicit_tol,
            measure_leftover: opts.mode == Mode::Unrolled && tolerance > 0.0,
            n,
            nf,
        };
        b.skel = SkeletalAdjoint::new(model, &b.sys, &b.direct);
        Ok(b)
    }

    /// Scatter free values into a full vector whose other entries are the rest positions or
    /// zero (`zero_fixed`).
    pub(super) fn scatter(
        sys: &GlobalSystem,
        model: &Model,
        free: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
        zero_fixed: bool,
    ) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = if zero_fixed { Vector3::zeros() } else { model.rest[i] };
        }
        for (k, &v) in sys.free.iter().enumerate() {
            out[v] = free[k];
        }
    }

    /// `z = A^-T x_bar` with the contact correction (`impulse_bar`: a direct adjoint of the
    /// impulses); anchors' adjoints into `anchor_bar`. `reuse`: the linearized contact system
    /// is the previous call's ([`Reuse::Everything`]); otherwise `set`, the contacts' set in
    /// this step's recording, keeps the Delassus block when the previous call had the same.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn solve_adjoint(
        &mut self,
        contacts: &[FreeContact],
        impulses: &[Vector3<f64>],
        x: &[Vector3<f64>],
        impulse_bar: Option<&[Vector3<f64>]>,
        anchor_bar: &mut [Vector3<f64>],
        q_start: &[Vector3<f64>],
        reuse: bool,
        set: Option<usize>,
    ) -> Result<(), DiffError> {
        self.direct.solve_free(&self.xbar, &mut self.z)?;
        if contacts.is_empty() {
            return Ok(());
        }
        let reuse = if reuse {
            Reuse::Everything
        } else if set.is_some() && set == self.contact_set {
            Reuse::Delassus
        } else {
            Reuse::Nothing
        };
        self.contact_set = set;
        let t = Instant::now();
        let pairs = self.model.collision.as_ref().map(|c| contact::PairInputs {
            q_start,
            free_index: &self.sys.index,
            thickness: c.settings.thickness,
        });
        let r = self.contact.apply(
            &mut self.direct,
            contacts,
            impulses,
            impulse_bar,
            x,
            &mut self.z,
            anchor_bar,
            pairs,
            // Inside an implicit adjoint's fixed point the contact system needs only to be
            // solved well below the fixed point's own tolerance.
            if self.opts.mode == Mode::Implicit {
                self.opts.contact_tolerance.max(INNER_FRACTION * self.implicit_tol)
            } else {
                self.opts.contact_tolerance
            },
            self.opts.contact_max_sweeps,
            reuse,
            self.contact_dense,
        );
        self.contact_ms += t.elapsed().as_secs_f64() * 1e3;
        r
    }

    /// One step's adjoint: `qbar`, `vbar` hold the adjoints of `(q_{n+1}, v_{n+1})` on entry and
    /// this step's part of those of `(q_n, v_n)` on exit; `before_bar` receives its part of
    /// those of `(q_{n-1}, v_{n-1})` (zero unless the scheme has two steps); parameter adjoints
    /// are added to `g`.
    pub(crate) fn step(
        &mut self,
        inp: StepInputs<'_>,
        qbar: &mut [Vector3<f64>],
        vbar: &mut [Vector3<f64>],
        before_bar: (&mut [Vector3<f64>], &mut [Vector3<f64>]),
        g: &mut Gradient,
    ) -> Result<(), DiffError> {
        let model = self.model;
        let ih2 = self.integrator.inv_h2();
        let c = self.integrator.velocity_coefficient();
        let (a0, a1) = self.integrator.weights();
        let two_step = self.integrator.two_step();
        if two_step && inp.previous.is_none() {
            return Err(DiffError::Unsupported(format!(
                "step {}: the BDF2 adjoint needs the state before the step",
                inp.step + 1
            )));
        }
        self.integrator
            .inertial_target(model, inp.q_n, inp.v_n, inp.previous, &mut self.s);
        for (k, &v) in self.sys.free.iter().enumerate() {
            self.xbar[k] = qbar[v] + vbar[v] * c;
            self.base_acc[k] = Vector3::zeros();
        }
        let entering = if self.measure_leftover { norm(&self.xbar) } else { 0.0 };
        if let Some(sa) = self.skel.as_mut() {
            // Bone vertices after the step sit at q_R(z_{n+1}).
            for (r, &v) in self.sys.rigid.iter().enumerate() {
                sa.q_r_bar_in[r] = qbar[v] + vbar[v] * c;
            }
        }
        // q_{n+1} = x_N on free vertices; v_{n+1} = c (q_{n+1} - a0 q_n - a1 q_{n-1})
        // everywhere (Eq. 4 / T3).
        let (qb_before, vb_before) = before_bar;
        for i in 0..self.n {
            qbar[i] = -vbar[i] * (c * a0);
            qb_before[i] = -vbar[i] * (c * a1);
            vbar[i] = Vector3::zeros();
            vb_before[i] = Vector3::zeros();
            self.s_bar[i] = Vector3::zeros();
        }
        let step = inp.step;
        self.contact.near_kinks = 0;
        self.contact_set = None;
        self.contact_dense = !inp.capped;
        let mut s_bar = std::mem::take(&mut self.s_bar);
        std::mem::swap(&mut self.act_grad, &mut g.activations[step]);
        let r = match (self.opts.mode, inp.replay) {
            (mode, Some(rec)) if self.skel.is_some() => {
                let implicit = mode == Mode::Implicit;
                let mut act_grad = std::mem::take(&mut self.act_grad);
                let r = self.skeletal_step(
                    inp.q_n,
                    rec,
                    inp.activations,
                    qbar,
                    &mut s_bar,
                    g,
                    step,
                    &mut act_grad,
                    implicit,
                );
                self.act_grad = act_grad;
                r
            }
            (Mode::Unrolled, Some(rec)) => self.unrolled(rec, inp.q_n, inp.activations, qbar, &mut s_bar, g),
            (Mode::Implicit, _) => self.implicit(&inp, qbar, &mut s_bar, g),
            (Mode::Unrolled, None) => Err(DiffError::Unsupported("unrolled mode needs a replay".into())),
        };
        std::mem::swap(&mut self.act_grad, &mut g.activations[step]);
        self.s_bar = s_bar;
        r?;
        if entering > 0.0 {
            // What of the step's adjoint reached its starting guess `x_0 = s` (and, with a
            // skeleton, the joint state it started from): the share of the converged step's
            // derivative that the iterations run did not carry.
            let left = norm(&self.xbar) / entering;
            let joints = self.skel.as_ref().map_or(0.0, |sa| sa.joint_leftover);
            g.stats.unrolled_leftover = g.stats.unrolled_leftover.max(left).max(joints);
        }
        if self.contact.near_kinks > 0 {
            g.stats.nonsmooth_steps += 1;
        }
        // The inertial target's adjoint to the states it was built from (Eq. 2 / T1).
        for (i, sb) in self.s_bar.iter().enumerate() {
            if model.fixed[i] {
                continue;
            }
            let before = two_step.then(|| (&mut qb_before[i], &mut vb_before[i]));
            self.integrator
                .inertial_target_adjoint(*sb, (&mut qbar[i], &mut vbar[i]), before, &mut g.accel[i]);
        }
        // The constant part of the right-hand side: M s/h^2 and the attachments.
        for (k, &v) in self.sys.free.iter().enumerate() {
            g.mass[v] += self.base_acc[k].dot(&self.s[v]) * ih2;
        }
        let (index, base_acc) = (&self.sys.index, &self.base_acc);
        let adjoint = |v: usize| (index[v] != usize::MAX).then(|| base_acc[index[v]]);
        self.local
            .constant_rhs_adjoint(model, &adjoint, &mut g.attachment_targets);
        Ok(())
    }

    /// Unrolled mode: the adjoint of every recorded local-global iteration
    /// `x_{k+1} = A^-1 (M s/h^2 + b_fixed + J p(x_k))`, last first (Eq. G1).
    fn unrolled(
        &mut self,
        rec: &Recording,
        q_n: &[Vector3<f64>],
        activations: &[f64],
        qbar: &mut [Vector3<f64>],
        s_bar: &mut [Vector3<f64>],
        g: &mut Gradient,
    ) -> Result<(), DiffError> {
        let model = self.model;
        let ih2 = self.integrator.inv_h2();
        let iters = rec.solves();
        if rec.iterates.len() != iters + 1 {
            return Err(DiffError::Unsupported("the replay recorded no iterates".into()));
        }
        for k in (0..iters).rev() {
            let (contacts, impulses) = rec.solve(k);
            let x_next = &rec.iterates[k + 1];
            self.solve_adjoint(
                contacts,
                impulses,
                x_next,
                None,
                qbar,
                q_n,
                false,
                Some(rec.solve_set(k)),
            )?;
            self.accumulate_solve(x_next, g);
            Self::scatter(&self.sys, model, &rec.iterates[k], &mut self.q_full, false);
            Self::scatter(&self.sys, model, x_next, &mut self.xn_full, false);
            Self::scatter(&self.sys, model, &self.z, &mut self.y_full, true);
            self.local.adjoint(
                model,
                &self.q_full,
                &self.y_full,
                Some(&self.xn_full),
                activations,
                rec.svds.get(k).map_or(Linearize::Recompute, Linearize::Recorded),
                &mut self.out_full,
                ParamGrads {
                    w_rot: &mut g.w_rot,
                    w_vol: &mut g.w_vol,
                    activations: &mut self.act_grad,
                },
            )?;
            for (k2, &v) in self.sys.free.iter().enumerate() {
                self.xbar[k2] = self.out_full[v];
            }
            g.stats.backward_iterations += 1;
        }
        // x_0 = s.
        for (k, &v) in self.sys.free.iter().enumerate() {
            s_bar[v] += self.xbar[k] + self.base_acc[k] * (model.mass[v] * ih2);
        }
        Ok(())
    }

    /// After `z` became the adjoint of one solve's right-hand side (solution `x_next`):
    /// accumulate it and the masses' `A` term (Eq. G3).
    pub(super) fn accumulate_solve(&mut self, x_next: &[Vector3<f64>], g: &mut Gradient) {
        let ih2 = self.integrator.inv_h2();
        for (k, &v) in self.sys.free.iter().enumerate() {
            self.base_acc[k] += self.z[k];
            g.mass[v] -= self.z[k].dot(&x_next[k]) * ih2;
        }
        g.stats.contact_sweeps = self.contact.sweeps;
        g.stats.contact_residual = self.contact.worst_residual;
    }
}

/// The Euclidean norm of stacked vectors.
fn norm(x: &[Vector3<f64>]) -> f64 {
    x.iter().map(|v| v.norm_squared()).sum::<f64>().sqrt()
}
