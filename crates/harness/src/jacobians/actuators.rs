//! The actuator checks (docs/method.md section 5, Eqs. 39-40): the pneumatic cell's and the
//! muscle fibre's Jacobians against dual numbers and central differences, with tolerances derived
//! per configuration (see the parent module's doc), and the residuals of the actuator constraints.

use nalgebra::{Matrix3, Rotation3, Vector3};
use num_dual::Dual64;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::{ActuatorConstraintCheck, JacobianCheck};
use crate::fd::{compare, sweep};
use diffsoft::kernel::actuator::{
    muscle_energy, muscle_energy_gradient, muscle_energy_gradient_dual, muscle_jacobian, muscle_jacobian_dual,
    muscle_target, nearest_product_dual, nearest_product_jacobian, pneumatic_energy, pneumatic_energy_gradient,
    pneumatic_energy_gradient_dual, pneumatic_jacobian, pneumatic_jacobian_dual, pneumatic_target_of, ActuatorError,
};
use diffsoft::kernel::svd::svd3;
use diffsoft::kernel::volume;
use diffsoft::testing::unit;

const EPS: f64 = f64::EPSILON;

/// Factor between a predicted error level (round-off of the reference, or the best error of
/// central differences) and the tolerance of an actuator check.
pub const ACTUATOR_SAFETY: f64 = 100.0;

/// The smallest error of central differences of values with absolute round-off `r0` and third
/// derivative `c3` with steps at most `h_max`: `r0/h + c3 h^2` at `h = min((r0/c3)^(1/3), h_max)`.
pub fn fd_floor(r0: f64, c3: f64, h_max: f64) -> f64 {
    if c3 > 0.0 {
        let h = (r0 / c3).cbrt().min(h_max);
        r0 / h + c3 * h * h
    } else {
        r0 / h_max
    }
}

/// Sweep scale for [`fd_floor`]'s model: `10^4` times the optimal step (so the ten steps span
/// three decades of truncation error and six of round-off), at most `limit` (the distance over
/// which the map is smooth, or the domain).
pub fn sweep_scale(r0: f64, c3: f64, limit: f64) -> f64 {
    if c3 > 0.0 {
        (1e4 * (r0 / c3).cbrt()).min(limit)
    } else {
        limit
    }
}

/// Scales of the pneumatic projection at singular values `s` (signed) with nearest product `x`:
/// `(M, L, gap)`: `M = max(|s|, x)`; `L` the distance over which `R` is smooth, the smallest of
/// `s_i + s_j` (the antisymmetric coefficient's pole), `c_i + c_j` (`c = 2x - s`, the symmetric
/// coefficient's pole) when both are on the `+` branch or `|s_i - s_j|` otherwise, and `M`;
/// `gap = min ||s_i| - |s_j||` (the dual reference's Jacobi SVD loses `eps M / gap`).
pub fn pneumatic_scales(s: &Vector3<f64>, x: &Vector3<f64>) -> (f64, f64, f64) {
    let m = s.amax().max(x.amax());
    let mut l = m;
    let mut gap = f64::INFINITY;
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        let (ci, cj) = (2.0 * x[i] - s[i], 2.0 * x[j] - s[j]);
        l = l.min(s[i] + s[j]);
        l = l.min(if ci >= 0.0 && cj >= 0.0 {
            ci + cj
        } else {
            (s[i] - s[j]).abs()
        });
        gap = gap.min((s[i].abs() - s[j].abs()).abs());
    }
    (m, l, gap)
}

fn mat_vec(m: &Matrix3<f64>) -> Vec<f64> {
    m.iter().copied().collect()
}

fn nan_vec(n: usize) -> Vec<f64> {
    vec![f64::NAN; n]
}

/// Largest `|r|`, at least the smallest positive normal number.
fn amax(v: &[f64]) -> f64 {
    v.iter().fold(f64::MIN_POSITIVE, |m, x| m.max(x.abs()))
}

#[allow(clippy::too_many_arguments)]
fn actuator_check(
    name: &str,
    configuration: &str,
    analytic: &[f64],
    dual: &[f64],
    dual_atol: f64,
    f: &dyn Fn(f64) -> Vec<f64>,
    (r0, c3, limit): (f64, f64, f64),
    condition: f64,
) -> JacobianCheck {
    let scale = sweep_scale(r0, c3, limit);
    let s = sweep(f, analytic, scale, 10);
    // Both the analytic value's own round-off (the dual tolerance) and the differences' error.
    let fd_atol = dual_atol + ACTUATOR_SAFETY * fd_floor(r0, c3, scale / 10.0);
    JacobianCheck {
        name: name.to_string(),
        configuration: configuration.to_string(),
        entries: analytic.len(),
        versus_dual: compare(analytic, dual, dual_atol, 0.0),
        versus_fd: compare(analytic, &s.best_difference, fd_atol, 0.0),
        sweep: s,
        condition: Some(condition),
    }
}

/// The pneumatic checks at one `F` and activation `a` (Eqs. 39-40): `d vec(R)/d vec(F)`,
/// `d vec(R)/da`, the log-log Jacobian of the nearest product `d ln x / d ln(s, a)` and the
/// energy gradient `dPsi/dF`, each against dual numbers and a central-difference step sweep.
/// Tolerances (absolute, normwise: `ACTUATOR_SAFETY` times a predicted error level):
///
/// * versus dual: `eps (M / min(L, gap)) max|J|` (round-off of two SVDs, amplified by the
///   coefficients' poles and, for the Jacobi reference, by close singular values);
/// * versus differences: the above (the analytic value's own round-off) plus [`fd_floor`] with
///   round-off `eps M max(1, max|J|)` (`R` from a backward-stable SVD: `eps |F|` times its
///   condition), third derivative `max|J| / L^2`, steps at most `L / 10`.
///
/// `dR/da` is differenced through the singular values (`U` and `V` do not depend on `a`):
/// `U diag(x(a + h) - x(a)) V^T`, round-off `eps max x`, curvature length `a`. For a tiny `a`
/// next to a large singular value that resolution (`eps max x / a`) can exceed `dR/da` itself;
/// the log-log Jacobian covers `dx/da` there. It is differenced in `ln s_j` and `ln a`
/// (multiplicative steps keep the sign of an inverted `s_3`): elasticities are O(1) and `ln x`
/// has round-off `eps`, so that check is well conditioned at every scale.
pub fn check_pneumatic(
    f: &Matrix3<f64>,
    a: f64,
    k: f64,
    configuration: &str,
) -> Result<Vec<JacobianCheck>, ActuatorError> {
    let j = pneumatic_jacobian(f, a)?;
    let (dual_f, dual_a) = pneumatic_jacobian_dual(f, a)?;
    let svd = svd3(f);
    let (s, x) = (j.sigma, j.x);
    let (m, l, gap) = pneumatic_scales(&s, &x);
    let kappa_dual = m / l.min(gap);
    let mut out = Vec::new();

    // dR/dF: concatenated columns, each differenced along its own entry of F.
    let analytic: Vec<f64> = j.wrt_f.iter().copied().collect();
    let jmax = amax(&analytic);
    let target = |g: &Matrix3<f64>| pneumatic_target_of(g, a).map_or_else(|_| nan_vec(9), |r| mat_vec(&r));
    let fun = |h: f64| -> Vec<f64> {
        (0..9)
            .flat_map(|q| {
                let mut g = *f;
                g[(q % 3, q / 3)] += h;
                target(&g)
            })
            .collect()
    };
    let dual: Vec<f64> = dual_f.iter().copied().collect();
    out.push(actuator_check(
        "pneumatic dR/dF",
        configuration,
        &analytic,
        &dual,
        ACTUATOR_SAFETY * EPS * kappa_dual * jmax,
        &fun,
        // R from a backward-stable SVD: forward round-off eps |F| times its condition max|J|.
        (EPS * m * jmax.max(1.0), jmax / (l * l), l),
        m / l,
    ));

    // dR/da through the singular values.
    let analytic: Vec<f64> = j.wrt_a.iter().copied().collect();
    let ja = amax(&analytic);
    let fun = |h: f64| -> Vec<f64> {
        volume::nearest_product(&s, a + h).map_or_else(|_| nan_vec(9), |xh| mat_vec(&svd.compose(&(xh - x))))
    };
    let dual: Vec<f64> = dual_a.iter().copied().collect();
    out.push(actuator_check(
        "pneumatic dR/da",
        configuration,
        &analytic,
        &dual,
        ACTUATOR_SAFETY * EPS * kappa_dual * ja,
        &fun,
        (EPS * x.amax(), ja / (a * a), a),
        m / l,
    ));

    // Log-log Jacobian of the nearest product: columns ln s_1, ln s_2, ln s_3, ln a.
    let (jx, dxda) = nearest_product_jacobian(&s, &x, a)?;
    let analytic: Vec<f64> = (0..4)
        .flat_map(|col| {
            (0..3).map(move |i| {
                if col < 3 {
                    jx[(i, col)] * s[col] / x[i]
                } else {
                    dxda[i] * a / x[i]
                }
            })
        })
        .collect();
    let mut dual = Vec::with_capacity(12);
    for col in 0..4 {
        let sd = Vector3::from_fn(|i, _| {
            // d/d ln s_col: the derivative part of s_col is s_col itself.
            Dual64::new(s[i], if i == col { s[i] } else { 0.0 })
        });
        let ad = Dual64::new(a, if col == 3 { a } else { 0.0 });
        let xd = nearest_product_dual(&sd, ad)?;
        dual.extend((0..3).map(|i| xd[i].eps / xd[i].re));
    }
    let fun = |h: f64| -> Vec<f64> {
        (0..4)
            .flat_map(|col| {
                let (mut sh, mut ah) = (s, a);
                if col < 3 {
                    sh[col] *= h.exp();
                } else {
                    ah *= h.exp();
                }
                volume::nearest_product(&sh, ah).map_or_else(|_| nan_vec(3), |xh| xh.iter().map(|v| v.ln()).collect())
            })
            .collect()
    };
    let el = amax(&analytic).max(1.0);
    // In log coordinates x(s, a) is smooth on a unit scale, except near a tie between a
    // collapsed component (`-` branch) and another one: relative distance |s_i - s_j| / |s_i|.
    let log_l = [(0, 1), (0, 2), (1, 2)]
        .iter()
        .filter(|&&(i, j)| (2.0 * x[i] - s[i] < 0.0) != (2.0 * x[j] - s[j] < 0.0))
        .map(|&(i, j)| (s[i] - s[j]).abs() / s[i].abs().max(s[j].abs()))
        .fold(1.0f64, f64::min);
    out.push(actuator_check(
        "pneumatic dln x/dln(s, a)",
        configuration,
        &analytic,
        &dual,
        ACTUATOR_SAFETY * EPS * kappa_dual * el,
        &fun,
        (4.0 * EPS, el / (log_l * log_l), log_l),
        m / l,
    ));

    // Energy gradient (Eq. 39).
    let g = pneumatic_energy_gradient(f, a, k)?;
    let analytic = mat_vec(&g);
    let dual = mat_vec(&pneumatic_energy_gradient_dual(f, a, k)?);
    let dist = (f - j.target).amax() + EPS * m;
    let fun = |h: f64| -> Vec<f64> {
        (0..9)
            .map(|q| {
                let mut gg = *f;
                gg[(q % 3, q / 3)] += h;
                pneumatic_energy(&gg, a, k).unwrap_or(f64::NAN)
            })
            .collect()
    };
    out.push(actuator_check(
        "pneumatic dPsi/dF",
        configuration,
        &analytic,
        &dual,
        // F - R (both rounded), and the dual's term (F - R) . dR, zero up to round-off.
        ACTUATOR_SAFETY * EPS * k * (m * jmax.max(1.0) + dist * (1.0 + kappa_dual * jmax)),
        &fun,
        (9.0 * EPS * k * m * jmax.max(1.0) * dist, k * jmax / l, l),
        m / l,
    ));
    Ok(out)
}

/// The muscle checks at one `F`, fibre direction `m` and activation `a`: `dp/d vec(F)`, `dp/da`
/// and the energy gradient, against dual numbers and a central-difference step sweep. With
/// `l = |F m|` and `kappa = |F| |m| / l` (the relative round-off of `F m`), tolerances are
/// `ACTUATOR_SAFETY` times: versus dual `eps kappa max|J|`; versus differences [`fd_floor`]
/// with round-off `eps kappa (1 - a)` and third derivative `(1 - a)/l^3` (steps at most `l/10`);
/// `dp/da` is linear in `a` (round-off only, steps at most `min(a, 1 - a)/10`).
pub fn check_muscle(
    f: &Matrix3<f64>,
    mdir: &Vector3<f64>,
    a: f64,
    k: f64,
    configuration: &str,
) -> Result<Vec<JacobianCheck>, ActuatorError> {
    let j = muscle_jacobian(f, mdir, a)?;
    let (dual_f, dual_a) = muscle_jacobian_dual(f, mdir, a)?;
    let fm = f * mdir;
    let l = fm.norm();
    let fnorm = f.norm() * mdir.norm();
    let kappa = fnorm / l;
    let mut out = Vec::new();
    let target = |g: &Matrix3<f64>, aa: f64| {
        muscle_target(&(g * mdir), aa).map_or_else(|_| nan_vec(3), |p| p.iter().copied().collect())
    };

    let analytic: Vec<f64> = j.wrt_f.iter().copied().collect();
    let jmax = amax(&analytic);
    let fun = |h: f64| -> Vec<f64> {
        (0..9)
            .flat_map(|q| {
                let mut g = *f;
                g[(q % 3, q / 3)] += h;
                target(&g, a)
            })
            .collect()
    };
    let dual: Vec<f64> = dual_f.iter().copied().collect();
    let len = (1.0 - a).max(EPS);
    out.push(actuator_check(
        "muscle dp/dF",
        configuration,
        &analytic,
        &dual,
        ACTUATOR_SAFETY * EPS * kappa * jmax,
        &fun,
        (EPS * kappa * len, len / (l * l * l), l),
        kappa,
    ));

    let analytic: Vec<f64> = j.wrt_a.iter().copied().collect();
    let fun = |h: f64| target(f, a + h);
    let dual: Vec<f64> = dual_a.iter().copied().collect();
    out.push(actuator_check(
        "muscle dp/da",
        configuration,
        &analytic,
        &dual,
        ACTUATOR_SAFETY * EPS * kappa,
        &fun,
        // p(a) = (1 - a) n with the same n at every step: round-off eps only.
        (4.0 * EPS, 0.0, a.min(1.0 - a)),
        kappa,
    ));

    let g = muscle_energy_gradient(f, mdir, a, k)?;
    let analytic = mat_vec(&g);
    let dual = mat_vec(&muscle_energy_gradient_dual(f, mdir, a, k)?);
    let dist = (l - (1.0 - a)).abs() + EPS * fnorm;
    let fun = |h: f64| -> Vec<f64> {
        (0..9)
            .map(|q| {
                let mut gg = *f;
                gg[(q % 3, q / 3)] += h;
                muscle_energy(&gg, mdir, a, k).unwrap_or(f64::NAN)
            })
            .collect()
    };
    out.push(actuator_check(
        "muscle dPsi/dF",
        configuration,
        &analytic,
        &dual,
        // F m - p (both rounded), and the dual's term (F m - p) . dp, zero up to round-off.
        ACTUATOR_SAFETY * EPS * k * (fnorm + kappa * len + dist * (1.0 + kappa * jmax)),
        &fun,
        (3.0 * EPS * k * fnorm * dist, k * len / (l * l), l),
        kappa,
    ));
    Ok(out)
}

/// `U diag(s) V^T` with random rotations.
pub fn with_singular_values(s: [f64; 3], rng: &mut ChaCha8Rng) -> Matrix3<f64> {
    let u = Rotation3::from_scaled_axis(unit(rng) * rng.random_range(0.0..3.0));
    let v = Rotation3::from_scaled_axis(unit(rng) * rng.random_range(0.0..3.0));
    u.matrix() * Matrix3::from_diagonal(&Vector3::from(s)) * v.matrix().transpose()
}

/// Pneumatic activations checked (docs/method.md section 5: a target volume ratio, from nearly
/// collapsed to doubled).
pub const PNEUMATIC_ACTIVATIONS: [f64; 4] = [1e-6, 0.5, 1.0, 2.0];
/// Muscle activations checked (the central differences in `a` need `a +- h` in `[0, 1]`).
pub const MUSCLE_ACTIVATIONS: [f64; 3] = [1e-6, 0.5, 1.0 - 1e-6];

fn fmt_s(s: [f64; 3]) -> String {
    let one = |v: f64| {
        if (1e-2..1e2).contains(&v.abs()) {
            format!("{v:.2}")
        } else {
            format!("{v:.0e}")
        }
    };
    format!("({}, {}, {})", one(s[0]), one(s[1]), one(s[2]))
}

/// All actuator checks of the report, with the constraint residuals.
pub fn actuator_checks(rng: &mut ChaCha8Rng) -> (Vec<JacobianCheck>, ActuatorConstraintCheck) {
    let mut checks = Vec::new();
    let mut failed = false;
    let random_s = |rng: &mut ChaCha8Rng, lo: f64, hi: f64| {
        let mut v = [
            rng.random_range(lo..hi),
            rng.random_range(lo..hi),
            rng.random_range(lo..hi),
        ];
        v.sort_by(|x, y| y.total_cmp(x));
        v
    };
    let spectra = [
        ("random", random_s(rng, 0.5, 1.5)),
        ("inverted", {
            let mut v = random_s(rng, 0.3, 1.5);
            v[2] = -v[2];
            v
        }),
        ("wide", [1e4, 1.0, 1e-4]),
        ("wide inverted", [1e4, 1e-2, -1e-4]),
    ];
    for (label, s) in &spectra {
        let f = with_singular_values(*s, rng);
        for &a in &PNEUMATIC_ACTIVATIONS {
            let cfg = format!("{label} {} a={a:e}", fmt_s(*s));
            match check_pneumatic(&f, a, 1.0, &cfg) {
                Ok(c) => checks.extend(c),
                Err(_) => failed = true,
            }
        }
    }
    for (label, s) in &spectra {
        let f = with_singular_values(*s, rng);
        let svd = svd3(&f);
        for &a in &MUSCLE_ACTIVATIONS {
            for (along, m) in [("m random", unit(rng)), ("m = v_3", svd.v.column(2).into_owned())] {
                if along == "m = v_3" && !label.starts_with("wide") {
                    continue;
                }
                let cfg = format!("{label}, {along}, a={a:e}");
                match check_muscle(&f, &m, a, 1.0, &cfg) {
                    Ok(c) => checks.extend(c),
                    Err(_) => failed = true,
                }
            }
        }
    }
    // Constraint residuals on random F: half inverted, singular values log-uniform in
    // [1e-4, 1e4].
    let (mut prod_err, mut len_err) = (0.0f64, 0.0f64);
    let (mut np, mut nm) = (0, 0);
    for n in 0..250 {
        let mut s = [0.0; 3];
        for v in &mut s {
            *v = 10f64.powf(rng.random_range(-4.0..4.0));
        }
        s.sort_by(|x, y| y.total_cmp(x));
        if n % 2 == 1 {
            s[2] = -s[2];
        }
        let f = with_singular_values(s, rng);
        let sigma = svd3(&f).sigma;
        for &a in &PNEUMATIC_ACTIVATIONS {
            np += 1;
            match volume::nearest_product(&sigma, a) {
                Ok(x) if x.iter().all(|&v| v > 0.0) => prod_err = prod_err.max((x.product() - a).abs() / a),
                _ => failed = true,
            }
        }
        let m = unit(rng);
        for a in [0.0, 1e-6, 0.5, 1.0] {
            nm += 1;
            match muscle_target(&(f * m), a) {
                Ok(p) => len_err = len_err.max((p.norm() - (1.0 - a)).abs()),
                Err(_) => failed = true,
            }
        }
    }
    let constraints = ActuatorConstraintCheck {
        pneumatic_cases: np,
        max_product_rel_error: prod_err,
        muscle_cases: nm,
        max_fibre_length_error: len_err,
        pass: !failed && prod_err <= 1e-12 && len_err <= 1e-12,
    };
    (checks, constraints)
}
