//! The material model as a knob of the trade-off study: the same scene run with each of the
//! models a sweep names (`TradeoffSpec::models`), every body switched to it, with Newton's method
//! at each grid step `h/d`, against one reference: the `neo_hookean` model at `h/R` with the
//! reference tolerance. A row's error is therefore the model's difference from the Neo-Hookean
//! material the scene's `E, nu` describe plus the time discretisation, and its cost the thread
//! CPU time per simulated second (docs/tradeoff.md, "The material model").
//!
//! The projective model (the paper's constraints) responds with `E_eff = E / (1 + 2 nu / 3)`
//! (docs/method.md Eq. H5), so its error against the reference does not vanish as `h -> 0`; the
//! corotated model shares the Neo-Hookean model's small-strain moduli and differs from it only
//! at finite strain.

use serde::{Deserialize, Serialize};

use super::trajectory::{self, advance, ErrorAcc};
use super::{damping_at, Family, TradeoffError, TradeoffSpec};
use crate::pool::{self, Task};
use diffsoft::base::{Choice, MaterialModel};
use diffsoft::model::Model;
use diffsoft::solver::{Integrator, Settings, Simulator};

/// The model the comparison's reference runs.
pub const REFERENCE_MODEL: MaterialModel = MaterialModel::NeoHookean;

/// Newton iterations per step of the reference: Newton's method converges quadratically, so a
/// step that needs more is stuck, not slow.
pub const REFERENCE_CAP: usize = 200;

/// The reference's Newton tolerance: a tenth of the rows' (the local-global references'
/// `reference_tolerance`, 1e-12, is below the round-off floor of the hyperelastic energies'
/// Newton steps on some scenes, where every step would run to its cap).
pub fn reference_tolerance(spec: &TradeoffSpec) -> f64 {
    spec.model_tolerance * 1e-1
}

/// One model at one time step.
#[derive(Debug, Clone, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ModelRow {
    /// Id, e.g. `corotated/h/4`.
    pub id: String,
    /// The material model of every body.
    pub model: MaterialModel,
    /// The time step is `h / dt_divisor`.
    pub dt_divisor: usize,
    /// Time step (s).
    pub dt: f64,
    /// `ok`, or what failed.
    pub status: String,
    /// Newton iterations per step.
    pub iterations_per_step: Option<f64>,
    /// Steps whose Newton solve stopped at its cap.
    pub unconverged_steps: Option<usize>,
    /// Thread CPU seconds per simulated second.
    pub cpu_s_per_sim_s: Option<f64>,
    /// Largest vertex distance from the reference over the samples (m).
    pub max_vertex_error: Option<f64>,
    /// `max_vertex_error` over the reference's largest displacement (1).
    pub max_relative: Option<f64>,
    /// Root mean square vertex distance over the reference's largest displacement (1).
    pub rms_relative: Option<f64>,
    /// Largest centre-of-mass distance over the reference's largest displacement (1).
    pub com_relative: Option<f64>,
}

/// The material-model comparison of one sweep.
#[derive(Debug, Clone, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ModelStudy {
    /// The reference's model ([`REFERENCE_MODEL`]).
    pub reference_model: MaterialModel,
    /// The reference runs at `h / reference_divisor`.
    pub reference_divisor: usize,
    /// Its Newton tolerance (1).
    pub reference_tolerance: f64,
    /// Its largest vertex displacement from rest over the samples (m).
    pub displacement_scale: f64,
    /// Thread CPU seconds per simulated second of the reference.
    pub reference_cpu_s_per_sim_s: Option<f64>,
    /// Newton iterations per step of the reference.
    pub reference_iterations_per_step: f64,
    /// Steps of the reference whose Newton solve stopped at [`REFERENCE_CAP`] (the comparison is
    /// sound only when 0).
    pub reference_unconverged_steps: usize,
    /// The Newton tolerance of the rows (1).
    pub tolerance: f64,
    /// Integrator of every run.
    pub integrator: Integrator,
    /// One row per model and grid step.
    pub rows: Vec<ModelRow>,
}

/// `model` with every body switched to `material`.
fn switched(model: &Model, material: MaterialModel) -> Result<Model, String> {
    let mut m = model.clone();
    let names: Vec<String> = m.bodies().iter().map(|b| b.name.clone()).collect();
    for name in names {
        m.set_material_model(&name, material).map_err(|e| e.to_string())?;
    }
    Ok(m)
}

/// Newton settings at `h / divisor` (damping per second kept) with `tolerance` and `cap`.
fn newton(base: &Settings, spec: &TradeoffSpec, divisor: usize, tolerance: f64, cap: usize) -> Settings {
    let mut s = base.clone();
    s.dt = base.dt / divisor as f64;
    s.damping = damping_at(base.damping, divisor);
    s.integrator = spec.reference_integrator;
    Family::Newton.apply(&mut s);
    s.tolerance = tolerance;
    s.max_iterations = cap;
    s
}

/// A trajectory sampled at every grid step `h`, and its run's work and time.
type Sampled = (Vec<Vec<nalgebra::Vector3<f64>>>, trajectory::RunOutcome);

/// Run `model` under `settings` for the sweep's duration, sampling at every grid step `h`.
fn run(model: Model, settings: Settings, steps: usize, every: usize) -> Result<Sampled, String> {
    let mut sim = Simulator::new(model, settings).map_err(|e| e.to_string())?;
    let mut q = Vec::with_capacity(steps);
    let out = advance(&mut sim, steps * every, every, |_, x| q.push(x.to_vec())).map_err(|f| f.to_string())?;
    Ok((q, out))
}

/// The comparison of `spec.models` on `model` with the scene's settings `base`, the runs on
/// `workers` one-thread pools at once ([`crate::pool`]); `None` when the sweep names no models.
pub fn study(
    spec: &TradeoffSpec,
    model: &Model,
    base: &Settings,
    workers: usize,
    bar: &indicatif::ProgressBar,
) -> Result<Option<ModelStudy>, TradeoffError> {
    if spec.models.is_empty() {
        return Ok(None);
    }
    let sim_s = spec.steps as f64 * base.dt;
    let per_sim_s = |cpu: Option<f64>| cpu.map(|c| c / sim_s);
    let r = spec.reference_divisor;
    // The reference first, then every model at every grid step.
    let mut keys = vec![(REFERENCE_MODEL, r)];
    for &material in &spec.models {
        keys.extend(spec.dt_divisors.iter().map(|&d| (material, d)));
    }
    let tasks: Vec<Task<'_, Result<Sampled, String>>> = keys
        .iter()
        .enumerate()
        .map(|(k, &(material, d))| -> Task<'_, Result<Sampled, String>> {
            let (tolerance, cap) = if k == 0 {
                (reference_tolerance(spec), REFERENCE_CAP)
            } else {
                (spec.model_tolerance, spec.tolerance_max_iterations)
            };
            let settings = newton(base, spec, d, tolerance, cap);
            Box::new(move || switched(model, material).and_then(|m| run(m, settings, spec.steps, d)))
        })
        .collect();
    let mut results = pool::run(tasks, workers, bar).into_iter().map(|r| r.and_then(|x| x));
    let (q_ref, ref_out) = results
        .next()
        .unwrap_or_else(|| Err("not run".into()))
        .map_err(|message| TradeoffError::Reference {
            name: spec.name.clone(),
            divisor: r,
            message: format!("{} reference: {message}", REFERENCE_MODEL.name()),
        })?;
    let scale = match trajectory::displacement_scale(model, &q_ref) {
        s if s > 0.0 => s,
        _ => model.length_scale(),
    };
    let rows = keys[1..]
        .iter()
        .zip(results)
        .map(|(&(material, d), result)| {
            let mut row = ModelRow {
                id: format!(
                    "{}/{}",
                    material.name(),
                    if d == 1 { "h".to_string() } else { format!("h/{d}") }
                ),
                model: material,
                dt_divisor: d,
                dt: base.dt / d as f64,
                status: "ok".into(),
                iterations_per_step: None,
                unconverged_steps: None,
                cpu_s_per_sim_s: None,
                max_vertex_error: None,
                max_relative: None,
                rms_relative: None,
                com_relative: None,
            };
            match result {
                Ok((q, out)) => {
                    let mut acc = ErrorAcc::default();
                    for (a, b) in q.iter().zip(&q_ref) {
                        acc.add(model, a, b);
                    }
                    row.iterations_per_step = Some(out.work.iterations as f64 / out.work.steps.max(1) as f64);
                    row.unconverged_steps = Some(out.work.unconverged_steps);
                    row.cpu_s_per_sim_s = per_sim_s(out.cpu_s);
                    row.max_vertex_error = Some(acc.max());
                    row.max_relative = Some(acc.max() / scale);
                    row.rms_relative = Some(acc.rms() / scale);
                    row.com_relative = Some(acc.com_max() / scale);
                }
                Err(e) => row.status = e,
            }
            row
        })
        .collect();
    Ok(Some(ModelStudy {
        reference_model: REFERENCE_MODEL,
        reference_divisor: r,
        reference_tolerance: reference_tolerance(spec),
        displacement_scale: scale,
        reference_cpu_s_per_sim_s: per_sim_s(ref_out.cpu_s),
        reference_iterations_per_step: ref_out.work.iterations as f64 / ref_out.work.steps.max(1) as f64,
        reference_unconverged_steps: ref_out.work.unconverged_steps,
        tolerance: spec.model_tolerance,
        integrator: spec.reference_integrator,
        rows,
    }))
}
