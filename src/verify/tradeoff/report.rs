//! The trade-off report: per-setting rows and references (partial reports, one per shard),
//! and their assembly ([`finalize`]) into the scene's report with gradient errors, Pareto
//! fronts, recommendations per target error and the verdicts on monotonicity and order.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use super::pareto::{self, Point};
use super::trajectory::Work;
use super::{Family, Knob, SceneSummary, Setting, TimeAxis, TradeoffSpec};
use crate::report::{Verdict, CRATE_VERSION};
use crate::solver::SolverKind;
use crate::verify::shard::{check_cover, check_same, Shard, ShardError};

/// Schema of a shard's partial report.
pub const PARTIAL_SCHEMA: &str = "diffsoft.tradeoff.partial/1";
/// Schema of `reports/tradeoff.json` and of merged reports.
pub const SCHEMA: &str = "diffsoft.tradeoff/1";

/// Factor between a reference's tolerance (times the length scale) and the smallest error
/// difference the study resolves: a step's error is the tolerance times `rho / (1 - rho)` of
/// the local-global iteration (up to ~100 on the paper's scenes), accumulated over steps.
pub const RESOLUTION_FACTOR: f64 = 1e3;

/// What happened to a setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Ran every step.
    Ran,
    /// Not run: certification (or the skeleton's reduced step) makes it the same solver as
    /// the row `resolved_to`.
    Resolved,
    /// A step failed: divergence or non-finite values detected (message).
    Diverged,
    /// The simulator refused the settings (message).
    Rejected,
    /// The run panicked (a bug; message).
    Panicked,
}

/// Wall and CPU time of a setting's forward run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    /// Set-up (assembly, factorisation, certification), s.
    pub setup_s: f64,
    /// Forward runs timed (the median is reported).
    pub runs: usize,
    /// Median wall time of the stepping over the runs, s.
    pub wall_s: f64,
    /// Mean thread CPU time of the stepping over the runs (total / runs), s (`null` without
    /// `/proc`).
    pub cpu_s: Option<f64>,
    /// `wall_s` per simulated second.
    pub wall_s_per_sim_s: f64,
    /// `cpu_s` per simulated second.
    pub cpu_s_per_sim_s: Option<f64>,
}

/// Errors of a setting's trajectory, sampled at every multiple of the scene's step `h`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrajectoryErrors {
    /// Largest vertex distance to the reference at `h/R` (m).
    pub max_vertex_error: f64,
    /// RMS vertex distance to it over vertices and samples (m).
    pub rms_vertex_error: f64,
    /// Largest centre-of-mass distance to it (m).
    pub com_error: f64,
    /// `max_vertex_error` / the reference's largest displacement: the error the fronts use.
    pub max_relative: f64,
    /// `rms_vertex_error` / the same scale.
    pub rms_relative: f64,
    /// `com_error` / the same scale.
    pub com_relative: f64,
    /// Largest vertex distance to the converged run at the same time step, / the same scale
    /// (the solver's share of the error).
    pub solver_max_relative: f64,
    /// RMS of the same.
    pub solver_rms_relative: f64,
    /// `(E_end - E_0) / E_scale`: total energy drift over the run.
    pub energy_drift: f64,
    /// `|energy_drift - reference energy_drift|`.
    pub energy_drift_error: f64,
}

/// A setting's gradient.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GradientResult {
    /// `p dL/dp` for each parameter (log-derivatives, all in loss units), `null` when not
    /// computed.
    pub values: Option<Vec<f64>>,
    /// Why there is no gradient (unsupported scene, not requested, forward failed).
    pub message: Option<String>,
    /// Wall time of forward + backward, s.
    pub wall_s: Option<f64>,
    /// Thread CPU time of forward + backward, s.
    pub cpu_s: Option<f64>,
    /// `max_k |g_k - g_ref_k| / max_k |g_ref_k|` against the reference gradient at `h/R`.
    pub error: Option<f64>,
    /// The same against the tight-tolerance gradient at the setting's own time step.
    pub solver_error: Option<f64>,
}

/// One setting of the grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// Position in the grid.
    pub index: usize,
    /// Id, e.g. `direct/tol=1e-6/h/4`.
    pub id: String,
    /// Family, knob, time-step divisor.
    pub setting: Setting,
    /// Time step (s).
    pub dt: f64,
    /// Steps taken (simulated time / dt).
    pub steps: usize,
    /// Outcome.
    pub status: Status,
    /// Divergence, rejection or panic message.
    pub message: Option<String>,
    /// The global solver that ran (after certification).
    pub solver_used: Option<SolverKind>,
    /// The certificate's message.
    pub certificate: Option<String>,
    /// For `resolved` rows: the row that runs the same solver.
    pub resolved_to: Option<String>,
    /// Iterations (deterministic).
    pub work: Option<Work>,
    /// Times.
    pub timing: Option<Timing>,
    /// Trajectory errors.
    pub trajectory: Option<TrajectoryErrors>,
    /// Gradient and its errors.
    pub gradient: GradientResult,
}

/// A reference trajectory (direct solver, tight tolerance).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Reference {
    /// Time step divisor.
    pub dt_divisor: usize,
    /// Time step (s).
    pub dt: f64,
    /// Tolerance.
    pub tolerance: f64,
    /// Iteration cap.
    pub max_iterations: usize,
    /// Anderson memory.
    pub anderson: usize,
    /// Iterations and unconverged steps.
    pub work: Work,
    /// Wall time (s).
    pub wall_s: f64,
    /// Largest displacement of a vertex from rest over the samples (m; the length scale if
    /// nothing moves): relative errors divide by the `h/R` reference's.
    pub displacement_scale: f64,
    /// Energy drift over the run, `(E_end - E_0) / E_scale`.
    pub energy_drift: f64,
    /// Hash of the sampled states (equal in every shard).
    pub fingerprint: String,
}

/// A reference gradient (direct solver, tight tolerance, unrolled).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GradientReference {
    /// Time step divisor.
    pub dt_divisor: usize,
    /// The gradient, or why there is none.
    pub gradient: GradientResult,
}

/// A shard's part of a sweep (`diffsoft tradeoff --shard K/N`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TradeoffPartial {
    /// [`PARTIAL_SCHEMA`].
    pub schema: String,
    /// Version of the crate that wrote it.
    pub crate_version: String,
    /// Which shard.
    pub shard: Shard,
    /// The sweep.
    pub spec: TradeoffSpec,
    /// The scene.
    pub scene: SceneSummary,
    /// Parameters of the gradients.
    pub gradient_parameters: Vec<String>,
    /// Size of the whole grid.
    pub total_rows: usize,
    /// Reference at `h/R`.
    pub reference: Reference,
    /// References at the grid's time steps this shard needed.
    pub dt_references: Vec<Reference>,
    /// Reference gradients this shard needed.
    pub gradient_references: Vec<GradientReference>,
    /// This shard's rows.
    pub rows: Vec<Row>,
    /// Settings run at once (one thread each).
    pub workers: usize,
    /// Wall time (s).
    pub wall_time_s: f64,
}

/// A point of a Pareto front or a recommendation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Pick {
    /// Setting id.
    pub id: String,
    /// Cost per simulated second (the report's time axis).
    pub time: f64,
    /// Error.
    pub error: f64,
}

/// The Pareto fronts.
#[derive(Debug, Clone, Serialize)]
pub struct Fronts {
    /// Cost axis.
    pub time_axis: TimeAxis,
    /// What the cost is, in words.
    pub time_meaning: String,
    /// Forward cost against `trajectory.max_relative`.
    pub trajectory: Vec<Pick>,
    /// Forward cost against `trajectory.solver_max_relative` (the solver's share).
    pub trajectory_solver: Vec<Pick>,
    /// Forward + backward cost against `gradient.error` (empty without gradients).
    pub gradient: Vec<Pick>,
    /// Forward + backward cost against `gradient.solver_error`.
    pub gradient_solver: Vec<Pick>,
    /// Why the gradient front is empty.
    pub gradient_note: Option<String>,
}

/// The setting to pick for a target error.
#[derive(Debug, Clone, Serialize)]
pub struct Recommendation {
    /// Target relative error.
    pub target: f64,
    /// Fastest setting whose trajectory error (vs the `h/R` reference) is within the target.
    pub trajectory: Option<Pick>,
    /// Explanation, or why none qualifies.
    pub trajectory_note: String,
    /// Keeping the scene's step `h`: fastest setting whose solver error is within the target.
    pub at_scene_dt: Option<Pick>,
    /// Explanation.
    pub at_scene_dt_note: String,
    /// Fastest setting whose gradient error (vs the `h/R` reference gradient) is within the
    /// target.
    pub gradient: Option<Pick>,
    /// Explanation.
    pub gradient_note: String,
    /// Keeping `h`: fastest setting whose gradient is within the target of the tight-tolerance
    /// gradient at `h`.
    pub gradient_at_scene_dt: Option<Pick>,
    /// Explanation.
    pub gradient_at_scene_dt_note: String,
}

/// The order of convergence in the time step between two grid steps.
#[derive(Debug, Clone, Serialize)]
pub struct ObservedOrder {
    /// The coarser step's row (direct solver, tightest tolerance).
    pub coarse: String,
    /// The finer step's row (half the step).
    pub fine: String,
    /// Its error against the `h/R` reference.
    pub coarse_error: f64,
    /// The finer row's.
    pub fine_error: f64,
    /// `p` with `e(x) = C (x^p - (h/R)^p)` (`null` outside `[0.05, 8]`).
    pub order: Option<f64>,
}

/// How the study measured, in words and numbers.
#[derive(Debug, Clone, Serialize)]
pub struct Method {
    /// The references.
    pub reference: String,
    /// The errors.
    pub errors: String,
    /// The timing and parallelism.
    pub timing: String,
    /// Settings run at once in each shard.
    pub workers: Vec<usize>,
    /// Number of shards merged.
    pub shards: usize,
    /// Differences below this relative error are not resolved (monotonicity verdicts).
    pub resolution: f64,
}

/// The study of one scene.
#[derive(Debug, Clone, Serialize)]
pub struct SceneTradeoff {
    /// Sweep name.
    pub name: String,
    /// The sweep.
    pub inputs: TradeoffSpec,
    /// The scene.
    pub scene: SceneSummary,
    /// Method.
    pub method: Method,
    /// Gradient parameters, in the order of every `values` vector.
    pub gradient_parameters: Vec<String>,
    /// The reference at `h/R`.
    pub reference: Reference,
    /// The references at each grid step.
    pub dt_references: Vec<Reference>,
    /// The reference gradients.
    pub gradient_references: Vec<GradientReference>,
    /// Every setting.
    pub rows: Vec<Row>,
    /// Pareto fronts.
    pub pareto: Fronts,
    /// Setting per target error.
    pub recommendations: Vec<Recommendation>,
    /// Observed order of convergence in the time step, per pair of grid steps.
    pub observed_orders: Vec<ObservedOrder>,
    /// Checks of what theory predicts.
    pub verdicts: Vec<Verdict>,
    /// Plots, relative to the report (set by the writer).
    pub svg: Vec<String>,
    /// Wall time summed over shards (s).
    pub wall_time_s: f64,
}

/// `reports/tradeoff.json`.
#[derive(Debug, Clone, Serialize)]
pub struct TradeoffReport {
    /// [`SCHEMA`].
    pub schema: String,
    /// Crate version.
    pub crate_version: String,
    /// One study per scene.
    pub scenes: Vec<SceneTradeoff>,
}

impl TradeoffReport {
    /// A report of these scenes.
    pub fn new(scenes: Vec<SceneTradeoff>) -> Self {
        Self {
            schema: SCHEMA.into(),
            crate_version: CRATE_VERSION.into(),
            scenes,
        }
    }
}

fn rel_vec_error(a: &[f64], r: &[f64]) -> Option<f64> {
    let scale = r.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if a.len() != r.len() || scale <= 0.0 || scale.is_nan() {
        return None;
    }
    Some(a.iter().zip(r).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / scale)
}

fn union_by_divisor<T: Clone + PartialEq>(
    what: &str,
    lists: Vec<(Vec<T>, &String)>,
    divisor: impl Fn(&T) -> usize,
    same: impl Fn(&T, &T) -> bool,
) -> Result<Vec<T>, ShardError> {
    let mut out: BTreeMap<usize, (T, String)> = BTreeMap::new();
    for (list, path) in lists {
        for x in list {
            let d = divisor(&x);
            if let Some((y, p)) = out.get(&d) {
                if !same(y, &x) {
                    return Err(ShardError::Mismatch(format!(
                        "{what} at h/{d} differs between {p} and {path} (different builds or inputs?)"
                    )));
                }
            } else {
                out.insert(d, (x, path.clone()));
            }
        }
    }
    Ok(out.into_values().map(|(x, _)| x).collect())
}

/// Assemble the partial reports of one sweep (every shard once; `paths` name them in errors)
/// into the scene's study.
pub fn finalize(parts: Vec<TradeoffPartial>, paths: &[String]) -> Result<SceneTradeoff, ShardError> {
    let shards: Vec<Shard> = parts.iter().map(|p| p.shard).collect();
    check_cover(&shards, paths)?;
    for (p, path) in parts.iter().zip(paths) {
        if p.schema != PARTIAL_SCHEMA {
            return Err(ShardError::Mismatch(format!(
                "{path}: schema {} is not {PARTIAL_SCHEMA}",
                p.schema
            )));
        }
    }
    let versions: Vec<&String> = parts.iter().map(|p| &p.crate_version).collect();
    check_same("crate versions", &versions, paths)?;
    let specs: Vec<&TradeoffSpec> = parts.iter().map(|p| &p.spec).collect();
    check_same("sweep inputs", &specs, paths)?;
    let scenes: Vec<&SceneSummary> = parts.iter().map(|p| &p.scene).collect();
    check_same("scenes", &scenes, paths)?;
    let refs: Vec<&String> = parts.iter().map(|p| &p.reference.fingerprint).collect();
    check_same("reference trajectories (fingerprints)", &refs, paths)?;
    let first = &parts[0];
    let spec = first.spec.clone();
    let scene = first.scene.clone();
    let reference = first.reference.clone();
    let gradient_parameters = first.gradient_parameters.clone();
    let total = first.total_rows;
    let dt_references = union_by_divisor(
        "the reference trajectory",
        parts
            .iter()
            .zip(paths)
            .map(|(p, path)| (p.dt_references.clone(), path))
            .collect(),
        |r| r.dt_divisor,
        |a, b| a.fingerprint == b.fingerprint,
    )?;
    let gradient_references = union_by_divisor(
        "the reference gradient",
        parts
            .iter()
            .zip(paths)
            .map(|(p, path)| (p.gradient_references.clone(), path))
            .collect(),
        |r| r.dt_divisor,
        |a, b| a.gradient.values == b.gradient.values && a.gradient.message == b.gradient.message,
    )?;
    let mut rows: Vec<Row> = parts.iter().flat_map(|p| p.rows.iter().cloned()).collect();
    rows.sort_by_key(|r| r.index);
    if rows.len() != total || rows.iter().enumerate().any(|(i, r)| r.index != i) {
        return Err(ShardError::Mismatch(format!(
            "the shards hold {} rows, the grid has {total}",
            rows.len()
        )));
    }
    let workers: Vec<usize> = parts.iter().map(|p| p.workers).collect();
    let wall_time_s = parts.iter().map(|p| p.wall_time_s).sum();
    let grad_ref = |d: usize| {
        gradient_references
            .iter()
            .find(|g| g.dt_divisor == d)
            .and_then(|g| g.gradient.values.clone())
    };
    let total_ref = grad_ref(spec.reference_divisor);
    for r in rows.iter_mut() {
        if let Some(v) = r.gradient.values.clone() {
            r.gradient.error = total_ref.as_deref().and_then(|g| rel_vec_error(&v, g));
            r.gradient.solver_error = grad_ref(r.setting.dt_divisor).and_then(|g| rel_vec_error(&v, &g));
        }
    }
    let resolution = RESOLUTION_FACTOR * spec.reference_tolerance * scene.length_scale / reference.displacement_scale;
    let (pareto, points, gpoints) = fronts(&spec, &rows, &gradient_references);
    let observed_orders = observed_orders(&spec, &rows);
    let order = finest_order(&spec, &rows, &observed_orders);
    let recommendations = recommend(&spec, &rows, &points, &gpoints, order, &pareto);
    let verdicts = verdicts(&spec, &rows, &reference, &dt_references, resolution, &observed_orders);
    let method = Method {
        reference: format!(
            "direct solver, tolerance {:e} (RMS change per iteration relative to the length scale {:.4} m), cap {} iterations, Anderson memory {}, at h/{} = {:e} s for the total error and at every grid step h/d for the solver error; reference gradients: unrolled, same tolerance, no Anderson",
            spec.reference_tolerance,
            scene.length_scale,
            spec.reference_max_iterations,
            spec.reference_anderson,
            spec.reference_divisor,
            scene.dt / spec.reference_divisor as f64
        ),
        errors: format!(
            "states compared at every multiple of h over {} steps of h ({:e} s), the velocity damping per step rescaled to the scene's damping per second; relative errors divide by the reference's largest vertex displacement from rest, {:.6e} m; gradient errors are max_k |g_k - g_ref_k| / max_k |g_ref_k| over p dL/dp for {} with loss {}",
            spec.steps,
            spec.steps as f64 * scene.dt,
            reference.displacement_scale,
            gradient_parameters.join(", "),
            spec.loss
        ),
        timing: "each setting and reference runs on one thread (its own one-thread rayon pool); `workers` settings run at once; a setting's forward run is repeated until min_timing_s of CPU time is measured (the thread CPU clock, /proc/thread-self/schedstat, advances in scheduler ticks of a few ms); cpu_s is the total over the runs / runs, wall_s the median run; thread CPU time is not inflated by the concurrent settings or other processes, wall time is; the fronts use the time_axis".into(),
        workers,
        shards: parts.len(),
        resolution,
    };
    Ok(SceneTradeoff {
        name: spec.name.clone(),
        inputs: spec,
        scene,
        method,
        gradient_parameters,
        reference,
        dt_references,
        gradient_references,
        rows,
        pareto,
        recommendations,
        observed_orders,
        verdicts,
        svg: Vec::new(),
        wall_time_s,
    })
}

/// Merge the partial reports of one sweep into a report.
pub fn merge(parts: Vec<TradeoffPartial>, paths: &[String]) -> Result<TradeoffReport, ShardError> {
    Ok(TradeoffReport::new(vec![finalize(parts, paths)?]))
}

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

fn fronts(spec: &TradeoffSpec, rows: &[Row], grefs: &[GradientReference]) -> (Fronts, Vec<Point>, Vec<Point>) {
    let points: Vec<Point> = rows
        .iter()
        .filter(|r| r.status == Status::Ran)
        .filter_map(|r| {
            Some(Point {
                id: r.id.clone(),
                time: forward_cost(spec, r)?,
                error: r.trajectory?.max_relative,
            })
        })
        .collect();
    let gpoints: Vec<Point> = rows
        .iter()
        .filter(|r| r.status == Status::Ran)
        .filter_map(|r| {
            Some(Point {
                id: r.id.clone(),
                time: gradient_cost(spec, r)?,
                error: r.gradient.error?,
            })
        })
        .collect();
    let solver_points: Vec<Point> = rows
        .iter()
        .filter(|r| r.status == Status::Ran)
        .filter_map(|r| {
            Some(Point {
                id: r.id.clone(),
                time: forward_cost(spec, r)?,
                error: r.trajectory?.solver_max_relative,
            })
        })
        .collect();
    let gsolver_points: Vec<Point> = rows
        .iter()
        .filter(|r| r.status == Status::Ran)
        .filter_map(|r| {
            Some(Point {
                id: r.id.clone(),
                time: gradient_cost(spec, r)?,
                error: r.gradient.solver_error?,
            })
        })
        .collect();
    let gradient_note = if gpoints.is_empty() {
        Some(if spec.gradient_dt_divisors.is_empty() {
            "no gradients requested for this scene (gradient_dt_divisors is empty)".to_string()
        } else if let Some(m) = grefs
            .iter()
            .find(|g| g.dt_divisor == spec.reference_divisor)
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
            "thread CPU seconds per simulated second, one thread (wall time where CPU time is unavailable)"
        }
        TimeAxis::Iterations => "local-global iterations per simulated second (deterministic)",
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

/// Rows of `family` with knob `Tolerance(t)` for the smallest tolerance of the grid, by
/// increasing divisor, that ran.
fn tightest(spec: &TradeoffSpec, rows: &[Row], family: Family) -> Vec<Row> {
    let Some(t) = spec.tolerances.iter().copied().reduce(f64::min) else {
        return Vec::new();
    };
    let mut v: Vec<Row> = rows
        .iter()
        .filter(|r| r.setting.family == family && r.setting.knob == Knob::Tolerance(t) && r.status == Status::Ran)
        .cloned()
        .collect();
    v.sort_by_key(|r| r.setting.dt_divisor);
    v
}

/// Whether an observed order is first order (within 0.25).
fn first_order(p: f64) -> bool {
    (p - 1.0).abs() <= 0.25
}

/// The observed order of the direct solver at the tightest tolerance for every pair of grid
/// steps `h/d, h/2d` (finest pair last, the one nearest the asymptotic regime).
fn observed_orders(spec: &TradeoffSpec, rows: &[Row]) -> Vec<ObservedOrder> {
    let t = tightest(spec, rows, Family::Direct);
    let mut out = Vec::new();
    for a in &t {
        let d = a.setting.dt_divisor;
        let Some(b) = t.iter().find(|r| r.setting.dt_divisor == 2 * d) else {
            continue;
        };
        let (Some(ea), Some(eb)) = (a.trajectory, b.trajectory) else {
            continue;
        };
        let r = spec.reference_divisor as f64 / d as f64;
        out.push(ObservedOrder {
            coarse: a.id.clone(),
            fine: b.id.clone(),
            coarse_error: ea.max_relative,
            fine_error: eb.max_relative,
            order: pareto::observed_order(ea.max_relative, eb.max_relative, r),
        });
    }
    out
}

/// The finest observed order and the most accurate tight row (for extrapolation).
fn finest_order(spec: &TradeoffSpec, rows: &[Row], orders: &[ObservedOrder]) -> Option<(f64, Row)> {
    let p = orders.last()?.order?;
    Some((p, tightest(spec, rows, Family::Direct).last()?.clone()))
}

fn recommend(
    spec: &TradeoffSpec,
    rows: &[Row],
    points: &[Point],
    gpoints: &[Point],
    order: Option<(f64, Row)>,
    fr: &Fronts,
) -> Vec<Recommendation> {
    let at_h: Vec<Point> = rows
        .iter()
        .filter(|r| r.status == Status::Ran && r.setting.dt_divisor == 1)
        .filter_map(|r| {
            Some(Point {
                id: r.id.clone(),
                time: forward_cost(spec, r)?,
                error: r.trajectory?.solver_max_relative,
            })
        })
        .collect();
    let grad_at_h: Vec<Point> = rows
        .iter()
        .filter(|r| r.status == Status::Ran && r.setting.dt_divisor == 1)
        .filter_map(|r| {
            Some(Point {
                id: r.id.clone(),
                time: gradient_cost(spec, r)?,
                error: r.gradient.solver_error?,
            })
        })
        .collect();
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

/// Solver errors of `family`'s rows at divisor `d` along a knob, ordered by increasing effort.
fn along(rows: &[Row], family: Family, d: usize, caps: bool) -> Vec<(String, f64)> {
    let mut v: Vec<(f64, String, f64)> = rows
        .iter()
        .filter(|r| r.setting.family == family && r.setting.dt_divisor == d && r.status == Status::Ran)
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
fn floor_at(rows: &[Row], family: Family, d: usize, resolution: f64) -> f64 {
    let best = rows
        .iter()
        .filter(|r| r.setting.family == family && r.setting.dt_divisor == d && r.status == Status::Ran)
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

fn verdicts(
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
    for family in [Family::Direct, Family::Anderson] {
        if !spec.families.contains(&family) {
            continue;
        }
        let name = family.name();
        let seqs = |caps: bool| -> Vec<Sequence> {
            spec.dt_divisors
                .iter()
                .map(|&d| (along(rows, family, d, caps), floor_at(rows, family, d, resolution)))
                .collect()
        };
        out.extend(monotone_verdict(
            format!("More local-global iterations give a smaller error ({name}, every time step): the error against the converged run at the same step does not grow with the iteration cap"),
            seqs(true),
        ));
        out.extend(monotone_verdict(
            format!("A tighter tolerance gives a smaller error ({name}, every time step): the error against the converged run at the same step does not grow as the tolerance falls"),
            seqs(false),
        ));
    }
    let t = tightest(spec, rows, Family::Direct);
    let seq: Vec<(String, f64)> = t
        .iter()
        .filter_map(|r| Some((r.id.clone(), r.trajectory?.max_relative)))
        .collect();
    out.extend(monotone_verdict(
        format!(
            "A smaller time step gives a smaller error against the h/{} reference (direct solver at the tightest tolerance)",
            spec.reference_divisor
        ),
        vec![(seq, resolution)],
    ));
    if let Some(o) = orders.last() {
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
    out
}

/// A readable summary of one scene's study.
pub fn summary(s: &SceneTradeoff) -> String {
    let mut o = String::new();
    let sc = &s.scene;
    let ran = s.rows.iter().filter(|r| r.status == Status::Ran).count();
    let resolved = s.rows.iter().filter(|r| r.status == Status::Resolved).count();
    let failed: Vec<&Row> = s
        .rows
        .iter()
        .filter(|r| matches!(r.status, Status::Diverged | Status::Rejected | Status::Panicked))
        .collect();
    let _ = writeln!(
        o,
        "  {}: {} vertices, {} tets{}, h = {:e} s, {} steps of h; reference h/{}; {} settings: {ran} ran, {resolved} resolved to another row, {} failed ({} s on {:?} workers)",
        s.name,
        sc.vertices,
        sc.tets,
        if sc.bones > 0 { format!(", {} bones", sc.bones) } else { String::new() },
        sc.dt,
        s.inputs.steps,
        s.inputs.reference_divisor,
        s.rows.len(),
        failed.len(),
        s.wall_time_s.round(),
        s.method.workers
    );
    let mut kinds: BTreeMap<String, usize> = BTreeMap::new();
    for r in &failed {
        *kinds.entry(format!("{:?}", r.status).to_lowercase()).or_default() += 1;
    }
    if let Some(r) = failed.first() {
        let _ = writeln!(
            o,
            "    failed: {kinds:?}; e.g. {}: {}",
            r.id,
            r.message.as_deref().unwrap_or("")
        );
    }
    let _ = writeln!(
        o,
        "    Pareto front ({}; error = max vertex error / largest displacement):",
        s.pareto.time_meaning
    );
    for p in &s.pareto.trajectory {
        let _ = writeln!(o, "      {:<28} {:>10.4e} {:>10.3e}", p.id, p.time, p.error);
    }
    for r in &s.recommendations {
        let show = |p: &Option<Pick>, note: &str| match p {
            Some(p) => format!("{} ({:.3e}, error {:.2e})", p.id, p.time, p.error),
            None => format!("none: {note}"),
        };
        let _ = writeln!(o, "    target {:e}:", r.target);
        let _ = writeln!(o, "      trajectory:      {}", show(&r.trajectory, &r.trajectory_note));
        let _ = writeln!(
            o,
            "      keeping h:       {}",
            show(&r.at_scene_dt, &r.at_scene_dt_note)
        );
        let _ = writeln!(o, "      gradient:        {}", show(&r.gradient, &r.gradient_note));
        let _ = writeln!(
            o,
            "      gradient at h:   {}",
            show(&r.gradient_at_scene_dt, &r.gradient_at_scene_dt_note)
        );
    }
    for v in &s.verdicts {
        let _ = writeln!(
            o,
            "    [{}] {} (measured {}, threshold {})",
            if v.holds { "holds" } else { "FAILS" },
            v.claim,
            v.measured.map_or("-".into(), |m| format!("{m:.3e}")),
            v.threshold.map_or("-".into(), |m| format!("{m:.3e}"))
        );
    }
    o
}
