//! A small L-BFGS (Nocedal and Wright, Algorithm 7.4) with a backtracking Armijo line search,
//! for system identification with the gradients of this module.

use serde::Serialize;

/// One iteration of the optimizer.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Iterate {
    /// Iteration (0: the start).
    pub iteration: usize,
    /// Parameters (their own units; system identification: `ln(E / Pa)`, 1).
    pub x: Vec<f64>,
    /// Objective (its own unit; system identification: 1, squared residuals over the target's
    /// squared norm).
    pub f: f64,
    /// Largest gradient component (objective unit per parameter unit).
    pub gradient_norm: f64,
}

/// Result of [`lbfgs`].
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Minimum {
    /// Final parameters (as `history[].x`).
    pub x: Vec<f64>,
    /// Final objective (as `history[].f`).
    pub f: f64,
    /// Iterations taken.
    pub iterations: usize,
    /// Objective evaluations (each with its gradient).
    pub evaluations: usize,
    /// Whether a stopping test was met before the cap.
    pub converged: bool,
    /// Every accepted iterate.
    pub history: Vec<Iterate>,
}

/// Settings of [`lbfgs`].
#[derive(Debug, Clone, Copy)]
pub struct Lbfgs {
    /// Pairs kept.
    pub memory: usize,
    /// Iteration cap.
    pub max_iterations: usize,
    /// Stop when the largest gradient component is below this.
    pub gradient_tolerance: f64,
    /// Stop when the objective is below this.
    pub f_tolerance: f64,
}

impl Default for Lbfgs {
    fn default() -> Self {
        Self {
            memory: 6,
            max_iterations: 50,
            gradient_tolerance: 1e-10,
            f_tolerance: 0.0,
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Minimise `f` (returning value and gradient) from `x0`.
///
/// ```
/// use diffsoft::diff::optim::{lbfgs, Lbfgs};
///
/// // (x - 3)^2 + 10 (y + 1)^2
/// let f = |x: &[f64]| {
///     let value = (x[0] - 3.0).powi(2) + 10.0 * (x[1] + 1.0).powi(2);
///     Ok::<_, std::convert::Infallible>((value, vec![2.0 * (x[0] - 3.0), 20.0 * (x[1] + 1.0)]))
/// };
/// let min = lbfgs(Lbfgs::default(), vec![0.0, 0.0], f)?;
/// assert!(min.converged);
/// assert!((min.x[0] - 3.0).abs() < 1e-8 && (min.x[1] + 1.0).abs() < 1e-8);
/// assert_eq!(min.history.len(), min.iterations + 1);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn lbfgs<E>(
    settings: Lbfgs,
    x0: Vec<f64>,
    mut f: impl FnMut(&[f64]) -> Result<(f64, Vec<f64>), E>,
) -> Result<Minimum, E> {
    let mut x = x0;
    let (mut fx, mut g) = f(&x)?;
    let mut evals = 1;
    let amax = |g: &[f64]| g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut history = vec![Iterate {
        iteration: 0,
        x: x.clone(),
        f: fx,
        gradient_norm: amax(&g),
    }];
    let mut pairs: std::collections::VecDeque<(Vec<f64>, Vec<f64>, f64)> = Default::default();
    let mut converged = false;
    let mut it = 0;
    while it < settings.max_iterations {
        if amax(&g) <= settings.gradient_tolerance || fx <= settings.f_tolerance {
            converged = true;
            break;
        }
        // Two-loop recursion: d = -H g.
        let mut q = g.clone();
        let mut alphas = Vec::with_capacity(pairs.len());
        for (s, y, rho) in pairs.iter().rev() {
            let a = rho * dot(s, &q);
            q.iter_mut().zip(y).for_each(|(qi, yi)| *qi -= a * yi);
            alphas.push(a);
        }
        let gamma = pairs
            .back()
            .map_or(1.0 / amax(&g).max(f64::MIN_POSITIVE), |(s, y, _)| dot(s, y) / dot(y, y));
        q.iter_mut().for_each(|v| *v *= gamma);
        for ((s, y, rho), a) in pairs.iter().zip(alphas.iter().rev()) {
            let b = rho * dot(y, &q);
            q.iter_mut().zip(s).for_each(|(qi, si)| *qi += (a - b) * si);
        }
        let mut d: Vec<f64> = q.iter().map(|v| -v).collect();
        let mut slope = dot(&g, &d);
        if slope >= 0.0 {
            // Not a descent direction: restart from steepest descent.
            pairs.clear();
            d = g.iter().map(|v| -v / amax(&g).max(f64::MIN_POSITIVE)).collect();
            slope = dot(&g, &d);
        }
        // Backtracking Armijo line search from the unit step.
        let mut step = 1.0;
        let mut accepted = None;
        for _ in 0..40 {
            let xn: Vec<f64> = x.iter().zip(&d).map(|(xi, di)| xi + step * di).collect();
            match f(&xn) {
                Ok((fn_, gn)) => {
                    evals += 1;
                    if fn_.is_finite() && fn_ <= fx + 1e-4 * step * slope {
                        accepted = Some((xn, fn_, gn));
                        break;
                    }
                }
                Err(_) => evals += 1,
            }
            step *= 0.5;
        }
        let Some((xn, fn_, gn)) = accepted else {
            break;
        };
        let s: Vec<f64> = xn.iter().zip(&x).map(|(a, b)| a - b).collect();
        let y: Vec<f64> = gn.iter().zip(&g).map(|(a, b)| a - b).collect();
        let sy = dot(&s, &y);
        if sy > 1e-12 * dot(&y, &y).sqrt() * dot(&s, &s).sqrt() {
            pairs.push_back((s, y, 1.0 / sy));
            if pairs.len() > settings.memory {
                pairs.pop_front();
            }
        }
        x = xn;
        fx = fn_;
        g = gn;
        it += 1;
        history.push(Iterate {
            iteration: it,
            x: x.clone(),
            f: fx,
            gradient_norm: amax(&g),
        });
    }
    if amax(&g) <= settings.gradient_tolerance || fx <= settings.f_tolerance {
        converged = true;
    }
    Ok(Minimum {
        x,
        f: fx,
        iterations: it,
        evaluations: evals,
        converged,
        history,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rosenbrock from (-1.2, 1): the textbook L-BFGS test.
    #[test]
    fn minimises_rosenbrock() {
        let r = lbfgs(
            Lbfgs {
                max_iterations: 200,
                ..Default::default()
            },
            vec![-1.2, 1.0],
            |x| -> Result<_, ()> {
                let (a, b) = (x[0], x[1]);
                let f = (1.0 - a).powi(2) + 100.0 * (b - a * a).powi(2);
                let g = vec![-2.0 * (1.0 - a) - 400.0 * a * (b - a * a), 200.0 * (b - a * a)];
                Ok((f, g))
            },
        )
        .unwrap();
        assert!(
            r.converged && (r.x[0] - 1.0).abs() < 1e-6 && (r.x[1] - 1.0).abs() < 1e-6,
            "{r:?}"
        );
    }
}
