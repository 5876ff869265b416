//! The parameters a Python caller can set, read and differentiate: those of the library's
//! registry (`diffsoft::diff::params::PARAMETERS`), scalars and arrays, by name.

use diffsoft::diff::params::{self as lib, ArrayParam};
use diffsoft::{Controls, Gradient, Model, Param};
use nalgebra::Vector3;
use pyo3::prelude::*;

use crate::arrays;
use crate::errors;

/// A parameter by name.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Name {
    /// A scalar (the CLI's `--param`/`--set`).
    Scalar(Param),
    /// An array.
    Array(ArrayParam),
}

impl Name {
    /// Parse a parameter name.
    pub fn parse(s: &str) -> PyResult<Self> {
        let spec = lib::lookup(s).ok_or_else(|| {
            errors::value(format!(
                "unknown parameter '{s}' (scalars: {}; arrays: {})",
                lib::scalar_names().join(", "),
                lib::array_names().join(", ")
            ))
        })?;
        Ok(match (Param::of(spec), spec.array()) {
            (Some(p), _) => Name::Scalar(p),
            (None, Some(a)) => Name::Array(a),
            (None, None) => unreachable!("a parameter is a scalar or an array"),
        })
    }

    /// Refuse a parameter that `model` has nothing for (a material without bodies, activations
    /// without actuators, torques without a skeleton): its derivative would be vacuous.
    pub fn check_applies(self, model: &Model) -> PyResult<()> {
        match self {
            Name::Scalar(p) => p.check_applies(model).map_err(errors::diff),
            Name::Array(ArrayParam::Activations) if groups(model) == 0 => {
                Err(errors::value("activations: the scene has no actuators"))
            }
            Name::Array(ArrayParam::Torques) if dofs(model) == 0 => {
                Err(errors::value("torques: the scene has no skeleton"))
            }
            Name::Array(_) => Ok(()),
        }
    }
}

/// What a scene holds besides its model: the controls a caller set.
#[derive(Debug, Clone, Default)]
pub struct Inputs {
    /// Initial positions (`None`: the rest positions).
    pub q0: Option<Vec<Vector3<f64>>>,
    /// Initial velocities (`None`: the model's).
    pub v0: Option<Vec<Vector3<f64>>>,
    /// Activations per step and group (`None`: the schedules).
    pub activations: Option<Vec<Vec<f64>>>,
    /// Torques per step and coordinate (`None`: the schedules).
    pub torques: Option<Vec<Vec<f64>>>,
}

impl Inputs {
    /// The library's controls for a run the user asked for: initial positions set from Python
    /// get the obstacle checks of a scene's own start first (`check_initial_positions`: no
    /// vertex inside an obstacle, no edge through one), an `InputError` naming them otherwise.
    pub fn checked_controls(&self, model: &Model, steps: usize) -> PyResult<Controls> {
        self.check_rows(steps)?;
        if let Some(q) = &self.q0 {
            diffsoft::solver::check_initial_positions(model, q).map_err(errors::solver)?;
        }
        Ok(self.controls(model))
    }

    /// Refuse per-step controls that do not have one row per step of a run of `steps` steps
    /// (more rows would be dropped without a word, and their gradient would lose rows).
    pub fn check_rows(&self, steps: usize) -> PyResult<()> {
        for (name, rows) in [("activations", &self.activations), ("torques", &self.torques)] {
            if let Some(rows) = rows.as_ref().filter(|r| r.len() != steps) {
                return Err(errors::value(format!(
                    "{name}: {} rows for a run of {steps} steps; give one row per step",
                    rows.len()
                )));
            }
        }
        Ok(())
    }

    /// The library's controls, unchecked (the gradient-check harness perturbs a start that
    /// touches an obstacle on purpose).
    pub fn controls(&self, model: &Model) -> Controls {
        let initial = (self.q0.is_some() || self.v0.is_some()).then(|| {
            (
                self.q0.clone().unwrap_or_else(|| model.rest().to_vec()),
                self.v0.clone().unwrap_or_else(|| model.initial_velocity().to_vec()),
            )
        });
        Controls {
            initial,
            activations: self.activations.clone(),
            torques: self.torques.clone(),
        }
    }
}

fn groups(model: &Model) -> usize {
    model.actuators().map_or(0, |a| a.groups.len())
}

fn dofs(model: &Model) -> usize {
    model.skeleton().map_or(0, |s| s.dofs)
}

/// Refuse activations outside their actuator group's range (as the run would, at its step).
fn check_activations(model: &Model, rows: &[Vec<f64>]) -> PyResult<()> {
    let Some(act) = model.actuators() else { return Ok(()) };
    for (step, row) in rows.iter().enumerate() {
        for (g, (a, group)) in row.iter().zip(&act.groups).enumerate() {
            if !group.kind.admits(*a) {
                return Err(errors::value(format!(
                    "activations[{step}, {g}]: actuator '{}': activation {a} out of range ({})",
                    group.name,
                    group.kind.range()
                )));
            }
        }
    }
    Ok(())
}

/// Refuse torques on the coordinates of joints with other than one DoF, by the rule the run
/// applies ([`diffsoft::skeleton::Skeleton::misplaced_torque`]), naming the entry.
fn check_torques(model: &Model, rows: &[Vec<f64>]) -> PyResult<()> {
    let Some(sk) = model.skeleton() else { return Ok(()) };
    for (step, row) in rows.iter().enumerate() {
        if let Some((k, b)) = sk.misplaced_torque(row) {
            return Err(errors::value(format!(
                "torques[{step}, {k}]: {}, but bone '{}' has a {} joint; torques act on one-DoF joints (give 0)",
                row[k],
                b.name,
                b.joint.kind()
            )));
        }
    }
    Ok(())
}

/// A parameter's value, converted from Python, ready to set (checked against the model).
#[derive(Debug, Clone)]
pub enum Value {
    /// A scalar.
    Scalar(Param, f64),
    /// Vectors (initial positions, velocities, attachment targets).
    Vectors(ArrayParam, Vec<Vector3<f64>>),
    /// Per-tet values.
    PerTet(Vec<f64>),
    /// Rows per step.
    PerStep(ArrayParam, Vec<Vec<f64>>),
}

/// A parameter's value read from Python but not yet checked against a model ([`Value::convert`]):
/// what `Scene.set` reads before it takes the scene, so that no Python code runs while it holds
/// it.
#[derive(Debug, Clone)]
pub enum Raw {
    /// A scalar.
    Scalar(Param, f64),
    /// An array: its values and shape.
    Array(ArrayParam, Vec<f64>, Vec<usize>),
}

impl Value {
    /// Convert `value` for parameter `name` of `model`.
    pub fn read(model: &Model, name: &str, value: &Bound<'_, PyAny>) -> PyResult<Self> {
        Self::check(model, name, Self::convert(name, value)?)
    }

    /// Read `value` for parameter `name` from Python (numbers, finiteness; no model needed).
    pub fn convert(name: &str, value: &Bound<'_, PyAny>) -> PyResult<Raw> {
        Ok(match Name::parse(name)? {
            // `True` is an int to Python, not a modulus; a complex number is not a real one.
            Name::Scalar(p) => Raw::Scalar(p, arrays::read_scalar(name, value)?),
            Name::Array(ArrayParam::InitialJointState) => {
                return Err(errors::value(
                    "initial_joint_state can be differentiated but not set (set the bones' initial coordinates in the scene file)",
                ))
            }
            Name::Array(a) => {
                let (data, shape) = arrays::read(name, value)?;
                Raw::Array(a, data, shape)
            }
        })
    }

    /// A value [`Value::convert`] read, checked against `model` (shapes, ranges); no Python
    /// code runs.
    pub fn check(model: &Model, name: &str, raw: Raw) -> PyResult<Self> {
        let (a, read) = match raw {
            Raw::Scalar(p, v) => return Ok(Value::Scalar(p, v)),
            Raw::Array(a, data, shape) => (a, (data, shape)),
        };
        Ok(match a {
            ArrayParam::InitialPositions | ArrayParam::InitialVelocities => {
                Value::Vectors(a, arrays::vectors_of(name, read, model.n())?)
            }
            ArrayParam::AttachmentTargets => Value::Vectors(
                ArrayParam::AttachmentTargets,
                arrays::vectors_of(name, read, model.attachments().len())?,
            ),
            ArrayParam::YoungsModulusPerTet => Value::PerTet(arrays::vector_of(name, read, model.tets().len())?),
            ArrayParam::Activations => {
                Name::Array(a).check_applies(model)?;
                let rows = arrays::matrix_of(name, read, None, groups(model))?;
                check_activations(model, &rows)?;
                Value::PerStep(a, rows)
            }
            ArrayParam::Torques => {
                Name::Array(a).check_applies(model)?;
                let rows = arrays::matrix_of(name, read, None, dofs(model))?;
                check_torques(model, &rows)?;
                Value::PerStep(a, rows)
            }
            ArrayParam::InitialJointState => {
                return Err(errors::value(
                    "initial_joint_state can be differentiated but not set (set the bones' initial coordinates in the scene file)",
                ))
            }
        })
    }

    /// Set the value in `model` and `inputs`.
    pub fn apply(self, model: &mut Model, inputs: &mut Inputs) -> PyResult<()> {
        match self {
            Value::Scalar(p, v) => {
                p.set(model, v).map_err(errors::diff)?;
                // Initial velocities the caller set replace the model's: the scalar sets them too.
                if let (Some(k), Some(v0)) = (p.initial_velocity_axis(), inputs.v0.as_mut()) {
                    v0.iter_mut().for_each(|x| x[k] = v);
                }
            }
            Value::Vectors(ArrayParam::InitialPositions, q) => inputs.q0 = Some(q),
            Value::Vectors(ArrayParam::InitialVelocities, v) => inputs.v0 = Some(v),
            Value::Vectors(_, t) => lib::set_attachment_targets(model, &t).map_err(errors::diff)?,
            Value::PerTet(e) => lib::set_youngs_modulus_per_tet(model, &e).map_err(errors::diff)?,
            Value::PerStep(ArrayParam::Activations, a) => inputs.activations = Some(a),
            Value::PerStep(_, t) => inputs.torques = Some(t),
        }
        Ok(())
    }
}

/// A parameter's current value as Rust data ([`current`]), made a Python object with
/// [`Current::into_py`] once the scene is no longer borrowed.
pub enum Current {
    /// A scalar.
    Scalar(f64),
    /// An array of `shape`.
    Array(Vec<f64>, Vec<usize>),
    /// A per-step control left to the schedules.
    None,
}

impl Current {
    /// The Python object: a float, an ndarray or `None`.
    pub fn into_py(self, py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
        Ok(match self {
            Current::Scalar(v) => v.into_pyobject(py)?.into_any(),
            Current::Array(data, shape) => arrays::array(py, data, &shape)?,
            Current::None => py.None().into_bound(py),
        })
    }
}

/// The current value of parameter `name` (`None` for per-step controls left to the schedules).
pub fn current(model: &Model, inputs: &Inputs, name: &str) -> PyResult<Current> {
    let vectors = |v: Vec<Vector3<f64>>| {
        let rows = v.len();
        Current::Array(arrays::flatten(v), vec![rows, 3])
    };
    let matrix = |rows: &[Vec<f64>], cols: usize| {
        Current::Array(rows.iter().flatten().copied().collect(), vec![rows.len(), cols])
    };
    Ok(match Name::parse(name)? {
        Name::Scalar(p) => Current::Scalar(p.get(model).map_err(errors::diff)?),
        Name::Array(a) => match a {
            ArrayParam::InitialPositions => vectors(inputs.q0.clone().unwrap_or_else(|| model.rest().to_vec())),
            ArrayParam::InitialVelocities => {
                vectors(inputs.v0.clone().unwrap_or_else(|| model.initial_velocity().to_vec()))
            }
            ArrayParam::YoungsModulusPerTet => {
                Current::Array(lib::youngs_modulus_per_tet(model), vec![model.tets().len()])
            }
            ArrayParam::AttachmentTargets => vectors(lib::attachment_targets(model)),
            ArrayParam::Activations => inputs
                .activations
                .as_ref()
                .map_or(Current::None, |a| matrix(a, groups(model))),
            ArrayParam::Torques => inputs
                .torques
                .as_ref()
                .map_or(Current::None, |t| matrix(t, dofs(model))),
            ArrayParam::InitialJointState => {
                return Err(errors::value("initial_joint_state is available as a gradient only"));
            }
        },
    })
}

/// The derivative of the loss with respect to parameter `name`.
pub fn derivative<'py>(py: Python<'py>, model: &Model, g: &Gradient, name: Name) -> PyResult<Bound<'py, PyAny>> {
    Ok(match name {
        Name::Scalar(p) => {
            name.check_applies(model)?;
            p.derivative(model, g).into_pyobject(py)?.into_any()
        }
        Name::Array(a) => match a {
            ArrayParam::InitialPositions => arrays::vectors(py, g.q0.clone())?,
            ArrayParam::InitialVelocities => arrays::vectors(py, g.v0.clone())?,
            ArrayParam::YoungsModulusPerTet => arrays::array(py, g.youngs_modulus(model), &[model.tets().len()])?,
            ArrayParam::AttachmentTargets => arrays::vectors(py, g.attachment_targets.clone())?,
            ArrayParam::Activations => {
                name.check_applies(model)?;
                arrays::matrix(py, &g.activations, groups(model))?
            }
            ArrayParam::Torques => {
                name.check_applies(model)?;
                arrays::matrix(py, &g.torques, dofs(model))?
            }
            ArrayParam::InitialJointState => {
                let d = g.joints0.clone();
                let len = d.len();
                arrays::array(py, d, &[len])?
            }
        },
    })
}
