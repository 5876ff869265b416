//! Vectors from input files made unit length without over- or underflow.

use nalgebra::Vector3;

/// The unit vector along `axis` (a joint axis, a plane normal, a fibre direction), scaled by its largest component first so that no finite,
/// non-zero axis over- or underflows (`[1e200, 1e200, 0]` or `[1e-320, 0, 0]` are fine); `None`
/// for a zero or non-finite axis.
///
/// ```
/// use diffsoft::base::unit_vector;
/// use nalgebra::Vector3;
///
/// let u = unit_vector(Vector3::new(1e200, 1e200, 0.0)).ok_or("no axis")?;
/// assert!((u - Vector3::new(1.0, 1.0, 0.0) / 2f64.sqrt()).norm() < 1e-15);
/// assert_eq!(unit_vector(Vector3::new(5e-324, 0.0, 0.0)), Some(Vector3::x()));
/// assert_eq!(unit_vector(Vector3::zeros()), None);
/// assert_eq!(unit_vector(Vector3::new(f64::INFINITY, 0.0, 0.0)), None);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn unit_vector(axis: Vector3<f64>) -> Option<Vector3<f64>> {
    let scale = axis.amax();
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    let a = axis / scale;
    Some(a / a.norm())
}
