//! What certification says about a solver on a system ([`Certificate`]), and the policy and
//! thresholds it applies.

use serde::Serialize;

use super::global::SolverKind;

/// What to do when the chosen iteration would diverge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum CertifyPolicy {
    /// Do not check (the run detects divergence when it happens).
    Off,
    /// Stop with an error before stepping.
    Refuse,
    /// Use the direct solver instead.
    Fallback,
}

/// The smallest and largest eigenvalue of an iteration matrix.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, schemars::JsonSchema)]
pub struct EigenvalueRange {
    /// Smallest eigenvalue (1).
    pub smallest: f64,
    /// Largest eigenvalue (1).
    pub largest: f64,
}

/// The outcome of certification.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Certificate {
    /// Solver asked for.
    pub requested: SolverKind,
    /// Solver used.
    pub used: SolverKind,
    /// Policy.
    pub policy: CertifyPolicy,
    /// Time step certified (s).
    pub dt: f64,
    /// Spectral radius of the requested iteration (1; null for direct or when not checked;
    /// auto: of the iteration chosen, split's possibly the row-sum bound, Chebyshev's `r`).
    pub spectral_radius: Option<f64>,
    /// Extreme eigenvalues of `G21` (Chebyshev only).
    pub split_extremes: Option<EigenvalueRange>,
    /// Relaxation of the iteration without contacts (1).
    pub relaxation: f64,
    /// Relaxation of the projected contact iteration (1).
    pub contact_relaxation: f64,
    /// Chebyshev's spectral radius parameter (1).
    pub chebyshev_rho: Option<f64>,
    /// Whether the requested iteration converges at this time step.
    pub converges: Option<bool>,
    /// Asymptotic error reduction per inner iteration (1; `rho`; Chebyshev: `r / (1 + sqrt(1 -
    /// r^2))`).
    pub asymptotic_rate: Option<f64>,
    /// Inner iterations predicted for a `1e-10` error reduction, `ln(1e-10) / ln(rate)` (auto:
    /// the chosen iteration's predicted iterations per warm-started solve, see `candidates`).
    pub predicted_iterations: Option<f64>,
    /// Auto only: each candidate solver's measured and predicted cost, from which the
    /// cheapest was chosen (empty when a solver was requested).
    pub candidates: Vec<Candidate>,
    /// What happened, in words.
    pub message: String,
    /// Time spent on certification: the eigenvalue computation, and for auto the timings (ms).
    pub elapsed_ms: f64,
}

impl Certificate {
    /// A certificate that `requested` runs as requested, with nothing checked yet.
    pub(crate) fn unchecked(requested: SolverKind, policy: CertifyPolicy, dt: f64) -> Self {
        Self {
            requested,
            used: requested,
            policy,
            dt,
            spectral_radius: None,
            split_extremes: None,
            relaxation: 1.0,
            contact_relaxation: 1.0,
            chebyshev_rho: None,
            converges: None,
            asymptotic_rate: None,
            predicted_iterations: None,
            candidates: Vec::new(),
            message: String::new(),
            elapsed_ms: 0.0,
        }
    }
}

/// What one candidate solver is predicted to cost.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Candidate {
    /// The solver.
    pub solver: SolverKind,
    /// Whether it can run here (iterative: certified as a requested iteration would be, and
    /// predicted within the inner iteration cap; direct: factored).
    pub eligible: bool,
    /// Predicted inner iterations per solve (iterative only).
    pub predicted_iterations: Option<f64>,
    /// Measured cost of one inner iteration (ms; iterative only).
    pub cost_per_iteration_ms: Option<f64>,
    /// Measured (direct) or predicted (iterative) cost of one solve (ms).
    pub cost_per_solve_ms: Option<f64>,
    /// One-off cost: the factorisation (direct) or the eigenvalue computation (iterative), ms.
    pub setup_ms: f64,
    /// Predicted cost of the setup and `AMORTISED_SOLVES` solves (ms).
    pub predicted_ms: Option<f64>,
}

/// Error reduction a global solve must be able to reach within its iteration cap.
pub const REQUIRED_REDUCTION: f64 = 1e-10;

crate::choice!(CertifyPolicy {
    Off => "off",
    Refuse => "refuse",
    Fallback => "fallback",
});
