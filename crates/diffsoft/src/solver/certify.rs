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

use super::certificate::{Certificate, CertifyPolicy, EigenvalueRange, REQUIRED_REDUCTION};
use super::global::SolverKind;
use super::system::System;
use super::SolverError;
use crate::analysis::rho_split;
use crate::analysis::spectral::{largest_eigenvalue, EigenMethod};

/// Certify `requested` on `sys` (assembled for time step `h`) under `policy`: the iteration must converge (spectral radius
/// below 1) and reach a [`REQUIRED_REDUCTION`] within `max_iterations` at its asymptotic rate.
pub(crate) fn certify(
    sys: &System,
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
    let it = sys.iteration_system()?;
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
            let (lo, hi) = sys.split_extremes(method)?;
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
        // Only Chebyshev is checked under `Off` (it needs the extremes for its parameters):
        // it runs with them as asked, and the certificate says what it will cost.
        CertifyPolicy::Off => {
            cert.message = format!("{why}; certification off: the iteration runs unchecked");
            Ok(cert)
        }
    }
}
