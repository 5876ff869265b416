//! The default global solver ([`SolverKind::Auto`]): certification picks the cheapest of
//! direct, split and Chebyshev for this mesh and time step.
//!
//! The rule, in order:
//!
//! 1. factor `M/h^2 + L` and time the factorisation and two solves (the factor is kept: if
//!    direct wins, the simulator runs on it); time a few iterations of the split and of the
//!    Chebyshev iteration (the actual `Stationary` solvers, so the cost per iteration
//!    includes everything an inner iteration does);
//! 2. bound `rho(G21)` by the row sums of `|G21|` (`O(nnz)`, no eigenvalues): when the bound
//!    certifies the split iteration (as in step 4, at the bound's rate) and its predicted cost
//!    at that rate beats the direct solver's, split runs without eigenvalues (small time steps,
//!    soft bodies: a handful of iterations per solve);
//! 3. estimate what the eigenvalue computation would cost ([`eigen_estimate_ms`]); when it
//!    would cost more than the direct solver's whole predicted run (factorisation plus
//!    [`AMORTISED_SOLVES`] solves), no iterative method can pay for it: direct, without
//!    eigenvalues;
//! 4. otherwise compute the extremes of `G21` once, predict each iterative method's inner
//!    iterations per solve from its asymptotic rate ([`predicted_iterations`]), and take the
//!    method with the smallest predicted cost of [`AMORTISED_SOLVES`] solves (direct: the
//!    factorisation plus the solves; iterative: the eigenvalue computation plus the
//!    iterations). An iteration is eligible only when it passes the certification a requested
//!    iteration must pass (a `1e-10` error reduction within the inner iteration cap at its
//!    asymptotic rate) and its predicted iterations per solve are within the cap.

use std::time::Instant;

use nalgebra::Vector3;

use super::assembled::GlobalSystem;
use super::certificate::{Candidate, Certificate, EigenvalueRange, REQUIRED_REDUCTION};
use super::direct::Direct;
use super::global::{GlobalSolver, InnerControl, SolverKind};
use super::stationary::Stationary;
use super::system::System;
use super::SolverError;
use crate::analysis::spectral::{EigenMethod, KRYLOV_MIN_N};

/// Solves a run is assumed to make when the factorisation is amortised. A run makes a global
/// solve per local-global iteration, so 100 solves are 10-20 steps at the 5-10 iterations a
/// step typically takes: a short run. Longer runs only make the factorisation (and the
/// eigenvalue computation) cheaper per solve, which does not change the order of the
/// candidates unless their per-solve costs are close, so a short horizon keeps the
/// one-off costs visible without letting them dominate.
pub const AMORTISED_SOLVES: f64 = 100.0;

/// Typical error of a warm-started global solve's initial guess, relative to the length scale.
/// Each solve starts from the previous local-global iterate, which is within one iteration's
/// change of the answer; on clamped beams under gravity at `dt = 0.01` that change is
/// `1e-4`-`1e-3` of the length scale in the first iterations of a step and smaller later, and
/// this value makes the predicted iterations match the ones run within a factor 2 there
/// (docs/performance.md, "Which global solver runs by default").
pub const WARM_START_ERROR: f64 = 1e-4;

/// Inner iterations timed per round of an iterative method (after one untimed round that warms
/// the caches).
const TIMED_ITERATIONS: usize = 6;

/// Timed rounds of an iterative method; the cheapest counts, as for the direct solves, so that
/// a moment's load on the machine (another process, a page fault) does not flip the choice.
const TIMED_ROUNDS: usize = 3;

/// Direct solves timed (the cheapest counts).
const TIMED_SOLVES: usize = 3;

/// What a Krylov computation of the two extremes of `G21` costs, in units of one split
/// iteration (two thick-restart Lanczos runs of a 96-vector basis with restarts; measured
/// 1800 on a clamped beam of 10k tets at `dt = 0.01`).
const KRYLOV_ITERATION_EQUIVALENTS: f64 = 2000.0;

/// Dense symmetric eigenvalues take about `n^3` times this (ms).
const DENSE_MS_PER_N3: f64 = 1e-6;

/// The measured costs of the candidates before any eigenvalue is known.
struct Timings {
    /// The factored direct solver and its factorisation time (ms), if it factored.
    direct: Option<(Direct, f64)>,
    /// One direct solve (ms).
    solve_ms: f64,
    /// One split iteration (ms).
    split_ms: f64,
    /// One Chebyshev iteration (ms).
    chebyshev_ms: f64,
}

/// A right-hand side for timing: the inertia and the fixed vertices' pull of a body at rest
/// (any finite vector does; this one has the scale of the real ones).
fn timing_rhs(sys: &GlobalSystem) -> Vec<Vector3<f64>> {
    sys.mass_h2
        .iter()
        .zip(&sys.coupling)
        .map(|(m, c)| c + Vector3::new(1.0, 0.5, -0.25) * *m)
        .collect()
}

/// The factorisation's time (measured when the system was first factored) and the cheapest of
/// [`TIMED_SOLVES`] solves.
fn time_direct(sys: &System, control: InnerControl, b: &[Vector3<f64>]) -> (Option<(Direct, f64)>, f64) {
    let Ok((_, factor_ms)) = sys.factor() else {
        return (None, f64::INFINITY);
    };
    let Ok(mut direct) = sys.direct(control) else {
        return (None, f64::INFINITY);
    };
    let mut x = vec![Vector3::zeros(); sys.n()];
    let mut best = f64::INFINITY;
    for _ in 0..TIMED_SOLVES {
        let t = Instant::now();
        if direct.solve_free(b, &mut x).is_err() {
            return (None, f64::INFINITY);
        }
        best = best.min(ms(t));
    }
    (Some((direct, factor_ms)), best)
}

/// Time one inner iteration of a stationary solver (Chebyshev-accelerated when `chebyshev`):
/// the cheapest of [`TIMED_ROUNDS`] rounds.
fn time_iteration(sys: &GlobalSystem, chebyshev: bool, b: &[Vector3<f64>]) -> f64 {
    let control = InnerControl {
        tolerance: 0.0,
        max_iterations: TIMED_ITERATIONS,
    };
    let rho = chebyshev.then_some(0.5);
    let mut solver = Stationary::new(sys, SolverKind::Split, 1.0, 1.0, rho, control);
    let mut x = vec![Vector3::zeros(); sys.n()];
    // A divergence error would only mean the timed iterates grew; the time is what counts.
    let _ = solver.solve(sys, b, &mut x, &[]);
    let mut best = f64::INFINITY;
    for _ in 0..TIMED_ROUNDS {
        x.iter_mut().for_each(|v| *v = Vector3::zeros());
        let t = Instant::now();
        let _ = solver.solve(sys, b, &mut x, &[]);
        best = best.min(ms(t));
    }
    best / TIMED_ITERATIONS as f64
}

/// Milliseconds since `t`.
fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Measure every candidate's costs that need no eigenvalues.
fn measure(sys: &System, control: InnerControl) -> Timings {
    let b = timing_rhs(sys);
    let (direct, solve_ms) = time_direct(sys, control, &b);
    Timings {
        direct,
        solve_ms,
        split_ms: time_iteration(sys, false, &b),
        chebyshev_ms: time_iteration(sys, true, &b),
    }
}

/// The eigensolver used for the choice: the settings' one, except that `auto` takes Krylov
/// from [`KRYLOV_MIN_N`] vertices on (the choice needs the rates to a few digits only, and
/// Lanczos costs a few hundred iterations where the dense eigendecomposition grows as `n^3`).
fn eigen_method(method: EigenMethod, n: usize) -> EigenMethod {
    match method {
        EigenMethod::Auto if n >= KRYLOV_MIN_N => EigenMethod::Krylov,
        m => m.resolve(n),
    }
}

/// Predicted cost of the eigenvalue computation (ms): `KRYLOV_ITERATION_EQUIVALENTS` (2000) split
/// iterations for Krylov, `DENSE_MS_PER_N3 n^3` (1e-6 ms) for the dense eigendecomposition.
pub fn eigen_estimate_ms(method: EigenMethod, n: usize, iteration_ms: f64) -> f64 {
    match method {
        EigenMethod::Krylov => KRYLOV_ITERATION_EQUIVALENTS * iteration_ms,
        _ => DENSE_MS_PER_N3 * (n as f64).powi(3),
    }
}

/// Inner iterations a warm-started solve takes at asymptotic rate `rate` (per iteration)
/// until its update drops below `tolerance` (relative to the length scale). The warm-start
/// error is a smooth deformation, which lies in the modes at the top of the spectrum of
/// `G21` (eigenvalue `top`, near 1 on stiff bodies); the update of an iteration is that error
/// times `1 - top`, so the error must fall from [`WARM_START_ERROR`] to
/// `tolerance / (1 - top)`. At least 1; `None` when the iteration does not converge.
pub fn predicted_iterations(rate: f64, top: f64, tolerance: f64) -> Option<f64> {
    if !(rate.is_finite() && rate < 1.0) {
        return None;
    }
    if rate <= 0.0 {
        return Some(1.0);
    }
    let target = tolerance.max(f64::MIN_POSITIVE) / (1.0 - top).max(f64::EPSILON);
    let n = (target / WARM_START_ERROR).ln() / rate.ln();
    Some(n.ceil().max(1.0))
}

/// `||G21||_inf = max_i sum_j |L_ij| (j != i) / (m_i/h^2 + L_ii)`, an upper bound of
/// `rho(G21)` that needs no eigenvalues (`L` is stored with both triangles).
pub(crate) fn split_row_sum_bound(sys: &GlobalSystem) -> f64 {
    (0..sys.n())
        .map(|i| {
            let off: f64 = sys.l.column(i).filter(|&(r, _)| r != i).map(|(_, v)| v.abs()).sum();
            off / (sys.mass_h2[i] + sys.l_diag[i])
        })
        .fold(0.0, f64::max)
}

/// Whether an iteration at asymptotic `rate` passes the certification a requested iteration
/// must pass: a [`REQUIRED_REDUCTION`] of the error within `cap` iterations. The warm-start
/// prediction alone is not enough: when `1 - top` is tiny, the update test stops an iteration
/// long before its error is small (a falsely converged solve), so it would look cheap.
fn certified(rate: f64, cap: usize) -> bool {
    rate < 1.0 && (rate <= 0.0 || REQUIRED_REDUCTION.ln() / rate.ln() <= cap as f64)
}

/// The direct candidate.
fn direct_candidate(t: &Timings) -> Candidate {
    let factor = t.direct.as_ref().map(|(_, f)| *f);
    Candidate {
        solver: SolverKind::Direct,
        eligible: factor.is_some(),
        predicted_iterations: None,
        cost_per_iteration_ms: None,
        cost_per_solve_ms: factor.map(|_| t.solve_ms),
        setup_ms: factor.unwrap_or(0.0),
        predicted_ms: factor.map(|f| f + AMORTISED_SOLVES * t.solve_ms),
    }
}

/// An iterative candidate at asymptotic `rate` with top eigenvalue `top`.
fn iterative_candidate(
    solver: SolverKind,
    rate: f64,
    top: f64,
    iteration_ms: f64,
    eigen_ms: f64,
    tolerance: f64,
    cap: usize,
) -> Candidate {
    let n = predicted_iterations(rate, top, tolerance);
    let per_solve = n.map(|n| n * iteration_ms);
    Candidate {
        solver,
        eligible: n.is_some_and(|n| n <= cap as f64) && certified(rate, cap),
        predicted_iterations: n,
        cost_per_iteration_ms: Some(iteration_ms),
        cost_per_solve_ms: per_solve,
        setup_ms: eigen_ms,
        predicted_ms: per_solve.map(|s| eigen_ms + AMORTISED_SOLVES * s),
    }
}

/// Chebyshev's parameters from the extremes `lo <= hi` of `G21`: relaxation, radius and rate.
fn chebyshev_parameters(lo: f64, hi: f64) -> (f64, f64, f64) {
    let gamma = 2.0 / (2.0 - lo - hi);
    let r = (hi - lo) / (2.0 - lo - hi);
    let rate = r / (1.0 + (1.0 - r * r).max(0.0).sqrt());
    (gamma, r, rate)
}

/// One line per candidate for the message.
fn describe(c: &Candidate) -> String {
    let name = format!("{:?}", c.solver).to_lowercase();
    match (c.eligible, c.predicted_ms, c.predicted_iterations) {
        (true, Some(p), Some(n)) => format!("{name} {p:.1} ms ({n} iterations/solve)"),
        (true, Some(p), None) => format!("{name} {p:.1} ms"),
        (false, _, Some(_)) => format!("{name} not eligible (no 1e-10 error reduction within the inner iteration cap)"),
        _ => format!("{name} not eligible"),
    }
}

/// The eligible candidate with the smallest predicted cost.
fn cheapest(candidates: &[Candidate]) -> Option<&Candidate> {
    candidates
        .iter()
        .filter(|c| c.eligible)
        .filter(|c| c.predicted_ms.is_some_and(f64::is_finite))
        .min_by(|a, b| {
            a.predicted_ms
                .unwrap_or(f64::INFINITY)
                .total_cmp(&b.predicted_ms.unwrap_or(f64::INFINITY))
        })
}

/// Choose the global solver for `sys` at time step `h`; the certificate says why, and when
/// direct wins its factor is returned so that the simulator need not factor again.
/// `tolerance` is the inner tolerance relative to the length scale, `control` the inner
/// iteration's absolute control.
pub(crate) fn choose(
    sys: &System,
    base: Certificate,
    method: EigenMethod,
    tolerance: f64,
    control: InnerControl,
) -> Result<(Certificate, Option<Direct>), SolverError> {
    let t0 = Instant::now();
    let mut cert = base;
    cert.converges = Some(true);
    let timings = measure(sys, control);
    let direct = direct_candidate(&timings);
    let direct_ms = direct.predicted_ms.filter(|_| direct.eligible);
    let summary = format!("{} free vertices, {AMORTISED_SOLVES} solves amortised", sys.n());
    let cap = control.max_iterations;
    // 2. The row-sum bound certifies split without eigenvalues when it is small.
    let bound = split_row_sum_bound(sys);
    let by_bound = iterative_candidate(SolverKind::Split, bound, bound, timings.split_ms, 0.0, tolerance, cap);
    if by_bound.eligible && by_bound.predicted_ms < direct_ms.or(Some(f64::INFINITY)) {
        let listed = [&direct, &by_bound].map(describe).join(", ");
        cert.used = SolverKind::Split;
        cert.spectral_radius = Some(bound);
        cert.asymptotic_rate = Some(bound);
        cert.predicted_iterations = by_bound.predicted_iterations;
        cert.message = format!(
            "auto: split, certified without eigenvalues by the row-sum bound rho(G21) <= {bound:.3e} < 1 and cheaper than direct (predicted: {listed}; {summary})"
        );
        cert.candidates = vec![direct, by_bound];
        cert.elapsed_ms = ms(t0);
        return Ok((cert, None));
    }
    // 3. Eigenvalues that would cost more than the direct run are not spent.
    let method = eigen_method(method, sys.n());
    let estimate = eigen_estimate_ms(method, sys.n(), timings.split_ms);
    if let Some(d) = direct_ms.filter(|&d| estimate >= d) {
        cert.used = SolverKind::Direct;
        cert.message = format!(
            "auto: direct sparse Cholesky without eigenvalues: computing them would take about {estimate:.1} ms, more than the direct solver's predicted {d:.1} ms for factoring and {AMORTISED_SOLVES} solves, so no iteration can be cheaper ({summary})"
        );
        cert.candidates = vec![direct];
        cert.elapsed_ms = ms(t0);
        return Ok((cert, timings.direct.map(|(d, _)| d)));
    }
    // 4. Every candidate from the extremes of G21.
    let te = Instant::now();
    let (lo, hi) = sys.split_extremes(method)?;
    let eigen_ms = ms(te);
    let rho = lo.abs().max(hi.abs());
    let (gamma, r, cheb_rate) = chebyshev_parameters(lo, hi);
    let candidates = vec![
        direct,
        iterative_candidate(SolverKind::Split, rho, hi, timings.split_ms, eigen_ms, tolerance, cap),
        iterative_candidate(
            SolverKind::Chebyshev,
            cheb_rate,
            hi,
            timings.chebyshev_ms,
            eigen_ms,
            tolerance,
            cap,
        ),
    ];
    cert.split_extremes = Some(EigenvalueRange {
        smallest: lo,
        largest: hi,
    });
    let listed = candidates.iter().map(describe).collect::<Vec<_>>().join(", ");
    let best = cheapest(&candidates).map(|c| c.solver).ok_or_else(|| {
        SolverError::Uncertified(format!(
            "auto: no global solver can run: {listed}; check masses, stiffness and time step"
        ))
    })?;
    cert.used = best;
    match best {
        SolverKind::Split => {
            cert.spectral_radius = Some(rho);
            cert.asymptotic_rate = Some(rho);
        }
        SolverKind::Chebyshev => {
            cert.spectral_radius = Some(r);
            cert.relaxation = gamma;
            cert.contact_relaxation = gamma.min(1.0);
            cert.chebyshev_rho = Some(r);
            cert.asymptotic_rate = Some(cheb_rate);
        }
        _ => {}
    }
    cert.predicted_iterations = candidates
        .iter()
        .find(|c| c.solver == best)
        .and_then(|c| c.predicted_iterations);
    cert.message = format!(
        "auto: {} is cheapest for this mesh and time step (rho(G21) = {rho:.6}; predicted: {listed}; {summary})",
        format!("{best:?}").to_lowercase()
    );
    cert.candidates = candidates;
    cert.elapsed_ms = ms(t0);
    let direct = if best == SolverKind::Direct {
        timings.direct.map(|(d, _)| d)
    } else {
        None
    };
    Ok((cert, direct))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iterations_follow_the_rate() {
        // rate 0.5, top mode 0.5: error from 1e-4 to 2e-10 (update 1e-10) is 19 halvings.
        assert_eq!(predicted_iterations(0.5, 0.5, 1e-10), Some(19.0));
        assert_eq!(predicted_iterations(1.0, 1.0, 1e-10), None);
        assert_eq!(predicted_iterations(0.0, 0.0, 1e-10), Some(1.0));
        assert_eq!(predicted_iterations(f64::NAN, 0.0, 1e-10), None);
    }

    #[test]
    fn a_rate_next_to_one_is_not_eligible_even_if_its_updates_are_tiny() {
        // The update test would stop at once (1 - top is tiny), with the error still large.
        let rate = 1.0 - 1e-15;
        assert_eq!(predicted_iterations(rate, rate, 1e-10), Some(1.0));
        let c = iterative_candidate(SolverKind::Split, rate, rate, 1e-3, 0.0, 1e-10, 2000);
        assert!(!c.eligible);
        assert!(certified(0.5, 2000) && certified(0.0, 1) && !certified(1.0, 2000));
    }

    #[test]
    fn chebyshev_parameters_are_optimal() {
        let (gamma, r, rate) = chebyshev_parameters(-0.5, 0.5);
        assert!((gamma - 1.0).abs() < 1e-15);
        assert!((r - 0.5).abs() < 1e-15);
        assert!(rate < r);
    }
}
