//! Assembly of the trade-off report: the partial reports of one scene's sweep (one per shard)
//! are checked ([`crate::shard::check_partials`]) and joined ([`finalize`]); gradient
//! errors against the reference gradients, then the fronts, recommendations and verdicts of
//! [`super::assess`].

use super::assess;
use diffsoft::base::Choice;
use std::collections::BTreeMap;

use super::report::*;
use super::{SceneSummary, TradeoffSpec};
use crate::shard::{check_partials, check_same, ShardError};
use diffsoft::solver::Integrator;

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
    divisor: impl Fn(&T) -> (Integrator, usize),
    same: impl Fn(&T, &T) -> bool,
) -> Result<Vec<T>, ShardError> {
    let mut out: BTreeMap<(Integrator, usize), (T, String)> = BTreeMap::new();
    for (list, path) in lists {
        for x in list {
            let d = divisor(&x);
            if let Some((y, p)) = out.get(&d) {
                if !same(y, &x) {
                    return Err(ShardError::Mismatch(format!(
                        "{what} ({}) at h/{} differs between {p} and {path} (different builds or inputs?)",
                        d.0.name(),
                        d.1
                    )));
                }
            } else {
                out.insert(d, (x, path.clone()));
            }
        }
    }
    Ok(out.into_values().map(|(x, _)| x).collect())
}

/// The most workers a partial report may say it ran on: one per thread, and no machine this
/// harness runs on has more threads than this (a larger count is a damaged or edited file).
const MAX_WORKERS: usize = 1 << 16;

/// The figures a row holds, checked for what its status says it has: a row that ran holds its
/// work (as many steps as the row), timing and trajectory errors, every figure finite and the
/// non-negative ones (times, errors, counts) not negative; a resolved row names a row of the
/// grid; a row that failed says why. `Err` names the first figure that is off.
fn check_row_figures(r: &Row, ids: &std::collections::HashSet<String>, dt: f64) -> Result<(), String> {
    let fig = figure;
    let want_dt = dt / r.setting.dt_divisor as f64;
    if !(r.dt > 0.0 && ((r.dt - want_dt) / want_dt).abs() <= 1e-9) {
        return Err(format!(
            "dt is {}, where the scene's step over {} is {}",
            diffsoft::base::number(r.dt),
            r.setting.dt_divisor,
            diffsoft::base::number(want_dt)
        ));
    }
    match r.status {
        Status::Ran => {
            let (Some(work), Some(t), Some(e)) = (&r.work, &r.timing, &r.trajectory) else {
                return Err("ran, but its work, timing or trajectory errors are missing".into());
            };
            if work.steps != r.steps || work.unconverged_steps > work.steps {
                return Err(format!(
                    "work counts {} steps ({} unconverged) for a row of {} steps",
                    work.steps, work.unconverged_steps, r.steps
                ));
            }
            if t.runs == 0 {
                return Err("timing counts 0 runs".into());
            }
            fig("timing.setup_s", t.setup_s, false)?;
            fig("timing.wall_s", t.wall_s, false)?;
            fig("timing.wall_s_per_sim_s", t.wall_s_per_sim_s, false)?;
            for (name, v) in [("timing.cpu_s", t.cpu_s), ("timing.cpu_s_per_sim_s", t.cpu_s_per_sim_s)] {
                if let Some(v) = v {
                    fig(name, v, false)?;
                }
            }
            for (name, v) in [
                ("max_vertex_error", e.max_vertex_error),
                ("rms_vertex_error", e.rms_vertex_error),
                ("com_error", e.com_error),
                ("max_relative", e.max_relative),
                ("rms_relative", e.rms_relative),
                ("com_relative", e.com_relative),
                ("solver_max_relative", e.solver_max_relative),
                ("solver_rms_relative", e.solver_rms_relative),
                ("energy_drift_error", e.energy_drift_error),
            ] {
                fig(&format!("trajectory.{name}"), v, false)?;
            }
            fig("trajectory.energy_drift", e.energy_drift, true)?;
        }
        Status::Resolved => match &r.resolved_to {
            Some(to) if ids.contains(to) => {}
            Some(to) => return Err(format!("is resolved to '{to}', which is not a row of the grid")),
            None => return Err("is resolved, but does not say to which row".into()),
        },
        Status::Diverged | Status::Rejected | Status::Panicked => {
            if r.message.as_deref().is_none_or(str::is_empty) {
                return Err("failed, but does not say why (no message)".into());
            }
        }
    }
    let g = &r.gradient;
    if let Some(v) = &g.values {
        for (k, &x) in v.iter().enumerate() {
            fig(&format!("gradient.values[{k}]"), x, true)?;
        }
    }
    for (name, v) in [("gradient.wall_s", g.wall_s), ("gradient.cpu_s", g.cpu_s)] {
        if let Some(v) = v {
            fig(name, v, false)?;
        }
    }
    Ok(())
}

/// A finite figure, not negative unless `signed`: `Err` says which and what it holds.
fn figure(name: &str, v: f64, signed: bool) -> Result<(), String> {
    if v.is_finite() && (signed || v >= 0.0) {
        Ok(())
    } else {
        let what = if signed { "finite" } else { "finite and not negative" };
        Err(format!("{name} must be {what}, got {}", diffsoft::base::number(v)))
    }
}

/// A reference trajectory's figures against the sweep it belongs to: its time step is the
/// scene's over its divisor, its run covers the sweep's horizon at that step, its tolerance and
/// cap are the sweep's reference settings, and its scale, drift and time are finite (the scale
/// positive: every relative error divides by it).
fn check_reference(r: &Reference, spec: &TradeoffSpec, scene: &SceneSummary) -> Result<(), String> {
    if r.dt_divisor == 0 {
        return Err("dt_divisor is 0".into());
    }
    let want_dt = scene.dt / r.dt_divisor as f64;
    if !(r.dt > 0.0 && ((r.dt - want_dt) / want_dt).abs() <= 1e-9) {
        return Err(format!(
            "dt is {}, where the scene's step over {} is {}",
            diffsoft::base::number(r.dt),
            r.dt_divisor,
            diffsoft::base::number(want_dt)
        ));
    }
    let steps = spec.steps * r.dt_divisor;
    if r.work.steps != steps || r.work.unconverged_steps > r.work.steps {
        return Err(format!(
            "work counts {} steps ({} unconverged) for {} steps of h/{} ({} steps of h)",
            r.work.steps, r.work.unconverged_steps, steps, r.dt_divisor, spec.steps
        ));
    }
    if r.tolerance != spec.reference_tolerance || r.max_iterations != spec.reference_max_iterations {
        return Err(format!(
            "its tolerance {} and cap {} are not the sweep's reference_tolerance {} and reference_max_iterations {}",
            diffsoft::base::number(r.tolerance),
            r.max_iterations,
            diffsoft::base::number(spec.reference_tolerance),
            spec.reference_max_iterations
        ));
    }
    if !(r.displacement_scale.is_finite() && r.displacement_scale > 0.0) {
        return Err(format!(
            "displacement_scale must be finite and positive, got {}",
            diffsoft::base::number(r.displacement_scale)
        ));
    }
    figure("wall_s", r.wall_s, false)?;
    figure("energy_drift", r.energy_drift, true)
}

/// What a partial report says of its sweep, beyond its rows: its inputs pass the same checks
/// as a sweep's inputs ([`TradeoffSpec::validate`]), the scene's figures are those of a scene
/// that ran (vertices, a positive step, length scale and mass), every reference trajectory fits
/// the sweep ([`check_reference`]), the main reference is at the sweep's reference divisor and
/// integrator, reference gradients hold finite figures, and the shard's time is finite.
fn check_partial_figures(p: &TradeoffPartial) -> Result<(), String> {
    p.spec.validate().map_err(|e| format!("its sweep inputs: {e}"))?;
    let sc = &p.scene;
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if sc.vertices == 0 || sc.fixed_vertices > sc.vertices {
        return Err(format!(
            "its scene has {} vertices ({} fixed)",
            sc.vertices, sc.fixed_vertices
        ));
    }
    for (name, v) in [("dt", sc.dt), ("length_scale", sc.length_scale), ("mass", sc.mass)] {
        if !positive(v) {
            return Err(format!(
                "its scene's {name} must be finite and positive, got {}",
                diffsoft::base::number(v)
            ));
        }
    }
    if p.reference.dt_divisor != p.spec.reference_divisor || p.reference.integrator != p.spec.reference_integrator {
        return Err(format!(
            "its reference is {} at h/{}, where the sweep's is {} at h/{}",
            p.reference.integrator.name(),
            p.reference.dt_divisor,
            p.spec.reference_integrator.name(),
            p.spec.reference_divisor
        ));
    }
    check_reference(&p.reference, &p.spec, sc).map_err(|e| format!("reference: {e}"))?;
    for r in &p.dt_references {
        check_reference(r, &p.spec, sc)
            .map_err(|e| format!("reference ({}) at h/{}: {e}", r.integrator.name(), r.dt_divisor))?;
    }
    for g in &p.gradient_references {
        let at = format!("reference gradient ({}) at h/{}", g.integrator.name(), g.dt_divisor);
        for (k, &v) in g.gradient.values.iter().flatten().enumerate() {
            figure(&format!("{at}: values[{k}]"), v, true)?;
        }
        for (name, v) in [("wall_s", g.gradient.wall_s), ("cpu_s", g.gradient.cpu_s)] {
            if let Some(v) = v {
                figure(&format!("{at}: {name}"), v, false)?;
            }
        }
    }
    let parameters: Vec<String> = super::PARAMETERS.iter().map(|p| p.to_string()).collect();
    if p.gradient_parameters != parameters {
        return Err(format!(
            "its gradient parameters are {:?}, where a sweep differentiates {parameters:?}",
            p.gradient_parameters
        ));
    }
    figure("wall_time_s", p.wall_time_s, false)
}

/// Assemble the partial reports of one sweep (every shard once; `paths` name them in errors)
/// into the scene's study.
pub fn finalize(parts: Vec<TradeoffPartial>, paths: &[String]) -> Result<SceneTradeoff, ShardError> {
    check_partials(&parts, paths, PARTIAL_SCHEMA)?;
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
    // The grid follows from the inputs (checked equal above): each shard's rows are checked
    // against it, not trusted.
    let grid = spec.grid();
    let total = grid.len();
    let ids: std::collections::HashSet<String> = grid.iter().map(|g| g.id()).collect();
    for (p, path) in parts.iter().zip(paths) {
        check_partial_figures(p).map_err(|e| ShardError::Mismatch(format!("{path}: {e}")))?;
    }
    if let Some((p, path)) = parts
        .iter()
        .zip(paths)
        .find(|(p, _)| p.workers == 0 || p.workers > MAX_WORKERS)
    {
        return Err(ShardError::Mismatch(format!(
            "{path} says it ran on {} workers (a run uses 1 to {MAX_WORKERS}: one per thread)",
            p.workers
        )));
    }
    if let Some((p, path)) = parts.iter().zip(paths).find(|(p, _)| p.total_rows != total) {
        return Err(ShardError::Mismatch(format!(
            "{path} says its sweep has {} rows, but its inputs give a grid of {total}",
            p.total_rows
        )));
    }
    let dt_references = union_by_divisor(
        "the reference trajectory",
        parts
            .iter()
            .zip(paths)
            .map(|(p, path)| (p.dt_references.clone(), path))
            .collect(),
        |r| (r.integrator, r.dt_divisor),
        |a, b| a.fingerprint == b.fingerprint,
    )?;
    let gradient_references = union_by_divisor(
        "the reference gradient",
        parts
            .iter()
            .zip(paths)
            .map(|(p, path)| (p.gradient_references.clone(), path))
            .collect(),
        |r| (r.integrator, r.dt_divisor),
        |a, b| a.gradient.values == b.gradient.values && a.gradient.message == b.gradient.message,
    )?;
    let mut owned: Vec<(Row, &String)> = parts
        .iter()
        .zip(paths)
        .flat_map(|(p, path)| p.rows.iter().cloned().map(move |r| (r, path)))
        .collect();
    owned.sort_by_key(|(r, _)| r.index);
    for w in owned.windows(2) {
        if w[0].0.index == w[1].0.index {
            return Err(ShardError::Mismatch(format!(
                "row {} is in both {} and {}",
                w[0].0.index, w[0].1, w[1].1
            )));
        }
    }
    for (r, path) in &owned {
        let Some(setting) = grid.get(r.index) else {
            return Err(ShardError::Mismatch(format!(
                "{path}: row index {} is past the grid's {total} rows",
                r.index
            )));
        };
        if r.id != setting.id() {
            return Err(ShardError::Mismatch(format!(
                "{path}: row {} is '{}', where the grid has '{}'",
                r.index,
                r.id,
                setting.id()
            )));
        }
        if r.setting != *setting {
            return Err(ShardError::Mismatch(format!(
                "{path}: row {} ('{}') holds a setting that is not the grid's (its family, knob, time step or integrator differs)",
                r.index, r.id
            )));
        }
        check_row_figures(r, &ids, scene.dt)
            .map_err(|e| ShardError::Mismatch(format!("{path}: row {} ('{}'): {e}", r.index, r.id)))?;
    }
    if owned.len() != total {
        return Err(ShardError::Mismatch(format!(
            "the shards hold {} of the grid's {total} rows",
            owned.len()
        )));
    }
    let mut rows: Vec<Row> = owned.into_iter().map(|(r, _)| r).collect();
    let models = parts.iter().find_map(|p| p.models.clone());
    if !spec.models.is_empty() && models.is_none() {
        return Err(ShardError::Mismatch(
            "the sweep compares material models, but no shard holds the comparison (the first shard runs it)".into(),
        ));
    }
    let workers: Vec<usize> = parts.iter().map(|p| p.workers).collect();
    let shard_provenance = parts.iter().map(|p| p.provenance.clone()).collect();
    let wall_time_s = parts.iter().map(|p| p.wall_time_s).sum();
    let grad_ref = |i: Integrator, d: usize| {
        gradient_references
            .iter()
            .find(|g| g.dt_divisor == d && g.integrator == i)
            .and_then(|g| g.gradient.values.clone())
    };
    let total_ref = grad_ref(spec.reference_integrator, spec.reference_divisor);
    for r in rows.iter_mut() {
        if let Some(v) = r.gradient.values.clone() {
            r.gradient.error = total_ref.as_deref().and_then(|g| rel_vec_error(&v, g));
            r.gradient.solver_error =
                grad_ref(r.setting.integrator, r.setting.dt_divisor).and_then(|g| rel_vec_error(&v, &g));
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
            "direct solver, tolerance {:e} (RMS change per iteration relative to the length scale {:.4} m), cap {} iterations, Anderson memory {}, {} at h/{} = {:e} s for the total error and each setting's integrator at every grid step h/d for the solver error; reference gradients: unrolled, same tolerance, no Anderson",
            spec.reference_tolerance,
            scene.length_scale,
            spec.reference_max_iterations,
            spec.reference_anderson,
            spec.reference_integrator.name(),
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
        timing: "each setting and reference runs on one thread (its own one-thread rayon pool); `workers` settings run at once; a setting's forward run is repeated until min_timing_s of CPU time is measured (the thread CPU clock, CLOCK_THREAD_CPUTIME_ID, read to the nanosecond); cpu_s is the total over the runs / runs, wall_s the median run; thread CPU time does not count the time a thread waits for a core, wall time does, but both move with what the concurrent settings do to the shared caches and memory (settings doing identical work differ by about 1.2x in the median); the fronts use the time_axis".into(),
        workers,
        shards: parts.len(),
        shard_provenance,
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
        models,
        svg: Vec::new(),
        wall_time_s,
    })
}

/// Merge the partial reports of one sweep into a report.
pub fn merge(parts: Vec<TradeoffPartial>, paths: &[String]) -> Result<TradeoffReport, ShardError> {
    Ok(TradeoffReport::new(vec![finalize(parts, paths)?]))
}
