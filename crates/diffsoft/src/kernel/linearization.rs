//! The differential of one tet's weighted projection (docs/method.md section 7).
//!
//! A tet's weighted projection `p(F) = w_rot U V^T + w_vol U X(sigma) V^T` is an isotropic
//! matrix function of `F = U diag(sigma) V^T`. Its differential, with `G = U^T dF V`, is
//! `dp = U H V^T` where `H_ii = w_vol (J dsigma)_i` (`J = dX/dsigma` of the nearest product,
//! `dsigma = diag G`) and, for `i != j`,
//! `H_ij = c_sym (G_ij + G_ji)/2 + c_anti (G_ij - G_ji)/2` with
//! `c_sym = w_vol (x_i - x_j)/(s_i - s_j)`, `c_anti = w_rot 2/(s_i + s_j) + w_vol (x_i + x_j)/(s_i + s_j)`
//! (the spectral-function differential of Lewis and Sendov). A projection onto a set is the
//! gradient of `|F|^2/2 - dist(F, C)^2/2`, so `dp/dF` is symmetric: the same routine gives the
//! Jacobian-vector and the vector-Jacobian product (a unit test checks the symmetry).

use nalgebra::{Matrix3, Vector3};

use super::actuator::{nearest_product_jacobian, pair_coefficients};
use super::svd::Svd3;
use super::volume;

/// The derivative of one tet's weighted projection at one `F`.
#[derive(Debug, Clone, Copy)]
pub struct TetLinearization {
    /// Left rotation.
    pub u: Matrix3<f64>,
    /// Right rotation.
    pub v: Matrix3<f64>,
    /// Diagonal block `w_vol J` (acts on `diag G`).
    pub diag: Matrix3<f64>,
    /// `(c_sym, c_anti)` for the pairs (0,1), (0,2), (1,2).
    pub pairs: [(f64, f64); 3],
    /// The rotation target `U V^T` (for the `w_rot` gradient).
    pub rotation: Matrix3<f64>,
    /// The volume target `U X V^T` (for the `w_vol` gradient; zero without volume constraint).
    pub volume: Matrix3<f64>,
}

/// The off-diagonal index pairs of a 3 x 3 matrix, in the order of [`TetLinearization::pairs`].
pub const PAIRS: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

impl TetLinearization {
    /// The zero map (a placeholder in buffers).
    ///
    /// ```
    /// use diffsoft::kernel::linearization::TetLinearization;
    /// use nalgebra::Matrix3;
    ///
    /// let zero = TetLinearization::zero();
    /// assert_eq!(zero.apply(&Matrix3::repeat(1.0)), Matrix3::zeros());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn zero() -> Self {
        Self {
            u: Matrix3::identity(),
            v: Matrix3::identity(),
            diag: Matrix3::zeros(),
            pairs: [(0.0, 0.0); 3],
            rotation: Matrix3::zeros(),
            volume: Matrix3::zeros(),
        }
    }

    /// Linearize `w_rot U V^T + w_vol U X V^T` at the SVD of `F`. Fails where the projection
    /// is not differentiable (`s_i + s_j = 0`, a volume projection on a branch point).
    ///
    /// ```
    /// use diffsoft::kernel::linearization::TetLinearization;
    /// use diffsoft::kernel::svd::svd3;
    /// use nalgebra::Matrix3;
    ///
    /// // The corotated projection alone at F = I: an infinitesimal rotation passes through, a
    /// // stretch is projected out.
    /// let lin = TetLinearization::new(&svd3(&Matrix3::identity()), 1.0, 0.0)?;
    /// let spin = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    /// assert!((lin.apply(&spin) - spin).norm() < 1e-12);
    /// assert!(lin.apply(&Matrix3::from_diagonal_element(1.0)).norm() < 1e-12);
    /// // Two singular values summing to zero: the rotation has no derivative.
    /// let f = Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 1.0, -1.0));
    /// assert!(TetLinearization::new(&svd3(&f), 1.0, 0.0).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(svd: &Svd3, w_rot: f64, w_vol: f64) -> Result<Self, &'static str> {
        let x = if w_vol > 0.0 {
            Some(volume::nearest_product(&svd.sigma, 1.0).map_err(|_| "volume projection failed")?)
        } else {
            None
        };
        Self::with_target(svd, x, w_rot, w_vol)
    }

    /// [`TetLinearization::new`] with the volume target's singular values `x` already computed
    /// (`None` without volume constraint).
    ///
    /// ```
    /// use diffsoft::kernel::linearization::TetLinearization;
    /// use diffsoft::kernel::svd::svd3;
    /// use nalgebra::{Matrix3, Vector3};
    ///
    /// // At F = I the volume target's singular values are (1, 1, 1).
    /// let svd = svd3(&Matrix3::identity());
    /// let lin = TetLinearization::with_target(&svd, Some(Vector3::repeat(1.0)), 1.0, 0.5)?;
    /// assert!((lin.rotation - Matrix3::identity()).norm() < 1e-12);
    /// assert!((lin.volume - Matrix3::identity()).norm() < 1e-12);
    /// // A uniform dilation changes neither target.
    /// assert!(lin.apply(&Matrix3::identity()).norm() < 1e-12);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    #[inline(always)]
    pub fn with_target(svd: &Svd3, x: Option<Vector3<f64>>, w_rot: f64, w_vol: f64) -> Result<Self, &'static str> {
        let s = svd.sigma;
        let mut pairs = [(0.0, 0.0); 3];
        for (k, &(i, j)) in PAIRS.iter().enumerate() {
            let den = s[i] + s[j];
            if den == 0.0 || !den.is_finite() {
                return Err("two singular values sum to zero (rotation not differentiable)");
            }
            pairs[k] = (0.0, w_rot * 2.0 / den);
        }
        let mut diag = Matrix3::zeros();
        let mut volume = Matrix3::zeros();
        // The target enters `volume` (what `dL/dw_vol` reads) whenever it is given, also at
        // weight 0 (Poisson ratio 0: the weight's derivative is still the target's); its
        // Jacobian enters with the weight.
        if let Some(x) = x {
            volume = svd.compose(&x);
        }
        if let (true, Some(x)) = (w_vol > 0.0, x) {
            let (jac, _) =
                nearest_product_jacobian(&s, &x, 1.0).map_err(|_| "volume projection not differentiable here")?;
            diag = jac * w_vol;
            for (k, &(i, j)) in PAIRS.iter().enumerate() {
                let (cs, ca) = pair_coefficients(x[i], x[j], s[i], s[j])
                    .map_err(|_| "volume projection not differentiable here")?;
                pairs[k].0 += w_vol * cs;
                pairs[k].1 += w_vol * ca;
            }
        }
        Ok(Self {
            u: svd.u,
            v: svd.v,
            diag,
            pairs,
            rotation: svd.rotation(),
            volume,
        })
    }

    /// `dp = (dp/dF) dF` (equal to `(dp/dF)^T dF`: the Jacobian is symmetric).
    #[inline(always)]
    pub fn apply(&self, df: &Matrix3<f64>) -> Matrix3<f64> {
        let g = self.u.transpose() * df * self.v;
        let ds = Vector3::new(g[(0, 0)], g[(1, 1)], g[(2, 2)]);
        let dd = self.diag * ds;
        let mut h = Matrix3::from_diagonal(&dd);
        for (k, &(i, j)) in PAIRS.iter().enumerate() {
            let (cs, ca) = self.pairs[k];
            let (sym, anti) = (0.5 * (g[(i, j)] + g[(j, i)]), 0.5 * (g[(i, j)] - g[(j, i)]));
            h[(i, j)] = cs * sym + ca * anti;
            h[(j, i)] = cs * sym - ca * anti;
        }
        self.u * h * self.v.transpose()
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::kernel::svd::svd3;

    /// A reproducible pseudo-random matrix with entries in [-0.5, 0.5) (shared by the tests
    /// of the kernels built on this linearization).
    pub(crate) fn mat(seed: u64) -> Matrix3<f64> {
        let mut s = seed;
        Matrix3::from_fn(|_, _| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        })
    }

    /// The projection's Jacobian is symmetric: <J a, b> = <a, J b>.
    #[test]
    fn linearization_is_symmetric() {
        for k in 0..50 {
            let f = Matrix3::identity() + mat(k) * 0.8;
            let lin = TetLinearization::new(&svd3(&f), 2.0, 0.7).unwrap();
            let (a, b) = (mat(1000 + k), mat(2000 + k));
            let (l, r) = (lin.apply(&a).dot(&b), a.dot(&lin.apply(&b)));
            assert!((l - r).abs() <= 1e-12 * (l.abs() + r.abs() + 1.0), "{l} vs {r}");
        }
    }

    /// The linearization matches central differences of the projection.
    #[test]
    fn linearization_matches_differences() {
        let target = |f: &Matrix3<f64>| {
            let s = svd3(f);
            let x = volume::nearest_product(&s.sigma, 1.0).unwrap();
            s.rotation() * 2.0 + s.compose(&x) * 0.7
        };
        for k in 0..20 {
            let f = Matrix3::identity() + mat(k) * 0.6;
            let d = mat(500 + k);
            let lin = TetLinearization::new(&svd3(&f), 2.0, 0.7).unwrap();
            let e = 1e-6;
            let fd = (target(&(f + d * e)) - target(&(f - d * e))) / (2.0 * e);
            let an = lin.apply(&d);
            assert!((fd - an).norm() <= 1e-7 * (1.0 + an.norm()), "{fd} vs {an}");
        }
    }
}
