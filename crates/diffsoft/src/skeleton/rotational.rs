//! Rotational joint (appendix C, Eqs. 32-35): rotation by `theta` about the unit axis `n`
//! through the joint position `p` (rest frame):
//! `A = [R, p - R p; 0, 1]`, `R = cos t I + sin t [n]x + (1 - cos t) n n^T` (33),
//! `dR/dt = -sin t I + cos t [n]x + sin t n n^T` (34), and the update
//! `t <- atan2(sin t + cos t dt, cos t - sin t dt)` (35), which keeps the angle on the circle
//! (it adds `atan(dt)`, equal to `dt` to first order).

use nalgebra::{Matrix3, Matrix4, RealField, Vector3};
use num_dual::Dual64;

use super::joint::{homogeneous, homogeneous_derivative, skew, Joint};

/// A 1-DoF rotational joint.
#[derive(Debug, Clone, PartialEq)]
pub struct Rotational {
    /// Joint position (rest frame).
    pub position: Vector3<f64>,
    /// Unit rotation axis (rest frame).
    pub axis: Vector3<f64>,
    /// Current angle, in `(-pi, pi]`.
    pub angle: f64,
    /// Optional angle limits `(min, max)`.
    pub limits: Option<(f64, f64)>,
}

/// Rodrigues' formula (Eq. 33).
pub fn rodrigues<T: RealField + Copy>(n: &Vector3<T>, t: T) -> Matrix3<T> {
    let (s, c) = (t.sin(), t.cos());
    Matrix3::identity() * c + skew(n) * s + n * n.transpose() * (T::one() - c)
}

/// Its derivative with respect to the angle (Eq. 34).
pub fn rodrigues_derivative<T: RealField + Copy>(n: &Vector3<T>, t: T) -> Matrix3<T> {
    let (s, c) = (t.sin(), t.cos());
    -Matrix3::identity() * s + skew(n) * c + n * n.transpose() * s
}

impl Rotational {
    /// A joint at `position` about `axis` (normalised here by [`crate::base::unit_vector`], which no
    /// finite axis over- or underflows; a zero or non-finite axis, which the scene loaders refuse,
    /// gives the zero axis) at angle 0.
    ///
    /// ```
    /// use diffsoft::skeleton::rotational::Rotational;
    /// use diffsoft::skeleton::Joint;
    /// use nalgebra::{Vector3, Vector4};
    ///
    /// let hinge = Rotational::new(Vector3::x(), Vector3::new(0.0, 0.0, 2.0));
    /// assert_eq!(hinge.axis, Vector3::z());
    /// assert_eq!((hinge.angle, hinge.dofs()), (0.0, 1));
    /// // A quarter turn about z through (1, 0, 0) takes (2, 0, 0) to (1, 1, 0).
    /// let q = hinge.transform_at(std::f64::consts::FRAC_PI_2) * Vector4::new(2.0, 0.0, 0.0, 1.0);
    /// assert!((q - Vector4::new(1.0, 1.0, 0.0, 1.0)).norm() < 1e-12);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(position: Vector3<f64>, axis: Vector3<f64>) -> Self {
        Self {
            position,
            axis: crate::base::unit_vector(axis).unwrap_or(Vector3::zeros()),
            angle: 0.0,
            limits: None,
        }
    }

    /// The transform at angle `t`, in any real field.
    pub fn transform_at<T: RealField + Copy>(&self, t: T) -> Matrix4<T> {
        let n = self.axis.map(|x| T::from_f64(x).expect("f64 converts"));
        let p = self.position.map(|x| T::from_f64(x).expect("f64 converts"));
        let r = rodrigues(&n, t);
        homogeneous(&r, &(p - r * p))
    }

    /// Eq. 35: the angle after an increment `dt`, kept in `(-pi, pi]`.
    pub fn updated_angle(angle: f64, dt: f64) -> f64 {
        let (s, c) = angle.sin_cos();
        (s + c * dt).atan2(c - s * dt)
    }
}

impl Joint for Rotational {
    fn kind(&self) -> &'static str {
        "rotational"
    }
    fn dofs(&self) -> usize {
        1
    }
    fn transform(&self) -> Matrix4<f64> {
        self.transform_at(self.angle)
    }
    fn derivative(&self, _k: usize) -> Matrix4<f64> {
        let dr = rodrigues_derivative(&self.axis, self.angle);
        homogeneous_derivative(&dr, &(-dr * self.position))
    }
    fn update(&mut self, dz: &[f64]) {
        self.angle = Self::updated_angle(self.angle, dz[0]);
        if let Some((lo, hi)) = self.limits {
            self.angle = self.angle.clamp(lo, hi);
        }
    }
    fn transform_dual(&self, z: &[Dual64]) -> Matrix4<Dual64> {
        self.transform_at(Dual64::from(self.angle) + z[0])
    }
    fn transform_after(&self, z: &[f64]) -> Matrix4<f64> {
        self.transform_at(self.angle + z[0])
    }
    fn coordinates(&self) -> Vec<f64> {
        vec![self.angle]
    }
    fn scalar(&self) -> Option<f64> {
        Some(self.angle)
    }
    fn increment_bounds(&self) -> Option<(f64, f64)> {
        // Eq. 35 moves the angle by atan(dz): angle + atan(dz) in [lo, hi].
        use std::f64::consts::FRAC_PI_2;
        let (lo, hi) = self.limits?;
        let (a, b) = (lo - self.angle, hi - self.angle);
        let lower = if a <= -FRAC_PI_2 {
            f64::NEG_INFINITY
        } else {
            a.min(FRAC_PI_2 - 1e-6).tan()
        };
        let upper = if b >= FRAC_PI_2 {
            f64::INFINITY
        } else {
            b.max(-FRAC_PI_2 + 1e-6).tan()
        };
        Some((lower, upper))
    }
    fn increment_bound_derivative(&self, bound: f64) -> f64 {
        -(1.0 + bound * bound)
    }
    fn set_coordinates(&mut self, c: &[f64]) {
        self.angle = Self::updated_angle(c[0], 0.0);
    }
    fn state_len(&self) -> usize {
        1
    }
    fn write_state(&self, out: &mut [f64]) {
        out[0] = self.angle;
    }
    fn read_state(&mut self, s: &[f64]) {
        self.angle = s[0];
    }
    fn derivative_dual(&self, z: &[Dual64], _k: usize) -> Matrix4<Dual64> {
        let n = self.axis.map(Dual64::from);
        let p = self.position.map(Dual64::from);
        let dr = rodrigues_derivative(&n, Dual64::from(self.angle) + z[0]);
        homogeneous_derivative(&dr, &(-dr * p))
    }
    fn update_jacobians(&self, dz: &[f64], jz: &mut [f64], jdz: &mut [f64]) {
        // Eq. 35 adds atan(dz): d/d angle = 1, d/d dz = 1 / (1 + dz^2); a clamp makes both 0.
        let raw = Self::updated_angle(self.angle, dz[0]);
        let clamped = self.limits.is_some_and(|(lo, hi)| raw < lo || raw > hi);
        if clamped {
            jz[0] = 0.0;
            jdz[0] = 0.0;
        } else {
            jz[0] = 1.0;
            jdz[0] = 1.0 / (1.0 + dz[0] * dz[0]);
        }
    }
    fn boxed_clone(&self) -> Box<dyn Joint> {
        Box::new(self.clone())
    }
}
