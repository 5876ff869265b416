//! A running simulation: the model, the state, the assembled and factored global system, the
//! constraint sets' buffers and every per-step buffer, allocated once in [`Simulator::new`].
//! The step itself is in `step.rs`; this file sets it up and holds the API around it.

use nalgebra::Vector3;

use super::certificate::Certificate;
use super::contacts::StepContacts;
use super::integrator::{Integrator, Scheme};
use super::iteration::{self, StepIteration};
use std::sync::Arc;

use super::system::{System, Systems};
use super::work::{PreviousState, Work};
use super::{Settings, SolverError, State};
use crate::base::Choice;
use crate::constraint::Constraints;
use crate::model::Model;
use crate::skeleton::Skeleton;

/// The state a step is replayed from ([`Simulator::restore`]): what the forward pass
/// checkpointed before it.
pub(crate) struct Checkpoint<'a> {
    /// Positions and velocities before the step.
    pub q: &'a [Vector3<f64>],
    /// Velocities before the step.
    pub v: &'a [Vector3<f64>],
    /// BDF2: the state one step earlier (`None`: the step is the run's first, implicit Euler).
    pub previous: super::integrator::Previous<'a>,
    /// The skeleton's raw joint state before the step (`None` without a skeleton).
    pub skeleton: Option<&'a [f64]>,
    /// Simulated time and steps taken before the step.
    pub time: f64,
    /// Steps taken before the step.
    pub step: usize,
    /// The activation of each actuator group the step used.
    pub activations: &'a [f64],
}

/// A global system built for the scheme not in use, swapped in when the scheme changes.
pub(crate) struct Alternate {
    scheme: Scheme,
    system: Arc<System>,
    iteration: Box<dyn StepIteration>,
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
    /// The global system of the current scheme (shared with the backward pass and replays).
    pub(crate) system: Arc<System>,
    /// Where this run's systems come from and go (shared with runs of the same model).
    pub(crate) systems: Systems,
    /// The method that solves each contact round of a step (local-global or Newton).
    pub(crate) iteration: Box<dyn StepIteration>,
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
    pub(crate) energy_scale: f64,
}

impl std::fmt::Debug for Simulator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Simulator")
            .field("vertices", &self.model.n())
            .field("tets", &self.model.tets.len())
            .field("solver", &self.iteration.kind())
            .field("step", &self.state.step)
            .finish()
    }
}

impl Simulator {
    /// Set up a simulation from the model's initial state (rest positions, initial velocities):
    /// assemble, certify and factor its global system.
    ///
    /// ```
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Settings, Simulator};
    ///
    /// let mesh = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1]).build()?;
    /// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
    /// let model = ModelBuilder::new()
    ///     .gravity(nalgebra::Vector3::new(0.0, -9.81, 0.0))
    ///     .body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0)))
    ///     .build()?;
    /// let mut sim = Simulator::new(model, Settings::default())?;
    /// let stats = sim.step()?;
    /// assert!(stats.converged && sim.state().q[0].y < 0.0);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(model: Model, settings: Settings) -> Result<Self, SolverError> {
        Self::with_systems(model, settings, &Systems::new())
    }

    /// [`Simulator::new`] taking its global systems from `systems` where one was built for an
    /// identical matrix (its factor and certificates with it) and leaving the ones it builds
    /// there: runs of the same model share the set-up (a sweep over solver settings, the
    /// repeated runs of a finite-difference check).
    ///
    /// ```
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::solver::Systems;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Settings, Simulator};
    ///
    /// let mesh = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1]).build()?;
    /// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
    /// let model = ModelBuilder::new()
    ///     .body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0)))
    ///     .build()?;
    /// let systems = Systems::new();
    /// let a = Simulator::with_systems(model.clone(), Settings::default(), &systems)?;
    /// let b = Simulator::with_systems(model, Settings::default(), &systems)?;
    /// assert_eq!(systems.len(), 1);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn with_systems(model: Model, settings: Settings, systems: &Systems) -> Result<Self, SolverError> {
        settings.validate()?;
        let system = systems.get(&model, Self::first_scheme(&settings).h_e())?;
        Self::with_system(model, settings, systems, system)
    }

    /// The scheme a run is set up for: BDF2 runs its own scheme from the second step on, so its
    /// system is built first (its certificate is the run's), the first step's implicit Euler
    /// when that step is taken.
    fn first_scheme(settings: &Settings) -> Scheme {
        Scheme::for_step(
            settings.integrator,
            settings.dt,
            settings.damping,
            settings.integrator == Integrator::Bdf2,
        )
    }

    /// A fresh simulator of the same model and settings on this one's systems (no assembly,
    /// factorisation or certification: the systems keep theirs): the backward pass replays
    /// steps from their checkpoints on one. It keeps this run's energy scale (the divergence
    /// check's, [`Simulator::start_from`]), so a replayed step is judged as the forward's was.
    pub(crate) fn replayer(&self) -> Result<Self, SolverError> {
        let scheme = Self::first_scheme(&self.settings);
        let system = match self.system_for(scheme.h_e()) {
            Some(s) => s,
            None => self.systems.get(&self.model, scheme.h_e())?,
        };
        let mut replayer = Self::with_system(self.model.clone(), self.settings.clone(), &self.systems, system)?;
        replayer.energy_scale = self.energy_scale;
        Ok(replayer)
    }

    /// The system this run built for step `h_e`, if it built one (the current scheme's or the
    /// other scheme's of BDF2).
    pub(crate) fn system_for(&self, h_e: f64) -> Option<Arc<System>> {
        if self.system.h().to_bits() == h_e.to_bits() {
            return Some(Arc::clone(&self.system));
        }
        self.alternate
            .as_ref()
            .filter(|a| a.system.h().to_bits() == h_e.to_bits())
            .map(|a| Arc::clone(&a.system))
    }

    /// The systems this run takes its global systems from.
    pub(crate) fn systems(&self) -> &Systems {
        &self.systems
    }

    /// Set up on `system` (assembled for the first scheme's step).
    fn with_system(
        model: Model,
        settings: Settings,
        systems: &Systems,
        system: Arc<System>,
    ) -> Result<Self, SolverError> {
        settings.validate()?;
        check_initial_state(&model, model.rest())?;
        let scheme = Self::first_scheme(&settings);
        let (iteration, certificate) = iteration::build(&model, &settings, &system)?;
        let n = model.n();
        let nf = system.n();
        let nr = system.rigid.len();
        let state = State {
            q: model.rest.clone(),
            v: model.initial_velocity.clone(),
            time: 0.0,
            step: 0,
        };
        let e_scale = energy_scale(&model, &state.v);
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
            energy_scale: e_scale,
            model,
            settings,
            state,
            system,
            systems: systems.clone(),
            iteration,
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

    /// Replace the state (positions and velocities must have the model's vertex count). The
    /// run then starts from it: the divergence check's energy scale takes its velocities in, as
    /// it takes the model's initial velocities.
    pub fn set_state(&mut self, q: Vec<Vector3<f64>>, v: Vec<Vector3<f64>>) -> Result<(), SolverError> {
        self.start_from(&q, &v)
    }

    /// [`Simulator::set_state_from`] for a state a run starts from (not a checkpoint of its
    /// own): the energy scale of the divergence check (a step whose kinetic energy exceeds
    /// 1e8 times it is refused as diverged) grows to count the state's velocities, as it counts
    /// the model's initial velocities, so a body thrown faster than the model's own initial
    /// velocities is not refused for its own kinetic energy.
    pub(crate) fn start_from(&mut self, q: &[Vector3<f64>], v: &[Vector3<f64>]) -> Result<(), SolverError> {
        self.set_state_from(q, v)?;
        self.energy_scale = self.energy_scale.max(energy_scale(&self.model, v));
        Ok(())
    }

    /// Start the run from `q` and `v` instead of the model's rest positions and initial
    /// velocities: the positions get the obstacle checks of a model's own initial state
    /// ([`check_initial_positions`]), then [`Simulator::set_state_from`]. A state the run itself reached (a
    /// checkpoint) is restored with [`Simulator::set_state_from`] alone.
    pub fn set_initial_state(&mut self, q: &[Vector3<f64>], v: &[Vector3<f64>]) -> Result<(), SolverError> {
        self.check_state(q, v)?;
        check_initial_positions(&self.model, q)?;
        self.start_from(q, v)
    }

    /// Positions and velocities with the model's vertex count, finite.
    fn check_state(&self, q: &[Vector3<f64>], v: &[Vector3<f64>]) -> Result<(), SolverError> {
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
        Ok(())
    }

    /// Replace the state by copies of `q` and `v` (no allocation), keeping the divergence
    /// check's energy scale: for a state the run itself reached (a checkpoint). A state a run
    /// starts from goes through [`Simulator::set_state`] or [`Simulator::set_initial_state`].
    pub fn set_state_from(&mut self, q: &[Vector3<f64>], v: &[Vector3<f64>]) -> Result<(), SolverError> {
        self.check_state(q, v)?;
        self.state.q.copy_from_slice(q);
        self.state.v.copy_from_slice(v);
        // A new state has no history: BDF2's next step is implicit Euler (or see
        // `set_previous_state`).
        self.previous.valid = false;
        Ok(())
    }

    /// Put the run where the forward pass was before a step: state, earlier state (BDF2), joint
    /// state, clock and the step's activations, in one call.
    pub(crate) fn restore(&mut self, c: Checkpoint<'_>) -> Result<(), SolverError> {
        self.set_state_from(c.q, c.v)?;
        if let Some((q, v)) = c.previous {
            self.set_previous_state(q, v)?;
        }
        if let Some(st) = c.skeleton {
            self.set_skeleton_state(st)?;
        }
        self.set_clock(c.time, c.step);
        for (g, a) in c.activations.iter().enumerate() {
            self.set_activation_of(g, *a)?;
        }
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
                let system = self.systems.get(&self.model, want.h_e())?;
                let (iteration, certificate) = iteration::build(&self.model, &self.settings, &system)?;
                Box::new(Alternate {
                    scheme: want,
                    system,
                    iteration,
                    certificate,
                })
            }
        };
        let mut alt = alt;
        std::mem::swap(&mut self.integrator, &mut alt.scheme);
        std::mem::swap(&mut self.system, &mut alt.system);
        std::mem::swap(&mut self.iteration, &mut alt.iteration);
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
        let g = act.group(name).ok_or_else(|| {
            let names: Vec<&str> = act.groups.iter().map(|g| g.name.as_str()).collect();
            let shown = if names.len() > 12 {
                format!("{}, ... ({} groups)", names[..12].join(", "), names.len())
            } else {
                names.join(", ")
            };
            SolverError::input(format!("no actuator group named '{name}' (the groups: {shown})"))
        })?;
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
                "actuator '{}': activation {} out of range ({})",
                g.name,
                crate::base::number(a),
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

    /// Change the time step (the velocity damping per second kept, [`Settings::with_dt`]):
    /// rebuilds, re-certifies and refactors the global system. Under
    /// BDF2 only before the first step or after [`Simulator::set_state`] (its formula assumes
    /// a constant step).
    pub fn set_dt(&mut self, dt: f64) -> Result<(), SolverError> {
        if self.previous.valid && dt != self.settings.dt {
            return Err(SolverError::input(format!(
                "set_dt: BDF2 assumes a constant time step, and this run has taken steps of {} s; change dt before the first step or after set_state (which restarts BDF2 with an implicit Euler step)",
                self.settings.dt
            )));
        }
        // The damping per second stays (Settings::with_dt).
        let s = self.settings.with_dt(dt);
        s.validate()?;
        let scheme = Scheme::for_step(s.integrator, s.dt, s.damping, s.integrator == Integrator::Bdf2);
        let system = self.systems.get(&self.model, scheme.h_e())?;
        let (iteration, cert) = iteration::build(&self.model, &s, &system)?;
        self.integrator = scheme;
        self.alternate = None;
        self.settings = s;
        self.system = system;
        self.iteration = iteration;
        self.certificate = cert;
        Ok(())
    }
}

/// The obstacle checks [`Simulator::new`] makes on a model's rest positions, for positions `q`
/// a run is to start from instead (no vertex inside an obstacle deeper than 1e-6 of the length
/// scale, no edge through one): what a caller that sets a run's initial positions (Python's
/// `set("initial_positions")`) runs before the run. Overlap between bodies is not checked here:
/// a state a run itself reached (a soft ball folded against a cloth) can fail the point-in-tet
/// test of [`Simulator::new`] while its surfaces do not cross, and continuing a run from its
/// last state must work. [`Controls::initial`] is not checked by the rollout itself:
/// finite-difference checks perturb a start that touches the ground on purpose. The error names
/// the positions, the body, its vertex and the obstacle.
///
/// [`Controls::initial`]: crate::diff::Controls::initial
///
/// ```
/// use diffsoft::solver::check_initial_positions;
///
/// let model = diffsoft::testing::ground_contact(1)?.model;
/// assert!(check_initial_positions(&model, model.rest()).is_ok());
/// let sunk: Vec<_> = model.rest().iter().map(|q| q - nalgebra::Vector3::new(0.0, 5.0, 0.0)).collect();
/// let e = check_initial_positions(&model, &sunk).unwrap_err().to_string();
/// assert!(e.contains("the initial positions given") && e.contains("inside obstacle 'ground'"), "{e}");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn check_initial_positions(model: &Model, q: &[Vector3<f64>]) -> Result<(), SolverError> {
    if q.len() != model.n() || !q.iter().all(|x| x.iter().all(|c| c.is_finite())) {
        return Err(SolverError::input(format!(
            "the initial positions given: {} positions for {} vertices, or a non-finite one",
            q.len(),
            model.n()
        )));
    }
    check_obstacles_at_start(model, q).map_err(|e| match e {
        SolverError::Input(e) => SolverError::Input(e.context("the initial positions given")),
        e => e,
    })
}

/// Refuse initial positions `q` of `model` with a vertex inside a one-sided obstacle (deeper
/// than 1e-6 of the length scale below its surface): the first step would push it out at
/// whatever speed that takes (a body flattened and launched at hundreds of m/s) while the run
/// reports no penetration. The error names the body, its vertex, the obstacle and the depth.
fn check_initial_state(model: &Model, q: &[Vector3<f64>]) -> Result<(), SolverError> {
    check_initial_overlap(model, q)?;
    check_obstacles_at_start(model, q)
}

/// The obstacle part of [`check_initial_state`].
fn check_obstacles_at_start(model: &Model, q: &[Vector3<f64>]) -> Result<(), SolverError> {
    let tolerance = 1e-6 * model.length_scale();
    if let Some((depth, [a, b], k)) = crate::contact::initial_crossing(&model.obstacles, &model.tets, q, tolerance) {
        let body = model
            .bodies
            .iter()
            .find(|bd| bd.vertices.contains(&a))
            .map_or("a body".to_string(), |bd| format!("body '{}'", bd.name));
        return Err(SolverError::input(format!(
            "{body} starts through obstacle '{}': the edge from vertex {a} to {b} of the model crosses its surface with both ends at least {depth:.3e} m from it (thickness {:e} m); move the body or the obstacle",
            model.obstacles[k].name, model.obstacles[k].thickness
        )));
    }
    let Some((depth, v, k)) = crate::contact::initial_penetration(&model.obstacles, q, tolerance) else {
        return Ok(());
    };
    let (body, local) = model
        .bodies
        .iter()
        .find(|b| b.vertices.contains(&v))
        .map(|b| (format!("body '{}'", b.name), v - b.vertices.start))
        .or_else(|| {
            let cloth = model.cloth.as_ref()?;
            let c = cloth.bodies.iter().find(|c| c.vertices.contains(&v))?;
            Some((format!("cloth '{}'", c.name), v - c.vertices.start))
        })
        .unwrap_or_else(|| ("the model".to_string(), v));
    Err(SolverError::input(format!(
        "{body}: vertex {local} starts {depth:.3e} m inside obstacle '{}' (the initial state must be outside every obstacle: move the body or the obstacle; the first step would otherwise push it out at whatever speed that takes)",
        model.obstacles[k].name
    )))
}

/// With collisions between bodies on, no body may start through another deeper than the
/// collision thickness: the first step would push them apart at whatever speed that takes, or
/// lock the crossing surfaces together.
fn check_initial_overlap(model: &Model, q: &[Vector3<f64>]) -> Result<(), SolverError> {
    let Some(col) = model.collision() else {
        return Ok(());
    };
    let ranges: Vec<_> = model.bodies.iter().map(|b| b.tets.clone()).collect();
    if let Some(i) = crate::contact::pair::overlap::inside(col, &model.tets, &ranges, q) {
        let (a, b) = (&col.names[i.body], &col.names[i.other]);
        let point = match (i.vertex, i.tet) {
            (Some(v), _) if i.triangle => format!("the centre of a surface triangle at vertex {v} of the model"),
            (Some(v), _) => format!("vertex {v} of the model"),
            (_, Some(t)) => format!("the centre of tet {t} of the model"),
            _ => "a point".to_string(),
        };
        return Err(SolverError::input(format!(
            "body '{a}' starts inside body '{b}': {point} is {:.3e} m inside its surface (the collision thickness is {:e} m); move the bodies apart before the first step",
            i.depth, col.settings.thickness
        )));
    }
    let Some(c) = crate::contact::pair::Detector::default().deepest_crossing(col, q) else {
        return Ok(());
    };
    if c.depth <= col.settings.thickness {
        return Ok(());
    }
    let (a, b) = (&col.names[c.edge_body], &col.names[c.triangle_body]);
    Err(SolverError::input(format!(
        "body '{a}' starts through body '{b}': its surface edge from vertex {} to {} of the model crosses the other's surface, with both ends at least {:.3e} m from it (the collision thickness is {:e} m); move the bodies apart before the first step",
        c.edge[0], c.edge[1], c.depth, col.settings.thickness
    )))
}

/// The energy scale of the divergence check: `M (g L + v^2) + 1e-6 sum w`, with `M` the total
/// mass, `g` the largest acceleration of a vertex by gravity, `L` the model's length scale, `v`
/// the largest speed in `v` and `w` the elastic weights (at least the smallest positive
/// number).
fn energy_scale(model: &Model, v: &[Vector3<f64>]) -> f64 {
    let g = model.accel.iter().map(|a| a.norm()).fold(0.0, f64::max);
    let total_mass: f64 = model.mass.iter().sum();
    let v0 = v.iter().map(|v| v.norm()).fold(0.0, f64::max);
    let stiffness = model.w_rot.iter().sum::<f64>() + model.hyper.as_ref().map_or(0.0, |h| h.weight.iter().sum());
    (total_mass * (g * model.length_scale + v0 * v0) + stiffness * 1e-6).max(f64::MIN_POSITIVE)
}
