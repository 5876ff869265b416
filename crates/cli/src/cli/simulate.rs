//! `diffsoft simulate`: the run with its frames and run log, kept current during the run and
//! finalised however it ends.

use super::prelude::*;

/// Set by SIGINT/SIGTERM: the run stops after its current step and finalises its log.
static INTERRUPTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// The token the steps run under: the first signal cancels it, so a step that runs long (a
/// contact solve of thousands of sweeps) stops within it, its state left as the step found it.
static CANCEL: std::sync::LazyLock<diffsoft::base::cancel::Cancel> =
    std::sync::LazyLock::new(diffsoft::base::cancel::Cancel::new);

/// Where `simulate` writes, and whether it may replace an earlier run's files.
pub(crate) struct RunOutput<'a> {
    pub(crate) dir: Option<&'a Path>,
    pub(crate) every: usize,
    pub(crate) overwrite: bool,
}

/// Catch SIGINT and SIGTERM from here on: the first stops the run within the current step
/// (which is dropped: the run ends at the last completed one; before the first step, when it
/// comes during the set-up) with its log finalised and exit status 130; a second ends the
/// process at once, also with 130. Called before the scene is loaded, so a signal during the
/// set-up ends the run the same way.
pub(crate) fn catch_signals() {
    std::sync::LazyLock::force(&CANCEL);
    if let Err(e) = ctrlc::set_handler(|| {
        // A second signal ends the process at once; the log of the last refresh stays.
        if INTERRUPTED.swap(true, std::sync::atomic::Ordering::SeqCst) {
            std::process::exit(130);
        }
        CANCEL.cancel();
    }) {
        warn!("warning: cannot catch SIGINT/SIGTERM ({e}); an interrupted run keeps its last log refresh");
    }
}

/// Run a scene, printing a summary and writing frames and the run log. The output directory is
/// checked before the first step; the log is kept current during the run and finalised however
/// it ends (completed, failed, or interrupted by SIGINT/SIGTERM, exit status 130).
pub(crate) fn simulate(
    sc: diffsoft::scene::Scene,
    steps: usize,
    out: RunOutput<'_>,
    activations: &[(String, f64)],
) -> Result<()> {
    use diffsoft::output::{FrameWriter, RunDir, RunLog, RunStatus, RunSummary, RUN_SCHEMA};
    use diffsoft::report::Header;
    use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
    use std::sync::atomic::Ordering;
    // The run log holds every step's figures: a step count it cannot hold is refused up front.
    diffsoft::base::memory::check(
        &format!("--steps {steps}"),
        steps,
        std::mem::size_of::<diffsoft::StepStats>(),
    )?;
    let mut run_dir = match out.dir {
        Some(dir) => Some(RunDir::prepare(dir, &[sc.path.as_path()], out.overwrite)?),
        None => None,
    };
    let model_size = diffsoft::report::ModelSize::of(&sc.model);

    let bodies: Vec<diffsoft::output::BodyLog> = sc.model.bodies().iter().map(diffsoft::output::BodyLog::of).collect();
    let cloth = sc.model.cloth().map_or(Vec::new(), |c| c.bodies.clone());
    say!(
        "scene       {} ({:?}): {} vertices, {} tets, {} bodies{}",
        sc.path.display(),
        sc.format,
        model_size.vertices,
        model_size.tets,
        bodies.len(),
        if cloth.is_empty() {
            String::new()
        } else {
            format!(", {} cloth ({} triangles)", cloth.len(), sc.model.num_cloth_triangles())
        }
    );
    for n in &sc.notes {
        say!("note        {n}");
    }
    for n in diffsoft::output::body_notes(&sc.model) {
        say!("note        {n}");
    }
    // Set-up errors from here on are recorded in the run log before they are returned.
    let fail = |run_dir: &mut Option<RunDir>, e: anyhow::Error| -> anyhow::Error {
        if let Some(d) = run_dir.as_mut() {
            if let Err(w) = d.write_setup_failure(&super::message(&e)) {
                return e.context(format!("and the run log could not record it: {w}"));
            }
        }
        e
    };
    // Inputs near the ends of f64's range, named when the set-up or a step fails numerically.
    let extremes = diffsoft::diff::params::extreme_inputs(&sc.model, sc.settings.dt);
    let numerical = |e: &diffsoft::SolverError| {
        use diffsoft::SolverError as E;
        matches!(
            e,
            E::Certification(_) | E::Factorization(_) | E::NonFinite(_) | E::Diverged(_) | E::Projection { .. }
        )
    };
    let with_extremes = |e: diffsoft::SolverError| -> anyhow::Error {
        if numerical(&e) && !extremes.is_empty() {
            anyhow::anyhow!("{e} (inputs at the edge of floating point: {})", extremes.join(", "))
        } else {
            e.into()
        }
    };
    let mut sim = diffsoft::solver::Simulator::new(sc.model, sc.settings.clone())
        .map_err(|e| fail(&mut run_dir, with_extremes(e)))?;
    say!("solver      {}", sim.certificate().message);
    if sc.settings.integrator == diffsoft::solver::Integrator::Bdf2 {
        say!(
            "integrator  bdf2 (docs/method.md Eq. T1): the matrix above is M/h_e^2 + L with h_e = 2h/3; the first step is implicit Euler on M/h^2 + L, factored when it is taken"
        );
    }
    for (name, a) in activations {
        sim.set_activation(name, *a).map_err(|e| {
            fail(
                &mut run_dir,
                anyhow::anyhow!("--activation {name}={}: {e}", diffsoft::base::number(*a)),
            )
        })?;
        say!("activation  {name} held at {}", diffsoft::base::number(*a));
    }
    let frames = match (&run_dir, out.every) {
        (Some(d), every) if every > 0 => Some(FrameWriter::new(d.path(), sim.model())),
        _ => None,
    };
    let mut frames = frames.transpose().map_err(|e| fail(&mut run_dir, e.into()))?;
    let mut log = RunLog {
        header: Header::new(RUN_SCHEMA),
        scene: sc.path.display().to_string(),
        notes: sc.notes.clone(),
        bodies,
        cloth,
        size: model_size,
        settings: sim.settings().clone(),
        damping_per_second: sim.settings().damping_per_second(),
        activations: activations.iter().cloned().collect(),
        certificate: sim.certificate().clone(),
        summary: RunSummary::of(&[]),
        steps: Vec::new(),
        frames: Vec::new(),
        status: RunStatus::Running,
        error: None,
    };
    let frame_name = |p: PathBuf| p.file_name().unwrap_or_default().to_string_lossy().into_owned();
    if let Some(f) = frames.as_mut() {
        let first = f.write_state(&sim).map_err(|e| fail(&mut run_dir, e.into()))?;
        log.frames.push(frame_name(first));
    }
    if let Some(d) = run_dir.as_mut() {
        if let Err(e) = d.write_log(&log) {
            return Err(fail(&mut run_dir, e.into()));
        }
    }
    let bar = ProgressBar::new(steps as u64);
    if steps < 50 || !std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} steps {elapsed_precise} eta {eta} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    for k in 0..steps {
        if INTERRUPTED.load(Ordering::SeqCst) {
            log.status = RunStatus::Interrupted;
            break;
        }
        match CANCEL.scope(|| sim.step()) {
            Ok(s) => {
                bar.set_message(format!("{} it", s.iterations));
                log.steps.push(s);
            }
            Err(diffsoft::SolverError::Interrupted) => {
                log.status = RunStatus::Interrupted;
                break;
            }
            Err(e) => {
                log.status = RunStatus::Failed;
                // Non-finite and divergence messages already name their step.
                let text = e.to_string();
                let text = if text.contains(&format!("step {}", k + 1)) {
                    text
                } else {
                    format!("step {}: {text}", k + 1)
                };
                log.error = Some(if numerical(&e) {
                    diffsoft::diff::params::name_extreme_inputs(text, sim.model(), sim.settings().dt)
                } else {
                    text
                });
                break;
            }
        }
        bar.inc(1);
        if let Some(f) = frames.as_mut() {
            if (k + 1) % out.every == 0 {
                match f.write_state(&sim) {
                    Ok(p) => log.frames.push(frame_name(p)),
                    Err(e) => return Err(fail_run(&mut run_dir, &mut log, e.into())),
                }
            }
        }
        if let Some(d) = run_dir.as_mut().filter(|d| d.log_due()) {
            log.summary = RunSummary::of(&log.steps);
            if let Err(e) = d.write_log(&log) {
                return Err(fail_run(&mut run_dir, &mut log, e.into()));
            }
        }
    }
    if log.status == RunStatus::Running {
        log.status = if INTERRUPTED.load(Ordering::SeqCst) && log.steps.len() < steps {
            RunStatus::Interrupted
        } else {
            RunStatus::Completed
        };
    }
    bar.finish_and_clear();
    log.summary = RunSummary::of(&log.steps);
    let summary = &log.summary;
    say!(
        "ran         {} steps ({:.4} s simulated) in {:.3} s: median {:.3} ms/step, {:.2} iterations/step, {} of {} converged, max penetration {:.3e} m, max contacts {} (between bodies {})",
        summary.steps,
        summary.simulated_time,
        summary.wall_time_s,
        summary.median_ms_per_step,
        summary.mean_iterations,
        summary.converged_steps,
        summary.steps,
        summary.max_penetration,
        summary.max_contacts,
        summary.max_pair_contacts
    );
    let settings = &log.settings;
    if settings.tolerance > 0.0 && summary.converged_steps < summary.steps {
        say!(
            "warning     {} of {} steps stopped at the iteration cap (max_iterations {}) before meeting the tolerance {:e}: their states carry that error (a stiff or fast scene can gain energy this way); raise --max-iterations or lower --dt; a gradient through this run is refused unless --allow-unconverged",
            summary.steps - summary.converged_steps,
            summary.steps,
            settings.max_iterations,
            // Four significant digits, shortest form (1e-6, 1.035e-5).
            format!("{:.3e}", settings.tolerance)
                .parse::<f64>()
                .unwrap_or(settings.tolerance)
        );
    }
    if let Some(diffsoft::output::EnergyGain { step, before, after }) =
        diffsoft::output::solver_energy_gain(sim.model(), &log.steps)
    {
        say!(
            "warning     step {step} stopped at the iteration cap and raised the total energy from {before:.4e} J to {after:.4e} J, in a scene with no energy source (no actuators or joint torques): that energy is the solver's, not the physics'; lower --dt or raise --max-iterations until no step gains energy"
        );
    }
    if summary.steps_with_capped_solves > 0 {
        say!(
            "warning     {} of {} steps had a global or contact solve stop unconverged, at its iteration cap (the scene's solver.inner_max_iterations) or stalled (no progress over a long batch of sweeps: an infeasible or badly conditioned contact set); capped_solves in the step log",
            summary.steps_with_capped_solves,
            summary.steps
        );
    }
    if summary.steps_with_pair_crossings > 0 {
        say!(
            "warning     {} of {} steps ended with bodies passing through each other (surface edges of one body crossing faces of another: contacts the run missed; pair_crossings in the step log): lower the time step or the speed, or raise the contact rounds",
            summary.steps_with_pair_crossings,
            summary.steps
        );
    }
    if summary.steps_with_swept_pairs > 0 {
        say!(
            "note        {} of {} steps kept bodies apart only with contacts found by sweeping their motion (surfaces that passed through each other within a contact round; swept_pairs in the step log): a gradient through them is refused; lower the time step or the speed for differentiable steps",
            summary.steps_with_swept_pairs,
            summary.steps
        );
    }
    if diffsoft::output::folded(summary.max_inverted_tets, model_size.tets) {
        say!(
            "warning     {} of {} steps ended with inverted tets (at most {} of {}; inverted_tets in the step log): a body folded through itself, under a load its material is too soft for or in too long a time step; its contacts cannot keep it apart from other bodies",
            summary.steps_with_inverted_tets,
            summary.steps,
            summary.max_inverted_tets,
            model_size.tets
        );
    }
    if let Some(d) = run_dir.as_mut() {
        if let Err(e) = d.write_log(&log) {
            let e = anyhow::Error::from(e).context("writing the final run log");
            return Err(fail_run(&mut run_dir, &mut log, e));
        }
        say!(
            "wrote       {} ({:?}) and {} frames{}",
            d.log_path().display(),
            log.status,
            log.frames.len(),
            if log.frames.is_empty() { "" } else { " (frames.pvd)" }
        );
    }
    match (log.status, log.error) {
        (RunStatus::Interrupted, _) => {
            warn!("interrupted after {} of {steps} steps", log.steps.len());
            std::process::exit(130);
        }
        (_, Some(e)) => bail!(e),
        _ => Ok(()),
    }
}

/// An error after the steps began: the run log says `failed` with the error (in place if the
/// disk takes nothing new, see `RunDir::write_failure`), and the error says if even that failed.
fn fail_run(
    run_dir: &mut Option<diffsoft::output::RunDir>,
    log: &mut diffsoft::output::RunLog,
    e: anyhow::Error,
) -> anyhow::Error {
    log.summary = diffsoft::output::RunSummary::of(&log.steps);
    if let Some(d) = run_dir.as_mut() {
        if let Err(w) = d.write_failure(log, &super::message(&e)) {
            return e.context(format!("and the run log could not record it: {w}"));
        }
    }
    e
}
