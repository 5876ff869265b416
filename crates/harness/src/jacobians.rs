//! Jacobian checks of the skeleton and the actuators (`diffsoft jacobians`,
//! `reports/jacobians.json`, schema `diffsoft.jacobians/2`):
//!
//! * every joint type's `dA/dz_k` against forward-mode dual numbers (num-dual) and against
//!   central differences with a step sweep, at random configurations including angles at
//!   `+-pi` and large prismatic extensions;
//! * every column of `B = dq/dz` (Eqs. 12-16) for mixed chains at least four joints deep;
//! * the rotational update across `+-pi` (Eq. 35) and the root update's projection onto the
//!   rotations (Eq. 10);
//! * the actuators (docs/method.md section 5, Eqs. 39-40; [`diffsoft::kernel::actuator`]): for the
//!   pneumatic cell `dR/dF`, `dR/da`, the nearest product's log-log Jacobian
//!   `d ln x / d ln(s, a)` and `dPsi/dF`; for the muscle fibre `dp/dF`, `dp/da` and `dPsi/dF`;
//!   each against dual numbers (an independent one-sided Jacobi SVD and Newton in dual
//!   arithmetic) and a step sweep, at random, inverted (`det F < 0`) and wide (singular values
//!   `1e4 .. 1e-4`) `F`, pneumatic `a in {1e-6, 0.5, 1, 2}`, muscle `a in {1e-6, 0.5, 1 - 1e-6}`
//!   and fibres of length `1e-4 .. 1e4`; plus the constraint residuals
//!   `max |prod x - a| / a` and `max ||p| - (1 - a)|` over random `F`.
//!
//! The skeleton checks use the fixed tolerances [`DUAL_TOL`] and [`FD_TOL`]. The actuator checks
//! span eight decades of conditioning, so their tolerances are derived per configuration
//! ([`check_pneumatic`], [`check_muscle`]): `ACTUATOR_SAFETY = 100` times the predicted
//! round-off of the two computations (against dual numbers) or the predicted best error of
//! central differences, [`fd_floor`] (against differences), from the scale `M` of the values,
//! the conditioning `max|J|`, and the distance `L` to the nearest pole of the Jacobian
//! ([`pneumatic_scales`]). Each check records the condition number `M / L` it used
//! (`condition`); at `M / L ~ 1` the tolerances are about `1e-14` and `1e-8` relative to
//! `max|J|`.

use nalgebra::{Matrix3, Matrix4, Rotation3, Vector3};
use num_dual::Dual64;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::fd::{compare, sweep, Comparison, StepSweep};
use crate::report::{Header, Verdict};
use diffsoft::kernel::actuator::{
    muscle_energy, muscle_energy_gradient, muscle_energy_gradient_dual, muscle_jacobian, muscle_jacobian_dual,
    muscle_target, nearest_product_dual, nearest_product_jacobian, pneumatic_energy, pneumatic_energy_gradient,
    pneumatic_energy_gradient_dual, pneumatic_jacobian, pneumatic_jacobian_dual, pneumatic_target_of, ActuatorError,
};
use diffsoft::kernel::svd::svd3;
use diffsoft::kernel::volume;
use diffsoft::skeleton::free::Free;
use diffsoft::skeleton::prismatic::Prismatic;
use diffsoft::skeleton::rotational::Rotational;
use diffsoft::skeleton::{Joint, Skeleton};
pub use diffsoft::testing::random_chain;
use diffsoft::testing::unit;

/// Schema of the report.
pub const SCHEMA: &str = "diffsoft.jacobians/3";
/// Tolerances against dual numbers (both exact up to round-off).
pub const DUAL_TOL: Tolerance = Tolerance {
    atol: 1e-12,
    rtol: 1e-10,
};
/// Tolerances against central differences at the best step.
pub const FD_TOL: Tolerance = Tolerance { atol: 1e-7, rtol: 1e-6 };

/// A comparison passes where `|analytic - reference| <= atol + rtol |reference|` entrywise.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, schemars::JsonSchema)]
pub struct Tolerance {
    /// Absolute tolerance (the unit of the compared derivative's entries).
    pub atol: f64,
    /// Relative tolerance (1).
    pub rtol: f64,
}

/// The fixed tolerances of the skeleton checks.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, schemars::JsonSchema)]
pub struct Tolerances {
    /// Against dual numbers ([`DUAL_TOL`]).
    pub versus_dual: Tolerance,
    /// Against central differences at the best step ([`FD_TOL`]).
    pub versus_fd: Tolerance,
}

/// One derivative check.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct JacobianCheck {
    /// What is checked.
    pub name: String,
    /// The configuration, in words.
    pub configuration: String,
    /// Entries compared.
    pub entries: usize,
    /// Against dual numbers.
    pub versus_dual: Comparison,
    /// Against central differences at the best step.
    pub versus_fd: Comparison,
    /// The step sweep.
    pub sweep: StepSweep,
    /// Actuator checks: the condition number the tolerances are derived from (1; `M / L`, see the
    /// module doc); absent for the skeleton checks.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub condition: Option<f64>,
}

impl JacobianCheck {
    /// Both comparisons pass.
    pub fn pass(&self) -> bool {
        self.versus_dual.pass && self.versus_fd.pass
    }
}

/// The rotational update across the branch cut.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct AngleWrapCheck {
    /// Start angle (rad).
    pub from: f64,
    /// Increment (1: the update adds `atan(increment)` to the angle).
    pub increment: f64,
    /// Angle after the update (rad, in `(-pi, pi]`).
    pub to: f64,
    /// `|A(to) - A(from + atan(increment))|_max` (1): the transform is continuous across the cut.
    pub transform_jump: f64,
    /// In range and continuous.
    pub pass: bool,
}

/// The root update stays a rotation.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct RootUpdateCheck {
    /// Updates applied (random rotations up to 1 rad, translations up to 1e3).
    pub updates: usize,
    /// Largest `|R^T R - I|_max` after an update (1).
    pub max_orthogonality_error: f64,
    /// Largest `|det R - 1|` (1).
    pub max_det_error: f64,
    /// Both below 1e-12.
    pub pass: bool,
}

/// The actuator constraints are met: `prod sigma(R) = a` and `|p| = 1 - a`.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct ActuatorConstraintCheck {
    /// Pneumatic projections evaluated (random `F`, half inverted, singular values log-uniform
    /// in `[1e-4, 1e4]`, `a in {1e-6, 0.5, 1, 2}`).
    pub pneumatic_cases: usize,
    /// `max |x_1 x_2 x_3 - a| / a` over them (1; `x` the singular values `R` is composed from).
    pub max_product_rel_error: f64,
    /// Muscle targets evaluated (the same `F`, random unit `m`, `a in {0, 1e-6, 0.5, 1}`).
    pub muscle_cases: usize,
    /// `max ||p| - (1 - a)|` over them (1: `p` is a stretch).
    pub max_fibre_length_error: f64,
    /// Both below 1e-12 and no projection failed.
    pub pass: bool,
}

/// `reports/jacobians.json`.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct JacobiansReport {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// Seed of the random configurations.
    pub seed: u64,
    /// Tolerances of the skeleton checks against dual numbers and against finite differences.
    pub tolerances: Tolerances,
    /// Derivative checks.
    pub checks: Vec<JacobianCheck>,
    /// Angle updates across `+-pi`.
    pub angle_wrap: Vec<AngleWrapCheck>,
    /// Root updates.
    pub root_update: RootUpdateCheck,
    /// Residuals of the actuator constraints.
    pub actuator_constraints: ActuatorConstraintCheck,
    /// Claims.
    pub verdicts: Vec<Verdict>,
}

fn flat(m: &Matrix4<f64>) -> Vec<f64> {
    m.iter().copied().collect()
}

/// Check `dA/dz_k` of one joint for every coordinate.
pub fn check_joint(joint: &dyn Joint, name: &str, configuration: &str, scale: f64) -> Vec<JacobianCheck> {
    (0..joint.dofs())
        .map(|k| {
            let analytic = flat(&joint.derivative(k));
            let mut z = vec![num_dual::Dual64::from(0.0); joint.dofs()];
            z[k] = num_dual::Dual64::from(0.0).derivative();
            let dual: Vec<f64> = joint.transform_dual(&z).iter().map(|d| d.eps).collect();
            let f = |h: f64| {
                let mut zz = vec![0.0; joint.dofs()];
                zz[k] = h;
                flat(&joint.transform_after(&zz))
            };
            let s = sweep(&f, &analytic, scale, 10);
            JacobianCheck {
                name: format!("{name}: dA/dz_{k}"),
                configuration: configuration.to_string(),
                entries: analytic.len(),
                versus_dual: compare(&analytic, &dual, DUAL_TOL.atol, DUAL_TOL.rtol),
                versus_fd: compare(&analytic, &s.best_difference, FD_TOL.atol, FD_TOL.rtol),
                sweep: s,
                condition: None,
            }
        })
        .collect()
}

/// Check every column of `B` of a skeleton.
pub fn check_jacobian(sk: &Skeleton, name: &str, configuration: &str) -> Vec<JacobianCheck> {
    let nr = sk.rigid.len();
    let mut b = nalgebra::DMatrix::zeros(3 * nr, sk.dofs);
    sk.jacobian(&mut b);
    (0..sk.dofs)
        .map(|c| {
            let analytic: Vec<f64> = b.column(c).iter().copied().collect();
            let dual: Vec<f64> = sk
                .jacobian_column_dual(c)
                .iter()
                .flat_map(|v| [v.x, v.y, v.z])
                .collect();
            let f = |h: f64| {
                sk.positions_after(c, h)
                    .iter()
                    .flat_map(|v| [v.x, v.y, v.z])
                    .collect::<Vec<f64>>()
            };
            let s = sweep(&f, &analytic, 1.0, 10);
            JacobianCheck {
                name: format!("{name}: column {c} of B"),
                configuration: configuration.to_string(),
                entries: analytic.len(),
                versus_dual: compare(&analytic, &dual, DUAL_TOL.atol, DUAL_TOL.rtol),
                versus_fd: compare(&analytic, &s.best_difference, FD_TOL.atol, FD_TOL.rtol),
                sweep: s,
                condition: None,
            }
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Actuators (docs/method.md section 5, Eqs. 39-40).

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

/// Run every check with configurations drawn from `seed`.
pub fn run(seed: u64) -> JacobiansReport {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut checks = Vec::new();
    // Rotational joints at random, at +-pi and at 0.
    for (label, angle) in [
        ("random angle", rng.random_range(-3.0..3.0)),
        ("angle pi - 1e-9", std::f64::consts::PI - 1e-9),
        ("angle -pi + 1e-9", -std::f64::consts::PI + 1e-9),
        ("angle 0", 0.0),
    ] {
        let mut r = Rotational::new(
            Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 0.5),
            unit(&mut rng),
        );
        r.angle = angle;
        checks.extend(check_joint(&r, "rotational", label, 1.0));
    }
    for (label, ext) in [("extension 0.3", 0.3), ("extension 1e4", 1e4), ("extension -1e6", -1e6)] {
        let mut p = Prismatic::new(unit(&mut rng));
        p.extension = ext;
        checks.extend(check_joint(&p, "prismatic", label, 1.0));
    }
    let root = Free {
        rotation: *Rotation3::from_scaled_axis(unit(&mut rng) * 2.5).matrix(),
        translation: Vector3::new(1e3, -2e2, 3.0),
    };
    checks.extend(check_joint(
        &root,
        "free root",
        "rotation 2.5 rad, translation ~1e3",
        1.0,
    ));
    // Chains at least four joints deep, mixed types.
    for (label, depth, near_pi, long) in [
        ("chain of 4, random", 4, false, false),
        ("chain of 5, angles at +-pi", 5, true, false),
        ("chain of 6, extensions ~1e3", 6, false, true),
    ] {
        let sk = random_chain(depth, &mut rng, near_pi, long);
        checks.extend(check_jacobian(&sk, "B", label));
    }
    // Angle update across the cut.
    let mut angle_wrap = Vec::new();
    for (from, inc) in [
        (std::f64::consts::PI - 1e-3, 2e-3),
        (-std::f64::consts::PI + 1e-3, -2e-3),
        (3.0, 0.5),
        (-3.0, -0.5),
    ] {
        let mut r = Rotational::new(Vector3::zeros(), Vector3::new(0.3, -0.4, 0.87));
        r.angle = from;
        let expected = r.transform_at(from + f64::atan(inc));
        r.update(&[inc]);
        let jump = (r.transform() - expected).amax();
        angle_wrap.push(AngleWrapCheck {
            from,
            increment: inc,
            to: r.angle,
            transform_jump: jump,
            pass: r.angle > -std::f64::consts::PI && r.angle <= std::f64::consts::PI && jump < 1e-12,
        });
    }
    // Root updates.
    let mut root = Free::default();
    let (mut orth, mut det) = (0.0f64, 0.0f64);
    let updates = 1000;
    for _ in 0..updates {
        let w = unit(&mut rng) * rng.random_range(0.0..1.0);
        let l = unit(&mut rng) * rng.random_range(0.0..1e3);
        root.update(&[w.x, w.y, w.z, l.x, l.y, l.z]);
        orth = orth.max((root.rotation.transpose() * root.rotation - nalgebra::Matrix3::identity()).amax());
        det = det.max((root.rotation.determinant() - 1.0).abs());
    }
    let root_update = RootUpdateCheck {
        updates,
        max_orthogonality_error: orth,
        max_det_error: det,
        pass: orth < 1e-12 && det < 1e-12,
    };
    let (actuator, actuator_constraints) = actuator_checks(&mut rng);
    let joint_checks: Vec<&JacobianCheck> = checks.iter().filter(|c| !c.name.starts_with("B")).collect();
    let chain_checks: Vec<&JacobianCheck> = checks.iter().filter(|c| c.name.starts_with("B")).collect();
    let pneumatic: Vec<&JacobianCheck> = actuator.iter().filter(|c| c.name.starts_with("pneumatic")).collect();
    let muscle: Vec<&JacobianCheck> = actuator.iter().filter(|c| c.name.starts_with("muscle")).collect();
    // Normwise relative error against differences, the largest over the checks.
    let rel_fd = |cs: &[&JacobianCheck]| {
        cs.iter()
            .map(|c| c.versus_fd.max_abs_error / c.sweep.max_abs_difference.max(f64::MIN_POSITIVE))
            .fold(0.0, f64::max)
    };
    let verdicts = vec![
        Verdict::new(
            "dA/dz of rotational, prismatic and free joints matches dual numbers and central differences",
            joint_checks.iter().all(|c| c.pass()),
            Some(joint_checks.iter().map(|c| c.versus_fd.max_rel_error.min(c.versus_fd.max_abs_error)).fold(0.0, f64::max)),
            Some(FD_TOL.rtol),
            "per check: |a - r| <= atol + rtol |r| against both references",
        ),
        Verdict::new(
            "Every column of B (Eqs. 12-16) of mixed chains 4-6 joints deep matches dual numbers and central differences",
            chain_checks.iter().all(|c| c.pass()),
            None,
            None,
            "per check: |a - r| <= atol + rtol |r| against both references",
        ),
        Verdict::new(
            "The rotational update (Eq. 35) keeps the angle in (-pi, pi] and the transform continuous across the cut",
            angle_wrap.iter().all(|a| a.pass),
            Some(angle_wrap.iter().map(|a| a.transform_jump).fold(0.0, f64::max)),
            Some(1e-12),
            "measured = largest transform jump",
        ),
        Verdict::at_most("The root update (Eq. 10) yields a rotation to 1e-12", orth.max(det), 1e-12),
        Verdict::new(
            "Pneumatic cell Jacobians (dR/dF, dR/da, the nearest product's log-log Jacobian, dPsi/dF; Eqs. 39-40) match dual numbers and central differences, including inverted F, a in {1e-6, 0.5, 1, 2} and singular values 1e-4..1e4",
            pneumatic.len() == 4 * 16 && pneumatic.iter().all(|c| c.pass()),
            Some(rel_fd(&pneumatic)),
            None,
            "per check: |a - r| <= atol with atol from the conditioning (module doc); measured = largest max|a - r_FD| / max|r_FD|",
        ),
        Verdict::new(
            "Muscle fibre Jacobians (dp/dF, dp/da, dPsi/dF) match dual numbers and central differences, including inverted F, fibres of length 1e-4..1e4 and a in {1e-6, 0.5, 1 - 1e-6}",
            muscle.len() == 3 * 3 * 6 && muscle.iter().all(|c| c.pass()),
            Some(rel_fd(&muscle)),
            None,
            "per check: |a - r| <= atol with atol from the conditioning (module doc); measured = largest max|a - r_FD| / max|r_FD|",
        ),
        Verdict::new(
            "The actuator constraints are met to 1e-12 (prod sigma(R) = a relative, |p| = 1 - a absolute) and no projection fails",
            actuator_constraints.pass,
            Some(actuator_constraints.max_product_rel_error.max(actuator_constraints.max_fibre_length_error)),
            Some(1e-12),
            "measured <= threshold",
        ),
    ];
    checks.extend(actuator);
    JacobiansReport {
        header: Header::new(SCHEMA),
        seed,
        tolerances: Tolerances {
            versus_dual: DUAL_TOL,
            versus_fd: FD_TOL,
        },
        checks,
        angle_wrap,
        root_update,
        actuator_constraints,
        verdicts,
    }
}
