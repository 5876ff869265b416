//! Importer for the paper's scene files (`verification/paper/*/*.json`), with the reference
//! implementation's defaults (checked against its source, see the README):
//!
//! * time step `1 / "Simulation HZ"` (default 200), iteration cap `"Max Iteration"` (30), velocity
//!   damping `"Damping coefficient"` (0.9999), and its stopping rule `|dq|_2 / (3N) < 5e-7`
//!   expressed as this solver's relative RMS tolerance;
//! * per mesh: `"Scale"` (default 0.05) about the origin, `"Mass"` (default 10) lumped by
//!   volume, `"Youngs Modulus"` (2e5), `"Poisson Ratio"` (0.4), `"Enable Gravity"` (1); the file
//!   is looked up relative to the data folder (the scene's parent) and then to the scene's own
//!   folder;
//! * `"Attach Verts"` with `"Attach Stiffness"`: springs to the rest position, or Dirichlet
//!   vertices when the stiffness is at least 1e12 (the bridges' 1e20 is a Dirichlet condition
//!   imposed by penalty);
//! * `"Gravity"` `[x, y, z]` unless `"Is underwater"`; `"Obstacles"` as static triangle meshes
//!   with the top-level friction coefficient, when `"Handle collision"` is set;
//! * `"Bones"` as an embedded skeleton;
//! * `"Volume Verts"` as pneumatic groups `pneumatic0, pneumatic1, ...`: the tets with at least
//!   two listed vertices, stiffness `"Muscle Stiffness"`, activation 1 (rest) until set (the
//!   reference turns each list into a chain of edge-length actuators between consecutive
//!   vertices; diffsoft uses the paper's pneumatic cells, Eqs. 39-40, on those tets);
//! * `"Muscle filename"` (lines `muscle sample x y z`) as muscle groups `muscle0, muscle1, ...`:
//!   each tet whose centroid is within half the mean edge length of a muscle's polyline joins
//!   the nearest one, along its nearest segment; activation 0 (rest) until set.
//! * Names: a body is named by its file's stem (`box.obj`: `box`), a later mesh whose stem an
//!   earlier one took by `<stem>_<k>` (`k` its place in `"Meshes"`); an actuator whose name an
//!   earlier mesh took is prefixed with its body's name (`box_1_pneumatic0`). A note says so.
//!
//! * `"Clothes"` as cloth bodies (triangle meshes, see [`crate::cloth`]): `"Area Density"`,
//!   `"Stretching"`, `"Bending"`, `"Attach Verts"` with `"Attach Stiffness"`, scale 1 by
//!   default; with `"Handle collision"` and `"Self-collision"` the bodies collide with each
//!   other ([`crate::contact::pair`], thickness [`CLOTH_THICKNESS`]).
//!
//! Every other key is either known and ignored (listed in the scene's notes with the reason) or
//! an error naming it.
//!
//! A scene rebuilt elsewhere from the files it named when it was first read (a pickled scene)
//! is imported from their contents in memory ([`import_carried_bytes`], [`CarriedFile`]): no
//! file is looked for, read or written, and messages name each file as the caller shows it.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde_json::Value;

// The importer's parts. This module calls them and they may call one another (without
// cycles), but none uses an item of this module.

// `"Volume Verts"` and `"Muscle filename"` as actuator groups.
mod actuators;
// `"Attach Verts"` with `"Attach Stiffness"`: springs or Dirichlet vertices.
mod attach;
// One `"Meshes"` entry as a soft body.
mod body;
// `"Bones"` as an embedded skeleton.
mod bones;
// A file carried in memory: its contents and the path its messages name.
mod carried;
// One `"Clothes"` entry as a cloth body.
mod cloth;
// Friction, collisions between bodies and obstacles.
mod collision;
// The import's state (`Ctx`) and its readers of JSON values.
mod context;
// Where the files a scene names are looked for, or carried.
mod files;
// The keys of each object: read, ignored (with the reason) or unsupported.
mod keys;
// Body and actuator names told apart.
mod naming;
// The `"Parameters"` object and its gravity.
mod parameters;
// The files a scene names read from disk or from memory: meshes, surfaces, text.
mod read;
// The checked scalar keys: the solver's settings, a body's scale and mass.
mod settings;

pub use attach::DIRICHLET_STIFFNESS;
pub use carried::CarriedFile;
pub use collision::CLOTH_THICKNESS;
pub use files::{companion_file, find_file};

use super::{LoadOptions, Scene, SceneError, SceneFormat};
use crate::model::ModelBuilder;
use context::Ctx;
use files::Files;
use keys::TOP_KEYS;
use naming::Names;

/// Import a parsed paper scene.
///
/// ```
/// use std::path::Path;
/// use diffsoft::scene::paper;
///
/// let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../verification/paper/bridgesus/bridgesus.json"));
/// let value: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path)?)?;
/// let sc = paper::import(path, &value, Default::default())?;
/// assert!(sc.model.n() > 0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn import(path: &Path, value: &Value, opts: LoadOptions) -> Result<Scene, SceneError> {
    import_with(path, value, opts, Files::Search)
}

/// Import a paper scene rebuilt from the files it named when it was first read: `carried` maps
/// each name as the scene gives it to where that file now is, and no other file is looked for
/// (a scene unpickled elsewhere must not pick up whatever lies at its names there). To import
/// from the files' contents without writing them anywhere, see [`import_carried_bytes`].
pub fn import_carried(
    path: &Path,
    value: &Value,
    opts: LoadOptions,
    carried: &HashMap<String, PathBuf>,
) -> Result<Scene, SceneError> {
    import_with(path, value, opts, Files::Paths(carried))
}

/// Import a paper scene from the contents of the files it names, in memory: `carried` maps each
/// name as the scene gives it (`"Obj filename"`, `"Muscle filename"`, and the other half of a
/// TetGen pair under [`companion_file`]'s name) to its contents. Nothing is read from disk or
/// written: a name that is not carried is an error naming it, even where a file lies at that
/// name. `path` is the scene's path as messages show it (no file is read there); each file's
/// messages, notes and [`MeshInfo::path`](crate::mesh::MeshInfo::path) name it as its
/// [`CarriedFile::shown`] path, as [`import`] names the files it reads.
///
/// ```
/// use std::collections::HashMap;
/// use std::path::Path;
/// use diffsoft::scene::paper::{self, CarriedFile};
///
/// let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../verification/paper"));
/// let path = root.join("bridgesus/bridgesus.json");
/// let value: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path)?)?;
/// let name = "bridgesus/bridgesus200_tet_cen.obj";
/// let shown = root.join(name);
/// let carried = HashMap::from([(name.to_string(), CarriedFile::new(&shown, std::fs::read(&shown)?))]);
/// let from_memory = paper::import_carried_bytes(&path, &value, Default::default(), &carried)?;
/// let from_disk = paper::import(&path, &value, Default::default())?;
/// assert_eq!(from_memory.model.rest(), from_disk.model.rest());
/// assert_eq!(from_memory.notes, from_disk.notes);
///
/// // Only carried files are read: without the mesh, its name is refused.
/// let err = paper::import_carried_bytes(&path, &value, Default::default(), &HashMap::new()).unwrap_err();
/// assert!(err.to_string().contains(name));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn import_carried_bytes(
    path: &Path,
    value: &Value,
    opts: LoadOptions,
    carried: &HashMap<String, CarriedFile>,
) -> Result<Scene, SceneError> {
    import_with(path, value, opts, Files::Carried(carried))
}

/// The import: the top level's keys, `"Parameters"`, friction, the meshes, the cloths, the
/// collisions between bodies and with obstacles, then the model and the solver's settings.
fn import_with(path: &Path, value: &Value, opts: LoadOptions, files: Files<'_>) -> Result<Scene, SceneError> {
    let mut cx = Ctx {
        path,
        notes: Vec::new(),
        passive: opts.passive,
        files,
    };
    let top = value
        .as_object()
        .ok_or_else(|| cx.invalid("the scene must be a JSON object".into()))?;
    for k in top.keys() {
        if !TOP_KEYS.contains(&k.as_str()) {
            return Err(cx.invalid(format!("unknown top-level key \"{k}\"")));
        }
    }
    let empty = Value::Object(Default::default());
    let params = parameters::object(&mut cx, value)?.unwrap_or(&empty);
    let hz = settings::simulation_hz(&cx, params)?;
    let gravity = parameters::gravity(&mut cx, params)?;
    let collisions = cx.flag(params, "Handle collision", false, "Parameters[0]")?;
    let friction = collision::friction(&mut cx, value.get("Friction coefficients"))?;
    let mut builder = ModelBuilder::new().gravity(gravity);
    let meshes_json = value
        .get("Meshes")
        .and_then(|m| m.as_array())
        .ok_or_else(|| cx.invalid("\"Meshes\" must be a list".into()))?;
    let mut meshes = Vec::new();
    let mut names = Names::default();
    for (k, mj) in meshes_json.iter().enumerate() {
        let (spec, info) = body::paper_body(&mut cx, &mut names, k, mj)?;
        builder = builder.body(spec);
        meshes.push(info);
    }
    let mut bodies = meshes_json.len();
    if let Some(cloths) = value.get("Clothes") {
        let list = cloths
            .as_array()
            .ok_or_else(|| cx.invalid("\"Clothes\" must be a list".into()))?;
        for (k, cj) in list.iter().enumerate() {
            builder = builder.cloth(cloth::paper_cloth(&mut cx, k, cj)?);
            bodies += 1;
        }
    }
    if let Some(pairs) = collision::body_collisions(&mut cx, params, collisions, bodies, friction)? {
        builder = builder.collisions(pairs);
    }
    for obstacle in collision::obstacles(&mut cx, value.get("Obstacles"), collisions, friction)? {
        builder = builder.obstacle(obstacle);
    }
    let model = builder.build().map_err(|source| SceneError::Model {
        path: cx.shown(),
        source,
    })?;
    let settings = settings::solver(&mut cx, params, hz, model.n(), model.length_scale)?;
    Ok(Scene {
        path: path.to_path_buf(),
        format: SceneFormat::Paper,
        model,
        settings,
        meshes,
        notes: cx.notes,
    })
}
