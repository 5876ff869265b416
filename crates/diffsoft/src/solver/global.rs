//! The global step of projective dynamics (docs/method.md Eq. 5): solve
//! `(M/h^2 + L) q = M s_n / h^2 + J p` on the free vertices, for x, y and z at once (the axes
//! share the per-axis matrix). Every solver implements [`GlobalSolver`]:
//!
//! * [`Direct`](super::direct::Direct): sparse Cholesky, factored once and reused; contacts by
//!   projected Gauss-Seidel on the contact-space (Delassus) operator (Eq. C4);
//! * [`Stationary`](super::stationary::Stationary): the paper's iterations in position form,
//!   plain (Eq. 19) or split (Eq. 21), relaxed and Chebyshev-accelerated, with the contact cone
//!   projection inside the iteration.

use nalgebra::Vector3;
use serde::Serialize;

use super::assembled::GlobalSystem;
use super::free_contact::FreeContact;
use super::SolverError;

/// Which global solver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SolverKind {
    /// Sparse Cholesky of `M/h^2 + L`, factored once.
    Direct,
    /// Eq. 19: `M/h^2 x' = b - L x`.
    Plain,
    /// Eq. 21: `(M/h^2 + D) x' = b - (L - D) x`.
    Split,
    /// Eq. 21, relaxed and Chebyshev-accelerated with parameters from the spectral analysis.
    Chebyshev,
    /// The cheapest of direct, split and Chebyshev for this mesh and time step, predicted by
    /// certification.
    Auto,
    /// Newton's method on the step's energy (docs/method.md Eqs. S3-S5) instead of local-global
    /// iterations: projected Hessian, conjugate gradients preconditioned with the factored
    /// `M/h^2 + L`, Armijo line search. Tets, actuators, fixed vertices, attachments and
    /// gravity only; never chosen by auto.
    Newton,
}

/// What one global solve did.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct GlobalStats {
    /// Inner iterations (0 for a direct solve without contacts).
    pub iterations: usize,
    /// Largest update of the last inner iteration (m), or 0 for a direct solve.
    pub last_update: f64,
    /// Contact iterations (projected Gauss-Seidel sweeps for `Direct`).
    pub contact_iterations: usize,
    /// Whether the inner iteration met its tolerance before its cap.
    pub converged: bool,
}

/// Solves the global step.
pub(crate) trait GlobalSolver: Send {
    /// Which solver this is.
    fn kind(&self) -> SolverKind;

    /// Solve `(M/h^2 + L) x = b` on the free vertices with the given contacts; `x` holds an
    /// initial guess on entry and the solution on exit.
    fn solve(
        &mut self,
        sys: &GlobalSystem,
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
        contacts: &[FreeContact],
    ) -> Result<GlobalStats, SolverError>;

    /// A new time step begins (solvers that keep per-step state reset it).
    fn begin_step(&mut self) {}

    /// Whether a solve runs parallel work of its own (then the pool's workers are not kept
    /// spinning through it, see `warm`).
    fn parallel_inside(&self) -> bool {
        false
    }

    /// The contact impulses the last solve ended with, one per contact in the order given
    /// (`None`: this solver projects contacts inside its iteration and keeps no impulses).
    fn impulses(&self) -> Option<&[Vector3<f64>]> {
        None
    }

    /// The contact impulses of the last solve for output (VTK frames): those of
    /// [`GlobalSolver::impulses`], or the last projection's of a solver that keeps none for
    /// the backward pass.
    fn contact_impulses(&self) -> Option<&[Vector3<f64>]> {
        self.impulses()
    }
}

/// Tolerances of the inner iterations.
#[derive(Debug, Clone, Copy)]
pub(crate) struct InnerControl {
    /// Stop when the largest update is below this (m).
    pub tolerance: f64,
    /// Iteration cap.
    pub max_iterations: usize,
}

crate::choice!(SolverKind {
    Direct => "direct",
    Plain => "plain",
    Split => "split",
    Chebyshev => "chebyshev",
    Auto => "auto",
    Newton => "newton",
});
