//! The per-step buffers of a run and the state one step back (BDF2), allocated once in
//! [`Simulator::new`](super::Simulator::new) and lent to the step's phases and iteration.

use nalgebra::Vector3;

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
