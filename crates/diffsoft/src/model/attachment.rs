//! Attachment (penalty pin): pulls one vertex to a target with weight `w`; energy
//! `w/2 |x - target|^2`, selection `e_i`, so it adds `w` to the diagonal of `L` and `w target` to
//! the right-hand side (docs/method.md section 2).

use nalgebra::Vector3;
use serde::Serialize;

/// One attached vertex.
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
