//! Running a sweep: the references first (their states are what every setting is compared
//! with), then the settings and the reference gradients, all single-threaded on the workers of
//! [`super::pool`], with a progress bar.

use std::collections::HashMap;
use std::path::Path;
use std::sync::LazyLock;
use std::time::Instant;

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use nalgebra::Vector3;

use super::report::{
    GradientReference, GradientResult, Reference, ReferenceCheck, Row, Status, Timing, TrajectoryErrors,
};
use super::trajectory::{self, advance, ErrorAcc};
use super::{
    reference_settings, scene, Family, Knob, SceneSummary, Setting, TradeoffError, TradeoffPartial, TradeoffSpec,
    MAX_TIMING_RUNS, PARTIAL_SCHEMA,
};
use crate::pool::{self, Task};
use crate::report::{write_json, CRATE_VERSION};
use crate::shard::Shard;
use diffsoft::diff::{self, loss::Loss, Controls, Mode, Options, Param};
use diffsoft::model::Model;
use diffsoft::solver::{Integrator, Settings, Simulator, SolverKind, Systems};

/// The gradient parameters: Young's modulus, Poisson ratio, density.
pub const PARAMETERS: [Param; 3] = [Param::YOUNGS_MODULUS, Param::POISSON_RATIO, Param::DENSITY];

/// A reference trajectory's sampled states.
struct RefStates {
    q: Vec<Vec<Vector3<f64>>>,
    energy_drift: f64,
    /// Relative errors divide by this (m).
    scale: f64,
}

/// What every task reads.
struct Ctx<'a> {
    spec: &'a TradeoffSpec,
    model: &'a Model,
    base: &'a Settings,
    loss: Box<dyn Loss>,
    e0: f64,
    e_scale: f64,
    /// The scene's global systems, shared by every run of the sweep (each step size's matrix
    /// is factored and certified once).
    systems: Systems,
}

/// The progress bars of the sweeps running at once (one line each on a terminal).
static BARS: LazyLock<MultiProgress> = LazyLock::new(MultiProgress::new);

fn progress(len: usize, label: &str, show: bool) -> ProgressBar {
    let bar = ProgressBar::new(len as u64);
    let bar = if !show || !std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        bar.set_draw_target(ProgressDrawTarget::hidden());
        bar
    } else {
        BARS.add(bar)
    };
    bar.set_style(
        ProgressStyle::with_template("{prefix} {bar:40} {pos}/{len} runs {elapsed_precise} eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_prefix(label.to_string());
    bar
}

/// A reference trajectory is keyed by its integrator and time-step divisor.
type RefKey = (Integrator, usize);

fn reference_run(ctx: &Ctx<'_>, (integrator, divisor): RefKey) -> Result<(Reference, RefStates), String> {
    let spec = ctx.spec;
    let settings = reference_settings(ctx.base, spec, divisor, spec.reference_anderson, integrator);
    let t0 = Instant::now();
    let mut sim =
        Simulator::with_systems(ctx.model.clone(), settings.clone(), &ctx.systems).map_err(|e| e.to_string())?;
    let mut q = Vec::with_capacity(spec.steps);
    let out = advance(&mut sim, spec.steps * divisor, divisor, |_, x| q.push(x.to_vec())).map_err(|f| f.to_string())?;
    let energy_drift = (out.final_energy - ctx.e0) / ctx.e_scale;
    let scale = match trajectory::displacement_scale(ctx.model, &q) {
        s if s > 0.0 => s,
        _ => ctx.model.length_scale(),
    };
    Ok((
        Reference {
            dt_divisor: divisor,
            integrator,
            dt: settings.dt,
            tolerance: settings.tolerance,
            max_iterations: settings.max_iterations,
            anderson: settings.anderson,
            work: out.work,
            wall_s: t0.elapsed().as_secs_f64(),
            displacement_scale: scale,
            energy_drift,
            fingerprint: trajectory::fingerprint(&q),
        },
        RefStates { q, energy_drift, scale },
    ))
}

fn gradient(ctx: &Ctx<'_>, settings: &Settings, steps: usize) -> GradientResult {
    let cpu0 = trajectory::thread_cpu_s();
    let t0 = Instant::now();
    let g = diff::gradient_on(
        &ctx.systems,
        ctx.model,
        settings,
        steps,
        &Controls::default(),
        ctx.loss.as_ref(),
        // The study measures gradients of unconverged settings too (their stats say so). Newton
        // is differentiated at its converged step (implicit mode), the others unrolled.
        Options {
            allow_unconverged: true,
            ..Options::mode(if settings.solver == SolverKind::Newton {
                Mode::Implicit
            } else {
                Mode::Unrolled
            })
        },
        &mut |_| {},
    );
    let wall_s = Some(t0.elapsed().as_secs_f64());
    let cpu_s = match (cpu0, trajectory::thread_cpu_s()) {
        (Some(a), Some(b)) => Some(b - a),
        _ => None,
    };
    let mut out = GradientResult {
        wall_s,
        cpu_s,
        ..Default::default()
    };
    match g {
        Ok(g) => {
            let values: Result<Vec<f64>, _> = PARAMETERS
                .iter()
                .map(|p| p.get(ctx.model).map(|v| v * p.derivative(ctx.model, &g)))
                .collect();
            match values {
                Ok(v) if v.iter().all(|x| x.is_finite()) => out.values = Some(v),
                Ok(v) => out.message = Some(format!("non-finite gradient {v:?}")),
                Err(e) => out.message = Some(e.to_string()),
            }
        }
        Err(e) => out.message = Some(e.to_string()),
    }
    out
}

/// Relative steps of a reference gradient's finite-difference check.
const REFERENCE_CHECK_STEPS: [f64; 2] = [1e-3, 1e-4];

/// Largest relative disagreement of a reference gradient with its closest central difference.
const REFERENCE_CHECK_RTOL: f64 = 0.1;

fn gradient_reference(ctx: &Ctx<'_>, (integrator, divisor): RefKey) -> GradientReference {
    let settings = reference_settings(ctx.base, ctx.spec, divisor, 0, integrator);
    let steps = ctx.spec.steps * divisor;
    let mut gradient = gradient(ctx, &settings, steps);
    // A loss that jumps at this resolution (contacts or joint limits switching within a step)
    // has a derivative that means nothing: measured errors against it would all be about 1.
    let fd_check = gradient
        .values
        .as_ref()
        .and_then(|v| v.first().copied())
        .and_then(|analytic| reference_check(ctx, &settings, steps, analytic));
    if let Some(c) = fd_check.as_ref().filter(|c| !c.agrees) {
        gradient.message = Some(format!(
            "withdrawn: the reference's E dL/dE = {:.3e} disagrees with central differences of its own loss ({:?} at relative steps {:?}); the loss is not differentiable at this resolution",
            c.analytic, c.central_differences, c.steps
        ));
        gradient.values = None;
    }
    GradientReference {
        dt_divisor: divisor,
        integrator,
        gradient,
        fd_check,
    }
}

/// The reference gradient's first component (`p dL/dp`, Young's modulus) against central
/// differences of the same loss; `None` when a forward run fails.
fn reference_check(ctx: &Ctx<'_>, settings: &Settings, steps: usize, analytic: f64) -> Option<ReferenceCheck> {
    let p = PARAMETERS[0];
    let x = p.get(ctx.model).ok()?;
    let loss_at = |value: f64| -> Option<f64> {
        let mut model = ctx.model.clone();
        p.set(&mut model, value).ok()?;
        diff::loss_value_on(
            &ctx.systems,
            &model,
            settings,
            steps,
            &Controls::default(),
            ctx.loss.as_ref(),
        )
        .ok()
    };
    let mut central = Vec::new();
    for e in REFERENCE_CHECK_STEPS {
        central.push((loss_at(x * (1.0 + e))? - loss_at(x * (1.0 - e))?) / (2.0 * e));
    }
    let agrees = central
        .iter()
        .any(|fd| (analytic - fd).abs() <= REFERENCE_CHECK_RTOL * fd.abs().max(1e-12));
    Some(ReferenceCheck {
        analytic,
        central_differences: central,
        steps: REFERENCE_CHECK_STEPS.to_vec(),
        agrees,
    })
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn run_row(ctx: &Ctx<'_>, refs: &HashMap<RefKey, RefStates>, index: usize, setting: Setting) -> Row {
    let spec = ctx.spec;
    let d = setting.dt_divisor;
    let settings = setting.settings(ctx.base, spec);
    let steps = spec.steps * d;
    let mut row = Row {
        index,
        id: setting.id(),
        setting,
        dt: settings.dt,
        steps,
        status: Status::Ran,
        message: None,
        solver_used: None,
        certificate: None,
        resolved_to: None,
        work: None,
        timing: None,
        trajectory: None,
        gradient: GradientResult::default(),
    };
    let t0 = Instant::now();
    let mut sim = match Simulator::with_systems(ctx.model.clone(), settings.clone(), &ctx.systems) {
        Ok(s) => s,
        Err(e) => {
            row.status = Status::Rejected;
            row.message = Some(e.to_string());
            row.gradient.message = Some("not computed: the settings were rejected".into());
            return row;
        }
    };
    let setup_s = t0.elapsed().as_secs_f64();
    let cert = sim.certificate();
    row.solver_used = Some(cert.used);
    row.certificate = Some(cert.message.clone());
    let running = Family::running(cert.used, settings.anderson);
    if running != setting.family && spec.families.contains(&running) {
        row.status = Status::Resolved;
        row.resolved_to = Some(
            Setting {
                family: running,
                ..setting
            }
            .id(),
        );
        row.gradient.message = Some("not computed: see resolved_to".into());
        return row;
    }
    let (total_ref, same_ref) = (
        &refs[&(spec.reference_integrator, spec.reference_divisor)],
        &refs[&(setting.integrator, d)],
    );
    let mut total = ErrorAcc::default();
    let mut solver = ErrorAcc::default();
    let first = advance(&mut sim, steps, d, |k, q| {
        total.add(ctx.model, q, &total_ref.q[k]);
        solver.add(ctx.model, q, &same_ref.q[k]);
    });
    let first = match first {
        Ok(o) => o,
        Err(f) => {
            row.status = Status::Diverged;
            row.message = Some(f.to_string());
            row.gradient.message = Some("not computed: the forward run failed".into());
            return row;
        }
    };
    row.work = Some(first.work);
    // Repeat until min_timing_s is measured: short runs are timed by their total over several
    // runs, which averages their run-to-run noise.
    let mut walls = vec![first.wall_s];
    let mut cpu_total = first.cpu_s;
    let measured = |walls: &[f64], cpu: Option<f64>| cpu.unwrap_or_else(|| walls.iter().sum());
    while walls.len() < MAX_TIMING_RUNS && measured(&walls, cpu_total) < spec.min_timing_s {
        let Ok(mut again) = Simulator::with_systems(ctx.model.clone(), settings.clone(), &ctx.systems) else {
            break;
        };
        match advance(&mut again, steps, d, |_, _| {}) {
            Ok(o) => {
                walls.push(o.wall_s);
                cpu_total = cpu_total.zip(o.cpu_s).map(|(a, b)| a + b);
            }
            Err(_) => break,
        }
    }
    let runs = walls.len();
    let wall_s = median(&mut walls);
    let cpu_s = cpu_total.map(|c| c / runs as f64);
    let sim_s = spec.steps as f64 * ctx.base.dt;
    row.timing = Some(Timing {
        setup_s,
        runs,
        wall_s,
        cpu_s,
        wall_s_per_sim_s: wall_s / sim_s,
        cpu_s_per_sim_s: cpu_s.map(|c| c / sim_s),
    });
    let scale = total_ref.scale;
    let drift = (first.final_energy - ctx.e0) / ctx.e_scale;
    row.trajectory = Some(TrajectoryErrors {
        max_vertex_error: total.max(),
        rms_vertex_error: total.rms(),
        com_error: total.com_max(),
        max_relative: total.max() / scale,
        rms_relative: total.rms() / scale,
        com_relative: total.com_max() / scale,
        solver_max_relative: solver.max() / scale,
        solver_rms_relative: solver.rms() / scale,
        energy_drift: drift,
        energy_drift_error: (drift - total_ref.energy_drift).abs(),
    });
    row.gradient = if spec.gradient_dt_divisors.contains(&d) {
        gradient(ctx, &settings, steps)
    } else {
        GradientResult {
            message: Some(format!(
                "not computed: gradients are requested at dt divisors {:?} only",
                spec.gradient_dt_divisors
            )),
            ..Default::default()
        }
    };
    row
}

/// A setting's iteration cap (a tolerance's: the sweep's largest cap), for ordering the tasks.
fn cap(spec: &TradeoffSpec, s: &Setting) -> usize {
    match s.knob {
        Knob::Cap(k) => k,
        Knob::Tolerance(_) => spec.caps.iter().copied().max().unwrap_or(1),
    }
}

/// Run shard `shard` of a sweep; scene files resolve against `base`; `workers` settings run at
/// once; `show_progress` draws a progress bar on a terminal.
pub fn run_shard(
    spec: &TradeoffSpec,
    base: &Path,
    shard: Shard,
    workers: usize,
    show_progress: bool,
) -> Result<TradeoffPartial, TradeoffError> {
    let t0 = Instant::now();
    spec.validate()?;
    let (model, base_settings) = scene::load(&spec.name, &spec.source, base)?;
    // A loss the model cannot have (a joint angle without a skeleton) is refused before any
    // run, not left in every gradient row.
    let loss = diff::loss::by_name(&spec.loss)
        .and_then(|l| l.validate(&model).map(|()| l))
        .map_err(|e| TradeoffError::Spec {
            name: spec.name.clone(),
            message: e.to_string(),
        })?;
    let ctx = Ctx {
        spec,
        model: &model,
        base: &base_settings,
        loss,
        e0: trajectory::initial_energy(&model),
        e_scale: trajectory::energy_scale(&model),
        systems: Systems::new(),
    };
    let grid = spec.grid();
    let owned: Vec<(usize, Setting)> = grid
        .iter()
        .copied()
        .enumerate()
        .filter(|(i, _)| shard.owns(*i))
        .collect();
    let total_key = (spec.reference_integrator, spec.reference_divisor);
    let mut divisors: Vec<RefKey> = vec![total_key];
    for (_, s) in &owned {
        if !divisors.contains(&(s.integrator, s.dt_divisor)) {
            divisors.push((s.integrator, s.dt_divisor));
        }
    }
    let mut grad_divisors: Vec<RefKey> = Vec::new();
    if owned
        .iter()
        .any(|(_, s)| spec.gradient_dt_divisors.contains(&s.dt_divisor))
    {
        grad_divisors.push(total_key);
        for (_, s) in &owned {
            let key = (s.integrator, s.dt_divisor);
            if spec.gradient_dt_divisors.contains(&s.dt_divisor) && !grad_divisors.contains(&key) {
                grad_divisors.push(key);
            }
        }
    }
    // One run's set-up per step size and family, done in the first phase (below).
    let mut warm: Vec<Setting> = Vec::new();
    for (_, s) in &owned {
        if !warm
            .iter()
            .any(|w| (w.integrator, w.dt_divisor, w.family) == (s.integrator, s.dt_divisor, s.family))
        {
            warm.push(*s);
        }
    }
    let model_runs = if shard.index == 0 && !spec.models.is_empty() {
        1 + spec.models.len() * spec.dt_divisors.len()
    } else {
        0
    };
    let bar = progress(
        divisors.len() + grad_divisors.len() + warm.len() + owned.len() + model_runs,
        &spec.name,
        show_progress,
    );
    // Phase 1: reference trajectories and, alongside (they need no trajectory), the reference
    // gradients; the longest tasks first (gradients, then the finest steps).
    for keys in [&mut grad_divisors, &mut divisors] {
        keys.sort_by_key(|&(_, d)| std::cmp::Reverse(d));
    }
    enum First {
        Ref(Result<(Reference, RefStates), String>),
        Grad(GradientReference),
        /// A step size's systems set up (factor, certification), or why not (the rows say).
        Warm,
    }
    let mut first: Vec<Task<'_, First>> = Vec::new();
    for &d in &grad_divisors {
        let ctx = &ctx;
        first.push(Box::new(move || First::Grad(gradient_reference(ctx, d))));
    }
    for &d in &divisors {
        let ctx = &ctx;
        first.push(Box::new(move || First::Ref(reference_run(ctx, d))));
    }
    // Last and alongside the references: one run's set-up per step size and family, so the
    // shared systems hold every factor and certification (the extremes of G21 take seconds on
    // a large mesh) before the rows start; rows that started together would otherwise each
    // wait for, or repeat, the same set-up.
    for s in &warm {
        let ctx = &ctx;
        first.push(Box::new(move || {
            let _ = Simulator::with_systems(ctx.model.clone(), s.settings(ctx.base, ctx.spec), &ctx.systems);
            First::Warm
        }));
    }
    let keys: Vec<Option<(bool, RefKey)>> = grad_divisors
        .iter()
        .map(|&d| Some((true, d)))
        .chain(divisors.iter().map(|&d| Some((false, d))))
        .chain(warm.iter().map(|_| None))
        .collect();
    let mut refs = HashMap::new();
    let mut reference = None;
    let mut dt_references = Vec::new();
    let mut gradient_references = Vec::new();
    for (key, r) in keys.iter().zip(pool::run(first, workers, &bar)) {
        // A set-up that failed or panicked fails again in its rows, which report it.
        let Some((is_grad, key)) = *key else {
            continue;
        };
        match (r, is_grad) {
            (Ok(First::Grad(g)), _) => gradient_references.push(g),
            (Err(panic), true) => gradient_references.push(GradientReference {
                dt_divisor: key.1,
                integrator: key.0,
                gradient: GradientResult {
                    message: Some(format!("panicked: {panic}")),
                    ..Default::default()
                },
                fd_check: None,
            }),
            (r, _) => {
                let r = match r {
                    Ok(First::Ref(x)) => x,
                    Ok(First::Grad(_) | First::Warm) => Err("another task in a reference slot".into()),
                    Err(panic) => Err(panic),
                };
                let (info, states) = r.map_err(|message| TradeoffError::Reference {
                    name: spec.name.clone(),
                    divisor: key.1,
                    message,
                })?;
                if key == total_key {
                    reference = Some(info);
                } else {
                    dt_references.push(info);
                }
                refs.insert(key, states);
            }
        }
    }
    dt_references.sort_by_key(|r| (r.integrator, r.dt_divisor));
    let reference = reference.ok_or_else(|| TradeoffError::Reference {
        name: spec.name.clone(),
        divisor: spec.reference_divisor,
        message: "missing".into(),
    })?;
    // Phase 2: the settings, larger step counts and then larger iteration caps first so the
    // last tasks are short (a step size's settings together: they share its system).
    let mut order: Vec<(usize, Setting)> = owned.clone();
    order.sort_by_key(|(i, s)| (std::cmp::Reverse((s.dt_divisor, cap(spec, s))), *i));
    let mut tasks: Vec<Task<'_, Row>> = Vec::new();
    for &(i, s) in &order {
        let (ctx, refs) = (&ctx, &refs);
        tasks.push(Box::new(move || run_row(ctx, refs, i, s)));
    }
    let mut rows = Vec::new();
    for ((i, s), r) in order.iter().copied().zip(pool::run(tasks, workers, &bar)) {
        match r {
            Ok(row) => rows.push(row),
            Err(panic) => rows.push(Row {
                index: i,
                id: s.id(),
                setting: s,
                dt: base_settings.dt / s.dt_divisor as f64,
                steps: spec.steps * s.dt_divisor,
                status: Status::Panicked,
                message: Some(format!("panicked: {panic}")),
                solver_used: None,
                certificate: None,
                resolved_to: None,
                work: None,
                timing: None,
                trajectory: None,
                gradient: GradientResult::default(),
            }),
        }
    }
    // The material models (the first shard's), after the grid.
    let models = if shard.index == 0 {
        super::models::study(spec, &model, &base_settings, workers, &bar)?
    } else {
        None
    };
    bar.finish_and_clear();
    BARS.remove(&bar);
    rows.sort_by_key(|r| r.index);
    gradient_references.sort_by_key(|g| (g.integrator, g.dt_divisor));
    Ok(TradeoffPartial {
        schema: PARTIAL_SCHEMA.into(),
        crate_version: CRATE_VERSION.into(),
        provenance: Some(crate::report::Provenance::now()),
        shard,
        spec: spec.clone(),
        scene: SceneSummary::of(&model, &base_settings),
        gradient_parameters: PARAMETERS.iter().map(|p| p.to_string()).collect(),
        total_rows: grid.len(),
        reference,
        dt_references,
        gradient_references,
        rows,
        models,
        workers,
        wall_time_s: t0.elapsed().as_secs_f64(),
    })
}

/// Run a whole sweep (one shard) and assemble its study.
pub fn run_scene(
    spec: &TradeoffSpec,
    base: &Path,
    workers: usize,
    show_progress: bool,
) -> Result<super::SceneTradeoff, TradeoffError> {
    let part = run_shard(spec, base, Shard::ALL, workers, show_progress)?;
    super::finalize(vec![part], &["(unsharded run)".to_string()]).map_err(|e| TradeoffError::Output {
        name: spec.name.clone(),
        message: e.to_string(),
    })
}

/// Write the plots of a study into `dir` and record their names in it.
pub fn write_plots(s: &mut super::SceneTradeoff, dir: &Path) -> Result<(), TradeoffError> {
    let err = |e: std::io::Error| TradeoffError::Output {
        name: s.name.clone(),
        message: e.to_string(),
    };
    let names = super::chart::write(s, dir).map_err(err)?;
    s.svg = names;
    Ok(())
}

/// The part of a sweep's plot names taken from its name (`name` with every character other
/// than an ASCII letter or digit replaced by `_`).
fn plot_slug(name: &str) -> String {
    name.chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect()
}

/// The file names [`write_plots`] may give the plots of the sweep `name` (in its directory):
/// `tradeoff_<slug>.svg` and `tradeoff_<slug>_gradient.svg`.
///
/// ```
/// let names = diffsoft_harness::tradeoff::plot_names("beam 1");
/// assert_eq!(names, ["tradeoff_beam_1.svg", "tradeoff_beam_1_gradient.svg"]);
/// ```
pub fn plot_names(name: &str) -> [String; 2] {
    let slug = plot_slug(name);
    [format!("tradeoff_{slug}.svg"), format!("tradeoff_{slug}_gradient.svg")]
}

/// The main job's section: every sweep of the suite, `out/tradeoff.json` and the plots. The
/// sweeps run at once on shared cores ([`pool::concurrently`]: one sweep's phase tails overlap
/// another's work, still one setting per core); their summaries print in suite order.
pub fn suite_section(base: &Path, out: &Path, specs: &[TradeoffSpec]) -> Result<super::TradeoffReport, TradeoffError> {
    let workers = rayon::current_num_threads();
    let jobs: Vec<Task<'_, _>> = specs
        .iter()
        .map(|spec| -> Task<'_, _> {
            Box::new(move || {
                let mut s = run_scene(spec, base, workers, true)?;
                let plots = write_plots(&mut s, out);
                Ok((s, plots))
            })
        })
        .collect();
    let mut scenes = Vec::new();
    // Data before plots: a plot that cannot be drawn is reported after the report is written.
    let mut plots = Ok(());
    for r in pool::concurrently(jobs, workers) {
        let (s, p): (super::SceneTradeoff, Result<(), TradeoffError>) = r?;
        plots = plots.and(p);
        crate::say_raw!("{}", super::summary(&s));
        scenes.push(s);
    }
    let report = super::TradeoffReport::new(scenes);
    diffsoft::output::own_file(out, "tradeoff.json")
        .map_err(anyhow::Error::from)
        .and_then(|path| write_json(path, &report).map_err(anyhow::Error::from))
        .map_err(|e| TradeoffError::Output {
            name: "tradeoff".into(),
            message: e.to_string(),
        })?;
    plots?;
    Ok(report)
}
