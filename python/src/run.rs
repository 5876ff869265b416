//! `diffsoft.Run`: the trajectory of a simulation as numpy arrays and its run log as a dict.

use diffsoft::diff::Rollout;
use diffsoft::output::RunSummary;
use diffsoft::Settings;
use pyo3::prelude::*;

use crate::arrays;

/// The result of `Scene.simulate`.
#[pyclass(name = "Run", module = "diffsoft", frozen)]
pub struct Run {
    /// Positions of every state, float64 `(steps + 1, n, 3)`.
    #[pyo3(get)]
    positions: Py<PyAny>,
    /// Velocities of every state, float64 `(steps + 1, n, 3)`.
    #[pyo3(get)]
    velocities: Py<PyAny>,
    /// Time of every state, float64 `(steps + 1,)`.
    #[pyo3(get)]
    times: Py<PyAny>,
    /// The run's figures as the run log holds them (`run.json`'s summary, certificate, settings
    /// and every step's figures; not its scene, provenance or frames, so no schema is claimed).
    #[pyo3(get)]
    stats: Py<PyAny>,
}

impl Run {
    /// Arrays and log of `r`.
    pub fn new(py: Python<'_>, r: Rollout, settings: &Settings) -> PyResult<Self> {
        let (states, n) = (r.times.len(), r.n);
        // The run log's figures of the run itself, as `run.json` holds them; not the file's
        // other fields (scene, provenance, frames), so it claims no schema.
        let stats = serde_json::json!({
            "crate_version": diffsoft::report::CRATE_VERSION,
            "vertices": n,
            "settings": settings,
            "certificate": r.certificate,
            "summary": RunSummary::of(&r.stats),
            "unconverged_steps": r.unconverged_steps(),
            "steps": r.stats,
        });
        Ok(Self {
            positions: arrays::array(py, arrays::flatten(r.positions), &[states, n, 3])?.unbind(),
            velocities: arrays::array(py, arrays::flatten(r.velocities), &[states, n, 3])?.unbind(),
            times: arrays::array(py, r.times, &[states])?.unbind(),
            stats: arrays::json(py, &stats)?.unbind(),
        })
    }
}

/// `steps` read as `Scene.simulate` reads it, and the memory of its trajectory (positions and
/// velocities of `steps + 1` states) checked as the rollout checks it: what the JAX wrapper
/// checks before JAX allocates the trajectory's buffers, so that it raises the same errors.
#[pyfunction]
pub fn _trajectory_steps(scene: &Bound<'_, crate::scene_core::Scene>, steps: &Bound<'_, PyAny>) -> PyResult<usize> {
    let steps = crate::args::count(steps, "steps", 1)?;
    let n = crate::scene_core::view(scene, "steps")?.inner.model.n();
    let state = 2 * n * std::mem::size_of::<nalgebra::Vector3<f64>>();
    diffsoft::base::memory::check(
        &format!("{steps} steps of {n} vertices"),
        steps.saturating_add(1),
        state,
    )
    .map_err(|e| crate::errors::solver(e.into()))?;
    Ok(steps)
}

/// A `Run` from its four attributes (what unpickling calls).
#[pyfunction]
pub fn _run_from_state(positions: Py<PyAny>, velocities: Py<PyAny>, times: Py<PyAny>, stats: Py<PyAny>) -> Run {
    Run {
        positions,
        velocities,
        times,
        stats,
    }
}

#[pymethods]
impl Run {
    /// Pickling and copying by value (its arrays and log).
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyTuple>> {
        let f = py.import("diffsoft._diffsoft")?.getattr("_run_from_state")?;
        let args = pyo3::types::PyTuple::new(
            py,
            [&self.positions, &self.velocities, &self.times, &self.stats].map(|x| x.clone_ref(py)),
        )?;
        pyo3::types::PyTuple::new(py, [f, args.into_any()])
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let shape = self.positions.bind(py).getattr("shape")?.str()?.to_string();
        Ok(format!("Run(positions{shape})"))
    }
}
