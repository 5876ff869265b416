//! A running simulation: the model, the state, the assembled and factored global system, the
//! constraint sets' buffers and every per-step buffer, allocated once in [`Simulator::new`].
//! The step itself is in `step.rs`; this file sets it up and holds the API around it.

use nalgebra::Vector3;

use super::anderson::Anderson;
use super::certify::{self, Certificate};
use super::choose;
use super::contacts::StepContacts;
use super::direct::Direct;
use super::global::{GlobalSolver, InnerControl, SolverKind};
use super::integrator::{Integrator, Scheme};
use super::skeletal::Skeletal;
use super::stationary::Stationary;
use super::system::GlobalSystem;
use super::{Settings, SolverError, State};
use crate::base::Choice;
use crate::constraint::Constraints;
use crate::model::Model;
use crate::skeleton::Skeleton;

/// The global step: any global solver on the free vertices, or with a skeleton the reduced step
/// (Eqs. 7-8, 17-18), which needs the direct solver of the free block by type.
pub(crate) enum GlobalStep {
    /// Any [`GlobalSolver`].
    Free(Box<dyn GlobalSolver>),
    /// The skeleton's reduced step on the factored free block.
    Skeletal {
        /// Sparse Cholesky of the free block.
        direct: Box<Direct>,
        /// Schur complement and buffers of the reduced step.
        reduced: Box<Skeletal>,
        /// With `solver: newton`: Newton's method in the reduced coordinates
        /// (`newton_skeletal.rs`); `None`: local-global iterations.
        newton: Option<Box<super::newton_skeletal::NewtonSkeletal>>,
    },
}

impl GlobalStep {
    /// Which solver runs.
    pub(crate) fn kind(&self) -> SolverKind {
        match self {
            GlobalStep::Free(s) => s.kind(),
            GlobalStep::Skeletal { newton: Some(_), .. } => SolverKind::Newton,
            GlobalStep::Skeletal { .. } => SolverKind::Direct,
        }
    }

    /// The contact impulses of the last solve (see [`GlobalSolver::impulses`]).
    pub(crate) fn impulses(&self) -> Option<&[Vector3<f64>]> {
        match self {
            GlobalStep::Free(s) => s.impulses(),
            GlobalStep::Skeletal { direct, .. } => direct.impulses(),
        }
    }

    /// The contact impulses of the last solve for output (see
    /// [`GlobalSolver::contact_impulses`]).
    pub(crate) fn contact_impulses(&self) -> Option<&[Vector3<f64>]> {
        match self {
            GlobalStep::Free(s) => s.contact_impulses(),
            GlobalStep::Skeletal { direct, .. } => direct.contact_impulses(),
        }
    }
}

/// Per-step buffers of the iterations (full numbering unless noted).
#[derive(Debug, Clone)]
pub(crate) struct Work {
    /// Positions at the start of the step.
    pub q_start: Vec<Vector3<f64>>,
    /// The inertial target `s_n` (Eq. 2).
    pub s: Vec<Vector3<f64>>,
    /// The current iterate on every vertex (fixed and bone vertices included).
    pub full: Vec<Vector3<f64>>,
    /// `J p` of the last local step.
    pub gathered: Vec<Vector3<f64>>,
    /// Free: the right-hand side's constant part `M s / h^2 + fixed pull + attachments`.
    pub base: Vec<Vector3<f64>>,
    /// Free: the global step's right-hand side.
    pub rhs: Vec<Vector3<f64>>,
    /// Free: the iterate.
    pub x: Vec<Vector3<f64>>,
    /// Free: the previous iterate.
    pub x_prev: Vec<Vector3<f64>>,
    /// Free: scratch of the Anderson mixing.
    pub x_plain: Vec<Vector3<f64>>,
    /// Bone vertices: the right-hand side and the positions of the reduced step.
    pub b_rigid: Vec<Vector3<f64>>,
    /// Bone vertices: their positions after the reduced step.
    pub q_rigid: Vec<Vector3<f64>>,
    /// Joint scalars at the start of the step and joint torques (skeleton DoF layout).
    pub coords0: Vec<f64>,
    /// Joint torques of the step.
    pub torque: Vec<f64>,
}

/// The state one step before the current one, which BDF2 reads (docs/method.md Eq. T1).
#[derive(Debug, Clone, Default)]
pub(crate) struct PreviousState {
    /// Positions `q_{n-1}` (empty for implicit Euler).
    pub q: Vec<Vector3<f64>>,
    /// Velocities `v_{n-1}`.
    pub v: Vec<Vector3<f64>>,
    /// Whether `q`, `v` hold the state before the current one (false at the start and after
    /// the state was replaced).
    pub valid: bool,
}

/// A global system built for the scheme not in use, swapped in when the scheme changes.
pub(crate) struct Alternate {
    scheme: Scheme,
    system: GlobalSystem,
    global: GlobalStep,
    certificate: Certificate,
}

/// A running simulation.
pub struct Simulator {
    pub(crate) model: Model,
    pub(crate) settings: Settings,
    /// The scheme the global system below is built for (BDF2's first step: implicit Euler).
    pub(crate) integrator: Scheme,
    pub(crate) state: State,
    /// BDF2: the state one step before `state` (empty for implicit Euler).
    pub(crate) previous: PreviousState,
    /// BDF2: the other scheme's system, solver and certificate, kept once built (its first step
    /// runs implicit Euler, whose matrix differs).
    pub(crate) alternate: Option<Box<Alternate>>,
    pub(crate) system: GlobalSystem,
    pub(crate) global: GlobalStep,
    pub(crate) certificate: Certificate,
    pub(crate) constraints: Constraints,
    /// Activation of each actuator group in the current step.
    pub(crate) activations: Vec<f64>,
    /// Activations set through the API, per actuator group (`None`: follow the schedule).
    pub(crate) activation_override: Vec<Option<f64>>,
    /// The skeleton's current state (joint coordinates).
    pub(crate) skeleton: Option<Skeleton>,
    pub(crate) contacts: StepContacts,
    pub(crate) work: Work,
    /// Anderson acceleration of the local-global iteration.
    pub(crate) anderson: Option<Anderson>,
    pub(crate) energy_scale: f64,
}

impl std::fmt::Debug for Simulator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Simulator")
            .field("vertices", &self.model.n())
            .field("tets", &self.model.tets.len())
            .field("solver", &self.global.kind())
            .field("step", &self.state.step)
            .finish()
    }
}

/// Certify the requested solver for `system` and build the global step.
fn build_global(
    model: &Model,
    settings: &Settings,
    system: &GlobalSystem,
    h: f64,
) -> Result<(GlobalStep, Certificate), SolverError> {
    if model.collision.is_some() && model.skeleton.is_some() {
        return Err(SolverError::input(
            "collisions between bodies with a skeleton are not supported yet (bone vertices in a pair contact)",
        ));
    }
    let control = InnerControl {
        tolerance: settings.inner_tolerance * model.length_scale,
        max_iterations: settings.inner_max_iterations,
    };
    if settings.solver == SolverKind::Newton {
        return super::newton::build(model, settings, system, control);
    }
    let (cert, factored) = certify_global(model, settings, system, h, control)?;
    let global = match (&model.skeleton, cert.used) {
        (Some(sk), _) => {
            let direct = Box::new(Direct::new(system, control)?);
            let reduced = Box::new(Skeletal::new(system, &direct, sk));
            GlobalStep::Skeletal {
                direct,
                reduced,
                newton: None,
            }
        }
        (None, SolverKind::Direct) => GlobalStep::Free(Box::new(match factored {
            Some(d) => d,
            None => Direct::new(system, control)?,
        })),
        (None, kind) => GlobalStep::Free(Box::new(Stationary::new(
            system,
            if kind == SolverKind::Chebyshev {
                SolverKind::Split
            } else {
                kind
            },
            cert.relaxation,
            cert.contact_relaxation,
            cert.chebyshev_rho,
            control,
        ))),
    };
    Ok((global, cert))
}

/// The direct solver's certificate when `why` forces it on a run that requested another.
fn forced_direct(settings: &Settings, system: &GlobalSystem, h: f64, why: &str) -> Result<Certificate, SolverError> {
    let mut c = certify::certify(
        system,
        h,
        SolverKind::Direct,
        settings.certify,
        settings.eigen_method,
        0,
    )?;
    c.requested = settings.solver;
    c.message = format!("{:?} requested, but {why}: direct sparse Cholesky", settings.solver);
    Ok(c)
}

/// Certify the requested solver (auto: choose it); with auto's choice of direct, its factor.
fn certify_global(
    model: &Model,
    settings: &Settings,
    system: &GlobalSystem,
    h: f64,
    control: InnerControl,
) -> Result<(Certificate, Option<Direct>), SolverError> {
    let requested = settings.solver;
    if model.collision.is_some() && requested != SolverKind::Direct {
        // A contact between two bodies couples several vertices through one impulse: the
        // projected Gauss-Seidel runs on the factored matrix's Delassus operator.
        let why = "contacts between bodies couple several vertices per impulse";
        return Ok((forced_direct(settings, system, h, why)?, None));
    }
    if model.skeleton.is_some() && requested != SolverKind::Direct {
        // The reduced step (Eqs. 17-18) eliminates the free vertices with the factored free
        // block, so a skeleton always runs on the direct solver; no eigenvalue check is needed.
        let why = "the skeleton's reduced step (Eqs. 17-18) factors the free block";
        return Ok((forced_direct(settings, system, h, why)?, None));
    }
    if requested == SolverKind::Auto {
        let base = Certificate::unchecked(requested, settings.certify, h);
        return choose::choose(
            system,
            h,
            base,
            settings.eigen_method,
            settings.inner_tolerance,
            control,
        );
    }
    let cert = certify::certify(
        system,
        h,
        requested,
        settings.certify,
        settings.eigen_method,
        settings.inner_max_iterations,
    )?;
    Ok((cert, None))
}

impl Simulator {
    /// Set up a simulation from the model's initial state (rest positions, initial velocities).
    pub fn new(model: Model, settings: Settings) -> Result<Self, SolverError> {
        settings.validate()?;
        // BDF2 runs its own scheme from the second step on: build that system first (its
        // certificate is the run's), the first step's implicit Euler when it is taken.
        let scheme = Scheme::for_step(
            settings.integrator,
            settings.dt,
            settings.damping,
            settings.integrator == Integrator::Bdf2,
        );
        let system = GlobalSystem::new(&model, scheme.h_e())?;
        let (global, certificate) = build_global(&model, &settings, &system, scheme.h_e())?;
        let n = model.n();
        let nf = system.n();
        let nr = system.rigid.len();
        let state = State {
            q: model.rest.clone(),
            v: model.initial_velocity.clone(),
            time: 0.0,
            step: 0,
        };
        let g = model.accel.iter().map(|a| a.norm()).fold(0.0, f64::max);
        let total_mass: f64 = model.mass.iter().sum();
        let v0 = state.v.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let e_scale = total_mass * (g * model.length_scale + v0 * v0) + model.w_rot.iter().sum::<f64>() * 1e-6;
        let dofs = model.skeleton.as_ref().map_or(0, |sk| sk.dofs);
        let groups = model.actuators.as_ref().map_or(0, |a| a.groups.len());
        Ok(Self {
            integrator: scheme,
            previous: if settings.integrator == Integrator::Bdf2 {
                PreviousState {
                    q: vec![Vector3::zeros(); n],
                    v: vec![Vector3::zeros(); n],
                    valid: false,
                }
            } else {
                PreviousState::default()
            },
            alternate: None,
            activation_override: vec![None; groups],
            constraints: Constraints::new(&model),
            activations: model
                .actuators
                .as_ref()
                .map_or(Vec::new(), |a| a.groups.iter().map(|g| g.activation.at(0.0)).collect()),
            contacts: StepContacts::new(&model),
            work: Work {
                q_start: vec![Vector3::zeros(); n],
                s: vec![Vector3::zeros(); n],
                full: vec![Vector3::zeros(); n],
                gathered: vec![Vector3::zeros(); n],
                base: vec![Vector3::zeros(); nf],
                rhs: vec![Vector3::zeros(); nf],
                x: vec![Vector3::zeros(); nf],
                x_prev: vec![Vector3::zeros(); nf],
                x_plain: vec![Vector3::zeros(); nf],
                b_rigid: vec![Vector3::zeros(); nr],
                q_rigid: vec![Vector3::zeros(); nr],
                coords0: vec![0.0; dofs],
                torque: vec![0.0; dofs],
            },
            skeleton: model.skeleton.clone(),
            anderson: (settings.anderson > 0).then(|| Anderson::new(settings.anderson, nf)),
            energy_scale: e_scale.max(f64::MIN_POSITIVE),
            model,
            settings,
            state,
            system,
            global,
            certificate,
        })
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The current state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// Replace the state (positions and velocities must have the model's vertex count).
    pub fn set_state(&mut self, q: Vec<Vector3<f64>>, v: Vec<Vector3<f64>>) -> Result<(), SolverError> {
        self.set_state_from(&q, &v)
    }

    /// Replace the state by copies of `q` and `v` (no allocation).
    pub fn set_state_from(&mut self, q: &[Vector3<f64>], v: &[Vector3<f64>]) -> Result<(), SolverError> {
        if q.len() != self.model.n() || v.len() != self.model.n() {
            return Err(SolverError::input(format!(
                "state has {} positions and {} velocities, the model {} vertices",
                q.len(),
                v.len(),
                self.model.n()
            )));
        }
        if !q.iter().chain(v).all(|x| x.iter().all(|c| c.is_finite())) {
            return Err(SolverError::input("state has non-finite entries"));
        }
        self.state.q.copy_from_slice(q);
        self.state.v.copy_from_slice(v);
        // A new state has no history: BDF2's next step is implicit Euler (or see
        // `set_previous_state`).
        self.previous.valid = false;
        Ok(())
    }

    /// BDF2: set the state one step before the current one (positions and velocities), so the
    /// next step is a BDF2 step rather than the implicit Euler step that starts a run. Call it
    /// after [`Simulator::set_state`] (which forgets the earlier state); an error under
    /// implicit Euler, which reads no earlier state.
    pub fn set_previous_state(&mut self, q: &[Vector3<f64>], v: &[Vector3<f64>]) -> Result<(), SolverError> {
        if self.settings.integrator != Integrator::Bdf2 {
            return Err(SolverError::input(format!(
                "set_previous_state: the integrator is {}, which reads no earlier state",
                self.settings.integrator.name()
            )));
        }
        if q.len() != self.model.n() || v.len() != self.model.n() {
            return Err(SolverError::input(format!(
                "previous state has {} positions and {} velocities, the model {} vertices",
                q.len(),
                v.len(),
                self.model.n()
            )));
        }
        if !q.iter().chain(v).all(|x| x.iter().all(|c| c.is_finite())) {
            return Err(SolverError::input("previous state has non-finite entries"));
        }
        self.previous.q.copy_from_slice(q);
        self.previous.v.copy_from_slice(v);
        self.previous.valid = true;
        Ok(())
    }

    /// BDF2: the state one step before the current one, `(positions, velocities)`, once a step
    /// was taken (`None` under implicit Euler and at the start of a run).
    pub fn previous_state(&self) -> super::integrator::Previous<'_> {
        self.previous
            .valid
            .then_some((&self.previous.q[..], &self.previous.v[..]))
    }

    /// Make the built system match the scheme of the next step (BDF2: implicit Euler without an
    /// earlier state, BDF2 with one), swapping in the other system or building it once.
    pub(crate) fn prepare_scheme(&mut self) -> Result<(), SolverError> {
        let s = &self.settings;
        let want = Scheme::for_step(s.integrator, s.dt, s.damping, self.previous.valid);
        if want == self.integrator {
            return Ok(());
        }
        let alt = match self.alternate.take() {
            Some(a) if a.scheme == want => a,
            _ => {
                let system = GlobalSystem::new(&self.model, want.h_e())?;
                let (global, certificate) = build_global(&self.model, &self.settings, &system, want.h_e())?;
                Box::new(Alternate {
                    scheme: want,
                    system,
                    global,
                    certificate,
                })
            }
        };
        let mut alt = alt;
        std::mem::swap(&mut self.integrator, &mut alt.scheme);
        std::mem::swap(&mut self.system, &mut alt.system);
        std::mem::swap(&mut self.global, &mut alt.global);
        std::mem::swap(&mut self.certificate, &mut alt.certificate);
        self.alternate = Some(alt);
        Ok(())
    }

    /// Set joint coordinates (by bone name) and move the bone vertices with them; free vertices
    /// stay where they are.
    pub fn set_joint_coordinates(&mut self, bone: &str, c: &[f64]) -> Result<(), SolverError> {
        let sk = self
            .skeleton
            .as_mut()
            .ok_or_else(|| SolverError::input("the model has no skeleton"))?;
        let b = sk
            .bones
            .iter_mut()
            .find(|b| b.name == bone)
            .ok_or_else(|| SolverError::input(format!("no bone named '{bone}'")))?;
        if c.len() != b.joint.coordinates().len() || !c.iter().all(|v| v.is_finite()) {
            return Err(SolverError::input(format!(
                "bone '{bone}': expected {} finite coordinates, got {c:?}",
                b.joint.coordinates().len()
            )));
        }
        b.joint.set_coordinates(c);
        let mut q = vec![Vector3::zeros(); sk.rigid.len()];
        sk.positions(&mut q);
        for (k, &v) in sk.rigid.iter().enumerate() {
            self.state.q[v] = q[k];
        }
        Ok(())
    }

    /// Set the activation of actuator group `name` from the next step on (overrides its
    /// schedule until [`Simulator::follow_schedule`]); `a > 0` for pneumatic groups, `a` in
    /// `[0, 1]` for muscles.
    pub fn set_activation(&mut self, name: &str, a: f64) -> Result<(), SolverError> {
        let act = self
            .model
            .actuators
            .as_ref()
            .ok_or_else(|| SolverError::input("the model has no actuators"))?;
        let g = act
            .group(name)
            .ok_or_else(|| SolverError::input(format!("no actuator group named '{name}'")))?;
        self.set_activation_of(g, a)
    }

    /// [`Simulator::set_activation`] by group index (no lookup, no allocation).
    pub fn set_activation_of(&mut self, group: usize, a: f64) -> Result<(), SolverError> {
        let act = self
            .model
            .actuators
            .as_ref()
            .ok_or_else(|| SolverError::input("the model has no actuators"))?;
        let g = act
            .groups
            .get(group)
            .ok_or_else(|| SolverError::input(format!("no actuator group {group}")))?;
        if !g.kind.admits(a) {
            return Err(SolverError::input(format!(
                "actuator '{}': activation {a} out of range ({})",
                g.name,
                g.kind.range()
            )));
        }
        self.activation_override[group] = Some(a);
        Ok(())
    }

    /// Let actuator group `name` follow its schedule again.
    pub fn follow_schedule(&mut self, name: &str) -> Result<(), SolverError> {
        let g = self
            .model
            .actuators
            .as_ref()
            .and_then(|a| a.group(name))
            .ok_or_else(|| SolverError::input(format!("no actuator group named '{name}'")))?;
        self.activation_override[g] = None;
        Ok(())
    }

    /// The activations used by the last step, per group (`None` without actuators).
    pub fn activations(&self) -> Option<&[f64]> {
        self.model.actuators.as_ref().map(|_| self.activations.as_slice())
    }

    /// Set the simulated time and step counter (with [`Simulator::set_state`], to replay a step).
    pub fn set_clock(&mut self, time: f64, step: usize) {
        self.state.time = time;
        self.state.step = step;
    }

    /// The raw joint state of the skeleton (see [`crate::skeleton::Skeleton::save_state`]), if
    /// the model has one.
    pub fn skeleton_state(&self) -> Option<Vec<f64>> {
        self.skeleton.as_ref().map(|sk| {
            let mut s = Vec::new();
            sk.save_state(&mut s);
            s
        })
    }

    /// Append the raw joint state to `out` (see [`Simulator::skeleton_state`]); nothing without
    /// a skeleton.
    pub fn save_skeleton_state(&self, out: &mut Vec<f64>) {
        if let Some(sk) = &self.skeleton {
            sk.save_state(out);
        }
    }

    /// Restore a joint state saved by [`Simulator::skeleton_state`]; the bone vertices' positions
    /// are set separately with [`Simulator::set_state`].
    pub fn set_skeleton_state(&mut self, s: &[f64]) -> Result<(), SolverError> {
        let sk = self
            .skeleton
            .as_mut()
            .ok_or_else(|| SolverError::input("the model has no skeleton"))?;
        Ok(sk.load_state(s)?)
    }

    /// Set the torque on the one-DoF joint of bone `bone` from the next step on (`None`: follow
    /// its schedule again).
    pub fn set_torque(&mut self, bone: &str, value: Option<f64>) -> Result<(), SolverError> {
        let sk = self
            .skeleton
            .as_mut()
            .ok_or_else(|| SolverError::input("the model has no skeleton"))?;
        let dof = sk.scalar_dof(bone)?;
        Ok(sk.set_torque(dof, value)?)
    }

    /// Set the torque on reduced coordinate `dof` (a one-DoF joint's) from the next step on.
    pub fn set_torque_dof(&mut self, dof: usize, value: Option<f64>) -> Result<(), SolverError> {
        let sk = self
            .skeleton
            .as_mut()
            .ok_or_else(|| SolverError::input("the model has no skeleton"))?;
        Ok(sk.set_torque(dof, value)?)
    }

    /// The skeleton's current state, if the model has one.
    pub fn skeleton(&self) -> Option<&Skeleton> {
        self.skeleton.as_ref()
    }

    /// The certification outcome (which solver runs and why).
    pub fn certificate(&self) -> &Certificate {
        &self.certificate
    }

    /// Change the time step: rebuilds, re-certifies and refactors the global system. Under
    /// BDF2 only before the first step or after [`Simulator::set_state`] (its formula assumes
    /// a constant step).
    pub fn set_dt(&mut self, dt: f64) -> Result<(), SolverError> {
        if self.previous.valid && dt != self.settings.dt {
            return Err(SolverError::input(format!(
                "set_dt: BDF2 assumes a constant time step, and this run has taken steps of {} s; change dt before the first step or after set_state (which restarts BDF2 with an implicit Euler step)",
                self.settings.dt
            )));
        }
        let mut s = self.settings.clone();
        s.dt = dt;
        s.validate()?;
        let scheme = Scheme::for_step(s.integrator, s.dt, s.damping, s.integrator == Integrator::Bdf2);
        let system = GlobalSystem::new(&self.model, scheme.h_e())?;
        let (global, cert) = build_global(&self.model, &s, &system, scheme.h_e())?;
        self.integrator = scheme;
        self.alternate = None;
        self.settings = s;
        self.system = system;
        self.global = global;
        self.certificate = cert;
        Ok(())
    }
}
