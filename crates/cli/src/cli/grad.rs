//! `diffsoft grad`: its options, one forward and one backward pass, the loss and the
//! derivatives.

use super::choice::choice;
use super::files::{preflight, save};
use super::overrides::SolverOverrides;
use super::prelude::*;

#[derive(clap::Args)]
pub(crate) struct GradArgs {
    /// Scene file (.json, diffsoft.scene/1 or a paper scene), positional as in `simulate`.
    #[arg(required_unless_present = "scene_flag", conflicts_with = "scene_flag")]
    scene: Option<PathBuf>,
    /// The scene as a flag (the older spelling; same as the positional SCENE).
    #[arg(long = "scene", value_name = "SCENE", hide = true)]
    scene_flag: Option<PathBuf>,
    /// Steps to simulate.
    #[arg(long, default_value_t = 100, value_parser = super::numbers::at_least_one)]
    steps: usize,
    /// Loss: final_com.x|y|z, mean_com.x|y|z, joint_angle.BONE or mean_joint_angle.BONE.
    #[arg(long, default_value = "final_com.y")]
    loss: String,
    // The names come from the parameter registry (`diffsoft::diff::params`).
    #[arg(long, required = true, help = param_help(), long_help = param_long_help())]
    param: Vec<String>,
    /// Override a parameter first, `NAME=VALUE` (repeatable; same names as --param).
    #[arg(long, value_name = "NAME=VALUE")]
    set: Vec<String>,
    /// Differentiation mode.
    #[arg(long, value_parser = choice::<diffsoft::diff::Mode>(), default_value = "unrolled")]
    mode: diffsoft::diff::Mode,
    #[command(flatten)]
    overrides: SolverOverrides,
    /// Write `{loss, gradient}` as JSON here (`-`: standard output).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Unrolled mode: keep whole steps' recordings from the forward pass up to this many MB
    /// instead of replaying them from checkpoints (0: pure checkpointing).
    #[arg(long, default_value_t = 0.0, value_parser = super::numbers::non_negative)]
    store_mb: f64,
    /// Return the loss and gradient even if forward steps miss the tolerance or a replay
    /// deviates from the forward pass (otherwise an error; the counts are printed).
    #[arg(long)]
    allow_unconverged: bool,
    /// Implicit mode: relative residual at which the adjoint solve of each step stops (default:
    /// matched to the forward's tolerance, within [1e-12, 1e-5]; 1e-12 for a fixed iteration
    /// count)
    #[arg(long, value_parser = super::numbers::positive)]
    implicit_tolerance: Option<f64>,
}

/// The help of `--param`: the scalar parameters of the registry, `initial_velocity.x|y|z` for
/// the components of one vector.
fn param_help() -> String {
    let mut names: Vec<String> = Vec::new();
    for name in diffsoft::diff::params::scalar_names() {
        match (name.split_once('.'), names.last_mut()) {
            (Some((base, axis)), Some(last)) if last.starts_with(&format!("{base}.")) => {
                last.push('|');
                last.push_str(axis);
            }
            _ => names.push(name.to_string()),
        }
    }
    format!("Parameters to differentiate (repeatable): {}", names.join(", "))
}

/// The long help of `--param`: each scalar parameter with its unit and meaning.
fn param_long_help() -> String {
    format!(
        "Parameters to differentiate (repeatable):\n{}",
        diffsoft::diff::params::scalar_help()
            .lines()
            .map(|l| format!("  {l}"))
            .collect::<Vec<_>>()
            .join("\n")
    )
}

/// A memory budget in MB as bytes.
pub(crate) fn store_bytes(mb: f64) -> Result<usize> {
    if !(mb.is_finite() && mb >= 0.0) {
        anyhow::bail!("--store-mb must be finite and >= 0, got {}", diffsoft::base::number(mb));
    }
    Ok((mb * 1e6) as usize)
}

/// `diffsoft grad`: overrides, one forward and one backward pass, the loss and the derivatives.
pub(crate) fn grad(a: GradArgs) -> Result<()> {
    use diffsoft::diff::{self, Controls, Options, Param};
    let Some(scene) = a.scene.clone().or_else(|| a.scene_flag.clone()) else {
        bail!("give the scene file: diffsoft grad SCENE --param P");
    };
    preflight(a.json.as_deref(), &[&scene])?;
    if let Some(t) = a
        .implicit_tolerance
        .filter(|t| !(t.is_finite() && (0.0..1.0).contains(t)))
    {
        bail!(
            "--implicit-tolerance is a relative residual and must be in (0, 1), got {}",
            diffsoft::base::number(t)
        );
    }
    if let (Some(t), diffsoft::diff::Mode::Unrolled) = (a.implicit_tolerance, a.mode) {
        bail!(
            "--implicit-tolerance {}: applies to --mode implicit only (the unrolled backward has no tolerance)",
            diffsoft::base::number(t)
        );
    }
    let set_names: Vec<&str> = a
        .set
        .iter()
        .map(|s| s.split_once('=').map_or(s.as_str(), |(n, _)| n).trim())
        .collect();
    if let Some(k) = (1..set_names.len()).find(|&k| set_names[..k].contains(&set_names[k])) {
        bail!(
            "--set {}: {} is set twice; give each parameter once",
            a.set[k],
            set_names[k]
        );
    }
    let mut sc = diffsoft::scene::load(&scene, diffsoft::scene::LoadOptions::default())?;
    a.overrides.apply(&mut sc.settings)?;
    let mut overrides = std::collections::BTreeMap::new();
    for s in &a.set {
        let (name, value) = s
            .split_once('=')
            .ok_or_else(|| anyhow::anyhow!("--set {s}: expected NAME=VALUE"))?;
        let p: Param = name.parse()?;
        let v: f64 = value
            .trim()
            .parse()
            .map_err(|_| anyhow::anyhow!("--set {s}: '{value}' is not a number"))?;
        p.set(&mut sc.model, v)?;
        overrides.insert(p.to_string(), v);
    }
    let params: Vec<Param> = a.param.iter().map(|p| p.parse()).collect::<Result<_, _>>()?;
    for p in &params {
        p.check_applies(&sc.model).map_err(|e| anyhow::anyhow!("--param {e}"))?;
    }
    if let Some(k) = (1..a.param.len()).find(|&k| a.param[..k].contains(&a.param[k])) {
        bail!("--param {}: given twice; give each parameter once", a.param[k]);
    }
    let loss = diff::loss::by_name(&a.loss)?;
    let g = diff::gradient(
        &sc.model,
        &sc.settings,
        a.steps,
        &Controls::default(),
        loss.as_ref(),
        Options {
            store_bytes: store_bytes(a.store_mb)?,
            allow_unconverged: a.allow_unconverged,
            implicit_tolerance: a.implicit_tolerance,
            ..Options::mode(a.mode)
        },
    )
    .map_err(|e| match e {
        diff::DiffError::Unconverged { .. }
        | diff::DiffError::CappedSolves { .. }
        | diff::DiffError::NotReplayable { .. } => {
            anyhow::anyhow!("{e} (--allow-unconverged)")
        }
        diff::DiffError::Solver(s @ (diffsoft::SolverError::NonFinite(_) | diffsoft::SolverError::Diverged(_))) => {
            anyhow::anyhow!(diff::params::name_extreme_inputs(
                s.to_string(),
                &sc.model,
                sc.settings.dt
            ))
        }
        e => e.into(),
    })?;
    let mut gradient = std::collections::BTreeMap::new();
    let mut values = std::collections::BTreeMap::new();
    for n in diffsoft::output::body_notes(&sc.model) {
        say!("note {n}");
    }
    if let Some(k) = g.stats.solver {
        say!(
            "solver auto: {} for the gradient (its backward pass exists for this scene)",
            diffsoft::base::Choice::name(k)
        );
    }
    say!("loss {} = {:.17e}", a.loss, g.loss);
    for p in &params {
        let d = p.derivative(&sc.model, &g);
        say!(
            "d loss / d {p} = {d:.17e}   (at {p} = {})",
            p.get(&sc.model).map_or("-".into(), diffsoft::base::number)
        );
        gradient.insert(p.to_string(), d);
        if let Ok(v) = p.get(&sc.model) {
            values.insert(p.to_string(), v);
        }
    }
    say!(
        "forward {:.1} ms, backward {:.1} ms ({:?} mode), {} forward iterations, {} backward iterations",
        g.stats.forward_ms,
        g.stats.backward_ms,
        a.mode,
        g.stats.forward_iterations,
        g.stats.backward_iterations
    );
    let missed = sc.settings.tolerance > 0.0 && g.stats.unconverged_steps > 0;
    if missed || g.stats.replay_deviation > 1e-6 * sc.model.length_scale() {
        say!(
            "warning: {} of {} forward steps did not converge, replay deviation {:.3e} m (allowed by --allow-unconverged)",
            g.stats.unconverged_steps, a.steps, g.stats.replay_deviation
        );
    }
    for w in g.stats.warnings(a.steps) {
        warn!("warning: {w}");
    }
    if let Some(path) = &a.json {
        let out = diffsoft::output::GradReport {
            header: diffsoft::report::Header::new(diffsoft::output::GRAD_SCHEMA),
            scene: scene.display().to_string(),
            steps: a.steps,
            mode: a.mode,
            loss_name: a.loss.clone(),
            loss: g.loss,
            parameters: values,
            gradient,
            overrides,
            settings: sc.settings.clone(),
            stats: g.stats,
        };
        save(path, &out, &[&scene])?;
    }
    Ok(())
}
