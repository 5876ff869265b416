//! Fixed joint: a bone welded to its parent (or, as a root, to the world). No coordinates.

use nalgebra::Matrix4;
use num_dual::Dual64;

use super::joint::Joint;

/// A 0-DoF joint.
///
/// ```
/// use diffsoft::skeleton::fixed::Fixed;
/// use diffsoft::skeleton::Joint;
/// use nalgebra::Matrix4;
///
/// let weld = Fixed;
/// assert_eq!((weld.kind(), weld.dofs()), ("fixed", 0));
/// assert_eq!(weld.transform(), Matrix4::identity());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Fixed;

impl Joint for Fixed {
    fn kind(&self) -> &'static str {
        "fixed"
    }
    fn dofs(&self) -> usize {
        0
    }
    fn transform(&self) -> Matrix4<f64> {
        Matrix4::identity()
    }
    fn derivative(&self, k: usize) -> Matrix4<f64> {
        unreachable!("a fixed joint has no coordinate {k}")
    }
    fn update(&mut self, _dz: &[f64]) {}
    fn transform_dual(&self, _z: &[Dual64]) -> Matrix4<Dual64> {
        Matrix4::identity()
    }
    fn transform_after(&self, _z: &[f64]) -> Matrix4<f64> {
        Matrix4::identity()
    }
    fn coordinates(&self) -> Vec<f64> {
        Vec::new()
    }
    fn set_coordinates(&mut self, _c: &[f64]) {}
    fn state_len(&self) -> usize {
        0
    }
    fn write_state(&self, _out: &mut [f64]) {}
    fn read_state(&mut self, _s: &[f64]) {}
    fn derivative_dual(&self, _z: &[Dual64], k: usize) -> Matrix4<Dual64> {
        unreachable!("a fixed joint has no coordinate {k}")
    }
    fn update_jacobians(&self, _dz: &[f64], _jz: &mut [f64], _jdz: &mut [f64]) {}
    fn boxed_clone(&self) -> Box<dyn Joint> {
        Box::new(self.clone())
    }
}
