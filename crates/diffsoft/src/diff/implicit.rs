//! Implicit mode (docs/method.md section 7, Eq. G4): the converged step differentiated by the
//! implicit function theorem at the stored next state, `(A - K) r = x_bar` with `K` the local
//! step's linearization (symmetric). Without contacts it is solved by conjugate gradients
//! preconditioned with the prefactored `A` (DiffPD's approach); with contacts, or where `A - K`
//! is not positive definite along a search direction, by the fixed point
//! `r = A^-T (x_bar + K r)` with the contact correction, accelerated by Anderson mixing. Exact
//! where the forward converged.

use nalgebra::Vector3;

use super::backward::{Backward, StepInputs};
use super::{DiffError, Gradient};
use crate::constraint::{Linearize, ParamGrads};
use crate::model::Model;
use crate::solver::anderson::Anderson;

/// An implicit adjoint's fixed point that ends with a relative change above this has diverged.
const DIVERGED_CHANGE: f64 = 0.1;

/// A residual this many times the best so far restarts the mixing.
const RESTART_GROWTH: f64 = 100.0;

/// Refuse the result of an implicit adjoint fixed point that diverged (the linearized step is
/// not contractive there, e.g. far from convergence or where the contact set is switching).
pub(crate) fn fixed_point_converged(residual: f64, iterations: usize, step: usize) -> Result<(), DiffError> {
    if residual.is_finite() && residual <= DIVERGED_CHANGE {
        return Ok(());
    }
    Err(DiffError::NotDifferentiable(format!(
        "step {}: the implicit adjoint's fixed point diverged (relative change {residual:.1e} after {iterations} iterations); the linearized step is not contractive here (forward far from converged?): use unrolled mode",
        step + 1
    )))
}

/// The work vectors' slots in [`Backward::implicit`] (conjugate gradients' `r, z, p, Hp, Ap`
/// follow `CG_X`, then the adjoint of the step two after this one).
const X_STAR: usize = 0;
const XBAR0: usize = 1;
const PREV: usize = 2;
const CG_X: usize = 3;

fn dot(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x.dot(y)).sum::<f64>()
}

impl Backward<'_> {
    /// Implicit mode's adjoint of one converged step (see the module docs).
    pub(super) fn implicit(
        &mut self,
        inp: &StepInputs<'_>,
        qbar: &mut [Vector3<f64>],
        s_bar: &mut [Vector3<f64>],
        g: &mut Gradient,
    ) -> Result<(), DiffError> {
        let model = self.model;
        let ih2 = self.integrator.inv_h2();
        let (q_next, activations, step) = (inp.q_next, inp.activations, inp.step);
        let (contacts, impulses) = inp.final_contacts.unwrap_or((&[], &[]));
        let mut w = std::mem::take(&mut self.implicit);
        for (k, &v) in self.sys.free.iter().enumerate() {
            w[X_STAR][k] = q_next[v];
        }
        self.local.linearize(model, q_next)?;
        self.xn_full.copy_from_slice(q_next);
        w[XBAR0].copy_from_slice(&self.xbar);
        // Without contacts (A - K) r = x_bar is symmetric: conjugate gradients preconditioned by
        // the factored A. Falls back to the fixed point below if the step's Hessian A - K is
        // not positive definite along a search direction.
        let mut done = false;
        if contacts.is_empty() {
            let cg = self.implicit_cg(model, q_next, activations, &mut w);
            self.implicit_warm = matches!(cg, Ok(Some(_)));
            match cg {
                Ok(Some((iters, res))) => {
                    self.z.copy_from_slice(&w[CG_X]);
                    g.stats.backward_iterations += iters;
                    g.stats.implicit_residual = g.stats.implicit_residual.max(res);
                    self.anchor_scratch.iter_mut().for_each(|a| *a = Vector3::zeros());
                    done = true;
                }
                Ok(None) => {}
                Err(e) => {
                    self.implicit = w;
                    return Err(e);
                }
            }
        }
        let r = if done {
            Ok(())
        } else {
            self.implicit_fixed_point(inp, contacts, impulses, &mut w, g, step)
        };
        let x_star = std::mem::take(&mut w[X_STAR]);
        self.implicit = w;
        r?;
        for (q, a) in qbar.iter_mut().zip(&self.anchor_scratch) {
            *q += a;
        }
        // Parameter adjoints at the fixed point.
        self.accumulate_solve(&x_star, g);
        self.implicit[X_STAR] = x_star;
        Self::scatter(&self.sys, model, &self.z, &mut self.y_full, true);
        self.local.adjoint(
            model,
            q_next,
            &self.y_full,
            Some(&self.xn_full),
            activations,
            Linearize::Cached,
            &mut self.out_full,
            ParamGrads {
                w_rot: &mut g.w_rot,
                w_vol: &mut g.w_vol,
                activations: &mut self.act_grad,
            },
        )?;
        for (k, &v) in self.sys.free.iter().enumerate() {
            s_bar[v] += self.base_acc[k] * (model.mass[v] * ih2);
        }
        Ok(())
    }

    /// `r = A^-T (x_bar + K r)` from `r = A^-T x_bar`, with the contact correction, to the
    /// implicit tolerance or the iteration cap.
    #[allow(clippy::too_many_arguments)]
    fn implicit_fixed_point(
        &mut self,
        inp: &StepInputs<'_>,
        contacts: &[crate::solver::free_contact::FreeContact],
        impulses: &[Vector3<f64>],
        w: &mut [Vec<Vector3<f64>>; 10],
        g: &mut Gradient,
        step: usize,
    ) -> Result<(), DiffError> {
        let model = self.model;
        // The iterate `u` (in `w[PREV]`) whose right-hand side `x_bar0 + K u` the solve sees;
        // the solve returns `G(u)` in `z`. The map is linear, so Anderson's mixing of the last
        // iterates (type II, a restarted GMRES in effect) converges in far fewer solves than the
        // plain iteration, whose rate is the forward's own.
        // Warm start from the adjoint of the step after this one, as conjugate gradients do.
        if self.implicit_warm {
            let [_, _, prev, cg_x, ..] = &mut *w;
            prev.copy_from_slice(cg_x);
            self.apply_k(model, inp.q_next, inp.activations, &w[PREV])?;
            for (k, &v) in self.sys.free.iter().enumerate() {
                self.xbar[k] = w[XBAR0][k] + self.out_full[v];
            }
        } else {
            w[PREV].iter_mut().for_each(|p| *p = Vector3::zeros());
        }
        let mut accel = std::mem::replace(&mut self.accel, Anderson::new(0, 0));
        accel.reset();
        let mut it = 0;
        let mut best = f64::INFINITY;
        let result = loop {
            self.anchor_scratch.iter_mut().for_each(|a| *a = Vector3::zeros());
            let mut anchors = std::mem::take(&mut self.anchor_scratch);
            // The step's contact system is the same every iteration: built on the first.
            let r = self.solve_adjoint(
                contacts,
                impulses,
                &w[X_STAR],
                None,
                &mut anchors,
                inp.q_n,
                it > 0,
                None,
            );
            self.anchor_scratch = anchors;
            if let Err(e) = r {
                break Err(e);
            }
            it += 1;
            let (mut d, mut s) = (0.0f64, 0.0f64);
            for (a, b) in self.z.iter().zip(&w[PREV]) {
                d = d.max((a - b).amax());
                s = s.max(a.amax());
            }
            let residual = if s > 0.0 { d / s } else { 0.0 };
            if residual <= self.implicit_tol || it >= self.opts.implicit_max_iterations {
                g.stats.backward_iterations += it;
                g.stats.implicit_residual = g.stats.implicit_residual.max(residual);
                break fixed_point_converged(residual, it, step);
            }
            // A mixed iterate that made the residual much worse: forget the history (the
            // next update is the plain one).
            if residual > RESTART_GROWTH * best {
                accel.reset();
            }
            best = best.min(residual);
            let [_, _, prev, _, mixed, ..] = &mut *w;
            if self.opts.implicit_anderson > 0 {
                accel.mix(prev, &self.z, mixed);
                prev.copy_from_slice(mixed);
            } else {
                prev.copy_from_slice(&self.z);
            }
            let r = self.apply_k(model, inp.q_next, inp.activations, &w[PREV]);
            if let Err(e) = r {
                break Err(e);
            }
            for (k, &v) in self.sys.free.iter().enumerate() {
                self.xbar[k] = w[XBAR0][k] + self.out_full[v];
            }
        };
        self.accel = accel;
        // The next (earlier) step's solve, either kind, starts from this adjoint alone.
        self.implicit_warm = result.is_ok();
        self.implicit_older = false;
        if self.implicit_warm {
            w[CG_X].copy_from_slice(&self.z);
        }
        result
    }

    /// `out_full = K y` (all vertices) for free-numbered `y`, with the linearization cached at
    /// `q_next`; the parameter adjoints it also produces are discarded.
    fn apply_k(
        &mut self,
        model: &Model,
        q_next: &[Vector3<f64>],
        activations: &[f64],
        y: &[Vector3<f64>],
    ) -> Result<(), DiffError> {
        Self::scatter(&self.sys, model, y, &mut self.y_full, true);
        self.scratch_act.iter_mut().for_each(|a| *a = 0.0);
        // No x_next: the parameter adjoints are discarded here, and its term costs a gather.
        self.local.adjoint(
            model,
            q_next,
            &self.y_full,
            None,
            activations,
            Linearize::Cached,
            &mut self.out_full,
            ParamGrads {
                w_rot: &mut self.scratch_rot,
                w_vol: &mut self.scratch_vol,
                activations: &mut self.scratch_act,
            },
        )?;
        Ok(())
    }

    /// `(A - K) r = x_bar0` by conjugate gradients preconditioned with `A^-1` (`K` the cached
    /// local linearization), into `w[CG_X]`: the iterations and final relative residual, or
    /// `None` if a direction of non-positive curvature appears (the caller then iterates the
    /// fixed point).
    fn implicit_cg(
        &mut self,
        model: &Model,
        q_next: &[Vector3<f64>],
        activations: &[f64],
        w: &mut [Vec<Vector3<f64>>; 10],
    ) -> Result<Option<(usize, f64)>, DiffError> {
        let nf = self.nf;
        let bnorm = dot(&w[XBAR0], &w[XBAR0]).sqrt();
        if bnorm == 0.0 {
            w[CG_X].iter_mut().for_each(|x| *x = Vector3::zeros());
            self.implicit_older = false;
            return Ok(Some((0, 0.0)));
        }
        let [_, b, _, x, r, z, p, hp, ap, older] = w;
        // Warm start from the adjoints of the steps after this one (the backward pass runs
        // backwards in time, and adjoints change smoothly from step to step): their linear
        // extrapolation where there are two, r = b - H x0.
        if self.implicit_warm {
            if self.implicit_older {
                for (xk, ok) in x.iter_mut().zip(older.iter_mut()) {
                    let last = *xk;
                    *xk = last * 2.0 - *ok;
                    *ok = last;
                }
            } else {
                older.copy_from_slice(x);
            }
            self.implicit_older = true;
            self.sys.apply(x, ap);
            self.apply_k(model, q_next, activations, x)?;
            for (k, &v) in self.sys.free.iter().enumerate() {
                r[k] = b[k] - (ap[k] - self.out_full[v]);
            }
            // A warm start worse than zero is dropped.
            if dot(r, r) >= bnorm * bnorm {
                x.iter_mut().for_each(|v| *v = Vector3::zeros());
                r.copy_from_slice(b);
            }
        } else {
            self.implicit_older = false;
            x.iter_mut().for_each(|v| *v = Vector3::zeros());
            r.copy_from_slice(b);
        }
        let mut res = dot(r, r).sqrt() / bnorm;
        if res <= self.implicit_tol {
            return Ok(Some((0, res)));
        }
        self.direct.solve_free(r, z)?;
        p.copy_from_slice(z);
        let mut rz = dot(r, z);
        let mut it = 0;
        while it < self.opts.implicit_max_iterations {
            it += 1;
            // hp = A p - K p.
            self.sys.apply(p, ap);
            self.apply_k(model, q_next, activations, p)?;
            for (k, &v) in self.sys.free.iter().enumerate() {
                hp[k] = ap[k] - self.out_full[v];
            }
            let php = dot(p, hp);
            if php.is_nan() || php <= 0.0 {
                return Ok(None);
            }
            let alpha = rz / php;
            for k in 0..nf {
                x[k] += p[k] * alpha;
                r[k] -= hp[k] * alpha;
            }
            res = dot(r, r).sqrt() / bnorm;
            if res <= self.implicit_tol {
                break;
            }
            self.direct.solve_free(r, z)?;
            let rz_new = dot(r, z);
            let beta = rz_new / rz;
            rz = rz_new;
            for k in 0..nf {
                p[k] = z[k] + p[k] * beta;
            }
        }
        Ok(Some((it, res)))
    }
}
