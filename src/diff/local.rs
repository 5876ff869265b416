//! Transitional paths of the local step's linearization (now in [`crate::kernel::linearization`]
//! and [`crate::constraint`]).

use nalgebra::{Matrix3, Vector3};

#[doc(hidden)]
pub use crate::kernel::linearization::TetLinearization;
use crate::model::Model;

/// `F_t(x)`: see [`Model::tet_deformation`].
#[doc(hidden)]
pub fn deformation(model: &Model, t: usize, x: &[Vector3<f64>]) -> Matrix3<f64> {
    model.tet_deformation(t, x)
}
