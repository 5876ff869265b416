//! Signed singular value decomposition of 3 x 3 matrices, `F = U diag(sigma) V^T`, with `U`
//! and `V` proper rotations (`det = +1`) and the sign of `det F` carried by the smallest
//! singular value. This is what makes the corotated projection `R = U V^T` a rotation for
//! inverted tets (docs/method.md section 2).
//!
//! The fast path follows McAdams et al. (2011): cyclic Jacobi on `F^T F` with exact rotations
//! (warm-startable from the previous `V`, so a local step of projective dynamics usually needs
//! one sweep), sorting, then an orthonormal factorisation of `F V` (Gram-Schmidt, `u3 = u1 x u2`)
//! whose column norms give the singular values. That step projects out the error of `V` along the
//! large singular directions, so small singular values stay accurate even when `F^T F` cannot
//! resolve them. Non-finite input falls back to
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
        let us = Matrix3::from_fn(|i, j| self.u[(i, j)] * s[j]);
        us * self.v.transpose()
    }

    /// The rotation `u v^T` closest to `F` (polar factor with `det = +1`).
    pub fn rotation(&self) -> Matrix3<f64> {
        self.u * self.v.transpose()
    }
}

/// Jacobi stops when the off-diagonal of `V^T F^T F V` is below this times its diagonal
/// (converged to round-off: looser values cost reconstruction accuracy on graded matrices).
const JACOBI_TOL: f64 = 1e-17;

/// SVD of `f` (cold start).
///
/// ```
/// use diffsoft::kernel::svd::svd3;
/// use nalgebra::{Matrix3, Vector3};
///
/// // An inverted F: the sign of det F is carried by the smallest singular value.
/// let f = Matrix3::new(0.0, 2.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0, 1.0);
/// let svd = svd3(&f);
/// assert!((svd.sigma - Vector3::new(3.0, 2.0, -1.0)).norm() < 1e-12);
/// assert!((svd.u.determinant() - 1.0).abs() < 1e-12 && (svd.v.determinant() - 1.0).abs() < 1e-12);
/// assert!((svd.compose(&svd.sigma) - f).norm() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn svd3(f: &Matrix3<f64>) -> Svd3 {
    svd3_warm(f, &Matrix3::identity())
}

/// SVD of `f`, starting the Jacobi iteration from the rotation `v0` (e.g. the previous `V` of
/// the same tet).
///
/// ```
/// use diffsoft::kernel::svd::{svd3, svd3_warm};
/// use nalgebra::Matrix3;
///
/// let f = Matrix3::new(1.0, 0.2, 0.0, 0.1, 0.9, 0.0, 0.0, 0.05, 1.1);
/// let previous = svd3(&f);
/// // A small change of F, started from the previous V.
/// let g = f + Matrix3::identity() * 1e-3;
/// let svd = svd3_warm(&g, &previous.v);
/// assert!((svd.compose(&svd.sigma) - g).norm() < 1e-12);
/// assert!((svd.sigma - svd3(&g).sigma).norm() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
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
        if off <= JACOBI_TOL * scale || off == 0.0 {
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
    let (u, sigma) = orthonormal_factor(&(f * vm));
    if sigma[1] * ILL_CONDITIONED < sigma[0] {
        return one_sided_polish(f, &vm);
    }
    Svd3 { u, sigma, v: vm }
}

/// When `sigma_1 / sigma_2` exceeds this, `V` from `F^T F` is accurate only to
/// `eps (sigma_1/sigma_2)^2`; such (rare, extreme) matrices are finished by one-sided Jacobi.
const ILL_CONDITIONED: f64 = 30.0;

/// One-sided (Hestenes) Jacobi on `B = F V`, started from an approximate `V`: rotate column
/// pairs of `B` (and `V`) until they are orthogonal to round-off, so `F = U diag(sigma) V^T`
/// holds to `eps |F|` and small singular values keep their relative accuracy.
#[allow(clippy::needless_range_loop)]
fn one_sided_polish(f: &Matrix3<f64>, v0: &Matrix3<f64>) -> Svd3 {
    let mut b = f * v0;
    let mut v = *v0;
    for _ in 0..20 {
        let mut rotated = false;
        for (i, j) in [(0, 1), (0, 2), (1, 2)] {
            let alpha = b.column(i).norm_squared();
            let beta = b.column(j).norm_squared();
            let gamma = b.column(i).dot(&b.column(j));
            if gamma == 0.0 || gamma.abs() <= f64::EPSILON * (alpha * beta).sqrt() {
                continue;
            }
            rotated = true;
            let zeta = (beta - alpha) / (2.0 * gamma);
            let t = zeta.signum() / (zeta.abs() + (1.0 + zeta * zeta).sqrt());
            let c = 1.0 / (1.0 + t * t).sqrt();
            let sn = c * t;
            for m in [&mut b, &mut v] {
                for r in 0..3 {
                    let (x, y) = (m[(r, i)], m[(r, j)]);
                    m[(r, i)] = c * x - sn * y;
                    m[(r, j)] = sn * x + c * y;
                }
            }
        }
        if !rotated {
            break;
        }
    }
    // Sort columns by norm, make V a rotation, then factor B = U diag(sigma).
    let norms = [b.column(0).norm(), b.column(1).norm(), b.column(2).norm()];
    let mut col = [0usize, 1, 2];
    col.sort_by(|&x, &y| norms[y].total_cmp(&norms[x]));
    let mut vm = Matrix3::from_columns(&[v.column(col[0]), v.column(col[1]), v.column(col[2])]);
    let mut bm = Matrix3::from_columns(&[b.column(col[0]), b.column(col[1]), b.column(col[2])]);
    if vm.determinant() < 0.0 {
        vm.set_column(2, &(-vm.column(2)));
        bm.set_column(2, &(-bm.column(2)));
    }
    let (u, sigma) = orthonormal_factor(&bm);
    Svd3 { u, sigma, v: vm }
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
    let d = *aqq - *app;
    let t = 2.0 * a * d.signum() / (d.abs() + (d * d + 4.0 * a * a).sqrt()).max(f64::MIN_POSITIVE);
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

/// `B = U diag(sigma)` for `B = F V` whose columns are orthogonal (up to the accuracy of `V`):
/// Gram-Schmidt on the first two columns, `u3 = u1 x u2` (so `U` is a rotation), and
/// `sigma_3 = u3 . b3` carrying the sign of `det F`.
#[inline(always)]
fn orthonormal_factor(b: &Matrix3<f64>) -> (Matrix3<f64>, Vector3<f64>) {
    let b1 = b.column(0).into_owned();
    let b2 = b.column(1).into_owned();
    let b3 = b.column(2).into_owned();
    let s1 = b1.norm();
    let u1 = if s1 > 0.0 { b1 / s1 } else { Vector3::x() };
    let w2 = b2 - u1 * u1.dot(&b2);
    let s2 = w2.norm();
    let u2 = if s2 > 0.0 {
        w2 / s2
    } else {
        // Any unit vector orthogonal to u1.
        let a = if u1.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
        let p = a - u1 * u1.dot(&a);
        p / p.norm()
    };
    let u3 = u1.cross(&u2);
    (Matrix3::from_columns(&[u1, u2, u3]), Vector3::new(s1, s2, u3.dot(&b3)))
}

/// Reference path: nalgebra's SVD with the signs fixed to rotations.
///
/// ```
/// use diffsoft::kernel::svd::{svd3, svd3_nalgebra};
/// use nalgebra::Matrix3;
///
/// let f = Matrix3::new(1.0, 0.2, 0.0, 0.1, -0.9, 0.0, 0.0, 0.05, 1.1);
/// let (a, b) = (svd3_nalgebra(&f), svd3(&f));
/// assert!((a.sigma - b.sigma).norm() < 1e-12);
/// assert!(a.sigma[2] < 0.0); // det F < 0
/// assert!((a.u.determinant() - 1.0).abs() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
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

/// Number of tets decomposed together by [`svd3_warm_batch`]: two AVX2 vectors, so two
/// independent chains of the latency-bound Jacobi rotations overlap (measured 22% faster
/// than one vector of four).
pub const LANES: usize = 8;

/// [`svd3_warm`] for `LANES` matrices at once, structure-of-arrays: the Jacobi sweeps, sorting
/// and QR run lane by lane
/// on arrays, so the serial chains of divisions and square roots of independent matrices
/// overlap (and vectorise). Results are identical in exact arithmetic and agree with the
/// one-matrix version to round-off. Sweeps continue until every lane has converged.
///
/// On x86-64 CPUs with AVX2 the same code runs compiled for AVX2 (selected at run time); only
/// the vector width changes, so results are bit-identical (no fused multiply-add is enabled).
///
/// ```
/// use diffsoft::kernel::svd::{svd3, svd3_warm_batch, LANES};
/// use nalgebra::Matrix3;
///
/// let f: [Matrix3<f64>; LANES] =
///     std::array::from_fn(|k| Matrix3::identity() * (1.0 + k as f64) + Matrix3::repeat(0.1));
/// let svds = svd3_warm_batch(&f, &[Matrix3::identity(); LANES]);
/// for (svd, f) in svds.iter().zip(&f) {
///     assert!((svd.compose(&svd.sigma) - f).norm() < 1e-12);
///     assert!((svd.sigma - svd3(f).sigma).norm() < 1e-12);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn svd3_warm_batch(f: &[Matrix3<f64>; LANES], v0: &[Matrix3<f64>; LANES]) -> [Svd3; LANES] {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { batch_avx2(f, v0) };
        }
    }
    batch_generic(f, v0)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn batch_avx2(f: &[Matrix3<f64>; LANES], v0: &[Matrix3<f64>; LANES]) -> [Svd3; LANES] {
    batch_generic(f, v0)
}

/// One scalar per lane.
pub(crate) type Lane = [f64; LANES];
/// One 3 x 3 matrix per lane, `m[i][j][lane]`.
pub(crate) type LaneMatrix = [[Lane; 3]; 3];

/// The identity in every lane (a warm start never decomposed, the `F` of an unused lane).
pub(crate) const IDENTITY_LANES: LaneMatrix = {
    let mut m = [[[0.0; LANES]; 3]; 3];
    let mut i = 0;
    while i < 3 {
        m[i][i] = [1.0; LANES];
        i += 1;
    }
    m
};

/// `LANES` decompositions in structure-of-arrays form (`u[i][j][lane]`), as the batched kernel
/// computes them: the local step reads its lanes from here without first gathering each into
/// an [`Svd3`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct SoaSvd {
    /// Left rotations.
    pub u: [[Lane; 3]; 3],
    /// Signed singular values.
    pub sigma: [Lane; 3],
    /// Right rotations.
    pub v: [[Lane; 3]; 3],
}

impl SoaSvd {
    /// All zeros (a buffer to decompose into).
    pub(crate) const ZERO: SoaSvd = SoaSvd {
        u: [[[0.0; LANES]; 3]; 3],
        sigma: [[0.0; LANES]; 3],
        v: [[[0.0; LANES]; 3]; 3],
    };

    /// Lane `k` as an [`Svd3`].
    #[inline(always)]
    pub(crate) fn lane(&self, k: usize) -> Svd3 {
        Svd3 {
            u: lane_matrix(&self.u, k),
            sigma: self.sigma_of(k),
            v: self.v_of(k),
        }
    }

    /// Lane `k`'s right rotation.
    #[inline(always)]
    pub(crate) fn v_of(&self, k: usize) -> Matrix3<f64> {
        lane_matrix(&self.v, k)
    }

    /// Lane `k`'s singular values.
    #[inline(always)]
    pub(crate) fn sigma_of(&self, k: usize) -> Vector3<f64> {
        Vector3::new(self.sigma[0][k], self.sigma[1][k], self.sigma[2][k])
    }

    /// Store `svd` in lane `k`.
    #[inline(always)]
    fn set(&mut self, k: usize, svd: &Svd3) {
        for i in 0..3 {
            for j in 0..3 {
                self.u[i][j][k] = svd.u[(i, j)];
                self.v[i][j][k] = svd.v[(i, j)];
            }
            self.sigma[i][k] = svd.sigma[i];
        }
    }

    /// Lane `k`'s `u diag(s) v^T`, with the same operations in the same order as
    /// [`Svd3::compose`] (so the same bits): `(u_i0 s_0) v_j0 + (u_i1 s_1) v_j1`, then
    /// `+ (u_i2 s_2) v_j2`.
    #[inline(always)]
    pub(crate) fn compose(&self, k: usize, s: &Vector3<f64>) -> Matrix3<f64> {
        let (u, v) = (&self.u, &self.v);
        // Row i of `u diag(s)`.
        let us = |i: usize| [u[i][0][k] * s[0], u[i][1][k] * s[1], u[i][2][k] * s[2]];
        let (a, b, c) = (us(0), us(1), us(2));
        let dot = |r: &[f64; 3], j: usize| r[0] * v[j][0][k] + r[1] * v[j][1][k] + r[2] * v[j][2][k];
        Matrix3::new(
            dot(&a, 0),
            dot(&a, 1),
            dot(&a, 2),
            dot(&b, 0),
            dot(&b, 1),
            dot(&b, 2),
            dot(&c, 0),
            dot(&c, 1),
            dot(&c, 2),
        )
    }
}

/// Lane `k` of a structure-of-arrays matrix (written out: nalgebra's `from_fn` is not always
/// inlined into the AVX2 kernel).
#[inline(always)]
pub(crate) fn lane_matrix(m: &LaneMatrix, k: usize) -> Matrix3<f64> {
    Matrix3::new(
        m[0][0][k], m[0][1][k], m[0][2][k], m[1][0][k], m[1][1][k], m[1][2][k], m[2][0][k], m[2][1][k], m[2][2][k],
    )
}

#[inline(always)]
pub(crate) fn batch_generic(f: &[Matrix3<f64>; LANES], v0: &[Matrix3<f64>; LANES]) -> [Svd3; LANES] {
    let soa = batch_soa(f, v0);
    let mut out = [Svd3 {
        u: Matrix3::zeros(),
        sigma: Vector3::zeros(),
        v: Matrix3::zeros(),
    }; LANES];
    for (k, o) in out.iter_mut().enumerate() {
        *o = soa.lane(k);
    }
    out
}

/// [`svd3_warm_batch`] in structure-of-arrays form, for callers compiled for the same
/// target features (the local step's AVX2 kernel inlines it).
#[inline(always)]
#[allow(clippy::needless_range_loop)] // lane loops over parallel arrays
pub(crate) fn batch_soa(f: &[Matrix3<f64>; LANES], v0: &[Matrix3<f64>; LANES]) -> SoaSvd {
    // (Plain loops: a profile of a run bound by the local step showed `try_from_fn` frames,
    // 5.5% of it, for the arrays this kernel and its caller built with `std::array::from_fn`.)
    let mut fm = [[[0.0f64; LANES]; 3]; 3];
    let mut v = [[[0.0f64; LANES]; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..LANES {
                fm[i][j][k] = f[k][(i, j)];
                v[i][j][k] = v0[k][(i, j)];
            }
        }
    }
    batch_lanes(&fm, &v)
}

/// [`batch_soa`] with its inputs already in structure-of-arrays form, `f[i][j][lane]` and
/// `v0[i][j][lane]` (the local step gathers each tet's `F` there and keeps its warm starts
/// there between steps).
#[inline(always)]
#[allow(clippy::needless_range_loop)] // lane loops over parallel arrays
pub(crate) fn batch_lanes(fm: &LaneMatrix, v0: &LaneMatrix) -> SoaSvd {
    // One sum is non-finite iff an entry is (or, harmlessly, the sum overflows): cheaper than
    // testing 144 entries one by one. Nine sums, one per entry position, so the additions
    // form nine short chains instead of one of 144.
    let mut total = [0.0f64; 9];
    for m in [fm, v0] {
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..LANES {
                    total[3 * i + j] += m[i][j][k] * 0.0;
                }
            }
        }
    }
    if !total.iter().sum::<f64>().is_finite() {
        let mut out = SoaSvd::ZERO;
        for k in 0..LANES {
            out.set(k, &svd3_warm(&lane_matrix(fm, k), &lane_matrix(v0, k)));
        }
        return out;
    }
    const L: usize = LANES;
    // Everything below is structure-of-arrays (`m[i][j][lane]`) and branch-free per lane, so
    // it vectorises; only lanes that need the one-sided polish leave for the scalar code.
    let mut v = *v0;
    // B0 = F V0, then S = B0^T B0 = V0^T F^T F V0 (six entries).
    let mut b = [[[0.0f64; L]; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..L {
                b[i][j][k] = fm[i][0][k] * v[0][j][k] + fm[i][1][k] * v[1][j][k] + fm[i][2][k] * v[2][j][k];
            }
        }
    }
    let mut s = [[0.0f64; L]; 6]; // s00, s11, s22, s01, s02, s12
    for (slot, (p, q)) in [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)].into_iter().enumerate() {
        for k in 0..L {
            s[slot][k] = b[0][p][k] * b[0][q][k] + b[1][p][k] * b[1][q][k] + b[2][p][k] * b[2][q][k];
        }
    }
    for _ in 0..16 {
        let mut done = true;
        for k in 0..L {
            let scale = s[0][k].abs().max(s[1][k].abs()).max(s[2][k].abs());
            let off = s[3][k].abs().max(s[4][k].abs()).max(s[5][k].abs());
            done &= off <= JACOBI_TOL * scale || off == 0.0;
        }
        if done {
            break;
        }
        // (p, q) = (0,1): app s00, aqq s11, apq s01, arp s02, arq s12.
        rotate_lanes(&mut s, &mut v, [0, 1, 3, 4, 5], 0, 1);
        // (0,2): app s00, aqq s22, apq s02, arp s01, arq s12.
        rotate_lanes(&mut s, &mut v, [0, 2, 4, 3, 5], 0, 2);
        // (1,2): app s11, aqq s22, apq s12, arp s01, arq s02.
        rotate_lanes(&mut s, &mut v, [1, 2, 5, 3, 4], 1, 2);
    }
    // Sort the eigenvalues decreasingly (the network of the scalar code), permuting V's columns.
    let mut d = [s[0], s[1], s[2]];
    for (p, q) in [(0, 1), (1, 2), (0, 1)] {
        for k in 0..L {
            let swap = d[p][k] < d[q][k];
            let (dp, dq) = (d[p][k], d[q][k]);
            d[p][k] = if swap { dq } else { dp };
            d[q][k] = if swap { dp } else { dq };
            for row in v.iter_mut() {
                let (a, c) = (row[p][k], row[q][k]);
                row[p][k] = if swap { c } else { a };
                row[q][k] = if swap { a } else { c };
            }
        }
    }
    // det V = +1 (flip the last column otherwise).
    for k in 0..L {
        let det = v[0][0][k] * (v[1][1][k] * v[2][2][k] - v[1][2][k] * v[2][1][k])
            - v[0][1][k] * (v[1][0][k] * v[2][2][k] - v[1][2][k] * v[2][0][k])
            + v[0][2][k] * (v[1][0][k] * v[2][1][k] - v[1][1][k] * v[2][0][k]);
        let sign = if det < 0.0 { -1.0 } else { 1.0 };
        for row in v.iter_mut() {
            row[2][k] *= sign;
        }
    }
    // B = F V and its orthonormal factor (as `orthonormal_factor`).
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..L {
                b[i][j][k] = fm[i][0][k] * v[0][j][k] + fm[i][1][k] * v[1][j][k] + fm[i][2][k] * v[2][j][k];
            }
        }
    }
    let mut u = [[[0.0f64; L]; 3]; 3];
    let mut sigma = [[0.0f64; L]; 3];
    let mut scalar = [false; L];
    for k in 0..L {
        let s1 = (b[0][0][k] * b[0][0][k] + b[1][0][k] * b[1][0][k] + b[2][0][k] * b[2][0][k]).sqrt();
        let inv1 = if s1 > 0.0 { 1.0 / s1 } else { 0.0 };
        let u1 = [b[0][0][k] * inv1, b[1][0][k] * inv1, b[2][0][k] * inv1];
        let c = u1[0] * b[0][1][k] + u1[1] * b[1][1][k] + u1[2] * b[2][1][k];
        let w2 = [b[0][1][k] - u1[0] * c, b[1][1][k] - u1[1] * c, b[2][1][k] - u1[2] * c];
        let s2 = (w2[0] * w2[0] + w2[1] * w2[1] + w2[2] * w2[2]).sqrt();
        let inv2 = if s2 > 0.0 { 1.0 / s2 } else { 0.0 };
        let u2 = [w2[0] * inv2, w2[1] * inv2, w2[2] * inv2];
        let u3 = [
            u1[1] * u2[2] - u1[2] * u2[1],
            u1[2] * u2[0] - u1[0] * u2[2],
            u1[0] * u2[1] - u1[1] * u2[0],
        ];
        for i in 0..3 {
            u[i][0][k] = u1[i];
            u[i][1][k] = u2[i];
            u[i][2][k] = u3[i];
        }
        sigma[0][k] = s1;
        sigma[1][k] = s2;
        sigma[2][k] = u3[0] * b[0][2][k] + u3[1] * b[1][2][k] + u3[2] * b[2][2][k];
        // Zero columns (need an arbitrary completion) and ill-conditioned lanes: scalar tail.
        scalar[k] = !(s1 > 0.0 && s2 > 0.0) || s2 * ILL_CONDITIONED < s1;
    }
    let mut out = SoaSvd { u, sigma, v };
    for k in 0..L {
        if scalar[k] {
            let vm = Matrix3::from_fn(|i, j| v[i][j][k]);
            let fk = lane_matrix(fm, k);
            let (uk, sk) = orthonormal_factor(&(fk * vm));
            let svd = if sk[1] * ILL_CONDITIONED < sk[0] {
                one_sided_polish(&fk, &vm)
            } else {
                Svd3 {
                    u: uk,
                    sigma: sk,
                    v: vm,
                }
            };
            out.set(k, &svd);
        }
    }
    out
}

/// One Jacobi rotation on every lane; `idx` = positions of (app, aqq, apq, arp, arq) in `s`.
#[inline(always)]
#[allow(clippy::needless_range_loop)]
fn rotate_lanes(s: &mut [[f64; LANES]; 6], v: &mut [[[f64; LANES]; 3]; 3], idx: [usize; 5], p: usize, q: usize) {
    let [ip, iq, ipq, irp, irq] = idx;
    let mut c = [1.0f64; LANES];
    let mut sn = [0.0f64; LANES];
    for k in 0..LANES {
        let a = s[ipq][k];
        // t = tan of the rotation angle, branch-free: 2a sgn(d) / (|d| + sqrt(d^2 + 4a^2)),
        // which is 0 when a = 0 (the max() only guards a = d = 0).
        let d = s[iq][k] - s[ip][k];
        let t = 2.0 * a * d.signum() / (d.abs() + (d * d + 4.0 * a * a).sqrt()).max(f64::MIN_POSITIVE);
        let ck = 1.0 / (t * t + 1.0).sqrt();
        c[k] = ck;
        sn[k] = t * ck;
        s[ip][k] -= t * a;
        s[iq][k] += t * a;
        s[ipq][k] = 0.0;
        let (rp, rq) = (s[irp][k], s[irq][k]);
        s[irp][k] = ck * rp - sn[k] * rq;
        s[irq][k] = sn[k] * rp + ck * rq;
    }
    for row in v.iter_mut() {
        for k in 0..LANES {
            let (vp, vq) = (row[p][k], row[q][k]);
            row[p][k] = c[k] * vp - sn[k] * vq;
            row[q][k] = sn[k] * vp + c[k] * vq;
        }
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

    /// A reproducible stream of numbers in `[-0.5, 0.5)` (a linear congruential generator).
    fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    #[test]
    fn matches_nalgebra_on_a_grid_of_matrices() {
        let mut rnd = uniform(7u64);
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

    #[test]
    fn the_lanes_compose_to_the_same_bits_as_svd3_compose() {
        // The local step composes its projections from the structure-of-arrays result; its
        // trajectories stay bit-identical only if this equals `Svd3::compose` exactly.
        let mut rnd = uniform(11u64);
        for round in 0..200 {
            let f: [Matrix3<f64>; LANES] = std::array::from_fn(|k| {
                let m = Matrix3::from_fn(|_, _| rnd()) + Matrix3::identity() * (1.0 + rnd());
                // Some lanes ill-conditioned or inverted: the scalar tail's lanes too.
                match (round + k) % 5 {
                    0 => m * Matrix3::from_diagonal(&Vector3::new(1.0, 1e-3, 1.0)),
                    1 => -m,
                    _ => m,
                }
            });
            let v0: [Matrix3<f64>; LANES] = std::array::from_fn(|k| svd3(&(f[k] + Matrix3::repeat(1e-3))).v);
            let soa = batch_soa(&f, &v0);
            let arr = batch_generic(&f, &v0);
            for (k, svd) in arr.iter().enumerate() {
                assert_eq!(soa.lane(k), *svd);
                let d = Vector3::new(rnd(), rnd(), rnd());
                let a = soa.compose(k, &d);
                let b = svd.compose(&d);
                for (x, y) in a.iter().zip(b.iter()) {
                    assert_eq!(x.to_bits(), y.to_bits(), "lane {k}: {a} vs {b}");
                }
            }
        }
    }
}
