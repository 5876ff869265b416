//! Newton's method on the step energy with an embedded skeleton (docs/method.md section 6.5,
//! Eqs. S7-S9), selected with `solver: newton` on a model with bones.
//!
//! The unknowns are the free vertices `x_F` and the joint increments `dz` in the joints' tangent
//! charts (the coordinates of the reduced step, [`super::skeletal`]); the bone vertices follow
//! rigidly, `q_R = q_R(z)`. The energy is the step energy of `newton.rs` plus the torques'
//! potential, `E(x_F, q_R(z)) - tau . (z - z_start)` (`step_objective`). Per iteration:
//!
//! 1. at the iterate: the local step, `grad_q E = A q - b - J p` on every vertex, and the reduced
//!    gradient `g = (g_F, B^T g_R - tau)` with `B = dq_R/dz`;
//! 2. joint limits as an active set: a coordinate at a bound whose gradient pushes it further
//!    out is held there (its increment is zero); the others are free;
//! 3. the direction by conjugate gradients on the reduced Hessian
//!    `[I 0; 0 B]^T H [I 0; 0 B] + [0 0; 0 sym(G)]`, `H = A - J K~ J^T` ([`super::hessian`]) and
//!    `G_lk = g_R . d^2 q_R / dz_l dz_k` the bones' curvature (exact Hessian first; where
//!    conjugate gradients meet non-positive curvature, the projected `K~` without `G`, which is
//!    positive definite), preconditioned with the projective-dynamics reduced matrix through its
//!    Schur complement `S = B^T Sigma B` (the `W`, `Sigma` and `A_FF` factor of the reduced step);
//! 4. a backtracking (Armijo) line search, the joints moved by their exact update rules (which
//!    also clamp at the limits); if it fails, one reduced projective-dynamics iteration;
//! 5. stop when the RMS change of the free and bone vertices is below `tolerance x length scale`.
//!
//! When the step is recorded for the backward pass (implicit mode differentiates the reduced
//! step's fixed point, `diff::skeletal`), one observed local-global iteration follows at the
//! converged iterate: Newton's fixed point is the reduced step's, so that iteration moves the
//! state by round-off and gives the backward pass the data of a converged reduced solve.
//!
//! Obstacles with a skeleton are refused (`newton::check_supported`). Every buffer is allocated
//! in [`NewtonSkeletal::new`] (the skeleton's transforms go to scratch buffers too), so a step
//! allocates nothing once warm (`crates/diffsoft/tests/allocations.rs`).

use std::time::Instant;

use nalgebra::{DMatrix, Matrix4, Vector3};

use super::local_global::{global_phase, local_phase, PhaseRef, ReducedStep};
use super::newton_cg::{self, CgVector, CgWork, Direction, NewtonOperator};
use super::newton_rules::{accepts, ABSOLUTE_FRACTION, MAX_HALVINGS};
use super::{StepContext, StepIteration};
use crate::constraint::{Constraints, TetSvd};
use crate::model::Model;
use crate::skeleton::{DualScratch, Skeleton};
use crate::solver::assembled::GlobalSystem;
use crate::solver::certificate::Certificate;
use crate::solver::cholesky;
use crate::solver::direct::Direct;
use crate::solver::global::{GlobalSolver, InnerControl, SolverKind};
use crate::solver::hessian::ConstraintHessian;
use crate::solver::observer::StepObserver;
use crate::solver::problem::StepProblem;
use crate::solver::skeletal::Skeletal;
use crate::solver::{Settings, SolverError, StepStats};

/// The certificate of a Newton run with a skeleton; `t0`: when its set-up began.
pub(crate) fn certificate(settings: &Settings, t0: Instant) -> Certificate {
    let mut cert = Certificate::unchecked(SolverKind::Newton, settings.certify, settings.dt);
    cert.message = "Newton's method on the step energy in the skeleton's reduced coordinates (Eqs. S3-S5, S7-S9): free vertices and joint increments, projected Hessian with the bones' curvature, conjugate gradients preconditioned with the reduced M/h^2 + L through its Schur complement, Armijo line search with the joints' update rules; no spectral certification needed".into();
    cert.elapsed_ms = t0.elapsed().as_secs_f64() * 1e3;
    cert
}

/// Newton's method with a skeleton: its own buffers and the reduced step it preconditions
/// with (and runs once, observed, when the backward pass records the step).
pub(crate) struct NewtonSkeletalIteration {
    step: ReducedStep,
    newton: Box<NewtonSkeletal>,
}

impl NewtonSkeletalIteration {
    /// Newton's buffers for `model` on the reduced step `step`.
    pub(crate) fn new(
        model: &Model,
        sys: &GlobalSystem,
        sk: &Skeleton,
        step: ReducedStep,
        control: InnerControl,
    ) -> Self {
        Self {
            step,
            newton: Box::new(NewtonSkeletal::new(model, sys, sk, control)),
        }
    }
}

/// A vector of the reduced unknowns: free vertices and joint increments.
#[derive(Debug, Clone)]
struct Red {
    f: Vec<Vector3<f64>>,
    z: Vec<f64>,
}

impl Red {
    fn new(nf: usize, dofs: usize) -> Self {
        Self {
            f: vec![Vector3::zeros(); nf],
            z: vec![0.0; dofs],
        }
    }
}

impl CgVector for Red {
    fn dot(&self, o: &Red) -> f64 {
        self.f.iter().zip(&o.f).map(|(a, b)| a.dot(b)).sum::<f64>()
            + self.z.iter().zip(&o.z).map(|(a, b)| a * b).sum::<f64>()
    }

    fn set_zero(&mut self) {
        self.f.iter_mut().for_each(|v| *v = Vector3::zeros());
        self.z.iter_mut().for_each(|v| *v = 0.0);
    }

    fn copy_from(&mut self, o: &Red) {
        self.f.copy_from_slice(&o.f);
        self.z.copy_from_slice(&o.z);
    }

    fn axpy(&mut self, a: f64, o: &Red) {
        for (x, y) in self.f.iter_mut().zip(&o.f) {
            *x += y * a;
        }
        for (x, y) in self.z.iter_mut().zip(&o.z) {
            *x += y * a;
        }
    }

    fn xpby(&mut self, z: &Red, beta: f64) {
        for (p, z) in self.f.iter_mut().zip(&z.f) {
            *p = z + *p * beta;
        }
        for (p, z) in self.z.iter_mut().zip(&z.z) {
            *p = z + *p * beta;
        }
    }
}

/// Newton's method's Hessian and buffers with a skeleton (free numbering for `_f`, skeleton
/// order for `_r`, joint coordinates for `_z`).
pub(crate) struct NewtonSkeletal {
    /// The constraints' part of the Hessian at the iterate.
    hessian: ConstraintHessian,
    record: Vec<TetSvd>,
    control: InnerControl,
    /// The reduced gradient.
    grad: Red,
    /// Conjugate gradients' vectors; the direction ends in `cg.dir` (`cg.r.z` doubles as the
    /// line search's joint increment).
    cg: CgWork<Red>,
    /// The free iterate and raw joint state at the start of the line search.
    x0: Vec<Vector3<f64>>,
    state0: Vec<f64>,
    /// `grad_q E` on the bone vertices.
    g_r: Vec<Vector3<f64>>,
    /// The right-hand side's constant part on the bone vertices.
    base_r: Vec<Vector3<f64>>,
    q_r: Vec<Vector3<f64>>,
    q_r0: Vec<Vector3<f64>>,
    tmp_r: Vec<Vector3<f64>>,
    tmp_r2: Vec<Vector3<f64>>,
    /// `B = dq_R/dz` at the iterate (`3 n_R x dofs`), `(Sigma (x) I3) B`.
    b_jac: DMatrix<f64>,
    sb: DMatrix<f64>,
    /// `S = B^T Sigma B` (held coordinates replaced by identity rows), then its Cholesky factor.
    s: DMatrix<f64>,
    /// `sym(G)`, the bones' curvature term.
    geo: DMatrix<f64>,
    /// Coordinates held at a joint limit in this iteration.
    held: Vec<bool>,
    /// Every vertex: a reduced vector expanded and `J K~ J^T` of it.
    y_full: Vec<Vector3<f64>>,
    out_full: Vec<Vector3<f64>>,
    /// Scratch of the skeleton's transforms (world transforms; dual numbers for `G`).
    world: Vec<Matrix4<f64>>,
    dual: DualScratch,
    /// Line searches replaced by a projective-dynamics iteration (diagnostics).
    pub(crate) fallbacks: usize,
}

impl std::fmt::Debug for NewtonSkeletal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NewtonSkeletal")
            .field("free", &self.grad.f.len())
            .field("dofs", &self.grad.z.len())
            .field("fallbacks", &self.fallbacks)
            .finish()
    }
}

/// `out = B v` (per bone vertex).
fn b_times(b: &DMatrix<f64>, v: &[f64], out: &mut [Vector3<f64>]) {
    out.iter_mut().for_each(|o| *o = Vector3::zeros());
    let rows = 3 * out.len();
    for (k, &vk) in v.iter().enumerate() {
        if vk == 0.0 {
            continue;
        }
        let col = &b.as_slice()[k * rows..(k + 1) * rows];
        for (o, c) in out.iter_mut().zip(col.chunks_exact(3)) {
            *o += Vector3::new(c[0], c[1], c[2]) * vk;
        }
    }
}

/// `out = B^T v`.
fn bt_times(b: &DMatrix<f64>, v: &[Vector3<f64>], out: &mut [f64]) {
    let rows = 3 * v.len();
    for (k, o) in out.iter_mut().enumerate() {
        let col = &b.as_slice()[k * rows..(k + 1) * rows];
        *o = v
            .iter()
            .zip(col.chunks_exact(3))
            .map(|(x, c)| x.x * c[0] + x.y * c[1] + x.z * c[2])
            .sum::<f64>();
    }
}

impl NewtonSkeletal {
    fn new(model: &Model, sys: &GlobalSystem, sk: &Skeleton, control: InnerControl) -> Self {
        let (n, nf, nr, dofs) = (model.n(), sys.n(), sys.rigid.len(), sk.dofs);
        let red = || Red::new(nf, dofs);
        let mut state0 = Vec::new();
        sk.save_state(&mut state0);
        Self {
            hessian: ConstraintHessian::new(model),
            record: vec![TetSvd::default(); model.tets.len()],
            control,
            grad: red(),
            cg: CgWork::new(red()),
            x0: vec![Vector3::zeros(); nf],
            state0,
            g_r: vec![Vector3::zeros(); nr],
            base_r: vec![Vector3::zeros(); nr],
            q_r: vec![Vector3::zeros(); nr],
            q_r0: vec![Vector3::zeros(); nr],
            tmp_r: vec![Vector3::zeros(); nr],
            tmp_r2: vec![Vector3::zeros(); nr],
            b_jac: DMatrix::zeros(3 * nr, dofs),
            sb: DMatrix::zeros(3 * nr, dofs),
            s: DMatrix::zeros(dofs, dofs),
            geo: DMatrix::zeros(dofs, dofs),
            held: vec![false; dofs],
            y_full: vec![Vector3::zeros(); n],
            out_full: vec![Vector3::zeros(); n],
            world: Vec::with_capacity(sk.bones.len()),
            dual: DualScratch::default(),
            fallbacks: 0,
        }
    }

    /// The iterate `x0 + alpha d` (free vertices into `x`, the joints from the saved state by
    /// their update rules; `r.z` holds the increment).
    fn try_step(&mut self, sk: &mut Skeleton, x: &mut [Vector3<f64>], alpha: f64) -> Result<(), SolverError> {
        for ((xk, x0), d) in x.iter_mut().zip(&self.x0).zip(&self.cg.dir.f) {
            *xk = x0 + d * alpha;
        }
        sk.load_state(&self.state0)?;
        for (r, d) in self.cg.r.z.iter_mut().zip(&self.cg.dir.z) {
            *r = d * alpha;
        }
        sk.update(&self.cg.r.z);
        Ok(())
    }

    /// The step energy at the free iterate `x` and the skeleton's state, scattered into `full`
    /// (bone vertices from the skeleton into `q_r` too): the local step, then
    /// `step_objective`. Returns `(E, constraint energy)`.
    fn energy(
        &mut self,
        cx: &StepProblem<'_>,
        constraints: &mut Constraints,
        sk: &Skeleton,
        x: &[Vector3<f64>],
        full: &mut [Vector3<f64>],
    ) -> Result<(f64, f64), SolverError> {
        for (k, &v) in cx.sys.free.iter().enumerate() {
            full[v] = x[k];
        }
        sk.positions_with(&mut self.world, &mut self.q_r);
        for (r, &v) in cx.sys.rigid.iter().enumerate() {
            full[v] = self.q_r[r];
        }
        cx.energy(constraints, full, Some(sk), &mut self.record)
    }

    /// `grad_q E = A q - b - J p` on the free and bone vertices from the last local step, `B` at
    /// the iterate and the reduced gradient `(g_F, B^T g_R - tau)`.
    fn gradient(
        &mut self,
        cx: &StepProblem<'_>,
        constraints: &mut Constraints,
        sk: &Skeleton,
        x: &[Vector3<f64>],
        gathered: &mut [Vector3<f64>],
    ) {
        cx.gradient(
            constraints,
            x,
            &self.q_r,
            &self.base_r,
            gathered,
            &mut self.grad.f,
            &mut self.g_r,
        );
        sk.jacobian_with(&mut self.world, &mut self.b_jac);
        bt_times(&self.b_jac, &self.g_r, &mut self.grad.z);
        for (g, t) in self.grad.z.iter_mut().zip(cx.torque) {
            *g -= t;
        }
    }

    /// Hold the coordinates at a joint limit whose gradient pushes them out.
    fn active_set(&mut self, sk: &Skeleton) -> usize {
        self.held.iter_mut().for_each(|h| *h = false);
        let mut n = 0;
        for b in &sk.bones {
            if let Some((lo, hi)) = b.joint.increment_bounds() {
                let k = b.dof_offset;
                let g = self.grad.z[k];
                if (hi <= 0.0 && g < 0.0) || (lo >= 0.0 && g > 0.0) {
                    self.held[k] = true;
                    n += 1;
                }
            }
        }
        n
    }

    /// `S = B^T Sigma B` at the iterate (held coordinates decoupled), factored; and the bones'
    /// curvature `sym(G)` when the exact Hessian is used.
    fn prepare_reduced(&mut self, reduced: &Skeletal, sk: &Skeleton) -> Result<(), SolverError> {
        let nr = self.q_r.len();
        let dofs = self.s.nrows();
        let sigma = reduced.sigma();
        for k in 0..dofs {
            for r in 0..nr {
                let mut acc = Vector3::zeros();
                for c in 0..nr {
                    let s = sigma[(r, c)];
                    if s != 0.0 {
                        acc += Vector3::new(
                            self.b_jac[(3 * c, k)],
                            self.b_jac[(3 * c + 1, k)],
                            self.b_jac[(3 * c + 2, k)],
                        ) * s;
                    }
                }
                for a in 0..3 {
                    self.sb[(3 * r + a, k)] = acc[a];
                }
            }
        }
        for k1 in 0..dofs {
            for k2 in k1..dofs {
                let v = self.b_jac.column(k1).dot(&self.sb.column(k2));
                self.s[(k1, k2)] = v;
                self.s[(k2, k1)] = v;
            }
        }
        let scale = (0..dofs)
            .map(|k| self.s[(k, k)].abs())
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        for k in 0..dofs {
            self.s[(k, k)] += 1e-14 * scale;
            if self.held[k] {
                for j in 0..dofs {
                    self.s[(k, j)] = 0.0;
                    self.s[(j, k)] = 0.0;
                }
                self.s[(k, k)] = 1.0;
            }
        }
        let n = self.s.nrows();
        if !cholesky::factor(self.s.as_mut_slice(), n) {
            return Err(SolverError::Factorization(
                "the reduced skeleton matrix B^T Sigma B is not positive definite".into(),
            ));
        }
        sk.jacobian_derivative_matrix_with(&self.g_r, &mut self.geo, &mut self.dual);
        for k1 in 0..dofs {
            for k2 in k1 + 1..dofs {
                let v = 0.5 * (self.geo[(k1, k2)] + self.geo[(k2, k1)]);
                self.geo[(k1, k2)] = v;
                self.geo[(k2, k1)] = v;
            }
        }
        Ok(())
    }

    /// Prepare the constraints' Hessian at `q`: unprojected (exact; the bones' curvature is
    /// added in the product) or projected (without it). Returns whether the unprojected one
    /// could be linearized.
    fn prepare(&mut self, model: &Model, q: &[Vector3<f64>], unprojected: bool) -> bool {
        self.hessian.prepare(model, &self.record, q, unprojected)
    }

    /// The Newton direction at the iterate `q` by conjugate gradients preconditioned with the
    /// reduced projective-dynamics matrix (as `newton.rs`, the residuals measured in position
    /// space; [`newton_cg::direction`]); in `cg.dir`.
    fn direction(
        &mut self,
        cx: &StepProblem<'_>,
        reduced: &Skeletal,
        direct: &mut Direct,
        q: &[Vector3<f64>],
        z_first: f64,
        floor: f64,
    ) -> Result<Direction, SolverError> {
        for (r, g) in self.cg.r.f.iter_mut().zip(&self.grad.f) {
            *r = -g;
        }
        for (k, (r, g)) in self.cg.r.z.iter_mut().zip(&self.grad.z).enumerate() {
            *r = if self.held[k] { 0.0 } else { -g };
        }
        let mut op = ReducedOperator {
            cx,
            q,
            reduced,
            direct,
            hessian: &mut self.hessian,
            b_jac: &self.b_jac,
            s: &self.s,
            geo: &self.geo,
            held: &self.held,
            tmp_r: &mut self.tmp_r,
            tmp_r2: &mut self.tmp_r2,
            y_full: &mut self.y_full,
            out_full: &mut self.out_full,
        };
        newton_cg::direction(&mut op, &mut self.cg, z_first, floor, self.control.max_iterations)
    }
}

/// Position-space RMS of a reduced vector: free vertices and `B v_z` on the bone vertices
/// (`tmp_r`: scratch, one entry per bone vertex).
fn pos_rms(b_jac: &DMatrix<f64>, tmp_r: &mut [Vector3<f64>], v: &Red) -> f64 {
    b_times(b_jac, &v.z, tmp_r);
    let sq: f64 =
        v.f.iter().map(|x| x.norm_squared()).sum::<f64>() + tmp_r.iter().map(|x| x.norm_squared()).sum::<f64>();
    (sq / (v.f.len() + tmp_r.len()).max(1) as f64).sqrt()
}

/// Newton's system in the reduced coordinates: `[I 0; 0 B]^T H [I 0; 0 B] + [0 0; 0 sym(G)]`
/// (the bones' curvature with the unprojected Hessian), held coordinates decoupled,
/// preconditioned with the reduced projective-dynamics matrix through its Schur complement.
struct ReducedOperator<'a, 'c> {
    cx: &'a StepProblem<'c>,
    /// The iterate (every vertex).
    q: &'a [Vector3<f64>],
    reduced: &'a Skeletal,
    direct: &'a mut Direct,
    hessian: &'a mut ConstraintHessian,
    b_jac: &'a DMatrix<f64>,
    /// The Cholesky factor of `S = B^T Sigma B`.
    s: &'a DMatrix<f64>,
    geo: &'a DMatrix<f64>,
    held: &'a [bool],
    tmp_r: &'a mut Vec<Vector3<f64>>,
    tmp_r2: &'a mut Vec<Vector3<f64>>,
    y_full: &'a mut Vec<Vector3<f64>>,
    out_full: &'a mut Vec<Vector3<f64>>,
}

impl NewtonOperator for ReducedOperator<'_, '_> {
    type V = Red;

    /// `zz = P^-1 r` with the reduced projective-dynamics matrix through its Schur complement:
    /// `d_z = S^-1 (r_z - B^T A_RF A_FF^-1 r_F)`, `d_F = A_FF^-1 r_F - W B d_z`.
    fn precondition(&mut self, r: &Red, zz: &mut Red) -> Result<(), SolverError> {
        self.direct.solve_free(&r.f, &mut zz.f)?;
        for (rv, list) in self.cx.sys.l_rf.iter().enumerate() {
            let mut acc = Vector3::zeros();
            for &(f, v) in list {
                acc += zz.f[f] * v;
            }
            self.tmp_r[rv] = acc;
        }
        bt_times(self.b_jac, self.tmp_r, &mut zz.z);
        for (k, z) in zz.z.iter_mut().enumerate() {
            *z = if self.held[k] { 0.0 } else { r.z[k] - *z };
        }
        cholesky::solve(self.s.as_slice(), &mut zz.z, self.s.nrows());
        for (k, z) in zz.z.iter_mut().enumerate() {
            if self.held[k] {
                *z = 0.0;
            }
        }
        b_times(self.b_jac, &zz.z, self.tmp_r);
        let nf = zz.f.len();
        for (rv, col) in self.reduced.w().as_slice().chunks_exact(nf.max(1)).enumerate() {
            let c = self.tmp_r[rv];
            for (x, &wv) in zz.f.iter_mut().zip(col) {
                *x -= c * wv;
            }
        }
        Ok(())
    }

    fn measure(&mut self, z: &Red) -> f64 {
        pos_rms(self.b_jac, self.tmp_r2, z)
    }

    /// `hp = H_red p` (see the module docs); `false` where an actuator's projection is not
    /// differentiable.
    fn apply(&mut self, p: &Red, hp: &mut Red) -> bool {
        let cx = self.cx;
        b_times(self.b_jac, &p.z, self.tmp_r);
        if !cx.hessian_product(
            self.hessian,
            self.q,
            &p.f,
            self.tmp_r,
            &mut hp.f,
            self.tmp_r2,
            self.y_full,
            self.out_full,
        ) {
            return false;
        }
        bt_times(self.b_jac, self.tmp_r2, &mut hp.z);
        let dofs = hp.z.len();
        let unprojected = self.hessian.unprojected();
        for k in 0..dofs {
            if self.held[k] {
                hp.z[k] = 0.0;
                continue;
            }
            if unprojected {
                let mut acc = 0.0;
                for j in 0..dofs {
                    acc += self.geo[(k, j)] * p.z[j];
                }
                hp.z[k] += acc;
            }
        }
        true
    }
}

impl StepIteration for NewtonSkeletalIteration {
    fn kind(&self) -> SolverKind {
        SolverKind::Newton
    }

    fn begin_step(&mut self) {
        self.step.reduced.reset_impulses();
        self.step.direct.begin_step();
    }

    /// Newton iterations from the first iterate `begin_step` set (see the module docs); with a
    /// recording observer, one observed local-global iteration at the converged iterate.
    fn iterate(
        &mut self,
        cx: &mut StepContext<'_>,
        stats: &mut StepStats,
        observer: &mut dyn StepObserver,
    ) -> Result<(), SolverError> {
        stats.begin_round();
        newton_skeletal_loop(&mut self.newton, &mut self.step, cx, stats)?;
        if observer.records_iterations() {
            observer.iterate(&cx.work.x, cx.skeleton.as_deref());
            cx.scatter_iterate();
            let tl = Instant::now();
            let mut energy_prev = f64::INFINITY;
            local_phase(cx, None, stats, observer, &mut energy_prev, false)?;
            stats.local_ms += tl.elapsed().as_secs_f64() * 1e3;
            let tg = Instant::now();
            let g = global_phase(cx, PhaseRef::Reduced(&mut self.step), observer)?;
            stats.global_ms += tg.elapsed().as_secs_f64() * 1e3;
            stats.global_iterations += g.iterations;
            if !cx.work.x.iter().all(|x| x.iter().all(|c| c.is_finite())) {
                return Err(SolverError::NonFinite(format!(
                    "step {}: positions became non-finite in the recorded iteration after Newton's",
                    stats.step
                )));
            }
        }
        Ok(())
    }

    fn impulses(&self) -> Option<&[Vector3<f64>]> {
        self.step.direct.impulses()
    }

    fn contact_impulses(&self) -> Option<&[Vector3<f64>]> {
        self.step.direct.contact_impulses()
    }
}

/// The Newton iterations themselves.
fn newton_skeletal_loop(
    nw: &mut NewtonSkeletal,
    step: &mut ReducedStep,
    cx: &mut StepContext<'_>,
    stats: &mut StepStats,
) -> Result<(), SolverError> {
    let (model, settings, system, activations) = (cx.model, cx.settings, cx.system, cx.activations);
    let (constraints, w) = (&mut *cx.constraints, &mut *cx.work);
    let ReducedStep { direct, reduced } = step;
    let sk = cx.skeleton.as_deref_mut().expect("a skeletal step has a skeleton");
    let ih2 = cx.scheme.inv_h2();
    let time = cx.time;
    // The constant part of the bone vertices' right-hand side.
    for (r, &v) in system.rigid.iter().enumerate() {
        nw.base_r[r] = w.s[v] * (model.mass[v] * ih2) + system.coupling_rigid[r];
    }
    {
        let (base_r, rigid_index) = (&mut nw.base_r, &system.rigid_index);
        constraints.constant_rhs(model, &mut |v, b| {
            let r = rigid_index[v];
            if r != usize::MAX {
                base_r[r] += b;
            }
        });
    }
    let cx = StepProblem {
        model,
        sys: system,
        activations,
        s: &w.s,
        ih2,
        base: &w.base,
        coords0: &w.coords0,
        torque: &w.torque,
    };
    let tol = settings.absolute_tolerance(model);
    let floor = ABSOLUTE_FRACTION * tol;
    let (nf, nr) = (system.n(), system.rigid.len());
    let tl = Instant::now();
    let (mut e, mut elastic) = nw.energy(&cx, constraints, sk, &w.x, &mut w.full)?;
    nw.gradient(&cx, constraints, sk, &w.x, &mut w.gathered);
    stats.local_ms += tl.elapsed().as_secs_f64() * 1e3;
    let mut z_first = f64::NAN;
    for _ in 0..settings.max_iterations {
        if crate::base::cancel::requested() {
            return Err(SolverError::Interrupted);
        }
        let tg = Instant::now();
        nw.active_set(sk);
        nw.prepare_reduced(reduced, sk)?;
        let mut dir = if nw.prepare(model, &w.full, true) {
            nw.direction(&cx, reduced, direct, &w.full, z_first, floor)?
        } else {
            Direction::undefined()
        };
        if dir.indefinite {
            stats.global_iterations += dir.iterations;
            nw.prepare(model, &w.full, false);
            dir = nw.direction(&cx, reduced, direct, &w.full, z_first, floor)?;
        }
        if z_first.is_nan() {
            z_first = dir.z0;
        }
        stats.global_iterations += dir.iterations;
        if !dir.met {
            stats.capped_solves += 1;
        }
        stats.global_ms += tg.elapsed().as_secs_f64() * 1e3;
        // Backtracking line search on E (Armijo), the joints moved by their update rules.
        let tl = Instant::now();
        let gd = nw.grad.dot(&nw.cg.dir);
        nw.x0.copy_from_slice(&w.x);
        nw.q_r0.copy_from_slice(&nw.q_r);
        sk.save_state(&mut nw.state0);
        let dir_size = pos_rms(&nw.b_jac, &mut nw.tmp_r2, &nw.cg.dir);
        let mut accepted = false;
        // Only a full Newton step can end the iteration (see `newton.rs`).
        let mut full_step = true;
        if dir_size <= floor {
            nw.try_step(sk, &mut w.x, 1.0)?;
            (e, elastic) = nw.energy(&cx, constraints, sk, &w.x, &mut w.full)?;
            accepted = true;
        } else if gd < 0.0 {
            let mut alpha = 1.0;
            for _ in 0..MAX_HALVINGS {
                nw.try_step(sk, &mut w.x, alpha)?;
                let (et, el) = nw.energy(&cx, constraints, sk, &w.x, &mut w.full)?;
                if accepts(alpha, gd, e, et) {
                    (e, elastic) = (et, el);
                    accepted = true;
                    full_step = alpha == 1.0;
                    break;
                }
                alpha *= 0.5;
            }
        }
        if !accepted {
            full_step = false;
            // One reduced projective-dynamics iteration from the start point instead.
            nw.fallbacks += 1;
            w.x.copy_from_slice(&nw.x0);
            sk.load_state(&nw.state0)?;
            nw.energy(&cx, constraints, sk, &w.x, &mut w.full)?;
            constraints.gather(model, &mut w.gathered);
            for (k, &v) in system.free.iter().enumerate() {
                w.rhs[k] = w.base[k] + w.gathered[v];
            }
            for (r, &v) in system.rigid.iter().enumerate() {
                w.b_rigid[r] = nw.base_r[r] + w.gathered[v];
            }
            let control = nw.control;
            reduced.solve(
                system,
                direct,
                sk,
                &w.rhs,
                &w.b_rigid,
                time,
                &mut w.x,
                &mut w.q_rigid,
                &[],
                &[],
                control,
            )?;
            (e, elastic) = nw.energy(&cx, constraints, sk, &w.x, &mut w.full)?;
        }
        nw.gradient(&cx, constraints, sk, &w.x, &mut w.gathered);
        stats.local_ms += tl.elapsed().as_secs_f64() * 1e3;
        stats.iterations += 1;
        stats.elastic_energy = elastic;
        let mut sq = 0.0;
        for k in 0..nf {
            sq += (w.x[k] - nw.x0[k]).norm_squared();
        }
        for r in 0..nr {
            sq += (nw.q_r[r] - nw.q_r0[r]).norm_squared();
        }
        let change = (sq / (nf + nr).max(1) as f64).sqrt();
        if !change.is_finite() || !e.is_finite() {
            return Err(SolverError::NonFinite(format!(
                "step {}: positions became non-finite in Newton iteration {}",
                stats.step, stats.iterations
            )));
        }
        stats.record_change(change / model.length_scale);
        if change <= tol && full_step {
            stats.converged = true;
            break;
        }
    }
    for (r, &v) in system.rigid.iter().enumerate() {
        w.q_rigid[r] = nw.q_r[r];
        w.full[v] = nw.q_r[r];
    }
    stats.elastic_energy = elastic;
    Ok(())
}
