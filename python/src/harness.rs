//! The verification harness from Python: the same reports as the CLI's `bounds`, `gradcheck`
//! and `jacobians`, as dicts.

use diffsoft::analysis::bounds::{analyze, BoundsParams};
use diffsoft::analysis::spectral::EigenMethod;
use diffsoft::diff::params::ArrayParam;
use diffsoft::testing::{gradcheck_settings, Case, Group};
use diffsoft_harness::gradients;
use pyo3::prelude::*;

use crate::arrays;
use crate::errors;
use crate::interrupt;
use crate::params::Name;
use crate::scene_core::{self as scene, Scene};

/// Spectral radii and critical time steps of the paper's iterations (19) and (21) on a mesh,
/// with the appendix's verdicts (the `diffsoft bounds` report).
#[pyfunction]
#[pyo3(signature = (mesh, rho, mu, dt, scale = 1.0, empirical = false, method = "auto"))]
#[allow(clippy::too_many_arguments)] // the Python signature: keyword arguments with defaults
pub fn bounds<'py>(
    py: Python<'py>,
    mesh: std::path::PathBuf,
    rho: f64,
    mu: f64,
    dt: f64,
    scale: f64,
    empirical: bool,
    method: &str,
) -> PyResult<Bound<'py, PyAny>> {
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
    let report = interrupt::run(py, || -> PyResult<_> {
        let loaded = diffsoft::mesh::load(&mesh).map_err(errors::mesh)?.scaled(scale);
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

/// Reverse-mode gradients of `scene` checked against central finite differences (step sweeps)
/// and dual numbers, per parameter group (a `diffsoft gradcheck` case); `iterations` (fixed
/// local-global iterations per step) is 30 when not given.
#[pyfunction]
#[pyo3(signature = (scene, steps, loss = "final_com.y", params = None, iterations = None, seed = 2021))]
pub fn gradcheck<'py>(
    py: Python<'py>,
    scene: &Scene,
    steps: &Bound<'py, PyAny>,
    loss: &str,
    params: Option<&Bound<'py, PyAny>>,
    iterations: Option<&Bound<'py, PyAny>>,
    seed: u64,
) -> PyResult<Bound<'py, PyAny>> {
    let steps = crate::args::count(steps, "steps", 1)?;
    let iterations = iterations.map_or(Ok(30), |i| crate::args::count(i, "iterations", 1))?;
    let params = match params {
        Some(p) => crate::args::names(p, "params")?,
        None => vec!["youngs_modulus".into(), "initial_velocities".into()],
    };
    let groups = scene::names(&params)?
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
    let case = Case {
        name: scene
            .inner
            .path
            .file_stem()
            .map_or("scene".into(), |s| s.to_string_lossy().into_owned()),
        description: format!("{} (from Python)", scene.inner.path.display()),
        model: scene.inner.model.clone(),
        settings: gradcheck_settings(scene.inner.settings.dt, iterations),
        steps,
        loss: diffsoft::diff::loss::by_name(loss).map_err(errors::diff)?,
        controls: scene.inputs.controls(&scene.inner.model),
        groups,
    };
    let check = interrupt::run(py, || gradients::check_case(&case, seed))?;
    arrays::report(py, &check)
}

/// Jacobians of the joints and of `B = dq/dz` against dual numbers and finite differences
/// (the `diffsoft jacobians` report).
#[pyfunction]
#[pyo3(signature = (seed = 2021))]
pub fn jacobians(py: Python<'_>, seed: u64) -> PyResult<Bound<'_, PyAny>> {
    let report = interrupt::run(py, || diffsoft_harness::jacobians::run(seed))?;
    arrays::report(py, &report)
}
