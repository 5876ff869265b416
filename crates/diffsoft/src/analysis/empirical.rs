//! Run the iterations (19) and (21) themselves, with a fixed random right-hand side `f`, no
//! contact impulse (`xi = 0`) and `v_0 = 0`, and measure their contraction rate.
//!
//! The iteration runs in correction form, `v_{k+1} = v_k + d_k`, `d_{k+1} = G d_k`: algebraically
//! the same iteration (`d_k = v_{k+1} - v_k`), but `d` keeps full relative precision instead of
//! hitting the round-off floor `eps |v|`. `G` is self-adjoint in the `W` inner product (`W = M`
//! for (19), `W = M + h^2 D` for (21)), so the ratio `|d_{k+1}|_W / |d_k|_W` is non-decreasing
//! and converges to the spectral radius from below, at the speed `(|l_2| / |l_1|)^(2k)` of the
//! two largest eigenvalue magnitudes. When the two are close, a run that stops as soon as `v`
//! has converged reads the rate too low, so once `v` is converged (`|d| < 1e-17 |v|`) the
//! correction keeps being propagated, renormalised to avoid underflow (ratios do not change),
//! until the rate sequence is stable to `1e-14` for 20 steps or the iteration cap is hit; the
//! same happens after divergence (growth by 100 orders of magnitude). For converged runs the residual of the
//! implicit-Euler system `(M + h^2 L) v = f` shows that the fixed point is its solution.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::IterationSystem;

/// Which iteration to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Scheme {
    /// `M v' = f - h^2 L v` (Eq. 19).
    Plain,
    /// `(M + h^2 D) v' = f - h^2 (L - D) v` (Eq. 21).
    Split,
}

/// How an empirical run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// The iterate reached the solution to round-off (`|d| < 1e-17 |v|`).
    Converged,
    /// The correction grew by 100 orders of magnitude, or at a rate above 1 that was stable to
    /// 1e-14 for 20 steps.
    Diverged,
    /// Neither within the iteration cap.
    IterationCap,
    /// The correction overflowed or became NaN (no rate can be observed).
    NonFinite,
}

/// Observed vs predicted contraction of one scheme at one time step.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct EmpiricalCheck {
    /// The scheme.
    pub scheme: Scheme,
    /// Time step (s).
    pub dt: f64,
    /// Spectral radius predicted by the eigen-analysis (1).
    pub predicted_spectral_radius: f64,
    /// Last ratio `|d_{k+1}|_W / |d_k|_W` (1).
    pub observed_rate: f64,
    /// `|observed - predicted| / predicted` (1; the absolute difference when the prediction is 0).
    pub relative_difference: f64,
    /// Iterations run (including the propagation of the correction after convergence).
    pub iterations: usize,
    /// Iteration at which the iterate converged to round-off (null if it did not).
    pub converged_at: Option<usize>,
    /// Whether the rate sequence was stable to 1e-14 for 20 steps when the run stopped.
    pub rate_stable: bool,
    /// How the run ended.
    pub outcome: Outcome,
    /// `|f - (M + h^2 L) v| / |f|` at the end (1; for converged runs: the fixed point is the
    /// implicit-Euler solution).
    pub final_relative_residual: f64,
}

/// Run `scheme` at time step `h` from `v = 0` with a random `f` (seeded) for at most
/// `max_iter` iterations, and compare its rate with `predicted`.
///
/// ```
/// use diffsoft::analysis::empirical::{contraction, Outcome, Scheme};
/// use diffsoft::analysis::spectral::EigenMethod;
/// use diffsoft::analysis::{Attachments, IterationSystem, Spectrum};
/// use diffsoft::mesh::generate::BoxSpec;
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let sys = IterationSystem::new(&mesh, 1000.0, 1e5, &Attachments::default())?;
/// let spectrum = Spectrum::compute(&sys, EigenMethod::Dense)?;
/// let h = 0.5 * spectrum.critical_dt_plain();
/// let check = contraction(&sys, h, Scheme::Plain, spectrum.rho_plain(h), 10_000, 1);
/// assert_eq!(check.outcome, Outcome::Converged);
/// assert!(check.relative_difference < 1e-3, "observed {} vs {}", check.observed_rate, spectrum.rho_plain(h));
/// assert!(check.final_relative_residual < 1e-10);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn contraction(
    sys: &IterationSystem,
    h: f64,
    scheme: Scheme,
    predicted: f64,
    max_iter: usize,
    seed: u64,
) -> EmpiricalCheck {
    let n = sys.n();
    let h2 = h * h;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let f: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
    // Diagonal of the left-hand side and the diagonal part moved to it.
    let (w, dshift): (Vec<f64>, Vec<f64>) = match scheme {
        Scheme::Plain => (sys.mass.clone(), vec![0.0; n]),
        Scheme::Split => (
            sys.mass.iter().zip(&sys.diag).map(|(m, d)| m + h2 * d).collect(),
            sys.diag.iter().map(|d| h2 * d).collect(),
        ),
    };
    // W-norm, scaled by max |x| so that tiny corrections do not underflow when squared.
    let norm_w = |x: &[f64]| -> f64 {
        let s = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if s == 0.0 || !s.is_finite() {
            return s;
        }
        s * x.iter().zip(&w).map(|(x, w)| w * (x / s) * (x / s)).sum::<f64>().sqrt()
    };
    // v_1 = W^-1 f = d_0.
    let mut d: Vec<f64> = f.iter().zip(&w).map(|(f, w)| f / w).collect();
    let mut v = d.clone();
    let mut ld = vec![0.0; n];
    let mut prev = norm_w(&d);
    // log10 of |d_k| / |d_0|, accumulated across renormalisations.
    let mut log_growth = 0.0f64;
    let mut rate = f64::NAN;
    let mut stable = 0usize;
    let mut converged_at = None;
    let mut outcome = Outcome::IterationCap;
    let mut iterations = 1;
    while iterations < max_iter {
        sys.l.matvec(&d, &mut ld);
        for i in 0..n {
            d[i] = (dshift[i] * d[i] - h2 * ld[i]) / w[i];
        }
        let settled = outcome != Outcome::IterationCap;
        if !settled {
            for i in 0..n {
                v[i] += d[i];
            }
        }
        iterations += 1;
        let dn = norm_w(&d);
        let new_rate = dn / prev;
        if new_rate == 0.0 {
            // The correction vanished exactly (e.g. h^2 L underflows): the iterate is the
            // solution and the observed contraction is 0.
            if !settled {
                converged_at = Some(iterations);
                outcome = Outcome::Converged;
            }
            rate = 0.0;
            break;
        }
        if !new_rate.is_finite() {
            if !settled {
                outcome = Outcome::NonFinite;
            }
            break;
        }
        stable = if (new_rate - rate).abs() <= 1e-14 * new_rate {
            stable + 1
        } else {
            0
        };
        rate = new_rate;
        log_growth += rate.log10();
        if !settled {
            if log_growth > 100.0 {
                outcome = Outcome::Diverged;
            } else if dn < 1e-17 * norm_w(&v) {
                converged_at = Some(iterations);
                outcome = Outcome::Converged;
            } else if stable >= 20 && rate > 1.0 {
                outcome = Outcome::Diverged;
            }
        }
        if outcome != Outcome::IterationCap {
            // v no longer changes: renormalise d (ratios do not depend on its scale) and keep
            // propagating it until the rate is stable.
            for x in d.iter_mut() {
                *x /= dn;
            }
            prev = 1.0;
            if stable >= 20 {
                break;
            }
        } else {
            prev = dn;
        }
    }
    // Residual of (M + h^2 L) v = f.
    sys.l.matvec(&v, &mut ld);
    let fnorm = f.iter().map(|x| x * x).sum::<f64>().sqrt();
    let res = (0..n)
        .map(|i| {
            let r = f[i] - sys.mass[i] * v[i] - h2 * ld[i];
            r * r
        })
        .sum::<f64>()
        .sqrt()
        / fnorm;
    EmpiricalCheck {
        scheme,
        dt: h,
        predicted_spectral_radius: predicted,
        observed_rate: rate,
        // Relative to the prediction, or absolute when the prediction is 0.
        relative_difference: if predicted == 0.0 {
            (rate - predicted).abs()
        } else {
            (rate - predicted).abs() / predicted
        },
        iterations,
        converged_at,
        rate_stable: stable >= 20,
        outcome,
        final_relative_residual: res,
    }
}
