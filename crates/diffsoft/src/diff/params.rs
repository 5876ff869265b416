//! The parameter registry: [`PARAMETERS`] is the one table of everything a caller can set, read
//! or differentiate by name (`youngs_modulus`, `gravity.y`, `initial_positions`, ...), with its
//! shape, units and meaning. A scalar's entry also holds how it is read from a [`Model`], set in
//! one and picked out of a [`Gradient`]; [`Param`] is a handle to such an entry.
//!
//! Everything that names parameters reads this table: `diffsoft grad --param`/`--set` (their
//! help and validation), Python's `Scene.set`/`get`/`grad`/`vjp`, `diffsoft.SCALAR_PARAMETERS`
//! and `diffsoft.ARRAY_PARAMETERS` and their error messages, and the JSON Schema of
//! `diffsoft grad --json` ([`values_schema`]). A new differentiable scalar is one entry here
//! plus the adjoint code that fills the [`Gradient`] field its `derivative` reads.

use std::fmt;
use std::str::FromStr;

use nalgebra::Vector3;

use crate::kernel::hyperelastic::Lame;
use crate::model::Model;

use super::{DiffError, Gradient};

/// One parameter of the registry.
#[derive(Debug)]
pub struct ParamSpec {
    /// Name: `--param`/`--set`, Python's `Scene.set`/`get`/`grad` and the reports spell it so.
    pub name: &'static str,
    /// Shape in words: [`SCALAR`] for a scalar, `(n, 3)`, `(tets,)`, `(steps, groups)`, ...
    pub shape: &'static str,
    /// Unit (`1`: dimensionless).
    pub units: &'static str,
    /// What it is, in a phrase (units apart).
    pub description: &'static str,
    /// How it is read, set and differentiated.
    pub kind: ParamKind,
}

/// The shape of a scalar parameter.
pub const SCALAR: &str = "()";

/// How a parameter is read, set and differentiated.
#[derive(Debug)]
pub enum ParamKind {
    /// One value shared by every body (or vertex) of a model. `set` receives a finite value.
    Scalar {
        /// The value in a model (an error if bodies disagree or nothing has it).
        get: Getter,
        /// Set the value in a model, updating what depends on it.
        set: Setter,
        /// `dL/d(parameter)` from a gradient of the model.
        derivative: Derivative,
    },
    /// An array: initial state, per-tet or per-attachment values, or per-step controls (the
    /// bindings hold the arrays that are not part of the model).
    Array(ArrayParam),
}

/// Reads a scalar parameter from a model.
pub type Getter = fn(&Model) -> Result<f64, DiffError>;
/// Sets a scalar parameter in a model (given a finite value).
pub type Setter = fn(&mut Model, f64) -> Result<(), DiffError>;
/// Picks `dL/d(parameter)` out of a gradient of a model.
pub type Derivative = fn(&Model, &Gradient) -> f64;

/// The array parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArrayParam {
    /// Positions before the first step (the controls' initial state).
    InitialPositions,
    /// Velocities before the first step (the controls' initial state).
    InitialVelocities,
    /// Young's modulus of every tet ([`youngs_modulus_per_tet`]).
    YoungsModulusPerTet,
    /// The attachments' targets ([`attachment_targets`]).
    AttachmentTargets,
    /// Activations per step and group (the controls).
    Activations,
    /// Joint torques per step and reduced coordinate (the controls).
    Torques,
    /// The initial joint state (a gradient only).
    InitialJointState,
}

/// Every parameter: the scalars, then the arrays.
pub static PARAMETERS: &[ParamSpec] = &[
    ParamSpec {
        name: "youngs_modulus",
        shape: SCALAR,
        units: "Pa",
        description: "Young's modulus of every body",
        kind: ParamKind::Scalar {
            get: youngs_modulus,
            set: |m, v| set_material(m, |mat| mat.youngs_modulus = v, Moduli::Scalar),
            derivative: |m, g| g.youngs_modulus(m).iter().sum(),
        },
    },
    ParamSpec {
        name: "poisson_ratio",
        shape: SCALAR,
        units: "1",
        description: "Poisson ratio of every body",
        kind: ParamKind::Scalar {
            get: |m| uniform("poisson_ratio", m.bodies.iter().map(|b| b.material.poisson_ratio)),
            set: |m, v| set_material(m, |mat| mat.poisson_ratio = v, Moduli::Kept),
            derivative: |m, g| g.poisson_ratio(m).iter().sum(),
        },
    },
    ParamSpec {
        name: "density",
        shape: SCALAR,
        units: "kg/m^3",
        description: "density of every body (the lumped masses scale with it)",
        kind: ParamKind::Scalar {
            get: |m| uniform("density", m.bodies.iter().map(|b| b.density)),
            set: set_density,
            derivative: |m, g| g.density(m).iter().sum(),
        },
    },
    initial_velocity::<0>("initial_velocity.x", "x component of every vertex's initial velocity"),
    initial_velocity::<1>("initial_velocity.y", "y component of every vertex's initial velocity"),
    initial_velocity::<2>("initial_velocity.z", "z component of every vertex's initial velocity"),
    gravity::<0>(
        "gravity.x",
        "x component of gravity, on the bodies and cloth with gravity",
    ),
    gravity::<1>(
        "gravity.y",
        "y component of gravity, on the bodies and cloth with gravity",
    ),
    gravity::<2>(
        "gravity.z",
        "z component of gravity, on the bodies and cloth with gravity",
    ),
    ParamSpec {
        name: "initial_positions",
        shape: "(n, 3)",
        units: "m",
        description: "positions of every vertex before the first step",
        kind: ParamKind::Array(ArrayParam::InitialPositions),
    },
    ParamSpec {
        name: "initial_velocities",
        shape: "(n, 3)",
        units: "m/s",
        description: "velocities of every vertex before the first step",
        kind: ParamKind::Array(ArrayParam::InitialVelocities),
    },
    ParamSpec {
        name: "youngs_modulus_per_tet",
        shape: "(tets,)",
        units: "Pa",
        description: "Young's modulus of every tet",
        kind: ParamKind::Array(ArrayParam::YoungsModulusPerTet),
    },
    ParamSpec {
        name: "attachment_targets",
        shape: "(attachments, 3)",
        units: "m",
        description: "target of every attachment",
        kind: ParamKind::Array(ArrayParam::AttachmentTargets),
    },
    ParamSpec {
        name: "activations",
        shape: "(steps, groups)",
        units: "1",
        description: "activation of every actuator group at every step",
        kind: ParamKind::Array(ArrayParam::Activations),
    },
    ParamSpec {
        name: "torques",
        shape: "(steps, dofs)",
        units: "N m or N",
        description: "torque on every joint coordinate at every step, one-DoF joints only",
        kind: ParamKind::Array(ArrayParam::Torques),
    },
    ParamSpec {
        name: "initial_joint_state",
        shape: "(dofs,)",
        units: "rad or m",
        description: "initial joint coordinates, a gradient only",
        kind: ParamKind::Array(ArrayParam::InitialJointState),
    },
];

/// The entry of `initial_velocity.<axis>`, axis `K`.
const fn initial_velocity<const K: usize>(name: &'static str, description: &'static str) -> ParamSpec {
    ParamSpec {
        name,
        shape: SCALAR,
        units: "m/s",
        description,
        kind: ParamKind::Scalar {
            get: |m| uniform(AXES[K].0, m.initial_velocity.iter().map(|v| v[K])),
            set: |m, v| {
                m.initial_velocity.iter_mut().for_each(|x| x[K] = v);
                Ok(())
            },
            derivative: |_, g| g.v0.iter().map(|v| v[K]).sum(),
        },
    }
}

/// The entry of `gravity.<axis>`, axis `K`: the external acceleration of the bodies and cloth
/// with gravity.
const fn gravity<const K: usize>(name: &'static str, description: &'static str) -> ParamSpec {
    ParamSpec {
        name,
        shape: SCALAR,
        units: "m/s^2",
        description,
        kind: ParamKind::Scalar {
            get: |m| uniform(AXES[K].1, with_gravity(m).map(|i| m.accel[i][K])),
            set: |m, v| {
                let vertices: Vec<usize> = with_gravity(m).collect();
                for i in vertices {
                    m.accel[i][K] = v;
                }
                Ok(())
            },
            derivative: |m, g| with_gravity(m).map(|i| g.accel[i][K]).sum(),
        },
    }
}

/// The names of the per-axis scalars: `(initial_velocity.<axis>, gravity.<axis>)`.
const AXES: [(&str, &str); 3] = [
    ("initial_velocity.x", "gravity.x"),
    ("initial_velocity.y", "gravity.y"),
    ("initial_velocity.z", "gravity.z"),
];

/// The entry named `name`.
///
/// ```
/// use diffsoft::diff::params::{self, Param};
///
/// let e = params::lookup("youngs_modulus").unwrap();
/// assert_eq!(e.units, "Pa");
/// assert!(Param::of(e).is_some());
/// assert!(params::lookup("youngs_modulus_per_tet").is_some_and(|a| Param::of(a).is_none()));
/// assert!(params::lookup("stiffness").is_none());
/// ```
pub fn lookup(name: &str) -> Option<&'static ParamSpec> {
    PARAMETERS.iter().find(|p| p.name == name)
}

/// The scalar parameters, in registry order.
pub fn scalars() -> impl Iterator<Item = &'static ParamSpec> {
    PARAMETERS.iter().filter(|p| p.is_scalar())
}

/// The array parameters, in registry order.
pub fn arrays() -> impl Iterator<Item = &'static ParamSpec> {
    PARAMETERS.iter().filter(|p| !p.is_scalar())
}

/// The names of the scalar parameters (`diffsoft grad --param`), in registry order.
pub fn scalar_names() -> Vec<&'static str> {
    scalars().map(|p| p.name).collect()
}

/// The inputs of `model` (its scalar parameters, time step `dt`, initial velocities,
/// attachments, torque and activation schedules) whose values sit at the edge of floating point
/// (magnitude above 1e100 or below 1e-100 but not zero), as `name = value`, the first of each
/// kind: the likely cause when a run turns non-finite, for its error message.
///
/// ```
/// use diffsoft::diff::params::extreme_inputs;
/// use diffsoft::testing::ground_box;
///
/// let model = ground_box(0.5)?;
/// assert!(extreme_inputs(&model, 0.01).is_empty());
/// assert_eq!(extreme_inputs(&model, 1e-300), vec!["time_step = 1e-300".to_string()]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn extreme_inputs(model: &Model, dt: f64) -> Vec<String> {
    fn extreme(v: f64) -> bool {
        v != 0.0 && !(1e-100..=1e100).contains(&v.abs())
    }
    let mut out: Vec<String> = scalars()
        .filter_map(Param::of)
        .filter_map(|p| {
            p.get(model)
                .ok()
                .filter(|v| extreme(*v))
                .map(|v| format!("{p} = {v:e}"))
        })
        .collect();
    if extreme(dt) {
        out.push(format!("time_step = {dt:e}"));
    }
    // Per-vertex, per-attachment and scheduled inputs: the first extreme value of each kind
    // (a cloth thrown at 1e300 m/s, a torque of 1e308 N m), named by its element.
    fn first<K>(mut values: impl Iterator<Item = (K, f64)>) -> Option<(K, f64)> {
        values.find(|(_, v)| extreme(*v))
    }
    let components = |v: &Vector3<f64>| [v.x, v.y, v.z];
    let velocities = model.initial_velocity().iter().enumerate();
    if let Some((i, v)) = first(velocities.flat_map(|(i, v)| components(v).map(|c| (i, c)))) {
        out.push(format!("initial velocity of vertex {i} = {v:e}"));
    }
    let attachments = model.attachments().iter().enumerate();
    if let Some((k, v)) = first(attachments.clone().map(|(k, a)| (k, a.weight))) {
        out.push(format!("stiffness of attachment {k} = {v:e}"));
    }
    if let Some((k, v)) = first(attachments.flat_map(|(k, a)| components(&a.target).map(|c| (k, c)))) {
        out.push(format!("target of attachment {k} = {v:e}"));
    }
    if let Some(skeleton) = model.skeleton() {
        let torques = skeleton
            .bones
            .iter()
            .filter_map(|b| Some((b, b.torque.as_ref()?)))
            .flat_map(|(b, t)| t.values.iter().map(move |&v| (&b.name, v)));
        if let Some((name, v)) = first(torques) {
            out.push(format!("torque of bone '{name}' = {v:e}"));
        }
    }
    if let Some(actuators) = model.actuators() {
        let groups = actuators.groups.iter();
        let activations = groups
            .clone()
            .flat_map(|g| g.activation.values.iter().map(move |&v| (&g.name, v)));
        if let Some((name, v)) = first(activations) {
            out.push(format!("activation of actuator '{name}' = {v:e}"));
        }
        if let Some((name, v)) = first(groups.map(|g| (&g.name, g.stiffness))) {
            out.push(format!("stiffness of actuator '{name}' = {v:e}"));
        }
    }
    out
}

/// `message`, followed by the inputs that [`extreme_inputs`] finds, if any.
pub fn name_extreme_inputs(message: String, model: &Model, dt: f64) -> String {
    let found = extreme_inputs(model, dt);
    if found.is_empty() {
        message
    } else {
        format!("{message} (inputs at the edge of floating point: {})", found.join(", "))
    }
}

/// The names of the array parameters, in registry order.
pub fn array_names() -> Vec<&'static str> {
    arrays().map(|p| p.name).collect()
}

impl ParamSpec {
    /// Whether it is a scalar.
    pub fn is_scalar(&self) -> bool {
        matches!(self.kind, ParamKind::Scalar { .. })
    }

    /// Which array it is (`None` for a scalar).
    pub fn array(&self) -> Option<ArrayParam> {
        match self.kind {
            ParamKind::Array(a) => Some(a),
            ParamKind::Scalar { .. } => None,
        }
    }

    /// The description with the unit: `Young's modulus of every body (Pa)`.
    pub fn summary(&self) -> String {
        format!("{} ({})", self.description, self.units)
    }
}

/// A scalar parameter: a handle to its entry in [`PARAMETERS`], parsed from its name
/// (`"gravity.y".parse::<Param>()`) or one of the constants.
#[derive(Clone, Copy)]
pub struct Param(&'static ParamSpec);

impl Param {
    /// `youngs_modulus`.
    pub const YOUNGS_MODULUS: Param = Param::named("youngs_modulus");
    /// `poisson_ratio`.
    pub const POISSON_RATIO: Param = Param::named("poisson_ratio");
    /// `density`.
    pub const DENSITY: Param = Param::named("density");
    /// `initial_velocity.x`.
    pub const INITIAL_VELOCITY_X: Param = Param::named("initial_velocity.x");
    /// `initial_velocity.y`.
    pub const INITIAL_VELOCITY_Y: Param = Param::named("initial_velocity.y");
    /// `initial_velocity.z`.
    pub const INITIAL_VELOCITY_Z: Param = Param::named("initial_velocity.z");
    /// `gravity.x`.
    pub const GRAVITY_X: Param = Param::named("gravity.x");
    /// `gravity.y`.
    pub const GRAVITY_Y: Param = Param::named("gravity.y");
    /// `gravity.z`.
    pub const GRAVITY_Z: Param = Param::named("gravity.z");

    /// The scalar named `name` (at compile time: a constant naming no scalar does not build).
    const fn named(name: &str) -> Param {
        let mut i = 0;
        while i < PARAMETERS.len() {
            let p = &PARAMETERS[i];
            if const_eq(p.name, name) && matches!(p.kind, ParamKind::Scalar { .. }) {
                return Param(p);
            }
            i += 1;
        }
        panic!("no scalar parameter of that name in PARAMETERS");
    }

    /// The scalar of an entry (`None` for an array).
    pub fn of(spec: &'static ParamSpec) -> Option<Param> {
        spec.is_scalar().then_some(Param(spec))
    }

    /// Its entry in the registry.
    pub fn spec(&self) -> &'static ParamSpec {
        self.0
    }

    /// Its name.
    pub fn name(&self) -> &'static str {
        self.0.name
    }

    /// The axis of an `initial_velocity.<axis>` parameter: it sets that component of every
    /// vertex's initial velocity, wherever a caller keeps them (`None` for the others).
    pub fn initial_velocity_axis(&self) -> Option<usize> {
        AXES.iter().position(|a| a.0 == self.name())
    }

    fn access(&self) -> (Getter, Setter, Derivative) {
        match self.0.kind {
            ParamKind::Scalar { get, set, derivative } => (get, set, derivative),
            ParamKind::Array(_) => unreachable!("a Param is made only from a scalar entry"),
        }
    }

    /// The parameter's value in `model` (an error if bodies disagree).
    pub fn get(&self, model: &Model) -> Result<f64, DiffError> {
        (self.access().0)(model)
    }

    /// Set the parameter in `model` (every body), updating what depends on it; an error if it
    /// applies to nothing there ([`Param::check_applies`]).
    pub fn set(&self, model: &mut Model, value: f64) -> Result<(), DiffError> {
        if !value.is_finite() {
            return Err(DiffError::Input(format!(
                "{self}: value must be finite, got {}",
                crate::base::number(value)
            )));
        }
        self.check_applies(model)?;
        (self.access().1)(model, value)
    }

    /// An error when the parameter applies to nothing in `model` (a material parameter of a
    /// scene with cloth alone, gravity where nothing has gravity): setting it would change
    /// nothing, and its derivative would be a zero that no input produced.
    ///
    /// ```
    /// use diffsoft::diff::params::Param;
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
    /// let mut body = BodySpec::new("box", mesh, material, MassSpec::Density(1000.0));
    /// body.gravity = false;
    /// let model = ModelBuilder::new().body(body).build()?;
    /// let density: Param = "density".parse()?;
    /// assert!(density.check_applies(&model).is_ok());
    /// let gravity: Param = "gravity.y".parse()?;
    /// let err = gravity.check_applies(&model).unwrap_err().to_string();
    /// assert!(err.contains("nothing that 'gravity.y' applies to"), "{err}");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn check_applies(&self, model: &Model) -> Result<(), DiffError> {
        match self.get(model) {
            Err(e @ DiffError::NothingApplies { .. }) => Err(e),
            _ => Ok(()),
        }
    }

    /// `dL/d(parameter)` from a gradient of `model`.
    pub fn derivative(&self, model: &Model, g: &Gradient) -> f64 {
        (self.access().2)(model, g)
    }
}

const fn const_eq(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

impl PartialEq for Param {
    fn eq(&self, other: &Self) -> bool {
        self.name() == other.name()
    }
}

impl Eq for Param {}

impl fmt::Debug for Param {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Param({})", self.name())
    }
}

impl fmt::Display for Param {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Param {
    type Err = DiffError;
    fn from_str(s: &str) -> Result<Self, DiffError> {
        lookup(s).and_then(Param::of).ok_or_else(|| {
            DiffError::Input(format!(
                "unknown parameter '{s}' (known: {})",
                scalar_names().join(", ")
            ))
        })
    }
}

/// The scalar parameters in words, one per line: `name (units): description`.
pub fn scalar_help() -> String {
    scalars()
        .map(|p| format!("{} ({}): {}", p.name, p.units, p.description))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The JSON Schema of a map from scalar parameter names to numbers (the `parameters` and
/// `gradient` of `diffsoft grad --json`): any subset of the scalars of [`PARAMETERS`].
pub fn values_schema(generator: &mut schemars::SchemaGenerator) -> schemars::Schema {
    let mut schema = <std::collections::BTreeMap<String, f64> as schemars::JsonSchema>::json_schema(generator);
    schema.insert("propertyNames".into(), serde_json::json!({ "enum": scalar_names() }));
    schema
}

/// The description of the `parameters` of `diffsoft grad --json`, with each scalar's unit.
pub fn values_description() -> String {
    let units: Vec<String> = scalars().map(|p| format!("`{}` ({})", p.name, p.units)).collect();
    format!(
        "Value of each differentiated parameter, by name, in its unit: {}; parameters without a single value are left out.",
        units.join(", ")
    )
}

fn uniform(name: &str, values: impl Iterator<Item = f64>) -> Result<f64, DiffError> {
    let mut first = None;
    for v in values {
        match first {
            None => first = Some(v),
            Some(f) if f != v => {
                return Err(DiffError::Input(format!(
                    "'{name}' differs between bodies or vertices ({f} and {v}); set one value for all (the CLI's --set {name}=VALUE, Python's Scene.set)"
                )))
            }
            _ => {}
        }
    }
    first.ok_or_else(|| DiffError::NothingApplies { param: name.into() })
}

/// Which Young's moduli the tets have after a change of material.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Moduli {
    /// The body's scalar (setting `youngs_modulus`: the scalar takes over from per-tet values).
    Scalar,
    /// Each tet keeps its own (setting `poisson_ratio`: per-tet moduli stay in force).
    Kept,
}

/// The bodies' Young's modulus, when it is the one in force: an error naming the per-tet values
/// when `youngs_modulus_per_tet` set others (until `youngs_modulus` is set again).
fn youngs_modulus(model: &Model) -> Result<f64, DiffError> {
    let e = uniform("youngs_modulus", model.bodies.iter().map(|b| b.material.youngs_modulus))?;
    let per_tet = youngs_modulus_per_tet(model);
    for b in &model.bodies {
        if let Some(t) = b
            .tets
            .clone()
            .find(|&t| (per_tet[t] - b.material.youngs_modulus).abs() > 1e-9 * b.material.youngs_modulus)
        {
            return Err(DiffError::Input(format!(
                "youngs_modulus: per-tet values are in force (body '{}', tet {t}: {} Pa, the body's scalar {e} Pa); read youngs_modulus_per_tet, or set youngs_modulus to give every tet one value again",
                b.name, per_tet[t]
            )));
        }
    }
    Ok(e)
}

/// Change every body's material, updating the tets' rotation and volume weights (or, for a
/// hyperelastic body, its tets' Lame parameters) with the Young's moduli `moduli` says; every
/// body is checked before any changes.
fn set_material(
    model: &mut Model,
    change: impl Fn(&mut crate::base::Material),
    moduli: Moduli,
) -> Result<(), DiffError> {
    let per_tet = (moduli == Moduli::Kept).then(|| youngs_modulus_per_tet(model));
    let mut next = Vec::with_capacity(model.bodies.len());
    for b in &model.bodies {
        let mut m = b.material;
        change(&mut m);
        m.validate(&b.name).map_err(|e| DiffError::Input(e.to_string()))?;
        next.push(m);
    }
    for (k, m) in next.into_iter().enumerate() {
        model.bodies[k].material = m;
        let (tets, volume_constraint) = (model.bodies[k].tets.clone(), model.bodies[k].volume_constraint);
        for t in tets {
            let vol = model.fem.geometry[t].volume;
            let m = crate::base::Material {
                youngs_modulus: per_tet.as_ref().map_or(m.youngs_modulus, |e| e[t]),
                ..m
            };
            if set_hyper(model, t, m.youngs_modulus, m.poisson_ratio) {
                continue;
            }
            model.w_rot[t] = m.rotation_stiffness() * vol;
            model.w_vol[t] = if volume_constraint {
                m.volume_stiffness() * vol
            } else {
                0.0
            };
        }
    }
    Ok(())
}

fn set_density(model: &mut Model, value: f64) -> Result<(), DiffError> {
    if value <= 0.0 {
        return Err(DiffError::Input(format!(
            "density must be positive, got {}",
            crate::base::number(value)
        )));
    }
    for b in &mut model.bodies {
        let scale = value / b.density;
        for i in b.vertices.clone() {
            model.mass[i] *= scale;
        }
        b.mass *= scale;
        b.density = value;
    }
    Ok(())
}

/// The vertices of the bodies and cloth with gravity.
fn with_gravity(model: &Model) -> impl Iterator<Item = usize> + '_ {
    let cloth = model.cloth.as_ref().map_or(&[][..], |c| &c.bodies[..]);
    model
        .bodies
        .iter()
        .filter(|b| b.gravity)
        .map(|b| b.vertices.clone())
        .chain(cloth.iter().filter(|c| c.gravity).map(|c| c.vertices.clone()))
        .flatten()
}

/// Young's modulus of every tet (Pa), read back from the tets' weights (`w_rot = E V/(1+nu)`,
/// Eq. 24) or, for a hyperelastic tet, from its Lame parameters; in model order.
pub fn youngs_modulus_per_tet(model: &Model) -> Vec<f64> {
    let mut out = vec![0.0; model.tets.len()];
    for b in &model.bodies {
        let nu = b.material.poisson_ratio;
        for t in b.tets.clone() {
            out[t] = match model.hyper.as_ref().and_then(|h| h.position(t).map(|i| h.lame[i])) {
                Some(l) => l.mu * (3.0 * l.lambda + 2.0 * l.mu) / (l.lambda + l.mu),
                None => model.w_rot[t] * (1.0 + nu) / model.fem.geometry[t].volume,
            };
        }
    }
    out
}

/// Give hyperelastic tet `t` the Lame parameters of `(e, nu)` (and the matching weight in `L`);
/// `false` when `t` is not hyperelastic.
fn set_hyper(model: &mut Model, t: usize, e: f64, nu: f64) -> bool {
    let vol = model.fem.geometry[t].volume;
    let Some(h) = model.hyper.as_mut() else {
        return false;
    };
    let Some(i) = h.position(t) else {
        return false;
    };
    h.lame[i] = Lame::from_young(e, nu);
    h.weight[i] = crate::model::hyper_weight(h.lame[i], vol);
    true
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
    let bodies: Vec<_> = model
        .bodies
        .iter()
        .map(|b| (b.tets.clone(), b.material.poisson_ratio, b.volume_constraint))
        .collect();
    for (tets, nu, volume_constraint) in bodies {
        for t in tets {
            let vol = model.fem.geometry[t].volume;
            if set_hyper(model, t, values[t], nu) {
                continue;
            }
            model.w_rot[t] = values[t] * vol / (1.0 + nu);
            model.w_vol[t] = if volume_constraint {
                nu * values[t] * vol / (1.0 + nu)
            } else {
                0.0
            };
        }
    }
    Ok(())
}

/// The attachments' targets, in model order.
pub fn attachment_targets(model: &Model) -> Vec<Vector3<f64>> {
    model.attachments.iter().map(|a| a.target).collect()
}

/// Move the attachments' targets (`targets` in model order, finite).
pub fn set_attachment_targets(model: &mut Model, targets: &[Vector3<f64>]) -> Result<(), DiffError> {
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
