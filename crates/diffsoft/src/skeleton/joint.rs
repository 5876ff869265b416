//! The joint interface: every joint type gives its 4x4 transform (relative to its parent, in
//! the rest frame), the derivative of that transform with respect to each coordinate increment,
//! and its update rule. A new joint type is one file implementing [`Joint`].

use nalgebra::{Matrix3, Matrix4, RealField, Vector3};

/// A joint between a bone and its parent (or the world, for a root).
pub trait Joint: std::fmt::Debug + Send + Sync {
    /// Type name for reports ("free", "rotational", "prismatic", "fixed").
    fn kind(&self) -> &'static str;
    /// Number of coordinates (0, 1 or 6).
    fn dofs(&self) -> usize;
    /// The transform `A` at the current state.
    fn transform(&self) -> Matrix4<f64>;
    /// `dA / dz_k` at the current state, for a coordinate increment `z_k` (paper Eqs. 9, 34, 37).
    fn derivative(&self, k: usize) -> Matrix4<f64>;
    /// Apply an increment `dz` (length `dofs()`) with the joint's update rule (Eqs. 10, 35, 38).
    fn update(&mut self, dz: &[f64]);
    /// The transform after an increment `z`, evaluated in any real field (dual numbers give an
    /// independent derivative of the transform for the Jacobian checks).
    fn transform_dual(&self, z: &[num_dual::Dual64]) -> Matrix4<num_dual::Dual64>;
    /// The transform after an increment `z`, for finite differences: the coordinates moved by
    /// `z` (rotational, prismatic) or the projected update itself (free root, Eq. 10). Its
    /// derivative at `z = 0` is [`Joint::derivative`], as is that of [`Joint::transform_dual`].
    fn transform_after(&self, z: &[f64]) -> Matrix4<f64>;
    /// Current coordinates for reports (angle, extension, or rotation vector and translation).
    fn coordinates(&self) -> Vec<f64>;
    /// The coordinate of a one-DoF joint (angle or extension), `None` for other joints; does
    /// not allocate (for per-iteration use).
    fn scalar(&self) -> Option<f64> {
        None
    }
    /// Bounds `(lo, hi)` on the next increment `dz` of a one-DoF joint that keep its
    /// coordinate within its limits after [`Joint::update`] (infinite where a side cannot be
    /// reached in one update); `None` without limits. The reduced step enforces them as
    /// constraints together with the contacts.
    fn increment_bounds(&self) -> Option<(f64, f64)> {
        None
    }
    /// `d bound / d coordinate` of an active increment bound of [`Joint::increment_bounds`]
    /// whose value is `bound` (`-(1 + bound^2)` for a rotational joint, whose bound is
    /// `tan(limit - angle)`; `-1` for a prismatic one); 0 without limits.
    fn increment_bound_derivative(&self, _bound: f64) -> f64 {
        0.0
    }
    /// Set the coordinates (same layout as [`Joint::coordinates`]).
    fn set_coordinates(&mut self, c: &[f64]);
    /// Length of the raw state of [`Joint::write_state`] (12 for a free root: rotation and
    /// translation; 1 for rotational and prismatic joints; 0 for fixed ones).
    fn state_len(&self) -> usize;
    /// Write the raw state (exact, for checkpoints of the backward pass).
    fn write_state(&self, out: &mut [f64]);
    /// Restore a raw state written by [`Joint::write_state`].
    fn read_state(&mut self, s: &[f64]);
    /// `dA / dz_k` at the state moved by the increment `z` (the chart of [`Joint::transform_dual`]),
    /// in dual numbers: its derivative gives the second derivatives of `A` that the backward pass
    /// contracts with the adjoint of `B` (Eqs. 12-16).
    fn derivative_dual(&self, z: &[num_dual::Dual64], k: usize) -> Matrix4<num_dual::Dual64>;
    /// Jacobians of the update rule (Eqs. 10, 35, 38) at the current state and increment `dz`,
    /// in the charts of [`Joint::transform_dual`] before and after the update: row-major
    /// `dofs x dofs` blocks `(d z_after / d z_before, d z_after / d dz)`, written into `jz` and
    /// `jdz` (each of length `dofs^2`). Zero where a limit clamps the update.
    fn update_jacobians(&self, dz: &[f64], jz: &mut [f64], jdz: &mut [f64]);
    /// A boxed copy.
    fn boxed_clone(&self) -> Box<dyn Joint>;
}

/// `[v]x`, the cross-product matrix.
pub fn skew<T: RealField + Copy>(v: &Vector3<T>) -> Matrix3<T> {
    let z = T::zero();
    Matrix3::new(z, -v.z, v.y, v.z, z, -v.x, -v.y, v.x, z)
}

/// A homogeneous transform from a linear part and a translation.
pub fn homogeneous<T: RealField + Copy>(m: &Matrix3<T>, t: &Vector3<T>) -> Matrix4<T> {
    let mut a = Matrix4::identity();
    a.fixed_view_mut::<3, 3>(0, 0).copy_from(m);
    a.fixed_view_mut::<3, 1>(0, 3).copy_from(t);
    a
}

/// The same with a zero bottom row (a derivative of a transform).
pub fn homogeneous_derivative<T: RealField + Copy>(m: &Matrix3<T>, t: &Vector3<T>) -> Matrix4<T> {
    let mut a = Matrix4::zeros();
    a.fixed_view_mut::<3, 3>(0, 0).copy_from(m);
    a.fixed_view_mut::<3, 1>(0, 3).copy_from(t);
    a
}

/// Lift a plain matrix to dual numbers (zero derivative).
pub fn dual_matrix4(m: &Matrix4<f64>) -> Matrix4<num_dual::Dual64> {
    m.map(num_dual::Dual64::from)
}
