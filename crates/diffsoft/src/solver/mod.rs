//! Projective dynamics with implicit Euler (docs/method.md section 2, Eqs. 2-5).
//!
//! One step from `(q_n, v_n)`:
//!
//! 1. inertial target `s_n = q_n + h v_n + h^2 a_ext` (Eq. 2);
//! 2. local-global iterations from `q = s_n`: project every constraint (local, Eq. 3, in
//!    parallel), then solve `(M/h^2 + L) q = M s_n / h^2 + J p` (global, Eq. 5) with the chosen
//!    global solver; stop when the RMS change of `q` is below `tolerance x length scale` or at
//!    the iteration cap;
//! 3. with obstacles or collisions between bodies: candidate contacts come from the start and
//!    predicted positions; each global solve projects contact vertices on their Coulomb cones;
//!    after the iterations, any new penetration adds contacts and the iterations resume (a
//!    bounded number of rounds);
//! 4. `v_{n+1} = damping (q_{n+1} - q_n) / h` (Eq. 4).
//!
//! The system matrix depends only on `h` and the weights, so it is assembled, factored and
//! certified once per model and step size (`System`, shared through [`Systems`]); Newton's method
//! replaces step 2's iterations by Newton iterations on the same energy (`iteration/`). Every
//! buffer is allocated in [`Simulator::new`]. Non-finite values, exploding energy and divergent
//! iterations end the run with a [`SolverError`] that says what happened.
//!
//! Files, by job:
//!
//! * the run: [`Simulator`] (`simulator.rs`), its step as named phases (`step.rs`), the
//!   integrator's explicit phases (`integrator.rs`), its buffers (`work.rs`), settings and stats;
//! * the system: the assembled matrix (`assembled.rs`), the shared `System` with its factor and
//!   certificates (`system.rs`); certification (`certificate.rs`, `certify.rs`) and the default
//!   solver's choice (`choose.rs`);
//! * linear solves: the global solvers behind one trait (`global.rs`: `direct.rs`,
//!   `stationary.rs`), the direct solve's tree-parallel supernodal solve of large systems
//!   (`tree_solve.rs`) and its dense kernels for three right-hand sides (`few_rhs.rs`), the
//!   skeleton's reduced step (`skeletal.rs`), small dense Cholesky and LU (`cholesky.rs`,
//!   `dense_lu.rs`);
//! * contacts: the contact phase (`contacts.rs`), contacts on free vertices (`free_contact.rs`),
//!   the contact-space solve (`contact_space.rs`);
//! * the problem and its iterations: the step's energy, gradient and Hessian (`problem.rs`,
//!   `hessian.rs`), the iterations that minimise it (`iteration/`: local-global with Anderson
//!   acceleration (`anderson.rs`), Newton, Newton with a skeleton, one Newton-CG), observers of a
//!   step (`observer.rs`).

pub(crate) mod anderson;
pub(crate) mod assembled;
pub mod certificate;
pub(crate) mod certify;
mod cholesky;
pub mod choose;
pub(crate) mod contact_space;
pub(crate) mod contacts;
pub(crate) mod dense_lu;
pub(crate) mod direct;
mod error;
mod few_rhs;
pub(crate) mod free_contact;
pub(crate) mod global;
pub(crate) mod hessian;
pub(crate) mod integrator;
pub(crate) mod iteration;
pub(crate) mod observer;
pub(crate) mod problem;
mod settings;
mod simulator;
pub(crate) mod skeletal;
pub(crate) mod stationary;
mod stats;
mod step;
pub(crate) mod system;
pub(crate) mod tree_solve;
mod warm;
pub(crate) mod work;

use nalgebra::Vector3;

pub use certificate::{Candidate, Certificate, CertifyPolicy, EigenvalueRange};
pub use contacts::{PAIR_OBSTACLE, PAIR_TOLERANCE};
pub use error::SolverError;
pub use global::{GlobalStats, SolverKind};
pub use integrator::Integrator;
pub use settings::{Settings, MAX_ANDERSON};
pub(crate) use simulator::Checkpoint;
pub use simulator::{check_initial_positions, Simulator};
pub use stats::StepStats;
pub use system::Systems;

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
