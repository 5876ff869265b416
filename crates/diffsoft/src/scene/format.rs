//! The diffsoft scene format (`schema: "diffsoft.scene/1"`): JSON, every key checked (unknown
//! keys are errors that name the key, line and column). A scene names only what it needs: a body
//! without pins has no `fixed`, a scene without obstacles runs no collision code. The `solver`
//! section is [`Settings`]; the time step is its `dt`, or the top-level `time_step`, the older
//! spelling every scene file written so far uses.
//!
//! ```json
//! {
//!   "schema": "diffsoft.scene/1",
//!   "gravity": [0, -9.81, 0],
//!   "bodies": [{
//!     "name": "beam", "mesh": "beam.msh",
//!     "material": { "youngs_modulus": 1e6, "poisson_ratio": 0.3 },
//!     "density": 1000,
//!     "fixed": { "box": { "min": [-1, -1, -1], "max": [0.001, 1, 1] } }
//!   }],
//!   "obstacles": [{ "plane": { "point": [0, -1, 0], "normal": [0, 1, 0] }, "friction": 0.5 }],
//!   "solver": { "dt": 0.005, "solver": "auto", "certify": "fallback", "max_iterations": 30 }
//! }
//! ```

use std::path::PathBuf;

use serde::Deserialize;

use crate::solver::Settings;

/// Schema name of the scene format.
pub const SCENE_SCHEMA: &str = "diffsoft.scene/1";

/// A scene file.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Must be [`SCENE_SCHEMA`].
    pub schema: String,
    /// What the scene is for, in words (not read by the solver).
    #[serde(default)]
    pub description: Option<String>,
    /// Time step (s): the older spelling of `solver.dt`, which every scene file written so far
    /// uses. Give one of the two.
    #[serde(default)]
    pub time_step: Option<f64>,
    /// Gravitational acceleration (m/s^2).
    #[serde(default)]
    pub gravity: [f64; 3],
    /// Bodies.
    #[serde(default)]
    pub bodies: Vec<BodyFile>,
    /// Cloth bodies (triangle meshes).
    #[serde(default)]
    pub cloths: Vec<ClothFile>,
    /// Collisions between bodies (soft and cloth): `{ "thickness": m, "friction": mu }`.
    #[serde(default)]
    pub collisions: Option<crate::contact::pair::BodyCollision>,
    /// Static obstacles.
    #[serde(default)]
    pub obstacles: Vec<ObstacleFile>,
    /// Solver settings, every key optional (the defaults listed); the time step is `dt` here or
    /// the top-level `time_step`.
    #[serde(default)]
    pub solver: Settings,
}

impl SceneFile {
    /// The solver settings with the time step, from `solver.dt` or the top-level `time_step`
    /// (`solver_gives_dt`: whether the `solver` section has a `dt` key); an error unless
    /// exactly one of them is given, or when a setting is out of its range (naming it).
    pub fn settings(&self, solver_gives_dt: bool) -> Result<Settings, String> {
        let s = self.settings_as_given(solver_gives_dt)?;
        // Checked here, so that the error names the scene file and its `solver` block.
        s.validate()
            .map_err(|e| format!("solver: {}", e.to_string().trim_start_matches("invalid input: ")))?;
        Ok(s)
    }

    fn settings_as_given(&self, solver_gives_dt: bool) -> Result<Settings, String> {
        match (self.time_step, solver_gives_dt) {
            (Some(dt), false) => Ok(Settings {
                dt,
                ..self.solver.clone()
            }),
            (None, true) => Ok(self.solver.clone()),
            (Some(_), true) => Err(
                "the time step is given twice, as `solver.dt` and as `time_step` (its older spelling): give one".into(),
            ),
            (None, false) => Err("no time step: give `solver.dt` (or the top-level `time_step`)".into()),
        }
    }
}

/// One soft body.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BodyFile {
    /// Name.
    pub name: String,
    /// Tet mesh: a file (relative to the scene file) or inline arrays
    /// `{ "vertices": [[x, y, z], ...], "tets": [[i, j, k, l], ...] }` (0-based).
    pub mesh: TetMeshSource,
    /// Scale applied to the mesh about the origin (1).
    #[serde(default = "one")]
    pub scale: f64,
    /// Translation applied after scaling (m).
    #[serde(default)]
    pub translate: [f64; 3],
    /// Rotation applied after scaling, before translating: axis-angle vector (rad).
    #[serde(default)]
    pub rotate: [f64; 3],
    /// Material.
    pub material: MaterialFile,
    /// Density (kg/m^3); give this or `total_mass`.
    #[serde(default)]
    pub density: Option<f64>,
    /// Total mass (kg), lumped by volume.
    #[serde(default)]
    pub total_mass: Option<f64>,
    /// Whether gravity acts on the body.
    #[serde(default = "yes")]
    pub gravity: bool,
    /// Initial velocity (m/s).
    #[serde(default)]
    pub initial_velocity: [f64; 3],
    /// Constraints beyond the corotated one.
    #[serde(default)]
    pub constraints: ConstraintsFile,
    /// Vertices held at their rest position (Dirichlet).
    #[serde(default)]
    pub fixed: Option<VertexSelector>,
    /// Penalty attachments to the rest position.
    #[serde(default)]
    pub attachments: Vec<AttachmentFile>,
    /// An embedded skeleton.
    #[serde(default)]
    pub skeleton: Option<SkeletonFile>,
    /// Actuator groups (pneumatic cells, muscle fibres).
    #[serde(default)]
    pub actuators: Vec<ActuatorFile>,
}

/// One cloth body: a triangle mesh (OBJ `v`/`f` lines) with 2D as-rigid-as-possible stretching,
/// cotangent-Laplacian bending and an area density (see [`crate::cloth`]).
///
/// ```json
/// { "name": "sheet", "mesh": "sheet.obj", "stretching": 200, "bending": 5e-4,
///   "area_density": 3, "attachments": [{ "vertices": { "indices": [0, 8] }, "stiffness": 1e5 }] }
/// ```
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ClothFile {
    /// Name.
    pub name: String,
    /// Triangle mesh: an OBJ file (relative to the scene file) or inline arrays
    /// `{ "vertices": [[x, y, z], ...], "triangles": [[i, j, k], ...] }` (0-based).
    pub mesh: SurfaceSource,
    /// Scale applied to the mesh about the origin (1).
    #[serde(default = "one")]
    pub scale: f64,
    /// Translation applied after scaling (m).
    #[serde(default)]
    pub translate: [f64; 3],
    /// Rotation applied after scaling, before translating: axis-angle vector (rad).
    #[serde(default)]
    pub rotate: [f64; 3],
    /// In-plane stretching stiffness (N/m).
    pub stretching: f64,
    /// Bending stiffness (N m; 0 for none).
    #[serde(default)]
    pub bending: f64,
    /// Area density (kg/m^2).
    pub area_density: f64,
    /// Whether gravity acts on the cloth.
    #[serde(default = "yes")]
    pub gravity: bool,
    /// Initial velocity (m/s).
    #[serde(default)]
    pub initial_velocity: [f64; 3],
    /// Vertices held at their rest position (Dirichlet), OBJ order (0-based).
    #[serde(default)]
    pub fixed: Option<VertexSelector>,
    /// Penalty attachments to the rest position.
    #[serde(default)]
    pub attachments: Vec<AttachmentFile>,
}

/// One actuator group: exactly one of `pneumatic` and `muscle`.
///
/// ```json
/// { "name": "top", "pneumatic": { "tets": { "box": { "min": [0, 0.05, 0], "max": [1, 0.1, 0.1] } } },
///   "stiffness": 1e5, "activation": { "times": [0, 1], "values": [1, 1.5] } }
/// { "name": "arm", "muscle": { "polyline": [[0, 0, 0], [0, -1, 0]], "radius": 0.1 },
///   "stiffness": 5e5, "activation": 0.3 }
/// ```
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ActuatorFile {
    /// Name (activations are set by name).
    pub name: String,
    /// Pneumatic cells (Eqs. 39-40): activation = target volume ratio, `> 0`.
    #[serde(default)]
    pub pneumatic: Option<PneumaticFile>,
    /// Muscle fibres: activation in `[0, 1]` pulls fibres to length `1 - a`.
    #[serde(default)]
    pub muscle: Option<MuscleFile>,
    /// Stiffness `k` (Pa): weight per unit rest volume.
    pub stiffness: f64,
    /// Activation: a constant or a piecewise-linear time series.
    pub activation: ActivationFile,
}

/// Tets of a pneumatic group.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PneumaticFile {
    /// Which tets.
    pub tets: TetSelector,
}

/// Fibres of a muscle group: `tets` with a uniform `direction`, or a `polyline` with a
/// `radius` (tets whose centroid is within `radius` of it, each along its nearest segment).
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MuscleFile {
    /// Which tets (with `direction`).
    #[serde(default)]
    pub tets: Option<TetSelector>,
    /// Uniform fibre direction (scene coordinates; 1, normalised by the reader).
    #[serde(default)]
    pub direction: Option<[f64; 3]>,
    /// Fibre polyline (scene coordinates).
    #[serde(default)]
    pub polyline: Option<Vec<[f64; 3]>>,
    /// Capture radius around the polyline (m).
    #[serde(default)]
    pub radius: Option<f64>,
}

/// Selects tets of a body's mesh.
#[derive(Debug, Clone, schemars::JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum TetSelector {
    /// Every tet.
    All {},
    /// Tets by index in the mesh file's tet order (0-based).
    Indices(Vec<usize>),
    /// Tets whose centroid lies in an axis-aligned box (scene coordinates).
    Box {
        /// Lower corner.
        min: [f64; 3],
        /// Upper corner.
        max: [f64; 3],
    },
    /// Tets with at least `min_shared` vertices among the given mesh-file vertex ids.
    Vertices {
        /// Vertex ids of the mesh file.
        indices: Vec<usize>,
        /// How many of a tet's vertices must be listed (1-4).
        min_shared: usize,
    },
}

/// An activation: a constant or `{ "times": [...], "values": [...] }`.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum ActivationFile {
    /// The same value at all times.
    Constant(f64),
    /// Piecewise linear in time.
    Series(TorqueFile),
}

/// Bones embedded in a body.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SkeletonFile {
    /// Bones (parents may come in any order; names must be unique).
    pub bones: Vec<BoneFile>,
}

/// One bone.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BoneFile {
    /// Name (referred to by children).
    pub name: String,
    /// Parent bone's name (none for a root).
    #[serde(default)]
    pub parent: Option<String>,
    /// The joint to the parent (or the world).
    pub joint: JointFile,
    /// Rigidly attached vertices.
    #[serde(default)]
    pub vertices: Option<VertexSelector>,
    /// Torque on a 1-DoF joint: piecewise-linear in time.
    #[serde(default)]
    pub torque: Option<TorqueFile>,
}

/// Joint types; positions and axes in scene coordinates (after the body's scale, rotation and
/// translation).
#[derive(Debug, Clone, schemars::JsonSchema)]
#[serde(deny_unknown_fields, rename_all = "snake_case")]
pub enum JointFile {
    /// 6-DoF free joint (a root).
    Free {},
    /// Welded to the parent (or the world).
    Fixed {},
    /// Rotation about an axis through a point.
    Rotational {
        /// Joint position.
        position: [f64; 3],
        /// Rotation axis.
        axis: [f64; 3],
        /// Initial angle (rad).
        #[serde(default)]
        angle: f64,
        /// Angle limits (rad).
        #[serde(default)]
        limits: Option<[f64; 2]>,
    },
    /// Translation along an axis.
    Prismatic {
        /// Axis.
        axis: [f64; 3],
        /// Initial extension (m).
        #[serde(default)]
        extension: f64,
        /// Extension limits (m).
        #[serde(default)]
        limits: Option<[f64; 2]>,
    },
}

/// A piecewise-linear time series.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TorqueFile {
    /// Sample times (s), increasing.
    pub times: Vec<f64>,
    /// Values (N m for rotational joints, N for prismatic ones).
    pub values: Vec<f64>,
}

/// Material: its model and parameters. The paper's `projective` model (the default) responds at
/// small strain as `E_eff = E/(1 + 2nu/3)`, `nu_eff = nu/(3 + 2nu)`; `corotated` and
/// `neo_hookean` respond exactly as `(E, nu)` and run with `solver: newton` (docs/method.md
/// section 2.4).
#[derive(Debug, Clone, Copy, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MaterialFile {
    /// The constitutive model: `projective` (default), `corotated` or `neo_hookean`.
    #[serde(default)]
    pub model: crate::base::MaterialModel,
    /// Young's modulus (Pa).
    pub youngs_modulus: f64,
    /// Poisson ratio (1).
    pub poisson_ratio: f64,
}

/// Which constraints a body uses (the corotated one always).
#[derive(Debug, Clone, Copy, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ConstraintsFile {
    /// The volume constraint with weight `nu E/(1+nu) V`.
    #[serde(default = "yes")]
    pub volume: bool,
}

impl Default for ConstraintsFile {
    fn default() -> Self {
        Self { volume: true }
    }
}

/// A set of vertices: explicit indices (the mesh file's numbering) or those inside a box (in
/// scene coordinates, after scale/rotate/translate).
#[derive(Debug, Clone, schemars::JsonSchema)]
#[serde(deny_unknown_fields, rename_all = "snake_case")]
pub enum VertexSelector {
    /// Vertex ids as in the mesh file.
    Indices(Vec<usize>),
    /// Vertices inside an axis-aligned box.
    Box {
        /// Minimum corner.
        min: [f64; 3],
        /// Maximum corner.
        max: [f64; 3],
    },
}

/// Penalty attachments.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AttachmentFile {
    /// Attached vertices.
    pub vertices: VertexSelector,
    /// Spring weight (N/m).
    pub stiffness: f64,
}

/// A static obstacle.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ObstacleFile {
    /// Name.
    #[serde(default)]
    pub name: Option<String>,
    /// A plane (half-space).
    #[serde(default)]
    pub plane: Option<PlaneFile>,
    /// A triangle mesh (OBJ `v`/`f`).
    #[serde(default)]
    pub mesh: Option<ObstacleMeshFile>,
    /// Coulomb friction coefficient (1).
    pub friction: f64,
    /// Collision thickness (m).
    #[serde(default)]
    pub thickness: f64,
}

/// A plane through `point` with outward `normal`.
#[derive(Debug, Clone, Copy, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PlaneFile {
    /// A point on the plane (m).
    pub point: [f64; 3],
    /// Normal pointing to the free side (1, normalised by the reader).
    pub normal: [f64; 3],
}

/// A triangle-mesh obstacle.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ObstacleMeshFile {
    /// An OBJ file (relative to the scene file) or inline arrays
    /// `{ "vertices": [[x, y, z], ...], "triangles": [[i, j, k], ...] }` (0-based).
    pub file: SurfaceSource,
    /// Scale about the origin (1).
    #[serde(default = "one")]
    pub scale: f64,
}

/// A body's tet mesh: a file path or inline arrays.
#[derive(Debug, Clone, PartialEq, schemars::JsonSchema)]
#[serde(untagged)]
pub enum TetMeshSource {
    /// A mesh file (`.obj` with `t` lines, TetGen `.node`/`.ele`, Gmsh `.msh`), relative to the
    /// scene file.
    File(PathBuf),
    /// Vertices and tets.
    Arrays(TetArrays),
}

/// A tet mesh as arrays.
#[derive(Debug, Clone, PartialEq, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TetArrays {
    /// Vertex positions (mesh coordinates, before `scale`, `rotate`, `translate`).
    pub vertices: Vec<[f64; 3]>,
    /// Tets as 0-based vertex indices (either orientation; vertices no tet uses are dropped).
    pub tets: Vec<[usize; 4]>,
}

/// A triangle surface (cloth, obstacle): an OBJ file path or inline arrays.
#[derive(Debug, Clone, PartialEq, schemars::JsonSchema)]
#[serde(untagged)]
pub enum SurfaceSource {
    /// An OBJ file (`v`/`f` lines), relative to the scene file.
    File(PathBuf),
    /// Vertices and triangles.
    Arrays(TriArrays),
}

/// A triangle surface as arrays.
#[derive(Debug, Clone, PartialEq, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TriArrays {
    /// Vertex positions.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as 0-based vertex indices.
    pub triangles: Vec<[usize; 3]>,
}

/// A path string or an object of arrays; anything else is an error that says what is expected
/// (serde's untagged enums only say that nothing matched).
fn path_or_arrays<'de, D, T>(d: D, what: &str) -> Result<Result<PathBuf, T>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: serde::de::DeserializeOwned,
{
    use serde::de::Error;
    match serde_json::Value::deserialize(d)? {
        serde_json::Value::String(s) => Ok(Ok(PathBuf::from(s))),
        v @ serde_json::Value::Object(_) => super::json::typed_from_value(v)
            .map(Err)
            .map_err(|e| D::Error::custom(format!("inline mesh: {e}"))),
        other => Err(D::Error::custom(format!(
            "a mesh is a file path or {what}, got {}",
            match other {
                serde_json::Value::Null => "null",
                serde_json::Value::Bool(_) => "a bool",
                serde_json::Value::Number(_) => "a number",
                _ => "an array",
            }
        ))),
    }
}

impl<'de> Deserialize<'de> for TetMeshSource {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Ok(
            match path_or_arrays::<D, TetArrays>(d, r#"{"vertices": [[x, y, z], ...], "tets": [[i, j, k, l], ...]}"#)? {
                Ok(p) => TetMeshSource::File(p),
                Err(a) => TetMeshSource::Arrays(a),
            },
        )
    }
}

impl<'de> Deserialize<'de> for SurfaceSource {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Ok(
            match path_or_arrays::<D, TriArrays>(d, r#"{"vertices": [[x, y, z], ...], "triangles": [[i, j, k], ...]}"#)?
            {
                Ok(p) => SurfaceSource::File(p),
                Err(a) => SurfaceSource::Arrays(a),
            },
        )
    }
}

fn one() -> f64 {
    1.0
}

fn yes() -> bool {
    true
}
