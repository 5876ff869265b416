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
    ///
    /// ```
    /// use diffsoft::contact::{Obstacle, TriMeshObstacle};
    /// use nalgebra::Vector3;
    ///
    /// // A unit square plate in the plane y = 0, kept 0.01 thick.
    /// let v = vec![Vector3::zeros(), Vector3::x(), Vector3::new(1.0, 0.0, 1.0), Vector3::z()];
    /// let plate = TriMeshObstacle::new(v, vec![[0, 1, 2], [0, 2, 3]])?;
    /// let obstacle = Obstacle::new("plate", plate, 0.3, 0.01);
    /// obstacle.validate()?;
    /// // A vertex 0.005 above the plate is inside its thickness.
    /// let x = Vector3::new(0.5, 0.005, 0.5);
    /// let (d, normal, _) = obstacle.query(&x, &x, 0.0).ok_or("no contact")?;
    /// assert!((d + 0.005).abs() < 1e-12);
    /// assert_eq!(normal, Vector3::y());
    /// // A negative friction coefficient is refused.
    /// let v = vec![Vector3::zeros(), Vector3::x(), Vector3::z()];
    /// assert!(Obstacle::new("bad", TriMeshObstacle::new(v, vec![[0, 1, 2]])?, -1.0, 0.01).validate().is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(name: &str, shape: impl Shape + 'static, friction: f64, thickness: f64) -> Self {
        Self {
            name: name.to_string(),
            shape: Arc::new(shape),
            friction,
            thickness,
        }
    }

    /// A ground plane through `point` with normal `normal` (normalised here), no thickness.
    ///
    /// ```
    /// use diffsoft::contact::Obstacle;
    /// use nalgebra::Vector3;
    ///
    /// let ground = Obstacle::plane("ground", Vector3::new(0.0, -1.0, 0.0), Vector3::new(0.0, 2.0, 0.0), 0.5);
    /// ground.validate()?;
    /// assert_eq!((ground.friction, ground.thickness), (0.5, 0.0));
    /// // Signed distance of a vertex 0.5 below the plane.
    /// let x = Vector3::new(3.0, -1.5, 0.0);
    /// let (d, normal, _) = ground.query(&x, &x, 0.0).ok_or("no contact")?;
    /// assert_eq!((d, normal), (-0.5, Vector3::y()));
    /// // Far above it: no contact within the margin.
    /// assert!(ground.query(&Vector3::zeros(), &Vector3::zeros(), 0.1).is_none());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn plane(name: &str, point: Vector3<f64>, normal: Vector3<f64>, friction: f64) -> Self {
        Self::new(name, Plane::new(point, normal), friction, 0.0)
    }

    /// Check the parameters.
    pub fn validate(&self) -> Result<(), InputError> {
        let bad = |m: String| Err(InputError::new(format!("obstacle '{}': {m}", self.name)));
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return bad(format!(
                "friction must be finite and >= 0, got {}",
                crate::base::number(self.friction)
            ));
        }
        if !(self.thickness.is_finite() && self.thickness >= 0.0) {
            return bad(format!(
                "thickness must be finite and >= 0, got {}",
                crate::base::number(self.thickness)
            ));
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
