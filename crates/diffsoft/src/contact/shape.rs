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

    /// For a two-sided shape: when the segment `a -> b` passes through the surface, the smaller
    /// of its ends' distances to it (a body whose edge this is starts through the obstacle
    /// when that exceeds the thickness). `None` when it does not cross, and for one-sided
    /// shapes (their inside is found by [`Shape::query`]).
    fn passes_through(&self, _a: &Vector3<f64>, _b: &Vector3<f64>) -> Option<f64> {
        None
    }

    /// For a two-sided shape that encloses a volume (a closed triangle mesh): the distance of
    /// `p` to the surface when `p` is inside. `None` outside, when it cannot tell (an open
    /// surface; a closest point on an edge or corner), and for one-sided shapes.
    fn inside_depth(&self, _p: &Vector3<f64>) -> Option<f64> {
        None
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
