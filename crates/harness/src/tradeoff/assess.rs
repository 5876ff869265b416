//! What the measured rows say: the cost of a row on the report's time axis, the Pareto fronts,
//! the setting per target error, the observed order of convergence in `dt`, and the verdicts on
//! what theory predicts (errors monotone in each knob, first order for implicit Euler, second for
//! BDF2).

use diffsoft::base::Choice;
use std::fmt::Write as _;

use super::pareto::{self, Point};
use super::report::{Fronts, GradientReference, ObservedOrder, Pick, Recommendation, Reference, Row, Status};
use super::{Family, Knob, TimeAxis, TradeoffSpec};
use crate::report::Verdict;
use diffsoft::solver::Integrator;

fn sim_seconds(spec: &TradeoffSpec, scene: f64) -> f64 {
    spec.steps as f64 * scene
}

/// The forward cost of a row per simulated second on the spec's axis.
pub(super) fn forward_cost(spec: &TradeoffSpec, r: &Row) -> Option<f64> {
    let sim = sim_seconds(spec, r.dt * r.setting.dt_divisor as f64);
    match spec.time_axis {
        TimeAxis::Cpu => r.timing.map(|t| t.cpu_s_per_sim_s.unwrap_or(t.wall_s_per_sim_s)),
        TimeAxis::Iterations => r.work.map(|w| w.iterations as f64 / sim),
    }
}

/// Forward + backward cost of a row's gradient per simulated second.
pub(super) fn gradient_cost(spec: &TradeoffSpec, r: &Row) -> Option<f64> {
    let sim = sim_seconds(spec, r.dt * r.setting.dt_divisor as f64);
    match spec.time_axis {
        TimeAxis::Cpu => r.gradient.cpu_s.or(r.gradient.wall_s).map(|t| t / sim),
        TimeAxis::Iterations => r.work.map(|w| w.iterations as f64 / sim),
    }
}

fn pick(points: &[Point], i: usize) -> Pick {
    Pick {
        id: points[i].id.clone(),
        time: points[i].time,
        error: points[i].error,
    }
}

/// What a row computed, for telling rows that did identical work apart from the rest: its time
/// step, integrator, iteration counts and every trajectory error bit for bit (and, for a
/// gradient's cost, its gradient values). Rows with equal keys ran the same iterations to the
/// same states: Anderson mixing that never engaged because every step converged in its first
/// iteration, say.
fn same_work_key(r: &Row, gradient: bool) -> Option<Vec<u64>> {
    let w = r.work?;
    let t = r.trajectory?;
    let mut key = vec![
        r.setting.dt_divisor as u64,
        r.setting.integrator as u64,
        w.steps as u64,
        w.iterations as u64,
        w.global_iterations as u64,
        w.unconverged_steps as u64,
    ];
    key.extend([t.max_vertex_error, t.rms_vertex_error, t.com_error, t.energy_drift].map(f64::to_bits));
    if gradient {
        key.extend(r.gradient.values.as_ref()?.iter().map(|v| v.to_bits()));
    }
    Some(key)
}

/// One point per distinct computation among the rows `keep` selects: rows that did identical
/// work ([`same_work_key`]) differ in measured cost by timing noise alone (about 1.2x in the
/// median between two concurrent workers), so they form one point, named by the group's first
/// row in the grid's order (the spec's family order, simplest first) and costed at the group's
/// smallest measurement. Without this, which of two identical computations a front or a
/// recommendation named flipped from run to run.
fn distinct_points(
    rows: &[Row],
    keep: impl Fn(&Row) -> bool,
    cost: impl Fn(&Row) -> Option<f64>,
    error: impl Fn(&Row) -> Option<f64>,
    gradient: bool,
) -> Vec<Point> {
    let mut out: Vec<Point> = Vec::new();
    let mut group = std::collections::HashMap::new();
    for r in rows.iter().filter(|r| r.status == Status::Ran && keep(r)) {
        let (Some(time), Some(error)) = (cost(r), error(r)) else {
            continue;
        };
        let key = same_work_key(r, gradient);
        if let Some(&i) = key.as_ref().and_then(|k| group.get(k)) {
            let p: &mut Point = &mut out[i];
            p.time = p.time.min(time);
            continue;
        }
        if let Some(k) = key {
            group.insert(k, out.len());
        }
        out.push(Point {
            id: r.id.clone(),
            time,
            error,
        });
    }
    out
}

pub(super) fn fronts(
    spec: &TradeoffSpec,
    rows: &[Row],
    grefs: &[GradientReference],
) -> (Fronts, Vec<Point>, Vec<Point>) {
    let all = |_: &Row| true;
    let forward = |r: &Row| forward_cost(spec, r);
    let backward = |r: &Row| gradient_cost(spec, r);
    let points = distinct_points(rows, all, forward, |r| Some(r.trajectory?.max_relative), false);
    let gpoints = distinct_points(rows, all, backward, |r| r.gradient.error, true);
    let solver_points = distinct_points(rows, all, forward, |r| Some(r.trajectory?.solver_max_relative), false);
    let gsolver_points = distinct_points(rows, all, backward, |r| r.gradient.solver_error, true);
    let gradient_note = if gpoints.is_empty() {
        Some(if spec.gradient_dt_divisors.is_empty() {
            "no gradients requested for this scene (gradient_dt_divisors is empty)".to_string()
        } else if let Some(m) = grefs
            .iter()
            .find(|g| g.dt_divisor == spec.reference_divisor && g.integrator == spec.reference_integrator)
            .and_then(|g| g.gradient.message.clone())
        {
            format!("no reference gradient: {m}")
        } else {
            rows.iter()
                .find_map(|r| r.gradient.message.clone())
                .unwrap_or_else(|| "no setting produced a gradient".into())
        })
    } else {
        None
    };
    let time_meaning = match spec.time_axis {
        TimeAxis::Cpu => {
            "thread CPU seconds per simulated second, one thread (wall time where CPU time is unavailable); rows that did identical work (the same iterations, bit-identical errors) are one point, named by the first in the grid's order, at their smallest cost"
        }
        TimeAxis::Iterations => "local-global iterations per simulated second (deterministic); rows that did identical work are one point, named by the first in the grid's order",
    };
    let f = Fronts {
        time_axis: spec.time_axis,
        time_meaning: time_meaning.into(),
        trajectory: pareto::front(&points).into_iter().map(|i| pick(&points, i)).collect(),
        trajectory_solver: pareto::front(&solver_points)
            .into_iter()
            .map(|i| pick(&solver_points, i))
            .collect(),
        gradient: pareto::front(&gpoints).into_iter().map(|i| pick(&gpoints, i)).collect(),
        gradient_solver: pareto::front(&gsolver_points)
            .into_iter()
            .map(|i| pick(&gsolver_points, i))
            .collect(),
        gradient_note,
    };
    (f, points, gpoints)
}

/// Rows of `family` and `integrator` with knob `Tolerance(t)` for the smallest tolerance of the
/// grid, by increasing divisor, that ran.
fn tightest(spec: &TradeoffSpec, rows: &[Row], family: Family, integrator: Integrator) -> Vec<Row> {
    let Some(t) = spec.tolerances.iter().copied().reduce(f64::min) else {
        return Vec::new();
    };
    let mut v: Vec<Row> = rows
        .iter()
        .filter(|r| {
            r.setting.family == family
                && r.setting.integrator == integrator
                && r.setting.knob == Knob::Tolerance(t)
                && r.status == Status::Ran
        })
        .cloned()
        .collect();
    v.sort_by_key(|r| r.setting.dt_divisor);
    v
}

/// BDF2's observed order between h/2 and h/4 that counts as second order.
const BDF2_MIN_ORDER: f64 = 1.6;

/// Whether an observed order is first order (within 0.25).
fn first_order(p: f64) -> bool {
    (p - 1.0).abs() <= 0.25
}

/// The observed order of the direct solver at the tightest tolerance for every integrator and
/// pair of grid steps `h/d, h/2d` (per integrator the finest pair last, the one nearest the
/// asymptotic regime).
pub(super) fn observed_orders(spec: &TradeoffSpec, rows: &[Row]) -> Vec<ObservedOrder> {
    let mut out = Vec::new();
    for &integrator in &spec.integrators {
        out.extend(orders_of(spec, rows, integrator));
    }
    out
}

fn orders_of(spec: &TradeoffSpec, rows: &[Row], integrator: Integrator) -> Vec<ObservedOrder> {
    let t = tightest(spec, rows, Family::Direct, integrator);
    let mut out = Vec::new();
    for a in &t {
        let d = a.setting.dt_divisor;
        let Some(b) = t.iter().find(|r| r.setting.dt_divisor == 2 * d) else {
            continue;
        };
        let (Some(ea), Some(eb)) = (a.trajectory, b.trajectory) else {
            continue;
        };
        // The reference's own error follows the model only when it is of the same scheme; a
        // reference of another (higher-order) scheme is taken as exact.
        let r = if integrator == spec.reference_integrator {
            spec.reference_divisor as f64 / d as f64
        } else {
            f64::INFINITY
        };
        out.push(ObservedOrder {
            integrator,
            coarse: a.id.clone(),
            fine: b.id.clone(),
            coarse_error: ea.max_relative,
            fine_error: eb.max_relative,
            order: pareto::observed_order(ea.max_relative, eb.max_relative, r),
        });
    }
    out
}

/// Implicit Euler's finest observed order and its most accurate tight row (for extrapolation).
pub(super) fn finest_order(spec: &TradeoffSpec, rows: &[Row], orders: &[ObservedOrder]) -> Option<(f64, Row)> {
    let ie = Integrator::ImplicitEuler;
    let p = orders.iter().rfind(|o| o.integrator == ie)?.order?;
    Some((p, tightest(spec, rows, Family::Direct, ie).last()?.clone()))
}

pub(super) fn recommend(
    spec: &TradeoffSpec,
    rows: &[Row],
    points: &[Point],
    gpoints: &[Point],
    order: Option<(f64, Row)>,
    fr: &Fronts,
) -> Vec<Recommendation> {
    let at_scene_dt = |r: &Row| r.setting.dt_divisor == 1;
    let at_h = distinct_points(
        rows,
        at_scene_dt,
        |r| forward_cost(spec, r),
        |r| Some(r.trajectory?.solver_max_relative),
        false,
    );
    let grad_at_h = distinct_points(
        rows,
        at_scene_dt,
        |r| gradient_cost(spec, r),
        |r| r.gradient.solver_error,
        true,
    );
    let none = |pts: &[Point], target: f64, what: &str| -> String {
        match pareto::most_accurate(pts) {
            Some(i) => format!(
                "no setting reaches {target:e} {what}: the smallest is {:.3e} ({})",
                pts[i].error, pts[i].id
            ),
            None => format!("no setting has a {what}"),
        }
    };
    spec.targets
        .iter()
        .map(|&target| {
            let tr = pareto::fastest_within(points, target);
            let trajectory_note = match tr {
                Some(_) => format!(
                    "fastest setting with max vertex error <= {target:e} x the largest displacement against the h/{} reference",
                    spec.reference_divisor
                ),
                None => {
                    let mut s = none(points, target, "trajectory error");
                    if let Some((p, best)) = order.as_ref().filter(|(p, _)| first_order(*p)) {
                        if let Some(e) = best.trajectory.map(|t| t.max_relative).filter(|e| *e > target) {
                            let d = best.setting.dt_divisor as f64 * (e / target).powf(1.0 / p);
                            let _ = write!(
                                s,
                                "; with implicit Euler's observed order {p:.2}, the direct solver would need a time step of about h/{d:.0}"
                            );
                        }
                    }
                    s
                }
            };
            let ah = pareto::fastest_within(&at_h, target);
            let at_scene_dt_note = match ah {
                Some(_) => format!("keeping h: fastest setting whose trajectory is within {target:e} of the converged one at h (solver error only; the time discretisation error at h is not included)"),
                None => none(&at_h, target, "solver error at h"),
            };
            let gr = pareto::fastest_within(gpoints, target);
            let gradient_note = match gr {
                Some(_) => format!(
                    "fastest setting whose gradient is within {target:e} (relative) of the h/{} reference gradient",
                    spec.reference_divisor
                ),
                None if gpoints.is_empty() => fr.gradient_note.clone().unwrap_or_default(),
                None => none(gpoints, target, "gradient error"),
            };
            let gh = pareto::fastest_within(&grad_at_h, target);
            let gradient_at_scene_dt_note = match gh {
                Some(_) => format!("keeping h: fastest setting whose gradient is within {target:e} (relative) of the tight-tolerance gradient at h"),
                None if grad_at_h.is_empty() => fr.gradient_note.clone().unwrap_or_else(|| "no gradients at h".into()),
                None => none(&grad_at_h, target, "gradient error at h"),
            };
            Recommendation {
                target,
                trajectory: tr.map(|i| pick(points, i)),
                trajectory_note,
                at_scene_dt: ah.map(|i| pick(&at_h, i)),
                at_scene_dt_note,
                gradient: gr.map(|i| pick(gpoints, i)),
                gradient_note,
                gradient_at_scene_dt: gh.map(|i| pick(&grad_at_h, i)),
                gradient_at_scene_dt_note,
            }
        })
        .collect()
}

/// Solver errors of the rows of `family` and `integrator` at divisor `d` along a knob, ordered
/// by increasing effort.
fn along(rows: &[Row], family: Family, integrator: Integrator, d: usize, caps: bool) -> Vec<(String, f64)> {
    let mut v: Vec<(f64, String, f64)> = rows
        .iter()
        .filter(|r| {
            r.setting.family == family
                && r.setting.integrator == integrator
                && r.setting.dt_divisor == d
                && r.status == Status::Ran
        })
        .filter_map(|r| {
            let e = r.trajectory?.solver_max_relative;
            match (r.setting.knob, caps) {
                (Knob::Cap(k), true) => Some((k as f64, r.id.clone(), e)),
                (Knob::Tolerance(t), false) => Some((-t, r.id.clone(), e)),
                _ => None,
            }
        })
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    v.into_iter().map(|(_, id, e)| (id, e)).collect()
}

/// The floor below which errors of `family` at divisor `d` are not ordered: the reference's
/// resolution, or twice the smallest solver error any of the family's settings reaches at that
/// step (with contact, trajectories that differ by a contact decision differ at about that
/// level however many iterations run).
fn floor_at(rows: &[Row], family: Family, integrator: Integrator, d: usize, resolution: f64) -> f64 {
    let best = rows
        .iter()
        .filter(|r| {
            r.setting.family == family
                && r.setting.integrator == integrator
                && r.setting.dt_divisor == d
                && r.status == Status::Ran
        })
        .filter_map(|r| r.trajectory.map(|t| t.solver_max_relative))
        .fold(f64::INFINITY, f64::min);
    if best.is_finite() {
        resolution.max(2.0 * best)
    } else {
        resolution
    }
}

/// A sequence of errors along a knob with the floor that applies to it.
type Sequence = (Vec<(String, f64)>, f64);

fn monotone_verdict(claim: String, seqs: Vec<Sequence>) -> Option<Verdict> {
    let seqs: Vec<_> = seqs.into_iter().filter(|s| s.0.len() >= 2).collect();
    if seqs.is_empty() {
        return None;
    }
    // measured / threshold: the worst increase relative to the floor of its sequence.
    let mut worst = 0.0f64;
    let mut at = String::new();
    for (s, floor) in &seqs {
        for w in s.windows(2) {
            let inc = (w[1].1 - w[0].1) / floor;
            if inc > worst {
                worst = inc;
                at = format!(
                    "{} ({:.3e}) -> {} ({:.3e}), floor {floor:.3e}",
                    w[0].0, w[0].1, w[1].0, w[1].1
                );
            }
        }
    }
    let mut v = Verdict::at_most(claim, worst, 1.0);
    v.comparison = format!(
        "measured = largest increase of the error along the knob divided by the floor of its time step (the larger of the reference's resolution and twice the smallest error reached at that step){}; holds iff <= 1",
        if at.is_empty() { " (no increase)".to_string() } else { format!(", at {at}") }
    );
    Some(v)
}

pub(super) fn verdicts(
    spec: &TradeoffSpec,
    rows: &[Row],
    reference: &Reference,
    dt_refs: &[Reference],
    resolution: f64,
    orders: &[ObservedOrder],
) -> Vec<Verdict> {
    let mut out = Vec::new();
    let unconverged: usize = std::iter::once(reference)
        .chain(dt_refs)
        .map(|r| r.work.unconverged_steps)
        .sum();
    out.push(Verdict::at_most(
        "Every reference step met the reference tolerance within its iteration cap (steps at the cap)",
        unconverged as f64,
        0.0,
    ));
    for &integrator in &spec.integrators {
        // Implicit Euler's claims keep their wording; another integrator's name their scheme.
        let scheme = match integrator {
            Integrator::ImplicitEuler => String::new(),
            other => format!("{}, ", other.name()),
        };
        for family in [Family::Direct, Family::Anderson] {
            if !spec.families.contains(&family)
                || !rows
                    .iter()
                    .any(|r| r.setting.family == family && r.setting.integrator == integrator)
            {
                continue;
            }
            let name = family.name();
            let seqs = |caps: bool| -> Vec<Sequence> {
                spec.dt_divisors
                    .iter()
                    .map(|&d| {
                        (
                            along(rows, family, integrator, d, caps),
                            floor_at(rows, family, integrator, d, resolution),
                        )
                    })
                    .collect()
            };
            out.extend(monotone_verdict(
                format!("More local-global iterations give a smaller error ({scheme}{name}, every time step): the error against the converged run at the same step does not grow with the iteration cap"),
                seqs(true),
            ));
            out.extend(monotone_verdict(
                format!("A tighter tolerance gives a smaller error ({scheme}{name}, every time step): the error against the converged run at the same step does not grow as the tolerance falls"),
                seqs(false),
            ));
        }
        let t = tightest(spec, rows, Family::Direct, integrator);
        let seq: Vec<(String, f64)> = t
            .iter()
            .filter_map(|r| Some((r.id.clone(), r.trajectory?.max_relative)))
            .collect();
        out.extend(monotone_verdict(
            format!(
                "A smaller time step gives a smaller error against the h/{} reference ({scheme}direct solver at the tightest tolerance)",
                spec.reference_divisor
            ),
            vec![(seq, resolution)],
        ));
    }
    let of = |i: Integrator| orders.iter().filter(move |o| o.integrator == i);
    // (a DoubleEndedIterator: `next_back` is the finest pair)
    if let Some(o) = of(Integrator::ImplicitEuler).next_back() {
        if let Some(p) = o.order {
            out.push(Verdict::new(
                "Implicit Euler (Eq. 2) converges at first order in the time step (finest pair of grid steps)",
                first_order(p),
                Some(p),
                Some(1.0),
                format!(
                    "measured = observed order p between {} and {} against the h/R reference, e(x) = C (x^p - (h/R)^p); holds iff |p - 1| <= 0.25 (orders of every pair in observed_orders; a smaller p means the steps are not yet asymptotic: modes with omega h > 1, contact or joint-limit events)",
                    o.coarse, o.fine
                ),
            ));
        }
    }
    // BDF2: second order between h/2 and h/4 (the pair the criterion names), and its
    // error at h against implicit Euler's at h.
    if let Some(o) = of(Integrator::Bdf2).find(|o| o.coarse.ends_with("/h/2") && o.fine.ends_with("/h/4")) {
        if let Some(p) = o.order {
            out.push(Verdict::new(
                "BDF2 (Eq. T1) converges at second order in the time step (h/2 to h/4)",
                p >= BDF2_MIN_ORDER,
                Some(p),
                Some(BDF2_MIN_ORDER),
                format!(
                    "measured = observed order p between {} and {} against the h/R reference; holds iff p >= {BDF2_MIN_ORDER} (a smaller p: the steps are not asymptotic for every excited mode, or a contact, joint-limit or stick-slip event is resolved only to the time step, which is first order)",
                    o.coarse, o.fine
                ),
            ));
        }
    }
    let at_h = |i: Integrator| {
        tightest(spec, rows, Family::Direct, i)
            .into_iter()
            .find(|r| r.setting.dt_divisor == 1)
            .and_then(|r| Some((r.id, r.trajectory?.max_relative)))
    };
    if let (Some((bid, b)), Some((eid, e))) = (at_h(Integrator::Bdf2), at_h(Integrator::ImplicitEuler)) {
        if e > 0.0 {
            let mut v = Verdict::at_most(
                "BDF2 at the scene's time step is at least twice as accurate as implicit Euler (error ratio at h)",
                b / e,
                0.5,
            );
            v.comparison = format!(
                "measured = {bid}'s error {b:.3e} / {eid}'s {e:.3e} against the h/R reference; holds iff <= 0.5"
            );
            out.push(v);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row that ran, with the cost, iterations, one error and gradient value given.
    fn row(index: usize, id: &str, cost: f64, iterations: usize, error: f64, gradient: f64) -> Row {
        serde_json::from_value(serde_json::json!({
            "index": index, "id": id,
            "setting": { "family": "direct", "knob": { "cap": 3 }, "dt_divisor": 1, "integrator": "implicit_euler" },
            "dt": 0.01, "steps": 10, "status": "ran", "message": null, "solver_used": "direct",
            "certificate": null, "resolved_to": null,
            "work": { "steps": 10, "iterations": iterations, "global_iterations": 0, "unconverged_steps": 0 },
            "timing": { "setup_s": 0.0, "runs": 1, "wall_s": cost, "cpu_s": cost, "wall_s_per_sim_s": cost, "cpu_s_per_sim_s": cost },
            "trajectory": {
                "max_vertex_error": error, "rms_vertex_error": error, "com_error": error,
                "max_relative": error, "rms_relative": error, "com_relative": error,
                "solver_max_relative": error, "solver_rms_relative": error,
                "energy_drift": 0.0, "energy_drift_error": 0.0
            },
            "gradient": { "values": [gradient], "message": null, "wall_s": cost, "cpu_s": cost, "error": error, "solver_error": error }
        }))
        .unwrap()
    }

    /// Rows that did identical work are one point, named by the first in the grid's order at
    /// the smallest cost of the group, whichever of them measured faster; rows that differ in
    /// iterations, errors or (for gradients) gradient values stay points of their own.
    #[test]
    fn identical_work_is_one_point_named_by_the_first_row() {
        let pts = |rows: &[Row], gradient: bool| {
            let cost = |r: &Row| Some(r.timing?.cpu_s_per_sim_s.unwrap());
            distinct_points(rows, |_| true, cost, |r| Some(r.trajectory?.max_relative), gradient)
        };
        for (a, b) in [(2.0, 1.5), (1.5, 2.0)] {
            let rows = [
                row(0, "direct", a, 30, 1e-3, 1.0),
                row(1, "anderson", b, 30, 1e-3, 1.0),
                row(2, "other", 1.8, 30, 2e-3, 1.0),
            ];
            let p = pts(&rows, false);
            assert_eq!(
                p.iter().map(|p| (p.id.as_str(), p.time)).collect::<Vec<_>>(),
                [("direct", 1.5), ("other", 1.8)]
            );
            let fastest = pareto::fastest_within(&p, 1e-2).map(|i| p[i].id.as_str());
            assert_eq!(fastest, Some("direct"));
        }
        let rows = [
            row(0, "direct", 2.0, 30, 1e-3, 1.0),
            row(1, "anderson", 1.5, 31, 1e-3, 1.0),
        ];
        assert_eq!(pts(&rows, false).len(), 2, "different iterations");
        let rows = [
            row(0, "direct", 2.0, 30, 1e-3, 1.0),
            row(1, "anderson", 1.5, 30, 1e-3, 1.0 + 1e-15),
        ];
        assert_eq!(pts(&rows, false).len(), 1);
        assert_eq!(pts(&rows, true).len(), 2, "different gradients");
    }
}
