//! Actuator constraints (docs/method.md section 5, appendix D, Eqs. 39-40).
//!
//! * **Pneumatic cell** with activation `a > 0` (target volume ratio):
//!   `Psi = k_p/2 |F - R(a)|^2` (Eq. 39) with `F = U S V^T` and `R(a) = U (S + D) V^T`,
//!   `D = argmin |D|^2 s.t. prod (S_i + D_i) = a` (Eq. 40): the volume projection
//!   ([`volume::nearest_product`]) with target `a` instead of 1. Inverted `F` (signed
//!   `S_3 < 0`) is projected to the nearest point with all singular values positive.
//! * **Muscle fibre** with rest direction `m` (unit) and activation `a in [0, 1]`: the fibre
//!   `F m` of length `l = |F m|` is pulled to length `1 - a` along itself; the projective target
//!   is `p = (1 - a) F m / |F m|` and `Psi = k_m/2 |F m - p|^2`. This is the normalised form
//!   (docs/method.md section 5: the appendix prints the norm without the square and the reference implementation
//!   uses `(1 - a) F m` without normalising; diffsoft uses the normalised target, so an
//!   activation `a` means "fibre length `1 - a`" whatever the current stretch).
//!
//! Both energies are distances to a constraint set, so their gradients with respect to `F` are
//! `k (F - R(a))` and `k (F m - p) m^T` (the target's own variation is orthogonal to the
//! residual at the nearest point).
//!
//! # Derivatives of the targets
//!
//! **Pneumatic** ([`pneumatic_jacobian`]). `R = U diag(x(S, a)) V^T` is a spectral (isotropic)
//! matrix function of `F`. With `G = U^T dF V`, the singular values move by `dS_i = G_ii` and
//! `H = U^T dR V` has
//!
//! * diagonal `dx = J dS + (dx/da) da`, `J = dx/dS` from implicit differentiation of the
//!   stationarity system `x_i (x_i - S_i) = t` (one multiplier `t`), `prod x = a`. With
//!   `c_i = 2 x_i - S_i`, `w_i = x_i c_i` and `e2 = w_1 w_2 + w_1 w_3 + w_2 w_3` (the bordered
//!   Hessian's determinant up to a positive factor, `> 0` at a strict minimum):
//!   `J_ii = x_i^2 (w_j + w_k) / e2`, `J_ij = -x_i x_j w_k / e2`, `dx_i/da = x_i w_j w_k / (a e2)`
//!   (`{i, j, k}` distinct). No `w_i` is divided by, so the fold `c_i = 0` (where `t(x_i)` turns)
//!   is harmless, and every term keeps its relative precision for singular values spread over
//!   many decades;
//! * off-diagonal `H_ij = (x_i - x_j)/(S_i - S_j) sym(G)_ij + (x_i + x_j)/(S_i + S_j) antisym(G)_ij`
//!   ([`pair_coefficients`]). Because `x_i` and `x_j` share the multiplier `t`, the first quotient
//!   equals `(x_i + x_j) / (c_i + c_j)` exactly; when both components are on the `+` branch
//!   (`c >= 0`) that form has no cancellation and is also the limit `S_i -> S_j`. When one
//!   component is on the `-` branch (a tiny target collapses the smallest direction) the
//!   quotient is taken as written; `S_i = S_j` there means the nearest point is not unique.
//!   The second quotient has no finite limit as `S_i + S_j -> 0` (an inverted `F` with
//!   `S_2 = -S_3`, or a rank-1 `F`): the nearest point is not unique there either, the
//!   Jacobian grows like `1 / (S_i + S_j)`, and exactly `S_i + S_j = 0` is
//!   [`ActuatorError::NotDifferentiable`].
//!
//! **Muscle** ([`muscle_jacobian`]): with `n = F m / l`,
//! `dp/d(F m) = (1 - a)/l (I - n n^T)`, so `dp/dvec(F) = m^T (x) dp/d(F m)` and `dp/da = -n`.
//!
//! **Independent references** ([`pneumatic_target_dual`], [`muscle_target_dual`]) evaluate the
//! same targets in any dual-number type (num-dual): the pneumatic one through a one-sided
//! (Hestenes) Jacobi SVD with a fixed number of sweeps (relative accuracy for graded `F`, unlike
//! an eigen-decomposition of `F^T F`) and Newton's method for the nearest product in dual
//! arithmetic (started from the converged value, so the derivative parts are those of the
//! root), without any of the formulas above.
//!
//! Vectorisation is column-major: `vec(M)[i + 3 j] = M_ij` (nalgebra's storage order).

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use num_dual::{Dual64, DualNum};

use super::svd::{svd3, Svd3};
use super::{volume, ProjectionError};

/// A 9 x 9 matrix: `d vec(R) / d vec(F)`.
pub type Matrix9 = SMatrix<f64, 9, 9>;
/// A 9-vector: `vec` of a 3 x 3 matrix.
pub type Vector9 = SVector<f64, 9>;
/// A 3 x 9 matrix: `d p / d vec(F)`.
pub type Matrix3x9 = SMatrix<f64, 3, 9>;

/// Why an actuator projection has no answer (never a silent NaN).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ActuatorError {
    /// The deformation gradient or the direction has non-finite entries.
    #[error("deformation gradient or fibre direction has non-finite entries")]
    NonFinite,
    /// A pneumatic activation outside `(0, inf)` or a muscle activation outside `[0, 1]`.
    #[error("activation {0} is out of range (pneumatic: finite and > 0; muscle: in [0, 1])")]
    BadActivation(f64),
    /// The fibre `F m` has zero length: its direction, and so the target, is undefined.
    #[error("the fibre F m has zero length: its direction is undefined")]
    CollapsedFibre,
    /// The volume projection failed.
    #[error(transparent)]
    Projection(#[from] ProjectionError),
    /// A stiffness that is negative or not finite.
    #[error("stiffness {0} must be finite and >= 0")]
    BadStiffness(f64),
    /// The target is not differentiable at this `F`: its nearest point is not unique (opposite
    /// singular values `S_i = -S_j` of an inverted or rank-deficient `F`, or equal singular
    /// values on different branches), or the stationarity system is singular there.
    #[error("the actuator target is not differentiable here (non-unique nearest point)")]
    NotDifferentiable,
}

/// The pneumatic target `R(a) = U (S + D) V^T` of Eq. 40 for a decomposed `F`.
pub fn pneumatic_target(svd: &Svd3, a: f64) -> Result<Matrix3<f64>, ActuatorError> {
    if !(a.is_finite() && a > 0.0) {
        return Err(ActuatorError::BadActivation(a));
    }
    Ok(svd.compose(&volume::nearest_product(&svd.sigma, a)?))
}

/// The muscle target `p = (1 - a) F m / |F m|` for the fibre `fm = F m`.
pub fn muscle_target(fm: &Vector3<f64>, a: f64) -> Result<Vector3<f64>, ActuatorError> {
    if !(0.0..=1.0).contains(&a) {
        return Err(ActuatorError::BadActivation(a));
    }
    if !fm.iter().all(|v| v.is_finite()) {
        return Err(ActuatorError::NonFinite);
    }
    let l = fm.norm();
    if l == 0.0 || !l.is_finite() {
        return Err(ActuatorError::CollapsedFibre);
    }
    Ok(fm * ((1.0 - a) / l))
}

fn check_finite<'a>(values: impl IntoIterator<Item = &'a f64>) -> Result<(), ActuatorError> {
    if values.into_iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(ActuatorError::NonFinite)
    }
}

fn check_pneumatic_activation(a: f64) -> Result<(), ActuatorError> {
    if a.is_finite() && a > 0.0 {
        Ok(())
    } else {
        Err(ActuatorError::BadActivation(a))
    }
}

fn check_stiffness(k: f64) -> Result<(), ActuatorError> {
    if k.is_finite() && k >= 0.0 {
        Ok(())
    } else {
        Err(ActuatorError::BadStiffness(k))
    }
}

fn finite_or<T>(value: T, ok: bool) -> Result<T, ActuatorError> {
    if ok {
        Ok(value)
    } else {
        Err(ActuatorError::NonFinite)
    }
}

/// `R(F, a)` of Eq. 40 with its SVD taken here ([`svd3`]); non-finite `F` is an error.
pub fn pneumatic_target_of(f: &Matrix3<f64>, a: f64) -> Result<Matrix3<f64>, ActuatorError> {
    check_pneumatic_activation(a)?;
    check_finite(f.iter())?;
    let r = pneumatic_target(&svd3(f), a)?;
    finite_or(r, r.iter().all(|v| v.is_finite()))
}

/// Pneumatic energy `k/2 |F - R(a)|^2` (Eq. 39).
pub fn pneumatic_energy(f: &Matrix3<f64>, a: f64, k: f64) -> Result<f64, ActuatorError> {
    check_stiffness(k)?;
    let e = 0.5 * k * (f - pneumatic_target_of(f, a)?).norm_squared();
    finite_or(e, e.is_finite())
}

/// Gradient of the pneumatic energy (Eq. 39): `k (F - R(a))`.
pub fn pneumatic_energy_gradient(f: &Matrix3<f64>, a: f64, k: f64) -> Result<Matrix3<f64>, ActuatorError> {
    check_stiffness(k)?;
    let g = (f - pneumatic_target_of(f, a)?) * k;
    finite_or(g, g.iter().all(|v| v.is_finite()))
}

/// The pneumatic target with its derivatives (Eq. 40).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PneumaticJacobian {
    /// `R(F, a)`.
    pub target: Matrix3<f64>,
    /// Singular values of `F` (signed, [`svd3`]).
    pub sigma: Vector3<f64>,
    /// Singular values of `R` (`x`, all positive, `prod x = a`).
    pub x: Vector3<f64>,
    /// `d vec(R) / d vec(F)` (column-major `vec`).
    pub wrt_f: Matrix9,
    /// `d vec(R) / da`.
    pub wrt_a: Vector9,
}

/// Derivatives `J = dx/ds` and `dx/da` of the nearest product `x(s, a)`
/// ([`volume::nearest_product`]) from implicit differentiation of `x_i (x_i - s_i) = t`,
/// `prod x = a` (see the module doc; no division by `2 x_i - s_i`).
pub fn nearest_product_jacobian(
    s: &Vector3<f64>,
    x: &Vector3<f64>,
    a: f64,
) -> Result<(Matrix3<f64>, Vector3<f64>), ActuatorError> {
    let w = Vector3::from_fn(|i, _| x[i] * (2.0 * x[i] - s[i]));
    // Scale out the largest |w| so e2 neither overflows nor underflows.
    let scale = w.amax();
    if !(scale > 0.0 && scale.is_finite()) {
        return Err(ActuatorError::NotDifferentiable);
    }
    let w = w / scale;
    let e2 = w[0] * w[1] + w[0] * w[2] + w[1] * w[2];
    if !(e2 > 0.0 && e2.is_finite()) {
        return Err(ActuatorError::NotDifferentiable);
    }
    let mut j = Matrix3::zeros();
    let mut da = Vector3::zeros();
    for i in 0..3 {
        let (p, q) = ((i + 1) % 3, (i + 2) % 3);
        j[(i, i)] = x[i] * x[i] * (w[p] + w[q]) / (scale * e2);
        j[(i, p)] = -x[i] * x[p] * w[q] / (scale * e2);
        j[(i, q)] = -x[i] * x[q] * w[p] / (scale * e2);
        da[i] = x[i] * w[p] * w[q] / (a * e2);
    }
    if !(j.iter().all(|v| v.is_finite()) && da.iter().all(|v| v.is_finite())) {
        return Err(ActuatorError::NotDifferentiable);
    }
    Ok((j, da))
}

/// The off-diagonal coefficients of the spectral-function differential for the pair `(i, j)`:
/// `(sym, antisym) = ((x_i - x_j)/(s_i - s_j), (x_i + x_j)/(s_i + s_j))`, the first in the
/// cancellation-free form `(x_i + x_j)/(c_i + c_j)` (`c = 2x - s`) when both components are on the
/// `+` branch, which is also its limit as `s_i -> s_j`.
pub fn pair_coefficients(xi: f64, xj: f64, si: f64, sj: f64) -> Result<(f64, f64), ActuatorError> {
    let (ci, cj) = (2.0 * xi - si, 2.0 * xj - sj);
    let sym = if ci >= 0.0 && cj >= 0.0 && ci + cj > 0.0 {
        (xi + xj) / (ci + cj)
    } else if si != sj {
        (xi - xj) / (si - sj)
    } else {
        return Err(ActuatorError::NotDifferentiable);
    };
    let den = si + sj;
    if den == 0.0 || !den.is_finite() {
        return Err(ActuatorError::NotDifferentiable);
    }
    let anti = (xi + xj) / den;
    if sym.is_finite() && anti.is_finite() {
        Ok((sym, anti))
    } else {
        Err(ActuatorError::NotDifferentiable)
    }
}

/// `R(F, a)` (Eq. 40) with its analytic Jacobians `d vec(R)/d vec(F)` and `d vec(R)/da`.
///
/// ```
/// use diffsoft::kernel::actuator::pneumatic_jacobian;
/// use nalgebra::{Matrix3, Vector3};
///
/// // Activation 8 asks for eight times the volume: at F = I the target is 2 I.
/// let j = pneumatic_jacobian(&Matrix3::identity(), 8.0)?;
/// assert!((j.target - Matrix3::identity() * 2.0).norm() < 1e-12);
/// assert!((j.x - Vector3::repeat(2.0)).norm() < 1e-12);
/// // d vec(R)/da: each diagonal entry grows by d(a^(1/3))/da = 1/12.
/// assert!((j.wrt_a[0] - 1.0 / 12.0).abs() < 1e-12);
/// assert!(pneumatic_jacobian(&Matrix3::identity(), -1.0).is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn pneumatic_jacobian(f: &Matrix3<f64>, a: f64) -> Result<PneumaticJacobian, ActuatorError> {
    check_pneumatic_activation(a)?;
    check_finite(f.iter())?;
    let svd = svd3(f);
    check_finite(svd.sigma.iter())?;
    let s = svd.sigma;
    let x = volume::nearest_product(&s, a)?;
    let (j, dxda) = nearest_product_jacobian(&s, &x, a)?;
    let mut sym = Matrix3::zeros();
    let mut anti = Matrix3::zeros();
    for (p, q) in [(0, 1), (0, 2), (1, 2)] {
        let (cs, ca) = pair_coefficients(x[p], x[q], s[p], s[q])?;
        sym[(p, q)] = cs;
        sym[(q, p)] = cs;
        anti[(p, q)] = ca;
        anti[(q, p)] = ca;
    }
    let (u, v) = (svd.u, svd.v);
    let mut wrt_f = Matrix9::zeros();
    for col in 0..9 {
        let (r0, c0) = (col % 3, col / 3);
        // G = U^T E_(r0, c0) V.
        let g = Matrix3::from_fn(|i, k| u[(r0, i)] * v[(c0, k)]);
        let ds = g.diagonal();
        let dx = j * ds;
        let h = Matrix3::from_fn(|p, q| {
            if p == q {
                dx[p]
            } else {
                0.5 * sym[(p, q)] * (g[(p, q)] + g[(q, p)]) + 0.5 * anti[(p, q)] * (g[(p, q)] - g[(q, p)])
            }
        });
        let dr = u * h * v.transpose();
        wrt_f.set_column(col, &Vector9::from_column_slice(dr.as_slice()));
    }
    let dra = svd.compose(&dxda);
    let target = svd.compose(&x);
    let out = PneumaticJacobian {
        target,
        sigma: s,
        x,
        wrt_f,
        wrt_a: Vector9::from_column_slice(dra.as_slice()),
    };
    if out
        .wrt_f
        .iter()
        .chain(out.wrt_a.iter())
        .chain(target.iter())
        .all(|v| v.is_finite())
    {
        Ok(out)
    } else {
        Err(ActuatorError::NotDifferentiable)
    }
}

fn fibre(f: &Matrix3<f64>, m: &Vector3<f64>, a: f64) -> Result<(Vector3<f64>, Vector3<f64>), ActuatorError> {
    if !(0.0..=1.0).contains(&a) {
        return Err(ActuatorError::BadActivation(a));
    }
    check_finite(f.iter().chain(m.iter()))?;
    let fm = f * m;
    Ok((fm, muscle_target(&fm, a)?))
}

/// Muscle energy `k/2 |F m - p|^2` with `p = (1 - a) F m / |F m|` (docs/method.md section 5).
pub fn muscle_energy(f: &Matrix3<f64>, m: &Vector3<f64>, a: f64, k: f64) -> Result<f64, ActuatorError> {
    check_stiffness(k)?;
    let (fm, p) = fibre(f, m, a)?;
    let e = 0.5 * k * (fm - p).norm_squared();
    finite_or(e, e.is_finite())
}

/// Gradient of the muscle energy: `k (F m - p) m^T`.
pub fn muscle_energy_gradient(
    f: &Matrix3<f64>,
    m: &Vector3<f64>,
    a: f64,
    k: f64,
) -> Result<Matrix3<f64>, ActuatorError> {
    check_stiffness(k)?;
    let (fm, p) = fibre(f, m, a)?;
    let g = (fm - p) * m.transpose() * k;
    finite_or(g, g.iter().all(|v| v.is_finite()))
}

/// The muscle target with its derivatives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MuscleJacobian {
    /// `p = (1 - a) F m / |F m|`.
    pub target: Vector3<f64>,
    /// `dp / d vec(F) = m^T (x) (1 - a)/l (I - n n^T)`.
    pub wrt_f: Matrix3x9,
    /// `dp / da = -n`.
    pub wrt_a: Vector3<f64>,
}

/// The muscle target `p(F, a)` with its analytic Jacobians.
///
/// ```
/// use diffsoft::kernel::actuator::muscle_jacobian;
/// use nalgebra::{Matrix3, Vector3};
///
/// let j = muscle_jacobian(&Matrix3::identity(), &Vector3::x(), 0.25)?;
/// assert!((j.target - Vector3::x() * 0.75).norm() < 1e-12);
/// assert_eq!(j.wrt_a, -Vector3::x());
/// // Activation outside [0, 1] is refused.
/// assert!(muscle_jacobian(&Matrix3::identity(), &Vector3::x(), 1.5).is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn muscle_jacobian(f: &Matrix3<f64>, m: &Vector3<f64>, a: f64) -> Result<MuscleJacobian, ActuatorError> {
    let (fm, target) = fibre(f, m, a)?;
    let l = fm.norm();
    let n = fm / l;
    let dp = (Matrix3::identity() - n * n.transpose()) * ((1.0 - a) / l);
    let wrt_f = Matrix3x9::from_fn(|r, c| dp[(r, c % 3)] * m[c / 3]);
    let out = MuscleJacobian {
        target,
        wrt_f,
        wrt_a: -n,
    };
    finite_or(out, out.wrt_f.iter().chain(out.wrt_a.iter()).all(|v| v.is_finite()))
}

// ---------------------------------------------------------------------------------------------
// Independent references in dual-number arithmetic.

/// One-sided Jacobi sweeps of the dual SVD (fixed: the derivative parts converge with the values).
const DUAL_SWEEPS: usize = 40;
/// Newton steps of the dual nearest product, started from the converged value.
const DUAL_NEWTON: usize = 4;

fn c<D: DualNum<Primitive = f64> + Copy>(v: f64) -> D {
    D::from(v)
}

/// Signed SVD `F = U diag(s) V^T` (`det U = det V = 1`, `s_1 >= s_2 >= |s_3|`) in dual arithmetic
/// by one-sided Jacobi: rotate column pairs of `B = F V` until orthogonal (a fixed number of
/// sweeps), sort by column norm, make `V` a rotation, `u_i = b_i / s_i`, `u_3 = u_1 x u_2`,
/// `s_3 = u_3 . b_3`.
#[allow(clippy::type_complexity, clippy::needless_range_loop)]
fn svd_dual<D: DualNum<Primitive = f64> + Copy>(
    f: &Matrix3<D>,
) -> Result<([[D; 3]; 3], [D; 3], [[D; 3]; 3]), ActuatorError> {
    let mut b = [[c::<D>(0.0); 3]; 3];
    let mut v = [[c::<D>(0.0); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            b[i][j] = f[(i, j)];
        }
        v[i][i] = c(1.0);
    }
    for _ in 0..DUAL_SWEEPS {
        for (i, j) in [(0, 1), (0, 2), (1, 2)] {
            let (mut alpha, mut beta, mut gamma) = (c::<D>(0.0), c::<D>(0.0), c::<D>(0.0));
            for r in 0..3 {
                alpha += b[r][i] * b[r][i];
                beta += b[r][j] * b[r][j];
                gamma += b[r][i] * b[r][j];
            }
            let delta = beta - alpha;
            let q = delta * delta + gamma * gamma * 4.0;
            if q.re() == 0.0 {
                continue;
            }
            let sgn = if delta.re() >= 0.0 { 1.0 } else { -1.0 };
            // tan of the angle that makes columns i and j orthogonal (the smaller root).
            let t = gamma * (2.0 * sgn) / (delta * sgn + q.sqrt());
            let cs = (t * t + 1.0).sqrt().recip();
            let sn = cs * t;
            for m in [&mut b, &mut v] {
                for r in 0..3 {
                    let (x, y) = (m[r][i], m[r][j]);
                    m[r][i] = cs * x - sn * y;
                    m[r][j] = sn * x + cs * y;
                }
            }
        }
    }
    let norm = |k: usize, b: &[[D; 3]; 3]| (b[0][k] * b[0][k] + b[1][k] * b[1][k] + b[2][k] * b[2][k]).sqrt();
    let mut order = [0usize, 1, 2];
    let norms = [norm(0, &b).re(), norm(1, &b).re(), norm(2, &b).re()];
    order.sort_by(|&p, &q| norms[q].total_cmp(&norms[p]));
    let mut bs = [[c::<D>(0.0); 3]; 3];
    let mut vs = [[c::<D>(0.0); 3]; 3];
    for r in 0..3 {
        for k in 0..3 {
            bs[r][k] = b[r][order[k]];
            vs[r][k] = v[r][order[k]];
        }
    }
    let det = vs[0][0] * (vs[1][1] * vs[2][2] - vs[1][2] * vs[2][1])
        - vs[0][1] * (vs[1][0] * vs[2][2] - vs[1][2] * vs[2][0])
        + vs[0][2] * (vs[1][0] * vs[2][1] - vs[1][1] * vs[2][0]);
    if det.re() < 0.0 {
        for r in 0..3 {
            vs[r][2] = -vs[r][2];
            bs[r][2] = -bs[r][2];
        }
    }
    let s0 = norm(0, &bs);
    let s1 = norm(1, &bs);
    if !(s1.re() > 0.0 && s0.re().is_finite()) {
        return Err(ActuatorError::NotDifferentiable);
    }
    let mut u = [[c::<D>(0.0); 3]; 3];
    for r in 0..3 {
        u[r][0] = bs[r][0] / s0;
        u[r][1] = bs[r][1] / s1;
    }
    u[0][2] = u[1][0] * u[2][1] - u[2][0] * u[1][1];
    u[1][2] = u[2][0] * u[0][1] - u[0][0] * u[2][1];
    u[2][2] = u[0][0] * u[1][1] - u[1][0] * u[0][1];
    let s2 = u[0][2] * bs[0][2] + u[1][2] * bs[1][2] + u[2][2] * bs[2][2];
    Ok((u, [s0, s1, s2], vs))
}

/// `x_j(t) = (s_j + sqrt(s_j^2 + 4 t)) / 2` (`s_j >= 0`) with `sqrt(s_j^2 + 4t)`.
fn plus_root<D: DualNum<Primitive = f64> + Copy>(s: D, t: D) -> (D, D) {
    let d = (s * s + t * 4.0).sqrt();
    ((s + d) * 0.5, d)
}

/// The nearest product `x(s, a)` ([`volume::nearest_product`]) in dual arithmetic: Newton on
/// `ln x_k + sum_j ln x_j(t) = ln a` in the component `x_k` with the smallest `|s_k|`, with
/// `t = x_k (x_k - s_k)` and `x_j = (s_j + sqrt(s_j^2 + 4t))/2` (`s_j >= 0`), started from the
/// value of [`volume::nearest_product`] (so the derivative parts are those of that root).
pub fn nearest_product_dual<D: DualNum<Primitive = f64> + Copy>(
    s: &Vector3<D>,
    a: D,
) -> Result<Vector3<D>, ActuatorError> {
    check_pneumatic_activation(a.re())?;
    let sr = s.map(|v| v.re());
    check_finite(sr.iter())?;
    let x0 = volume::nearest_product(&sr, a.re())?;
    let k = (0..3).min_by(|&i, &j| sr[i].abs().total_cmp(&sr[j].abs())).unwrap_or(2);
    let (p, q) = ((k + 1) % 3, (k + 2) % 3);
    if sr[p] < 0.0 || sr[q] < 0.0 {
        return Err(ActuatorError::NotDifferentiable);
    }
    let ln_a = a.ln();
    let mut xk = c::<D>(x0[k]);
    for _ in 0..DUAL_NEWTON {
        let t = xk * (xk - s[k]);
        let dt = xk * 2.0 - s[k];
        let (xp, dp) = plus_root(s[p], t);
        let (xq, dq) = plus_root(s[q], t);
        let h = xk.ln() + xp.ln() + xq.ln() - ln_a;
        let dh = xk.recip() + dt * ((dp * xp).recip() + (dq * xq).recip());
        xk -= h / dh;
    }
    let t = xk * (xk - s[k]);
    let mut x = Vector3::from_element(xk);
    x[p] = plus_root(s[p], t).0;
    x[q] = plus_root(s[q], t).0;
    // The dual Newton must stay on the root the scalar solver found (same branch).
    for i in 0..3 {
        if !((x[i].re() - x0[i]).abs() <= 1e-8 * x0[i] && x[i].re() > 0.0) {
            return Err(ActuatorError::NotDifferentiable);
        }
    }
    Ok(x)
}

/// The pneumatic target `R(F, a)` (Eq. 40) in dual arithmetic: one-sided Jacobi SVD, then
/// [`nearest_product_dual`]. An independent reference for [`pneumatic_jacobian`].
pub fn pneumatic_target_dual<D: DualNum<Primitive = f64> + Copy>(
    f: &Matrix3<D>,
    a: D,
) -> Result<Matrix3<D>, ActuatorError> {
    check_pneumatic_activation(a.re())?;
    check_finite(f.iter().map(|v| v.re()).collect::<Vec<f64>>().iter())?;
    let (u, s, v) = svd_dual(f)?;
    let x = nearest_product_dual(&Vector3::from(s), a)?;
    let r = Matrix3::from_fn(|i, j| u[i][0] * x[0] * v[j][0] + u[i][1] * x[1] * v[j][1] + u[i][2] * x[2] * v[j][2]);
    if r.iter().all(|z| z.re().is_finite()) {
        Ok(r)
    } else {
        Err(ActuatorError::NotDifferentiable)
    }
}

/// A tet's weighted projective-dynamics target `w_rot U V^T + w_vol U X V^T` (corotated plus
/// volume constraint, docs/method.md section 2) in dual arithmetic: an independent reference for the
/// local step's linearization in the constraint sets' adjoints.
pub fn tet_target_dual<D: DualNum<Primitive = f64> + Copy>(
    f: &Matrix3<D>,
    w_rot: f64,
    w_vol: f64,
) -> Result<Matrix3<D>, ActuatorError> {
    let (u, _, v) = svd_dual(f)?;
    let rot = Matrix3::from_fn(|i, j| u[i][0] * v[j][0] + u[i][1] * v[j][1] + u[i][2] * v[j][2]);
    let mut p = rot.map(|z| z * w_rot);
    if w_vol > 0.0 {
        p += pneumatic_target_dual(f, D::from(1.0))?.map(|z| z * w_vol);
    }
    Ok(p)
}

/// The muscle target `p = (1 - a) F m / |F m|` in dual arithmetic (independent reference for
/// [`muscle_jacobian`]).
pub fn muscle_target_dual<D: DualNum<Primitive = f64> + Copy>(
    f: &Matrix3<D>,
    m: &Vector3<f64>,
    a: D,
) -> Result<Vector3<D>, ActuatorError> {
    if !(0.0..=1.0).contains(&a.re()) {
        return Err(ActuatorError::BadActivation(a.re()));
    }
    check_finite(
        f.iter()
            .map(|v| v.re())
            .chain(m.iter().copied())
            .collect::<Vec<f64>>()
            .iter(),
    )?;
    let fm = Vector3::from_fn(|i, _| f[(i, 0)] * m[0] + f[(i, 1)] * m[1] + f[(i, 2)] * m[2]);
    let l = (fm[0] * fm[0] + fm[1] * fm[1] + fm[2] * fm[2]).sqrt();
    if !(l.re() > 0.0 && l.re().is_finite()) {
        return Err(ActuatorError::CollapsedFibre);
    }
    let r = (c::<D>(1.0) - a) / l;
    Ok(fm.map(|z| z * r))
}

fn seeded(f: &Matrix3<f64>, col: Option<usize>) -> Matrix3<Dual64> {
    Matrix3::from_fn(|i, j| {
        let d = Dual64::from(f[(i, j)]);
        if col == Some(i + 3 * j) {
            d.derivative()
        } else {
            d
        }
    })
}

/// `d vec(R)/d vec(F)` and `d vec(R)/da` from [`pneumatic_target_dual`] with `Dual64`
/// (ten forward passes).
pub fn pneumatic_jacobian_dual(f: &Matrix3<f64>, a: f64) -> Result<(Matrix9, Vector9), ActuatorError> {
    let mut jf = Matrix9::zeros();
    for col in 0..9 {
        let r = pneumatic_target_dual(&seeded(f, Some(col)), Dual64::from(a))?;
        jf.set_column(col, &Vector9::from_iterator(r.iter().map(|z| z.eps)));
    }
    let r = pneumatic_target_dual(&seeded(f, None), Dual64::from(a).derivative())?;
    Ok((jf, Vector9::from_iterator(r.iter().map(|z| z.eps))))
}

/// `dp/d vec(F)` and `dp/da` from [`muscle_target_dual`] with `Dual64`.
pub fn muscle_jacobian_dual(
    f: &Matrix3<f64>,
    m: &Vector3<f64>,
    a: f64,
) -> Result<(Matrix3x9, Vector3<f64>), ActuatorError> {
    let mut jf = Matrix3x9::zeros();
    for col in 0..9 {
        let p = muscle_target_dual(&seeded(f, Some(col)), m, Dual64::from(a))?;
        jf.set_column(col, &p.map(|z| z.eps));
    }
    let p = muscle_target_dual(&seeded(f, None), m, Dual64::from(a).derivative())?;
    Ok((jf, p.map(|z| z.eps)))
}

/// Gradient of the pneumatic energy (Eq. 39) by forward-mode differentiation of
/// `k/2 |F - R(F, a)|^2` through [`pneumatic_target_dual`] (includes the target's variation).
pub fn pneumatic_energy_gradient_dual(f: &Matrix3<f64>, a: f64, k: f64) -> Result<Matrix3<f64>, ActuatorError> {
    check_stiffness(k)?;
    let mut g = Matrix3::zeros();
    for col in 0..9 {
        let fd = seeded(f, Some(col));
        let r = pneumatic_target_dual(&fd, Dual64::from(a))?;
        let e: Dual64 = fd
            .iter()
            .zip(r.iter())
            .map(|(p, q)| (*p - *q) * (*p - *q))
            .sum::<Dual64>()
            * (0.5 * k);
        g[(col % 3, col / 3)] = e.eps;
    }
    Ok(g)
}

/// Gradient of the muscle energy by forward-mode differentiation of `k/2 |F m - p(F, a)|^2`
/// through [`muscle_target_dual`].
pub fn muscle_energy_gradient_dual(
    f: &Matrix3<f64>,
    m: &Vector3<f64>,
    a: f64,
    k: f64,
) -> Result<Matrix3<f64>, ActuatorError> {
    check_stiffness(k)?;
    let mut g = Matrix3::zeros();
    for col in 0..9 {
        let fd = seeded(f, Some(col));
        let p = muscle_target_dual(&fd, m, Dual64::from(a))?;
        let e: Dual64 = (0..3)
            .map(|i| {
                let r = fd[(i, 0)] * m[0] + fd[(i, 1)] * m[1] + fd[(i, 2)] * m[2] - p[i];
                r * r
            })
            .sum::<Dual64>()
            * (0.5 * k);
        g[(col % 3, col / 3)] = e.eps;
    }
    Ok(g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::svd::svd3;

    fn rot(axis: Vector3<f64>, angle: f64) -> Matrix3<f64> {
        *nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle).matrix()
    }

    fn make(s: [f64; 3]) -> Matrix3<f64> {
        rot(Vector3::new(0.3, -1.0, 0.4), 0.9)
            * Matrix3::from_diagonal(&Vector3::from(s))
            * rot(Vector3::new(1.0, 0.2, -0.5), -2.1)
    }

    #[test]
    fn analytic_pneumatic_jacobian_matches_dual_numbers() {
        for s in [[1.3, 0.9, 0.6], [1.3, 0.8, -0.4], [1e4, 1.0, 1e-4]] {
            for a in [1e-6, 0.5, 1.0, 2.0] {
                let f = make(s);
                let j = pneumatic_jacobian(&f, a).unwrap();
                let (df, da) = pneumatic_jacobian_dual(&f, a).unwrap();
                let ef = (j.wrt_f - df).amax() / df.amax();
                let ea = (j.wrt_a - da).amax() / da.amax();
                assert!(ef < 1e-8 && ea < 1e-8, "{s:?} a={a}: {ef:e} {ea:e}");
            }
        }
    }

    #[test]
    fn muscle_jacobian_matches_dual_numbers() {
        let f = make([1.3, 0.8, -0.4]);
        let m = Vector3::new(0.3, 0.5, -0.8).normalize();
        for a in [0.0, 0.5, 1.0] {
            let j = muscle_jacobian(&f, &m, a).unwrap();
            let (df, da) = muscle_jacobian_dual(&f, &m, a).unwrap();
            assert!((j.wrt_f - df).amax() < 1e-14 && (j.wrt_a - da).amax() < 1e-15);
        }
    }

    #[test]
    fn degenerate_pairs_are_errors() {
        // Opposite singular values: non-unique nearest point.
        let f = Matrix3::from_diagonal(&Vector3::new(2.0, 1.0, -1.0));
        assert_eq!(pneumatic_jacobian(&f, 1.0), Err(ActuatorError::NotDifferentiable));
        let s = svd3(&f);
        assert!(pneumatic_target(&s, 1.0).is_ok());
    }
}
