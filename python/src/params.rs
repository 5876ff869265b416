//! The parameters a Python caller can set, read and differentiate: the CLI's scalars
//! (`youngs_modulus`, `gravity.y`, ...) and the library's arrays, with their shapes.

use diffsoft::diff::params as lib;
use diffsoft::{Controls, Gradient, Model, Param};
use nalgebra::Vector3;
use pyo3::prelude::*;

use crate::arrays;
use crate::errors;

/// Array parameters: name, shape (in words) and what it is.
pub const ARRAYS: &[(&str, &str, &str)] = &[
    (
        "initial_positions",
        "(n, 3)",
        "positions of every vertex before the first step (m)",
    ),
    (
        "initial_velocities",
        "(n, 3)",
        "velocities of every vertex before the first step (m/s)",
    ),
    ("youngs_modulus_per_tet", "(tets,)", "Young's modulus of every tet (Pa)"),
    (
        "attachment_targets",
        "(attachments, 3)",
        "target of every attachment (m)",
    ),
    (
        "activations",
        "(steps, groups)",
        "activation of every actuator group at every step",
    ),
    (
        "torques",
        "(steps, dofs)",
        "torque on every joint coordinate at every step (one-DoF joints)",
    ),
    (
        "initial_joint_state",
        "(dofs,)",
        "initial joint coordinates (gradient only)",
    ),
];

/// A parameter by name.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Name {
    /// A scalar of the CLI.
    Scalar(Param),
    /// `initial_positions`.
    InitialPositions,
    /// `initial_velocities`.
    InitialVelocities,
    /// `youngs_modulus_per_tet`.
    YoungsPerTet,
    /// `attachment_targets`.
    AttachmentTargets,
    /// `activations`.
    Activations,
    /// `torques`.
    Torques,
    /// `initial_joint_state`.
    InitialJointState,
}

impl Name {
    /// Parse a parameter name.
    pub fn parse(s: &str) -> PyResult<Self> {
        Ok(match s {
            "initial_positions" => Name::InitialPositions,
            "initial_velocities" => Name::InitialVelocities,
            "youngs_modulus_per_tet" => Name::YoungsPerTet,
            "attachment_targets" => Name::AttachmentTargets,
            "activations" => Name::Activations,
            "torques" => Name::Torques,
            "initial_joint_state" => Name::InitialJointState,
            _ => Name::Scalar(s.parse().map_err(|_| {
                let arrays: Vec<&str> = ARRAYS.iter().map(|a| a.0).collect();
                errors::value(format!(
                    "unknown parameter '{s}' (scalars: {}; arrays: {})",
                    lib::NAMES.join(", "),
                    arrays.join(", ")
                ))
            })?),
        })
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
    /// The library's controls.
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

/// A parameter's value, converted from Python, ready to set (checked against the model).
#[derive(Debug, Clone)]
pub enum Value {
    /// A scalar.
    Scalar(Param, f64),
    /// Vectors (initial positions, velocities, attachment targets).
    Vectors(Name, Vec<Vector3<f64>>),
    /// Per-tet values.
    PerTet(Vec<f64>),
    /// Rows per step.
    PerStep(Name, Vec<Vec<f64>>),
}

impl Value {
    /// Convert `value` for parameter `name` of `model`.
    pub fn read(model: &Model, name: &str, value: &Bound<'_, PyAny>) -> PyResult<Self> {
        Ok(match Name::parse(name)? {
            Name::Scalar(p) => {
                let v: f64 = value
                    .extract()
                    .map_err(|_| errors::value(format!("{name}: expected a number")))?;
                Value::Scalar(p, v)
            }
            n @ (Name::InitialPositions | Name::InitialVelocities) => {
                Value::Vectors(n, arrays::read_vectors(name, value, model.n())?)
            }
            Name::AttachmentTargets => {
                Value::Vectors(Name::AttachmentTargets, arrays::read_vectors(name, value, model.attachments().len())?)
            }
            Name::YoungsPerTet => Value::PerTet(arrays::read_vector(name, value, model.tets().len())?),
            Name::Activations => {
                if groups(model) == 0 {
                    return Err(errors::value("activations: the scene has no actuators"));
                }
                Value::PerStep(Name::Activations, arrays::read_matrix(name, value, None, groups(model))?)
            }
            Name::Torques => {
                if dofs(model) == 0 {
                    return Err(errors::value("torques: the scene has no skeleton"));
                }
                Value::PerStep(Name::Torques, arrays::read_matrix(name, value, None, dofs(model))?)
            }
            Name::InitialJointState => {
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
                if let (Param::InitialVelocity(k), Some(v0)) = (p, inputs.v0.as_mut()) {
                    v0.iter_mut().for_each(|x| x[k] = v);
                }
            }
            Value::Vectors(Name::InitialPositions, q) => inputs.q0 = Some(q),
            Value::Vectors(Name::InitialVelocities, v) => inputs.v0 = Some(v),
            Value::Vectors(_, t) => lib::set_attachment_targets(model, &t).map_err(errors::diff)?,
            Value::PerTet(e) => lib::set_youngs_modulus_per_tet(model, &e).map_err(errors::diff)?,
            Value::PerStep(Name::Activations, a) => inputs.activations = Some(a),
            Value::PerStep(_, t) => inputs.torques = Some(t),
        }
        Ok(())
    }
}

/// The current value of parameter `name` (`None` for per-step controls left to the schedules).
pub fn get<'py>(py: Python<'py>, model: &Model, inputs: &Inputs, name: &str) -> PyResult<Bound<'py, PyAny>> {
    Ok(match Name::parse(name)? {
        Name::Scalar(p) => p.get(model).map_err(errors::diff)?.into_pyobject(py)?.into_any(),
        Name::InitialPositions => arrays::vectors(py, inputs.q0.clone().unwrap_or_else(|| model.rest().to_vec()))?,
        Name::InitialVelocities => arrays::vectors(
            py,
            inputs.v0.clone().unwrap_or_else(|| model.initial_velocity().to_vec()),
        )?,
        Name::YoungsPerTet => arrays::array(py, lib::youngs_modulus_per_tet(model), &[model.tets().len()])?,
        Name::AttachmentTargets => arrays::vectors(py, lib::attachment_targets(model))?,
        Name::Activations => match &inputs.activations {
            Some(a) => arrays::matrix(py, a, groups(model))?,
            None => py.None().into_bound(py),
        },
        Name::Torques => match &inputs.torques {
            Some(t) => arrays::matrix(py, t, dofs(model))?,
            None => py.None().into_bound(py),
        },
        Name::InitialJointState => {
            return Err(errors::value("initial_joint_state is available as a gradient only"));
        }
    })
}

/// The derivative of the loss with respect to parameter `name`.
pub fn derivative<'py>(py: Python<'py>, model: &Model, g: &Gradient, name: Name) -> PyResult<Bound<'py, PyAny>> {
    Ok(match name {
        Name::Scalar(p) => p.derivative(model, g).into_pyobject(py)?.into_any(),
        Name::InitialPositions => arrays::vectors(py, g.q0.clone())?,
        Name::InitialVelocities => arrays::vectors(py, g.v0.clone())?,
        Name::YoungsPerTet => arrays::array(py, g.youngs_modulus(model), &[model.tets().len()])?,
        Name::AttachmentTargets => arrays::vectors(py, g.attachment_targets.clone())?,
        Name::Activations => arrays::matrix(py, &g.activations, groups(model))?,
        Name::Torques => {
            if dofs(model) == 0 {
                return Err(errors::value("torques: the scene has no skeleton"));
            }
            arrays::matrix(py, &g.torques, dofs(model))?
        }
        Name::InitialJointState => {
            let d = g.joints0.clone();
            let len = d.len();
            arrays::array(py, d, &[len])?
        }
    })
}
