//! Attachment (penalty pin): pulls one vertex to a target with weight `w`; energy
//! `w/2 |x - target|^2`, selection `e_i`, so it adds `w` to the diagonal of `L` and `w target` to
//! the right-hand side (docs/method.md section 2).

use nalgebra::Vector3;
use serde::Serialize;

/// One attached vertex. A model makes them from the specs' `attachments`; a struct literal
/// makes one directly.
///
/// ```
/// use diffsoft::model::Attachment;
/// use nalgebra::Vector3;
///
/// let pin = Attachment { vertex: 3, target: Vector3::zeros(), weight: 100.0 };
/// assert!((pin.energy(&Vector3::new(0.1, 0.0, 0.0)) - 0.5).abs() < 1e-12); // 100/2 x 0.1^2
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Attachment {
    /// Vertex index in the simulated system.
    pub vertex: usize,
    /// Target position.
    pub target: Vector3<f64>,
    /// Spring weight (N/m).
    pub weight: f64,
}

impl Attachment {
    /// Energy `w/2 |x - target|^2`.
    pub fn energy(&self, x: &Vector3<f64>) -> f64 {
        0.5 * self.weight * (x - self.target).norm_squared()
    }
}
