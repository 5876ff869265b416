//! Projective dynamics with implicit Euler (METHOD.md Eqs. 2-5).
//!
//! One step from `(q_n, v_n)`:
//!
//! 1. inertial target `s_n = q_n + h v_n + h^2 a_ext` (Eq. 2);
//! 2. local-global iterations from `q = s_n`: project every constraint (local, Eq. 3, in
//!    parallel), then solve `(M/h^2 + L) q = M s_n / h^2 + J p` (global, Eq. 5) with the chosen
//!    [`GlobalSolver`]; stop when the RMS change of `q` is below `tolerance x length scale` or
//!    at the iteration cap;
//! 3. with obstacles: candidate contacts come from the start and predicted positions; each
//!    global solve projects contact vertices on their Coulomb cones; after the iterations, any
//!    new penetration adds contacts and the iterations resume (a bounded number of rounds);
//! 4. `v_{n+1} = damping (q_{n+1} - q_n) / h`.
//!
//! The system matrix depends only on `h` and the weights, so it is built and (for the direct
//! solver) factored once, and certified once (see [`certify`]). Every buffer is allocated in
//! [`Simulator::new`]. Non-finite values, exploding energy and divergent iterations end the run
//! with a [`SolverError`] that says what happened.

pub mod anderson;
pub mod certify;
pub mod direct;
pub mod global;
pub mod skeletal;
pub mod warm;

use std::time::Instant;

use nalgebra::Vector3;
use serde::Serialize;

pub use crate::base::{Body, Material};
pub use crate::model::{BodySpec, MassSpec, Model, ModelBuilder};
pub use certify::{Certificate, CertifyPolicy};
pub use global::{GlobalSolver, GlobalStats, GlobalSystem, SolverKind};

use crate::analysis::spectral::EigenMethod;
use crate::base::InputError;
use crate::constraint::{Constraints, TetSvd};
use crate::contact::pair::{BodyCollision, Detector, PairContact, Query as PairQuery};
use crate::contact::{self, Contact};
use crate::kernel::ProjectionError;
use global::{FreeContact, InnerControl, Stationary};

/// Errors of the solver: bad input, a time step the certification rejects, divergence.
#[derive(Debug, Clone, thiserror::Error)]
pub enum SolverError {
    /// Physically meaningless or inconsistent input.
    #[error("invalid input: {0}")]
    Input(#[from] InputError),
    /// The chosen iteration diverges at this time step (certified check).
    #[error("time step rejected by certification: {0}")]
    Uncertified(String),
    /// The eigenvalue computation behind certification failed.
    #[error("certification failed: {0}")]
    Certification(String),
    /// The sparse factorization failed.
    #[error("factorization failed: {0}")]
    Factorization(String),
    /// A constraint projection failed.
    #[error("tet {tet}: {source}")]
    Projection {
        /// Tet index.
        tet: usize,
        /// Cause.
        source: ProjectionError,
    },
    /// An actuator projection failed.
    #[error("actuator '{group}', tet {tet}: {source}")]
    Actuator {
        /// Group name.
        group: String,
        /// Tet index.
        tet: usize,
        /// Cause.
        source: crate::kernel::actuator::ActuatorError,
    },
    /// A NaN or infinity appeared.
    #[error("non-finite value: {0}")]
    NonFinite(String),
    /// The simulation or an iteration diverged.
    #[error("diverged: {0}")]
    Diverged(String),
}

/// Solver settings.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Settings {
    /// Time step (s).
    pub dt: f64,
    /// Global solver.
    pub solver: SolverKind,
    /// Certification policy for iterative solvers.
    pub certify: CertifyPolicy,
    /// Local-global iteration cap per step.
    pub max_iterations: usize,
    /// Stop when the RMS change of the positions is below `tolerance x length scale`.
    pub tolerance: f64,
    /// Inner iterations stop when no coordinate moves more than this `x length scale`.
    pub inner_tolerance: f64,
    /// Inner iteration cap (iterative global solvers, contact sweeps).
    pub inner_max_iterations: usize,
    /// Velocity damping factor per step (1 = none; the paper uses 0.9999).
    pub damping: f64,
    /// Contact detection margin, as a fraction of the length scale.
    pub contact_margin: f64,
    /// Largest number of detect-and-resolve rounds per step.
    pub contact_rounds: usize,
    /// Eigensolver for certification.
    pub eigen_method: EigenMethod,
    /// Anderson acceleration memory of the local-global iteration (0: off, the paper's plain
    /// iteration).
    pub anderson: usize,
}

impl From<crate::constraint::ConstraintError> for SolverError {
    fn from(e: crate::constraint::ConstraintError) -> Self {
        use crate::constraint::ConstraintError as C;
        match e {
            C::Projection { tet, source } => SolverError::Projection { tet, source },
            C::Actuator { group, tet, source } => SolverError::Actuator { group, tet, source },
            C::NonFinite(m) => SolverError::NonFinite(m),
        }
    }
}

impl SolverError {
    /// An input error with this message.
    pub(crate) fn input(message: impl Into<String>) -> Self {
        Self::Input(InputError::new(message))
    }
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            dt: 0.01,
            solver: SolverKind::Split,
            certify: CertifyPolicy::Fallback,
            max_iterations: 30,
            tolerance: 1e-6,
            inner_tolerance: 1e-10,
            inner_max_iterations: 2000,
            damping: 1.0,
            contact_margin: 1e-3,
            contact_rounds: 4,
            eigen_method: EigenMethod::Auto,
            anderson: 0,
        }
    }
}

impl Settings {
    fn validate(&self) -> Result<(), SolverError> {
        let bad = |m: String| Err(SolverError::input(m));
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return bad(format!("time step must be finite and positive, got {}", self.dt));
        }
        if self.max_iterations == 0 || self.inner_max_iterations == 0 {
            return bad("iteration caps must be at least 1".into());
        }
        for (name, v) in [
            ("tolerance", self.tolerance),
            ("inner_tolerance", self.inner_tolerance),
            ("contact_margin", self.contact_margin),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{name} must be finite and >= 0, got {v}"));
            }
        }
        if !(self.damping.is_finite() && self.damping > 0.0 && self.damping <= 1.0) {
            return bad(format!("damping must be in (0, 1], got {}", self.damping));
        }
        Ok(())
    }
}

/// Positions and velocities of all vertices.
#[derive(Debug, Clone)]
pub struct State {
    /// Positions.
    pub q: Vec<Vector3<f64>>,
    /// Velocities.
    pub v: Vec<Vector3<f64>>,
    /// Simulated time.
    pub time: f64,
    /// Steps taken.
    pub step: usize,
}

/// What one step did.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct StepStats {
    /// Step number (1-based).
    pub step: usize,
    /// Time after the step.
    pub time: f64,
    /// Local-global iterations.
    pub iterations: usize,
    /// Whether the tolerance was met before the cap.
    pub converged: bool,
    /// Last RMS position change relative to the length scale.
    pub relative_change: f64,
    /// Inner iterations of the global solver, summed over the step.
    pub global_iterations: usize,
    /// Contacts in the final round.
    pub contacts: usize,
    /// Contact rounds.
    pub contact_rounds: usize,
    /// Contact iterations (sweeps), summed over the step.
    pub contact_iterations: usize,
    /// Deepest penetration after the step (m; 0 without obstacles).
    pub max_penetration: f64,
    /// Kinetic energy after the step (J).
    pub kinetic_energy: f64,
    /// Constraint energy at the last local step (J).
    pub elastic_energy: f64,
    /// Potential energy of the external accelerations, `-sum m a . q` (J).
    pub potential_energy: f64,
    /// Wall time (ms).
    pub wall_ms: f64,
    /// Of which in local steps (projections and gather, ms).
    pub local_ms: f64,
    /// Of which in global solves (ms).
    pub global_ms: f64,
    /// Accelerated iterates rejected by the energy safeguard.
    pub anderson_rejections: usize,
    /// Largest change of a distance within a bone after the step (m; 0 without a skeleton).
    pub bone_length_error: f64,
    /// Contacts between bodies (vertex-face and edge-edge pairs) in the final round.
    pub pair_contacts: usize,
}

impl StepStats {
    /// Kinetic + elastic + potential energy.
    pub fn total_energy(&self) -> f64 {
        self.kinetic_energy + self.elastic_energy + self.potential_energy
    }
}

/// Buffers reused every step.
#[derive(Debug, Clone)]
struct Work {
    q_start: Vec<Vector3<f64>>,
    s: Vec<Vector3<f64>>,
    full: Vec<Vector3<f64>>,
    gathered: Vec<Vector3<f64>>,
    base: Vec<Vector3<f64>>,
    rhs: Vec<Vector3<f64>>,
    x: Vec<Vector3<f64>>,
    x_prev: Vec<Vector3<f64>>,
    contacts: Vec<Contact>,
    free_contacts: Vec<FreeContact>,
    rigid_contacts: Vec<(usize, Contact)>,
    in_contact: Vec<bool>,
    /// Vertices that take no contacts: Dirichlet vertices.
    excluded: Vec<bool>,
    b_rigid: Vec<Vector3<f64>>,
    q_rigid: Vec<Vector3<f64>>,
    q_start_free: Vec<Vector3<f64>>,
    /// Joint scalars at the start of the step and joint torques (skeleton DoF layout).
    coords0: Vec<f64>,
    torque: Vec<f64>,
    /// Contacts between bodies and their detection buffers.
    pairs: Vec<PairContact>,
    detector: Detector,
}

/// A contact on a bone vertex as a reduced solve ended: `(bone-vertex index, contact, impulse,
/// projected Gauss-Seidel weight)`.
pub type RigidContact = (usize, Contact, Vector3<f64>, f64);

/// One step's local-global iterations, recorded for the backward pass (see [`crate::diff`]).
#[derive(Debug, Clone, Default)]
pub struct Recording {
    /// Keep every iterate (unrolled differentiation); otherwise only the last solve's contacts.
    pub keep_iterates: bool,
    /// Free-vertex iterates `x_0 .. x_N`: iteration `k` projects at `x_k` and solves for
    /// `x_{k+1}`; `x_N` is the step's result.
    pub iterates: Vec<Vec<Vector3<f64>>>,
    /// Contact sets in use (one more per contact round that added contacts).
    pub contact_sets: Vec<Vec<FreeContact>>,
    /// Per global solve: its contact set (index into `contact_sets`) and the contact impulses
    /// it ended with (direct solver; empty without contacts).
    pub solves: Vec<(usize, Vec<Vector3<f64>>)>,
    /// Whether an iterative global solver handled contacts (no impulses to record).
    pub iterative_contacts: bool,
    /// With a skeleton and `keep_iterates`: the raw joint state at every iterate (aligned with
    /// `iterates`, see [`crate::skeleton::Skeleton::save_state`]).
    pub skeleton_states: Vec<Vec<f64>>,
    /// Per reduced solve: the joint increment `dz`.
    pub increments: Vec<Vec<f64>>,
    /// Per reduced solve: the residual `g - Sigma q_R` per bone vertex.
    pub residuals: Vec<Vec<Vector3<f64>>>,
    /// Per reduced solve: active joint limits `(coordinate, multiplier)`.
    pub active_limits: Vec<Vec<(usize, f64)>>,
    /// Reduced solves that had contacts on bone vertices.
    pub rigid_contact_solves: usize,
    /// Per reduced solve: contacts on bone vertices `(bone-vertex index, contact, impulse,
    /// weight)`, as the projected Gauss-Seidel in the reduced coordinates ended.
    pub rigid_contacts: Vec<Vec<RigidContact>>,
    /// With `keep_iterates`: every tet's decomposition at each iterate's local step (aligned
    /// with `iterates`, one fewer), so the backward pass need not decompose again.
    pub svds: Vec<Vec<TetSvd>>,
    /// Buffers of `svds` kept for reuse.
    svd_pool: Vec<Vec<TetSvd>>,
    /// Whether `svds` are recorded (with `keep_iterates`).
    pub keep_decompositions: bool,
}

impl Recording {
    /// A copy without the reuse pool (to keep a step's recording).
    pub fn snapshot(&self) -> Recording {
        Recording {
            keep_iterates: self.keep_iterates,
            iterates: self.iterates.clone(),
            contact_sets: self.contact_sets.clone(),
            solves: self.solves.clone(),
            iterative_contacts: self.iterative_contacts,
            skeleton_states: self.skeleton_states.clone(),
            increments: self.increments.clone(),
            residuals: self.residuals.clone(),
            active_limits: self.active_limits.clone(),
            rigid_contact_solves: self.rigid_contact_solves,
            rigid_contacts: self.rigid_contacts.clone(),
            svds: self.svds.clone(),
            svd_pool: Vec::new(),
            keep_decompositions: self.keep_decompositions,
        }
    }

    /// Approximate heap size of the recorded data (bytes).
    pub fn bytes(&self) -> usize {
        use std::mem::size_of;
        let v3 = size_of::<Vector3<f64>>();
        self.iterates.iter().map(|x| x.len() * v3).sum::<usize>()
            + self
                .contact_sets
                .iter()
                .map(|c| c.len() * size_of::<FreeContact>())
                .sum::<usize>()
            + self.solves.iter().map(|(_, l)| l.len() * v3 + 8).sum::<usize>()
            + self
                .skeleton_states
                .iter()
                .chain(&self.increments)
                .map(|x| x.len() * 8)
                .sum::<usize>()
            + self.residuals.iter().map(|x| x.len() * v3).sum::<usize>()
            + self.active_limits.iter().map(|x| x.len() * 16).sum::<usize>()
            + self
                .rigid_contacts
                .iter()
                .map(|x| x.len() * (size_of::<Contact>() + 40))
                .sum::<usize>()
            + self.svds.iter().map(|x| x.len() * size_of::<TetSvd>()).sum::<usize>()
    }

    fn clear(&mut self) {
        self.iterates.clear();
        self.contact_sets.clear();
        self.solves.clear();
        self.iterative_contacts = false;
        self.skeleton_states.clear();
        self.increments.clear();
        self.residuals.clear();
        self.active_limits.clear();
        self.rigid_contact_solves = 0;
        self.rigid_contacts.clear();
        self.svd_pool.append(&mut self.svds);
    }

    /// Record the iterate `x` (and the skeleton's state).
    fn push_iterate(&mut self, x: &[Vector3<f64>], skeleton: Option<&crate::skeleton::Skeleton>) {
        self.iterates.push(x.to_vec());
        if let Some(sk) = skeleton {
            let mut s = Vec::new();
            sk.save_state(&mut s);
            self.skeleton_states.push(s);
        }
    }
}

/// A running simulation.
pub struct Simulator {
    model: Model,
    settings: Settings,
    state: State,
    system: GlobalSystem,
    solver: Box<dyn GlobalSolver>,
    certificate: Certificate,
    constraints: Constraints,
    /// Activation of each actuator group in the current step.
    activations: Vec<f64>,
    work: Work,
    energy_scale: f64,
    /// The skeleton's current state (joint coordinates), and its reduced step.
    skeleton: Option<(crate::skeleton::Skeleton, skeletal::Skeletal)>,
    /// Anderson acceleration of the local-global iteration.
    anderson: Option<anderson::Anderson>,
    /// Activations set through the API, per actuator group (`None`: follow the schedule).
    activation_override: Vec<Option<f64>>,
    /// What the steps record for the backward pass (`None`: nothing).
    recording: Option<Recording>,
}

impl std::fmt::Debug for Simulator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Simulator")
            .field("vertices", &self.model.n())
            .field("tets", &self.model.tets.len())
            .field("solver", &self.solver.kind())
            .field("step", &self.state.step)
            .finish()
    }
}

/// The one-DoF joints' coordinates into `c` (indexed by DoF offset; other entries untouched).
fn joint_scalars(sk: &crate::skeleton::Skeleton, c: &mut [f64]) {
    for b in &sk.bones {
        if let Some(x) = b.joint.scalar() {
            c[b.dof_offset] = x;
        }
    }
}

/// The local step at `q`; with a recording that keeps iterates, every tet's decomposition is
/// recorded too (`replace_last`: the iteration's earlier record is replaced).
fn project_local(
    constraints: &mut Constraints,
    activations: &[f64],
    recording: Option<&mut Recording>,
    model: &Model,
    q: &[Vector3<f64>],
    replace_last: bool,
) -> Result<f64, SolverError> {
    match recording.filter(|r| r.keep_iterates && r.keep_decompositions) {
        Some(r) => {
            if replace_last {
                if let Some(b) = r.svds.pop() {
                    r.svd_pool.push(b);
                }
            }
            let mut buf = r.svd_pool.pop().unwrap_or_default();
            buf.resize(model.tets.len(), TetSvd::default());
            let e = constraints.project(model, q, activations, Some(&mut buf));
            r.svds.push(buf);
            Ok(e?)
        }
        None => Ok(constraints.project(model, q, activations, None)?),
    }
}

/// The objective the local-global iteration of one step minimises:
/// `1/(2h^2) |q - s|_M^2 + E_constraints(q) + attachments - tau . (z - z_start)`.
#[allow(clippy::too_many_arguments)]
fn step_objective(
    model: &Model,
    q: &[Vector3<f64>],
    s: &[Vector3<f64>],
    ih2: f64,
    elastic: f64,
    skeleton: Option<&crate::skeleton::Skeleton>,
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

/// A pair's linearised gap at the end of a step may fall this far (times the thickness) below
/// zero before the pair is added as a new contact.
pub const PAIR_TOLERANCE: f64 = 1e-3;

/// The obstacle index that marks a contact between two bodies.
pub const PAIR_OBSTACLE: usize = usize::MAX;

/// A pair between bodies as a contact on its free vertices: Dirichlet vertices move into the
/// plane's offset and the anchor (`None` when every vertex of the pair is fixed).
fn pair_contact(
    p: &PairContact,
    sys: &GlobalSystem,
    q_start: &[Vector3<f64>],
    col: &BodyCollision,
) -> Option<FreeContact> {
    let mut stencil = global::Stencil {
        len: 0,
        index: [0; 4],
        coef: [0.0; 4],
    };
    let mut offset = Vector3::zeros();
    let mut anchor = Vector3::zeros();
    for (&v, &c) in p.vertices.iter().zip(&p.coefs) {
        let k = sys.index[v];
        if k == usize::MAX {
            offset += q_start[v] * c;
        } else {
            stencil.index[stencil.len as usize] = k;
            stencil.coef[stencil.len as usize] = c;
            stencil.len += 1;
            anchor += q_start[v] * c;
        }
    }
    (stencil.len > 0).then(|| FreeContact {
        index: stencil.index[0],
        contact: Contact {
            vertex: p.vertices[0],
            obstacle: PAIR_OBSTACLE,
            normal: p.normal,
            point: p.normal * col.thickness - offset,
            anchor,
            friction: col.friction,
        },
        stencil,
        pair: Some(*p),
    })
}

fn build_solver(
    model: &Model,
    settings: &Settings,
    system: &GlobalSystem,
) -> Result<(Box<dyn GlobalSolver>, Certificate), SolverError> {
    if model.collision.is_some() && model.skeleton.is_some() {
        return Err(SolverError::input(
            "collisions between bodies with a skeleton are not supported yet (bone vertices in a pair contact)",
        ));
    }
    let cert = if model.collision.is_some() && settings.solver != SolverKind::Direct {
        // A contact between two bodies couples several vertices through one impulse: the
        // projected Gauss-Seidel runs on the factored matrix's Delassus operator.
        let mut c = certify::certify(system, SolverKind::Direct, settings.certify, settings.eigen_method, 0)?;
        c.requested = settings.solver;
        c.message = format!(
            "{:?} requested, but contacts between bodies couple several vertices per impulse: direct sparse Cholesky",
            settings.solver
        );
        c
    } else if model.skeleton.is_some() && settings.solver != SolverKind::Direct {
        // The reduced step (Eqs. 17-18) eliminates the free vertices with the factored free
        // block, so a skeleton always runs on the direct solver; no eigenvalue check is needed.
        let mut c = certify::certify(system, SolverKind::Direct, settings.certify, settings.eigen_method, 0)?;
        c.requested = settings.solver;
        c.message = format!(
            "{:?} requested, but the skeleton's reduced step (Eqs. 17-18) factors the free block: direct sparse Cholesky",
            settings.solver
        );
        c
    } else {
        certify::certify(
            system,
            settings.solver,
            settings.certify,
            settings.eigen_method,
            settings.inner_max_iterations,
        )?
    };
    let control = InnerControl {
        tolerance: settings.inner_tolerance * model.length_scale,
        max_iterations: settings.inner_max_iterations,
    };
    let solver: Box<dyn GlobalSolver> = match cert.used {
        SolverKind::Direct => Box::new(direct::Direct::new(system, control)?),
        kind => Box::new(Stationary::new(
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
        )),
    };
    Ok((solver, cert))
}

impl Simulator {
    /// Set up a simulation from the model's initial state (rest positions, initial velocities).
    pub fn new(model: Model, settings: Settings) -> Result<Self, SolverError> {
        settings.validate()?;
        let system = GlobalSystem::new(&model, settings.dt)?;
        let (solver, certificate) = build_solver(&model, &settings, &system)?;
        let n = model.n();
        let nf = system.n();
        let nr = system.rigid.len();
        let excluded = model.fixed.clone();
        let mut solver = solver;
        let skeleton = match &model.skeleton {
            Some(sk) => {
                let direct = solver.as_direct().expect("skeleton scenes use the direct solver");
                Some((sk.clone(), skeletal::Skeletal::new(&system, direct, sk)))
            }
            None => None,
        };
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
        let dofs = skeleton.as_ref().map_or(0, |(sk, _)| sk.dofs);
        let groups = model.actuators.as_ref().map_or(0, |a| a.groups.len());
        Ok(Self {
            recording: None,
            activation_override: vec![None; groups],
            constraints: Constraints::new(&model),
            activations: model
                .actuators
                .as_ref()
                .map_or(Vec::new(), |a| a.groups.iter().map(|g| g.activation.at(0.0)).collect()),
            work: Work {
                q_start: vec![Vector3::zeros(); n],
                s: vec![Vector3::zeros(); n],
                full: vec![Vector3::zeros(); n],
                gathered: vec![Vector3::zeros(); n],
                base: vec![Vector3::zeros(); nf],
                rhs: vec![Vector3::zeros(); nf],
                x: vec![Vector3::zeros(); nf],
                x_prev: vec![Vector3::zeros(); nf],
                contacts: Vec::new(),
                free_contacts: Vec::new(),
                rigid_contacts: Vec::new(),
                in_contact: vec![false; n],
                excluded,
                b_rigid: vec![Vector3::zeros(); nr],
                q_rigid: vec![Vector3::zeros(); nr],
                q_start_free: vec![Vector3::zeros(); nf],
                coords0: vec![0.0; dofs],
                torque: vec![0.0; dofs],
                pairs: Vec::new(),
                detector: Detector::default(),
            },
            skeleton,
            anderson: (settings.anderson > 0).then(|| anderson::Anderson::new(settings.anderson, nf)),
            energy_scale: e_scale.max(f64::MIN_POSITIVE),
            model,
            settings,
            state,
            system,
            solver,
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
        if q.len() != self.model.n() || v.len() != self.model.n() {
            return Err(SolverError::input(format!(
                "state has {} positions and {} velocities, the model {} vertices",
                q.len(),
                v.len(),
                self.model.n()
            )));
        }
        if !q.iter().chain(&v).all(|x| x.iter().all(|c| c.is_finite())) {
            return Err(SolverError::input("state has non-finite entries"));
        }
        self.state.q = q;
        self.state.v = v;
        Ok(())
    }

    /// Set joint coordinates (by bone name) and move the bone vertices with them; free vertices
    /// stay where they are.
    pub fn set_joint_coordinates(&mut self, bone: &str, c: &[f64]) -> Result<(), SolverError> {
        let (sk, _) = self
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
        let kind = act.groups[g].kind;
        if !kind.admits(a) {
            return Err(SolverError::input(format!(
                "actuator '{name}': activation {a} out of range ({})",
                kind.range()
            )));
        }
        self.activation_override[g] = Some(a);
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

    /// Record every following step's iterations for the backward pass (`keep_iterates`: all
    /// iterates, for unrolled differentiation, with every tet's decomposition; otherwise only
    /// the final contacts), or stop recording (`None`).
    pub fn record(&mut self, keep_iterates: Option<bool>) {
        self.recording = keep_iterates.map(|k| Recording {
            keep_iterates: k,
            keep_decompositions: k,
            ..Default::default()
        });
    }

    /// Whether a recording that keeps iterates also keeps every tet's decomposition (memory:
    /// about 200 bytes per tet and iteration; saves the backward pass decomposing again).
    pub fn record_decompositions(&mut self, keep: bool) {
        if let Some(r) = self.recording.as_mut() {
            r.keep_decompositions = keep;
        }
    }

    /// What the last step recorded (see [`Simulator::record`]).
    pub fn recording(&self) -> Option<&Recording> {
        self.recording.as_ref()
    }

    /// Set the simulated time and step counter (with [`Simulator::set_state`], to replay a step).
    pub fn set_clock(&mut self, time: f64, step: usize) {
        self.state.time = time;
        self.state.step = step;
    }

    /// The raw joint state of the skeleton (see [`crate::skeleton::Skeleton::save_state`]), if
    /// the model has one.
    pub fn skeleton_state(&self) -> Option<Vec<f64>> {
        self.skeleton.as_ref().map(|(sk, _)| {
            let mut s = Vec::new();
            sk.save_state(&mut s);
            s
        })
    }

    /// Restore a joint state saved by [`Simulator::skeleton_state`]; the bone vertices' positions
    /// are set separately with [`Simulator::set_state`].
    pub fn set_skeleton_state(&mut self, s: &[f64]) -> Result<(), SolverError> {
        let (sk, _) = self
            .skeleton
            .as_mut()
            .ok_or_else(|| SolverError::input("the model has no skeleton"))?;
        Ok(sk.load_state(s)?)
    }

    /// Set the torque on the one-DoF joint of bone `bone` from the next step on (`None`: follow
    /// its schedule again).
    pub fn set_torque(&mut self, bone: &str, value: Option<f64>) -> Result<(), SolverError> {
        let (sk, _) = self
            .skeleton
            .as_mut()
            .ok_or_else(|| SolverError::input("the model has no skeleton"))?;
        let dof = sk.scalar_dof(bone)?;
        Ok(sk.set_torque(dof, value)?)
    }

    /// Set the torque on reduced coordinate `dof` (a one-DoF joint's) from the next step on.
    pub fn set_torque_dof(&mut self, dof: usize, value: Option<f64>) -> Result<(), SolverError> {
        let (sk, _) = self
            .skeleton
            .as_mut()
            .ok_or_else(|| SolverError::input("the model has no skeleton"))?;
        Ok(sk.set_torque(dof, value)?)
    }

    /// The skeleton's current state, if the model has one.
    pub fn skeleton(&self) -> Option<&crate::skeleton::Skeleton> {
        self.skeleton.as_ref().map(|(s, _)| s)
    }

    /// The certification outcome (which solver runs and why).
    pub fn certificate(&self) -> &Certificate {
        &self.certificate
    }

    /// Change the time step: rebuilds, re-certifies and refactors the global system.
    pub fn set_dt(&mut self, dt: f64) -> Result<(), SolverError> {
        let mut s = self.settings.clone();
        s.dt = dt;
        s.validate()?;
        let system = GlobalSystem::new(&self.model, dt)?;
        let (mut solver, cert) = build_solver(&self.model, &s, &system)?;
        if let Some((sk, sp)) = self.skeleton.as_mut() {
            let direct = solver.as_direct().expect("skeleton scenes use the direct solver");
            *sp = skeletal::Skeletal::new(&system, direct, sk);
        }
        self.settings = s;
        self.system = system;
        self.solver = solver;
        self.certificate = cert;
        Ok(())
    }

    /// Advance one time step.
    pub fn step(&mut self) -> Result<StepStats, SolverError> {
        let t0 = Instant::now();
        let h = self.settings.dt;
        let (model, sys, w, st) = (&self.model, &self.system, &mut self.work, &mut self.state);
        let ih2 = 1.0 / (h * h);
        for i in 0..model.n() {
            w.q_start[i] = st.q[i];
            w.s[i] = if model.fixed[i] {
                model.rest[i]
            } else {
                st.q[i] + st.v[i] * h + model.accel[i] * (h * h)
            };
        }
        // Right-hand side parts that do not change during the step.
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
        if let Some((_, sp)) = self.skeleton.as_mut() {
            // Bone vertices start where the skeleton is.
            for &v in &sys.rigid {
                w.full[v] = st.q[v];
            }
            sp.reset_impulses();
        }
        let margin = self.settings.contact_margin * model.length_scale;
        w.contacts.clear();
        w.free_contacts.clear();
        w.rigid_contacts.clear();
        if !model.obstacles.is_empty() {
            contact::detect(&model.obstacles, &w.excluded, &w.q_start, &w.s, margin, &mut w.contacts);
            w.rigid_contacts.clear();
            for c in &w.contacts {
                if sys.index[c.vertex] != usize::MAX {
                    w.free_contacts.push(FreeContact::single(sys.index[c.vertex], *c));
                } else {
                    w.rigid_contacts.push((sys.rigid_index[c.vertex], *c));
                }
            }
        }
        w.pairs.clear();
        if let Some(col) = &model.collision {
            w.detector
                .detect(col, &w.q_start, &w.s, PairQuery::Candidates { margin }, &mut w.pairs);
            for p in &w.pairs {
                if let Some(fc) = pair_contact(p, sys, &w.q_start, &col.settings) {
                    w.free_contacts.push(fc);
                }
            }
        }
        if let Some(r) = self.recording.as_mut() {
            r.clear();
        }
        let tol = self.settings.tolerance * model.length_scale;
        let mut stats = StepStats {
            step: st.step + 1,
            time: st.time + h,
            iterations: 0,
            converged: false,
            relative_change: f64::NAN,
            global_iterations: 0,
            contacts: 0,
            contact_rounds: 0,
            contact_iterations: 0,
            max_penetration: 0.0,
            kinetic_energy: 0.0,
            elastic_energy: 0.0,
            potential_energy: 0.0,
            wall_ms: 0.0,
            local_ms: 0.0,
            global_ms: 0.0,
            anderson_rejections: 0,
            bone_length_error: 0.0,
            pair_contacts: 0,
        };
        let nf = sys.n();
        let rms = (nf.max(1) as f64).sqrt();
        // Activations at the end of the step (implicit Euler), unless set through the API.
        if let Some(act) = model.actuators.as_ref() {
            for (g, group) in act.groups.iter().enumerate() {
                self.activations[g] = self.activation_override[g].unwrap_or_else(|| group.activation.at(st.time + h));
            }
        }
        // Joint coordinates at the start of the step, for the torques' potential.
        if let Some((sk, _)) = &self.skeleton {
            joint_scalars(sk, &mut w.coords0);
            sk.torques(st.time + h, &mut w.torque);
        }
        for round in 0..self.settings.contact_rounds.max(1) {
            if let Some(aa) = self.anderson.as_mut() {
                aa.reset();
            }
            let mut energy_prev = f64::INFINITY;
            let mut accelerated = false;
            stats.contact_rounds = round + 1;
            stats.converged = false;
            if let Some(r) = self.recording.as_mut() {
                if r.contact_sets.last().map(|c| c.len()) != Some(w.free_contacts.len()) {
                    r.contact_sets.push(w.free_contacts.clone());
                }
            }
            for _ in 0..self.settings.max_iterations {
                if let Some(r) = self.recording.as_mut().filter(|r| r.keep_iterates) {
                    r.push_iterate(&w.x, self.skeleton.as_ref().map(|(sk, _)| sk));
                }
                for (k, &v) in sys.free.iter().enumerate() {
                    w.full[v] = w.x[k];
                }
                let tl = Instant::now();
                stats.elastic_energy = project_local(
                    &mut self.constraints,
                    &self.activations,
                    self.recording.as_mut(),
                    model,
                    &w.full,
                    false,
                )?;
                if let Some(aa) = self.anderson.as_mut() {
                    // Safeguard: an accelerated iterate must lower the step's objective;
                    // otherwise fall back to the plain update and forget the history.
                    let sk = self.skeleton.as_ref().map(|(sk, _)| sk);
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
                    if accelerated && e > energy_prev + 1e-12 * energy_prev.abs() {
                        w.x.copy_from_slice(aa.last_plain());
                        for (k, &v) in sys.free.iter().enumerate() {
                            w.full[v] = w.x[k];
                        }
                        stats.elastic_energy = project_local(
                            &mut self.constraints,
                            &self.activations,
                            self.recording.as_mut(),
                            model,
                            &w.full,
                            true,
                        )?;
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
                    energy_prev = e;
                }
                self.constraints.gather(model, &mut w.gathered);
                stats.local_ms += tl.elapsed().as_secs_f64() * 1e3;
                for (k, &v) in sys.free.iter().enumerate() {
                    w.rhs[k] = w.base[k] + w.gathered[v];
                }
                w.x_prev.copy_from_slice(&w.x);
                let tg = Instant::now();
                let direct_only = self.solver.as_direct().is_some();
                let (skeleton, solver, settings, constraints) =
                    (&mut self.skeleton, &mut self.solver, &self.settings, &self.constraints);
                let mut global = || -> Result<_, SolverError> {
                    Ok(match skeleton.as_mut() {
                        None => solver.solve(sys, &w.rhs, &mut w.x, &w.free_contacts)?,
                        Some((sk, sp)) => {
                            for (r, &v) in sys.rigid.iter().enumerate() {
                                w.b_rigid[r] = w.s[v] * (model.mass[v] * ih2) + w.gathered[v] + sys.coupling_rigid[r];
                            }
                            constraints.constant_rhs(model, &mut |v, b| {
                                if let Some(r) = sys.rigid.iter().position(|&u| u == v) {
                                    w.b_rigid[r] += b;
                                }
                            });
                            let direct = solver.as_direct().expect("skeleton scenes use the direct solver");
                            let control = InnerControl {
                                tolerance: settings.inner_tolerance * model.length_scale,
                                max_iterations: settings.inner_max_iterations,
                            };
                            let g = sp.solve(
                                sys,
                                direct,
                                sk,
                                &w.rhs,
                                &w.b_rigid,
                                st.time + h,
                                &mut w.x,
                                &mut w.q_rigid,
                                &w.free_contacts,
                                &w.rigid_contacts,
                                control,
                            )?;
                            for (r, &v) in sys.rigid.iter().enumerate() {
                                w.full[v] = w.q_rigid[r];
                            }
                            g
                        }
                    })
                };
                // A direct solve has no parallel section inside: keep the workers warm for the
                // next local step meanwhile (see `warm`).
                let g = if direct_only {
                    warm::keep_warm(global)?
                } else {
                    global()?
                };
                stats.global_ms += tg.elapsed().as_secs_f64() * 1e3;
                if let Some(r) = self.recording.as_mut() {
                    if !r.keep_iterates {
                        r.solves.clear();
                    }
                    let set = r.contact_sets.len() - 1;
                    let mut impulses = Vec::new();
                    if !w.free_contacts.is_empty() {
                        match self.solver.as_direct() {
                            Some(d) => impulses.extend(d.impulses().map(|(_, l)| l)),
                            None => r.iterative_contacts = true,
                        }
                    }
                    r.solves.push((set, impulses));
                    if let (true, Some((_, sp))) = (r.keep_iterates, self.skeleton.as_ref()) {
                        r.increments.push(sp.last_increment().to_vec());
                        r.residuals.push(sp.last_residual().to_vec());
                        r.active_limits.push(sp.active_limits().collect());
                        r.rigid_contact_solves += usize::from(!w.rigid_contacts.is_empty());
                        let rc = if w.rigid_contacts.is_empty() {
                            Vec::new()
                        } else {
                            w.rigid_contacts
                                .iter()
                                .zip(sp.rigid_contact_solution())
                                .map(|(&(i, c), (l, wt))| (i, c, l, wt))
                                .collect()
                        };
                        r.rigid_contacts.push(rc);
                    }
                }
                stats.iterations += 1;
                stats.global_iterations += g.iterations;
                stats.contact_iterations += g.contact_iterations;
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
                stats.relative_change = change / model.length_scale;
                if change <= tol {
                    stats.converged = true;
                    break;
                }
                if let Some(aa) = self.anderson.as_mut() {
                    // w.x = G(x_prev): mix into the next iterate (the plain update is kept).
                    w.q_start_free.copy_from_slice(&w.x);
                    aa.mix(&w.x_prev, &w.q_start_free, &mut w.x);
                    accelerated = true;
                }
            }
            if model.obstacles.is_empty() && model.collision.is_none() {
                break;
            }
            // New penetrations: add them as contacts and resume.
            for (k, &v) in sys.free.iter().enumerate() {
                w.full[v] = w.x[k];
            }
            let pairs_before = w.pairs.len();
            if let Some(col) = &model.collision {
                w.detector.remember(&w.pairs, true);
                let tolerance = PAIR_TOLERANCE * col.settings.thickness;
                w.detector.detect(
                    col,
                    &w.q_start,
                    &w.full,
                    PairQuery::Violations { tolerance },
                    &mut w.pairs,
                );
                for p in &w.pairs[pairs_before..] {
                    if let Some(fc) = pair_contact(p, sys, &w.q_start, &col.settings) {
                        w.free_contacts.push(fc);
                    }
                }
            }
            let before = w.contacts.len();
            for c in &w.contacts {
                w.in_contact[c.vertex] = true;
            }
            for (i, (a, x)) in w.q_start.iter().zip(&w.full).enumerate() {
                if w.excluded[i] || w.in_contact[i] {
                    continue;
                }
                for (oi, o) in model.obstacles.iter().enumerate() {
                    if let Some((d, normal, point)) = o.query(a, x, 0.0) {
                        if d < 0.0 {
                            let c = Contact {
                                vertex: i,
                                obstacle: oi,
                                normal,
                                point,
                                anchor: *a,
                                friction: o.friction,
                            };
                            w.contacts.push(c);
                            if sys.index[i] != usize::MAX {
                                w.free_contacts.push(FreeContact::single(sys.index[i], c));
                            } else {
                                w.rigid_contacts.push((sys.rigid_index[i], c));
                            }
                            break;
                        }
                    }
                }
            }
            for c in &w.contacts {
                w.in_contact[c.vertex] = false;
            }
            if w.contacts.len() == before && w.pairs.len() == pairs_before {
                break;
            }
        }
        stats.contacts = w.contacts.len();
        stats.pair_contacts = w.pairs.len();
        if let Some(r) = self.recording.as_mut().filter(|r| r.keep_iterates) {
            r.push_iterate(&w.x, self.skeleton.as_ref().map(|(sk, _)| sk));
        }
        for (k, &v) in sys.free.iter().enumerate() {
            w.full[v] = w.x[k];
        }
        if !model.obstacles.is_empty() {
            stats.max_penetration = contact::max_penetration(&model.obstacles, &w.q_start, &w.full).0;
        }
        // Velocities, energies, divergence checks.
        let damping = self.settings.damping;
        let mut kinetic = 0.0;
        let mut potential = 0.0;
        for i in 0..model.n() {
            let q = w.full[i];
            let v = (q - w.q_start[i]) * (damping / h);
            st.q[i] = q;
            st.v[i] = v;
            kinetic += 0.5 * model.mass[i] * v.norm_squared();
            potential -= model.mass[i] * model.accel[i].dot(&q);
        }
        if let Some((sk, _)) = &self.skeleton {
            stats.bone_length_error = sk.bone_length_error(&st.q);
        }
        st.time += h;
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
        Ok(stats)
    }
}
