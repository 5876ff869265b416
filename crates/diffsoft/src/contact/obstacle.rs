//! A static obstacle: a shape with its name, friction (the cone of Eq. C1) and collision
//! thickness (Eq. C2; docs/method.md section 4).

use std::sync::Arc;

use nalgebra::Vector3;

use super::{Plane, Shape};
use crate::base::InputError;

/// A static obstacle with its friction coefficient.
#[derive(Debug, Clone)]
pub struct Obstacle {
    /// Name for reports.
    pub name: String,
    /// Geometry.
    pub shape: Arc<dyn Shape>,
    /// Coulomb friction coefficient `mu_f >= 0`.
    pub friction: f64,
    /// Collision thickness: vertices are kept this far from the surface.
    pub thickness: f64,
}

impl Obstacle {
    /// An obstacle of any shape.
    pub fn new(name: &str, shape: impl Shape + 'static, friction: f64, thickness: f64) -> Self {
        Self {
            name: name.to_string(),
            shape: Arc::new(shape),
            friction,
            thickness,
        }
    }

    /// A ground plane through `point` with normal `normal` (normalised here), no thickness.
    pub fn plane(name: &str, point: Vector3<f64>, normal: Vector3<f64>, friction: f64) -> Self {
        Self::new(name, Plane::new(point, normal), friction, 0.0)
    }

    /// Check the parameters.
    pub fn validate(&self) -> Result<(), InputError> {
        let bad = |m: String| Err(InputError::new(format!("obstacle '{}': {m}", self.name)));
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return bad(format!("friction must be finite and >= 0, got {}", self.friction));
        }
        if !(self.thickness.is_finite() && self.thickness >= 0.0) {
            return bad(format!("thickness must be finite and >= 0, got {}", self.thickness));
        }
        self.shape
            .validate()
            .map_err(|e| InputError::new(format!("obstacle '{}': {}", self.name, e.message())))
    }

    /// Signed distance of `x` to the surface minus the thickness, with the contact normal and
    /// surface point, seen from the side of `from` (see [`Shape::query`]).
    #[inline]
    pub fn query(
        &self,
        from: &Vector3<f64>,
        x: &Vector3<f64>,
        margin: f64,
    ) -> Option<(f64, Vector3<f64>, Vector3<f64>)> {
        self.shape.query(from, x, margin, self.thickness)
    }
}
