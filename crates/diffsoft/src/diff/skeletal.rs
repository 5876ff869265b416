//! The backward pass of the reduced skeleton step (paper Eqs. 7-8, 17-18; see
//! [`crate::solver::skeletal`]).
//!
//! One local-global iteration with a skeleton maps the free positions `x_k` and the joint state
//! `z_k` (a point on the joints' manifold: rotation and translation of a free root, angles,
//! extensions) to `(x_{k+1}, z_{k+1})`:
//!
//! ```text
//! b = [b_F; b_R]            right-hand side: M s / h^2 + J p(q_k) + couplings, q_k = (x_k, q_R(z_k))
//! y0 = A_FF^-1 b_F,         g = b_R - A_RF y0,        r = g - Sigma q_R(z_k)
//! S = B^T Sigma B,          dz = S^-1 (B^T r + tau)   (with active joint limits: E^T dz = d(z_k))
//! z_{k+1} = U(z_k, dz)      (the joints' update rules, Eqs. 10, 35, 38)
//! x_{k+1} = y0 - W q_R(z_{k+1}),   W = A_FF^-1 A_FR
//! ```
//!
//! Its adjoint, with adjoints in the joints' tangent charts (so `d q_R / d z = B` itself):
//!
//! ```text
//! z_bar' = z_bar + B(z_{k+1})^T (-W^T x_bar),     y0_bar = x_bar
//! (z_bar, dz_bar) = U'(z_k, dz)^T z_bar'
//! [S E; E^T 0] [u; v] = [dz_bar; 0]                tau_bar += u,   beta = B u
//! B_bar = (r - Sigma B dz) u^T - (Sigma B u) dz^T  z_bar += (dB/dz) : B_bar + B^T (-Sigma beta) + (dd/dz) v
//! y0_bar -= A_FR beta,   b_F_bar = A_FF^-1 y0_bar, b_R_bar = beta
//! ```
//!
//! and then the local step's adjoint at `q_k` with `y = (b_F_bar, b_R_bar)`, whose bone-vertex
//! part flows into `z_bar` through `B(z_k)^T` (or into `q_n` for the step's first iteration,
//! which starts from the stored positions). The weights and masses enter through `A`: with
//! `alpha = (-W beta, beta)`, `gamma = (y0 - W c, c)`, `c = q_R(z_k) + B dz` (the linearized
//! solution), `y~ = A_FF^-1 x_bar = b_F_bar + W beta` and `q' = (x_{k+1}, q_R(z_{k+1}))`, the
//! matrix terms are `-alpha^T dA gamma - y~^T dA q'` (fixed vertices at their rest positions,
//! which also differentiates the constant couplings).

use nalgebra::{DMatrix, DVector, DVectorView, Matrix3, Vector3};

use super::backward::Backward;
use super::contact::project_jacobian;
use super::recording::Recording;
use super::skeletal_state::{copy_into, SkeletalAdjoint};
use super::{DiffError, Gradient};
use crate::constraint::{Linearize, ParamGrads};
use crate::solver::free_contact::FreeContact;

/// Which iteration the adjoint of [`Backward::skeletal_iteration`] is of.
#[derive(Debug, Clone, Copy)]
struct Iteration<'r> {
    /// Index into the recording.
    k: usize,
    /// Whether it is the step's first (it starts from the stored positions, not from `z_k`).
    at_start: bool,
    /// The contacts and impulses of the solve before it (whose impulses it reuses).
    prev: Option<(&'r [FreeContact], &'r [Vector3<f64>])>,
}

/// Check that `rec` holds a skeleton step's recording; its number of iterations.
fn check_recording(rec: &Recording, step: usize) -> Result<usize, DiffError> {
    let iters = rec.solves();
    if rec.iterates.len() != iters + 1
        || rec.skeleton_states.len() != iters + 1
        || rec.increments.len() != iters
        || rec.residuals.len() != iters
        || rec.rigid_contacts.len() != iters
    {
        return Err(DiffError::Unsupported(format!(
            "step {}: the replay recorded no skeleton iterates",
            step + 1
        )));
    }
    Ok(iters)
}

/// Solve `k`'s contact set and impulses.
fn contacts_of(rec: &Recording, k: usize) -> (&[FreeContact], &[Vector3<f64>]) {
    rec.solve(k)
}

impl Backward<'_> {
    /// The unrolled backward of one step with a skeleton (see the module docs). On entry the
    /// skeleton adjoint holds the adjoint of `z_{n+1}` (and `qbar` the velocity update's part of
    /// that of `q_n`); on exit `qbar` has the step's direct part of the adjoint of `q_n`, `s_bar`
    /// that of the inertial target, and the skeleton adjoint that of `z_n`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn skeletal_step(
        &mut self,
        q_n: &[Vector3<f64>],
        rec: &Recording,
        activations: &[f64],
        qbar: &mut [Vector3<f64>],
        s_bar: &mut [Vector3<f64>],
        g: &mut Gradient,
        step: usize,
        act_grad: &mut [f64],
        implicit: bool,
    ) -> Result<(), DiffError> {
        let model = self.model;
        let ih2 = self.integrator.inv_h2();
        let mut sa = self
            .skel
            .take()
            .ok_or_else(|| DiffError::Unsupported("skeleton buffers missing".into()))?;
        let r = if implicit {
            self.skeletal_fixed_point(&mut sa, q_n, rec, activations, qbar, g, step, act_grad)
        } else {
            self.skeletal_iterations(&mut sa, q_n, rec, activations, qbar, g, step, act_grad)
        };
        if r.is_ok() {
            // x_0 = s on free vertices (unrolled mode), and s enters b on every vertex.
            let x0 = if implicit { 0.0 } else { 1.0 };
            for (k, &v) in self.sys.free.iter().enumerate() {
                s_bar[v] += self.xbar[k] * x0 + self.base_acc[k] * (model.mass[v] * ih2);
            }
            for (r, &v) in self.sys.rigid.iter().enumerate() {
                s_bar[v] += sa.base_acc[r] * (model.mass[v] * ih2);
                g.mass[v] += sa.base_acc[r].dot(&self.s[v]) * ih2;
            }
            let (rigid_index, base_acc) = (&self.sys.rigid_index, &sa.base_acc);
            let adjoint = |v: usize| (rigid_index[v] != usize::MAX).then(|| base_acc[rigid_index[v]]);
            self.local
                .constant_rhs_adjoint(model, &adjoint, &mut g.attachment_targets);
        }
        self.skel = Some(sa);
        r
    }

    /// The implicit adjoint of one step with a skeleton: at the converged iterate the step is a
    /// fixed point `(x, z, lambda) = Phi(x, z, lambda; params)` of one local-global iteration, so
    /// the adjoint solves `r = r_out + Phi'^T r` by iterating the last recorded iteration's
    /// adjoint (at the forward's own rate), then accumulates the parameter adjoints once with
    /// the converged `r`. The converged step does not depend on the joint state it started from.
    #[allow(clippy::too_many_arguments)]
    fn skeletal_fixed_point(
        &mut self,
        sa: &mut SkeletalAdjoint,
        q_n: &[Vector3<f64>],
        rec: &Recording,
        activations: &[f64],
        qbar: &mut [Vector3<f64>],
        g: &mut Gradient,
        step: usize,
        act_grad: &mut [f64],
    ) -> Result<(), DiffError> {
        let iters = check_recording(rec, step)?;
        if iters == 0 {
            return Err(DiffError::Unsupported("the replay ran no iteration".into()));
        }
        let dofs = sa.work.dofs;
        let k = iters - 1;
        SkeletalAdjoint::load(&mut sa.work, &rec.skeleton_states[iters], &mut sa.q_r, &mut sa.b)?;
        SkeletalAdjoint::add_bt(&sa.b, &sa.q_r_bar_in, &mut sa.z_bar);
        let mut sc = std::mem::take(&mut sa.scratch);
        sc.prepare(g, qbar.len(), act_grad.len(), dofs);
        copy_into(&mut sc.x_in, &self.xbar);
        copy_into(&mut sc.z_in, &sa.z_bar);
        let it = Iteration {
            k,
            at_start: false,
            prev: Some(contacts_of(rec, k)),
        };
        // Scratch accumulators for the iterations whose parameter adjoints are discarded.
        let (g_s, q_s, a_s, t_s) = (&mut sc.g, &mut sc.q, &mut sc.act, &mut sc.torque);
        let g_s = g_s.as_mut().expect("prepared");
        let mut has_prev = false;
        let mut count = 0;
        let mut residual = f64::INFINITY;
        while count < self.opts.implicit_max_iterations {
            count += 1;
            self.skeletal_iteration(
                sa,
                q_n,
                rec,
                it,
                &mut sc.impulse_bar,
                activations,
                q_s,
                g_s,
                step,
                a_s,
                t_s,
            )?;
            let (mut change, mut size) = (0.0f64, 0.0f64);
            for (x, x0) in self.xbar.iter_mut().zip(&sc.x_in) {
                let new = x0 + *x;
                size = size.max(new.amax());
                *x = new;
            }
            for (z, z0) in sa.z_bar.iter_mut().zip(&sc.z_in) {
                let new = z0 + *z;
                size = size.max(new.abs());
                *z = new;
            }
            // The change against the previous iterate: compare with what went in.
            if has_prev {
                for (a, b) in self.xbar.iter().zip(&sc.prev_x) {
                    change = change.max((a - b).amax());
                }
                for (a, b) in sa.z_bar.iter().zip(&sc.prev_z) {
                    change = change.max((a - b).abs());
                }
                residual = if size > 0.0 { change / size } else { 0.0 };
            }
            copy_into(&mut sc.prev_x, &self.xbar);
            copy_into(&mut sc.prev_z, &sa.z_bar);
            has_prev = true;
            if residual <= self.implicit_tol {
                break;
            }
        }
        g.stats.backward_iterations += count;
        g.stats.implicit_residual = g.stats.implicit_residual.max(residual);
        super::implicit::fixed_point_converged(residual, count, step)?;
        // The parameter adjoints with the converged r.
        self.base_acc.iter_mut().for_each(|b| *b = Vector3::zeros());
        sa.base_acc.iter_mut().for_each(|b| *b = Vector3::zeros());
        sc.torque_acc.iter_mut().for_each(|t| *t = 0.0);
        let r = self.skeletal_iteration(
            sa,
            q_n,
            rec,
            it,
            &mut sc.impulse_bar,
            activations,
            qbar,
            g,
            step,
            act_grad,
            &mut sc.torque_acc,
        );
        if r.is_ok() {
            if let Some(tg) = g.torques.get_mut(step) {
                for (a, b) in tg.iter_mut().zip(&sc.torque_acc) {
                    *a += b;
                }
            }
        }
        sa.scratch = sc;
        r?;
        sa.z_bar.iter_mut().for_each(|z| *z = 0.0);
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn skeletal_iterations(
        &mut self,
        sa: &mut SkeletalAdjoint,
        q_n: &[Vector3<f64>],
        rec: &Recording,
        activations: &[f64],
        qbar: &mut [Vector3<f64>],
        g: &mut Gradient,
        step: usize,
        act_grad: &mut [f64],
    ) -> Result<(), DiffError> {
        let iters = check_recording(rec, step)?;
        let dofs = sa.work.dofs;
        sa.base_acc.iter_mut().for_each(|b| *b = Vector3::zeros());
        // z_bar_N += B(z_N)^T q_R_bar.
        SkeletalAdjoint::load(&mut sa.work, &rec.skeleton_states[iters], &mut sa.q_r, &mut sa.b)?;
        SkeletalAdjoint::add_bt(&sa.b, &sa.q_r_bar_in, &mut sa.z_bar);
        let entering = DVectorView::from(&sa.z_bar[..]).norm();
        let mut sc = std::mem::take(&mut sa.scratch);
        sc.torque_acc.clear();
        sc.torque_acc.resize(dofs, 0.0);
        // The adjoint of solve k's impulses from iteration k + 1 (which adds them to `y`).
        sc.impulse_bar.clear();
        let mut r = Ok(());
        for k in (0..iters).rev() {
            let it = Iteration {
                k,
                at_start: k == 0,
                prev: (k > 0).then(|| contacts_of(rec, k - 1)),
            };
            r = self.skeletal_iteration(
                sa,
                q_n,
                rec,
                it,
                &mut sc.impulse_bar,
                activations,
                qbar,
                g,
                step,
                act_grad,
                &mut sc.torque_acc,
            );
            if r.is_err() {
                break;
            }
        }
        // What of the joints' adjoint reached the joint state the iterations started from
        // (the previous step's), the joints' share of `unrolled_leftover`.
        sa.joint_leftover = if entering > 0.0 {
            DVectorView::from(&sa.z_bar[..]).norm() / entering
        } else {
            0.0
        };
        if let (Ok(()), Some(tg)) = (&r, g.torques.get_mut(step)) {
            for (a, b) in tg.iter_mut().zip(&sc.torque_acc) {
                *a += b;
            }
        }
        sa.scratch = sc;
        r
    }

    /// The adjoint of one iteration `it.k` of `rec` (see the module docs): on entry `self.xbar`
    /// and `sa.z_bar` hold the adjoints of `(x_{k+1}, z_{k+1})`, on exit those of `(x_k, z_k)`;
    /// parameter adjoints are added to `g`, `torque_acc` and `act_grad`, the right-hand side's
    /// to the `base_acc` buffers.
    #[allow(clippy::too_many_arguments)]
    fn skeletal_iteration(
        &mut self,
        sa: &mut SkeletalAdjoint,
        q_n: &[Vector3<f64>],
        rec: &Recording,
        it: Iteration<'_>,
        impulse_bar: &mut Vec<Vector3<f64>>,
        activations: &[f64],
        qbar: &mut [Vector3<f64>],
        g: &mut Gradient,
        step: usize,
        act_grad: &mut [f64],
        torque_acc: &mut [f64],
    ) -> Result<(), DiffError> {
        let model = self.model;
        let ih2 = self.integrator.inv_h2();
        let dofs = sa.work.dofs;
        let k = it.k;
        let sigma = sa.skeletal.sigma();
        let x_next = &rec.iterates[k + 1];
        let dz = &rec.increments[k];
        let resid = &rec.residuals[k];
        let (contacts, impulses) = contacts_of(rec, k);
        // 1. x_{k+1} = A_FF^-1 (b_F - A_FR q_R(z_{k+1}) + E lambda_k), the impulses from the
        // contact solve at x_pre = y0 - W q_R': y~ = A_FF^-1 x_pre_bar (contact-corrected).
        let ib = (!contacts.is_empty() && impulse_bar.len() == contacts.len()).then_some(&impulse_bar[..]);
        // A skeleton has no contacts between bodies (refused by the simulator): no start positions needed.
        self.solve_adjoint(contacts, impulses, x_next, ib, qbar, &[], false, Some(rec.solve_set(k)))?;
        SkeletalAdjoint::load(
            &mut sa.work,
            &rec.skeleton_states[k + 1],
            &mut sa.q_r_next,
            &mut sa.b_next,
        )?;
        // q_R' adjoint: -W^T x_pre_bar = -A_RF y~.
        for (r, list) in self.sys.l_rf.iter().enumerate() {
            let mut acc = Vector3::zeros();
            for &(f, val) in list {
                acc += self.z[f] * val;
            }
            sa.tmp_r[r] = -acc;
        }
        sa.z_after.copy_from_slice(&sa.z_bar);
        SkeletalAdjoint::add_bt(&sa.b_next, &sa.tmp_r, &mut sa.z_after);
        // 2. z_{k+1} = U(z_k, dz).
        SkeletalAdjoint::load(&mut sa.work, &rec.skeleton_states[k], &mut sa.q_r, &mut sa.b)?;
        sa.work.update_adjoint(dz, &sa.z_after, &mut sa.z_bar, &mut sa.dz_bar);
        // 3. dz = S^-1 (B^T r + tau) under the active limits.
        let nr = sa.q_r.len();
        for kk in 0..dofs {
            for rr in 0..nr {
                for a in 0..3 {
                    let mut acc = 0.0;
                    for c in 0..nr {
                        acc += sigma[(rr, c)] * sa.b[(3 * c + a, kk)];
                    }
                    sa.sb[(3 * rr + a, kk)] = acc;
                }
            }
        }
        let mut s = sa.b.transpose() * &sa.sb;
        let scale = (0..dofs)
            .map(|i| s[(i, i)].abs())
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        for i in 0..dofs {
            s[(i, i)] += 1e-14 * scale;
        }
        let s = (&s + s.transpose()) * 0.5;
        let chol = s.clone().cholesky().ok_or_else(|| {
            DiffError::NotDifferentiable(format!("step {}: B^T Sigma B is not positive definite", step + 1))
        })?;
        let limits = &rec.active_limits[k];
        let rigid = rec.rigid_contacts.get(k).map_or(&[][..], |v| v);
        let mut v = DVector::zeros(limits.len());
        // Per contact on a bone vertex: (D_j, G_j) of its cone projection and its adjoint nu_j.
        let mut cone: Vec<(Matrix3<f64>, Matrix3<f64>, Vector3<f64>)> = Vec::with_capacity(rigid.len());
        let u = if rigid.is_empty() {
            let mut u = chol.solve(&DVector::from_column_slice(&sa.dz_bar));
            if !limits.is_empty() {
                // v = (E^T S^-1 E)^-1 E^T S^-1 dz_bar, u = S^-1 (dz_bar - E v).
                let m = limits.len();
                let mut e = DMatrix::zeros(dofs, m);
                for (l, &(kk, _)) in limits.iter().enumerate() {
                    e[(kk, l)] = 1.0;
                }
                let sie = chol.solve(&e);
                let schur = e.transpose() * &sie;
                let rhs = e.transpose() * &u;
                v = schur.lu().solve(&rhs).ok_or_else(|| {
                    DiffError::NotDifferentiable(format!("step {}: active joint limits are dependent", step + 1))
                })?;
                u -= &sie * &v;
            }
            u
        } else {
            // The projected Gauss-Seidel's fixed point in the reduced coordinates, linearized:
            // S ddz - B_c^T dlambda - E dmu = dc + dB_c^T lambda - dS dz,
            // (I + D_j / w_j) dlambda_j - D_j B_j ddz = D_j (dq_j + dB_j dz) + G_j da_j,
            // E^T ddz = dd. Its transpose gives (u, nu, v); a least-squares solve, since
            // sticking contacts of a rigid bone may over-determine its coordinates.
            let (m, nl) = (rigid.len(), limits.len());
            let nn = dofs + 3 * m + nl;
            let mut kt = DMatrix::zeros(nn, nn);
            for (j, (r, c, lambda, wj)) in rigid.iter().enumerate() {
                let mut x = sa.q_r[*r];
                for a in 0..3 {
                    x[a] += (0..dofs).map(|kk| sa.b[(3 * r + a, kk)] * dz[kk]).sum::<f64>();
                }
                let (d, gm) = project_jacobian(&(x - lambda / *wj), *wj, c);
                let col = dofs + 3 * j;
                for a in 0..3 {
                    for kk in 0..dofs {
                        // K[kk, col + a] = -B[3r + a, kk]  ->  K^T[col + a, kk].
                        kt[(col + a, kk)] = -sa.b[(3 * r + a, kk)];
                        // K[col + a, kk] = -(D B_j)[a, kk]  ->  K^T[kk, col + a].
                        kt[(kk, col + a)] = -(0..3).map(|b| d[(a, b)] * sa.b[(3 * r + b, kk)]).sum::<f64>();
                    }
                    for b in 0..3 {
                        let id = if a == b { 1.0 } else { 0.0 };
                        kt[(col + b, col + a)] = id + d[(a, b)] / *wj;
                    }
                }
                cone.push((d, gm, Vector3::zeros()));
            }
            for i in 0..dofs {
                for jj in 0..dofs {
                    kt[(i, jj)] = s[(jj, i)];
                }
            }
            for (l, &(kk, _)) in limits.iter().enumerate() {
                let col = dofs + 3 * m + l;
                kt[(col, kk)] = -1.0;
                kt[(kk, col)] = 1.0;
            }
            let mut rhs = DVector::zeros(nn);
            rhs.rows_mut(0, dofs).copy_from(&DVector::from_column_slice(&sa.dz_bar));
            let y = kt
                .clone()
                .lu()
                .solve(&rhs)
                .filter(|y| y.iter().all(|x| x.is_finite()))
                .map_or_else(|| kt.svd(true, true).solve(&rhs, 1e-13), Ok)
                .map_err(|e| {
                    DiffError::NotDifferentiable(format!(
                        "step {}: the linearized contacts on bones have no solution ({e})",
                        step + 1
                    ))
                })?;
            for (j, cj) in cone.iter_mut().enumerate() {
                cj.2 = Vector3::new(y[dofs + 3 * j], y[dofs + 3 * j + 1], y[dofs + 3 * j + 2]);
            }
            for l in 0..nl {
                v[l] = y[dofs + 3 * m + l];
            }
            y.rows(0, dofs).into_owned()
        };
        for (t, x) in torque_acc.iter_mut().zip(u.iter()) {
            *t += x;
        }
        // beta = B u; B_bar = (r - SB dz) u^T - (SB u) dz^T.
        let dzv = DVector::from_column_slice(dz);
        let sb_dz = &sa.sb * &dzv;
        let sb_u = &sa.sb * &u;
        for rr in 0..nr {
            let mut bu = Vector3::zeros();
            for a in 0..3 {
                bu[a] = (0..dofs).map(|kk| sa.b[(3 * rr + a, kk)] * u[kk]).sum::<f64>();
            }
            sa.beta[rr] = bu;
        }
        for kk in 0..dofs {
            for i in 0..3 * nr {
                sa.b_bar[(i, kk)] = (resid[i / 3][i % 3] - sb_dz[i]) * u[kk] - sb_u[i] * dz[kk];
            }
        }
        // Contacts on bones: B_c^T lambda and D_j dB_j dz.
        for ((r, c, lambda, _), (d, gm, nu)) in rigid.iter().zip(&cone) {
            let dnu = d.transpose() * nu;
            for kk in 0..dofs {
                for a in 0..3 {
                    sa.b_bar[(3 * r + a, kk)] += lambda[a] * u[kk] + dnu[a] * dz[kk];
                }
            }
            qbar[c.vertex] += gm.transpose() * nu;
        }
        sa.work.contract_jacobian_derivative(&sa.b_bar, &mut sa.z_bar);
        for (l, &(kk, _)) in limits.iter().enumerate() {
            let bone = sa
                .work
                .bones
                .iter()
                .find(|b| kk >= b.dof_offset && kk < b.dof_offset + b.joint.dofs())
                .ok_or_else(|| DiffError::Input(format!("limit on unknown coordinate {kk}")))?;
            sa.z_bar[kk] += v[l] * bone.joint.increment_bound_derivative(dz[kk]);
        }
        // r = g - Sigma q_R(z_k): q_R's adjoint is -Sigma beta.
        for rr in 0..nr {
            let mut acc = Vector3::zeros();
            for c in 0..nr {
                acc += sa.beta[c] * sigma[(rr, c)];
            }
            sa.tmp_r[rr] = -acc;
        }
        // The contact vertices' positions q_j (in x_j = q_j + B_j dz).
        for ((r, ..), (d, _, nu)) in rigid.iter().zip(&cone) {
            sa.tmp_r[*r] += d.transpose() * nu;
        }
        SkeletalAdjoint::add_bt(&sa.b, &sa.tmp_r, &mut sa.z_bar);
        // g = b_R - A_RF y, y = A_FF^-1 (b_F + E lambda_{k-1}): b_F_bar = y~ - W beta.
        let w = sa.skeletal.w();
        SkeletalAdjoint::w_times(w, &sa.beta, &mut sa.w_beta);
        for rr in 0..nr {
            let mut bdz = Vector3::zeros();
            for a in 0..3 {
                bdz[a] = (0..dofs).map(|kk| sa.b[(3 * rr + a, kk)] * dz[kk]).sum::<f64>();
            }
            // tmp_r = q_R' - c, c = q_R + B dz (the linearized solution).
            sa.tmp_r[rr] = sa.q_r_next[rr] - (sa.q_r[rr] + bdz);
        }
        SkeletalAdjoint::w_times(w, &sa.tmp_r, &mut sa.w_shift);
        // The impulses of solve k - 1 entered y: their adjoint is (-W beta) at their contacts;
        // y - W c = x_{k+1} + W (q_R' - c) + A_FF^-1 E (lambda_{k-1} - lambda_k).
        impulse_bar.clear();
        for (c, l) in contacts.iter().zip(impulses) {
            let col = self.direct.inverse_column(c.index);
            for (ws, a) in sa.w_shift.iter_mut().zip(col) {
                *ws -= l * *a;
            }
        }
        if let Some((prev, prev_imp)) = it.prev {
            if !prev_imp.is_empty() {
                impulse_bar.extend(prev.iter().map(|c| -sa.w_beta[c.index]));
                for (c, l) in prev.iter().zip(prev_imp) {
                    let col = self.direct.inverse_column(c.index);
                    for (ws, a) in sa.w_shift.iter_mut().zip(col) {
                        *ws += l * *a;
                    }
                }
            }
        }
        for (f, (b, z)) in self.base_acc.iter_mut().zip(&self.z).enumerate() {
            *b += z - sa.w_beta[f];
        }
        for (b, x) in sa.base_acc.iter_mut().zip(&sa.beta) {
            *b += x;
        }
        // Matrix terms: -alpha^T dA gamma - y~^T dA q'.
        for i in 0..self.n {
            let fixed = model.fixed[i];
            let rest = if fixed { model.rest[i] } else { Vector3::zeros() };
            sa.alpha[i] = Vector3::zeros();
            sa.y_tilde[i] = Vector3::zeros();
            sa.gamma[i] = rest;
            sa.q_prime[i] = rest;
        }
        for (f, &v) in self.sys.free.iter().enumerate() {
            sa.alpha[v] = -sa.w_beta[f];
            sa.gamma[v] = x_next[f] + sa.w_shift[f];
            sa.y_tilde[v] = self.z[f];
            sa.q_prime[v] = x_next[f];
        }
        for (rr, &v) in self.sys.rigid.iter().enumerate() {
            sa.alpha[v] = sa.beta[rr];
            sa.gamma[v] = sa.q_r_next[rr] - sa.tmp_r[rr];
            sa.q_prime[v] = sa.q_r_next[rr];
        }
        self.local.matrix_terms(
            model,
            &[(&sa.alpha, &sa.gamma), (&sa.y_tilde, &sa.q_prime)],
            ParamGrads {
                w_rot: &mut g.w_rot,
                w_vol: &mut g.w_vol,
                activations: &mut [],
            },
        );
        for i in 0..self.n {
            if !model.fixed[i] {
                g.mass[i] -= (sa.alpha[i].dot(&sa.gamma[i]) + sa.y_tilde[i].dot(&sa.q_prime[i])) * ih2;
            }
        }
        // The local step at q_k = (x_k, q_R(z_k)) (the stored positions at k = 0).
        for (z, wb) in self.z.iter_mut().zip(&sa.w_beta) {
            *z -= wb;
        }
        Self::scatter(&self.sys, model, &rec.iterates[k], &mut self.q_full, false);
        Self::scatter(&self.sys, model, &self.z, &mut self.y_full, true);
        for (rr, &v) in self.sys.rigid.iter().enumerate() {
            self.q_full[v] = if it.at_start { q_n[v] } else { sa.q_r[rr] };
            self.y_full[v] = sa.beta[rr];
        }
        self.local.adjoint(
            model,
            &self.q_full,
            &self.y_full,
            None,
            activations,
            rec.svds.get(k).map_or(Linearize::Recompute, Linearize::Recorded),
            &mut self.out_full,
            ParamGrads {
                w_rot: &mut g.w_rot,
                w_vol: &mut g.w_vol,
                activations: act_grad,
            },
        )?;
        for (f, &v) in self.sys.free.iter().enumerate() {
            self.xbar[f] = self.out_full[v];
        }
        for (rr, &v) in self.sys.rigid.iter().enumerate() {
            sa.tmp_r[rr] = self.out_full[v];
        }
        if it.at_start {
            for (rr, &v) in self.sys.rigid.iter().enumerate() {
                qbar[v] += sa.tmp_r[rr];
            }
        } else {
            SkeletalAdjoint::add_bt(&sa.b, &sa.tmp_r, &mut sa.z_bar);
        }
        g.stats.backward_iterations += 1;
        Ok(())
    }
}
