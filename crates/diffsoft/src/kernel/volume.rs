//! Volume constraint: the nearest deformation gradient whose singular values multiply to a
//! target `a` (1 for volume preservation; the pneumatic activation in Eq. 40).
//!
//! With `F = U diag(s) V^T`, the projection is `U diag(x) V^T` where
//! `x = argmin |x - s|^2 s.t. x1 x2 x3 = a`, `x > 0`. Stationarity gives
//! `x_i^2 - s_i x_i = t` for one multiplier `t`. Taking the component `k` with the smallest
//! `|s_k|` as the unknown, `t = x_k (x_k - s_k)` and every other component is the root
//! `x_j = (s_j + sqrt(s_j^2 + 4t)) / 2` (real because `s_j^2 >= s_k^2`), so the problem is one
//! equation `ln x_k + sum_j ln x_j(t(x_k)) = ln a` in `x_k > 0`. This covers both branches of
//! the stationarity condition in one interval (`x_k < s_k/2` is the branch where only the
//! smallest direction shrinks, reached for targets far below the current volume), stays
//! well conditioned at the fold between them, and keeps full relative precision in `x_k` for
//! tiny targets. It is solved by Newton's method in `ln x_k`, safeguarded by bisection on a
//! bracket, with the roots in cancellation-free form. For targets `a <= prod(s)/2` the branch
//! `x_k < s_k/2` can hold several stationary points (nearly isotropic `s` compressed strongly:
//! shrinking uniformly and collapsing the smallest direction are both local minima); unless a
//! bound shows the product monotone there, every root is found and the nearest kept. Inverted input (`s_3 < 0`) is projected
//! to the nearest point with all `x > 0`. Every failure is an explicit error, never a NaN.

use nalgebra::{Matrix3, Vector3};

use super::svd::{Svd3, LANES};
use super::ProjectionError;

/// `(s + sqrt(s^2 + 4t)) / 2` without cancellation.
#[inline]
fn root_plus(s: f64, t: f64) -> f64 {
    let d = (s * s + 4.0 * t).max(0.0).sqrt();
    if s >= 0.0 {
        0.5 * (s + d)
    } else {
        // (s + d)/2 = 2t / (d - s)
        2.0 * t / (d - s)
    }
}

/// Safeguarded Newton for a root of `h` on a bracket `[ya, yb]` (either order) whose ends have
/// opposite signs of `h` (`ha` is the sign at `ya`), from `y`: Newton steps that stay inside the
/// shrinking bracket, bisection otherwise. `eval(y) = (h, dh/dy, x)`; returns the `x` at the root.
fn bracketed_newton(
    eval: impl Fn(f64) -> (f64, f64, Vector3<f64>),
    (mut ya, mut ha): (f64, f64),
    mut yb: f64,
    mut y: f64,
) -> Option<Vector3<f64>> {
    for _ in 0..400 {
        let (h, dh, x) = eval(y);
        if h.abs() <= 2.0 * f64::EPSILON || (yb - ya).abs() <= 2.0 * f64::EPSILON * y.abs().max(1.0) {
            return Some(x);
        }
        if (h > 0.0) == (ha > 0.0) {
            ya = y;
            ha = h;
        } else {
            yb = y;
        }
        let newton = y - h / dh;
        let (lo, hi) = (ya.min(yb), ya.max(yb));
        y = if newton.is_finite() && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (ya + yb)
        };
    }
    None
}

/// Raise `hi` in steps of 2 while `h(hi) <= 0` (at most 400 steps).
fn raise_until_positive(h: impl Fn(f64) -> f64, mut hi: f64) -> Result<f64, ProjectionError> {
    for _ in 0..=400 {
        let v = h(hi);
        // A NaN stops the search too (as a positive value would); the caller's Newton then
        // reports it.
        if v > 0.0 || v.is_nan() {
            return Ok(hi);
        }
        hi += 2.0;
    }
    Err(ProjectionError::NoConvergence)
}

/// Nearest `x` (Euclidean) to `s` with `x1 x2 x3 = a` and `x > 0`.
pub fn nearest_product(s: &Vector3<f64>, a: f64) -> Result<Vector3<f64>, ProjectionError> {
    if !(a.is_finite() && a > 0.0) {
        return Err(ProjectionError::BadTarget(a));
    }
    if !s.iter().all(|v| v.is_finite()) {
        return Err(ProjectionError::NonFinite);
    }
    if s.iter().any(|&v| v <= 0.0) {
        return solve_in_t(s, a);
    }
    let k = (0..3).min_by(|&i, &j| s[i].abs().total_cmp(&s[j].abs())).unwrap_or(0);
    let others = [(k + 1) % 3, (k + 2) % 3];
    if a <= 0.5 * s.product() && !collapse_branch_is_monotone(s, k, others) {
        return nearest_of_all_roots(s, a, k, others);
    }
    if let Some(x) = newton_from_s(s, a, k, others) {
        return Ok(x);
    }
    let ln_a = a.ln();
    // x_k -> (h, dh/d ln x_k, x) with h = ln prod x - ln a.
    let eval = |xk: f64| -> (f64, f64, Vector3<f64>) {
        let t = xk * (xk - s[k]);
        let dt = 2.0 * xk - s[k];
        let mut x = Vector3::zeros();
        x[k] = xk;
        let mut h = xk.ln() - ln_a;
        let mut dh = 1.0 / xk;
        for &j in &others {
            let d = (s[j] * s[j] + 4.0 * t).max(0.0).sqrt();
            let xj = root_plus(s[j], t);
            x[j] = xj;
            h += xj.ln();
            dh += dt / (d.max(f64::MIN_POSITIVE) * xj);
        }
        (h, dh * xk, x)
    };
    // Lower end of the domain: every x_j > 0 needs t > 0 when some other s_j <= 0.
    let lo = if others.iter().any(|&j| s[j] <= 0.0) {
        s[k].max(0.0)
    } else {
        0.0
    };
    let y_lo = lo.max(f64::MIN_POSITIVE).ln();
    let y_hi = raise_until_positive(|y| eval(y.exp()).0, s.amax().max(a.cbrt()).max(1.0).ln() + 1.0)?;
    // Start from x = s when s is feasible (a solution near the identity converges in 2 steps).
    let y = if s[k] > lo && s[k].ln() < y_hi {
        s[k].ln()
    } else {
        0.5 * (y_lo + y_hi)
    };
    bracketed_newton(|y| eval(y.exp()), (y_lo, -1.0), y_hi, y).ok_or(ProjectionError::NoConvergence)
}

/// `h(x_k) = ln x_k + sum_j ln x_j(t(x_k)) - ln a` with `d h / d ln x_k`, and `x`.
fn eval_k(s: &Vector3<f64>, k: usize, others: [usize; 2], ln_a: f64, xk: f64) -> (f64, f64, Vector3<f64>) {
    let t = xk * (xk - s[k]);
    let dt = 2.0 * xk - s[k];
    let mut x = Vector3::zeros();
    x[k] = xk;
    let mut h = xk.ln() - ln_a;
    let mut dh = 1.0 / xk;
    for &j in &others {
        let d = (s[j] * s[j] + 4.0 * t).max(0.0).sqrt();
        let xj = root_plus(s[j], t);
        x[j] = xj;
        h += xj.ln();
        dh += dt / (d.max(f64::MIN_POSITIVE) * xj);
    }
    (h, dh * xk, x)
}

/// Whether the product `p(x_k)` certainly increases on the collapse branch `x_k < s_k/2` (all
/// `s > 0`, `s_k` the smallest), so that `h` has a single root: there
/// `d ln p / d x_k = (1 - phi) / x_k` with `phi = x_k (s_k - 2 x_k) sum_j 1/(d_j x_j)`, and
/// `x_k (s_k - 2 x_k) <= s_k^2/8`, `d_j >= sqrt(s_j^2 - s_k^2)`, `x_j >= s_j/2` bound `phi` below 1.
fn collapse_branch_is_monotone(s: &Vector3<f64>, k: usize, others: [usize; 2]) -> bool {
    let sum: f64 = others
        .iter()
        .map(|&j| {
            let g = (s[j] - s[k]) * (s[j] + s[k]);
            if g > 0.0 {
                2.0 / (s[j] * g.sqrt())
            } else {
                f64::INFINITY
            }
        })
        .sum();
    sum * s[k] * s[k] / 8.0 < 1.0
}

/// Samples of `x_k` on the collapse branch `(0, s_k/2]` scanned for roots of `h`.
const COLLAPSE_SAMPLES: usize = 64;

/// All `s > 0` and `a <= prod(s)/2`. The product `p(x_k)` is increasing for `x_k >= s_k/2`
/// (at most one root there), but on the collapse branch `x_k < s_k/2` it need not be monotone:
/// for nearly isotropic `s` compressed strongly, "shrink uniformly" and "collapse the smallest
/// direction" are both local minima, and a single bracketed solve may return the wrong one (or a
/// saddle). On that branch `p <= (s_k/2) s_i s_j = prod(s)/2`, so larger targets never get here,
/// nor do spectra whose collapse branch is monotone ([`collapse_branch_is_monotone`]).
/// Every root is found (a scan of `h` on the branch, each sign change refined by safeguarded
/// Newton, plus the root beyond the fold) and the nearest is kept.
fn nearest_of_all_roots(
    s: &Vector3<f64>,
    a: f64,
    k: usize,
    others: [usize; 2],
) -> Result<Vector3<f64>, ProjectionError> {
    let ln_a = a.ln();
    let eval = |y: f64| eval_k(s, k, others, ln_a, y.exp());
    let refine = |(ya, ha): (f64, f64), yb: f64| bracketed_newton(eval, (ya, ha), yb, 0.5 * (ya + yb));
    let mut roots = Vec::new();
    let fold = 0.5 * s[k];
    // h -> -inf as x_k -> 0 (the other components stay near s_j).
    let (mut y_prev, mut h_prev) = (f64::MIN_POSITIVE.ln(), f64::NEG_INFINITY);
    for i in 1..=COLLAPSE_SAMPLES {
        let y = (fold * i as f64 / COLLAPSE_SAMPLES as f64).ln();
        let h = eval(y).0;
        if h == 0.0 {
            roots.push(eval(y).2);
        } else if h_prev != 0.0 && (h > 0.0) != (h_prev > 0.0) {
            roots.extend(refine((y_prev, h_prev), y));
        }
        (y_prev, h_prev) = (y, h);
    }
    // Beyond the fold h increases: one root iff h(fold) < 0.
    if h_prev < 0.0 {
        let y_hi = raise_until_positive(|y| eval(y).0, s.amax().max(a.cbrt()).max(1.0).ln() + 1.0)?;
        roots.extend(refine((y_prev, h_prev), y_hi));
    }
    roots
        .into_iter()
        .filter(|x| x.iter().all(|v| v.is_finite() && *v > 0.0))
        .min_by(|x, y| (x - s).norm_squared().total_cmp(&(y - s).norm_squared()))
        .ok_or(ProjectionError::NoConvergence)
}

/// Some `s_i <= 0` (inverted or flat `F`): the multiplier `t > 0` is the unknown. Every
/// component is the `+` root, cancellation-free in `t`, and `ln prod x(t)` increases from
/// `-inf` (at `t = 0+` a component vanishes) to `+inf`: Newton in `ln t` on a bracket.
fn solve_in_t(s: &Vector3<f64>, a: f64) -> Result<Vector3<f64>, ProjectionError> {
    let ln_a = a.ln();
    let eval = |t: f64| -> (f64, f64, Vector3<f64>) {
        let mut x = Vector3::zeros();
        let (mut h, mut dh) = (-ln_a, 0.0);
        for i in 0..3 {
            let d = (s[i] * s[i] + 4.0 * t).sqrt();
            x[i] = root_plus(s[i], t);
            h += x[i].ln();
            dh += t / (d * x[i]);
        }
        (h, dh, x)
    };
    let scale = s.amax().max(a.cbrt()).max(f64::MIN_POSITIVE);
    let v_lo = (f64::MIN_POSITIVE * scale * scale).ln();
    let v_hi = raise_until_positive(|v| eval(v.exp()).0, (scale * scale).ln() + 1.0)?;
    bracketed_newton(|v| eval(v.exp()), (v_lo, -1.0), v_hi, 0.5 * (v_lo + v_hi)).ok_or(ProjectionError::NoConvergence)
}

/// Fast path: Newton on `prod x(x_k) = a` in product form, started at `x_k = s_k` (the answer
/// when `s` already meets the target). Accepted only if it converges to `4 eps` relative within
/// 8 steps without leaving the domain where `x_k >= s_k / 2` (the branch where the product is
/// increasing); anything else goes to the bracketed solver.
#[inline]
fn newton_from_s(s: &Vector3<f64>, a: f64, k: usize, others: [usize; 2]) -> Option<Vector3<f64>> {
    if others.iter().any(|&j| s[j] <= 0.0) || s[k] <= 0.0 {
        return None;
    }
    let mut xk = s[k];
    for _ in 0..8 {
        let t = xk * (xk - s[k]);
        let dt = 2.0 * xk - s[k];
        let (j1, j2) = (others[0], others[1]);
        let d1 = (s[j1] * s[j1] + 4.0 * t).sqrt();
        let d2 = (s[j2] * s[j2] + 4.0 * t).sqrt();
        let x1 = 0.5 * (s[j1] + d1);
        let x2 = 0.5 * (s[j2] + d2);
        let p = xk * x1 * x2;
        let r = p / a - 1.0;
        if r.abs() <= 4.0 * f64::EPSILON {
            let mut x = Vector3::zeros();
            x[k] = xk;
            x[j1] = x1;
            x[j2] = x2;
            return Some(x);
        }
        // d ln p / d x_k
        let dlp = 1.0 / xk + dt / (d1 * x1) + dt / (d2 * x2);
        let next = xk - (1.0 - a / p) / dlp;
        if !(next.is_finite() && next >= 0.5 * s[k]) {
            return None;
        }
        xk = next;
    }
    None
}

/// [`nearest_product`] for `LANES` singular-value triples at once: the product-form Newton
/// runs lane-parallel (vectorised, AVX2 when available); a lane that leaves the fast path's
/// domain or does not converge in 8 steps is solved by the robust scalar solver. Results agree
/// with the one-triple version to round-off.
pub fn nearest_product_batch(s: &[Vector3<f64>; LANES], a: f64) -> Result<[Vector3<f64>; LANES], ProjectionError> {
    let mut t = [0.0; LANES];
    nearest_product_batch_warm(s, a, &mut t)
}

/// [`nearest_product_batch`] warm-started from the multipliers `t` (`x_i (x_i - s_i) = t` for
/// every `i`, so one scalar per triple, independent of the ordering) of a nearby earlier
/// solve, e.g. the same tet in the previous local step; `t` is overwritten with the new
/// multipliers. A start outside the fast path's domain falls back to the cold start `x = s`.
/// The result does not depend on the start beyond round-off: Newton runs to `4 eps` relative.
pub fn nearest_product_batch_warm(
    s: &[Vector3<f64>; LANES],
    a: f64,
    t: &mut [f64; LANES],
) -> Result<[Vector3<f64>; LANES], ProjectionError> {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { batch_avx2(s, a, t) };
        }
    }
    batch_generic(s, a, t)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn batch_avx2(
    s: &[Vector3<f64>; LANES],
    a: f64,
    t: &mut [f64; LANES],
) -> Result<[Vector3<f64>; LANES], ProjectionError> {
    batch_generic(s, a, t)
}

#[inline(always)]
#[allow(clippy::needless_range_loop)] // lane loops over parallel arrays
pub(crate) fn batch_generic(
    s: &[Vector3<f64>; LANES],
    a: f64,
    t_warm: &mut [f64; LANES],
) -> Result<[Vector3<f64>; LANES], ProjectionError> {
    if !(a.is_finite() && a > 0.0) {
        return Err(ProjectionError::BadTarget(a));
    }
    // Lane-wise: the smallest-magnitude component is the unknown (sorted so it is s0 here).
    let mut sk = [0.0f64; LANES];
    let mut s1 = [0.0f64; LANES];
    let mut s2 = [0.0f64; LANES];
    let mut perm = [[0usize; 3]; LANES];
    let mut ok = [true; LANES];
    let mut xk = [0.0f64; LANES];
    for l in 0..LANES {
        let v = &s[l];
        let k = if v[0].abs() <= v[1].abs() && v[0].abs() <= v[2].abs() {
            0
        } else if v[1].abs() <= v[2].abs() {
            1
        } else {
            2
        };
        perm[l] = [k, (k + 1) % 3, (k + 2) % 3];
        sk[l] = v[k];
        s1[l] = v[perm[l][1]];
        s2[l] = v[perm[l][2]];
        // Targets at most half the current product may have several stationary points on the
        // collapse branch unless it is monotone: those lanes go to the scalar solver, which
        // compares them.
        ok[l] = v.iter().all(|x| x.is_finite())
            && sk[l] > 0.0
            && s1[l] > 0.0
            && s2[l] > 0.0
            && (a > 0.5 * sk[l] * s1[l] * s2[l]
                || collapse_branch_is_monotone(v, perm[l][0], [perm[l][1], perm[l][2]]));
        // Warm start x_k = root of x (x - s_k) = t, if it lies in the fast path's domain.
        let disc = sk[l] * sk[l] + 4.0 * t_warm[l];
        let warm = 0.5 * (sk[l] + disc.max(0.0).sqrt());
        xk[l] = if t_warm[l].is_finite() && disc > 0.0 && warm >= 0.5 * sk[l] {
            warm
        } else {
            sk[l]
        };
    }
    let mut x1 = s1;
    let mut x2 = s2;
    // A lane is active until its residual is at round-off (done) or it leaves the domain (!ok).
    let mut active = ok;
    let mut done = [false; LANES];
    for _ in 0..8 {
        for l in 0..LANES {
            let t = xk[l] * (xk[l] - sk[l]);
            let dt = 2.0 * xk[l] - sk[l];
            let d1 = (s1[l] * s1[l] + 4.0 * t).max(0.0).sqrt();
            let d2 = (s2[l] * s2[l] + 4.0 * t).max(0.0).sqrt();
            x1[l] = 0.5 * (s1[l] + d1);
            x2[l] = 0.5 * (s2[l] + d2);
            let p = xk[l] * x1[l] * x2[l];
            let converged = (p / a - 1.0).abs() <= 4.0 * f64::EPSILON;
            let dlp = 1.0 / xk[l] + dt / (d1 * x1[l]) + dt / (d2 * x2[l]);
            let next = xk[l] - (1.0 - a / p) / dlp;
            let valid = next.is_finite() && next >= 0.5 * sk[l];
            let step = active[l] && !converged;
            done[l] |= active[l] && converged;
            ok[l] &= !step || valid;
            xk[l] = if step && valid { next } else { xk[l] };
            active[l] = step && valid;
        }
        if !active.iter().any(|&x| x) {
            break;
        }
    }
    let mut out = [Vector3::zeros(); LANES];
    for l in 0..LANES {
        if ok[l] && done[l] {
            let [k, j1, j2] = perm[l];
            out[l][k] = xk[l];
            out[l][j1] = x1[l];
            out[l][j2] = x2[l];
            t_warm[l] = xk[l] * (xk[l] - sk[l]);
        } else {
            out[l] = nearest_product(&s[l], a)?;
            t_warm[l] = out[l][0] * (out[l][0] - s[l][0]);
        }
    }
    Ok(out)
}

/// Volume projection of a decomposed `F`: `U diag(x) V^T` with `prod x = a`.
pub fn project(svd: &Svd3, a: f64) -> Result<Matrix3<f64>, ProjectionError> {
    Ok(svd.compose(&nearest_product(&svd.sigma, a)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_kkt(s: Vector3<f64>, a: f64) {
        let x = nearest_product(&s, a).unwrap();
        assert!(x.iter().all(|&v| v > 0.0), "{s} -> {x}");
        assert!((x.product() / a - 1.0).abs() < 1e-12, "product {} vs {a}", x.product());
        // No nearby point on the constraint surface is closer (KKT + second-order check).
        let d0 = (x - s).norm();
        for i in 0..3 {
            for j in 0..3 {
                if i != j {
                    for e in [1e-4, -1e-4] {
                        let mut y = x;
                        y[i] *= 1.0 + e;
                        y[j] /= 1.0 + e;
                        assert!((y - s).norm() >= d0 - 1e-12 * (1.0 + d0), "{s} a={a}: {x} not nearest");
                    }
                }
            }
        }
    }

    #[test]
    fn identity_is_fixed_and_targets_are_met() {
        let x = nearest_product(&Vector3::new(1.0, 1.0, 1.0), 1.0).unwrap();
        assert!((x - Vector3::repeat(1.0)).norm() < 1e-15);
        for s in [
            Vector3::new(1.0, 1.0, 1.0),
            Vector3::new(2.0, 1.0, 0.5),
            Vector3::new(1.3, 0.9, -0.2),
            Vector3::new(1e4, 1.0, 1e-4),
            Vector3::new(3.0, 2.0, 1.0),
        ] {
            for a in [1e-6, 0.5, 1.0, 2.0] {
                assert_kkt(s, a);
            }
        }
    }

    #[test]
    fn small_targets_shrink_only_the_smallest_direction() {
        let x = nearest_product(&Vector3::new(1.0, 1.0, 1.0), 1e-6).unwrap();
        let mut v: Vec<f64> = x.iter().copied().collect();
        v.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert!(v[0] < 1e-5 && v[1] > 0.99, "{x}");
    }

    #[test]
    fn bad_input_is_an_error() {
        assert_eq!(
            nearest_product(&Vector3::repeat(1.0), 0.0),
            Err(ProjectionError::BadTarget(0.0))
        );
        assert!(nearest_product(&Vector3::repeat(1.0), f64::NAN).is_err());
        assert_eq!(
            nearest_product(&Vector3::new(1.0, f64::NAN, 1.0), 1.0),
            Err(ProjectionError::NonFinite)
        );
    }
}
