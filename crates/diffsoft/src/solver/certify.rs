//! Certified global solvers: before stepping, compute the spectral radius of the chosen
//! iteration for this mesh, material and time step (the `analysis` module), and refuse or fall
//! back to the direct solver when it would diverge. The certificate goes into the run log.
//!
//! * plain (Eq. 19): `rho = h^2 lambda_max(M^-1 L)`;
//! * split (Eq. 21): `rho(G21)`; contacts use the same iteration (relaxation 1, as the paper);
//! * Chebyshev: the extremes `mu_min <= mu_max < 1` of `G21` give the optimal relaxation
//!   `gamma = 2/(2 - mu_min - mu_max)` with radius `r = (mu_max - mu_min)/(2 - mu_min - mu_max)`,
//!   always below 1, and Chebyshev acceleration with that `r` (asymptotic rate
//!   `r / (1 + sqrt(1 - r^2))`); contacts use the relaxed split iteration with `min(gamma, 1)`;
//! * direct: always converges;
//! * auto: the cheapest of the three for this mesh and time step (`choose.rs`).

use std::time::Instant;

use serde::Serialize;

use super::choose::Candidate;
use super::global::SolverKind;
use super::system::GlobalSystem;
use super::SolverError;
use crate::analysis::spectral::{largest_eigenvalue, EigenMethod};
use crate::analysis::{rho_split, split_extremes, IterationSystem};

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

/// Error reduction a global solve must be able to reach within its iteration cap.
pub const REQUIRED_REDUCTION: f64 = 1e-10;

/// Certify `requested` on `sys` (assembled for time step `h`) under `policy`: the iteration must converge (spectral radius
/// below 1) and reach a [`REQUIRED_REDUCTION`] within `max_iterations` at its asymptotic rate.
pub(crate) fn certify(
    sys: &GlobalSystem,
    h: f64,
    requested: SolverKind,
    policy: CertifyPolicy,
    method: EigenMethod,
    max_iterations: usize,
) -> Result<Certificate, SolverError> {
    let t0 = Instant::now();
    let mut cert = Certificate::unchecked(requested, policy, h);
    if requested == SolverKind::Direct {
        cert.converges = Some(true);
        cert.message = "direct sparse Cholesky: no convergence condition".into();
        return Ok(cert);
    }
    let it = IterationSystem::from_parts(sys.l.clone(), sys.mass.clone(), sys.attachment.clone())
        .map_err(|e| SolverError::input(e.to_string()))?;
    let spectral = |e: crate::analysis::AnalysisError| SolverError::Certification(e.to_string());
    let need_check = policy != CertifyPolicy::Off || requested == SolverKind::Chebyshev;
    if !need_check {
        cert.message = "certification off: the iteration runs unchecked".into();
        return Ok(cert);
    }
    let (rho, name) = match requested {
        SolverKind::Plain => {
            let lam = largest_eigenvalue(&it.op_minv_l(), 0.0, method).map_err(|e| spectral(e.into()))?;
            (h * h * lam, "plain iteration (19): rho(G19) = h^2 lambda_max(M^-1 L)")
        }
        SolverKind::Split => (
            rho_split(&it, h, method).map_err(spectral)?,
            "split iteration (21): rho(G21)",
        ),
        SolverKind::Chebyshev => {
            let (lo, hi) = split_extremes(&it, h, method).map_err(spectral)?;
            let gamma = 2.0 / (2.0 - lo - hi);
            let r = (hi - lo) / (2.0 - lo - hi);
            cert.split_extremes = Some(EigenvalueRange {
                smallest: lo,
                largest: hi,
            });
            cert.relaxation = gamma;
            cert.contact_relaxation = gamma.min(1.0);
            cert.chebyshev_rho = Some(r);
            (r, "relaxed split iteration under Chebyshev acceleration")
        }
        SolverKind::Direct | SolverKind::Auto | SolverKind::Newton => {
            return Err(SolverError::input(format!(
                "{requested:?} has no iteration of its own to certify"
            )))
        }
    };
    cert.spectral_radius = Some(rho);
    cert.elapsed_ms = t0.elapsed().as_secs_f64() * 1e3;
    let converges = rho < 1.0;
    cert.converges = Some(converges);
    let rate = match cert.chebyshev_rho {
        Some(r) => r / (1.0 + (1.0 - r * r).max(0.0).sqrt()),
        None => rho,
    };
    cert.asymptotic_rate = Some(rate);
    let predicted = if rate <= 0.0 {
        1.0
    } else {
        (REQUIRED_REDUCTION.ln() / rate.ln()).ceil()
    };
    if converges {
        cert.predicted_iterations = Some(predicted);
    }
    let fast_enough = converges && predicted <= max_iterations as f64;
    if fast_enough {
        cert.message = format!(
            "{name} = {rho:.6} < 1 at dt = {h:e}: certified to converge (about {predicted} inner iterations per solve)"
        );
        return Ok(cert);
    }
    let why = if converges {
        format!(
            "{name} = {rho:.6} at dt = {h:e}: converges, but needs about {predicted} inner iterations per solve for a {REQUIRED_REDUCTION:e} reduction, above the cap of {max_iterations}"
        )
    } else {
        format!("{name} = {rho:.6} >= 1 at dt = {h:e}: the iteration diverges")
    };
    match policy {
        CertifyPolicy::Refuse => Err(SolverError::Uncertified(format!(
            "{why}; use a smaller time step, --solver direct or chebyshev, or --certify fallback"
        ))),
        CertifyPolicy::Fallback => {
            cert.used = SolverKind::Direct;
            cert.message = format!("{why}; falling back to the direct solver");
            Ok(cert)
        }
        CertifyPolicy::Off => unreachable!(),
    }
}

crate::choice!(CertifyPolicy {
    Off => "off",
    Refuse => "refuse",
    Fallback => "fallback",
});
