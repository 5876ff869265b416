//! `diffsoft.Scene`'s state and the calls every binding module shares: the library's gradient
//! and rollout on a scene, parameter names and values read from Python, gradients as a dict,
//! and the warnings a gradient raises. The Python methods are in the `scene` module.

use diffsoft::diff::{self, Options};
use diffsoft::{scene as lib_scene, Mode, Model};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors;
use crate::params::{self, Inputs, Name, Value};

/// A scene ready to simulate and differentiate.
#[pyclass(name = "Scene", module = "diffsoft")]
#[derive(Clone)]
pub struct Scene {
    pub(crate) inner: lib_scene::Scene,
    pub(crate) inputs: Inputs,
    /// Its source and the parameters set, by value (`crate::scene_source`).
    pub(crate) data: crate::scene_source::Data,
}

/// The scene behind `slf` for reading, or a `SceneBusyError` naming `what` (the call, e.g.
/// `Scene.simulate`) should another call hold it for a change. `Scene.set` and `configure` read
/// their arguments before they take the scene and run no Python code while they hold it, so
/// no other thread sees it held: this is the clean error in place of pyo3's panic or plain
/// `RuntimeError` should that ever change.
pub(crate) fn view<'py>(slf: &Bound<'py, Scene>, what: &str) -> PyResult<PyRef<'py, Scene>> {
    slf.try_borrow().map_err(|_| {
        errors::Class::Busy.err(format!(
            "{what}: the scene is in use by another call (a set or configure of it); wait for it to return, or use a copy (Scene.copy())"
        ))
    })
}

/// A copy of the scene behind `slf` ([`view`]), the borrow released: what calls that run
/// Python code or the library on it work on, so another thread's `set` or `configure`
/// meanwhile changes the scene, not the call.
pub(crate) fn snapshot(slf: &Bound<'_, Scene>, what: &str) -> PyResult<Scene> {
    Ok(view(slf, what)?.clone())
}

/// A differentiation mode by name.
pub fn mode(name: &str) -> PyResult<Mode> {
    match name {
        "unrolled" => Ok(Mode::Unrolled),
        "implicit" => Ok(Mode::Implicit),
        _ => Err(errors::value(format!(
            "mode '{name}': expected 'unrolled' or 'implicit'"
        ))),
    }
}

/// Parameter names, parsed, each refused unless `model` has something it applies to (what
/// `grad`, `vjp`, the batches and `gradcheck` check before they run).
pub fn names(model: &Model, params: &[String]) -> PyResult<Vec<Name>> {
    params
        .iter()
        .map(|p| {
            let n = Name::parse(p)?;
            n.check_applies(model)?;
            Ok(n)
        })
        .collect()
}

/// The loss named `name`, checked against `model` (a joint loss names one of its bones).
pub fn loss(model: &Model, name: &str) -> PyResult<Box<dyn diff::loss::Loss>> {
    let loss = diff::loss::by_name(name).map_err(errors::diff)?;
    loss.validate(model).map_err(errors::diff)?;
    Ok(loss)
}

/// `name -> derivative` for `params`.
pub fn grads<'py>(
    py: Python<'py>,
    model: &Model,
    g: &diffsoft::Gradient,
    params: &[String],
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (p, n) in params.iter().zip(names(model, params)?) {
        d.set_item(p, params::derivative(py, model, g, n)?)?;
    }
    Ok(d)
}

/// Read `{name: value}` pairs for `model`.
pub fn values(model: &Model, values: &Bound<'_, PyDict>) -> PyResult<Vec<Value>> {
    let mut out = values
        .iter()
        .map(|(k, v)| {
            let name: String = k
                .extract()
                .map_err(|_| errors::value("parameter names must be strings"))?;
            Value::read(model, &name, &v)
        })
        .collect::<PyResult<Vec<_>>>()?;
    // Scalars first, so a per-tet array in the same dict overrides its scalar whatever the
    // dict's order.
    out.sort_by_key(|v| !matches!(v, Value::Scalar(..)));
    Ok(out)
}

impl Scene {
    /// This scene with `values` set.
    pub fn with(&self, values: Vec<Value>) -> PyResult<Scene> {
        let mut s = self.clone();
        for v in values {
            v.apply(&mut s.inner.model, &mut s.inputs)?;
        }
        Ok(s)
    }

    fn check_steps(steps: usize) -> PyResult<()> {
        if steps == 0 {
            return Err(errors::value("steps must be at least 1"));
        }
        Ok(())
    }

    /// The gradient of `loss` (the library's call, without the GIL).
    pub fn gradient(
        &self,
        steps: usize,
        loss: &str,
        mode: Mode,
        allow_unconverged: bool,
    ) -> PyResult<diffsoft::Gradient> {
        Self::check_steps(steps)?;
        let loss = self::loss(&self.inner.model, loss)?;
        let controls = self.inputs.checked_controls(&self.inner.model, steps)?;
        diff::gradient(
            &self.inner.model,
            &self.inner.settings,
            steps,
            &controls,
            loss.as_ref(),
            Options {
                allow_unconverged,
                ..Options::mode(mode)
            },
        )
        .map_err(errors::diff)
    }

    /// A rollout (the library's call, without the GIL).
    pub fn rollout(&self, steps: usize) -> PyResult<diff::Rollout> {
        Self::check_steps(steps)?;
        let controls = self.inputs.checked_controls(&self.inner.model, steps)?;
        diff::rollout(&self.inner.model, &self.inner.settings, steps, &controls).map_err(errors::diff)
    }
}

/// A `UserWarning` at the caller's line ([`crate::warn`]) for each of `DiffStats::warnings`
/// (unrolled steps that met the tolerance in their first iteration, steps at a kink of the
/// loss, adjoint solves that stopped unconverged, a forward or its iterations' derivative far
/// from converged).
pub(crate) fn warn_stats(py: Python<'_>, g: &diffsoft::Gradient, steps: usize) -> PyResult<()> {
    let warn = |message: String| crate::warn::user(py, &message);
    for w in g.stats.warnings(steps) {
        warn(w)?;
    }
    Ok(())
}
