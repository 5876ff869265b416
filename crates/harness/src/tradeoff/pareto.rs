//! Pure functions on measured (cost, error) points: the Pareto front, the fastest point within a
//! target error, monotonicity along a knob, and the observed order of convergence in the time
//! step.

use serde::{Deserialize, Serialize};

/// A measured setting: its cost and its error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// Setting id.
    pub id: String,
    /// Cost (per simulated second, on the report's time axis).
    pub time: f64,
    /// Error.
    pub error: f64,
}

fn usable(p: &Point) -> bool {
    p.time.is_finite() && p.time >= 0.0 && p.error.is_finite() && p.error >= 0.0
}

/// Indices of the points no other point beats in both cost and error (ties broken by id), by
/// increasing cost and decreasing error.
pub fn front(points: &[Point]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..points.len()).filter(|&i| usable(&points[i])).collect();
    idx.sort_by(|&a, &b| {
        let (p, q) = (&points[a], &points[b]);
        p.time
            .total_cmp(&q.time)
            .then(p.error.total_cmp(&q.error))
            .then(p.id.cmp(&q.id))
    });
    let mut out = Vec::new();
    let mut best = f64::INFINITY;
    for i in idx {
        if points[i].error < best {
            best = points[i].error;
            out.push(i);
        }
    }
    out
}

/// The cheapest point whose error is at most `target` (it is on the front).
pub fn fastest_within(points: &[Point], target: f64) -> Option<usize> {
    (0..points.len())
        .filter(|&i| usable(&points[i]) && points[i].error <= target)
        .min_by(|&a, &b| {
            points[a]
                .time
                .total_cmp(&points[b].time)
                .then(points[a].error.total_cmp(&points[b].error))
                .then(points[a].id.cmp(&points[b].id))
        })
}

/// The most accurate point.
pub fn most_accurate(points: &[Point]) -> Option<usize> {
    (0..points.len())
        .filter(|&i| usable(&points[i]))
        .min_by(|&a, &b| points[a].error.total_cmp(&points[b].error))
}

/// The largest increase `e[i+1] - e[i]` along errors ordered by increasing effort (0 when the
/// sequence never increases).
pub fn worst_increase(errors: &[f64]) -> f64 {
    errors.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max)
}

/// The observed order `p` of a method from its errors `e1` at `h` and `e2` at `h/2`, both
/// measured against a reference at `h/r`: with `e(x) = C (x^p - (h/r)^p)`,
/// `e1/e2 = (1 - r^-p) / (2^-p - r^-p)`, solved by bisection on `p` in `[0.05, 8]`. `None`
/// outside that range or for non-positive errors.
pub fn observed_order(e1: f64, e2: f64, r: f64) -> Option<f64> {
    if !(e1 > 0.0 && e2 > 0.0 && r > 2.0 && e1.is_finite() && e2.is_finite()) {
        return None;
    }
    let ratio = e1 / e2;
    let f = |p: f64| (1.0 - r.powf(-p)) / (0.5f64.powf(p) - r.powf(-p));
    let (mut lo, mut hi) = (0.05, 8.0);
    if ratio < f(lo) || ratio > f(hi) {
        return None;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if f(mid) < ratio {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(id: &str, time: f64, error: f64) -> Point {
        Point {
            id: id.into(),
            time,
            error,
        }
    }

    #[test]
    fn front_keeps_only_non_dominated_points() {
        let pts = vec![
            p("a", 1.0, 1e-1),
            p("b", 2.0, 1e-2),
            p("c", 3.0, 5e-2),
            p("d", 4.0, 1e-4),
            p("e", 0.5, f64::NAN),
            p("f", 2.0, 1e-3),
        ];
        let f = front(&pts);
        let ids: Vec<&str> = f.iter().map(|&i| pts[i].id.as_str()).collect();
        assert_eq!(ids, ["a", "f", "d"]);
        assert_eq!(fastest_within(&pts, 1e-2).map(|i| pts[i].id.as_str()), Some("f"));
        assert_eq!(fastest_within(&pts, 1e-5), None);
        assert_eq!(most_accurate(&pts).map(|i| pts[i].id.as_str()), Some("d"));
    }

    #[test]
    fn worst_increase_finds_the_bump() {
        assert_eq!(worst_increase(&[3.0, 2.0, 1.0]), 0.0);
        assert_eq!(worst_increase(&[3.0, 2.0, 2.5, 1.0]), 0.5);
        assert_eq!(worst_increase(&[1.0]), 0.0);
    }

    #[test]
    fn observed_order_inverts_the_model() {
        for order in [0.5f64, 1.0, 2.0] {
            for r in [4.0f64, 16.0, 32.0] {
                let e = |x: f64| 3.0 * (x.powf(order) - (1.0 / r).powf(order));
                let got = observed_order(e(1.0), e(0.5), r).unwrap();
                assert!((got - order).abs() < 1e-9, "order {order} r {r}: {got}");
            }
        }
        assert_eq!(observed_order(1.0, 0.0, 16.0), None);
    }
}
