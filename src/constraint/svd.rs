//! Signed singular value decomposition of 3 x 3 matrices, `F = U diag(sigma) V^T`, with `U`
//! and `V` proper rotations (`det = +1`) and the sign of `det F` carried by the smallest
//! singular value. This is what makes the corotated projection `R = U V^T` a rotation for
//! inverted tets (METHOD.md section 2).
//!
//! The fast path follows McAdams et al. (2011): cyclic Jacobi on `F^T F` with exact rotations
//! (warm-startable from the previous `V`, so a local step of projective dynamics usually needs
//! one sweep), sorting, then a Givens QR of `F V` whose diagonal gives the singular values. The
//! QR step projects out the error of `V` along the large singular directions, so small singular
//! values stay accurate even when `F^T F` cannot resolve them. Non-finite input falls back to
//! nalgebra's SVD.

use nalgebra::{Matrix3, Vector3};

/// `F = u diag(sigma) v^T` with `det u = det v = 1`, `sigma[0] >= sigma[1] >= |sigma[2]|`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Svd3 {
    /// Left rotation.
    pub u: Matrix3<f64>,
    /// Signed singular values; only the last may be negative (inverted `F`).
    pub sigma: Vector3<f64>,
    /// Right rotation.
    pub v: Matrix3<f64>,
}

impl Svd3 {
    /// `u diag(s) v^T`.
    pub fn compose(&self, s: &Vector3<f64>) -> Matrix3<f64> {
        self.u * Matrix3::from_diagonal(s) * self.v.transpose()
    }

    /// The rotation `u v^T` closest to `F` (polar factor with `det = +1`).
    pub fn rotation(&self) -> Matrix3<f64> {
        self.u * self.v.transpose()
    }
}

/// SVD of `f` (cold start).
pub fn svd3(f: &Matrix3<f64>) -> Svd3 {
    svd3_warm(f, &Matrix3::identity())
}

/// SVD of `f`, starting the Jacobi iteration from the rotation `v0` (e.g. the previous `V` of
/// the same tet).
pub fn svd3_warm(f: &Matrix3<f64>, v0: &Matrix3<f64>) -> Svd3 {
    if !f.iter().all(|x| x.is_finite()) || !v0.iter().all(|x| x.is_finite()) {
        return svd3_nalgebra(f);
    }
    // S = V0^T (F^T F) V0, symmetric, stored as six scalars; V as a row-major array.
    let c = f.transpose() * f;
    let sm = v0.transpose() * c * v0;
    let (mut s00, mut s11, mut s22) = (sm[(0, 0)], sm[(1, 1)], sm[(2, 2)]);
    let (mut s01, mut s02, mut s12) = (sm[(0, 1)], sm[(0, 2)], sm[(1, 2)]);
    let mut v = [[0.0f64; 3]; 3];
    for (i, row) in v.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = v0[(i, j)];
        }
    }
    // Cyclic Jacobi with exact rotations (Numerical Recipes' update, unrolled for 3 x 3).
    for _ in 0..16 {
        let scale = s00.abs().max(s11.abs()).max(s22.abs());
        let off = s01.abs().max(s02.abs()).max(s12.abs());
        if off <= 1e-17 * scale || off == 0.0 {
            break;
        }
        // (p, q, r) = (0, 1, 2): zero s01; the third index couples through s02, s12.
        rotate(&mut s00, &mut s11, &mut s01, &mut s02, &mut s12, &mut v, 0, 1);
        rotate(&mut s00, &mut s22, &mut s02, &mut s01, &mut s12, &mut v, 0, 2);
        rotate(&mut s11, &mut s22, &mut s12, &mut s01, &mut s02, &mut v, 1, 2);
    }
    // Sort eigenvalues of F^T F decreasingly by permuting V's columns.
    let mut d = [s00, s11, s22];
    let mut col = [0usize, 1, 2];
    for i in 0..2 {
        for j in 0..2 - i {
            if d[j] < d[j + 1] {
                d.swap(j, j + 1);
                col.swap(j, j + 1);
            }
        }
    }
    let mut vm = Matrix3::from_fn(|i, j| v[i][col[j]]);
    if vm.determinant() < 0.0 {
        for i in 0..3 {
            vm[(i, 2)] = -vm[(i, 2)];
        }
    }
    // QR of B = F V by Givens rotations: B = U R, U a rotation, R upper triangular.
    let b = f * vm;
    let mut r = [[0.0f64; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = b[(i, j)];
        }
    }
    let mut u = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    givens(&mut r, &mut u, 0, 1, 0);
    givens(&mut r, &mut u, 0, 2, 0);
    givens(&mut r, &mut u, 1, 2, 1);
    Svd3 {
        u: Matrix3::from_fn(|i, j| u[i][j]),
        sigma: Vector3::new(r[0][0], r[1][1], r[2][2]),
        v: vm,
    }
}

/// Jacobi rotation zeroing `apq` of a symmetric 3 x 3 matrix with diagonal `app`, `aqq`,
/// whose remaining off-diagonal entries in rows `p` and `q` are `arp` and `arq` (`r` the third
/// index); `v <- v J` on columns `p`, `q`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn rotate(
    app: &mut f64,
    aqq: &mut f64,
    apq: &mut f64,
    arp: &mut f64,
    arq: &mut f64,
    v: &mut [[f64; 3]; 3],
    p: usize,
    q: usize,
) {
    let a = *apq;
    if a == 0.0 {
        return;
    }
    let theta = (*aqq - *app) / (2.0 * a);
    let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
    let c = 1.0 / (t * t + 1.0).sqrt();
    let s = t * c;
    *app -= t * a;
    *aqq += t * a;
    *apq = 0.0;
    let (rp, rq) = (*arp, *arq);
    *arp = c * rp - s * rq;
    *arq = s * rp + c * rq;
    for row in v.iter_mut() {
        let (vp, vq) = (row[p], row[q]);
        row[p] = c * vp - s * vq;
        row[q] = s * vp + c * vq;
    }
}

/// Zero `r[q][col]` against `r[p][col]` with a rotation from the left; `u <- u G`.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // rows p and q are updated in lockstep
fn givens(r: &mut [[f64; 3]; 3], u: &mut [[f64; 3]; 3], p: usize, q: usize, col: usize) {
    let (a, b) = (r[p][col], r[q][col]);
    let rho = (a * a + b * b).sqrt();
    if rho == 0.0 {
        return;
    }
    let (c, s) = (a / rho, b / rho);
    for k in 0..3 {
        let (rp, rq) = (r[p][k], r[q][k]);
        r[p][k] = c * rp + s * rq;
        r[q][k] = -s * rp + c * rq;
    }
    r[q][col] = 0.0;
    for row in u.iter_mut() {
        let (up, uq) = (row[p], row[q]);
        row[p] = c * up + s * uq;
        row[q] = -s * up + c * uq;
    }
}

/// Reference path: nalgebra's SVD with the signs fixed to rotations.
pub fn svd3_nalgebra(f: &Matrix3<f64>) -> Svd3 {
    let svd = f.svd(true, true);
    let (mut u, mut vt) = match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => (u, vt),
        _ => {
            return Svd3 {
                u: Matrix3::identity(),
                sigma: Vector3::repeat(f64::NAN),
                v: Matrix3::identity(),
            }
        }
    };
    let mut sigma = svd.singular_values;
    if u.determinant() < 0.0 {
        u.set_column(2, &(-u.column(2)));
        sigma[2] = -sigma[2];
    }
    if vt.determinant() < 0.0 {
        vt.set_row(2, &(-vt.row(2)));
        sigma[2] = -sigma[2];
    }
    Svd3 {
        u,
        sigma,
        v: vt.transpose(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(f: &Matrix3<f64>, s: &Svd3) {
        let scale = f.norm().max(1e-300);
        assert!(
            (s.compose(&s.sigma) - f).norm() <= 1e-13 * scale,
            "reconstruction {f} {s:?}"
        );
        assert!((s.u.determinant() - 1.0).abs() < 1e-12);
        assert!((s.v.determinant() - 1.0).abs() < 1e-12);
        assert!((s.u.transpose() * s.u - Matrix3::identity()).norm() < 1e-13);
        assert!(s.sigma[0] >= s.sigma[1] && s.sigma[1] >= s.sigma[2].abs() - 1e-14 * scale);
        assert_eq!(s.sigma[2] < 0.0, f.determinant() < 0.0);
    }

    #[test]
    fn identity_rotation_reflection_and_zero() {
        for f in [
            Matrix3::identity(),
            Matrix3::from_diagonal(&Vector3::new(1.0, 2.0, 3.0)),
            Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0)),
            Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0),
        ] {
            check(&f, &svd3(&f));
        }
        let z = svd3(&Matrix3::zeros());
        assert_eq!(z.sigma, Vector3::zeros());
    }

    #[test]
    fn matches_nalgebra_on_a_grid_of_matrices() {
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for _ in 0..2000 {
            let f = Matrix3::from_fn(|_, _| rnd()) + Matrix3::identity() * rnd();
            let a = svd3(&f);
            let b = svd3_nalgebra(&f);
            check(&f, &a);
            assert!(
                (a.sigma - b.sigma).norm() < 1e-13 * f.norm(),
                "{} vs {}",
                a.sigma,
                b.sigma
            );
        }
    }
}
