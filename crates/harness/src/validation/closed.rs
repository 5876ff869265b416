//! The closed forms the validation cases compare with, computed here from their published
//! formulas and independently of the engine: the integrators' characteristic roots on an
//! undamped oscillator, the elastica under self-weight (shooting), uniaxial stress-stretch
//! curves of the three material models, Timoshenko's cantilever, Hertz's contact radius and the
//! capstan limit of a belt with and without its own weight.

use nalgebra::Complex;
use serde::Serialize;

/// A time integrator applied to the undamped oscillator `x'' = -omega^2 x`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Scheme {
    /// Implicit (backward) Euler, `(q_{n+1} - q_n) = h v_{n+1}` (docs/method.md Eq. 1).
    ImplicitEuler,
    /// Two-step backward differentiation (docs/method.md Eqs. T1-T3).
    Bdf2,
}

impl Scheme {
    /// Its name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Scheme::ImplicitEuler => "implicit_euler",
            Scheme::Bdf2 => "bdf2",
        }
    }

    /// `rho(z) / sigma(z)` of the scheme: a root `z` of the oscillator's characteristic
    /// equation satisfies `rho(z) / sigma(z) = i omega h`. Implicit Euler: `(z - 1) / z`; BDF2:
    /// `(z^2 - 4/3 z + 1/3) / (2/3 z^2)`.
    pub fn rho_over_sigma(self, z: Complex<f64>) -> Complex<f64> {
        match self {
            Scheme::ImplicitEuler => (z - 1.0) / z,
            Scheme::Bdf2 => (z * z - z * (4.0 / 3.0) + 1.0 / 3.0) / (z * z * (2.0 / 3.0)),
        }
    }

    /// The principal root (the one that tends to 1 as `omega h -> 0`) of the characteristic
    /// equation at `omega h = wh`, for the mode `exp(+i omega t)`.
    ///
    /// Implicit Euler: `z (1 - i wh) = 1`. BDF2: `(1 - 2/3 i wh) z^2 - 4/3 z + 1/3 = 0`, the root
    /// of larger modulus (the other, near `1/3`, is parasitic and decays).
    pub fn root(self, wh: f64) -> Complex<f64> {
        let i = Complex::new(0.0, 1.0);
        match self {
            Scheme::ImplicitEuler => Complex::new(1.0, 0.0) / (Complex::new(1.0, 0.0) - i * wh),
            Scheme::Bdf2 => {
                let a = Complex::new(1.0, 0.0) - i * (2.0 * wh / 3.0);
                let b = Complex::new(-4.0 / 3.0, 0.0);
                let c = Complex::new(1.0 / 3.0, 0.0);
                let d = (b * b - a * c * 4.0).sqrt();
                let r1 = (-b + d) / (a * 2.0);
                let r2 = (-b - d) / (a * 2.0);
                if r1.norm() >= r2.norm() {
                    r1
                } else {
                    r2
                }
            }
        }
    }

    /// The exact per-period factors of the scheme on an undamped oscillator at `omega h = wh`.
    pub fn factors(self, wh: f64) -> Factors {
        let z = self.root(wh);
        let steps_per_period = 2.0 * std::f64::consts::PI / wh;
        Factors {
            omega_h: wh,
            amplitude_per_period: z.norm().powf(steps_per_period),
            frequency_ratio: z.arg() / wh,
        }
    }
}

/// What an integrator does to an undamped oscillator of angular frequency `omega` at step `h`.
#[derive(Debug, Clone, Copy, Serialize, schemars::JsonSchema)]
pub struct Factors {
    /// `omega h` (1).
    pub omega_h: f64,
    /// Amplitude factor per true period `2 pi / omega`: `|z|^(2 pi / (omega h))` (1).
    pub amplitude_per_period: f64,
    /// Numerical over true frequency: `arg(z) / (omega h)` (1).
    pub frequency_ratio: f64,
}

/// The reference values of the per-period factors (the project's reference notes), as
/// `(omega h, IE amplitude, IE frequency ratio, BDF2 amplitude, BDF2 frequency ratio)`. The
/// implicit-Euler frequency ratio at `omega h = 1` is `atan(1) = pi / 4` exactly, quoted to five
/// digits as the table quotes it.
#[allow(clippy::approx_constant)]
pub const FACTOR_TABLE: [(f64, f64, f64, f64, f64); 5] = [
    (0.05, 0.8548, 0.99917, 0.9998, 0.99917),
    (0.1, 0.7315, 0.99669, 0.9985, 0.99671),
    (0.2, 0.5401, 0.98698, 0.9886, 0.98733),
    (0.5, 0.2461, 0.92730, 0.8859, 0.93515),
    (1.0, 0.1133, 0.78540, 0.6482, 0.82380),
];

/// Prony's method of order `p` with the least-squares prediction solved by a truncated SVD
/// (Kumaresan and Tufts 1982): fit `x_n = sum_k a_k x_{n-k}` keeping the singular values above
/// `1e-6` of the largest, and return the roots of `z^p = sum_k a_k z^(p-k)`. A signal of `m` damped
/// modes `Re(c z^n)` gives their roots `z` and conjugates; the `p - 2m` extraneous roots of the
/// minimum-norm prediction lie inside the unit circle.
pub fn prony(x: &[f64], p: usize) -> Vec<Complex<f64>> {
    use nalgebra::{DMatrix, DVector};
    if x.len() < 2 * p + 1 {
        return Vec::new();
    }
    let rows = x.len() - p;
    let a = DMatrix::from_fn(rows, p, |r, k| x[r + p - 1 - k]);
    let b = DVector::from_fn(rows, |r, _| x[r + p]);
    let svd = a.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u.as_ref(), svd.v_t.as_ref()) else {
        return Vec::new();
    };
    let smax = svd.singular_values.max();
    let mut coef = DVector::zeros(p);
    for (k, &sk) in svd.singular_values.iter().enumerate() {
        if sk > 1e-6 * smax {
            let w = u.column(k).dot(&b) / sk;
            coef += vt.row(k).transpose() * w;
        }
    }
    // The companion matrix of z^p - a_1 z^(p-1) - ... - a_p.
    let mut c = DMatrix::zeros(p, p);
    for k in 0..p {
        c[(0, k)] = coef[k];
    }
    for k in 1..p {
        c[(k, k - 1)] = 1.0;
    }
    c.complex_eigenvalues().iter().copied().collect()
}

/// The root of the strongest oscillating mode of a signal: Prony's method of order 8 ([`prony`];
/// other modes left in the signal do not bias it), then the amplitudes `c_k` of
/// `x_n = sum_k c_k z_k^n` by least squares, and among the roots with an angle in `(0, pi)` the
/// one whose mode carries the most of the signal, `|c_k|^2 sum_n |z_k|^(2n)`. `None` when no
/// root oscillates.
pub fn fundamental_root(x: &[f64]) -> Option<Complex<f64>> {
    use nalgebra::{DMatrix, DVector};
    let roots = prony(x, 8);
    if roots.is_empty() {
        return None;
    }
    let n = x.len();
    let v = DMatrix::from_fn(n, roots.len(), |i, k| roots[k].powu(i as u32));
    let rhs = DVector::from_fn(n, |i, _| Complex::new(x[i], 0.0));
    let c = v.clone().svd(true, true).solve(&rhs, 1e-12).ok()?;
    let energy = |k: usize| -> f64 {
        let r2 = roots[k].norm_sqr();
        c[k].norm_sqr() * (0..n).map(|i| r2.powi(i as i32)).sum::<f64>()
    };
    (0..roots.len())
        .filter(|&k| roots[k].im > 1e-12 * roots[k].norm())
        .max_by(|&a, &b| energy(a).total_cmp(&energy(b)))
        .map(|k| roots[k])
}

/// One solution of the elastica under self-weight.
#[derive(Debug, Clone, Copy, Serialize, schemars::JsonSchema)]
pub struct Elastica {
    /// Load parameter `alpha = q L^3 / (E I)` (1).
    pub alpha: f64,
    /// Tip deflection over length `v / L` (1).
    pub tip_deflection: f64,
    /// Horizontal shortening of the tip `(L - x) / L` (1).
    pub tip_shortening: f64,
    /// Tip rotation (rad).
    pub tip_rotation: f64,
}

/// The inextensible elastica of a clamped cantilever under its own weight (load per unit
/// length fixed and vertical): with `s` the arc length over `L` and `theta` the slope,
/// `theta'' = -alpha (1 - s) cos(theta)`, `theta(0) = 0`, `theta'(1) = 0` (the moment of the load
/// beyond `s` is `q int_s^L (x(t) - x(s)) dt`; its derivative is `-q (L - s) cos(theta)`).
/// Solved by shooting on `theta'(0)` with classical Runge-Kutta (2000 steps) and bisection.
pub fn elastica(alpha: f64) -> Elastica {
    let n = 2000;
    // State: theta, theta', x, y.
    let shoot = |k0: f64| -> [f64; 4] {
        let f = |s: f64, y: &[f64; 4]| -> [f64; 4] { [y[1], -alpha * (1.0 - s) * y[0].cos(), y[0].cos(), y[0].sin()] };
        let h = 1.0 / n as f64;
        let mut y = [0.0, k0, 0.0, 0.0];
        for k in 0..n {
            let s = k as f64 * h;
            let add = |a: &[f64; 4], b: &[f64; 4], c: f64| -> [f64; 4] {
                [a[0] + c * b[0], a[1] + c * b[1], a[2] + c * b[2], a[3] + c * b[3]]
            };
            let k1 = f(s, &y);
            let k2 = f(s + h / 2.0, &add(&y, &k1, h / 2.0));
            let k3 = f(s + h / 2.0, &add(&y, &k2, h / 2.0));
            let k4 = f(s + h, &add(&y, &k3, h));
            for i in 0..4 {
                y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
        y
    };
    // theta'(1) as a function of theta'(0) is increasing; the root lies in [0, alpha / 2]
    // (the small-deflection value, which the shortening only lowers).
    let (mut lo, mut hi) = (0.0, alpha / 2.0 + 1e-12);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if shoot(mid)[1] > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let y = shoot(0.5 * (lo + hi));
    Elastica {
        alpha,
        tip_deflection: y[3],
        tip_shortening: 1.0 - y[2],
        tip_rotation: y[0],
    }
}

/// The reference values of the elastica (the project's reference notes):
/// `(alpha, v/L, (L-x)/L, tip rotation)`.
pub const ELASTICA_TABLE: [(f64, f64, f64, f64); 5] = [
    (1.0, 0.12347, 0.00875, 0.1651),
    (2.0, 0.23851, 0.03311, 0.3216),
    (4.0, 0.42516, 0.10989, 0.5886),
    (8.0, 0.64063, 0.27558, 0.9401),
    (16.0, 0.79702, 0.49001, 1.2603),
];

/// An isotropic energy density given by its principal stretches, for the uniaxial closed form.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Density {
    /// The projective model (docs/method.md section 2): corotated weight `E/(1+nu)` and volume
    /// weight `nu E/(1+nu)` per unit volume, `Psi = w_rot/2 |s - 1|^2 + w_vol/2 |s - d(s)|^2`
    /// with `d(s)` the nearest triple with product one.
    Projective {
        /// Young's modulus (Pa).
        e: f64,
        /// Poisson ratio (1).
        nu: f64,
    },
    /// Fixed corotated (Stomakhin et al. 2012): `Psi = mu |s - 1|^2 + lambda/2 (J - 1)^2`.
    Corotated {
        /// Shear modulus (Pa).
        mu: f64,
        /// Lame's first parameter (Pa).
        lambda: f64,
    },
    /// Stable Neo-Hookean (Smith et al. 2018) without its logarithmic term, re-parametrised:
    /// `Psi = mu/2 (|s|^2 - 3) + lambda'/2 (J - a)^2`, `lambda' = lambda + mu`,
    /// `a = 1 + mu / lambda'`.
    NeoHookean {
        /// Shear modulus (Pa).
        mu: f64,
        /// Lame's first parameter (Pa).
        lambda: f64,
    },
}

/// The Lame parameters `(mu, lambda)` of `(E, nu)`.
pub fn lame(e: f64, nu: f64) -> (f64, f64) {
    (e / (2.0 * (1.0 + nu)), e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)))
}

/// The root of the increasing function `f` in `[lo, hi]` (`f(lo) <= 0 <= f(hi)`), by the
/// Illinois variant of regula falsi (superlinear, never leaves the bracket), to round-off.
pub fn root(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    let (mut flo, mut fhi) = (f(lo), f(hi));
    if flo >= 0.0 {
        return lo;
    }
    if fhi <= 0.0 {
        return hi;
    }
    let mut side = 0;
    for _ in 0..400 {
        if hi - lo <= 4.0 * f64::EPSILON * hi.abs().max(lo.abs()) {
            break;
        }
        let mut x = (lo * fhi - hi * flo) / (fhi - flo);
        if !(x > lo && x < hi) {
            x = 0.5 * (lo + hi);
        }
        let fx = f(x);
        if fx == 0.0 {
            return x;
        }
        if fx < 0.0 {
            lo = x;
            flo = fx;
            if side == -1 {
                fhi /= 2.0;
            }
            side = -1;
        } else {
            hi = x;
            fhi = fx;
            if side == 1 {
                flo /= 2.0;
            }
            side = 1;
        }
    }
    0.5 * (lo + hi)
}

/// The nearest triple to `s` with product one (Euclidean): `d_i = (s_i + sqrt(s_i^2 + 4 g)) / 2`
/// with the multiplier `g` such that `prod d = 1` (`prod d` increases with `g`).
fn nearest_unit_product(s: [f64; 3]) -> [f64; 3] {
    let d = |g: f64| s.map(|si| 0.5 * (si + (si * si + 4.0 * g).max(0.0).sqrt()));
    let log_prod = |g: f64| d(g).iter().map(|x| x.ln()).sum::<f64>();
    let gmin = -s.iter().map(|si| si * si / 4.0).fold(f64::INFINITY, f64::min);
    let mut hi = 1.0;
    while log_prod(hi) < 0.0 {
        hi *= 2.0;
    }
    d(root(log_prod, gmin, hi))
}

impl Density {
    /// `dPsi/ds_i`, the principal first Piola-Kirchhoff stresses (Pa).
    pub fn principal_stress(self, s: [f64; 3]) -> [f64; 3] {
        let j = s[0] * s[1] * s[2];
        match self {
            Density::Projective { e, nu } => {
                let (wr, wv) = (e / (1.0 + nu), nu * e / (1.0 + nu));
                let d = if wv > 0.0 { nearest_unit_product(s) } else { s };
                // The distance to a set is differentiated at its nearest point.
                [0, 1, 2].map(|i| wr * (s[i] - 1.0) + wv * (s[i] - d[i]))
            }
            Density::Corotated { mu, lambda } => {
                [0, 1, 2].map(|i| 2.0 * mu * (s[i] - 1.0) + lambda * (j - 1.0) * j / s[i])
            }
            Density::NeoHookean { mu, lambda } => {
                let lp = lambda + mu;
                let a = 1.0 + mu / lp;
                [0, 1, 2].map(|i| mu * s[i] + lp * (j - a) * j / s[i])
            }
        }
    }

    /// Uniaxial stress: the axial stretch and lateral stretch at nominal axial stress `p` (Pa)
    /// with stress-free lateral faces, `(s_a, s_t)`; tension (`p >= 0`) only.
    pub fn uniaxial(self, p: f64) -> (f64, f64) {
        // The lateral stress increases with the lateral stretch, the axial one (at zero lateral
        // stress) with the axial stretch.
        let lateral = |sa: f64| root(|st| self.principal_stress([sa, st, st])[1], 0.05, 3.0);
        let axial = |sa: f64| self.principal_stress([sa, lateral(sa), lateral(sa)])[0] - p;
        let mut hi = 2.0;
        while axial(hi) < 0.0 {
            hi *= 1.5;
        }
        // Tension only (p >= 0): the axial stretch is at least 1.
        let sa = root(axial, 0.999, hi);
        (sa, lateral(sa))
    }

    /// Tip displacement of a bar of length `l` hanging from a clamp under its own weight in the
    /// uniaxial-stress (slender bar) approximation: at distance `x` from the clamp the nominal
    /// stress is `rho g (l - x)`, and the tip moves by `int_0^l (s_a(x) - 1) dx` (Gauss-Legendre,
    /// 8 points on each of 16 panels).
    pub fn hanging_tip(self, rho_g: f64, l: f64) -> f64 {
        const X: [f64; 4] = [
            0.183_434_642_495_649_8,
            0.525_532_409_916_329,
            0.796_666_477_413_626_7,
            0.960_289_856_497_536_3,
        ];
        const W: [f64; 4] = [
            0.362_683_783_378_362,
            0.313_706_645_877_887_3,
            0.222_381_034_453_374_5,
            0.101_228_536_290_376_3,
        ];
        let panels = 16;
        let dx = l / panels as f64;
        let mut sum = 0.0;
        for k in 0..panels {
            let mid = (k as f64 + 0.5) * dx;
            for (x, w) in X.iter().zip(W) {
                for sign in [-1.0, 1.0] {
                    let at = mid + sign * x * dx / 2.0;
                    sum += w * dx / 2.0 * (self.uniaxial(rho_g * (l - at)).0 - 1.0);
                }
            }
        }
        sum
    }
}

/// Euler-Bernoulli tip deflection of a clamped cantilever under a uniform load `q` (N/m),
/// `q L^4 / (8 E I)`.
pub fn euler_bernoulli(q: f64, l: f64, e: f64, i: f64) -> f64 {
    q * l.powi(4) / (8.0 * e * i)
}

/// Timoshenko's shear addition to the cantilever's tip deflection, `q L^2 / (2 kappa G A)`.
pub fn timoshenko_shear(q: f64, l: f64, g: f64, a: f64, kappa: f64) -> f64 {
    q * l * l / (2.0 * kappa * g * a)
}

/// Hertz's contact radius of a sphere of radius `r` pressed with force `f` onto a rigid plane,
/// `a = (3 F R / (4 E*))^(1/3)`, `E* = E / (1 - nu^2)`.
pub fn hertz_radius(f: f64, r: f64, e: f64, nu: f64) -> f64 {
    let e_star = e / (1.0 - nu * nu);
    (3.0 * f * r / (4.0 * e_star)).cbrt()
}

/// The largest tension ratio a half wrap (angle `pi`) holds, Euler-Eytelwein: `e^(mu pi)`.
pub fn capstan_ratio(mu: f64) -> f64 {
    (mu * std::f64::consts::PI).exp()
}

/// The largest tension `T2` a belt of weight `w` per unit length (N/m) holds over the top half of
/// a horizontal cylinder of radius `r` against `T1` on the other side: the equilibrium of an
/// element, `T' = mu N R + w R cos(theta)`, `N = T/R + w sin(theta)` (per unit length), with
/// `theta` from the light side, integrates to
/// `T2 = T1 e^(mu pi) + 2 mu w R (1 + e^(mu pi)) / (1 + mu^2)`.
pub fn heavy_capstan_limit(t1: f64, mu: f64, w: f64, r: f64) -> f64 {
    let e = capstan_ratio(mu);
    t1 * e + 2.0 * mu * w * r * (1.0 + e) / (1.0 + mu * mu)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integrator_factors_from_the_roots_match_the_reference_table() {
        for (wh, ie_a, ie_f, bdf_a, bdf_f) in FACTOR_TABLE {
            let ie = Scheme::ImplicitEuler.factors(wh);
            let bdf = Scheme::Bdf2.factors(wh);
            assert!((ie.amplitude_per_period - ie_a).abs() < 6e-5, "{wh}: {ie:?}");
            assert!((ie.frequency_ratio - ie_f).abs() < 6e-6, "{wh}: {ie:?}");
            assert!((bdf.amplitude_per_period - bdf_a).abs() < 6e-5, "{wh}: {bdf:?}");
            assert!((bdf.frequency_ratio - bdf_f).abs() < 6e-6, "{wh}: {bdf:?}");
        }
    }

    #[test]
    fn roots_satisfy_their_characteristic_equations() {
        for scheme in [Scheme::ImplicitEuler, Scheme::Bdf2] {
            for wh in [0.01, 0.3, 2.0] {
                let r = scheme.rho_over_sigma(scheme.root(wh));
                assert!(r.re.abs() < 1e-12 && (r.im - wh).abs() < 1e-12, "{scheme:?} {wh}: {r}");
            }
        }
    }

    #[test]
    fn prony_recovers_the_fundamental_beside_a_second_mode() {
        let z1 = Complex::from_polar(0.98, 0.2);
        let z2 = Complex::from_polar(0.7, 1.1);
        let x: Vec<f64> = (0..60)
            .map(|n| (Complex::new(0.3, -1.2) * z1.powu(n) + Complex::new(0.2, 0.1) * z2.powu(n)).re)
            .collect();
        let fit = fundamental_root(&x).unwrap();
        assert!((fundamental_root(&x[..30]).unwrap() - z1).norm() < 1e-9);
        let single: Vec<f64> = (0..40).map(|n| (Complex::new(0.3, -1.2) * z1.powu(n)).re).collect();
        assert!((fundamental_root(&single).unwrap() - z1).norm() < 1e-9);
        assert!((fit - z1).norm() < 1e-9, "{fit}");
    }

    #[test]
    fn elastica_matches_the_reference_table_and_small_deflection() {
        for (alpha, v, u, th) in ELASTICA_TABLE {
            let e = elastica(alpha);
            assert!((e.tip_deflection - v).abs() < 6e-6, "{e:?}");
            assert!((e.tip_shortening - u).abs() < 6e-6, "{e:?}");
            assert!((e.tip_rotation - th).abs() < 6e-5, "{e:?}");
        }
        let e = elastica(1e-3);
        assert!((e.tip_deflection / (1e-3 / 8.0) - 1.0).abs() < 1e-3);
        assert!((e.tip_rotation / (1e-3 / 6.0) - 1.0).abs() < 1e-3);
    }

    #[test]
    fn uniaxial_curves_reduce_to_youngs_modulus_and_poisson_ratio_at_small_strain() {
        let (e, nu) = (1e6, 0.3);
        let (mu, lambda) = lame(e, nu);
        let p = 1.0; // 1e-6 strain
        for (d, e_ref, nu_ref) in [
            (Density::Corotated { mu, lambda }, e, nu),
            (Density::NeoHookean { mu, lambda }, e, nu),
            (
                Density::Projective { e, nu },
                e / (1.0 + 2.0 * nu / 3.0),
                nu / (3.0 + 2.0 * nu),
            ),
        ] {
            let (sa, st) = d.uniaxial(p);
            let e_meas = p / (sa - 1.0);
            let nu_meas = -(st - 1.0) / (sa - 1.0);
            assert!((e_meas / e_ref - 1.0).abs() < 1e-5, "{d:?}: E {e_meas}");
            assert!((nu_meas - nu_ref).abs() < 1e-5, "{d:?}: nu {nu_meas}");
        }
        // Fixed corotated at nu = 0 is linear in the stretch at any strain.
        let d = Density::Corotated {
            mu: e / 2.0,
            lambda: 0.0,
        };
        assert!((d.uniaxial(0.4 * e).0 - 1.4).abs() < 1e-10);
        assert!((d.hanging_tip(0.5 * e, 1.0) - 0.25).abs() < 1e-10);
    }

    #[test]
    fn heavy_capstan_integrates_its_equation() {
        let (t1, mu, w, r) = (2.0, 0.3, 1.5, 0.1);
        let n = 100_000;
        let h = std::f64::consts::PI / n as f64;
        let mut t = t1;
        for k in 0..n {
            let th = (k as f64 + 0.5) * h;
            // Midpoint rule on T' = mu T + w R (cos + mu sin).
            let f = |t: f64| mu * t + w * r * (th.cos() + mu * th.sin());
            t += h * f(t + 0.5 * h * f(t));
        }
        assert!((t / heavy_capstan_limit(t1, mu, w, r) - 1.0).abs() < 1e-8);
        assert!((heavy_capstan_limit(t1, mu, 0.0, r) / t1 - capstan_ratio(mu)).abs() < 1e-14);
    }
}
