//! Projective constraints (METHOD.md section 2): each maps the current state of an element to
//! the nearest point `p` of its constraint set; the energy is `w/2 |G q - p|^2`.
//!
//! * [`corotated`]: `F` onto the rotations (as-rigid-as-possible);
//! * [`volume`]: `F` onto `det F = a` through its singular values (also the pneumatic cell of
//!   seed Eq. 40);
//! * [`attachment`]: a vertex onto a target point;
//! * [`actuator`]: pneumatic cells and muscle fibres (seed Appendix D, Eqs. 39-40).
//!
//! [`svd`] provides the signed, rotation-preserving 3 x 3 SVD they share.

pub mod actuator;
pub mod attachment;
pub mod corotated;
pub mod svd;
pub mod volume;

/// Failure of a constraint projection (never a silent NaN).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ProjectionError {
    /// The input has NaN or infinite entries.
    #[error("deformation gradient has non-finite entries")]
    NonFinite,
    /// The target volume ratio is not finite and positive.
    #[error("target volume ratio must be finite and positive, got {0}")]
    BadTarget(f64),
    /// The projection's root finder did not converge.
    #[error("volume projection did not converge")]
    NoConvergence,
}

/// Energy `w/2 |F - p|^2` of one constraint.
#[inline]
pub fn energy(weight: f64, f: &nalgebra::Matrix3<f64>, p: &nalgebra::Matrix3<f64>) -> f64 {
    0.5 * weight * (f - p).norm_squared()
}
