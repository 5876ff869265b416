//! Actuator constraints (METHOD.md section 5, seed Appendix D, Eqs. 39-40).
//!
//! * **Pneumatic cell** with activation `a > 0` (target volume ratio):
//!   `Psi = k_p/2 |F - R(a)|^2` (Eq. 39) with `F = U S V^T` and `R(a) = U (S + D) V^T`,
//!   `D = argmin |D|^2 s.t. prod (S_i + D_i) = a` (Eq. 40): the volume projection
//!   ([`volume::nearest_product`]) with target `a` instead of 1. Inverted `F` (signed
//!   `S_3 < 0`) is projected to the nearest point with all singular values positive.
//! * **Muscle fibre** with rest direction `m` (unit) and activation `a in [0, 1]`: the fibre
//!   `F m` of length `l = |F m|` is pulled to length `1 - a` along itself; the projective target
//!   is `p = (1 - a) F m / |F m|` and `Psi = k_m/2 |F m - p|^2`. This is the normalised form
//!   (METHOD.md: the seed prints the norm without the square and the reference implementation
//!   uses `(1 - a) F m` without normalising; diffsoft uses the normalised target, so an
//!   activation `a` means "fibre length `1 - a`" whatever the current stretch).
//!
//! Both energies are distances to a constraint set, so their gradients with respect to `F` are
//! `k (F - R(a))` and `k (F m - p) m^T` (the target's own variation is orthogonal to the
//! residual at the nearest point).

use nalgebra::{Matrix3, Vector3};

use super::svd::Svd3;
use super::{volume, ProjectionError};

/// Why an actuator projection has no answer (never a silent NaN).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ActuatorError {
    /// The deformation gradient or the direction has non-finite entries.
    #[error("deformation gradient or fibre direction has non-finite entries")]
    NonFinite,
    /// A pneumatic activation outside `(0, inf)` or a muscle activation outside `[0, 1]`.
    #[error("activation {0} is out of range (pneumatic: finite and > 0; muscle: in [0, 1])")]
    BadActivation(f64),
    /// The fibre `F m` has zero length: its direction, and so the target, is undefined.
    #[error("the fibre F m has zero length: its direction is undefined")]
    CollapsedFibre,
    /// The volume projection failed.
    #[error(transparent)]
    Projection(#[from] ProjectionError),
}

/// The pneumatic target `R(a) = U (S + D) V^T` of Eq. 40 for a decomposed `F`.
pub fn pneumatic_target(svd: &Svd3, a: f64) -> Result<Matrix3<f64>, ActuatorError> {
    if !(a.is_finite() && a > 0.0) {
        return Err(ActuatorError::BadActivation(a));
    }
    Ok(svd.compose(&volume::nearest_product(&svd.sigma, a)?))
}

/// The muscle target `p = (1 - a) F m / |F m|` for the fibre `fm = F m`.
pub fn muscle_target(fm: &Vector3<f64>, a: f64) -> Result<Vector3<f64>, ActuatorError> {
    if !(0.0..=1.0).contains(&a) {
        return Err(ActuatorError::BadActivation(a));
    }
    if !fm.iter().all(|v| v.is_finite()) {
        return Err(ActuatorError::NonFinite);
    }
    let l = fm.norm();
    if l == 0.0 || !l.is_finite() {
        return Err(ActuatorError::CollapsedFibre);
    }
    Ok(fm * ((1.0 - a) / l))
}
