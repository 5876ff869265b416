//! The nearest 3 x 2 matrix with orthonormal columns (the in-plane as-rigid-as-possible target of
//! a cloth triangle) and its derivative.
//!
//! For `F = U Sigma V^T` (thin SVD) the projection is `R = U V^T = F S^-1` with
//! `S = (F^T F)^(1/2)`; for a 2 x 2 symmetric positive definite `C = F^T F`,
//! `C^(1/2) = (C + sqrt(det C) I) / sqrt(tr C + 2 sqrt(det C))` in closed form. Differentiating
//! `F = R S` with `R^T dR` skew: `dR = R (omega J) + (I - R R^T) dF S^-1`, where `J` is the 2D
//! rotation generator and `omega = ((R^T dF)_10 - (R^T dF)_01) / tr S`. The map `F -> R` is the
//! gradient of the nuclear norm, so its Jacobian is symmetric: the same formula is its
//! vector-Jacobian product.

use nalgebra::{Matrix2, Matrix3, Matrix3x2, Vector2, Vector3};

/// Below this ratio `sigma_2 / sigma_1` a triangle counts as collapsed to a segment (the
/// projection is then not unique and has no derivative).
pub const COLLAPSED: f64 = 1e-12;

/// Singular values `(sigma_1, sigma_2)`, largest first.
pub fn singular_values(f: &Matrix3x2<f64>) -> (f64, f64) {
    let c = f.transpose() * f;
    let (tr, det) = (c.trace(), c.determinant().max(0.0));
    let disc = ((c[(0, 0)] - c[(1, 1)]).powi(2) * 0.25 + c[(0, 1)] * c[(1, 0)])
        .max(0.0)
        .sqrt();
    let l1 = (0.5 * tr + disc).max(0.0);
    let s1 = l1.sqrt();
    let s2 = if s1 > 0.0 { det.sqrt() / s1 } else { 0.0 };
    (s1, s2)
}

/// A polar decomposition `F = R S`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Polar {
    /// The projection: orthonormal columns.
    pub r: Matrix3x2<f64>,
    /// `S^-1` (zero when collapsed).
    pub s_inv: Matrix2<f64>,
    /// `tr S = sigma_1 + sigma_2`.
    pub trace: f64,
    /// Singular values, largest first.
    pub sigma: (f64, f64),
    /// Whether `F` is (numerically) of rank below 2: `R` is then one of many projections.
    pub collapsed: bool,
}

impl Polar {
    /// Decompose `F` (finite input assumed).
    ///
    /// ```
    /// use diffsoft::kernel::polar32::Polar;
    /// use nalgebra::Matrix3x2;
    ///
    /// let f = Matrix3x2::new(2.0, 0.0, 0.0, 3.0, 0.0, 0.0);
    /// let p = Polar::new(&f);
    /// assert!(!p.collapsed);
    /// assert!((p.r - Matrix3x2::new(1.0, 0.0, 0.0, 1.0, 0.0, 0.0)).norm() < 1e-12);
    /// assert!((p.sigma.0 - 3.0).abs() < 1e-12 && (p.sigma.1 - 2.0).abs() < 1e-12);
    /// assert!((p.distance_squared() - 5.0).abs() < 1e-12);
    /// // A triangle squashed to a segment.
    /// assert!(Polar::new(&Matrix3x2::new(1.0, 1.0, 0.0, 0.0, 0.0, 0.0)).collapsed);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(f: &Matrix3x2<f64>) -> Self {
        let c = f.transpose() * f;
        let det = c.determinant().max(0.0);
        let sd = det.sqrt();
        let (s1, s2) = singular_values(f);
        if s1 > 0.0 && s2 > COLLAPSED * s1 {
            let tr_s = (c.trace() + 2.0 * sd).sqrt();
            let s = (c + Matrix2::identity() * sd) / tr_s;
            // det S = sqrt(det C).
            let s_inv = Matrix2::new(s[(1, 1)], -s[(0, 1)], -s[(1, 0)], s[(0, 0)]) / sd;
            return Self {
                r: f * s_inv,
                s_inv,
                trace: tr_s,
                sigma: (s1, s2),
                collapsed: false,
            };
        }
        // Collapsed: keep the dominant direction, complete the frame arbitrarily.
        let (u1, v1) = if s1 > 0.0 {
            let v1 = dominant_eigenvector(&c);
            ((f * v1) / s1, v1)
        } else {
            (Vector3::x(), Vector2::x())
        };
        let helper = if u1.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
        let u2 = (helper - u1 * u1.dot(&helper)).normalize();
        let v2 = Vector2::new(-v1.y, v1.x);
        Self {
            r: u1 * v1.transpose() + u2 * v2.transpose(),
            s_inv: Matrix2::zeros(),
            trace: s1 + s2,
            sigma: (s1, s2),
            collapsed: true,
        }
    }

    /// `dR` for a change `dF` (also the vector-Jacobian product: the Jacobian is symmetric).
    pub fn differential(&self, df: &Matrix3x2<f64>) -> Matrix3x2<f64> {
        let k = self.r.transpose() * df;
        let omega = (k[(1, 0)] - k[(0, 1)]) / self.trace;
        let j = Matrix2::new(0.0, -1.0, 1.0, 0.0);
        let p = Matrix3::identity() - self.r * self.r.transpose();
        self.r * (j * omega) + p * df * self.s_inv
    }

    /// `|F - R|^2 = (sigma_1 - 1)^2 + (sigma_2 - 1)^2`.
    pub fn distance_squared(&self) -> f64 {
        (self.sigma.0 - 1.0).powi(2) + (self.sigma.1 - 1.0).powi(2)
    }
}

fn dominant_eigenvector(c: &Matrix2<f64>) -> Vector2<f64> {
    let e = c.symmetric_eigen();
    let k = if e.eigenvalues[0] >= e.eigenvalues[1] { 0 } else { 1 };
    e.eigenvectors.column(k).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn mat(v: &[f64]) -> Matrix3x2<f64> {
        Matrix3x2::from_row_slice(v)
    }

    proptest! {
        /// `R` has orthonormal columns, reproduces the SVD's `U V^T`, and its differential
        /// matches central differences and is symmetric.
        #[test]
        fn projection_and_derivative(v in proptest::collection::vec(-2.0f64..2.0, 6),
                                     d in proptest::collection::vec(-1.0f64..1.0, 6),
                                     e in proptest::collection::vec(-1.0f64..1.0, 6)) {
            let f = mat(&v);
            let (s1, s2) = singular_values(&f);
            prop_assume!(s2 > 1e-2 * s1.max(1e-3) && s1 > 1e-2);
            let p = Polar::new(&f);
            prop_assert!(!p.collapsed);
            let rtr = p.r.transpose() * p.r;
            prop_assert!((rtr - Matrix2::identity()).norm() < 1e-10);
            let svd = f.svd(true, true);
            let r_svd = svd.u.unwrap() * svd.v_t.unwrap();
            prop_assert!((r_svd - p.r).norm() < 1e-9, "{} vs {}", r_svd, p.r);
            let (s1_svd, s2_svd) = (svd.singular_values.max(), svd.singular_values.min());
            prop_assert!((s1 - s1_svd).abs() < 1e-9 && (s2 - s2_svd).abs() < 1e-9);
            let df = mat(&d);
            let h = 1e-6;
            let fd = (Polar::new(&(f + df * h)).r - Polar::new(&(f - df * h)).r) / (2.0 * h);
            let an = p.differential(&df);
            prop_assert!((fd - an).norm() < 1e-6 * (1.0 + an.norm()) / s2.min(1.0), "{} vs {}", fd, an);
            // Symmetry: <dF2, J dF1> = <dF1, J dF2>.
            let df2 = mat(&e);
            let a = df2.dot(&p.differential(&df));
            let b = df.dot(&p.differential(&df2));
            prop_assert!((a - b).abs() < 1e-9 * (1.0 + a.abs()));
        }
    }

    #[test]
    fn collapsed_triangles_still_get_a_frame() {
        for f in [mat(&[1.0, 2.0, 0.0, 0.0, 0.0, 0.0]), Matrix3x2::zeros()] {
            let p = Polar::new(&f);
            assert!(p.collapsed);
            let rtr = p.r.transpose() * p.r;
            assert!((rtr - Matrix2::identity()).norm() < 1e-12, "{rtr}");
        }
    }
}
