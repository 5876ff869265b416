//! Math on one element, shared by the forward and the backward pass: the projections of the
//! projective constraints (docs/method.md section 2, Eq. 3) and their derivatives. Each maps the
//! current state of an element to the nearest point `p` of its constraint set; the energy is
//! `w/2 |G q - p|^2`. Nothing here knows a model or a mesh.
//!
//! * [`svd`]: the signed, rotation-preserving 3 x 3 SVD (scalar, warm-started and batched
//!   AVX2 kernels);
//! * [`corotated`]: `F` onto the rotations (as-rigid-as-possible);
//! * [`volume`]: `F` onto `det F = a` through its singular values (also the pneumatic cell of
//!   docs/method.md Eq. 40);
//! * [`actuator`]: pneumatic cells and muscle fibres (docs/method.md section 5, Eqs. 39-40),
//!   their Jacobians and dual-number references;
//! * [`linearization`]: the differential of a tet's weighted corotated + volume projection
//!   (the spectral-function differential, docs/method.md section 7);
//! * [`polar32`]: the polar decomposition of a 3 x 2 in-plane deformation gradient (cloth
//!   stretching) and its differential.

pub mod actuator;
pub mod corotated;
pub mod hyperelastic;
pub mod linearization;
pub mod polar32;
pub mod svd;
pub mod volume;

/// Failure of a constraint projection (never a silent NaN).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
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
