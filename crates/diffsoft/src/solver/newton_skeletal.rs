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
//! allocates nothing once warm (`tests/allocations.rs`).

use std::time::Instant;

use nalgebra::{DMatrix, Matrix4, Vector3};

use super::certify::Certificate;
use super::direct::Direct;
use super::global::{InnerControl, SolverKind};
use super::hessian::ElasticHessian;
use super::observer::StepObserver;
use super::simulator::{GlobalStep, Simulator};
use super::skeletal::Skeletal;
use super::step::step_objective;
use super::system::GlobalSystem;
use super::{Settings, SolverError, StepStats};
use crate::constraint::{Constraints, Linearize, ParamGrads, TetSvd};
use crate::model::Model;
use crate::skeleton::{DualScratch, Skeleton};

use super::cholesky;
use super::newton_rules::{accepts, forcing, ABSOLUTE_FRACTION, MAX_HALVINGS};

/// Build the reduced step's factor and Schur complement and Newton's buffers.
pub(crate) fn build(
    model: &Model,
    settings: &Settings,
    system: &GlobalSystem,
    control: InnerControl,
) -> Result<(GlobalStep, Certificate), SolverError> {
    let sk = model
        .skeleton
        .as_ref()
        .expect("the skeletal Newton solver is built for a skeleton");
    let t0 = Instant::now();
    let direct = Box::new(Direct::new(system, control)?);
    let reduced = Box::new(Skeletal::new(system, &direct, sk));
    let newton = Box::new(NewtonSkeletal::new(model, system, sk, control));
    let mut cert = Certificate::unchecked(SolverKind::Newton, settings.certify, settings.dt);
    cert.message = "Newton's method on the step energy in the skeleton's reduced coordinates (Eqs. S3-S5, S7-S9): free vertices and joint increments, projected Hessian with the bones' curvature, conjugate gradients preconditioned with the reduced M/h^2 + L through its Schur complement, Armijo line search with the joints' update rules; no spectral certification needed".into();
    cert.elapsed_ms = t0.elapsed().as_secs_f64() * 1e3;
    Ok((
        GlobalStep::Skeletal {
            direct,
            reduced,
            newton: Some(newton),
        },
        cert,
    ))
}

/// With actuators: every constraint set's exact linearization `K` at the iterate (the
/// unprojected Hessian), with scratch for the parameter adjoints its application produces.
struct ExactK {
    constraints: Constraints,
    w_rot: Vec<f64>,
    w_vol: Vec<f64>,
    activations: Vec<f64>,
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

    fn dot(&self, o: &Red) -> f64 {
        self.f.iter().zip(&o.f).map(|(a, b)| a.dot(b)).sum::<f64>()
            + self.z.iter().zip(&o.z).map(|(a, b)| a * b).sum::<f64>()
    }

    fn fill_zero(&mut self) {
        self.f.iter_mut().for_each(|v| *v = Vector3::zeros());
        self.z.iter_mut().for_each(|v| *v = 0.0);
    }

    fn copy_from(&mut self, o: &Red) {
        self.f.copy_from_slice(&o.f);
        self.z.copy_from_slice(&o.z);
    }

    /// `self += a * o`.
    fn axpy(&mut self, a: f64, o: &Red) {
        for (x, y) in self.f.iter_mut().zip(&o.f) {
            *x += y * a;
        }
        for (x, y) in self.z.iter_mut().zip(&o.z) {
            *x += y * a;
        }
    }
}

/// What one direction solve did.
#[derive(Debug, Clone, Copy)]
struct Direction {
    iterations: usize,
    met: bool,
    /// Position-space RMS of the preconditioned gradient (the reduced projective-dynamics step).
    z0: f64,
    indefinite: bool,
}

/// Newton's method's Hessian and buffers with a skeleton (free numbering for `_f`, skeleton
/// order for `_r`, joint coordinates for `_z`).
pub(crate) struct NewtonSkeletal {
    hessian: ElasticHessian,
    record: Vec<TetSvd>,
    exact: Option<Box<ExactK>>,
    control: InnerControl,
    unprojected: bool,
    /// The reduced gradient, direction, and conjugate gradients' `r, z, p, H p`.
    grad: Red,
    dir: Red,
    r: Red,
    zz: Red,
    p: Red,
    hp: Red,
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

/// What the Newton loop reads besides its own buffers.
struct Ctx<'a> {
    model: &'a Model,
    sys: &'a GlobalSystem,
    activations: &'a [f64],
    s: &'a [Vector3<f64>],
    ih2: f64,
    base: &'a [Vector3<f64>],
    coords0: &'a [f64],
    torque: &'a [f64],
}

/// `y = A u` on the free and bone vertices for `u = (u_f, u_r)`.
fn apply_a(
    sys: &GlobalSystem,
    u_f: &[Vector3<f64>],
    u_r: &[Vector3<f64>],
    y_f: &mut [Vector3<f64>],
    y_r: &mut [Vector3<f64>],
) {
    sys.apply(u_f, y_f);
    let nr = u_r.len();
    for (r, list) in sys.l_rf.iter().enumerate() {
        let mut acc = u_r[r] * sys.mass_rigid_h2[r];
        for &(f, v) in list {
            y_f[f] += u_r[r] * v;
            acc += u_f[f] * v;
        }
        let row = &sys.l_rr[r * nr..(r + 1) * nr];
        for (c, &v) in row.iter().enumerate() {
            if v != 0.0 {
                acc += u_r[c] * v;
            }
        }
        y_r[r] = acc;
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
            hessian: ElasticHessian::new(model),
            record: vec![TetSvd::default(); model.tets.len()],
            exact: model.actuators.as_ref().map(|a| {
                Box::new(ExactK {
                    constraints: Constraints::new(model),
                    w_rot: vec![0.0; model.tets.len()],
                    w_vol: vec![0.0; model.tets.len()],
                    activations: vec![0.0; a.groups.len()],
                })
            }),
            control,
            unprojected: true,
            grad: red(),
            dir: red(),
            r: red(),
            zz: red(),
            p: red(),
            hp: red(),
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
        for ((xk, x0), d) in x.iter_mut().zip(&self.x0).zip(&self.dir.f) {
            *xk = x0 + d * alpha;
        }
        sk.load_state(&self.state0)?;
        for (r, d) in self.r.z.iter_mut().zip(&self.dir.z) {
            *r = d * alpha;
        }
        sk.update(&self.r.z);
        Ok(())
    }

    /// Position-space RMS of a reduced vector: free vertices and `B v_z` on the bone vertices.
    fn pos_rms(&mut self, v: &Red) -> f64 {
        b_times(&self.b_jac, &v.z, &mut self.tmp_r2);
        let sq: f64 = v.f.iter().map(|x| x.norm_squared()).sum::<f64>()
            + self.tmp_r2.iter().map(|x| x.norm_squared()).sum::<f64>();
        (sq / (v.f.len() + self.tmp_r2.len()).max(1) as f64).sqrt()
    }

    /// The step energy at the free iterate `x` and the skeleton's state, scattered into `full`
    /// (bone vertices from the skeleton into `q_r` too): the local step, then
    /// `step_objective`. Returns `(E, constraint energy)`.
    fn energy(
        &mut self,
        cx: &Ctx<'_>,
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
        let elastic = constraints.project(cx.model, full, cx.activations, Some(&mut self.record))?;
        let e = step_objective(cx.model, full, cx.s, cx.ih2, elastic, Some(sk), cx.coords0, cx.torque);
        Ok((e, elastic))
    }

    /// `grad_q E = A q - b - J p` on the free and bone vertices from the last local step, `B` at
    /// the iterate and the reduced gradient `(g_F, B^T g_R - tau)`.
    fn gradient(
        &mut self,
        cx: &Ctx<'_>,
        constraints: &Constraints,
        sk: &Skeleton,
        x: &[Vector3<f64>],
        gathered: &mut [Vector3<f64>],
    ) {
        constraints.gather(cx.model, gathered);
        apply_a(cx.sys, x, &self.q_r, &mut self.grad.f, &mut self.g_r);
        for (k, &v) in cx.sys.free.iter().enumerate() {
            self.grad.f[k] -= cx.base[k] + gathered[v];
        }
        for (r, &v) in cx.sys.rigid.iter().enumerate() {
            self.g_r[r] -= self.base_r[r] + gathered[v];
        }
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

    /// Prepare the elastic Hessian at `q`: unprojected (exact, with the bones' curvature) or
    /// projected (without it). Returns whether the unprojected one could be linearized.
    fn prepare(&mut self, model: &Model, q: &[Vector3<f64>], unprojected: bool) -> bool {
        self.unprojected = unprojected;
        self.hessian.build(model, &self.record, !unprojected);
        if let (true, Some(ex)) = (unprojected, self.exact.as_mut()) {
            return ex.constraints.linearize(model, q).is_ok();
        }
        true
    }

    /// `zz = P^-1 r` with the reduced projective-dynamics matrix through its Schur complement:
    /// `d_z = S^-1 (r_z - B^T A_RF A_FF^-1 r_F)`, `d_F = A_FF^-1 r_F - W B d_z`.
    fn precondition(&mut self, cx: &Ctx<'_>, reduced: &Skeletal, direct: &mut Direct) -> Result<(), SolverError> {
        direct.solve_free(&self.r.f, &mut self.zz.f)?;
        for (r, list) in cx.sys.l_rf.iter().enumerate() {
            let mut acc = Vector3::zeros();
            for &(f, v) in list {
                acc += self.zz.f[f] * v;
            }
            self.tmp_r[r] = acc;
        }
        bt_times(&self.b_jac, &self.tmp_r, &mut self.zz.z);
        for (k, z) in self.zz.z.iter_mut().enumerate() {
            *z = if self.held[k] { 0.0 } else { self.r.z[k] - *z };
        }
        cholesky::solve(self.s.as_slice(), &mut self.zz.z, self.s.nrows());
        for (k, z) in self.zz.z.iter_mut().enumerate() {
            if self.held[k] {
                *z = 0.0;
            }
        }
        b_times(&self.b_jac, &self.zz.z, &mut self.tmp_r);
        let nf = self.zz.f.len();
        for (r, col) in reduced.w().as_slice().chunks_exact(nf.max(1)).enumerate() {
            let c = self.tmp_r[r];
            for (x, &wv) in self.zz.f.iter_mut().zip(col) {
                *x -= c * wv;
            }
        }
        Ok(())
    }

    /// `hp = H_red p` (see the module docs); `false` where an actuator's projection is not
    /// differentiable.
    fn apply_hessian(&mut self, cx: &Ctx<'_>, q: &[Vector3<f64>]) -> bool {
        b_times(&self.b_jac, &self.p.z, &mut self.tmp_r);
        apply_a(cx.sys, &self.p.f, &self.tmp_r, &mut self.hp.f, &mut self.tmp_r2);
        for (k, &v) in cx.sys.free.iter().enumerate() {
            self.y_full[v] = self.p.f[k];
        }
        for (r, &v) in cx.sys.rigid.iter().enumerate() {
            self.y_full[v] = self.tmp_r[r];
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
            self.hp.f[k] -= self.out_full[v];
        }
        for (r, &v) in cx.sys.rigid.iter().enumerate() {
            self.tmp_r2[r] -= self.out_full[v];
        }
        bt_times(&self.b_jac, &self.tmp_r2, &mut self.hp.z);
        let dofs = self.hp.z.len();
        for k in 0..dofs {
            if self.held[k] {
                self.hp.z[k] = 0.0;
                continue;
            }
            if self.unprojected {
                let mut acc = 0.0;
                for j in 0..dofs {
                    acc += self.geo[(k, j)] * self.p.z[j];
                }
                self.hp.z[k] += acc;
            }
        }
        true
    }

    /// `H_red d = -g` by preconditioned conjugate gradients from `d = 0` (as `newton.rs`; the
    /// residuals measured in position space).
    fn direction(
        &mut self,
        cx: &Ctx<'_>,
        reduced: &Skeletal,
        direct: &mut Direct,
        q: &[Vector3<f64>],
        z_first: f64,
        floor: f64,
    ) -> Result<Direction, SolverError> {
        for (r, g) in self.r.f.iter_mut().zip(&self.grad.f) {
            *r = -g;
        }
        for (k, (r, g)) in self.r.z.iter_mut().zip(&self.grad.z).enumerate() {
            *r = if self.held[k] { 0.0 } else { -g };
        }
        self.dir.fill_zero();
        self.precondition(cx, reduced, direct)?;
        let zz = std::mem::replace(&mut self.zz, Red::new(0, 0));
        let z0 = self.pos_rms(&zz);
        self.zz = zz;
        let eta = forcing(z0, z_first);
        let stop = (eta * z0).max(floor);
        if z0 <= floor {
            self.dir.copy_from(&self.zz);
            return Ok(Direction {
                iterations: 0,
                met: true,
                z0,
                indefinite: false,
            });
        }
        self.p.copy_from(&self.zz);
        let mut rz = self.r.dot(&self.zz);
        for it in 1..=self.control.max_iterations {
            let ok = self.apply_hessian(cx, q);
            let php = self.p.dot(&self.hp);
            if !ok || php.is_nan() || php <= 0.0 {
                if it == 1 {
                    self.dir.copy_from(&self.zz);
                }
                return Ok(Direction {
                    iterations: it,
                    met: false,
                    z0,
                    indefinite: true,
                });
            }
            let alpha = rz / php;
            self.dir.axpy(alpha, &self.p);
            self.r.axpy(-alpha, &self.hp);
            self.precondition(cx, reduced, direct)?;
            let zz = std::mem::replace(&mut self.zz, Red::new(0, 0));
            let res = self.pos_rms(&zz);
            self.zz = zz;
            if res <= stop {
                return Ok(Direction {
                    iterations: it,
                    met: true,
                    z0,
                    indefinite: false,
                });
            }
            let rz_new = self.r.dot(&self.zz);
            let beta = rz_new / rz;
            rz = rz_new;
            for (p, z) in self.p.f.iter_mut().zip(&self.zz.f) {
                *p = z + *p * beta;
            }
            for (p, z) in self.p.z.iter_mut().zip(&self.zz.z) {
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
    /// Phase 3 with `solver: newton` and a skeleton (see the module docs): Newton iterations
    /// from the first iterate `begin_step` set; with a recording observer, one observed
    /// local-global iteration at the converged iterate.
    pub(super) fn newton_skeletal_iterate(
        &mut self,
        stats: &mut StepStats,
        observer: &mut dyn StepObserver,
    ) -> Result<(), SolverError> {
        self.newton_skeletal_loop(stats)?;
        if observer.records_iterations() {
            observer.iterate(&self.work.x, self.skeleton.as_ref());
            self.scatter_iterate();
            let tl = Instant::now();
            let mut energy_prev = f64::INFINITY;
            self.local_phase(stats, observer, &mut energy_prev, false)?;
            stats.local_ms += tl.elapsed().as_secs_f64() * 1e3;
            let tg = Instant::now();
            let g = self.global_phase(observer)?;
            stats.global_ms += tg.elapsed().as_secs_f64() * 1e3;
            stats.global_iterations += g.iterations;
            if !self.work.x.iter().all(|x| x.iter().all(|c| c.is_finite())) {
                return Err(SolverError::NonFinite(format!(
                    "step {}: positions became non-finite in the recorded iteration after Newton's",
                    stats.step
                )));
            }
        }
        Ok(())
    }

    /// The Newton iterations themselves.
    fn newton_skeletal_loop(&mut self, stats: &mut StepStats) -> Result<(), SolverError> {
        let Simulator {
            model,
            settings,
            integrator,
            system,
            global,
            constraints,
            activations,
            work: w,
            skeleton,
            state,
            ..
        } = self;
        let GlobalStep::Skeletal {
            direct,
            reduced,
            newton: Some(nw),
        } = global
        else {
            unreachable!("Newton with a skeleton holds its solver in the skeletal step");
        };
        let sk = skeleton.as_mut().expect("a skeletal step has a skeleton");
        let ih2 = integrator.inv_h2();
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
        let cx = Ctx {
            model,
            sys: system,
            activations,
            s: &w.s,
            ih2,
            base: &w.base,
            coords0: &w.coords0,
            torque: &w.torque,
        };
        let tol = settings.tolerance * model.length_scale;
        let floor = ABSOLUTE_FRACTION * tol;
        let (nf, nr) = (system.n(), system.rigid.len());
        let tl = Instant::now();
        let (mut e, mut elastic) = nw.energy(&cx, constraints, sk, &w.x, &mut w.full)?;
        nw.gradient(&cx, constraints, sk, &w.x, &mut w.gathered);
        stats.local_ms += tl.elapsed().as_secs_f64() * 1e3;
        let mut z_first = f64::NAN;
        let time = state.time + integrator.h();
        for _ in 0..settings.max_iterations {
            let tg = Instant::now();
            nw.active_set(sk);
            nw.prepare_reduced(reduced, sk)?;
            let mut dir = if nw.prepare(model, &w.full, true) {
                nw.direction(&cx, reduced, direct, &w.full, z_first, floor)?
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
            let gd = nw.grad.dot(&nw.dir);
            nw.x0.copy_from_slice(&w.x);
            nw.q_r0.copy_from_slice(&nw.q_r);
            sk.save_state(&mut nw.state0);
            let dir_size = {
                let d = std::mem::replace(&mut nw.dir, Red::new(0, 0));
                let s = nw.pos_rms(&d);
                nw.dir = d;
                s
            };
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
            stats.relative_change = change / model.length_scale;
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
}
