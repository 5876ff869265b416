//! `diffsoft.Scene`: a loaded scene with the parameters and controls a caller set, and its
//! simulation, gradient and vector-Jacobian product. The GIL is released while the library
//! runs.

use diffsoft::scene as lib_scene;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyFloat, PyTuple};

use crate::arrays;
use crate::errors;
use crate::interrupt;
use crate::params::{self, Inputs, Value};
use crate::run::Run;
use crate::scene_core::{grads, mode, names, snapshot, view, warn_stats, Scene};

#[pymethods]
impl Scene {
    /// Load a scene file: native `diffsoft.scene/1` or the paper's format. Relative paths in
    /// the scene resolve against the scene file's directory. Each file is read once (a named
    /// pipe fed once loads), and the scene and what it pickles are built from the same bytes.
    #[staticmethod]
    #[pyo3(signature = (path, passive = false))]
    fn load(py: Python<'_>, path: &Bound<'_, PyAny>, passive: bool) -> PyResult<Self> {
        let path = crate::args::path(path, "Scene.load: path")?;
        let (inner, source) = crate::scene_source::load(py, path, lib_scene::LoadOptions { passive })?;
        Ok(Scene {
            inner,
            inputs: Inputs::default(),
            data: crate::scene_source::Data::new(source),
        })
    }

    /// Set a parameter: a scalar of the CLI (`youngs_modulus`, `gravity.y`, ...) or an array
    /// (`initial_positions`, `youngs_modulus_per_tet`, `activations`, ...).
    fn set(slf: &Bound<'_, Self>, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        // The value is read from Python first (numpy, `__float__`, `__array__`: code that may
        // switch threads or touch this scene); the scene is held only while the value is
        // checked and applied, which runs no Python code.
        let raw = Value::convert(name, value)?;
        let mut this = busy(slf, "set")?;
        let this = &mut *this;
        let v = Value::check(&this.inner.model, name, raw)?;
        let mut model = this.inner.model.clone();
        let mut inputs = this.inputs.clone();
        let recorded = v.clone();
        v.apply(&mut model, &mut inputs)?;
        // Recorded for pickling once it applies (a refused value changes nothing).
        this.data.record(name, &recorded);
        this.inner.model = model;
        this.inputs = inputs;
        Ok(())
    }

    /// A parameter's current value (float or ndarray; `None` for per-step controls that follow
    /// the scene's schedules).
    fn get<'py>(slf: &Bound<'py, Self>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        let current = {
            let s = view(slf, "Scene.get")?;
            params::current(&s.inner.model, &s.inputs, name)?
        };
        current.into_py(slf.py())
    }

    /// Change solver settings by name (`solver`, `tolerance`, `max_iterations`, `dt`,
    /// `anderson`, ...: the fields of the library's `Settings`, as in a scene file's `solver`
    /// section and the CLI's overrides), each checked as it is set; on an error the settings
    /// are unchanged.
    #[pyo3(signature = (**settings))]
    fn configure(slf: &Bound<'_, Self>, settings: Option<&Bound<'_, PyDict>>) -> PyResult<()> {
        let Some(settings) = settings else {
            busy(slf, "configure")?;
            return Ok(());
        };
        // Every value is read from Python before the scene is held (see `set`).
        let mut values = Vec::with_capacity(settings.len());
        for (k, v) in settings.iter() {
            let key: String = k.extract()?;
            let value: serde_json::Value = match v.cast::<PyFloat>() {
                // JSON has no NaN or infinity: refused here, naming the value as given (an
                // unknown name is left to `Settings::set`, which says so).
                Ok(f) if !f.value().is_finite() && diffsoft::Settings::describe(&key).is_some() => {
                    return Err(errors::value(format!(
                        "configure({key}={}): must be a finite number",
                        f.value()
                    )))
                }
                _ => crate::pyjson::to_json_for(&v, &format!("configure({key})"))?,
            };
            values.push((key, value));
        }
        let mut this = busy(slf, "configure")?;
        let mut next = this.inner.settings.clone();
        for (key, value) in values {
            next.set(&key, value).map_err(errors::solver)?;
        }
        this.inner.settings = next;
        Ok(())
    }

    /// The solver settings as a dict (scene-file names).
    #[getter]
    fn settings<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let settings = view(slf, "Scene.settings")?.inner.settings.clone();
        arrays::report(slf.py(), &settings)
    }

    /// Number of vertices (rows of the position arrays).
    #[getter]
    fn n_vertices(slf: &Bound<'_, Self>) -> PyResult<usize> {
        Ok(view(slf, "Scene.n_vertices")?.inner.model.n())
    }

    /// Lumped mass of every vertex (kg), `(n,)`: for losses such as a centre of mass.
    #[getter]
    fn masses<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let m = view(slf, "Scene.masses")?.inner.model.mass().to_vec();
        let n = m.len();
        arrays::array(slf.py(), m, &[n])
    }

    /// Whether each vertex is fixed (pinned), `(n,)` bool as a list.
    #[getter]
    fn fixed(slf: &Bound<'_, Self>) -> PyResult<Vec<bool>> {
        Ok(view(slf, "Scene.fixed")?.inner.model.fixed().to_vec())
    }

    /// Number of tets.
    #[getter]
    fn n_tets(slf: &Bound<'_, Self>) -> PyResult<usize> {
        Ok(view(slf, "Scene.n_tets")?.inner.model.tets().len())
    }

    /// Time step (s).
    #[getter]
    fn dt(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(view(slf, "Scene.dt")?.inner.settings.dt)
    }

    /// The scene file.
    #[getter]
    fn path(slf: &Bound<'_, Self>) -> PyResult<String> {
        Ok(view(slf, "Scene.path")?.inner.path.display().to_string())
    }

    /// What the importer noted (defaults applied, keys not simulated), then each body's
    /// material notes as `diffsoft simulate` prints them (the projective response differing
    /// from the moduli given, a body too soft to carry its own weight), from the scene's
    /// current parameters.
    #[getter]
    fn notes(slf: &Bound<'_, Self>) -> PyResult<Vec<String>> {
        let s = view(slf, "Scene.notes")?;
        let mut notes = s.inner.notes.clone();
        notes.extend(diffsoft::output::body_notes(&s.inner.model));
        Ok(notes)
    }

    /// Every body's material: `name`, `model` (`projective`, `corotated`, `neo_hookean`),
    /// `youngs_modulus`, `poisson_ratio`, and for the projective model the moduli it responds
    /// with at small strain, `effective_youngs_modulus = E/(1 + 2nu/3)` and
    /// `effective_poisson_ratio = nu/(3 + 2nu)` (`None` for the true models), as `run.json`.
    #[getter]
    fn materials<'py>(slf: &Bound<'py, Self>) -> PyResult<Vec<Bound<'py, PyAny>>> {
        let materials = view(slf, "Scene.materials")?
            .inner
            .model
            .bodies()
            .iter()
            .map(|b| {
                let log = diffsoft::output::BodyLog::of(b);
                let mut v = serde_json::to_value(&log.material).map_err(errors::other)?;
                if let Some(o) = v.as_object_mut() {
                    o.insert("name".into(), serde_json::Value::String(log.name.clone()));
                }
                Ok(v)
            })
            .collect::<PyResult<Vec<_>>>()?;
        materials.iter().map(|v| arrays::json(slf.py(), v)).collect()
    }

    /// Names of the actuator groups (columns of `activations`).
    #[getter]
    fn actuator_groups(slf: &Bound<'_, Self>) -> PyResult<Vec<String>> {
        Ok(view(slf, "Scene.actuator_groups")?
            .inner
            .model
            .actuators()
            .map_or(Vec::new(), |a| a.groups.iter().map(|g| g.name.clone()).collect()))
    }

    /// Number of reduced joint coordinates (columns of `torques`; 0 without a skeleton).
    #[getter]
    fn joint_dofs(slf: &Bound<'_, Self>) -> PyResult<usize> {
        Ok(view(slf, "Scene.joint_dofs")?
            .inner
            .model
            .skeleton()
            .map_or(0, |s| s.dofs))
    }

    /// Number of attachments (rows of `attachment_targets`).
    #[getter]
    fn n_attachments(slf: &Bound<'_, Self>) -> PyResult<usize> {
        Ok(view(slf, "Scene.n_attachments")?.inner.model.attachments().len())
    }

    /// An independent copy.
    fn copy(slf: &Bound<'_, Self>) -> PyResult<Self> {
        snapshot(slf, "Scene.copy")
    }

    /// Simulate `steps` steps: positions and velocities of every state and the run log. Steps
    /// that stopped at `max_iterations` before meeting a positive tolerance raise a
    /// `ConvergenceWarning` at the caller's line (another names an unconverged step that raised
    /// the energy of a scene without an energy source); steps that ended with bodies passing
    /// through each other, or with inverted tets, a `UserWarning`.
    fn simulate(slf: &Bound<'_, Self>, steps: &Bound<'_, PyAny>) -> PyResult<Run> {
        let steps = crate::args::count(steps, "steps", 1)?;
        let (py, s) = (slf.py(), snapshot(slf, "Scene.simulate")?);
        let r = interrupt::run(py, || s.rollout(steps))??;
        // A tolerance of 0 asks for a fixed iteration count: no step is meant to converge.
        if s.inner.settings.tolerance > 0.0 && r.unconverged_steps() > 0 {
            crate::warn::unconverged(py)?;
        }
        if let Some(g) = diffsoft::output::solver_energy_gain(&s.inner.model, &r.stats) {
            crate::warn::energy_gain(py, &g, None)?;
        }
        if r.interpenetrating_steps() > 0 {
            crate::warn::interpenetration(py)?;
        }
        if diffsoft::output::folded(r.max_inverted_tets(), s.inner.model.tets().len()) {
            crate::warn::inversion(py, &crate::warn::soft_bodies(&s.inner.model))?;
        }
        Run::new(py, r, &s.inner.settings)
    }

    /// The loss and its derivatives with respect to `params` (name -> float or ndarray). A
    /// forward that misses its tolerance raises `ConvergenceError` unless `allow_unconverged`.
    /// A dict passed as `stats` receives the gradient's statistics (`diffsoft grad --json`'s
    /// `stats`: times, iterations, `forward_gap`, `unrolled_leftover`, ...).
    #[pyo3(signature = (steps, loss = "final_com.y", params = None, mode = "unrolled", allow_unconverged = false, stats = None))]
    #[allow(clippy::too_many_arguments)]
    fn grad<'py>(
        slf: &Bound<'py, Self>,
        steps: &Bound<'py, PyAny>,
        loss: &str,
        params: Option<&Bound<'py, PyAny>>,
        mode: &str,
        allow_unconverged: bool,
        stats: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let steps = crate::args::count(steps, "steps", 1)?;
        let params = params.map_or(Ok(Vec::new()), |p| crate::args::names(p, "params"))?;
        let (py, s) = (slf.py(), snapshot(slf, "Scene.grad")?);
        names(&s.inner.model, &params)?;
        let m = self::mode(mode)?;
        let g = interrupt::run(py, || s.gradient(steps, loss, m, allow_unconverged))??;
        warn_stats(py, &g, steps)?;
        fill_stats(py, stats, &g)?;
        let d = grads(py, &s.inner.model, &g, &params)?;
        PyTuple::new(py, [g.loss.into_pyobject(py)?.into_any(), d.into_any()])
    }

    /// The gradient of `sum(cotangent * positions) + sum(velocity_cotangent * velocities)` over
    /// the states `0..=steps` (arrays of shape `(steps + 1, n, 3)`) with respect to `params`. A
    /// forward that misses its tolerance raises `ConvergenceError` unless `allow_unconverged`.
    /// `stats` as in `grad`.
    #[pyo3(signature = (steps, params, cotangent, velocity_cotangent = None, mode = "unrolled", allow_unconverged = false, stats = None))]
    #[allow(clippy::too_many_arguments)]
    fn vjp<'py>(
        slf: &Bound<'py, Self>,
        steps: &Bound<'py, PyAny>,
        params: &Bound<'py, PyAny>,
        cotangent: &Bound<'py, PyAny>,
        velocity_cotangent: Option<&Bound<'py, PyAny>>,
        mode: &str,
        allow_unconverged: bool,
        stats: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let steps = crate::args::count(steps, "steps", 1)?;
        let params = crate::args::names(params, "params")?;
        let (py, s) = (slf.py(), snapshot(slf, "Scene.vjp")?);
        names(&s.inner.model, &params)?;
        let m = self::mode(mode)?;
        let cot = crate::vjp::cotangent(&s, steps, cotangent, velocity_cotangent, "")?;
        let g = interrupt::run(py, || s.vjp_gradient(steps, &cot, m, allow_unconverged))??;
        warn_stats(py, &g, steps)?;
        fill_stats(py, stats, &g)?;
        grads(py, &s.inner.model, &g, &params)
    }

    // --- Scenes as data, pickling (crate::scene_data) and accessors (crate::mesh_access) ---

    /// A scene from a dict of the scene file's structure (`schemas/scene.schema.json`; `schema`
    /// may be left out). A mesh is a file path (relative to `base_dir`, by default the working
    /// directory) or arrays: `{"vertices": (n, 3), "tets": (m, 4)}` for a body,
    /// `{"vertices": (n, 3), "triangles": (k, 3)}` for a cloth or an obstacle's `file`.
    #[staticmethod]
    #[pyo3(signature = (d, base_dir = None))]
    fn from_dict(py: Python<'_>, d: &Bound<'_, PyAny>, base_dir: Option<std::path::PathBuf>) -> PyResult<Self> {
        crate::scene_data::from_dict(py, d, base_dir)
    }

    /// A scene of one body from a meshio mesh (its `tetra` cells): `body` holds the body's keys
    /// (`material`, `density` or `total_mass`, `name`, ...) and `scene` the scene's other keys
    /// (`time_step` or `solver.dt`, `gravity`, `obstacles`, ...).
    #[staticmethod]
    #[pyo3(signature = (mesh, scene = None, **body))]
    fn from_meshio(
        py: Python<'_>,
        mesh: &Bound<'_, PyAny>,
        scene: Option<&Bound<'_, PyDict>>,
        body: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let d = py
            .import("diffsoft.mesh")?
            .call_method1("_meshio_scene", (mesh, scene, body))?;
        crate::scene_data::from_dict(py, &d, None)
    }

    /// The scene as a dict of the scene file's structure, every mesh inline as lists (so
    /// `json.dump` writes a scene file) and `solver` the current settings (`configure`).
    /// Parameters changed with `set` are not part of it (pickling keeps them).
    fn to_dict<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let doc = crate::scene_data::document(&*view(slf, "Scene.to_dict")?)?;
        arrays::json(slf.py(), &doc)
    }

    /// Every tet, `(m, 4)` int64, in the global vertex numbering (rows of the position arrays).
    #[getter]
    fn tets<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let tets = view(slf, "Scene.tets")?.inner.model.tets().to_vec();
        crate::mesh_access::index_array(slf.py(), &tets)
    }

    /// The boundary faces of the tets, `(k, 3)` int64, oriented outward (counter-clockwise seen
    /// from outside at rest), global vertex numbering.
    #[getter]
    fn surface_triangles<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let faces = crate::mesh_access::surface_triangles(&*view(slf, "Scene.surface_triangles")?);
        crate::mesh_access::index_array(slf.py(), &faces)
    }

    /// Every body: `name`, `kind` (`soft`, `cloth`), `vertices` `(start, stop)` (its rows of
    /// the position arrays) and `tets` (soft) or `triangles` (cloth) `(start, stop)`.
    #[getter]
    fn bodies<'py>(slf: &Bound<'py, Self>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let bodies = crate::mesh_access::bodies(&*view(slf, "Scene.bodies")?);
        crate::mesh_access::body_dicts(slf.py(), bodies)
    }

    /// Pickling by value: the scene's document (meshes inline, or a paper scene's files), its
    /// settings and the parameters set.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let f = py.import("diffsoft._diffsoft")?.getattr("_scene_from_state")?;
        // A copy, the borrow released: building the state runs Python code.
        let state = crate::scene_data::state(py, &snapshot(slf, "pickling the scene")?)?;
        PyTuple::new(py, [f, PyTuple::new(py, [state])?.into_any()])
    }

    fn __copy__(slf: &Bound<'_, Self>) -> PyResult<Self> {
        snapshot(slf, "copy.copy(scene)")
    }

    fn __deepcopy__(slf: &Bound<'_, Self>, _memo: &Bound<'_, PyAny>) -> PyResult<Self> {
        snapshot(slf, "copy.deepcopy(scene)")
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let s = view(slf, "repr(scene)")?;
        Ok(format!(
            "Scene('{}', vertices={}, tets={}, dt={})",
            s.inner.path.display(),
            s.inner.model.n(),
            s.inner.model.tets().len(),
            s.inner.settings.dt
        ))
    }
}

/// The scene for `set`/`configure`, or a `SceneBusyError` while a call on another thread holds
/// it (a batch or `gradcheck` reading it without the GIL).
fn busy<'py>(slf: &Bound<'py, Scene>, method: &str) -> PyResult<PyRefMut<'py, Scene>> {
    slf.try_borrow_mut().map_err(|_| {
        errors::Class::Busy.err(format!(
            "Scene.{method}: the scene is in use by a call running on another thread (a batch or gradcheck); wait for it to return, or change a copy (Scene.copy())"
        ))
    })
}

/// Put a gradient's statistics into the caller's `stats` dict, if one was given (cleared first).
fn fill_stats(py: Python<'_>, stats: Option<&Bound<'_, PyDict>>, g: &diffsoft::Gradient) -> PyResult<()> {
    let Some(out) = stats else { return Ok(()) };
    let value = serde_json::to_value(g.stats).map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    out.clear();
    let filled = arrays::json(py, &value)?;
    for (k, v) in filled.cast::<PyDict>()?.iter() {
        out.set_item(k, v)?;
    }
    Ok(())
}
