//! The trade-off report's types: per-setting rows and references (partial reports, one per
//! shard) and the scene's assembled report; `super::merge` assembles them.

use serde::{Deserialize, Serialize};

use super::trajectory::Work;
use super::{SceneSummary, Setting, TimeAxis, TradeoffSpec};
use crate::report::{Provenance, Verdict, CRATE_VERSION};
use crate::shard::{Partial, Shard};
use diffsoft::solver::{Integrator, SolverKind};

/// Schema of a shard's partial report.
pub const PARTIAL_SCHEMA: &str = "diffsoft.tradeoff_partial/1";
/// Schema of `reports/tradeoff.json` and of merged reports.
pub const SCHEMA: &str = "diffsoft.tradeoff/1";

/// Factor between a reference's tolerance (times the length scale) and the smallest error
/// difference the study resolves: a step's error is the tolerance times `rho / (1 - rho)` of
/// the local-global iteration (up to ~100 on the paper's scenes), accumulated over steps.
pub const RESOLUTION_FACTOR: f64 = 1e3;

/// What happened to a setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Timing {
    /// Set-up (assembly, factorisation, certification) (s).
    pub setup_s: f64,
    /// Forward runs timed (the median is reported).
    pub runs: usize,
    /// Median wall time of the stepping over the runs (s).
    pub wall_s: f64,
    /// Mean thread CPU time of the stepping over the runs, total / runs (s; `null` without
    /// `/proc`).
    pub cpu_s: Option<f64>,
    /// `wall_s` per simulated second (s/s).
    pub wall_s_per_sim_s: f64,
    /// `cpu_s` per simulated second (s/s).
    pub cpu_s_per_sim_s: Option<f64>,
}

/// Errors of a setting's trajectory, sampled at every multiple of the scene's step `h`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct TrajectoryErrors {
    /// Largest vertex distance to the reference at `h/R` (m).
    pub max_vertex_error: f64,
    /// RMS vertex distance to it over vertices and samples (m).
    pub rms_vertex_error: f64,
    /// Largest centre-of-mass distance to it (m).
    pub com_error: f64,
    /// `max_vertex_error` / the reference's largest displacement (1): the error the fronts use.
    pub max_relative: f64,
    /// `rms_vertex_error` / the same scale (1).
    pub rms_relative: f64,
    /// `com_error` / the same scale (1).
    pub com_relative: f64,
    /// Largest vertex distance to the converged run at the same time step, / the same scale (1; the
    /// solver's share of the error).
    pub solver_max_relative: f64,
    /// RMS of the same (1).
    pub solver_rms_relative: f64,
    /// `(E_end - E_0) / E_scale` (1): total energy drift over the run.
    pub energy_drift: f64,
    /// `|energy_drift - reference energy_drift|` (1).
    pub energy_drift_error: f64,
}

/// A setting's gradient.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct GradientResult {
    /// `p dL/dp` for each parameter (log-derivatives, in the loss unit: m for centre-of-mass
    /// losses), `null` when not computed.
    pub values: Option<Vec<f64>>,
    /// Why there is no gradient (unsupported scene, not requested, forward failed).
    pub message: Option<String>,
    /// Wall time of forward + backward (s).
    pub wall_s: Option<f64>,
    /// Thread CPU time of forward + backward (s).
    pub cpu_s: Option<f64>,
    /// `max_k |g_k - g_ref_k| / max_k |g_ref_k|` against the reference gradient at `h/R` (1).
    pub error: Option<f64>,
    /// The same against the tight-tolerance gradient at the setting's own time step (1).
    pub solver_error: Option<f64>,
}

/// One setting of the grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Reference {
    /// Time step divisor.
    pub dt_divisor: usize,
    /// Time integrator.
    #[serde(default)]
    pub integrator: Integrator,
    /// Time step (s).
    pub dt: f64,
    /// Tolerance (1: relative RMS change over the length scale).
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
    /// Energy drift over the run, `(E_end - E_0) / E_scale` (1).
    pub energy_drift: f64,
    /// Hash of the sampled states (equal in every shard).
    pub fingerprint: String,
}

/// A reference gradient (direct solver, tight tolerance, unrolled).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct GradientReference {
    /// Time step divisor.
    pub dt_divisor: usize,
    /// Time integrator.
    #[serde(default)]
    pub integrator: Integrator,
    /// The gradient, or why there is none.
    pub gradient: GradientResult,
    /// The check of its first parameter (Young's modulus) against central differences of the
    /// same loss: a reference that disagrees is withdrawn (`gradient.values` is `null`, and its
    /// `message` says why), since no error can be measured against it.
    #[serde(default)]
    pub fd_check: Option<ReferenceCheck>,
}

/// A reference gradient's first component against central differences of its own loss.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ReferenceCheck {
    /// `p dL/dp` of the reference gradient (the loss unit).
    pub analytic: f64,
    /// `(L(p (1 + e)) - L(p (1 - e))) / 2e` at each relative step `e` of `steps` (the loss
    /// unit).
    pub central_differences: Vec<f64>,
    /// The relative steps (1).
    pub steps: Vec<f64>,
    /// Whether the analytic value is within 10% of the closest central difference.
    pub agrees: bool,
}

/// A shard's part of a sweep (`diffsoft tradeoff --shard K/N`).
#[derive(Debug, Clone, Serialize, Deserialize, schemars::JsonSchema)]
pub struct TradeoffPartial {
    /// [`PARTIAL_SCHEMA`].
    pub schema: String,
    /// Version of the crate that wrote it.
    pub crate_version: String,
    /// Where and how this shard ran (its rows' timings depend on it; `null` in a partial
    /// written before partials carried it).
    #[serde(default)]
    pub provenance: Option<Provenance>,
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
    /// The material-model comparison (the first shard runs it; `None` in the others and when
    /// the sweep names no models).
    #[serde(default)]
    pub models: Option<super::models::ModelStudy>,
    /// Settings run at once (one thread each).
    pub workers: usize,
    /// Wall time (s).
    pub wall_time_s: f64,
}

impl Partial for TradeoffPartial {
    fn shard(&self) -> Shard {
        self.shard
    }
    fn schema(&self) -> &str {
        &self.schema
    }
    fn crate_version(&self) -> &str {
        &self.crate_version
    }
}

/// A point of a Pareto front or a recommendation.
#[derive(Debug, Clone, PartialEq, Serialize, schemars::JsonSchema)]
pub struct Pick {
    /// Setting id.
    pub id: String,
    /// Cost per simulated second on the report's time axis (s/s of CPU time for `cpu`, iterations
    /// per simulated second for `iterations`).
    pub time: f64,
    /// Error (1, relative: as the front it is on).
    pub error: f64,
}

/// The Pareto fronts.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
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
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Recommendation {
    /// Target relative error (1).
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
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct ObservedOrder {
    /// The integrator of both rows.
    pub integrator: Integrator,
    /// The coarser step's row (direct solver, tightest tolerance).
    pub coarse: String,
    /// The finer step's row (half the step).
    pub fine: String,
    /// Its error against the `h/R` reference (1, relative).
    pub coarse_error: f64,
    /// The finer row's (1, relative).
    pub fine_error: f64,
    /// `p` with `e(x) = C (x^p - (h/R)^p)` (1; `null` outside `[0.05, 8]`); against a reference
    /// of another integrator, `e(x) = C x^p`.
    pub order: Option<f64>,
}

/// How the study measured, in words and numbers.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
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
    /// Where and how each shard ran, in the order of `workers` (each row's timing comes from
    /// its shard's machine; `null` for a partial written before partials carried it).
    pub shard_provenance: Vec<Option<Provenance>>,
    /// Differences below this relative error are not resolved (1; monotonicity verdicts).
    pub resolution: f64,
}

/// The study of one scene.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
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
    /// The material-model comparison (`null` when the sweep names no models).
    pub models: Option<super::models::ModelStudy>,
    /// Plots, relative to the report (set by the writer).
    pub svg: Vec<String>,
    /// Wall time summed over shards (s).
    pub wall_time_s: f64,
}

/// `reports/tradeoff.json`.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct TradeoffReport {
    /// [`SCHEMA`].
    pub schema: String,
    /// Crate version.
    pub crate_version: String,
    /// Where and how this report was written (each scene's `method.shard_provenance` says
    /// where its rows ran).
    pub provenance: Provenance,
    /// One study per scene.
    pub scenes: Vec<SceneTradeoff>,
}

impl TradeoffReport {
    /// A report of these scenes.
    pub fn new(scenes: Vec<SceneTradeoff>) -> Self {
        Self {
            schema: SCHEMA.into(),
            crate_version: CRATE_VERSION.into(),
            provenance: Provenance::now(),
            scenes,
        }
    }
}
