//! Prismatic joint (appendix C, Eqs. 36-38): translation by `l` along the unit axis `u`,
//! `A = [I, l u; 0, 1]`, `dA/dl = [0, u; 0, 0]`, update `l <- l + dl`.

use nalgebra::{Matrix3, Matrix4, RealField, Vector3};
use num_dual::Dual64;

use super::joint::{homogeneous, homogeneous_derivative, Joint};

/// A 1-DoF prismatic joint.
#[derive(Debug, Clone, PartialEq)]
pub struct Prismatic {
    /// Unit axis (rest frame).
    pub axis: Vector3<f64>,
    /// Current extension.
    pub extension: f64,
    /// Optional limits `(min, max)`.
    pub limits: Option<(f64, f64)>,
}

impl Prismatic {
    /// A joint along `axis` (normalised here by [`crate::base::unit_vector`], which no finite axis
    /// over- or underflows; a zero or non-finite axis, which the scene loaders refuse, gives the
    /// zero axis) at extension 0.
    ///
    /// ```
    /// use diffsoft::skeleton::prismatic::Prismatic;
    /// use diffsoft::skeleton::Joint;
    /// use nalgebra::{Vector3, Vector4};
    ///
    /// let mut slider = Prismatic::new(Vector3::new(0.0, 3.0, 0.0));
    /// assert_eq!(slider.axis, Vector3::y());
    /// slider.update(&[0.5]);
    /// assert_eq!(slider.extension, 0.5);
    /// let q = slider.transform() * Vector4::new(1.0, 0.0, 0.0, 1.0);
    /// assert_eq!(q, Vector4::new(1.0, 0.5, 0.0, 1.0));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(axis: Vector3<f64>) -> Self {
        Self {
            axis: crate::base::unit_vector(axis).unwrap_or(Vector3::zeros()),
            extension: 0.0,
            limits: None,
        }
    }

    /// The transform at extension `l`, in any real field.
    pub fn transform_at<T: RealField + Copy>(&self, l: T) -> Matrix4<T> {
        let u = self.axis.map(|x| T::from_f64(x).expect("f64 converts"));
        homogeneous(&Matrix3::identity(), &(u * l))
    }
}

impl Joint for Prismatic {
    fn kind(&self) -> &'static str {
        "prismatic"
    }
    fn dofs(&self) -> usize {
        1
    }
    fn transform(&self) -> Matrix4<f64> {
        self.transform_at(self.extension)
    }
    fn derivative(&self, _k: usize) -> Matrix4<f64> {
        homogeneous_derivative(&Matrix3::zeros(), &self.axis)
    }
    fn update(&mut self, dz: &[f64]) {
        self.extension += dz[0];
        if let Some((lo, hi)) = self.limits {
            self.extension = self.extension.clamp(lo, hi);
        }
    }
    fn transform_dual(&self, z: &[Dual64]) -> Matrix4<Dual64> {
        self.transform_at(Dual64::from(self.extension) + z[0])
    }
    fn increment_bounds(&self) -> Option<(f64, f64)> {
        let (lo, hi) = self.limits?;
        Some((lo - self.extension, hi - self.extension))
    }
    fn transform_after(&self, z: &[f64]) -> Matrix4<f64> {
        self.transform_at(self.extension + z[0])
    }
    fn coordinates(&self) -> Vec<f64> {
        vec![self.extension]
    }
    fn scalar(&self) -> Option<f64> {
        Some(self.extension)
    }
    fn increment_bound_derivative(&self, _bound: f64) -> f64 {
        -1.0
    }
    fn set_coordinates(&mut self, c: &[f64]) {
        self.extension = c[0];
    }
    fn state_len(&self) -> usize {
        1
    }
    fn write_state(&self, out: &mut [f64]) {
        out[0] = self.extension;
    }
    fn read_state(&mut self, s: &[f64]) {
        self.extension = s[0];
    }
    fn derivative_dual(&self, _z: &[Dual64], _k: usize) -> Matrix4<Dual64> {
        super::joint::dual_matrix4(&self.derivative(0))
    }
    fn update_jacobians(&self, dz: &[f64], jz: &mut [f64], jdz: &mut [f64]) {
        let raw = self.extension + dz[0];
        let clamped = self.limits.is_some_and(|(lo, hi)| raw < lo || raw > hi);
        let d = if clamped { 0.0 } else { 1.0 };
        jz[0] = d;
        jdz[0] = d;
    }
    fn boxed_clone(&self) -> Box<dyn Joint> {
        Box::new(self.clone())
    }
}
