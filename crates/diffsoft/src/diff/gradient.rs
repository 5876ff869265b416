//! The gradient of a whole simulation: the forward pass with checkpoints, then the backward
//! pass over the steps in reverse (unrolled mode replays each step from its checkpoint unless
//! its recording was kept), with the loss's terms entering at each step.

use std::time::Instant;

use nalgebra::Vector3;

use super::backward::{Backward, StepInputs};
use super::forward::{forward, set_controls, Forward, Keep};
use super::loss::{Loss, LossGrad};
use super::recording::Recording;
use super::{Controls, DiffError, DiffStats, Gradient, Mode, Options};
use crate::model::Model;
use crate::solver::integrator::Scheme;
use crate::solver::Checkpoint;
use crate::solver::{Integrator, Settings, Simulator, SolverError, SolverKind, Systems};

/// Where a gradient evaluation is (for progress reports and observers).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Progress {
    /// Forward step `k` (0-based) is done.
    Forward(usize),
    /// The backward of step `k` (0-based; they run last to first) is done.
    Backward(usize),
}

/// The solver a gradient runs its forward with: the settings' own, except that `auto` becomes
/// one whose backward pass exists, `newton` for hyperelastic materials and `direct` with
/// contacts (obstacles or collisions between bodies), where the iterative solvers keep no
/// impulses; `None` when the settings stand. A requested solver is never changed (one that
/// cannot be differentiated is an error of [`gradient`]).
///
/// ```
/// use diffsoft::diff::differentiable_solver;
/// use diffsoft::testing::ground_box;
/// use diffsoft::{Settings, SolverKind};
///
/// let model = ground_box(0.5)?;
/// assert_eq!(differentiable_solver(&model, &Settings::default()), Some(SolverKind::Direct));
/// let direct = Settings { solver: SolverKind::Split, ..Settings::default() };
/// assert_eq!(differentiable_solver(&model, &direct), None);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn differentiable_solver(model: &Model, settings: &Settings) -> Option<SolverKind> {
    if settings.solver != SolverKind::Auto {
        return None;
    }
    if model.bodies.iter().any(|b| b.model.is_hyperelastic()) {
        return Some(SolverKind::Newton);
    }
    (!model.obstacles.is_empty() || model.collision.is_some()).then_some(SolverKind::Direct)
}

/// `settings` with [`differentiable_solver`] applied.
fn differentiable(model: &Model, settings: &Settings) -> Settings {
    let mut s = settings.clone();
    if let Some(k) = differentiable_solver(model, settings) {
        s.solver = k;
    }
    s
}

fn check_supported(model: &Model, settings: &Settings, mode: Mode) -> Result<(), DiffError> {
    if let Some(o) = model.obstacles.iter().find(|o| !o.shape.piecewise_planar()) {
        return Err(DiffError::Unsupported(format!(
            "obstacle '{}' is a curved {} surface: the backward pass holds contact normals fixed, which is exact only on piecewise planar shapes (planes, triangle meshes)",
            o.name,
            o.shape.kind()
        )));
    }
    if mode == Mode::Unrolled && settings.anderson > 0 {
        return Err(DiffError::Unsupported(
            "unrolled gradients through Anderson acceleration; use anderson = 0 or --mode implicit".into(),
        ));
    }
    if let (Mode::Unrolled, Some(b)) = (mode, model.bodies.iter().find(|b| b.model.is_hyperelastic())) {
        return Err(DiffError::Unsupported(format!(
            "unrolled gradients of a hyperelastic material (body '{}' is {}): it runs with Newton's method, whose gradients differentiate the converged step; use --mode implicit (mode=\"implicit\")",
            b.name,
            crate::base::Choice::name(b.model)
        )));
    }
    if mode == Mode::Unrolled && settings.solver == SolverKind::Newton {
        return Err(DiffError::Unsupported(
            "unrolled gradients through Newton's method (they differentiate local-global iterations); use --mode implicit, which differentiates the converged step whichever solver found it, or solver: direct".into(),
        ));
    }
    // Newton's method records its contacts' impulses at the converged step as the direct
    // solver does (implicit mode only, above).
    if !model.obstacles.is_empty() && !matches!(settings.solver, SolverKind::Direct | SolverKind::Newton) {
        return Err(DiffError::Unsupported(
            "gradients with contact need the direct solver (solver: direct) or Newton's method in implicit mode (solver: newton)".into(),
        ));
    }
    Ok(())
}

/// The loss of a forward run alone (for finite differences).
///
/// ```
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
/// use diffsoft::diff::loss::CenterOfMass;
/// use diffsoft::{loss_value, Controls, Settings};
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let model = ModelBuilder::new()
///     .gravity(nalgebra::Vector3::new(0.0, -9.81, 0.0))
///     .body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0)))
///     .build()?;
/// let com_y = CenterOfMass { direction: nalgebra::Vector3::y(), time_average: false, vertices: None };
/// let settings = Settings::default();
/// let y = loss_value(&model, &settings, 3, &Controls::default(), &com_y)?;
/// // Free fall from a centre at 0.05 m: implicit Euler gives 0.05 - (1 + 2 + 3) g dt^2.
/// assert!((y - (0.05 - 6.0 * 9.81 * 1e-4)).abs() < 1e-8, "{y}");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn loss_value(
    model: &Model,
    settings: &Settings,
    steps: usize,
    controls: &Controls,
    loss: &dyn Loss,
) -> Result<f64, DiffError> {
    loss_value_on(&Systems::new(), model, settings, steps, controls, loss)
}

/// [`loss_value`] on shared systems (see [`Simulator::with_systems`]): the repeated runs of a
/// finite-difference check factor and certify once.
///
/// ```
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
/// use diffsoft::diff::loss::CenterOfMass;
/// use diffsoft::diff::loss_value_on;
/// use diffsoft::solver::Systems;
/// use diffsoft::{Controls, Settings};
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let model = ModelBuilder::new()
///     .gravity(nalgebra::Vector3::new(0.0, -9.81, 0.0))
///     .body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0)))
///     .build()?;
/// let com_y = CenterOfMass { direction: nalgebra::Vector3::y(), time_average: false, vertices: None };
/// let systems = Systems::new();
/// // A central difference in the initial height: both runs share one factored system.
/// let eps = 1e-4;
/// let shifted = |dy: f64| {
///     let q0 = model.rest().iter().map(|q| q + nalgebra::Vector3::y() * dy).collect();
///     Controls { initial: Some((q0, vec![nalgebra::Vector3::zeros(); model.n()])), ..Controls::default() }
/// };
/// let up = loss_value_on(&systems, &model, &Settings::default(), 3, &shifted(eps), &com_y)?;
/// let down = loss_value_on(&systems, &model, &Settings::default(), 3, &shifted(-eps), &com_y)?;
/// assert!(((up - down) / (2.0 * eps) - 1.0).abs() < 1e-6);
/// assert_eq!(systems.len(), 1);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn loss_value_on(
    systems: &Systems,
    model: &Model,
    settings: &Settings,
    steps: usize,
    controls: &Controls,
    loss: &dyn Loss,
) -> Result<f64, DiffError> {
    // The forward a gradient of the same settings runs (finite differences compare with it).
    let settings = &differentiable(model, settings);
    let mut sim = Simulator::with_systems(model.clone(), settings.clone(), systems)?;
    Ok(forward(
        &mut sim,
        model,
        settings,
        steps,
        controls,
        loss,
        Keep::default(),
        &mut |_| {},
    )?
    .loss)
}

/// The loss of `steps` steps and its gradient (see the module docs).
///
/// ```
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
/// use diffsoft::diff::loss::CenterOfMass;
/// use diffsoft::{gradient, Controls, Options, Settings};
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let model = ModelBuilder::new()
///     .gravity(nalgebra::Vector3::new(0.0, -9.81, 0.0))
///     .body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0)))
///     .build()?;
/// let com_y = CenterOfMass { direction: nalgebra::Vector3::y(), time_average: false, vertices: None };
/// let (steps, settings) = (3, Settings::default());
/// let g = gradient(&model, &settings, steps, &Controls::default(), &com_y, Options::default())?;
/// assert!((g.loss - (0.05 - 6.0 * 9.81 * 1e-4)).abs() < 1e-8);
/// // Lifting every vertex lifts the centre of mass as much; a uniform initial velocity
/// // lifts it by steps x dt (the elastic forces do not see a translation).
/// let dq0: f64 = g.q0.iter().map(|d| d.y).sum();
/// let dv0: f64 = g.v0.iter().map(|d| d.y).sum();
/// assert!((dq0 - 1.0).abs() < 1e-9);
/// assert!((dv0 - steps as f64 * settings.dt).abs() < 1e-9);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn gradient(
    model: &Model,
    settings: &Settings,
    steps: usize,
    controls: &Controls,
    loss: &dyn Loss,
    opts: Options,
) -> Result<Gradient, DiffError> {
    gradient_with(model, settings, steps, controls, loss, opts, &mut |_| {})
}

/// Largest replay deviation, relative to the model's length scale, accepted without
/// [`Options::allow_unconverged`].
pub(crate) const REPLAY_TOLERANCE: f64 = 1e-6;

/// [`gradient`], telling `progress` after every forward and every backward step.
///
/// ```
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
/// use diffsoft::diff::loss::CenterOfMass;
/// use diffsoft::{gradient_with, Controls, Options, Progress, Settings};
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let model = ModelBuilder::new()
///     .gravity(nalgebra::Vector3::new(0.0, -9.81, 0.0))
///     .body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0)))
///     .build()?;
/// let com_y = CenterOfMass { direction: nalgebra::Vector3::y(), time_average: true, vertices: None };
/// let mut seen = Vec::new();
/// let (settings, controls) = (Settings::default(), Controls::default());
/// let g = gradient_with(&model, &settings, 3, &controls, &com_y, Options::default(), &mut |p| seen.push(p))?;
/// assert!(g.loss < 0.05);
/// assert_eq!(seen.len(), 6);
/// assert_eq!((seen[0], seen[5]), (Progress::Forward(0), Progress::Backward(0)));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn gradient_with(
    model: &Model,
    settings: &Settings,
    steps: usize,
    controls: &Controls,
    loss: &dyn Loss,
    opts: Options,
    progress: &mut dyn FnMut(Progress),
) -> Result<Gradient, DiffError> {
    gradient_on(&Systems::new(), model, settings, steps, controls, loss, opts, progress)
}

/// Implicit mode's [`DiffStats::forward_gap`]: the steps' estimated distances from their
/// converged solutions (`Forward::gap`) over the RMS distances the vertices moved in each
/// step, summed, both relative to the model's length scale; 0 when nothing moved.
fn forward_gap(model: &Model, fwd: &Forward) -> f64 {
    let rms = (model.n().max(1) as f64).sqrt() * model.length_scale;
    let motion: f64 = (1..fwd.q.len())
        .map(|k| {
            let moved: f64 = fwd
                .q
                .row(k)
                .iter()
                .zip(fwd.q.row(k - 1))
                .map(|(a, b)| (a - b).norm_squared())
                .sum();
            moved.sqrt() / rms
        })
        .sum();
    if motion > 0.0 {
        fwd.gap / motion
    } else {
        0.0
    }
}

/// [`gradient_with`] on shared systems (see [`Simulator::with_systems`]). The forward pass,
/// its replays and the backward pass use one global system per step size: assembled, certified
/// and factored once.
///
/// ```
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
/// use diffsoft::diff::gradient_on;
/// use diffsoft::diff::loss::CenterOfMass;
/// use diffsoft::solver::Systems;
/// use diffsoft::{Controls, Mode, Options, Settings};
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let model = ModelBuilder::new()
///     .gravity(nalgebra::Vector3::new(0.0, -9.81, 0.0))
///     .body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0)))
///     .build()?;
/// let com_y = CenterOfMass { direction: nalgebra::Vector3::y(), time_average: false, vertices: None };
/// let systems = Systems::new();
/// let (settings, controls) = (Settings::default(), Controls::default());
/// let run = |mode| gradient_on(&systems, &model, &settings, 3, &controls, &com_y, Options::mode(mode), &mut |_| {});
/// let (unrolled, implicit) = (run(Mode::Unrolled)?, run(Mode::Implicit)?);
/// assert_eq!(systems.len(), 1);
/// // Both modes agree on a converged run.
/// let dv0 = |g: &diffsoft::Gradient| g.v0.iter().map(|d| d.y).sum::<f64>();
/// assert!((dv0(&unrolled) - dv0(&implicit)).abs() < 1e-6);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[allow(clippy::too_many_arguments)]
pub fn gradient_on(
    systems: &Systems,
    model: &Model,
    settings: &Settings,
    steps: usize,
    controls: &Controls,
    loss: &dyn Loss,
    opts: Options,
    progress: &mut dyn FnMut(Progress),
) -> Result<Gradient, DiffError> {
    if steps == 0 {
        return Err(DiffError::Input("steps must be at least 1".into()));
    }
    let resolved = differentiable_solver(model, settings);
    let settings = &differentiable(model, settings);
    check_supported(model, settings, opts.mode)?;
    let implicit = opts.mode == Mode::Implicit;
    if let Some(t) = opts
        .implicit_tolerance
        .filter(|t| !(t.is_finite() && (0.0..1.0).contains(t)))
    {
        // A relative residual of 1 or more is met before the adjoint solve starts: the
        // gradient would be whatever its starting guess was (zero), with exit 0.
        return Err(DiffError::Input(format!(
            "the implicit tolerance is a relative residual and must be in [0, 1), got {}",
            crate::base::number(t)
        )));
    }
    let implicit_tol = opts.implicit_tolerance_for(settings);
    let t0 = Instant::now();
    let mut sim = Simulator::with_systems(model.clone(), settings.clone(), systems)?;
    let fwd = forward(
        &mut sim,
        model,
        settings,
        steps,
        controls,
        loss,
        Keep {
            states: true,
            contacts: implicit && (!model.obstacles.is_empty() || model.collision.is_some()),
            store_bytes: if implicit { 0 } else { opts.store_bytes },
        },
        progress,
    )?;
    let forward_ms = t0.elapsed().as_secs_f64() * 1e3;
    // Crossed surfaces first: no option waives them, so a run with both faults names the one
    // that allowing unconverged steps would not get past.
    if let Some((first, edges)) = fwd.first_crossed {
        return Err(DiffError::Interpenetration {
            steps: fwd.crossed,
            of: steps,
            first,
            edges,
        });
    }
    if let Some((first, pairs)) = fwd.first_swept {
        return Err(DiffError::SweptContacts {
            steps: fwd.swept,
            of: steps,
            first,
            pairs,
        });
    }
    if !opts.allow_unconverged && settings.tolerance > 0.0 && fwd.unconverged > 0 {
        return Err(DiffError::Unconverged {
            steps: fwd.unconverged,
            of: steps,
            tolerance: settings.tolerance,
            max_iterations: settings.max_iterations,
        });
    }
    if !opts.allow_unconverged && fwd.capped > 0 {
        return Err(DiffError::CappedSolves {
            steps: fwd.capped,
            of: steps,
            inner_max_iterations: settings.inner_max_iterations,
        });
    }
    let t1 = Instant::now();
    let n = model.n();
    let groups = model.actuators.as_ref().map_or(0, |a| a.groups.len());
    let dofs = model.skeleton.as_ref().map_or(0, |s| s.dofs);
    let mut g = Gradient {
        loss: fwd.loss,
        q0: vec![Vector3::zeros(); n],
        v0: vec![Vector3::zeros(); n],
        w_rot: vec![0.0; model.tets.len()],
        w_vol: vec![0.0; model.tets.len()],
        mass: vec![0.0; n],
        accel: vec![Vector3::zeros(); n],
        attachment_targets: vec![Vector3::zeros(); model.attachments.len()],
        activations: vec![vec![0.0; groups]; steps],
        torques: vec![vec![0.0; dofs]; if dofs > 0 { steps } else { 0 }],
        joints0: vec![0.0; dofs],
        stats: DiffStats {
            forward_ms,
            forward_iterations: fwd.iterations,
            unconverged_steps: fwd.flagged,
            one_iteration_steps: if implicit { 0 } else { fwd.one_iteration },
            joint_limit_steps: fwd.at_limit,
            forward_gap: if implicit { forward_gap(model, &fwd) } else { 0.0 },
            solver: resolved,
            ..Default::default()
        },
    };
    g.stats.stored_bytes = fwd.stored_bytes;
    g.stats.stored_steps = fwd.stored.iter().filter(|r| r.is_some()).count();
    g.stats.checkpoint_bytes = fwd.checkpoint_bytes();
    // Every step's scheme but the first (BDF2 starts with implicit Euler, whose matrix differs:
    // its backward is built when step 0 is reached).
    let bdf2 = settings.integrator == Integrator::Bdf2;
    // The backward pass solves with the forward's systems (one per scheme).
    let system_of = |scheme: Scheme| match sim.system_for(scheme.h_e()) {
        Some(s) => Ok(s),
        None => sim.systems().get(model, scheme.h_e()),
    };
    let mut bw = Backward::new(
        model,
        Scheme::for_step(settings.integrator, settings.dt, settings.damping, bdf2),
        system_of(Scheme::for_step(
            settings.integrator,
            settings.dt,
            settings.damping,
            bdf2,
        ))?,
        opts,
        implicit_tol,
        settings.tolerance,
    )?;
    let mut bw_first: Option<Backward> = None;
    // Implicit mode with a skeleton replays too: it linearizes the step's last iteration.
    let mut replayer = if implicit && model.skeleton.is_none() {
        None
    } else {
        Some((sim.replayer()?, Recording::new(true)))
    };
    // BDF2's first step is implicit Euler, differentiated on that scheme's system.
    let ie = Scheme::implicit_euler(settings.dt, settings.damping);
    let mut ie_system = if bdf2 { Some(system_of(ie)?) } else { None };
    // The forward's buffers are done with (its systems live on in the backward pass).
    drop(sim);
    let (mut qbar, mut vbar) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]);
    // BDF2: a step's adjoints of the state before its start, added to the next (earlier)
    // step's output; the other pair is that step's own.
    let two = if bdf2 { n } else { 0 };
    let (mut pend_q, mut pend_v) = (vec![Vector3::zeros(); two], vec![Vector3::zeros(); two]);
    let (mut out_q, mut out_v) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]);
    for step in (0..steps).rev() {
        if crate::base::cancel::requested() {
            return Err(SolverError::Interrupted.into());
        }
        let previous = (bdf2 && step > 0).then(|| (fwd.q.row(step - 1), fwd.v.row(step - 1)));
        // The loss term of the state after this step.
        let (qs, vs) = (fwd.q.row(step + 1), fwd.v.row(step + 1));
        if let (Some(sa), Some(j)) = (bw.skel.as_mut(), fwd.joints.get(step)) {
            loss.joint_term(model, step + 1, steps, j, &mut sa.z_bar);
        }
        loss.term(
            model,
            step + 1,
            steps,
            qs,
            vs,
            LossGrad {
                q: &mut qbar,
                v: &mut vbar,
                mass: &mut g.mass,
            },
        );
        let tr = Instant::now();
        let stored = fwd.stored.get(step).and_then(|r| r.as_ref());
        if let (Some((sim, replay)), None) = (replayer.as_mut(), stored) {
            sim.restore(Checkpoint {
                q: fwd.q.row(step),
                v: fwd.v.row(step),
                previous,
                skeleton: fwd.skeleton.get(step),
                time: fwd.time[step],
                step,
                activations: fwd.activations.row(step),
            })?;
            set_controls(sim, model, controls, step)?;
            sim.step_observed(replay)?;
            let dev = sim
                .state()
                .q
                .iter()
                .zip(fwd.q.row(step + 1))
                .map(|(a, b)| (a - b).amax())
                .fold(0.0, f64::max);
            g.stats.replay_deviation = g.stats.replay_deviation.max(dev);
            // Converged contact solves are warm-started from the previous step's impulses, which a
            // replay from a checkpoint does not have: replays of converged runs differ by up to
            // ~1e-9 of the length scale. A micron per metre separates that from a forward that
            // did not converge (1e-4 and more).
            let allowed = REPLAY_TOLERANCE * model.length_scale;
            if !opts.allow_unconverged && (dev.is_nan() || dev > allowed) {
                return Err(DiffError::NotReplayable {
                    deviation: dev,
                    allowed,
                });
            }
        }
        g.stats.replay_ms += tr.elapsed().as_secs_f64() * 1e3;
        let rec = stored.or_else(|| replayer.as_ref().map(|(_, r)| r));
        let b = if bdf2 && step == 0 {
            let first = match bw_first.take() {
                Some(b) => b,
                None => {
                    let system = ie_system.take().expect("a BDF2 run keeps its first step's system");
                    let mut b = Backward::new(model, ie, system, opts, implicit_tol, settings.tolerance)?;
                    // The skeleton's adjoint of z_1 carries over from the later steps.
                    if let (Some(dst), Some(src)) = (b.skel.as_mut(), bw.skel.as_ref()) {
                        dst.z_bar.copy_from_slice(&src.z_bar);
                    }
                    b.contact_ms = bw.contact_ms;
                    b
                }
            };
            bw_first.insert(first)
        } else {
            &mut bw
        };
        b.step(
            StepInputs {
                q_n: fwd.q.row(step),
                v_n: fwd.v.row(step),
                q_next: fwd.q.row(step + 1),
                activations: fwd.activations.row(step),
                replay: rec,
                final_contacts: fwd.contacts.get(step),
                previous,
                step,
                capped: fwd.capped_steps.get(step).copied().unwrap_or(false),
            },
            &mut qbar,
            &mut vbar,
            (&mut out_q, &mut out_v),
            &mut g,
        )
        .map_err(|e| match e {
            // The forward's states are finite (checked as it ran): a non-finite value here is
            // the adjoint's own, not "a position" as the solver's message would have it.
            DiffError::Solver(SolverError::NonFinite(_)) => DiffError::NonFiniteGradient {
                what: format!("the adjoint of step {}", step + 1),
            },
            e => e,
        })?;
        if bdf2 {
            // The adjoint of (q_n, v_n) is this step's part plus the later step's (which read
            // them as its earlier state); this step's part for (q_{n-1}, v_{n-1}) waits.
            for i in 0..n {
                qbar[i] += pend_q[i];
                vbar[i] += pend_v[i];
            }
            std::mem::swap(&mut pend_q, &mut out_q);
            std::mem::swap(&mut pend_v, &mut out_v);
        }
        progress(super::Progress::Backward(step));
    }
    g.q0 = qbar;
    g.v0 = vbar;
    let last = bw_first.as_ref().unwrap_or(&bw);
    if let Some(sa) = last.skel.as_ref() {
        g.joints0.copy_from_slice(&sa.z_bar);
    }
    g.stats.backward_ms = t1.elapsed().as_secs_f64() * 1e3;
    g.stats.contact_ms = last.contact_ms;
    if let Some(what) = g.first_non_finite() {
        return Err(DiffError::NonFiniteGradient { what });
    }
    Ok(g)
}
