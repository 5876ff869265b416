//! Vector-Jacobian products of the trajectory: the cotangents a caller gives (`Scene.vjp`) and
//! a batch of them (`vjp_batch`: one scene, many parameter sets and cotangents, in parallel
//! like `grad_batch`), which custom losses and the frameworks' batching rules
//! (`torch.func.vmap`, `jax.vmap`) map to.

use diffsoft::diff::{self, Cotangent, Options};
use diffsoft::Mode;
use nalgebra::Vector3;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays;
use crate::errors;
use crate::scene_core::{self as scene, Scene};

/// One `(steps + 1, n, 3)` cotangent array named `name`, as vectors.
fn states(name: &str, c: &Bound<'_, PyAny>, steps: usize, n: usize) -> PyResult<Vec<Vector3<f64>>> {
    let (data, shape) = arrays::read(name, c)?;
    if shape != [steps + 1, n, 3] {
        return Err(errors::value(format!(
            "{name}: shape {shape:?}, expected (steps + 1, n, 3) = ({}, {n}, 3)",
            steps + 1
        )));
    }
    Ok(data.chunks_exact(3).map(|c| Vector3::new(c[0], c[1], c[2])).collect())
}

/// The cotangent of a trajectory of `scene` over `steps` steps: `cq` on the positions and
/// `cv` (optional) on the velocities, each `(steps + 1, n, 3)`; `prefix` names the item in
/// errors (`""`, or `"cotangents[3]: "` in a batch).
pub(crate) fn cotangent(
    scene: &Scene,
    steps: usize,
    cq: &Bound<'_, PyAny>,
    cv: Option<&Bound<'_, PyAny>>,
    prefix: &str,
) -> PyResult<Cotangent> {
    let n = scene.inner.model.n();
    let q = states(&format!("{prefix}cotangent"), cq, steps, n)?;
    let v = cv
        .map(|c| states(&format!("{prefix}velocity_cotangent"), c, steps, n))
        .transpose()?;
    if steps == 0 {
        return Err(errors::value("steps must be at least 1"));
    }
    Cotangent::new(n, steps, q, v).map_err(errors::diff)
}

impl Scene {
    /// The gradient of the pairing of `cot` with the trajectory (the library's call, without
    /// the GIL).
    pub(crate) fn vjp_gradient(
        &self,
        steps: usize,
        cot: &Cotangent,
        mode: Mode,
        allow_unconverged: bool,
    ) -> PyResult<diffsoft::Gradient> {
        let controls = self.inputs.checked_controls(&self.inner.model, steps)?;
        diff::vjp(
            &self.inner.model,
            &self.inner.settings,
            steps,
            &controls,
            cot,
            Options {
                allow_unconverged,
                ..Options::mode(mode)
            },
        )
        .map_err(errors::diff)
    }
}

/// `[grads]`, one `Scene.vjp` per item: `values[k]` sets parameters on a copy of `scene` and
/// `cotangents[k]` (with `velocity_cotangents[k]`, if given) pairs with its trajectory. The
/// items run in parallel like `grad_batch`'s.
#[pyfunction]
#[pyo3(signature = (scene, steps, params, values, cotangents, velocity_cotangents = None, mode = "unrolled", allow_unconverged = false))]
#[allow(clippy::too_many_arguments)]
pub fn vjp_batch<'py>(
    scene: &Bound<'py, Scene>,
    steps: &Bound<'py, PyAny>,
    params: &Bound<'py, PyAny>,
    values: &Bound<'py, PyAny>,
    cotangents: Vec<Bound<'py, PyAny>>,
    velocity_cotangents: Option<Vec<Option<Bound<'py, PyAny>>>>,
    mode: &str,
    allow_unconverged: bool,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let py = scene.py();
    let steps = crate::args::count(steps, "steps", 1)?;
    let params = crate::args::names(params, "params")?;
    let values = crate::args::dicts(values, "values")?;
    let scene = scene::view(scene, "vjp_batch")?;
    scene::names(&scene.inner.model, &params)?;
    let m = scene::mode(mode)?;
    let items = values.len();
    if cotangents.len() != items {
        return Err(errors::value(format!(
            "cotangents: {} arrays for {items} parameter sets (values); give one per set",
            cotangents.len()
        )));
    }
    if let Some(cv) = &velocity_cotangents {
        if cv.len() != items {
            return Err(errors::value(format!(
                "velocity_cotangents: {} entries for {items} parameter sets (values); give one per set (None for none)",
                cv.len()
            )));
        }
    }
    let runs = crate::batch::scenes(&scene, &values)?;
    // Every item has its own copy: the caller's scene is free for other threads.
    drop(scene);
    let cots = runs
        .iter()
        .zip(&cotangents)
        .enumerate()
        .map(|(k, (s, cq))| {
            let cv = velocity_cotangents.as_ref().and_then(|v| v[k].as_ref());
            let prefix = format!("cotangents[{k}]: ");
            cotangent(s, steps, cq, cv, &prefix)
        })
        .collect::<PyResult<Vec<_>>>()?;
    let jobs: Vec<(&Scene, &Cotangent)> = runs.iter().zip(&cots).collect();
    let results = crate::batch::each(py, &jobs, |(s, c)| s.vjp_gradient(steps, c, m, allow_unconverged))?;
    runs.iter()
        .zip(results)
        .enumerate()
        .map(|(k, (s, g))| {
            let g = g.map_err(|e| crate::batch::item_error(py, k, e))?;
            scene::warn_stats(py, &g, steps)?;
            scene::grads(py, &s.inner.model, &g, &params)
        })
        .collect()
}
