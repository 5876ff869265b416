//! Named scalar parameters of a model (`youngs_modulus`, `density`, `gravity.y`, ...): read,
//! override (`--set`) and pick their derivative out of a [`Gradient`].

use std::fmt;
use std::str::FromStr;

use crate::model::Model;

use super::{DiffError, Gradient};

/// A scalar parameter shared by every body of a model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Param {
    /// Young's modulus of every body (Pa).
    YoungsModulus,
    /// Poisson ratio of every body.
    PoissonRatio,
    /// Density of every body (kg/m^3).
    Density,
    /// A component of every vertex's initial velocity (m/s).
    InitialVelocity(usize),
    /// A component of gravity (m/s^2), on bodies with gravity.
    Gravity(usize),
}

/// The names `diffsoft grad --param` accepts.
pub const NAMES: &[&str] = &[
    "youngs_modulus",
    "poisson_ratio",
    "density",
    "initial_velocity.x",
    "initial_velocity.y",
    "initial_velocity.z",
    "gravity.x",
    "gravity.y",
    "gravity.z",
];

impl FromStr for Param {
    type Err = DiffError;
    fn from_str(s: &str) -> Result<Self, DiffError> {
        let axis = |a: &str| match a {
            "x" => Some(0),
            "y" => Some(1),
            "z" => Some(2),
            _ => None,
        };
        Ok(match s {
            "youngs_modulus" => Param::YoungsModulus,
            "poisson_ratio" => Param::PoissonRatio,
            "density" => Param::Density,
            _ => match s.split_once('.') {
                Some(("initial_velocity", a)) if axis(a).is_some() => Param::InitialVelocity(axis(a).unwrap_or(0)),
                Some(("gravity", a)) if axis(a).is_some() => Param::Gravity(axis(a).unwrap_or(0)),
                _ => {
                    return Err(DiffError::Input(format!(
                        "unknown parameter '{s}' (known: {})",
                        NAMES.join(", ")
                    )))
                }
            },
        })
    }
}

impl fmt::Display for Param {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ax = |k: &usize| ["x", "y", "z"][*k];
        match self {
            Param::YoungsModulus => write!(f, "youngs_modulus"),
            Param::PoissonRatio => write!(f, "poisson_ratio"),
            Param::Density => write!(f, "density"),
            Param::InitialVelocity(k) => write!(f, "initial_velocity.{}", ax(k)),
            Param::Gravity(k) => write!(f, "gravity.{}", ax(k)),
        }
    }
}

fn uniform(name: &str, values: impl Iterator<Item = f64>) -> Result<f64, DiffError> {
    let mut first = None;
    for v in values {
        match first {
            None => first = Some(v),
            Some(f) if f != v => {
                return Err(DiffError::Input(format!(
                    "'{name}' differs between bodies or vertices ({f} and {v}); set one value with --set {name}=VALUE"
                )))
            }
            _ => {}
        }
    }
    first.ok_or_else(|| DiffError::Input(format!("the model has nothing that '{name}' applies to")))
}

impl Param {
    /// The parameter's value in `model` (an error if bodies disagree).
    pub fn get(&self, model: &Model) -> Result<f64, DiffError> {
        let name = self.to_string();
        match *self {
            Param::YoungsModulus => uniform(&name, model.bodies.iter().map(|b| b.material.youngs_modulus)),
            Param::PoissonRatio => uniform(&name, model.bodies.iter().map(|b| b.material.poisson_ratio)),
            Param::Density => uniform(&name, model.bodies.iter().map(|b| b.density)),
            Param::InitialVelocity(k) => uniform(&name, model.initial_velocity.iter().map(|v| v[k])),
            Param::Gravity(k) => uniform(
                &name,
                model
                    .bodies
                    .iter()
                    .filter(|b| b.gravity)
                    .flat_map(|b| b.vertices.clone())
                    .map(|i| model.accel[i][k]),
            ),
        }
    }

    /// Set the parameter in `model` (every body), updating what depends on it.
    pub fn set(&self, model: &mut Model, value: f64) -> Result<(), DiffError> {
        if !value.is_finite() {
            return Err(DiffError::Input(format!("{self}: value must be finite, got {value}")));
        }
        match *self {
            Param::YoungsModulus | Param::PoissonRatio => {
                for b in &mut model.bodies {
                    let mut m = b.material;
                    if *self == Param::YoungsModulus {
                        m.youngs_modulus = value;
                    } else {
                        m.poisson_ratio = value;
                    }
                    m.validate(&b.name).map_err(|e| DiffError::Input(e.to_string()))?;
                    b.material = m;
                    for t in b.tets.clone() {
                        let vol = model.fem.geometry[t].volume;
                        model.w_rot[t] = m.rotation_stiffness() * vol;
                        model.w_vol[t] = if b.volume_constraint {
                            m.volume_stiffness() * vol
                        } else {
                            0.0
                        };
                    }
                }
            }
            Param::Density => {
                if value <= 0.0 {
                    return Err(DiffError::Input(format!("density must be positive, got {value}")));
                }
                for b in &mut model.bodies {
                    let scale = value / b.density;
                    for i in b.vertices.clone() {
                        model.mass[i] *= scale;
                    }
                    b.mass *= scale;
                    b.density = value;
                }
            }
            Param::InitialVelocity(k) => model.initial_velocity.iter_mut().for_each(|v| v[k] = value),
            Param::Gravity(k) => {
                for b in model.bodies.iter().filter(|b| b.gravity) {
                    for i in b.vertices.clone() {
                        model.accel[i][k] = value;
                    }
                }
            }
        }
        Ok(())
    }

    /// `dL/d(parameter)` from a gradient of `model`.
    pub fn derivative(&self, model: &Model, g: &Gradient) -> f64 {
        match *self {
            Param::YoungsModulus => g.youngs_modulus(model).iter().sum(),
            Param::PoissonRatio => g.poisson_ratio(model).iter().sum(),
            Param::Density => g.density(model).iter().sum(),
            Param::InitialVelocity(k) => g.v0.iter().map(|v| v[k]).sum(),
            Param::Gravity(k) => model
                .bodies
                .iter()
                .filter(|b| b.gravity)
                .flat_map(|b| b.vertices.clone())
                .map(|i| g.accel[i][k])
                .sum(),
        }
    }
}

/// Young's modulus of every tet (Pa), read back from the tets' weights (`w_rot = E V/(1+nu)`,
/// Eq. 24); tets of cloth-free models only, in model order.
pub fn youngs_modulus_per_tet(model: &Model) -> Vec<f64> {
    let mut out = vec![0.0; model.tets.len()];
    for b in &model.bodies {
        let nu = b.material.poisson_ratio;
        for t in b.tets.clone() {
            out[t] = model.w_rot[t] * (1.0 + nu) / model.fem.geometry[t].volume;
        }
    }
    out
}

/// Set Young's modulus tet by tet (`values` in model order, finite and positive), updating the
/// tets' rotation and volume weights; the bodies' Poisson ratios stay.
pub fn set_youngs_modulus_per_tet(model: &mut Model, values: &[f64]) -> Result<(), DiffError> {
    if values.len() != model.tets.len() {
        return Err(DiffError::Input(format!(
            "youngs_modulus_per_tet: {} values for {} tets",
            values.len(),
            model.tets.len()
        )));
    }
    if let Some(t) = values.iter().position(|e| !(e.is_finite() && *e > 0.0)) {
        return Err(DiffError::Input(format!(
            "youngs_modulus_per_tet: tet {t} has Young's modulus {}, expected finite and positive",
            values[t]
        )));
    }
    for b in &model.bodies {
        let nu = b.material.poisson_ratio;
        for t in b.tets.clone() {
            let vol = model.fem.geometry[t].volume;
            model.w_rot[t] = values[t] * vol / (1.0 + nu);
            model.w_vol[t] = if b.volume_constraint {
                nu * values[t] * vol / (1.0 + nu)
            } else {
                0.0
            };
        }
    }
    Ok(())
}

/// The attachments' targets, in model order.
pub fn attachment_targets(model: &Model) -> Vec<nalgebra::Vector3<f64>> {
    model.attachments.iter().map(|a| a.target).collect()
}

/// Move the attachments' targets (`targets` in model order, finite).
pub fn set_attachment_targets(model: &mut Model, targets: &[nalgebra::Vector3<f64>]) -> Result<(), DiffError> {
    if targets.len() != model.attachments.len() {
        return Err(DiffError::Input(format!(
            "attachment_targets: {} targets for {} attachments",
            targets.len(),
            model.attachments.len()
        )));
    }
    if let Some(k) = targets.iter().position(|t| !t.iter().all(|x| x.is_finite())) {
        return Err(DiffError::Input(format!(
            "attachment_targets: target {k} is not finite"
        )));
    }
    for (a, t) in model.attachments.iter_mut().zip(targets) {
        a.target = *t;
    }
    Ok(())
}
