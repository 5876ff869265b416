//! The seam for obstacle geometry: every shape answers the one query the contact phase asks.

use nalgebra::Vector3;

use crate::base::InputError;

/// The geometry of a static obstacle (docs/method.md Eq. C2).
pub trait Shape: Send + Sync + std::fmt::Debug {
    /// Signed distance of `x` to the surface offset by `thickness`, with the contact normal and
    /// the (offset) surface point, seen from the side of `from` (where the vertex was at the
    /// start of the step). `None` when `x` is farther than `margin` beyond the offset surface and
    /// the segment `from -> x` does not cross it.
    fn query(
        &self,
        from: &Vector3<f64>,
        x: &Vector3<f64>,
        margin: f64,
        thickness: f64,
    ) -> Option<(f64, Vector3<f64>, Vector3<f64>)>;

    /// Check the geometry (finite, normalised, non-degenerate).
    fn validate(&self) -> Result<(), InputError>;

    /// Whether a vertex can be on either side (a surface, not a half-space): such a shape needs
    /// a positive thickness for resting vertices to stay on their side despite round-off.
    fn two_sided(&self) -> bool {
        false
    }

    /// A short name of the kind (messages).
    fn kind(&self) -> &'static str;

    /// Whether the contact normal and the surface point of [`Shape::query`] stay fixed as the
    /// vertex moves within a contact (a piecewise planar surface: a plane, a triangle mesh's
    /// faces). The backward pass differentiates contacts with the normal held fixed
    /// (docs/method.md section 7), which is exact only then; gradients through a model with a
    /// curved shape, which has no normal derivative here, are refused with a message naming it.
    /// No default: a new shape must say.
    fn piecewise_planar(&self) -> bool;
}
