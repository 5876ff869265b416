//! A plane obstacle: the half-space `n . (x - point) >= 0` (the ground; docs/method.md Eq. C2).

use nalgebra::Vector3;

use super::Shape;
use crate::base::InputError;

/// The half-space `n . (x - point) >= 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// A point on the plane.
    pub point: Vector3<f64>,
    /// Unit normal pointing into the free side.
    pub normal: Vector3<f64>,
}

impl Plane {
    /// The plane through `point` with normal `normal` (normalised here).
    ///
    /// ```
    /// use diffsoft::contact::{Plane, Shape};
    /// use nalgebra::Vector3;
    ///
    /// let slope = Plane::new(Vector3::zeros(), Vector3::new(1.0, 1.0, 0.0));
    /// assert!((slope.normal.norm() - 1.0).abs() < 1e-15);
    /// assert!(slope.piecewise_planar());
    /// slope.validate()?;
    /// // (1, 0, 0) is 1/sqrt(2) above it.
    /// let x = Vector3::x();
    /// let (d, _, _) = slope.query(&x, &x, 1.0, 0.0).ok_or("beyond the margin")?;
    /// assert!((d - 0.5f64.sqrt()).abs() < 1e-12);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(point: Vector3<f64>, normal: Vector3<f64>) -> Self {
        Self {
            point,
            // A zero normal stays zero, for `validate` to refuse.
            normal: crate::base::unit_vector(normal).unwrap_or(normal),
        }
    }
}

impl Shape for Plane {
    fn piecewise_planar(&self) -> bool {
        true
    }

    fn query(
        &self,
        _from: &Vector3<f64>,
        x: &Vector3<f64>,
        margin: f64,
        thickness: f64,
    ) -> Option<(f64, Vector3<f64>, Vector3<f64>)> {
        let d = self.normal.dot(&(x - self.point)) - thickness;
        (d < margin).then(|| (d, self.normal, self.point + self.normal * thickness))
    }

    fn validate(&self) -> Result<(), InputError> {
        let (point, normal) = (&self.point, &self.normal);
        if !point.iter().chain(normal.iter()).all(|v| v.is_finite()) || (normal.norm() - 1.0).abs() > 1e-9 {
            return Err(InputError::new(
                "plane point and normal must be finite, normal of unit length",
            ));
        }
        Ok(())
    }

    fn kind(&self) -> &'static str {
        "plane"
    }
}
