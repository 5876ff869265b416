//! Corotated (as-rigid-as-possible) constraint: project `F` onto the rotations,
//! `p = U V^T` with `det U = det V = +1`, so an inverted tet is pulled back to a rotation
//! rather than to a reflection (docs/method.md section 2).

use nalgebra::Matrix3;

use super::svd::Svd3;

/// The nearest rotation to the decomposed `F`.
#[inline]
pub fn project(svd: &Svd3) -> Matrix3<f64> {
    svd.rotation()
}
