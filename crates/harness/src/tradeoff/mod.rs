//! The accuracy/cost trade-off of the solver settings (`diffsoft tradeoff`,
//! `reports/tradeoff.json`).
//!
//! For one scene, a grid of settings (time integrator x global solver family x iteration cap or
//! tolerance x time step `h/d`) runs against reference trajectories computed with the direct
//! solver at a tight tolerance: one at the small step `h/R` with the reference integrator (the
//! total error of a setting: time discretisation of implicit Euler, docs/method.md Eq. 2, or
//! BDF2, Eq. T1, plus the truncated local-global iteration, Eqs. 3-5) and one per integrator
//! at each grid step `h/d` (the solver error alone). Each setting records its time per simulated
//! second, its trajectory errors (max and RMS vertex error, centre-of-mass error, energy drift)
//! and, where the backward pass supports the scene, the error of its gradient against
//! tight-tolerance reference gradients (`null` with the reason otherwise). The report marks the
//! Pareto front (time against error) and names the fastest setting for each target error.
//!
//! Every setting and every reference runs single-threaded on its own one-thread pool, and as
//! many run at once as there are workers ([`crate::pool`]), so results are bit-identical for any worker
//! count or shard split, and the recorded thread CPU time does not count the time a setting
//! waits for a core (it still moves with what the concurrent settings do to the shared caches and
//! memory: settings doing identical work differ by about 1.2x in the median). A sweep splits into shards (`--shard K/N`, [`super::shard`]); [`merge`] reassembles
//! the partial reports into the report of the unsharded run.

mod assess;
mod chart;
mod merge;
pub mod models;
pub mod pareto;
mod report;
mod run;
mod scene;
mod summary;
pub mod trajectory;

use diffsoft::base::Choice;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use diffsoft::solver::{CertifyPolicy, Integrator, Settings, SolverKind};

pub use merge::{finalize, merge};
pub use report::{
    Fronts, GradientResult, Pick, Recommendation, Reference, Row, SceneTradeoff, Status, TradeoffPartial,
    TradeoffReport, PARTIAL_SCHEMA, SCHEMA,
};
pub use run::{plot_names, run_scene, run_shard, suite_section, write_plots, PARAMETERS};
pub use scene::{Cantilever, SceneSummary};
pub use summary::summary;

/// Anderson memory of the `anderson` family.
pub const ANDERSON_MEMORY: usize = 5;

/// A family of global solvers (how each local-global iteration's linear system is solved).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Family {
    /// Sparse Cholesky, factored once.
    Direct,
    /// The split iteration (Eq. 21), uncertified: it may diverge.
    Split,
    /// Chebyshev-accelerated relaxed split iteration (parameters from the spectral analysis).
    Chebyshev,
    /// The default: split, certified before stepping, falling back to Cholesky (resolves to the
    /// `split` or `direct` row it picks).
    Certified,
    /// Cholesky with Anderson acceleration of the local-global iteration (memory 5).
    Anderson,
    /// Newton's method on the step energy (docs/method.md Eqs. S3-S5) instead of local-global
    /// iterations; caps and tolerances apply to its iterations.
    Newton,
}

impl Family {
    /// The solver fields of `base` for this family.
    pub fn apply(&self, s: &mut Settings) {
        let (solver, certify, anderson) = match self {
            Family::Direct => (SolverKind::Direct, CertifyPolicy::Off, 0),
            Family::Split => (SolverKind::Split, CertifyPolicy::Off, 0),
            Family::Chebyshev => (SolverKind::Chebyshev, CertifyPolicy::Off, 0),
            Family::Certified => (SolverKind::Split, CertifyPolicy::Fallback, 0),
            Family::Anderson => (SolverKind::Direct, CertifyPolicy::Off, ANDERSON_MEMORY),
            Family::Newton => (SolverKind::Newton, CertifyPolicy::Off, 0),
        };
        s.solver = solver;
        s.certify = certify;
        s.anderson = anderson;
    }

    /// The family that runs what a certificate chose (`used`) with Anderson memory `anderson`.
    pub fn running(used: SolverKind, anderson: usize) -> Family {
        match used {
            SolverKind::Direct if anderson > 0 => Family::Anderson,
            SolverKind::Direct | SolverKind::Auto => Family::Direct,
            SolverKind::Newton => Family::Newton,
            SolverKind::Split | SolverKind::Plain => Family::Split,
            SolverKind::Chebyshev => Family::Chebyshev,
        }
    }
}

/// How the local-global iteration of each step stops.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Knob {
    /// Exactly this many iterations per step (tolerance 0).
    Cap(usize),
    /// Stop when the RMS change is below this times the length scale (iteration cap
    /// `tolerance_max_iterations`).
    Tolerance(f64),
}

impl Knob {
    /// Short name in ids (`cap=10`, `tol=1e-6`).
    pub fn label(&self) -> String {
        match self {
            Knob::Cap(k) => format!("cap={k}"),
            Knob::Tolerance(t) => format!("tol={t:e}"),
        }
    }
}

/// What the Pareto fronts use as cost.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum TimeAxis {
    /// Thread CPU seconds per simulated second (one thread per setting).
    #[default]
    Cpu,
    /// Local-global iterations per simulated second: machine-independent and deterministic.
    Iterations,
}

/// Where a scene comes from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum SceneSource {
    /// A scene file (diffsoft or paper format), relative to the suite file (or the working
    /// directory on the command line).
    Scene(PathBuf),
    /// A cantilever beam generated in code (e.g. the ~50k-tet mesh).
    Cantilever(Cantilever),
}

fn default_divisors() -> Vec<usize> {
    vec![1, 2, 4, 8]
}
fn default_reference_divisor() -> usize {
    16
}
fn default_reference_tolerance() -> f64 {
    1e-12
}
fn default_reference_max_iterations() -> usize {
    20_000
}
fn default_tolerance_max_iterations() -> usize {
    1000
}
fn default_loss() -> String {
    "final_com.y".into()
}
fn default_targets() -> Vec<f64> {
    vec![1e-2, 1e-4, 1e-6]
}
/// The largest iteration cap a sweep takes (per step; the references use 20 000).
pub const MAX_CAP: usize = 1_000_000;

/// Default of [`TradeoffSpec::min_timing_s`]: the thread CPU clock reads to the nanosecond
/// ([`trajectory::thread_cpu_s`]), so a run is repeated only to average short runs' noise, not
/// to outlast a clock tick (the 0.2 s of the tick-granular clock used before).
pub const DEFAULT_MIN_TIMING_S: f64 = 0.05;

/// Most forward runs timed per setting, whatever [`TradeoffSpec::min_timing_s`] asks (a run of
/// a few microseconds would otherwise be repeated millions of times).
pub const MAX_TIMING_RUNS: usize = 1000;

fn default_min_timing_s() -> f64 {
    DEFAULT_MIN_TIMING_S
}
fn default_model_tolerance() -> f64 {
    1e-8
}
fn default_families() -> Vec<Family> {
    vec![Family::Direct, Family::Split, Family::Chebyshev, Family::Certified]
}
fn default_integrators() -> Vec<Integrator> {
    vec![Integrator::ImplicitEuler]
}
fn default_caps() -> Vec<usize> {
    vec![1, 3, 10, 30, 100]
}
fn default_tolerances() -> Vec<f64> {
    vec![1e-2, 1e-4, 1e-6, 1e-8, 1e-10]
}

/// One scene's trade-off sweep (a `tradeoff.scenes` entry of `verification/suite.json`, or the
/// `diffsoft tradeoff` options).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TradeoffSpec {
    /// Name (file names, report).
    pub name: String,
    /// The scene.
    pub source: SceneSource,
    /// Simulated duration in steps of the scene's time step `h`.
    pub steps: usize,
    /// Grid time steps `h/d`.
    #[serde(default = "default_divisors")]
    pub dt_divisors: Vec<usize>,
    /// The reference runs at `h/R`; `R` is a multiple of every `d` and larger than all.
    #[serde(default = "default_reference_divisor")]
    pub reference_divisor: usize,
    /// Tolerance of every reference run (1: relative RMS change over the length scale).
    #[serde(default = "default_reference_tolerance")]
    pub reference_tolerance: f64,
    /// Iteration cap of the reference runs.
    #[serde(default = "default_reference_max_iterations")]
    pub reference_max_iterations: usize,
    /// Anderson memory of the reference trajectories (0: the plain iteration; reference
    /// gradients always use 0, which unrolled differentiation needs).
    #[serde(default)]
    pub reference_anderson: usize,
    /// Solver families.
    #[serde(default = "default_families")]
    pub families: Vec<Family>,
    /// Time integrators of the grid (default implicit Euler only; docs/method.md Eqs. 2, T1).
    #[serde(default = "default_integrators")]
    pub integrators: Vec<Integrator>,
    /// Families run with the integrators after the first (empty: every one of `families`).
    #[serde(default)]
    pub integrator_families: Vec<Family>,
    /// Integrator of the reference runs at `h/R` (the total error of every setting is measured
    /// against it; each setting's solver error against a converged run of its own integrator at
    /// its own step).
    #[serde(default)]
    pub reference_integrator: Integrator,
    /// Iteration caps (tolerance 0).
    #[serde(default = "default_caps")]
    pub caps: Vec<usize>,
    /// Iteration caps of the `newton` family (empty: `caps`). Newton converges in a few
    /// iterations, so large caps only repeat converged steps at full cost.
    #[serde(default)]
    pub newton_caps: Vec<usize>,
    /// Tolerances (1: relative RMS change over the length scale).
    #[serde(default = "default_tolerances")]
    pub tolerances: Vec<f64>,
    /// Iteration cap used with the tolerance knob.
    #[serde(default = "default_tolerance_max_iterations")]
    pub tolerance_max_iterations: usize,
    /// Divisors `d` whose settings also get a gradient (empty: none, e.g. for cost).
    #[serde(default)]
    pub gradient_dt_divisors: Vec<usize>,
    /// Loss of the gradients (`final_com.y`, `mean_com.x`, ...).
    #[serde(default = "default_loss")]
    pub loss: String,
    /// Target relative errors to recommend a setting for (1).
    #[serde(default = "default_targets")]
    pub targets: Vec<f64>,
    /// Cost axis of the Pareto fronts.
    #[serde(default)]
    pub time_axis: TimeAxis,
    /// Repeat a setting's forward run until this much CPU time is measured (s), at most 1000
    /// runs ([`MAX_TIMING_RUNS`]; the row's `timing.runs` says how many ran); the report gives
    /// the mean CPU time and the median wall time per run.
    #[serde(default = "default_min_timing_s")]
    pub min_timing_s: f64,
    /// Material models to compare on this scene ([`models`]; empty: no comparison): every body
    /// switched to each, Newton's method at every grid step, against the `neo_hookean` model at
    /// `h/R`.
    #[serde(default)]
    pub models: Vec<diffsoft::base::MaterialModel>,
    /// Newton tolerance of the model comparison's rows (1).
    #[serde(default = "default_model_tolerance")]
    pub model_tolerance: f64,
}

/// Errors of the trade-off study.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TradeoffError {
    /// The sweep's inputs are meaningless.
    #[error("trade-off '{name}': {message}")]
    Spec {
        /// Sweep name.
        name: String,
        /// What is wrong.
        message: String,
    },
    /// The scene cannot be loaded.
    #[error("trade-off '{name}': {message}")]
    Scene {
        /// Sweep name.
        name: String,
        /// Cause.
        message: String,
    },
    /// A reference run failed.
    #[error("trade-off '{name}': reference at h/{divisor}: {message}")]
    Reference {
        /// Sweep name.
        name: String,
        /// Its time-step divisor.
        divisor: usize,
        /// Cause.
        message: String,
    },
    /// Writing outputs failed.
    #[error("trade-off '{name}': {message}")]
    Output {
        /// Sweep name.
        name: String,
        /// Cause.
        message: String,
    },
}

impl TradeoffSpec {
    /// A sweep of `source` with the default grid.
    pub fn new(name: &str, source: SceneSource, steps: usize) -> Self {
        Self {
            name: name.to_string(),
            source,
            steps,
            dt_divisors: default_divisors(),
            reference_divisor: default_reference_divisor(),
            reference_tolerance: default_reference_tolerance(),
            reference_max_iterations: default_reference_max_iterations(),
            reference_anderson: 0,
            families: default_families(),
            integrators: default_integrators(),
            integrator_families: Vec::new(),
            reference_integrator: Integrator::ImplicitEuler,
            caps: default_caps(),
            newton_caps: Vec::new(),
            tolerances: default_tolerances(),
            tolerance_max_iterations: default_tolerance_max_iterations(),
            gradient_dt_divisors: Vec::new(),
            loss: default_loss(),
            targets: default_targets(),
            time_axis: TimeAxis::Cpu,
            min_timing_s: default_min_timing_s(),
            models: Vec::new(),
            model_tolerance: default_model_tolerance(),
        }
    }

    /// Check the grid.
    pub fn validate(&self) -> Result<(), TradeoffError> {
        let bad = |m: String| {
            Err(TradeoffError::Spec {
                name: self.name.clone(),
                message: m,
            })
        };
        if self.steps == 0 {
            return bad("steps must be at least 1".into());
        }
        if self.dt_divisors.is_empty()
            || self.families.is_empty()
            || (self.caps.is_empty() && self.tolerances.is_empty())
        {
            return bad("needs at least one dt divisor, one family and one cap or tolerance".into());
        }
        fn distinct<T: PartialEq>(v: &[T]) -> bool {
            v.iter().enumerate().all(|(i, a)| !v[..i].contains(a))
        }
        if !distinct(&self.dt_divisors) || self.dt_divisors.contains(&0) {
            return bad(format!(
                "dt_divisors must be distinct and positive, got {:?}",
                self.dt_divisors
            ));
        }
        if !distinct(&self.families) || !distinct(&self.caps) || !distinct(&self.tolerances) {
            return bad("families, caps and tolerances must not repeat".into());
        }
        let names = |v: &[&'static str]| v.join(",");
        if self.integrators.is_empty() || !distinct(&self.integrators) {
            return bad(format!(
                "integrators must be distinct and at least one, got '{}'",
                names(&self.integrators.iter().map(|i| i.name()).collect::<Vec<_>>())
            ));
        }
        if let Some(f) = self.integrator_families.iter().find(|f| !self.families.contains(f)) {
            return bad(format!("integrator family {} is not one of families", f.name()));
        }
        let r = self.reference_divisor;
        if let Some(d) = self.dt_divisors.iter().find(|&&d| d >= r || !r.is_multiple_of(d)) {
            return bad(format!(
                "reference_divisor {r} must be a multiple of every dt divisor and larger than all (not of {d})"
            ));
        }
        if !distinct(&self.newton_caps) {
            return bad("newton_caps must not repeat".into());
        }
        if !self.newton_caps.is_empty() && !self.families.contains(&Family::Newton) {
            return bad("newton_caps are given, but newton is not one of families".into());
        }
        let caps = || {
            self.caps
                .iter()
                .chain(&self.newton_caps)
                .chain([&self.tolerance_max_iterations, &self.reference_max_iterations])
        };
        if caps().any(|&c| c == 0) {
            return bad("iteration caps must be at least 1".into());
        }
        if let Some(c) = caps().find(|&&c| c > MAX_CAP) {
            return bad(format!(
                "iteration caps must be at most {MAX_CAP} per step, got {c} (a sweep would run without end)"
            ));
        }
        let positive = |v: f64| v.is_finite() && v > 0.0;
        // A tolerance is relative to the scene's length scale: the solver refuses 1 or more.
        let relative = |v: f64| positive(v) && v < 1.0;
        if let Some(&t) = self.tolerances.iter().find(|&&t| !relative(t)) {
            return bad(format!(
                "tolerances must be finite, positive and below 1, got {}",
                diffsoft::base::number(t)
            ));
        }
        if !relative(self.reference_tolerance) {
            return bad(format!(
                "reference_tolerance must be finite, positive and below 1, got {}",
                diffsoft::base::number(self.reference_tolerance)
            ));
        }
        if !positive(self.model_tolerance) {
            return bad(format!(
                "model_tolerance must be finite and positive, got {}",
                diffsoft::base::number(self.model_tolerance)
            ));
        }
        if !distinct(&self.models) {
            return bad(format!(
                "models must not repeat, got '{}'",
                names(&self.models.iter().map(|m| m.name()).collect::<Vec<_>>())
            ));
        }
        if !self.targets.iter().all(|&t| positive(t)) || !distinct(&self.targets) {
            return bad(format!(
                "targets must be distinct, finite and positive, got {:?}",
                self.targets
            ));
        }
        if !distinct(&self.gradient_dt_divisors) {
            return bad(format!(
                "gradient dt divisors must not repeat, got {:?}",
                self.gradient_dt_divisors
            ));
        }
        if let Some(d) = self.gradient_dt_divisors.iter().find(|d| !self.dt_divisors.contains(d)) {
            return bad(format!("gradient dt divisor {d} is not one of dt_divisors"));
        }
        if !(self.min_timing_s.is_finite() && self.min_timing_s >= 0.0) {
            return bad("min_timing_s must be finite and >= 0".into());
        }
        if let Err(e) = diffsoft::diff::loss::by_name(&self.loss) {
            return bad(e.to_string());
        }
        Ok(())
    }

    /// The grid in report order: integrator, family, then caps and tolerances, then time steps.
    pub fn grid(&self) -> Vec<Setting> {
        let knobs_of = |family: Family| -> Vec<Knob> {
            let caps = if family == Family::Newton && !self.newton_caps.is_empty() {
                &self.newton_caps
            } else {
                &self.caps
            };
            caps.iter()
                .map(|&k| Knob::Cap(k))
                .chain(self.tolerances.iter().map(|&t| Knob::Tolerance(t)))
                .collect()
        };
        let mut out = Vec::new();
        for (i, &integrator) in self.integrators.iter().enumerate() {
            let families = if i == 0 || self.integrator_families.is_empty() {
                &self.families
            } else {
                &self.integrator_families
            };
            for &family in families {
                for knob in knobs_of(family) {
                    for &dt_divisor in &self.dt_divisors {
                        out.push(Setting {
                            family,
                            knob,
                            dt_divisor,
                            integrator,
                        });
                    }
                }
            }
        }
        out
    }
}

/// One point of the grid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Setting {
    /// Solver family.
    pub family: Family,
    /// Iteration cap or tolerance.
    pub knob: Knob,
    /// The time step is `h / dt_divisor`.
    pub dt_divisor: usize,
    /// Time integrator.
    #[serde(default)]
    pub integrator: Integrator,
}

impl Setting {
    /// Id in reports, e.g. `direct/tol=1e-6/h/4` (implicit Euler) or `bdf2/direct/tol=1e-6/h/4`.
    pub fn id(&self) -> String {
        let dt = if self.dt_divisor == 1 {
            "h".to_string()
        } else {
            format!("h/{}", self.dt_divisor)
        };
        let scheme = match self.integrator {
            Integrator::ImplicitEuler => String::new(),
            other => format!("{}/", other.name()),
        };
        format!("{scheme}{}/{}/{dt}", self.family.name(), self.knob.label())
    }

    /// The solver settings: the scene's, with this family, knob and time step (and the
    /// velocity damping per step rescaled to the same damping per second, [`damping_at`]).
    pub fn settings(&self, base: &Settings, spec: &TradeoffSpec) -> Settings {
        let mut s = base.clone();
        s.dt = base.dt / self.dt_divisor as f64;
        s.damping = damping_at(base.damping, self.dt_divisor);
        s.integrator = self.integrator;
        self.family.apply(&mut s);
        match self.knob {
            Knob::Cap(k) => {
                s.tolerance = 0.0;
                s.max_iterations = k;
            }
            Knob::Tolerance(t) => {
                s.tolerance = t;
                s.max_iterations = spec.tolerance_max_iterations;
            }
        }
        s
    }
}

/// The velocity damping per step at `h / divisor` that gives the scene's damping per second:
/// a factor `c` per step of `h` is `c^(1/divisor)` per step of `h / divisor` (the factor per
/// step would otherwise make the physics depend on the time step).
pub fn damping_at(per_step: f64, divisor: usize) -> f64 {
    per_step.powf(1.0 / divisor as f64)
}

/// Settings of the reference runs at `h / divisor` with `integrator`: direct, the reference
/// tolerance and cap.
pub fn reference_settings(
    base: &Settings,
    spec: &TradeoffSpec,
    divisor: usize,
    anderson: usize,
    integrator: Integrator,
) -> Settings {
    let mut s = base.clone();
    s.integrator = integrator;
    s.dt = base.dt / divisor as f64;
    s.damping = damping_at(base.damping, divisor);
    Family::Direct.apply(&mut s);
    s.anderson = anderson;
    s.tolerance = spec.reference_tolerance;
    s.max_iterations = spec.reference_max_iterations;
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> TradeoffSpec {
        TradeoffSpec::new("t", SceneSource::Cantilever(Cantilever::small()), 4)
    }

    #[test]
    fn grid_order_and_ids() {
        let s = spec();
        let g = s.grid();
        assert_eq!(
            g.len(),
            s.families.len() * (s.caps.len() + s.tolerances.len()) * s.dt_divisors.len()
        );
        assert_eq!(g[0].id(), "direct/cap=1/h");
        assert_eq!(g[1].id(), "direct/cap=1/h/2");
        let ids: Vec<String> = g.iter().map(Setting::id).collect();
        assert!(
            ids.iter().enumerate().all(|(i, a)| !ids[..i].contains(a)),
            "ids are unique"
        );
    }

    #[test]
    fn newton_has_its_own_caps_and_bdf2_its_families() {
        let mut s = spec();
        s.families = vec![Family::Direct, Family::Newton];
        s.caps = vec![1, 10, 100];
        s.newton_caps = vec![1, 3];
        s.tolerances = vec![1e-6];
        s.dt_divisors = vec![1];
        s.integrators = vec![Integrator::ImplicitEuler, Integrator::Bdf2];
        s.integrator_families = vec![Family::Newton];
        let ids: Vec<String> = s.grid().iter().map(Setting::id).collect();
        assert_eq!(
            ids,
            [
                "direct/cap=1/h",
                "direct/cap=10/h",
                "direct/cap=100/h",
                "direct/tol=1e-6/h",
                "newton/cap=1/h",
                "newton/cap=3/h",
                "newton/tol=1e-6/h",
                "bdf2/newton/cap=1/h",
                "bdf2/newton/cap=3/h",
                "bdf2/newton/tol=1e-6/h",
            ]
        );
        assert!(s.validate().is_ok());
        s.newton_caps = vec![0];
        assert!(s.validate().is_err());
    }

    #[test]
    fn validation_names_the_problem() {
        let mut s = spec();
        s.reference_divisor = 12;
        let e = s.validate().unwrap_err().to_string();
        assert!(
            e.contains("multiple of every dt divisor") && e.contains("not of 8"),
            "{e}"
        );
        let mut s = spec();
        s.gradient_dt_divisors = vec![3];
        assert!(s.validate().unwrap_err().to_string().contains("gradient dt divisor 3"));
        assert!(spec().validate().is_ok());
        // A tolerance of 1 or more is refused before any run (the solver would reject each
        // such row), naming the value.
        for t in [1.0, 2.0] {
            let mut s = spec();
            s.tolerances.push(t);
            let e = s.validate().unwrap_err().to_string();
            assert!(e.contains("tolerances must be finite, positive and below 1"), "{e}");
            let mut s = spec();
            s.reference_tolerance = t;
            assert!(s.validate().unwrap_err().to_string().contains("reference_tolerance"));
        }
    }

    #[test]
    fn settings_follow_the_knob() {
        let s = spec();
        let base = Settings::default();
        let a = Setting {
            family: Family::Certified,
            knob: Knob::Cap(7),
            dt_divisor: 4,
            integrator: Integrator::ImplicitEuler,
        }
        .settings(&base, &s);
        assert_eq!(
            (a.solver, a.certify, a.max_iterations, a.tolerance),
            (SolverKind::Split, CertifyPolicy::Fallback, 7, 0.0)
        );
        assert_eq!(a.dt, base.dt / 4.0);
        let damped = Settings {
            damping: 0.9999,
            ..Settings::default()
        };
        let c = Setting {
            family: Family::Direct,
            knob: Knob::Cap(1),
            dt_divisor: 8,
            integrator: Integrator::Bdf2,
        }
        .settings(&damped, &s);
        assert!((c.damping.powi(8) - 0.9999).abs() < 1e-15, "same damping per second");
        assert_eq!(c.integrator, Integrator::Bdf2);
        let b = Setting {
            family: Family::Anderson,
            knob: Knob::Tolerance(1e-8),
            dt_divisor: 1,
            integrator: Integrator::ImplicitEuler,
        }
        .settings(&base, &s);
        assert_eq!(
            (b.anderson, b.tolerance, b.max_iterations),
            (ANDERSON_MEMORY, 1e-8, s.tolerance_max_iterations)
        );
    }
}

diffsoft::choice!(Family {
    Direct => "direct",
    Split => "split",
    Chebyshev => "chebyshev",
    Certified => "certified",
    Anderson => "anderson",
    Newton => "newton",
});

diffsoft::choice!(TimeAxis {
    Cpu => "cpu",
    Iterations => "iterations",
});
