//! The verification harness from Python: the same reports as the CLI's `bounds`, `gradcheck`
//! and `jacobians`, as dicts.

use diffsoft::analysis::bounds::{analyze, BoundsParams};
use diffsoft::analysis::spectral::EigenMethod;
use diffsoft::base::memory;
use diffsoft::diff::params::ArrayParam;
use diffsoft::diff::Options;
use diffsoft::testing::{gradcheck_settings, Case, Group};
use diffsoft::Mode;
use diffsoft_harness::gradients;
use pyo3::prelude::*;

use crate::arrays;
use crate::errors;
use crate::interrupt;
use crate::params::Name;
use crate::scene_core::{self as scene, Scene};

/// Spectral radii and critical time steps of the paper's iterations (19) and (21) on a mesh,
/// with the appendix's verdicts (the `diffsoft bounds` report).
/// The numbers are read as `Scene.set` reads them (a bool is refused, not taken as 0 or 1).
#[pyfunction]
#[pyo3(
    signature = (mesh, rho, mu, dt, scale = None, empirical = false, method = "auto"),
    text_signature = "(mesh, rho, mu, dt, scale=1.0, empirical=False, method='auto')"
)]
#[allow(clippy::too_many_arguments)] // the Python signature: keyword arguments with defaults
pub fn bounds<'py>(
    py: Python<'py>,
    mesh: std::path::PathBuf,
    rho: &Bound<'py, PyAny>,
    mu: &Bound<'py, PyAny>,
    dt: &Bound<'py, PyAny>,
    scale: Option<&Bound<'py, PyAny>>,
    empirical: bool,
    method: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let [rho, mu, dt] = [(rho, "rho"), (mu, "mu"), (dt, "dt")].map(|(v, name)| arrays::read_scalar(name, v));
    let (rho, mu, dt) = (rho?, mu?, dt?);
    let scale = scale.map_or(Ok(1.0), |s| arrays::read_scalar("scale", s))?;
    if !(scale.is_finite() && scale > 0.0) {
        return Err(errors::value(format!("scale must be finite and positive, got {scale}")));
    }
    let method = match method {
        "auto" => EigenMethod::Auto,
        "dense" => EigenMethod::Dense,
        "krylov" => EigenMethod::Krylov,
        _ => {
            return Err(errors::value(format!(
                "method '{method}': expected auto, dense or krylov"
            )))
        }
    };
    // Read on a thread that Ctrl-C abandons (a named pipe nobody writes to), then analysed on
    // one that Ctrl-C cancels.
    let loaded = interrupt::abandonable(py, move || diffsoft::mesh::load(&mesh))?
        .map_err(errors::mesh)?
        .scaled(scale);
    let report = interrupt::run(py, || -> PyResult<_> {
        let params = BoundsParams {
            rho,
            mu,
            dt,
            attachments: Default::default(),
            method,
            empirical,
        };
        analyze(&loaded.mesh, &loaded.info, &params).map_err(|e| errors::value(e.to_string()))
    })??;
    arrays::report(py, &report)
}

/// The most fixed local-global iterations per step `gradcheck` runs (`iterations`): its runs
/// stop at no tolerance, so the count is the cost of every step (the library's own cases run 8
/// to 30).
pub const MAX_GRADCHECK_ITERATIONS: usize = 1000;

/// Reverse-mode gradients of `scene` checked against central finite differences (step sweeps)
/// and dual numbers, per parameter group (a `diffsoft gradcheck` case); `iterations` (fixed
/// local-global iterations per step, at most [`MAX_GRADCHECK_ITERATIONS`]) is 30 when not
/// given. The parameters, steps and controls are checked as `Scene.grad` checks them, raising
/// its exceptions.
#[pyfunction]
#[pyo3(
    signature = (scene, steps, loss = "final_com.y", params = None, iterations = None, seed = None),
    text_signature = "(scene, steps, loss='final_com.y', params=None, iterations=None, seed=2021)"
)]
pub fn gradcheck<'py>(
    py: Python<'py>,
    scene: &Bound<'py, Scene>,
    steps: &Bound<'py, PyAny>,
    loss: &str,
    params: Option<&Bound<'py, PyAny>>,
    iterations: Option<&Bound<'py, PyAny>>,
    seed: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let steps = crate::args::count(steps, "steps", 1)?;
    let iterations = iterations.map_or(Ok(30), |i| crate::args::count(i, "iterations", 1))?;
    if iterations > MAX_GRADCHECK_ITERATIONS {
        return Err(errors::value(format!(
            "iterations must be at most {MAX_GRADCHECK_ITERATIONS} (fixed iterations per step, every one run), got {iterations}"
        )));
    }
    let seed = seed.map_or(Ok(2021), |s| crate::args::count(s, "seed", 0))? as u64;
    let params = match params {
        Some(p) => crate::args::names(p, "params")?,
        None => vec!["youngs_modulus".into(), "initial_velocities".into()],
    };
    if params.is_empty() {
        return Err(errors::value("params: no parameter to check; name at least one"));
    }
    let scene = scene::view(scene, "gradcheck")?;
    let model = &scene.inner.model;
    let groups = scene::names(model, &params)?
        .into_iter()
        .map(|n| match n {
            Name::Scalar(p) => Ok(Group::Scalar(p)),
            Name::Array(a) => match a {
                ArrayParam::InitialPositions => Ok(Group::InitialPositions),
                ArrayParam::InitialVelocities => Ok(Group::InitialVelocities),
                ArrayParam::YoungsModulusPerTet => Ok(Group::YoungsPerTet),
                ArrayParam::AttachmentTargets => Ok(Group::AttachmentTargets),
                ArrayParam::Activations => Ok(Group::Activations),
                ArrayParam::Torques => Ok(Group::Torques),
                ArrayParam::InitialJointState => {
                    Err(errors::value("gradcheck: initial_joint_state cannot be perturbed"))
                }
            },
        })
        .collect::<PyResult<Vec<_>>>()?;
    scene.inputs.check_rows(steps)?;
    // Unchecked: the check perturbs a start that touches an obstacle on purpose.
    let mut controls = scene.inputs.controls(model);
    if let (true, None, Some(act)) = (
        groups.contains(&Group::Activations),
        &controls.activations,
        model.actuators(),
    ) {
        // Activations left to the schedules are checked at the schedules' values, each step's
        // at its end time (as the run reads them; torques likewise, `Case::direction`).
        let rows = format!("activations of {steps} steps");
        memory::check(&rows, steps, std::mem::size_of::<Vec<f64>>() + 8 * act.groups.len())
            .map_err(|e| errors::solver(e.into()))?;
        let dt = scene.inner.settings.dt;
        let at = |n: usize| act.groups.iter().map(|g| g.activation.at(n as f64 * dt)).collect();
        controls.activations = Some((1..=steps).map(at).collect());
    }
    let case = Case {
        name: scene
            .inner
            .path
            .file_stem()
            .map_or("scene".into(), |s| s.to_string_lossy().into_owned()),
        description: format!("{} (from Python)", scene.inner.path.display()),
        model: model.clone(),
        settings: gradcheck_settings(scene.inner.settings.dt, iterations),
        steps,
        loss: scene::loss(model, loss)?,
        controls,
        groups,
    };
    let check = interrupt::run(py, || {
        let check = gradients::check_case(&case, seed);
        // A case that failed: the input errors `Scene.grad` raises (a run too large for
        // memory, ...) are raised as it raises them, with their class; other failures stay in
        // the report.
        let refused = check
            .error
            .is_some()
            .then(|| case.gradient(&case.settings, Options::mode(Mode::Unrolled)).err())
            .flatten();
        (check, refused)
    })?;
    match check.1.map(errors::diff) {
        Some(e) if e.is_instance_of::<pyo3::exceptions::PyValueError>(py) => Err(e),
        _ => arrays::report(py, &check.0),
    }
}

/// Jacobians of the joints and of `B = dq/dz` against dual numbers and finite differences
/// (the `diffsoft jacobians` report).
#[pyfunction]
#[pyo3(signature = (seed = None), text_signature = "(seed=2021)")]
pub fn jacobians<'py>(py: Python<'py>, seed: Option<&Bound<'py, PyAny>>) -> PyResult<Bound<'py, PyAny>> {
    let seed = seed.map_or(Ok(2021), |s| crate::args::count(s, "seed", 0))? as u64;
    let report = interrupt::run(py, || diffsoft_harness::jacobians::run(seed))?;
    arrays::report(py, &report)
}
