//! Independent parameter sets run in parallel on all cores, one item per core and each
//! single-threaded ([`diffsoft::base::tasks`]: a batch scales like independent processes),
//! without the GIL; Ctrl-C stops every one of them ([`crate::interrupt`]).

use diffsoft::base::tasks;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::interrupt;
use crate::run::Run;
use crate::scene_core::{self as scene, Scene};

/// A copy of `base` for every parameter set of `values` (errors name the set's index).
pub(crate) fn scenes(base: &Scene, values: &[Bound<'_, PyDict>]) -> PyResult<Vec<Scene>> {
    values
        .iter()
        .enumerate()
        .map(|(k, v)| {
            scene::values(&base.inner.model, v)
                .and_then(|vals| base.with(vals))
                .map_err(|e| item_error(v.py(), k, e))
        })
        .collect()
}

/// The error of item `k` of a batch: its class and message, the message after `values[k]: `
/// (the original as its cause).
pub(crate) fn item_error(py: Python<'_>, k: usize, e: PyErr) -> PyErr {
    match e.get_type(py).call1((format!("values[{k}]: {}", e.value(py)),)) {
        Ok(renamed) => {
            let renamed = PyErr::from_value(renamed);
            renamed.set_cause(py, Some(e));
            renamed
        }
        Err(_) => e,
    }
}

/// `f` of every item in parallel ([`tasks::map_each`]) with the GIL released and Ctrl-C
/// watched; an item that panics gives the package's error for a panic.
pub(crate) fn each<T: Sync, R: Send>(
    py: Python<'_>,
    items: &[T],
    f: impl Fn(&T) -> PyResult<R> + Send + Sync,
) -> PyResult<Vec<PyResult<R>>> {
    interrupt::run(py, || {
        tasks::map_each(items, f)
            .into_iter()
            .map(|r| r.unwrap_or_else(|panic| Err(crate::errors::panicked(panic))))
            .collect()
    })
}

/// `[(loss, grads)]`, one per dict of `values` (each sets parameters on a copy of `scene`).
#[pyfunction]
#[pyo3(signature = (scene, steps, loss, params, values, mode = "unrolled", allow_unconverged = false))]
#[allow(clippy::too_many_arguments)]
pub fn grad_batch<'py>(
    py: Python<'py>,
    scene: &Bound<'py, Scene>,
    steps: &Bound<'py, PyAny>,
    loss: &str,
    params: &Bound<'py, PyAny>,
    values: &Bound<'py, PyAny>,
    mode: &str,
    allow_unconverged: bool,
) -> PyResult<Vec<Bound<'py, PyTuple>>> {
    let steps = crate::args::count(steps, "steps", 1)?;
    let params = crate::args::names(params, "params")?;
    let values = crate::args::dicts(values, "values")?;
    let scene = scene::view(scene, "grad_batch")?;
    scene::names(&scene.inner.model, &params)?;
    let m = scene::mode(mode)?;
    // Checked before the items (an empty batch included), as `Scene.grad` checks it.
    scene::loss(&scene.inner.model, loss)?;
    let runs = scenes(&scene, &values)?;
    let results = each(py, &runs, |s| s.gradient(steps, loss, m, allow_unconverged))?;
    runs.iter()
        .zip(results)
        .enumerate()
        .map(|(k, (s, g))| {
            let g = g.map_err(|e| item_error(py, k, e))?;
            scene::warn_stats(py, &g, steps)?;
            let d = scene::grads(py, &s.inner.model, &g, &params)?;
            PyTuple::new(py, [g.loss.into_pyobject(py)?.into_any(), d.into_any()])
        })
        .collect()
}

/// `[Run]`, one per dict of `values` (each sets parameters on a copy of `scene`); one
/// `ConvergenceWarning` if any run has steps that missed a positive tolerance, another naming
/// the first run whose unconverged step made energy in a scene without an energy source.
#[pyfunction]
pub fn simulate_batch<'py>(
    py: Python<'py>,
    scene: &Bound<'py, Scene>,
    steps: &Bound<'py, PyAny>,
    values: &Bound<'py, PyAny>,
) -> PyResult<Vec<Run>> {
    let steps = crate::args::count(steps, "steps", 1)?;
    let values = crate::args::dicts(values, "values")?;
    // Held until the batch returns (a `set` meanwhile raises `SceneBusyError`).
    let scene = scene::view(scene, "simulate_batch")?;
    let runs = scenes(&scene, &values)?;
    let mut unconverged = false;
    let mut crossed = false;
    let mut inverted = false;
    let mut gain = None;
    let mut soft: Vec<String> = Vec::new();
    let results = each(py, &runs, |s| s.rollout(steps))?;
    let runs: Vec<Run> = runs
        .iter()
        .zip(results)
        .enumerate()
        .map(|(k, (s, r))| {
            let r = r.map_err(|e| item_error(py, k, e))?;
            unconverged |= s.inner.settings.tolerance > 0.0 && r.unconverged_steps() > 0;
            if gain.is_none() {
                gain = diffsoft::output::solver_energy_gain(&s.inner.model, &r.stats).map(|g| (k, g));
            }
            crossed |= r.interpenetrating_steps() > 0;
            if diffsoft::output::folded(r.max_inverted_tets(), s.inner.model.tets().len()) {
                inverted = true;
                for name in crate::warn::soft_bodies(&s.inner.model) {
                    if !soft.contains(&name) {
                        soft.push(name);
                    }
                }
            }
            Run::new(py, r, &s.inner.settings)
        })
        .collect::<PyResult<_>>()?;
    if unconverged {
        crate::warn::unconverged(py)?;
    }
    if let Some((k, g)) = gain {
        crate::warn::energy_gain(py, &g, Some(k))?;
    }
    if crossed {
        crate::warn::interpenetration(py)?;
    }
    if inverted {
        crate::warn::inversion(py, &soft)?;
    }
    Ok(runs)
}
