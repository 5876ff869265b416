//! The settings of a simulation: time step and integrator, global solver and its certification, iteration caps
//! and tolerances, damping, contact handling, Anderson acceleration.

use serde::Serialize;

use super::certify::CertifyPolicy;
use super::global::SolverKind;
use super::integrator::Integrator;
use super::SolverError;
use crate::analysis::spectral::EigenMethod;

/// Solver settings.
#[derive(Debug, Clone, Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct Settings {
    /// Time step (s).
    pub dt: f64,
    /// Time integrator (default implicit Euler; `bdf2` is second order, docs/method.md
    /// Eqs. T1-T3).
    pub integrator: Integrator,
    /// Global solver (default `auto`: the cheapest for the mesh and time step).
    pub solver: SolverKind,
    /// Certification policy for iterative solvers.
    pub certify: CertifyPolicy,
    /// Local-global iteration cap per step.
    pub max_iterations: usize,
    /// Stop when the RMS change of the positions is below `tolerance x length scale` (1).
    pub tolerance: f64,
    /// Inner iterations stop when no coordinate moves more than this `x length scale` (1).
    pub inner_tolerance: f64,
    /// Inner iteration cap (iterative global solvers, contact sweeps).
    pub inner_max_iterations: usize,
    /// Velocity damping factor per step (1; 1 = none; the paper uses 0.9999).
    pub damping: f64,
    /// Contact detection margin, as a fraction of the length scale (1).
    pub contact_margin: f64,
    /// Largest number of detect-and-resolve rounds per step.
    pub contact_rounds: usize,
    /// Eigensolver for certification.
    pub eigen_method: EigenMethod,
    /// Anderson acceleration memory of the local-global iteration (0: off, the paper's plain
    /// iteration).
    pub anderson: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            dt: 0.01,
            integrator: Integrator::ImplicitEuler,
            solver: SolverKind::Auto,
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
    /// Check the settings are meaningful.
    pub(crate) fn validate(&self) -> Result<(), SolverError> {
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
