//! The trade-off report: per-setting rows and references (partial reports, one per shard),
//! and their assembly ([`finalize`]) into the scene's report: gradient errors against the
//! reference gradients, then the fronts, recommendations and verdicts of [`super::assess`].

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::assess;
use super::trajectory::Work;
use super::{SceneSummary, Setting, TimeAxis, TradeoffSpec};
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
    let (pareto, points, gpoints) = assess::fronts(&spec, &rows, &gradient_references);
    let observed_orders = assess::observed_orders(&spec, &rows);
    let order = assess::finest_order(&spec, &rows, &observed_orders);
    let recommendations = assess::recommend(&spec, &rows, &points, &gpoints, order, &pareto);
    let verdicts = assess::verdicts(&spec, &rows, &reference, &dt_references, resolution, &observed_orders);
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
