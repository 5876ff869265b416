//! Reverse-mode gradients of whole simulations (docs/method.md section 7).
//!
//! A loss `L(q_1, v_1, ..., q_N, v_N)` ([`loss`]) of a trajectory is differentiated with respect
//! to the initial positions and velocities, the per-tet constraint weights (hence Young's modulus
//! and Poisson ratio, globally or per element), the lumped masses (density), the external
//! accelerations (gravity), the attachment targets, the actuators' activations at every step,
//! the joint torques at every step and the initial joint state (skeletons, `skeletal.rs`).
//!
//! The forward pass stores each step's state (checkpointing, as the paper does); the backward
//! pass walks the steps in reverse. Two modes:
//!
//! * [`Mode::Unrolled`] replays each step from its checkpoint, recording the local-global
//!   iterates `x_0 = s, x_1, ..., x_N` (Eqs. 2-5), and differentiates every iteration the forward
//!   ran, `x_{k+1} = A^-1 (M s/h^2 + b_fixed + J p(x_k))`: with `r_bar = A^-1 x_bar` (plus the
//!   contact correction of `contact.rs`), `x_bar_k = J (dp/dq)(x_k)^T J^T r_bar`. It
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
//! contacts on free and bone vertices (see `skeletal.rs`); its implicit mode iterates the adjoint
//! of the step's last iteration to its fixed point. Anderson-accelerated unrolled runs return
//! [`DiffError::Unsupported`].
//!
//! Memory: one state per step (pure checkpointing, as the paper); [`Options::store_bytes`]
//! keeps whole steps' recordings from the forward pass within a budget so they need no replay.

mod backward;
pub(crate) mod contact;
mod cotangent;
mod forward;
mod gradient;
mod implicit;
pub mod loss;
pub mod optim;
pub mod params;
pub(crate) mod recording;
mod rollout;
pub(crate) mod skeletal;
mod skeletal_state;

use nalgebra::Vector3;
use serde::Serialize;

use crate::kernel::hyperelastic::Lame;
use crate::model::Model;
use crate::solver::SolverError;

pub use cotangent::{vjp, Cotangent};
pub use gradient::{differentiable_solver, gradient, gradient_on, gradient_with, loss_value, loss_value_on, Progress};
pub use params::Param;
pub use rollout::{rollout, Rollout};

/// Errors of the differentiation.
#[derive(Debug, Clone, thiserror::Error)]
#[non_exhaustive]
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
    /// The forward pass did not meet its tolerance on some steps, so the loss and gradient
    /// would be of an unconverged simulation (opt in with [`Options::allow_unconverged`]).
    #[error(
        "the forward simulation did not converge on {steps} of {of} steps (tolerance {tolerance:e}, cap {max_iterations} iterations): its loss and gradient would be those of an unconverged run; raise the iteration cap, lower the tolerance or the time step, or allow unconverged steps explicitly"
    )]
    Unconverged {
        /// Steps that hit the iteration cap.
        steps: usize,
        /// Steps simulated.
        of: usize,
        /// The tolerance they missed.
        tolerance: f64,
        /// The iteration cap.
        max_iterations: usize,
    },
    /// A global or contact solve inside some forward steps stopped unconverged (at its cap, or
    /// stalled on an infeasible or badly conditioned contact set): those steps' states solve no
    /// contact problem, so neither the unrolled nor the implicit backward pass differentiates
    /// the simulation (opt in with [`Options::allow_unconverged`]).
    #[error(
        "{steps} of {of} forward steps stopped a global or contact solve unconverged (at its cap of {inner_max_iterations} iterations, or stalled on an infeasible or badly conditioned contact set): the backward pass would differentiate states that solve no contact problem, and the gradient could be wrong by orders of magnitude; lower the time step or the impact speed, raise the solver's inner_max_iterations, or allow unconverged steps explicitly"
    )]
    CappedSolves {
        /// Steps with a capped or stalled solve.
        steps: usize,
        /// Steps simulated.
        of: usize,
        /// The inner solves' iteration cap.
        inner_max_iterations: usize,
    },
    /// Some forward steps ended with the surfaces of two bodies crossing (a contact the step
    /// missed: a body too fast for the time step, or a contact set the solve could not
    /// satisfy): the trajectory is not the contact problem's, so no gradient of it is. Not
    /// waived by [`Options::allow_unconverged`].
    #[error(
        "{steps} of {of} forward steps end with bodies passing through each other (from step {first} on, {edges} surface edges of one body cross faces of another there): the simulation missed contacts, so neither its loss nor its gradient is the physics'; lower the time step or the speed, raise the contact rounds, or thicken the contact layer"
    )]
    Interpenetration {
        /// Steps that ended with crossing surfaces.
        steps: usize,
        /// Steps simulated.
        of: usize,
        /// The first of them (1-based).
        first: usize,
        /// Crossing surface edges at the end of that step.
        edges: usize,
    },
    /// Some forward steps kept two bodies apart only with contacts found by sweeping their
    /// motion (primitives that passed through each other during a round of the step,
    /// linearised where they met, docs/method.md Eq. C6): those contacts' geometry depends on
    /// the round's end positions, which the backward pass does not differentiate, so the
    /// gradient would be missing terms. Not waived by [`Options::allow_unconverged`].
    #[error(
        "{steps} of {of} forward steps needed contacts found by sweeping the bodies' motion (from step {first} on, {pairs} such contacts there: surfaces that passed through each other within a round of the step): the trajectory is kept apart, but the backward pass does not differentiate where those contacts were linearised, so it refuses; lower the time step or the speed so that the contacts are found at the start of each step"
    )]
    SweptContacts {
        /// Steps with such contacts.
        steps: usize,
        /// Steps simulated.
        of: usize,
        /// The first of them (1-based).
        first: usize,
        /// Such contacts in that step.
        pairs: usize,
    },
    /// Unrolled mode: replaying a step from its checkpoint did not reproduce the forward pass
    /// (e.g. an accelerated forward that did not converge), so the backward pass would
    /// differentiate another trajectory.
    #[error(
        "the backward pass's replay deviates from the forward pass by {deviation:e} m (allowed {allowed:e} m): the gradient would be of another trajectory; use a tolerance the forward meets, or Anderson memory 0"
    )]
    NotReplayable {
        /// Largest position difference between replay and forward (m).
        deviation: f64,
        /// The allowed difference (m): 1e-6 of the model's length scale.
        allowed: f64,
    },
    /// The backward pass produced a value beyond floating point (the loss's derivatives, or a
    /// caller's cotangents, too large for doubles): no gradient is returned rather than one
    /// with infinities or NaNs in it.
    #[error(
        "the backward pass overflowed: {what} is not finite (the loss's derivatives or the cotangents are too large for doubles; the gradient is linear in them: scale them down and the result up)"
    )]
    NonFiniteGradient {
        /// Where: the adjoint solve of a step, or the first entry of the result that is not finite.
        what: String,
    },
    /// A parameter applies to nothing in the model (a material parameter of a scene with cloth
    /// alone, gravity where nothing has gravity): setting it would change nothing, and its
    /// derivative would be a zero that no input produced ([`Param::check_applies`]).
    #[error(
        "invalid input: {param}: the model has nothing that '{param}' applies to, so there is nothing to set or differentiate"
    )]
    NothingApplies {
        /// The parameter's name.
        param: String,
    },
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, schemars::JsonSchema)]
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
    /// Implicit mode: stop the adjoint solve (conjugate gradients' relative residual, the fixed
    /// point's relative change) at this tolerance. `None` (the default): matched to the
    /// forward's own accuracy, [`Options::matched_implicit_tolerance`] (docs/method.md section
    /// 7, Eq. G5).
    pub implicit_tolerance: Option<f64>,
    /// Implicit mode: iteration cap of the adjoint fixed point.
    pub implicit_max_iterations: usize,
    /// Implicit mode with contacts: memory of the Anderson mixing that accelerates the adjoint
    /// fixed point (0: the plain iteration, which converges at the forward's own rate).
    pub implicit_anderson: usize,
    /// Relative tolerance of the linearized contact systems (their residual, or the
    /// Gauss-Seidel's change per sweep, against the largest entry of the right-hand side and
    /// solution).
    pub contact_tolerance: f64,
    /// Sweep cap of the linearized contact systems solved by Gauss-Seidel.
    pub contact_max_sweeps: usize,
    /// Unrolled mode: keep the forward pass's recordings of whole steps (iterates and
    /// decompositions) up to this many bytes, so those steps need no replay in the backward
    /// pass; the steps beyond it are replayed from their checkpoints. 0: pure checkpointing, as
    /// the paper (memory: one state per step).
    pub store_bytes: usize,
    /// Return a gradient even when forward steps missed their tolerance (`settings.tolerance >
    /// 0`) or, in unrolled mode, a replay deviates from the forward pass; the counts are in
    /// [`DiffStats`]. Default `false`: such a run is an error ([`DiffError::Unconverged`],
    /// [`DiffError::NotReplayable`]). A tolerance of 0 (a fixed iteration count, the smooth
    /// forward the gradient checks use) is never an error.
    pub allow_unconverged: bool,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            mode: Mode::Unrolled,
            implicit_tolerance: None,
            implicit_max_iterations: 300,
            implicit_anderson: 8,
            contact_tolerance: 1e-14,
            contact_max_sweeps: 100_000,
            store_bytes: 0,
            allow_unconverged: false,
        }
    }
}

impl Options {
    /// Defaults with the given mode.
    ///
    /// ```
    /// use diffsoft::{Mode, Options};
    ///
    /// let o = Options::mode(Mode::Implicit);
    /// assert_eq!(o.mode, Mode::Implicit);
    /// assert_eq!(o.store_bytes, Options::default().store_bytes);
    /// ```
    pub fn mode(mode: Mode) -> Self {
        Self {
            mode,
            ..Self::default()
        }
    }

    /// The implicit adjoint's tolerance under `settings`: `implicit_tolerance` where set,
    /// otherwise [`Options::matched_implicit_tolerance`].
    pub fn implicit_tolerance_for(&self, settings: &crate::solver::Settings) -> f64 {
        self.implicit_tolerance
            .unwrap_or_else(|| Self::matched_implicit_tolerance(settings.tolerance))
    }

    /// The implicit adjoint's tolerance matched to a forward solved to the relative tolerance
    /// `forward` (docs/method.md Eq. G5): the forward's own, within `[1e-12, 1e-5]`; `1e-12`
    /// for a fixed iteration count (`forward = 0`). The forward's stopping error already moves
    /// the implicit gradient by more than an adjoint solved to that tolerance does, so a tighter
    /// adjoint buys nothing; the upper clamp keeps to the range where that was measured.
    ///
    /// ```
    /// use diffsoft::Options;
    ///
    /// assert_eq!(Options::matched_implicit_tolerance(8e-6), 8e-6);
    /// assert_eq!(Options::matched_implicit_tolerance(0.0), 1e-12);
    /// assert_eq!(Options::matched_implicit_tolerance(1e-2), 1e-5);
    /// ```
    pub fn matched_implicit_tolerance(forward: f64) -> f64 {
        if forward > 0.0 {
            forward.clamp(MATCHED_FLOOR, MATCHED_CEILING)
        } else {
            MATCHED_FLOOR
        }
    }
}

/// The tightest matched implicit tolerance (a forward with a fixed iteration count gets it).
const MATCHED_FLOOR: f64 = 1e-12;
/// The loosest matched implicit tolerance.
const MATCHED_CEILING: f64 = 1e-5;

/// Initial positions and velocities of every vertex.
pub type InitialState = (Vec<Vector3<f64>>, Vec<Vector3<f64>>);

/// The controls of a run: the initial state and activations per step (`[step][group]`,
/// overriding the groups' schedules).
///
/// ```
/// use diffsoft::Controls;
///
/// // Two steps of one actuator group, the rest as the model has it.
/// let c = Controls { activations: Some(vec![vec![0.5], vec![1.0]]), ..Controls::default() };
/// assert!(c.initial.is_none() && c.torques.is_none());
/// ```
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
#[derive(Debug, Clone, Copy, Default, Serialize, schemars::JsonSchema)]
pub struct DiffStats {
    /// The solver the forward ran with when the settings asked for `auto`: one whose backward
    /// pass exists ([`differentiable_solver`]); `null` when the settings' own ran.
    pub solver: Option<crate::solver::SolverKind>,
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
    /// Forward steps that stopped at the iteration cap, or in which a global or contact solve
    /// stopped unconverged (capped or stalled).
    pub unconverged_steps: usize,
    /// Unrolled mode: forward steps that met the tolerance in their first local-global
    /// iteration (their first iterate was already the fixed point, e.g. a body at rest or
    /// moving rigidly). Unrolled mode differentiates the iterations run, so through such a step
    /// it returns one iteration's derivative, not the converged step's (docs/gradients.md); 0
    /// in implicit mode and at fixed iteration counts (tolerance 0), which are unaffected.
    pub one_iteration_steps: usize,
    /// Steps whose contact solves ended near a switch of regime (`diff::contact::KINK_MARGIN`):
    /// a contact touching with near-zero gap and impulse, or sticking at the friction cone's
    /// boundary. The loss has a kink there: the gradient is one of its one-sided derivatives
    /// (or between them) and central differences straddling the kink disagree with it. Not an
    /// error; every gradient path warns when it is not 0.
    pub nonsmooth_steps: usize,
    /// Forward steps that ended with a skeleton joint at one of its limits (within 1e-9): the
    /// limit switches there between active and inactive, another kink of the loss. Not an
    /// error; every gradient path warns when it is not 0.
    pub joint_limit_steps: usize,
    /// Implicit mode: largest final relative change of an adjoint fixed point (1).
    pub implicit_residual: f64,
    /// Implicit mode: how far the forward's steps stopped from their converged solutions,
    /// against how far the bodies moved (the steps' estimated distances from convergence,
    /// [`crate::StepStats::distance_to_converged`], summed over the steps, those with contacts
    /// between bodies weighted by [`PAIR_CONTACT_GAP_WEIGHT`], over the summed RMS distance the
    /// vertices moved in them; 0 in unrolled mode or when nothing moved). Implicit mode
    /// differentiates the converged steps, so its gradient differs from the derivative of the
    /// run's own loss by about this share (docs/gradients.md).
    pub forward_gap: f64,
    /// Unrolled mode on a forward stopped by its tolerance: the largest share of a step's
    /// adjoint that reached the step's starting guess (`|x_0 bar| / |x_N bar|`, Eq. G1). Each
    /// iteration's derivative contracts at the iteration's own rate, so where a step met its
    /// tolerance after few iterations for that rate (a slow iteration, or a starting guess close
    /// to the solution) the iterations run carry only part of the converged step's derivative,
    /// and the unrolled gradient differs from it by about this share (docs/gradients.md). 0 in
    /// implicit mode and with a fixed iteration count (tolerance 0), whose unrolled gradient is
    /// the exact derivative of what ran.
    pub unrolled_leftover: f64,
    /// Passes over the linearized contact systems: dense refinement steps (one per solve with
    /// a factor, docs/method.md Eq. C5; one for a set with no touching contact) and
    /// Gauss-Seidel sweeps (sets beyond the dense path).
    pub contact_sweeps: usize,
    /// Largest final relative residual of a linearized contact system (1).
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

/// An adjoint solve whose final relative residual exceeds this has not converged to the
/// accuracy a gradient check needs (converged runs end near 1e-12 and 1e-14).
pub const ADJOINT_RESIDUAL_WARNING: f64 = 1e-6;

/// An implicit-mode [`DiffStats::forward_gap`] above this is warned about: the gradient then
/// differs from the derivative of the run's own loss by about 1e-5 or more. The gap estimates
/// that difference to an order of magnitude: measured 0.4 to 13 times the gap on a clamped
/// beam at tolerances 1e-2 to 1e-10 and fixed counts of 3 to 30 iterations, on bridgesus and
/// on Baymax on the ground, 33 times on a free body at two iterations per step (its rate
/// measured from two changes); an order of magnitude, not a bound: where rigid motion
/// dominates, the elastic parameters' derivatives were off by 75 to 165 times the gap (a free
/// body in flight, docs/gradients.md).
pub const FORWARD_GAP_WARNING: f64 = 1e-5;

/// The weight of a step with contacts between bodies in [`DiffStats::forward_gap`]: there the
/// forward's stopping error reaches the implicit gradient amplified by how the contact set
/// carries it. Measured (docs/gradients.md): a box resting on a cloth, 20 steps, at tolerances
/// 1e-8 to 1e-12, the largest component of the initial-state gradient 390 to 430 times the
/// unweighted gap off the converged derivative with friction and about 1 000 times without;
/// a ball dropped on a cloth, 0.7 to 1.2 times; the box away from the cloth, 0.3 to 0.5 times.
/// Weighted by the largest, the box's gap was 0.66 to 2.5 times its error over 20 to 40 steps
/// (an order of magnitude, not a bound; an overestimate on the ball).
pub const PAIR_CONTACT_GAP_WEIGHT: f64 = 1e3;

/// An unrolled-mode [`DiffStats::unrolled_leftover`] above this is warned about: the gradient
/// can then differ from the converged steps' derivative by about 1e-5 or more of its size.
pub const UNROLLED_LEFTOVER_WARNING: f64 = 1e-5;

impl DiffStats {
    /// What makes a returned gradient less than trustworthy, one sentence each, for every
    /// gradient path to show (the CLI on standard error, Python as `UserWarning`s): unrolled
    /// steps that met the tolerance in their first iteration, steps at a kink of the loss,
    /// adjoint solves that stopped unconverged, and a gradient of a forward that stopped far
    /// from its converged steps (implicit mode) or of iterations whose derivative had not
    /// converged (unrolled mode).
    ///
    /// ```
    /// use diffsoft::diff::DiffStats;
    ///
    /// let mut s = DiffStats::default();
    /// assert!(s.warnings(10).is_empty());
    /// s.nonsmooth_steps = 2;
    /// s.implicit_residual = 1e-3;
    /// assert_eq!(s.warnings(10).len(), 2);
    /// s.forward_gap = 5e-3;
    /// assert!(s.warnings(10)[2].contains("5.0e-3 of the distance the bodies moved"));
    /// ```
    pub fn warnings(&self, steps: usize) -> Vec<String> {
        let mut out = Vec::new();
        if self.one_iteration_steps > 0 {
            out.push(format!(
                "{} of {steps} forward steps met the tolerance in their first iteration; unrolled mode differentiates that one iteration, not the converged step (one_iteration_steps in the stats; use implicit mode, or a tolerance of 0 with a fixed iteration count)",
                self.one_iteration_steps
            ));
        }
        if self.nonsmooth_steps > 0 {
            out.push(format!(
                "{} of {steps} steps ended with a contact at a switch of regime (touching with near-zero gap and force, or sticking at the friction cone's boundary): the loss has a kink there, this gradient is one of its one-sided derivatives or between them, and central differences across the kink disagree with it (nonsmooth_steps in the stats)",
                self.nonsmooth_steps
            ));
        }
        if self.joint_limit_steps > 0 {
            out.push(format!(
                "{} of {steps} steps ended with a joint at one of its limits: the loss has a kink there (the limit switches between holding and not), and this gradient is one of its one-sided derivatives (joint_limit_steps in the stats)",
                self.joint_limit_steps
            ));
        }
        if self.implicit_residual > ADJOINT_RESIDUAL_WARNING {
            out.push(format!(
                "the implicit adjoint stopped at a relative residual of {:.1e} (its iteration cap): the adjoint's share of the gradient's error is about that (the gradient is the converged steps', so a forward stopped at a loose tolerance or a fixed iteration count adds its own error, docs/gradients.md); raise the implicit iteration cap, or use unrolled mode",
                self.implicit_residual
            ));
        }
        if self.forward_gap > FORWARD_GAP_WARNING {
            out.push(format!(
                "implicit mode differentiates the converged steps, and the forward stopped an estimated {:.1e} of the distance the bodies moved from them (forward_gap in the stats; steps with contacts between bodies weigh 1000 times): this gradient can differ from the derivative of the run's own loss by about that much; lower the solver's tolerance (1e-8 or below for implicit mode) or use unrolled mode",
                self.forward_gap
            ));
        }
        if self.unrolled_leftover > UNROLLED_LEFTOVER_WARNING {
            out.push(format!(
                "unrolled mode differentiates the iterations that ran, and in some step {:.1e} of the adjoint was still in the step's starting guess when they stopped (unrolled_leftover in the stats): the forward met its tolerance before the iterations' derivative converged, so this gradient is the derivative of those iterations and can differ from the converged steps' derivative by about that share; for the latter use implicit mode on a converged forward, or a tolerance of 0 with more iterations",
                self.unrolled_leftover
            ));
        }
        if self.contact_residual > ADJOINT_RESIDUAL_WARNING {
            out.push(format!(
                "the linearized contact systems of the backward pass stopped at a relative residual of {:.1e}: the backward's share of the gradient's error is about that",
                self.contact_residual
            ));
        }
        out
    }
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
    /// The first entry of the loss or the gradient that is not finite, named (`"dL/dv_0 of
    /// vertex 3"`), if any.
    pub(crate) fn first_non_finite(&self) -> Option<String> {
        let vectors = |v: &[Vector3<f64>]| v.iter().position(|x| !x.iter().all(|e| e.is_finite()));
        let scalars = |v: &[f64]| v.iter().position(|e| !e.is_finite());
        let rows = |v: &[Vec<f64>]| v.iter().position(|r| r.iter().any(|e| !e.is_finite()));
        if !self.loss.is_finite() {
            return Some("the loss".into());
        }
        let found = [
            vectors(&self.q0).map(|k| format!("dL/dq_0 of vertex {k}")),
            vectors(&self.v0).map(|k| format!("dL/dv_0 of vertex {k}")),
            scalars(&self.w_rot).map(|k| format!("dL/dw_rot of tet {k}")),
            scalars(&self.w_vol).map(|k| format!("dL/dw_vol of tet {k}")),
            scalars(&self.mass).map(|k| format!("dL/dm of vertex {k}")),
            vectors(&self.accel).map(|k| format!("dL/da of vertex {k}")),
            vectors(&self.attachment_targets).map(|k| format!("dL/d target of attachment {k}")),
            rows(&self.activations).map(|k| format!("dL/d activation of step {k}")),
            rows(&self.torques).map(|k| format!("dL/d torque of step {k}")),
            scalars(&self.joints0).map(|k| format!("dL/dz_0 of joint coordinate {k}")),
        ];
        found.into_iter().flatten().next()
    }

    /// `dL/dE_t` per tet (projective: `w_rot = E V/(1+nu)`, `w_vol = nu E V/(1+nu)`;
    /// hyperelastic: through the Lame parameters, whose adjoints are in the tet's `w_rot` and
    /// `w_vol` slots).
    pub fn youngs_modulus(&self, model: &Model) -> Vec<f64> {
        let mut out = vec![0.0; model.tets.len()];
        let per_tet = params::youngs_modulus_per_tet(model);
        for b in &model.bodies {
            let nu = b.material.poisson_ratio;
            for t in b.tets.clone() {
                if b.model.is_hyperelastic() {
                    let (dmu, dla, _, _) = Lame::derivatives(per_tet[t], nu);
                    out[t] = self.w_rot[t] * dmu + self.w_vol[t] * dla;
                    continue;
                }
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

    /// `dL/dnu_t` per tet, at each tet's own Young's modulus (a per-tet modulus included).
    pub fn poisson_ratio(&self, model: &Model) -> Vec<f64> {
        let mut out = vec![0.0; model.tets.len()];
        let per_tet = params::youngs_modulus_per_tet(model);
        for b in &model.bodies {
            let nu = b.material.poisson_ratio;
            for t in b.tets.clone() {
                let e = per_tet[t];
                if b.model.is_hyperelastic() {
                    let (_, _, dmu, dla) = Lame::derivatives(e, nu);
                    out[t] = self.w_rot[t] * dmu + self.w_vol[t] * dla;
                    continue;
                }
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

crate::choice!(Mode {
    Unrolled => "unrolled",
    Implicit => "implicit",
});
