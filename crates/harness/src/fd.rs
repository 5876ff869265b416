//! Finite-difference machinery for derivative checks (docs/method.md section 7): central differences
//! over a sweep of step sizes (the V-shaped error curve, its minimum, the truncation slope and a
//! Richardson estimate) and comparisons under `|a - r| <= atol + rtol |r|` that name the worst
//! entry with both values.

use serde::Serialize;

/// An analytic derivative compared with a reference.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Comparison {
    /// Absolute tolerance (the unit of the compared entries).
    pub atol: f64,
    /// Relative tolerance (1).
    pub rtol: f64,
    /// `max |a - r|` (the unit of the compared entries).
    pub max_abs_error: f64,
    /// `max |a - r| / max(|r|, tiny)` (1).
    pub max_rel_error: f64,
    /// Entry with the largest `|a - r| - (atol + rtol |r|)`.
    pub worst_index: usize,
    /// Analytic value there (the unit of the compared entries).
    pub analytic_at_worst: f64,
    /// Reference value there (the unit of the compared entries).
    pub reference_at_worst: f64,
    /// Every entry within `atol + rtol |r|`.
    pub pass: bool,
}

/// Compare `analytic` with `reference` entry by entry.
pub fn compare(analytic: &[f64], reference: &[f64], atol: f64, rtol: f64) -> Comparison {
    assert_eq!(analytic.len(), reference.len(), "compared vectors differ in length");
    let mut c = Comparison {
        atol,
        rtol,
        max_abs_error: 0.0,
        max_rel_error: 0.0,
        worst_index: 0,
        analytic_at_worst: analytic.first().copied().unwrap_or(0.0),
        reference_at_worst: reference.first().copied().unwrap_or(0.0),
        pass: true,
    };
    let mut worst_margin = f64::NEG_INFINITY;
    for (i, (&a, &r)) in analytic.iter().zip(reference).enumerate() {
        let e = (a - r).abs();
        let bound = atol + rtol * r.abs();
        c.max_abs_error = c.max_abs_error.max(e);
        c.max_rel_error = c.max_rel_error.max(e / r.abs().max(1e-300));
        let margin = if e.is_nan() { f64::INFINITY } else { e - bound };
        if margin > worst_margin {
            worst_margin = margin;
            c.worst_index = i;
            c.analytic_at_worst = a;
            c.reference_at_worst = r;
        }
        c.pass &= e <= bound;
    }
    c
}

/// Central differences over a sweep of step sizes.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct StepSweep {
    /// Steps (absolute, in the unit of the varied coordinate: `scale x 10^-k`).
    pub steps: Vec<f64>,
    /// Largest absolute error against the analytic derivative at each step (the derivative's unit).
    pub errors: Vec<f64>,
    /// Step with the smallest error (the unit of `steps`).
    pub best_step: f64,
    /// That error (the derivative's unit).
    pub best_error: f64,
    /// Log-log slope of the error on the large-step side (1; 2 for central differences; `null` in
    /// JSON when the function is linear in the increment, so every step is exact to round-off).
    pub truncation_slope: f64,
    /// Error of the Richardson extrapolation `(4 D(h/2) - D(h)) / 3` at the best step (the
    /// derivative's unit).
    pub richardson_error: f64,
    /// `max |D|` of the central difference at the best step (the derivative's unit; the scale of
    /// the errors).
    pub max_abs_difference: f64,
    /// The central difference at the best step (not written to reports).
    #[serde(skip)]
    pub best_difference: Vec<f64>,
}

fn slope(xs: &[f64], ys: &[f64]) -> f64 {
    let n = xs.len() as f64;
    if xs.len() < 2 {
        return f64::NAN;
    }
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let sxy: f64 = xs.iter().zip(ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// Sweep central differences `(f(h) - f(-h)) / 2h` of a vector function of one increment over
/// `h = scale x 10^-k`, `k = 1..=decades`, against `analytic`.
pub fn sweep(f: &dyn Fn(f64) -> Vec<f64>, analytic: &[f64], scale: f64, decades: u32) -> StepSweep {
    let central = |h: f64| -> Vec<f64> {
        let (p, m) = (f(h), f(-h));
        p.iter().zip(&m).map(|(a, b)| (a - b) / (2.0 * h)).collect()
    };
    let mut steps = Vec::new();
    let mut errors = Vec::new();
    let mut diffs = Vec::new();
    for k in 1..=decades {
        let h = scale * 10f64.powi(-(k as i32));
        let d = central(h);
        errors.push(max_abs_diff(&d, analytic));
        steps.push(h);
        diffs.push(d);
    }
    let best = (0..steps.len())
        .min_by(|&i, &j| errors[i].total_cmp(&errors[j]))
        .unwrap_or(0);
    // Truncation side: steps larger than the best one, where the error is still well above
    // round-off (at least 100x the best error).
    let floor = errors[best] * 100.0;
    let (lx, ly): (Vec<f64>, Vec<f64>) = (0..best)
        .filter(|&i| errors[i] > floor)
        .map(|i| (steps[i].ln(), errors[i].ln()))
        .unzip();
    let h = steps[best];
    let d1 = &diffs[best];
    let d2 = central(h / 2.0);
    let rich: Vec<f64> = d1.iter().zip(&d2).map(|(a, b)| (4.0 * b - a) / 3.0).collect();
    StepSweep {
        best_step: h,
        best_error: errors[best],
        truncation_slope: slope(&lx, &ly),
        richardson_error: max_abs_diff(&rich, analytic),
        max_abs_difference: diffs[best].iter().fold(0.0, |m: f64, x| m.max(x.abs())),
        best_difference: diffs[best].clone(),
        steps,
        errors,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sweep_of_a_known_function_has_slope_two_and_a_v_shape() {
        // d/dx [sin x, x^3] at x = 0.7.
        let x0 = 0.7f64;
        let f = |h: f64| vec![(x0 + h).sin(), (x0 + h).powi(3)];
        let exact = [x0.cos(), 3.0 * x0 * x0];
        let s = sweep(&f, &exact, 1.0, 10);
        assert!((s.truncation_slope - 2.0).abs() < 0.2, "slope {}", s.truncation_slope);
        assert!(s.best_error < 1e-9 && s.best_step < 1e-3 && s.best_step > 1e-8);
        assert!(
            s.errors[0] > 100.0 * s.best_error && s.errors[9] > 10.0 * s.best_error,
            "V shape {:?}",
            s.errors
        );
        // A wrong derivative plateaus and fails the comparison, naming the entry.
        let c = compare(&[x0.cos(), 3.0 * x0 * x0 * 1.01], &s.best_difference, 1e-8, 1e-6);
        assert!(!c.pass && c.worst_index == 1);
    }
}
