//! Hyperelastic energy densities of one element (docs/method.md section 2.4, Eqs. H1-H4): the
//! fixed-corotated energy (Stomakhin et al. 2012) and the stable Neo-Hookean energy (Smith,
//! de Goes and Kim 2018), each with its first Piola-Kirchhoff stress `P = dPsi/dF`, the stress
//! derivative `dP/dF` (a 9 x 9 matrix on `vec F`, column-major) and the derivatives of `P` with
//! respect to the Lame parameters (the backward pass's parameter adjoints).
//!
//! Both reproduce linear elasticity with the given Lame parameters `(mu, lambda)` at small
//! strain (Eq. H4, checked by the tests below): `P ~ mu (eps + eps^T) + lambda tr(eps) I`.
//!
//! * Fixed corotated (Eq. H1): `Psi = mu |F - R|^2 + lambda/2 (J - 1)^2`, `R` the rotation of
//!   the polar decomposition (the signed SVD's `U V^T`, a rotation even for inverted `F`).
//! * Stable Neo-Hookean (Eq. H2), without the logarithmic term: `Psi = mu/2 (|F|^2 - 3) +
//!   lambda'/2 (J - alpha)^2 - Psi_0` with `lambda' = lambda + mu` and `alpha = 1 + mu/lambda'`,
//!   so that `F = I` is stress-free and the small-strain response is exactly `(mu, lambda)`
//!   (Eq. H3); `Psi_0 = mu^2 / (2 lambda')` makes the rest energy zero. Defined and smooth for
//!   every `F`, inverted ones included.

use nalgebra::{Matrix3, SMatrix, SymmetricEigen, Vector3};

use super::svd::{svd3, svd3_warm_batch, Svd3, LANES};

/// A 9 x 9 matrix acting on `vec F` (column-major: entry `(i, j)` of `F` at `i + 3 j`).
pub type Mat9 = SMatrix<f64, 9, 9>;

/// The hyperelastic energies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Energy {
    /// Fixed corotated (Eq. H1).
    FixedCorotated,
    /// Stable Neo-Hookean (Eq. H2).
    StableNeoHookean,
}

/// Lame parameters `(mu, lambda)` (Pa).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lame {
    /// Shear modulus `mu`.
    pub mu: f64,
    /// Lame's first parameter `lambda`.
    pub lambda: f64,
}

impl Lame {
    /// The Lame parameters of Young's modulus `e` and Poisson ratio `nu`: `mu = E/(2(1+nu))`,
    /// `lambda = E nu/((1+nu)(1-2nu))`.
    ///
    /// ```
    /// use diffsoft::kernel::hyperelastic::Lame;
    /// let l = Lame::from_young(1e6, 0.25);
    /// assert!((l.mu - 4e5).abs() < 1e-6 && (l.lambda - 4e5).abs() < 1e-6);
    /// ```
    pub fn from_young(e: f64, nu: f64) -> Self {
        Self {
            mu: e / (2.0 * (1.0 + nu)),
            lambda: e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
        }
    }

    /// `(dmu/dE, dlambda/dE, dmu/dnu, dlambda/dnu)` at `(e, nu)`.
    pub fn derivatives(e: f64, nu: f64) -> (f64, f64, f64, f64) {
        let a = 1.0 + nu;
        let b = 1.0 - 2.0 * nu;
        let dmu_de = 1.0 / (2.0 * a);
        let dl_de = nu / (a * b);
        let dmu_dnu = -e / (2.0 * a * a);
        // lambda = E nu / (a b): d/dnu = E (a b - nu (b - 2 a)) / (a b)^2 = E (1 + 2 nu^2) / (a b)^2.
        let dl_dnu = e * (1.0 + 2.0 * nu * nu) / ((a * b) * (a * b));
        (dmu_de, dl_de, dmu_dnu, dl_dnu)
    }
}

/// `dJ/dF`, the cofactor matrix (columns `f1 x f2`, `f2 x f0`, `f0 x f1`).
fn cofactor(f: &Matrix3<f64>) -> Matrix3<f64> {
    let (c0, c1, c2) = (
        f.column(0).into_owned(),
        f.column(1).into_owned(),
        f.column(2).into_owned(),
    );
    Matrix3::from_columns(&[c1.cross(&c2), c2.cross(&c0), c0.cross(&c1)])
}

/// `d vec(cof F) / d vec(F)` (9 x 9, symmetric): the cofactor's columns are `f1 x f2`,
/// `f2 x f0` and `f0 x f1`, so block `(a, b)` (rows of column `a`, columns of column `b`) is
/// `[f_c]_x` or its negative for the third column `c`, and the diagonal blocks are zero.
fn cofactor_hessian(f: &Matrix3<f64>) -> Mat9 {
    let skew = |v: Vector3<f64>| Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0);
    let mut h = Mat9::zeros();
    for (a, b, c, sign) in [
        (0, 1, 2, -1.0),
        (0, 2, 1, 1.0),
        (1, 2, 0, -1.0),
        (1, 0, 2, 1.0),
        (2, 0, 1, -1.0),
        (2, 1, 0, 1.0),
    ] {
        let block = skew(f.column(c).into_owned()) * sign;
        h.fixed_view_mut::<3, 3>(3 * a, 3 * b).copy_from(&block);
    }
    h
}

/// The cofactor's derivative in direction `d` (the reference [`cofactor_hessian`] is tested
/// against).
#[cfg(test)]
fn cofactor_derivative(f: &Matrix3<f64>, d: &Matrix3<f64>) -> Matrix3<f64> {
    let c = |m: &Matrix3<f64>, k: usize| -> Vector3<f64> { m.column(k).into_owned() };
    Matrix3::from_columns(&[
        c(d, 1).cross(&c(f, 2)) + c(f, 1).cross(&c(d, 2)),
        c(d, 2).cross(&c(f, 0)) + c(f, 2).cross(&c(d, 0)),
        c(d, 0).cross(&c(f, 1)) + c(f, 0).cross(&c(d, 1)),
    ])
}

/// The rotation of `F` (signed SVD) and, for `dR/dF`, its singular vectors and values.
#[derive(Debug, Clone, Copy)]
struct Polar {
    r: Matrix3<f64>,
    u: Matrix3<f64>,
    v: Matrix3<f64>,
    s: Vector3<f64>,
}

fn polar(f: &Matrix3<f64>) -> Polar {
    Polar::of(&svd3(f))
}

impl Polar {
    fn of(svd: &Svd3) -> Self {
        Self {
            r: svd.u * svd.v.transpose(),
            u: svd.u,
            v: svd.v,
            s: svd.sigma,
        }
    }
}

/// The polar decompositions a batch of tets needs, computed together: `LANES` tets' `F` through
/// the batched SVD ([`svd3_warm_batch`], started from the identity, so the result does not
/// depend on what was decomposed before), where some tet of the batch is fixed corotated.
/// Tets past `f.len()` are padded with the identity.
pub struct Polars([Option<Polar>; LANES]);

impl Polars {
    /// The decompositions of `f` (at most [`LANES`] tets) for the energies `energy`.
    ///
    /// ```
    /// use diffsoft::kernel::hyperelastic::{Energy, Lame, Polars};
    /// use nalgebra::Matrix3;
    ///
    /// let f = [Matrix3::new(1.1, 0.2, 0.0, -0.1, 0.9, 0.05, 0.0, 0.1, 1.2); 3];
    /// let l = Lame::from_young(1e5, 0.3);
    /// let pol = Polars::new(&[Energy::FixedCorotated; 3], &f);
    /// let (p, psi) = Energy::FixedCorotated.stress_and_energy_at(l, &f[1], &pol, 1);
    /// assert!((p - Energy::FixedCorotated.stress(l, &f[1])).norm() < 1e-9 * p.norm());
    /// assert!((psi - Energy::FixedCorotated.energy(l, &f[1])).abs() < 1e-9 * psi);
    /// ```
    pub fn new(energy: &[Energy], f: &[Matrix3<f64>]) -> Self {
        assert!(
            f.len() <= LANES && energy.len() == f.len(),
            "at most LANES tets, one energy each"
        );
        if !energy.contains(&Energy::FixedCorotated) {
            return Self(std::array::from_fn(|_| None));
        }
        let fm: [Matrix3<f64>; LANES] = std::array::from_fn(|k| f.get(k).copied().unwrap_or_else(Matrix3::identity));
        let svds = svd3_warm_batch(&fm, &[Matrix3::identity(); LANES]);
        Self(std::array::from_fn(|k| {
            (energy.get(k) == Some(&Energy::FixedCorotated)).then(|| Polar::of(&svds[k]))
        }))
    }
}

impl Polar {
    /// `dR/dF` as its three rank-one terms: with `T_ab = u_a v_b^T - u_b v_a^T` for the pairs
    /// `a < b`, `dR[d] = sum_ab (T_ab : d) / (s_a + s_b) T_ab` (from `M = U^T d V`,
    /// `dR = U W V^T`, `W` antisymmetric with `W_ab = (M_ab - M_ba)/(s_a + s_b)`, and
    /// `M_ab - M_ba = T_ab : d`). Returns each pair's `T_ab` and `1/(s_a + s_b)`; a pair with
    /// `s_a + s_b` near zero, a tet inverted through a singular configuration, gets 0 and
    /// contributes nothing.
    fn derivative_terms(&self) -> [(Matrix3<f64>, f64); 3] {
        let scale = self.s.abs().max().max(f64::MIN_POSITIVE);
        [(0, 1), (0, 2), (1, 2)].map(|(a, b)| {
            let (ua, ub) = (self.u.column(a), self.u.column(b));
            let (va, vb) = (self.v.column(a), self.v.column(b));
            let t = ua * vb.transpose() - ub * va.transpose();
            let den = self.s[a] + self.s[b];
            (t, if den.abs() > 1e-12 * scale { 1.0 / den } else { 0.0 })
        })
    }
}

impl Energy {
    /// `lambda'` and `alpha` of the stable Neo-Hookean energy (Eq. H3).
    fn snh(l: Lame) -> (f64, f64) {
        let lp = l.lambda + l.mu;
        (lp, 1.0 + l.mu / lp)
    }

    /// The energy density `Psi(F)` (J/m^3).
    pub fn energy(self, l: Lame, f: &Matrix3<f64>) -> f64 {
        let j = f.determinant();
        match self {
            Energy::FixedCorotated => {
                let r = polar(f).r;
                l.mu * (f - r).norm_squared() + 0.5 * l.lambda * (j - 1.0) * (j - 1.0)
            }
            Energy::StableNeoHookean => {
                let (lp, alpha) = Self::snh(l);
                0.5 * l.mu * (f.norm_squared() - 3.0) + 0.5 * lp * (j - alpha) * (j - alpha) - l.mu * l.mu / (2.0 * lp)
            }
        }
    }

    /// The first Piola-Kirchhoff stress `P = dPsi/dF` (Pa).
    pub fn stress(self, l: Lame, f: &Matrix3<f64>) -> Matrix3<f64> {
        self.stress_and_energy(l, f).0
    }

    /// The stress `P(F)` and the energy density `Psi(F)` together, from one polar
    /// decomposition (the same values as [`Energy::stress`] and [`Energy::energy`]).
    pub fn stress_and_energy(self, l: Lame, f: &Matrix3<f64>) -> (Matrix3<f64>, f64) {
        self.stress_and_energy_with(l, f, || polar(f))
    }

    /// [`Energy::stress_and_energy`] of tet `k` of a batch whose decompositions are `polars`
    /// ([`Polars::new`] of the batch's `F`, `f` being tet `k`'s).
    pub fn stress_and_energy_at(self, l: Lame, f: &Matrix3<f64>, polars: &Polars, k: usize) -> (Matrix3<f64>, f64) {
        self.stress_and_energy_with(l, f, || polars.0[k].unwrap_or_else(|| polar(f)))
    }

    fn stress_and_energy_with(self, l: Lame, f: &Matrix3<f64>, polar: impl FnOnce() -> Polar) -> (Matrix3<f64>, f64) {
        let j = f.determinant();
        let cof = cofactor(f);
        match self {
            Energy::FixedCorotated => {
                let r = polar().r;
                (
                    (f - r) * (2.0 * l.mu) + cof * (l.lambda * (j - 1.0)),
                    l.mu * (f - r).norm_squared() + 0.5 * l.lambda * (j - 1.0) * (j - 1.0),
                )
            }
            Energy::StableNeoHookean => (
                {
                    let (lp, alpha) = Self::snh(l);
                    f * l.mu + cof * (lp * (j - alpha))
                },
                self.energy(l, f),
            ),
        }
    }

    /// `dP/dF` as a 9 x 9 matrix on `vec F` (symmetric: the Hessian of `Psi`).
    pub fn stress_derivative(self, l: Lame, f: &Matrix3<f64>) -> Mat9 {
        self.stress_derivative_with(l, f, || polar(f))
    }

    /// [`Energy::stress_derivative`] of tet `k` of a batch whose decompositions are `polars`
    /// ([`Polars::new`] of the batch's `F`, `f` being tet `k`'s).
    pub fn stress_derivative_at(self, l: Lame, f: &Matrix3<f64>, polars: &Polars, k: usize) -> Mat9 {
        self.stress_derivative_with(l, f, || polars.0[k].unwrap_or_else(|| polar(f)))
    }

    fn stress_derivative_with(self, l: Lame, f: &Matrix3<f64>, polar: impl FnOnce() -> Polar) -> Mat9 {
        let j = f.determinant();
        let cof = SMatrix::<f64, 9, 1>::from_column_slice(cofactor(f).as_slice());
        // dP/dF = a I + b cof cof^T + c dcof/dF (- 2 mu dR/dF for the corotated energy).
        let (a, b, c) = match self {
            Energy::FixedCorotated => (2.0 * l.mu, l.lambda, l.lambda * (j - 1.0)),
            Energy::StableNeoHookean => {
                let (lp, alpha) = Self::snh(l);
                (l.mu, lp, lp * (j - alpha))
            }
        };
        let mut out = Mat9::identity() * a + cof * cof.transpose() * b + cofactor_hessian(f) * c;
        if self == Energy::FixedCorotated {
            // dR/dF = sum over the pairs of vec(T_ab) vec(T_ab)^T / (s_a + s_b).
            for (t, inv) in polar().derivative_terms() {
                let t = SMatrix::<f64, 9, 1>::from_column_slice(t.as_slice());
                out -= t * t.transpose() * (a * inv);
            }
        }
        out
    }

    /// `(dP/dmu, dP/dlambda)` at `F`.
    pub fn stress_parameter_derivatives(self, _l: Lame, f: &Matrix3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
        let j = f.determinant();
        let cof = cofactor(f);
        match self {
            Energy::FixedCorotated => ((f - polar(f).r) * 2.0, cof * (j - 1.0)),
            // With lambda' = lambda + mu and alpha = 1 + mu/lambda' (Eq. H3):
            // dP/dmu = F + (J - 2) cof F, dP/dlambda = (J - 1) cof F.
            Energy::StableNeoHookean => (f + cof * (j - 2.0), cof * (j - 1.0)),
        }
    }
}

/// The positive semidefinite part of a symmetric 9 x 9 matrix (negative eigenvalues clamped to
/// zero); returns it and the number of clamped modes.
pub fn positive_part(m: &Mat9) -> (Mat9, usize) {
    let eig = SymmetricEigen::new(*m);
    let clamped = eig.eigenvalues.iter().filter(|&&x| x < 0.0).count();
    if clamped == 0 {
        return (*m, 0);
    }
    let vals = eig.eigenvalues.map(|x| x.max(0.0));
    (
        eig.eigenvectors * SMatrix::<f64, 9, 9>::from_diagonal(&vals) * eig.eigenvectors.transpose(),
        clamped,
    )
}

/// `M vec(d)` back as a 3 x 3 matrix.
pub fn apply(m: &Mat9, d: &Matrix3<f64>) -> Matrix3<f64> {
    let v = SMatrix::<f64, 9, 1>::from_column_slice(d.as_slice());
    let r = m * v;
    Matrix3::from_column_slice(r.as_slice())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mat(k: usize) -> Matrix3<f64> {
        Matrix3::from_fn(|i, j| (((k * 9 + i * 3 + j) as f64) * 1.618_034).sin())
    }

    const MODELS: [Energy; 2] = [Energy::FixedCorotated, Energy::StableNeoHookean];

    /// The stress is the energy's derivative, and `dP/dF` the stress's (central differences).
    #[test]
    fn stress_and_its_derivative_match_differences() {
        let l = Lame { mu: 3.0, lambda: 7.0 };
        for model in MODELS {
            for k in 0..12 {
                let f = Matrix3::identity() + mat(k) * 0.3;
                let d = mat(k + 100);
                let e = 1e-6;
                let fd = (model.energy(l, &(f + d * e)) - model.energy(l, &(f - d * e))) / (2.0 * e);
                let an = model.stress(l, &f).dot(&d);
                assert!((fd - an).abs() <= 1e-6 * (1.0 + an.abs()), "{model:?} {fd} {an}");
                let fd2 = (model.stress(l, &(f + d * e)) - model.stress(l, &(f - d * e))) / (2.0 * e);
                let an2 = apply(&model.stress_derivative(l, &f), &d);
                assert!((fd2 - an2).norm() <= 1e-5 * (1.0 + an2.norm()), "{model:?} {fd2} {an2}");
                let (dmu, dla) = model.stress_parameter_derivatives(l, &f);
                let h = 1e-6;
                let fm = (model.stress(Lame { mu: l.mu + h, ..l }, &f) - model.stress(Lame { mu: l.mu - h, ..l }, &f))
                    / (2.0 * h);
                let fl = (model.stress(
                    Lame {
                        lambda: l.lambda + h,
                        ..l
                    },
                    &f,
                ) - model.stress(
                    Lame {
                        lambda: l.lambda - h,
                        ..l
                    },
                    &f,
                )) / (2.0 * h);
                assert!((fm - dmu).norm() <= 1e-6 * (1.0 + dmu.norm()), "{model:?} dmu");
                assert!((fl - dla).norm() <= 1e-6 * (1.0 + dla.norm()), "{model:?} dlambda");
            }
        }
    }

    /// `stress_and_energy` is `stress` and `energy` from one polar decomposition, to the bit;
    /// the cofactor's 9 x 9 derivative is symmetric and holds its directional derivatives; the
    /// corotated `dP/dF` from the rank-one terms of `dR/dF` equals the directional derivative
    /// `U W V^T` (`W_ab = (M_ab - M_ba)/(s_a + s_b)`, `M = U^T d V`) it replaces.
    #[test]
    fn shared_polar_and_rank_one_rotation_derivative() {
        let l = Lame { mu: 3.0, lambda: 7.0 };
        for k in 0..12 {
            let f = Matrix3::identity() + mat(k) * 0.4;
            for model in MODELS {
                let (p, psi) = model.stress_and_energy(l, &f);
                assert_eq!(p, model.stress(l, &f), "{model:?}");
                assert_eq!(psi.to_bits(), model.energy(l, &f).to_bits(), "{model:?}");
            }
            let h = cofactor_hessian(&f);
            assert_eq!(h, h.transpose());
            for dk in 0..9 {
                let mut d = Matrix3::zeros();
                d[(dk % 3, dk / 3)] = 1.0;
                let column = Matrix3::from_column_slice(h.column(dk).as_slice());
                assert!((column - cofactor_derivative(&f, &d)).norm() <= 1e-14 * (1.0 + f.norm_squared()));
            }
            let pol = polar(&f);
            let terms = pol.derivative_terms();
            for dk in 0..4 {
                let d = mat(k + 50 + dk);
                let m = pol.u.transpose() * d * pol.v;
                let mut w = Matrix3::zeros();
                for (a, b) in [(0, 1), (0, 2), (1, 2)] {
                    let x = (m[(a, b)] - m[(b, a)]) / (pol.s[a] + pol.s[b]);
                    w[(a, b)] = x;
                    w[(b, a)] = -x;
                }
                let direct = pol.u * w * pol.v.transpose();
                let rank_one = terms
                    .iter()
                    .fold(Matrix3::zeros(), |acc, (t, inv)| acc + t * (t.dot(&d) * inv));
                assert!(
                    (direct - rank_one).norm() <= 1e-12 * (1.0 + direct.norm()),
                    "{direct} {rank_one}"
                );
            }
        }
    }

    /// Both energies are stress-free at rest and linear elasticity with `(mu, lambda)` at small
    /// strain: `dP/dF(I) d = mu (d + d^T) + lambda tr(d) I` (Eq. H4), so a uniaxial stress gives
    /// Young's modulus `E` and Poisson ratio `nu` exactly.
    #[test]
    fn small_strain_response_is_exactly_e_and_nu() {
        let (e, nu) = (2.5e5, 0.45);
        let l = Lame::from_young(e, nu);
        for model in MODELS {
            assert!(model.stress(l, &Matrix3::identity()).norm() <= 1e-9 * e, "{model:?}");
            assert!(model.energy(l, &Matrix3::identity()).abs() <= 1e-9 * e, "{model:?}");
            let c = model.stress_derivative(l, &Matrix3::identity());
            for k in 0..6 {
                let d = mat(k);
                let lin = (d + d.transpose()) * l.mu + Matrix3::identity() * (l.lambda * d.trace());
                assert!((apply(&c, &d) - lin).norm() <= 1e-9 * e, "{model:?}");
            }
            // Uniaxial stress sigma along x: strains sigma/E along x, -nu sigma/E across.
            let s = 1.0;
            let eps = Matrix3::from_diagonal(&Vector3::new(s / e, -nu * s / e, -nu * s / e));
            let p = apply(&c, &eps);
            assert!((p[(0, 0)] - s).abs() <= 1e-9, "{model:?} {}", p[(0, 0)]);
            assert!(p[(1, 1)].abs() <= 1e-9 && p[(2, 2)].abs() <= 1e-9, "{model:?}");
        }
    }

    /// The stable Neo-Hookean energy is finite and smooth through inversion.
    #[test]
    fn neo_hookean_is_defined_for_inverted_elements() {
        let l = Lame { mu: 1.0, lambda: 10.0 };
        let f = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -0.5));
        let m = Energy::StableNeoHookean;
        assert!(m.energy(l, &f).is_finite() && m.stress(l, &f).iter().all(|x| x.is_finite()));
        let (p, n) = positive_part(&m.stress_derivative(l, &f));
        assert!(n > 0 && SymmetricEigen::new(p).eigenvalues.min() >= -1e-9);
    }
}
