//! Reverse-mode gradients of whole simulations (METHOD.md section 7).
//!
//! A loss `L(q_1, v_1, ..., q_N, v_N)` ([`loss`]) of a trajectory is differentiated with respect
//! to the initial positions and velocities, the per-tet constraint weights (hence Young's modulus
//! and Poisson ratio, globally or per element), the lumped masses (density), the external
//! accelerations (gravity), the attachment targets, the actuators' activations at every step,
//! the joint torques at every step and the initial joint state (skeletons, [`skeletal`]).
//!
//! The forward pass stores each step's state (checkpointing, as the paper does); the backward
//! pass walks the steps in reverse. Two modes:
//!
//! * [`Mode::Unrolled`] replays each step from its checkpoint, recording the local-global
//!   iterates `x_0 = s, x_1, ..., x_N` (Eqs. 2-5), and differentiates every iteration the forward
//!   ran, `x_{k+1} = A^-1 (M s/h^2 + b_fixed + J p(x_k))`: with `r_bar = A^-1 x_bar` (plus the
//!   contact correction of [`contact`]), `x_bar_k = J (dp/dq)(x_k)^T J^T r_bar` ([`local`]). It
//!   is the exact derivative of what the truncated solver computed.
//! * [`Mode::Implicit`] differentiates the converged step by the implicit function theorem at the
//!   stored next state, solving `(A - K) r_bar = x_bar` (`K` the local step's linearization,
//!   symmetric) by conjugate gradients preconditioned with the prefactored `A` (DiffPD's
//!   approach), or with contacts by the fixed point `r_bar = A^-T (x_bar + K r_bar)`: cheap, and
//!   exact only where the forward converged.
//!
//! The weights enter `A = M/h^2 + L(w)` too: each solve contributes
//! `dL/dw_t = <F_t(r_bar), P_t(x_k)/w_t> - <F_t(r_bar), F_t(x_{k+1})>` and each mass
//! `r_bar . (s - x_{k+1}) / h^2`. The global solves are differentiated as exact linear solves with
//! a sparse Cholesky factor (built here for any forward solver); contact subproblems at the
//! impulses they converged to. With a skeleton, each iteration is the reduced step of Eqs. 7-18,
//! differentiated with the joints' tangent charts, their update rules, active joint limits and
//! contacts on free and bone vertices (see [`skeletal`]); its implicit mode iterates the adjoint
//! of the step's last iteration to its fixed point. Anderson-accelerated unrolled runs return
//! [`DiffError::Unsupported`].
//!
//! Memory: one state per step (pure checkpointing, as the paper); [`Options::store_bytes`]
//! keeps whole steps' recordings from the forward pass within a budget so they need no replay.

pub mod contact;
pub mod local;
pub mod loss;
pub mod optim;
pub mod params;
pub mod skeletal;

use std::time::Instant;

use nalgebra::Vector3;
use serde::Serialize;

use crate::model::Model;
use crate::solver::direct::Direct;
use crate::solver::global::{FreeContact, GlobalSystem, InnerControl};
use crate::solver::{Settings, Simulator, SolverError, SolverKind};

use crate::constraint::{Constraints, Linearize, ParamGrads};
use contact::ContactAdjoint;
use loss::{Loss, LossGrad};
use skeletal::SkeletalAdjoint;

pub use params::Param;

/// Errors of the differentiation.
#[derive(Debug, Clone, thiserror::Error)]
pub enum DiffError {
    /// Bad input (parameters, losses, controls).
    #[error("invalid input: {0}")]
    Input(String),
    /// A feature the backward pass does not differentiate.
    #[error("not supported by the backward pass: {0}")]
    Unsupported(String),
    /// The simulation passes through a point where it is not differentiable.
    #[error("not differentiable: {0}")]
    NotDifferentiable(String),
    /// The forward simulation failed.
    #[error(transparent)]
    Solver(#[from] SolverError),
}

impl From<crate::constraint::NotDifferentiable> for DiffError {
    fn from(e: crate::constraint::NotDifferentiable) -> Self {
        DiffError::NotDifferentiable(e.0)
    }
}

impl From<crate::base::InputError> for DiffError {
    fn from(e: crate::base::InputError) -> Self {
        DiffError::Solver(SolverError::Input(e))
    }
}

/// How steps are differentiated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// Every local-global iteration the forward ran (exact for the truncated solver).
    Unrolled,
    /// The converged step, by the implicit function theorem (exact at convergence).
    Implicit,
}

/// Settings of the backward pass.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Options {
    /// Mode.
    pub mode: Mode,
    /// Implicit mode: stop the adjoint fixed-point iteration at this relative change.
    pub implicit_tolerance: f64,
    /// Implicit mode: iteration cap of the adjoint fixed point.
    pub implicit_max_iterations: usize,
    /// Relative tolerance of the linearized contact systems.
    pub contact_tolerance: f64,
    /// Sweep cap of the linearized contact systems.
    pub contact_max_sweeps: usize,
    /// Unrolled mode: keep the forward pass's recordings of whole steps (iterates and
    /// decompositions) up to this many bytes, so those steps need no replay in the backward
    /// pass; the steps beyond it are replayed from their checkpoints. 0: pure checkpointing, as
    /// the paper (memory: one state per step).
    pub store_bytes: usize,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            mode: Mode::Unrolled,
            implicit_tolerance: 1e-12,
            implicit_max_iterations: 300,
            contact_tolerance: 1e-14,
            contact_max_sweeps: 100_000,
            store_bytes: 0,
        }
    }
}

impl Options {
    /// Defaults with the given mode.
    pub fn mode(mode: Mode) -> Self {
        Self {
            mode,
            ..Self::default()
        }
    }
}

/// Initial positions and velocities of every vertex.
pub type InitialState = (Vec<Vector3<f64>>, Vec<Vector3<f64>>);

/// The controls of a run: the initial state and activations per step (`[step][group]`,
/// overriding the groups' schedules).
#[derive(Debug, Clone, Default)]
pub struct Controls {
    /// Initial positions and velocities (`None`: the model's rest positions and initial
    /// velocities).
    pub initial: Option<InitialState>,
    /// Activation of each actuator group at each step (`None`: follow the schedules).
    pub activations: Option<Vec<Vec<f64>>>,
    /// Joint torque on each reduced coordinate at each step (`[step][coordinate]`, overriding
    /// the bones' schedules; entries of coordinates that are not one-DoF joints must be 0).
    pub torques: Option<Vec<Vec<f64>>>,
}

/// Cost and accuracy figures of one gradient evaluation.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct DiffStats {
    /// Forward pass wall time (ms).
    pub forward_ms: f64,
    /// Backward pass wall time (ms), replays included.
    pub backward_ms: f64,
    /// Of which replaying steps from their checkpoints (unrolled mode, ms).
    pub replay_ms: f64,
    /// Of which in the adjoints of the contact solves (ms).
    pub contact_ms: f64,
    /// Local-global iterations of the forward pass.
    pub forward_iterations: usize,
    /// Adjoint iterations of the backward pass.
    pub backward_iterations: usize,
    /// Forward steps that stopped at the iteration cap.
    pub unconverged_steps: usize,
    /// Implicit mode: largest final relative change of an adjoint fixed point.
    pub implicit_residual: f64,
    /// Gauss-Seidel sweeps of the linearized contact systems.
    pub contact_sweeps: usize,
    /// Largest final relative residual of a linearized contact system.
    pub contact_residual: f64,
    /// Unrolled mode: largest distance between a replayed step and its checkpoint (m).
    pub replay_deviation: f64,
    /// Bytes of stored checkpoints (states, activations, final contacts).
    pub checkpoint_bytes: usize,
    /// Bytes of whole-step recordings kept from the forward pass (see [`Options::store_bytes`]).
    pub stored_bytes: usize,
    /// Steps whose recording was kept (not replayed).
    pub stored_steps: usize,
}

/// The loss and its gradient with respect to everything differentiable.
#[derive(Debug, Clone)]
pub struct Gradient {
    /// Loss value.
    pub loss: f64,
    /// `dL/dq_0` per vertex.
    pub q0: Vec<Vector3<f64>>,
    /// `dL/dv_0` per vertex.
    pub v0: Vec<Vector3<f64>>,
    /// `dL/dw_rot` per tet.
    pub w_rot: Vec<f64>,
    /// `dL/dw_vol` per tet.
    pub w_vol: Vec<f64>,
    /// `dL/dm` per vertex.
    pub mass: Vec<f64>,
    /// `dL/da_ext` per vertex (external acceleration).
    pub accel: Vec<Vector3<f64>>,
    /// `dL/d target` per attachment (model order).
    pub attachment_targets: Vec<Vector3<f64>>,
    /// `dL/d activation`, `[step][group]`.
    pub activations: Vec<Vec<f64>>,
    /// `dL/d tau`, the joint torques (generalized forces) per step and reduced coordinate,
    /// `[step][coordinate]` (empty without a skeleton; a free root's entries are the
    /// derivatives with respect to generalized forces on its chart coordinates).
    pub torques: Vec<Vec<f64>>,
    /// `dL/dz_0`, the initial joint state in the joints' charts (angles, extensions; a free
    /// root's rotation vector and translation increments); empty without a skeleton.
    pub joints0: Vec<f64>,
    /// Cost and accuracy figures.
    pub stats: DiffStats,
}

impl Gradient {
    /// `dL/dE_t` per tet (`w_rot = E V/(1+nu)`, `w_vol = nu E V/(1+nu)`).
    pub fn youngs_modulus(&self, model: &Model) -> Vec<f64> {
        let mut out = vec![0.0; model.tets.len()];
        for b in &model.bodies {
            let nu = b.material.poisson_ratio;
            for t in b.tets.clone() {
                let vol = model.fem.geometry[t].volume;
                let mut d = self.w_rot[t] * vol / (1.0 + nu);
                if b.volume_constraint {
                    d += self.w_vol[t] * nu * vol / (1.0 + nu);
                }
                out[t] = d;
            }
        }
        out
    }

    /// `dL/dnu_t` per tet.
    pub fn poisson_ratio(&self, model: &Model) -> Vec<f64> {
        let mut out = vec![0.0; model.tets.len()];
        for b in &model.bodies {
            let (e, nu) = (b.material.youngs_modulus, b.material.poisson_ratio);
            for t in b.tets.clone() {
                let vol = model.fem.geometry[t].volume;
                let k = e * vol / ((1.0 + nu) * (1.0 + nu));
                let mut d = -self.w_rot[t] * k;
                if b.volume_constraint {
                    d += self.w_vol[t] * k;
                }
                out[t] = d;
            }
        }
        out
    }

    /// `dL/drho` per body (masses scale with density).
    pub fn density(&self, model: &Model) -> Vec<f64> {
        model
            .bodies
            .iter()
            .map(|b| {
                b.vertices
                    .clone()
                    .map(|i| self.mass[i] * model.mass[i] / b.density)
                    .sum()
            })
            .collect()
    }
}

/// The states of a forward run (checkpoints) and what the backward pass needs of each step.
#[derive(Debug, Clone)]
struct Forward {
    loss: f64,
    q: Vec<Vec<Vector3<f64>>>,
    v: Vec<Vec<Vector3<f64>>>,
    time: Vec<f64>,
    activations: Vec<Vec<f64>>,
    /// Raw joint state after each step (and before the first), with a skeleton.
    skeleton: Vec<Vec<f64>>,
    /// The one-DoF joints' coordinates after each step (for joint losses).
    joints: Vec<Vec<f64>>,
    /// Implicit mode with contacts: each step's final contact set and impulses.
    contacts: Vec<(Vec<FreeContact>, Vec<Vector3<f64>>)>,
    /// Unrolled mode: steps' recordings kept within the store budget (`None`: replay).
    stored: Vec<Option<crate::solver::Recording>>,
    stored_bytes: usize,
    iterations: usize,
    unconverged: usize,
}

fn check_supported(model: &Model, settings: &Settings, mode: Mode) -> Result<(), DiffError> {
    if mode == Mode::Unrolled && settings.anderson > 0 {
        return Err(DiffError::Unsupported(
            "unrolled gradients through Anderson acceleration; use anderson = 0 or --mode implicit".into(),
        ));
    }
    if !model.obstacles.is_empty() && settings.solver != SolverKind::Direct {
        return Err(DiffError::Unsupported(
            "gradients with contact need the direct solver (solver: direct)".into(),
        ));
    }
    Ok(())
}

fn set_controls(sim: &mut Simulator, model: &Model, controls: &Controls, step: usize) -> Result<(), DiffError> {
    if let (Some(acts), Some(act)) = (&controls.activations, &model.actuators) {
        let row = acts.get(step).ok_or_else(|| {
            DiffError::Input(format!(
                "activations given for {} steps, step {} needs one",
                acts.len(),
                step + 1
            ))
        })?;
        if row.len() != act.groups.len() {
            return Err(DiffError::Input(format!(
                "step {}: {} activations for {} actuator groups",
                step + 1,
                row.len(),
                act.groups.len()
            )));
        }
        for (g, a) in act.groups.iter().zip(row) {
            sim.set_activation(&g.name, *a)?;
        }
    }
    if let Some(torques) = &controls.torques {
        let sk = model
            .skeleton
            .as_ref()
            .ok_or_else(|| DiffError::Input("torques given, but the model has no skeleton".into()))?;
        let row = torques.get(step).ok_or_else(|| {
            DiffError::Input(format!(
                "torques given for {} steps, step {} needs one",
                torques.len(),
                step + 1
            ))
        })?;
        if row.len() != sk.dofs {
            return Err(DiffError::Input(format!(
                "step {}: {} torques for {} joint coordinates",
                step + 1,
                row.len(),
                sk.dofs
            )));
        }
        for b in &sk.bones {
            let n = b.joint.dofs();
            let vals = &row[b.dof_offset..b.dof_offset + n];
            if n == 1 {
                sim.set_torque_dof(b.dof_offset, Some(vals[0]))?;
            } else if vals.iter().any(|&t| t != 0.0) {
                return Err(DiffError::Input(format!(
                    "step {}: bone '{}' has a {} joint; torques act on one-DoF joints",
                    step + 1,
                    b.name,
                    b.joint.kind()
                )));
            }
        }
    }
    Ok(())
}

/// The one-DoF joints' coordinates of a simulator's skeleton (empty without one).
fn joint_scalars(sim: &Simulator) -> Vec<f64> {
    sim.skeleton().map_or(Vec::new(), |sk| {
        let mut c = vec![0.0; sk.dofs];
        sk.scalars(&mut c);
        c
    })
}

fn loss_term(
    model: &Model,
    loss: &dyn Loss,
    n: usize,
    steps: usize,
    q: &[Vector3<f64>],
    v: &[Vector3<f64>],
    joints: &[f64],
) -> f64 {
    let k = q.len();
    let (mut a, mut b, mut c) = (vec![Vector3::zeros(); k], vec![Vector3::zeros(); k], vec![0.0; k]);
    let mut gj = vec![0.0; joints.len()];
    loss.joint_term(model, n, steps, joints, &mut gj)
        + loss.term(
            model,
            n,
            steps,
            q,
            v,
            LossGrad {
                q: &mut a,
                v: &mut b,
                mass: &mut c,
            },
        )
}

/// What a forward pass keeps for the backward pass.
#[derive(Debug, Clone, Copy, Default)]
struct Keep {
    /// Every step's state (checkpoints).
    states: bool,
    /// Every step's final contacts (implicit mode).
    contacts: bool,
    /// Whole steps' recordings within this budget (unrolled mode, see [`Options::store_bytes`]).
    store_bytes: usize,
}

fn forward(
    model: &Model,
    settings: &Settings,
    steps: usize,
    controls: &Controls,
    loss: &dyn Loss,
    keep: Keep,
) -> Result<Forward, DiffError> {
    let Keep {
        states: keep,
        contacts: record_contacts,
        store_bytes,
    } = keep;
    loss.validate(model)?;
    let mut sim = Simulator::new(model.clone(), settings.clone())?;
    if let Some((q, v)) = &controls.initial {
        sim.set_state(q.clone(), v.clone())?;
    }
    if record_contacts {
        sim.record(Some(false));
    }
    let mut storing = keep && !record_contacts && store_bytes > 0;
    if storing {
        // Iterates only: decompositions are ~200 bytes per tet and iteration, and the backward
        // pass redoes them at a fraction of a replay's cost.
        sim.record(Some(true));
        sim.record_decompositions(false);
    }
    let skel0 = sim.skeleton_state();
    let mut f = Forward {
        loss: 0.0,
        q: vec![sim.state().q.clone()],
        v: vec![sim.state().v.clone()],
        time: vec![0.0],
        activations: Vec::with_capacity(steps),
        skeleton: skel0.into_iter().collect(),
        joints: Vec::new(),
        contacts: Vec::new(),
        stored: Vec::new(),
        stored_bytes: 0,
        iterations: 0,
        unconverged: 0,
    };
    for n in 0..steps {
        set_controls(&mut sim, model, controls, n)?;
        let st = sim.step()?;
        f.iterations += st.iterations;
        f.unconverged += usize::from(!st.converged);
        let joints = joint_scalars(&sim);
        let s = sim.state();
        f.loss += loss_term(model, loss, n + 1, steps, &s.q, &s.v, &joints);
        f.activations.push(sim.activations().map_or(Vec::new(), |a| a.to_vec()));
        if keep {
            f.q.push(s.q.clone());
            f.v.push(s.v.clone());
            f.time.push(s.time);
            if let Some(st) = sim.skeleton_state() {
                f.skeleton.push(st);
            }
            f.joints.push(joints);
        }
        if storing {
            let r = sim.recording().expect("recording enabled");
            let b = r.bytes();
            if f.stored_bytes + b <= store_bytes {
                f.stored_bytes += b;
                f.stored.push(Some(r.snapshot()));
            } else {
                storing = false;
                sim.record(None);
            }
        }
        if record_contacts {
            let r = sim.recording().expect("recording enabled");
            if r.iterative_contacts {
                return Err(DiffError::Unsupported(
                    "contacts were solved by an iterative global solver: gradients with contact need `solver: direct`"
                        .into(),
                ));
            }
            let (set, imp) = r.solves.last().cloned().unwrap_or((0, Vec::new()));
            let cs = r.contact_sets.get(set).cloned().unwrap_or_default();
            f.contacts.push((cs, imp));
        }
    }
    Ok(f)
}

/// An implicit adjoint's fixed point that ends with a relative change above this has diverged.
const DIVERGED_CHANGE: f64 = 0.1;

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

/// The loss of a forward run alone (for finite differences).
pub fn loss_value(
    model: &Model,
    settings: &Settings,
    steps: usize,
    controls: &Controls,
    loss: &dyn Loss,
) -> Result<f64, DiffError> {
    Ok(forward(model, settings, steps, controls, loss, Keep::default())?.loss)
}

/// Buffers of the backward pass.
struct Backward<'a> {
    model: &'a Model,
    sys: GlobalSystem,
    direct: Direct,
    local: Constraints,
    contact: ContactAdjoint,
    opts: Options,
    n: usize,
    nf: usize,
    // adjoints in the free numbering
    xbar: Vec<Vector3<f64>>,
    z: Vec<Vector3<f64>>,
    base_acc: Vec<Vector3<f64>>,
    // full numbering
    y_full: Vec<Vector3<f64>>,
    q_full: Vec<Vector3<f64>>,
    xn_full: Vec<Vector3<f64>>,
    out_full: Vec<Vector3<f64>>,
    s: Vec<Vector3<f64>>,
    anchor_scratch: Vec<Vector3<f64>>,
    scratch_rot: Vec<f64>,
    scratch_vol: Vec<f64>,
    scratch_act: Vec<f64>,
    /// The skeleton's backward buffers (`None` without a skeleton).
    skel: Option<SkeletalAdjoint>,
    /// Time in contact adjoints (ms).
    contact_ms: f64,
}

impl<'a> Backward<'a> {
    fn new(model: &'a Model, settings: &Settings, opts: Options) -> Result<Self, DiffError> {
        let sys = GlobalSystem::new(model, settings.dt)?;
        let direct = Direct::new(
            &sys,
            InnerControl {
                tolerance: 0.0,
                max_iterations: 1,
            },
        )?;
        let (n, nf) = (model.n(), sys.n());
        let groups = model.actuators.as_ref().map_or(0, |a| a.groups.len());
        let mut b = Self {
            skel: None,
            contact_ms: 0.0,
            local: Constraints::new(model),
            contact: ContactAdjoint::default(),
            xbar: vec![Vector3::zeros(); nf],
            z: vec![Vector3::zeros(); nf],
            base_acc: vec![Vector3::zeros(); nf],
            y_full: vec![Vector3::zeros(); n],
            q_full: vec![Vector3::zeros(); n],
            xn_full: vec![Vector3::zeros(); n],
            out_full: vec![Vector3::zeros(); n],
            s: vec![Vector3::zeros(); n],
            anchor_scratch: vec![Vector3::zeros(); n],
            scratch_rot: vec![0.0; model.tets.len()],
            scratch_vol: vec![0.0; model.tets.len()],
            scratch_act: vec![0.0; groups],
            model,
            sys,
            direct,
            opts,
            n,
            nf,
        };
        b.skel = SkeletalAdjoint::new(model, &b);
        Ok(b)
    }

    /// Scatter free values into a full vector whose other entries are `fill(vertex)`.
    fn scatter(sys: &GlobalSystem, model: &Model, free: &[Vector3<f64>], out: &mut [Vector3<f64>], zero_fixed: bool) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = if zero_fixed { Vector3::zeros() } else { model.rest[i] };
        }
        for (k, &v) in sys.free.iter().enumerate() {
            out[v] = free[k];
        }
    }

    /// `z = A^-T x_bar` with the contact correction (`impulse_bar`: a direct adjoint of the
    /// impulses); anchors' adjoints into `anchor_bar`.
    #[allow(clippy::too_many_arguments)]
    fn solve_adjoint(
        &mut self,
        contacts: &[FreeContact],
        impulses: &[Vector3<f64>],
        x: &[Vector3<f64>],
        impulse_bar: Option<&[Vector3<f64>]>,
        anchor_bar: &mut [Vector3<f64>],
        q_start: &[Vector3<f64>],
    ) -> Result<(), DiffError> {
        self.direct.solve_free(&self.xbar, &mut self.z)?;
        if contacts.is_empty() {
            return Ok(());
        }
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
            self.opts.contact_tolerance,
            self.opts.contact_max_sweeps,
        );
        self.contact_ms += t.elapsed().as_secs_f64() * 1e3;
        r
    }

    /// One step's adjoint: `qbar`, `vbar` hold the adjoints of `(q_{n+1}, v_{n+1})` on entry and
    /// of `(q_n, v_n)` on exit; parameter adjoints are added to `g`.
    #[allow(clippy::too_many_arguments)]
    fn step(
        &mut self,
        settings: &Settings,
        q_n: &[Vector3<f64>],
        v_n: &[Vector3<f64>],
        q_next: &[Vector3<f64>],
        activations: &[f64],
        replay: Option<&crate::solver::Recording>,
        final_contacts: Option<&(Vec<FreeContact>, Vec<Vector3<f64>>)>,
        qbar: &mut [Vector3<f64>],
        vbar: &mut [Vector3<f64>],
        g: &mut Gradient,
        step: usize,
    ) -> Result<(), DiffError> {
        let model = self.model;
        let h = settings.dt;
        let ih2 = 1.0 / (h * h);
        let c = settings.damping / h;
        for i in 0..self.n {
            self.s[i] = if model.fixed[i] {
                model.rest[i]
            } else {
                q_n[i] + v_n[i] * h + model.accel[i] * (h * h)
            };
        }
        for (k, &v) in self.sys.free.iter().enumerate() {
            self.xbar[k] = qbar[v] + vbar[v] * c;
            self.base_acc[k] = Vector3::zeros();
        }
        if let Some(sa) = self.skel.as_mut() {
            // Bone vertices after the step sit at q_R(z_{n+1}).
            for (r, &v) in self.sys.rigid.iter().enumerate() {
                sa.q_r_bar_in[r] = qbar[v] + vbar[v] * c;
            }
        }
        // q_{n+1} = x_N on free vertices; v_{n+1} = c (q_{n+1} - q_n) everywhere.
        for i in 0..self.n {
            qbar[i] = -vbar[i] * c;
            vbar[i] = Vector3::zeros();
        }
        let empty = (Vec::new(), Vec::new());
        let mut act_grad = std::mem::take(&mut g.activations[step]);
        match (self.opts.mode, replay) {
            (mode, Some(rec)) if self.skel.is_some() => {
                let implicit = mode == Mode::Implicit;
                self.skeletal_step(h, q_n, rec, activations, qbar, vbar, g, step, &mut act_grad, implicit)?;
            }
            (Mode::Unrolled, Some(rec)) => {
                let iters = rec.solves.len();
                if rec.iterates.len() != iters + 1 {
                    return Err(DiffError::Unsupported("the replay recorded no iterates".into()));
                }
                for k in (0..iters).rev() {
                    let (set, impulses) = &rec.solves[k];
                    let contacts = rec.contact_sets.get(*set).map_or(&empty.0, |c| c);
                    let x_next = &rec.iterates[k + 1];
                    self.solve_adjoint(contacts, impulses, x_next, None, qbar, q_n)?;
                    self.accumulate_solve(x_next, ih2, g);
                    Self::scatter(&self.sys, model, &rec.iterates[k], &mut self.q_full, false);
                    Self::scatter(&self.sys, model, x_next, &mut self.xn_full, false);
                    Self::scatter(&self.sys, model, &self.z, &mut self.y_full, true);
                    self.local.adjoint(
                        model,
                        &self.q_full,
                        &self.y_full,
                        Some(&self.xn_full),
                        activations,
                        rec.svds.get(k).map_or(Linearize::Recompute, |s| Linearize::Recorded(s)),
                        &mut self.out_full,
                        ParamGrads {
                            w_rot: &mut g.w_rot,
                            w_vol: &mut g.w_vol,
                            activations: &mut act_grad,
                        },
                    )?;
                    for (k2, &v) in self.sys.free.iter().enumerate() {
                        self.xbar[k2] = self.out_full[v];
                    }
                    g.stats.backward_iterations += 1;
                }
                // x_0 = s.
                for (k, &v) in self.sys.free.iter().enumerate() {
                    let sbar = self.xbar[k] + self.base_acc[k] * (model.mass[v] * ih2);
                    self.add_s_adjoint(v, sbar, h, qbar, vbar, g);
                }
            }
            (Mode::Implicit, _) => {
                let (contacts, impulses) = final_contacts.unwrap_or(&empty);
                let mut x_star = vec![Vector3::zeros(); self.nf];
                for (k, &v) in self.sys.free.iter().enumerate() {
                    x_star[k] = q_next[v];
                }
                self.local.linearize(model, q_next)?;
                self.xn_full.copy_from_slice(q_next);
                let xbar0 = self.xbar.clone();
                // Without contacts (A - K) r = x_bar is symmetric: conjugate gradients
                // preconditioned by the factored A. Falls back to the fixed point below if the
                // step's Hessian A - K is not positive definite along a search direction.
                let mut done = false;
                if contacts.is_empty() {
                    if let Some((r, iters, res)) = self.implicit_cg(model, q_next, activations, &xbar0)? {
                        self.z.copy_from_slice(&r);
                        g.stats.backward_iterations += iters;
                        g.stats.implicit_residual = g.stats.implicit_residual.max(res);
                        self.anchor_scratch.iter_mut().for_each(|a| *a = Vector3::zeros());
                        done = true;
                    }
                }
                // r = A^-T (x_bar + K r), from r = A^-T x_bar.
                let mut prev = vec![Vector3::zeros(); self.nf];
                let mut residual;
                let mut it = 0;
                if !done {
                    loop {
                        self.anchor_scratch.iter_mut().for_each(|a| *a = Vector3::zeros());
                        let mut anchors = std::mem::take(&mut self.anchor_scratch);
                        let r = self.solve_adjoint(contacts, impulses, &x_star, None, &mut anchors, q_n);
                        self.anchor_scratch = anchors;
                        r?;
                        it += 1;
                        let (mut d, mut s) = (0.0f64, 0.0f64);
                        for (a, b) in self.z.iter().zip(&prev) {
                            d = d.max((a - b).amax());
                            s = s.max(a.amax());
                        }
                        residual = if s > 0.0 { d / s } else { 0.0 };
                        prev.copy_from_slice(&self.z);
                        if residual <= self.opts.implicit_tolerance || it >= self.opts.implicit_max_iterations {
                            g.stats.backward_iterations += it;
                            g.stats.implicit_residual = g.stats.implicit_residual.max(residual);
                            fixed_point_converged(residual, it, step)?;
                            break;
                        }
                        let z = std::mem::take(&mut self.z);
                        let r = self.apply_k(model, q_next, activations, &z);
                        self.z = z;
                        r?;
                        for (k, &v) in self.sys.free.iter().enumerate() {
                            self.xbar[k] = xbar0[k] + self.out_full[v];
                        }
                    }
                }
                for (q, a) in qbar.iter_mut().zip(&self.anchor_scratch) {
                    *q += a;
                }
                // Parameter adjoints at the fixed point.
                self.accumulate_solve(&x_star, ih2, g);
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
                        activations: &mut act_grad,
                    },
                )?;
                for (k, &v) in self.sys.free.iter().enumerate() {
                    let sbar = self.base_acc[k] * (model.mass[v] * ih2);
                    self.add_s_adjoint(v, sbar, h, qbar, vbar, g);
                }
            }
            (Mode::Unrolled, None) => return Err(DiffError::Unsupported("unrolled mode needs a replay".into())),
        }
        g.activations[step] = act_grad;
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
        self.local.adjoint(
            model,
            q_next,
            &self.y_full,
            Some(&self.xn_full),
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

    /// `(A - K) r = b` by conjugate gradients preconditioned with `A^-1` (`K` the cached local
    /// linearization): the solution, iterations and final relative residual, or `None` if a
    /// direction of non-positive curvature appears (the caller then iterates the fixed point).
    #[allow(clippy::type_complexity)]
    fn implicit_cg(
        &mut self,
        model: &Model,
        q_next: &[Vector3<f64>],
        activations: &[f64],
        b: &[Vector3<f64>],
    ) -> Result<Option<(Vec<Vector3<f64>>, usize, f64)>, DiffError> {
        let nf = self.nf;
        let dot = |a: &[Vector3<f64>], b: &[Vector3<f64>]| a.iter().zip(b).map(|(x, y)| x.dot(y)).sum::<f64>();
        let bnorm = dot(b, b).sqrt();
        if bnorm == 0.0 {
            return Ok(Some((vec![Vector3::zeros(); nf], 0, 0.0)));
        }
        let mut x = vec![Vector3::zeros(); nf];
        let mut r = b.to_vec();
        let mut z = vec![Vector3::zeros(); nf];
        self.direct.solve_free(&r, &mut z)?;
        let mut p = z.clone();
        let mut rz = dot(&r, &z);
        let mut hp = vec![Vector3::zeros(); nf];
        let mut ap = vec![Vector3::zeros(); nf];
        let mut it = 0;
        let mut res = 1.0;
        while it < self.opts.implicit_max_iterations {
            it += 1;
            // hp = A p - K p.
            self.sys.apply(&p, &mut ap);
            self.apply_k(model, q_next, activations, &p)?;
            for (k, &v) in self.sys.free.iter().enumerate() {
                hp[k] = ap[k] - self.out_full[v];
            }
            let php = dot(&p, &hp);
            if php.is_nan() || php <= 0.0 {
                return Ok(None);
            }
            let alpha = rz / php;
            for k in 0..nf {
                x[k] += p[k] * alpha;
                r[k] -= hp[k] * alpha;
            }
            res = dot(&r, &r).sqrt() / bnorm;
            if res <= self.opts.implicit_tolerance {
                break;
            }
            self.direct.solve_free(&r, &mut z)?;
            let rz_new = dot(&r, &z);
            let beta = rz_new / rz;
            rz = rz_new;
            for k in 0..nf {
                p[k] = z[k] + p[k] * beta;
            }
        }
        Ok(Some((x, it, res)))
    }

    /// After `z` became the adjoint of one solve's right-hand side (solution `x_next`):
    /// accumulate it and the masses' `A` term.
    fn accumulate_solve(&mut self, x_next: &[Vector3<f64>], ih2: f64, g: &mut Gradient) {
        for (k, &v) in self.sys.free.iter().enumerate() {
            self.base_acc[k] += self.z[k];
            g.mass[v] -= self.z[k].dot(&x_next[k]) * ih2;
        }
        g.stats.contact_sweeps = self.contact.sweeps;
        g.stats.contact_residual = self.contact.worst_residual;
    }

    /// `s = q + h v + h^2 a` on a free vertex.
    fn add_s_adjoint(
        &self,
        v: usize,
        sbar: Vector3<f64>,
        h: f64,
        qbar: &mut [Vector3<f64>],
        vbar: &mut [Vector3<f64>],
        g: &mut Gradient,
    ) {
        qbar[v] += sbar;
        vbar[v] += sbar * h;
        g.accel[v] += sbar * (h * h);
    }
}

/// The loss of `steps` steps and its gradient (see the module docs).
pub fn gradient(
    model: &Model,
    settings: &Settings,
    steps: usize,
    controls: &Controls,
    loss: &dyn Loss,
    opts: Options,
) -> Result<Gradient, DiffError> {
    if steps == 0 {
        return Err(DiffError::Input("steps must be at least 1".into()));
    }
    check_supported(model, settings, opts.mode)?;
    let implicit = opts.mode == Mode::Implicit;
    let t0 = Instant::now();
    let fwd = forward(
        model,
        settings,
        steps,
        controls,
        loss,
        Keep {
            states: true,
            contacts: implicit && (!model.obstacles.is_empty() || model.collision.is_some()),
            store_bytes: if implicit { 0 } else { opts.store_bytes },
        },
    )?;
    let forward_ms = t0.elapsed().as_secs_f64() * 1e3;
    let t1 = Instant::now();
    let n = model.n();
    let groups = model.actuators.as_ref().map_or(0, |a| a.groups.len());
    let dofs = model.skeleton.as_ref().map_or(0, |s| s.dofs);
    let mut g = Gradient {
        loss: fwd.loss,
        q0: vec![Vector3::zeros(); n],
        v0: vec![Vector3::zeros(); n],
        w_rot: vec![0.0; model.tets.len()],
        w_vol: vec![0.0; model.tets.len()],
        mass: vec![0.0; n],
        accel: vec![Vector3::zeros(); n],
        attachment_targets: vec![Vector3::zeros(); model.attachments.len()],
        activations: vec![vec![0.0; groups]; steps],
        torques: vec![vec![0.0; dofs]; if dofs > 0 { steps } else { 0 }],
        joints0: vec![0.0; dofs],
        stats: DiffStats {
            forward_ms,
            forward_iterations: fwd.iterations,
            unconverged_steps: fwd.unconverged,
            ..Default::default()
        },
    };
    g.stats.stored_bytes = fwd.stored_bytes;
    g.stats.stored_steps = fwd.stored.iter().filter(|r| r.is_some()).count();
    g.stats.checkpoint_bytes = (fwd.q.len() + fwd.v.len()) * n * std::mem::size_of::<Vector3<f64>>()
        + fwd.activations.iter().map(|a| a.len() * 8).sum::<usize>()
        + fwd
            .skeleton
            .iter()
            .chain(&fwd.joints)
            .map(|a| a.len() * 8)
            .sum::<usize>()
        + fwd
            .contacts
            .iter()
            .map(|(c, l)| c.len() * std::mem::size_of::<FreeContact>() + l.len() * 24)
            .sum::<usize>();
    let mut bw = Backward::new(model, settings, opts)?;
    // Implicit mode with a skeleton replays too: it linearizes the step's last iteration.
    let mut replayer = if implicit && model.skeleton.is_none() {
        None
    } else {
        let mut sim = Simulator::new(model.clone(), settings.clone())?;
        sim.record(Some(true));
        Some(sim)
    };
    let (mut qbar, mut vbar) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]);
    for step in (0..steps).rev() {
        // The loss term of the state after this step.
        let (qs, vs) = (&fwd.q[step + 1], &fwd.v[step + 1]);
        if let (Some(sa), Some(j)) = (bw.skel.as_mut(), fwd.joints.get(step)) {
            loss.joint_term(model, step + 1, steps, j, &mut sa.z_bar);
        }
        loss.term(
            model,
            step + 1,
            steps,
            qs,
            vs,
            LossGrad {
                q: &mut qbar,
                v: &mut vbar,
                mass: &mut g.mass,
            },
        );
        let tr = Instant::now();
        let stored = fwd.stored.get(step).and_then(|r| r.as_ref());
        if let (Some(sim), None) = (replayer.as_mut(), stored) {
            sim.set_state(fwd.q[step].clone(), fwd.v[step].clone())?;
            if let Some(st) = fwd.skeleton.get(step) {
                sim.set_skeleton_state(st)?;
            }
            set_controls(sim, model, controls, step)?;
            sim.set_clock(fwd.time[step], step);
            if let Some(act) = &model.actuators {
                for (grp, a) in act.groups.iter().zip(&fwd.activations[step]) {
                    sim.set_activation(&grp.name, *a)?;
                }
            }
            sim.step()?;
            let dev = sim
                .state()
                .q
                .iter()
                .zip(&fwd.q[step + 1])
                .map(|(a, b)| (a - b).amax())
                .fold(0.0, f64::max);
            g.stats.replay_deviation = g.stats.replay_deviation.max(dev);
        }
        g.stats.replay_ms += tr.elapsed().as_secs_f64() * 1e3;
        let rec = stored.or_else(|| replayer.as_ref().and_then(|s| s.recording()));
        bw.step(
            settings,
            &fwd.q[step],
            &fwd.v[step],
            &fwd.q[step + 1],
            &fwd.activations[step],
            rec,
            fwd.contacts.get(step),
            &mut qbar,
            &mut vbar,
            &mut g,
            step,
        )?;
    }
    g.q0 = qbar;
    g.v0 = vbar;
    if let Some(sa) = bw.skel.as_ref() {
        g.joints0.copy_from_slice(&sa.z_bar);
    }
    g.stats.backward_ms = t1.elapsed().as_secs_f64() * 1e3;
    g.stats.contact_ms = bw.contact_ms;
    Ok(g)
}
