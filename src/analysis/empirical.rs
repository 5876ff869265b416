//! Run the iterations (19) and (21) themselves, with a fixed random right-hand side `f` and no
//! contact impulse (`xi = 0`), and measure their contraction rate.
//!
//! The successive differences `d_k = v_{k+1} - v_k` obey `d_{k+1} = G d_k`. `G` is self-adjoint
//! in the `W` inner product (`W = M` for (19), `W = M + h^2 D` for (21)), so the ratio
//! `|d_{k+1}|_W / |d_k|_W` is non-decreasing and converges to the spectral radius from below.
//! The iteration stops at the round-off floor (`|d| < 1e-10 |v|`), on divergence
//! (`|d| > 1e100 |d_0|`), or at the iteration cap; the last ratio is the observed rate.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::IterationSystem;

/// Which iteration to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Scheme {
    /// `M v' = f - h^2 L v` (Eq. 19).
    Plain,
    /// `(M + h^2 D) v' = f - h^2 (L - D) v` (Eq. 21).
    Split,
}

/// How an empirical run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Reached the round-off floor.
    Converged,
    /// Grew by 100 orders of magnitude.
    Diverged,
    /// Hit the iteration cap first.
    IterationCap,
}

/// Observed vs predicted contraction of one scheme at one time step.
#[derive(Debug, Clone, Serialize)]
pub struct EmpiricalCheck {
    /// The scheme.
    pub scheme: Scheme,
    /// Time step.
    pub dt: f64,
    /// Spectral radius predicted by the eigen-analysis.
    pub predicted_spectral_radius: f64,
    /// Last ratio `|d_{k+1}|_W / |d_k|_W`.
    pub observed_rate: f64,
    /// `|observed - predicted| / predicted`.
    pub relative_difference: f64,
    /// Iterations run.
    pub iterations: usize,
    /// How the run ended.
    pub outcome: Outcome,
}

/// Run `scheme` at time step `h` from `v = 0` with a random `f` (seeded) for at most
/// `max_iter` iterations, and compare its rate with `predicted`.
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
    let norm_w = |x: &[f64]| -> f64 { x.iter().zip(&w).map(|(x, w)| w * x * x).sum::<f64>().sqrt() };
    let mut v = vec![0.0; n];
    let mut next = vec![0.0; n];
    let mut lv = vec![0.0; n];
    let mut d = vec![0.0; n];
    let mut prev_norm = f64::NAN;
    let mut first_norm = f64::NAN;
    let mut rate = f64::NAN;
    let mut outcome = Outcome::IterationCap;
    let mut iterations = 0;
    for k in 0..max_iter {
        sys.l.matvec(&v, &mut lv);
        for i in 0..n {
            next[i] = (f[i] - h2 * lv[i] + dshift[i] * v[i]) / w[i];
            d[i] = next[i] - v[i];
        }
        std::mem::swap(&mut v, &mut next);
        iterations = k + 1;
        let dn = norm_w(&d);
        if k == 0 {
            first_norm = dn;
        } else {
            rate = dn / prev_norm;
        }
        prev_norm = dn;
        if !(dn.is_finite()) || dn > 1e100 * first_norm {
            outcome = Outcome::Diverged;
            break;
        }
        if dn < 1e-10 * norm_w(&v) {
            outcome = Outcome::Converged;
            break;
        }
    }
    EmpiricalCheck {
        scheme,
        dt: h,
        predicted_spectral_radius: predicted,
        observed_rate: rate,
        relative_difference: (rate - predicted).abs() / predicted,
        iterations,
        outcome,
    }
}
