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

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use serde_json::Value;

mod actuators;

use super::{LoadOptions, Scene, SceneError, SceneFormat};
use crate::base::Material;
use crate::contact::{Obstacle, TriMeshObstacle};
use crate::mesh;
use crate::model::{BodySpec, MassSpec, ModelBuilder};
use crate::solver::Settings;
use actuators::{paper_muscles, paper_pneumatic};

/// Attach stiffness at or above which attachments become Dirichlet vertices.
pub const DIRICHLET_STIFFNESS: f64 = 1e12;

const TOP_KEYS: &[&str] = &["Parameters", "Friction coefficients", "Meshes", "Obstacles", "Clothes"];
const PARAM_USED: &[&str] = &[
    "Self-collision",
    "Simulation HZ",
    "Gravity",
    "Is underwater",
    "Handle collision",
    "Max Iteration",
    "Damping coefficient",
];
const PARAM_IGNORED: &[(&str, &str)] = &[
    (
        "Self-collision tolerance",
        "not read by the reference implementation (its arcsim contact thickness is 1e-4); contacts between bodies keep 1e-3 m apart (CLOTH_THICKNESS)",
    ),
    ("Air damping", "air drag is not simulated"),
    ("Frame number", "not read by the reference implementation"),
    ("LocalGlobal", "not read by the reference implementation"),
    ("Signal", "not read by the reference implementation"),
    ("Type", "not read by the reference implementation"),
    ("Steps per frame", "not read by the reference implementation"),
    ("GravityY", "not read by the reference implementation (use \"Gravity\")"),
    (
        "World Alpha",
        "contact relaxation of the reference's self-collision loop",
    ),
    ("World Friction", "friction of the reference's self-collision loop"),
    (
        "Is skeleton actuated",
        "selects the reference's action interface (joint torques come from a controller)",
    ),
];
const MESH_USED: &[&str] = &[
    "Obj filename",
    "Scale",
    "Mass",
    "Youngs Modulus",
    "Poisson Ratio",
    "Attach Verts",
    "Attach Stiffness",
    "Enable Gravity",
    "Is Mass Same",
    "Bones",
    "Volume Verts",
    "Muscle filename",
    "Muscle Stiffness",
];
const MESH_IGNORED: &[(&str, &str)] = &[
    (
        "Friction coefficients",
        "the reference implementation ignores per-mesh friction",
    ),
    ("Actuator type", "selects the reference's action interface"),
    ("Center Index", "used by the reference's controllers only"),
    ("End Effector Index", "used by the reference's controllers only"),
    ("Local Contour Index", "used by the reference's controllers only"),
    ("Type", "always \"Soft Articulated\""),
    ("Material Identifier", "not used by the solver"),
    ("Attach y", "not read by the reference implementation"),
    (
        "Sampling filename",
        "vertex samples for the reference's controller observations (the file is not in its data either)",
    ),
];
const MESH_UNSUPPORTED: &[(&str, &str)] = &[];
/// The largest "Max Iteration" a paper scene may give (local-global iterations per step).
const MAX_ITERATION_CAP: f64 = 1e9;
const OBSTACLE_KEYS: &[&str] = &["Obj filename", "Scale", "Collision tolerance"];
const CLOTH_USED: &[&str] = &[
    "Obj filename",
    "Scale",
    "Area Density",
    "Bending",
    "Stretching",
    "Attach Stiffness",
    "Attach Verts",
];
const CLOTH_IGNORED: &[(&str, &str)] = &[
    (
        "Friction coefficients",
        "per-body friction; contacts between bodies use the top-level \"Friction coefficients\"",
    ),
    ("Material Identifier", "not used by the solver"),
];

/// Distance kept between the surfaces of two bodies in the paper's scenes (m): a cloth's
/// thickness. The reference's own contact thickness is arcsim's 1e-4 m; its scene files'
/// "Self-collision tolerance" (5e-2) is not read.
pub const CLOTH_THICKNESS: f64 = 1e-3;

struct Ctx<'a> {
    path: &'a Path,
    notes: Vec<String>,
    passive: bool,
    /// Where each file name the scene gives was found when it was first read, for a scene
    /// rebuilt from the files it carried (a pickled scene): names resolve only through it.
    carried: Option<&'a HashMap<String, PathBuf>>,
}

impl Ctx<'_> {
    fn shown(&self) -> String {
        self.path.display().to_string()
    }
    fn invalid(&self, message: String) -> SceneError {
        SceneError::Invalid {
            path: self.shown(),
            message,
        }
    }
    fn unsupported(&mut self, what: &str, feature: &str) -> Result<(), SceneError> {
        if self.passive {
            self.notes
                .push(format!("{what}: {feature} not simulated yet; ignored (--passive)"));
            Ok(())
        } else {
            Err(SceneError::Unsupported {
                path: self.shown(),
                message: format!(
                    "{what} ({feature}) cannot be simulated yet; run with --passive to simulate the bodies without it"
                ),
            })
        }
    }
    fn check_keys(
        &mut self,
        where_: &str,
        obj: &Value,
        used: &[&str],
        ignored: &[(&str, &str)],
        unsupported: &[(&str, &str)],
    ) -> Result<(), SceneError> {
        let map = obj
            .as_object()
            .ok_or_else(|| self.invalid(format!("{where_} must be a JSON object")))?;
        for (k, v) in map {
            if used.contains(&k.as_str()) {
                continue;
            }
            if let Some((_, why)) = ignored.iter().find(|(name, _)| name == k) {
                self.notes.push(format!("{where_}: \"{k}\" ignored ({why})"));
            } else if let Some((_, feature)) = unsupported.iter().find(|(name, _)| name == k) {
                let empty = v.as_array().is_some_and(|a| a.is_empty());
                if !empty {
                    self.unsupported(&format!("{where_}: \"{k}\""), feature)?;
                }
            } else {
                return Err(self.invalid(format!("{where_}: unknown key \"{k}\"")));
            }
        }
        Ok(())
    }
    fn number(&self, obj: &Value, key: &str, default: f64, where_: &str) -> Result<f64, SceneError> {
        match obj.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_f64()
                .ok_or_else(|| self.invalid(format!("{where_}: \"{key}\" must be a number, got {v}"))),
        }
    }
    /// A boolean under `key` (`default` where absent); any other JSON type is an error (a
    /// string such as `"yes"` must not read as false).
    fn flag(&self, obj: &Value, key: &str, default: bool, where_: &str) -> Result<bool, SceneError> {
        match obj.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_bool()
                .ok_or_else(|| self.invalid(format!("{where_}: \"{key}\" must be true or false, got {}", excerpt(v)))),
        }
    }
    /// A list of vertex indices under `key`.
    fn indices(&self, v: &Value, where_: &str, key: &str) -> Result<Vec<usize>, SceneError> {
        v.as_array()
            .and_then(|a| {
                a.iter()
                    .map(|x| x.as_u64().map(|u| u as usize))
                    .collect::<Option<Vec<_>>>()
            })
            .ok_or_else(|| self.invalid(format!("{where_}: \"{key}\" must be a list of vertex indices")))
    }
    /// A file the scene names: through the carried files of a rebuilt scene, else as
    /// [`find_file`] looks for it.
    fn resolve(&self, file: &str) -> Result<PathBuf, SceneError> {
        if let Some(carried) = self.carried {
            return carried.get(file).cloned().ok_or_else(|| {
                self.invalid(format!(
                    "cannot find \"{file}\": this scene was rebuilt from the files it named when it was first read, and this name was not one of them"
                ))
            });
        }
        let candidates = file_candidates(self.path, file);
        candidates.iter().find(|p| p.is_file()).cloned().ok_or_else(|| {
            let looked: Vec<String> = candidates.iter().map(|p| p.display().to_string()).collect();
            self.invalid(format!("cannot find \"{file}\" (looked in {})", looked.join(", ")))
        })
    }
}

/// Where a paper scene at `scene` looks for a file it names `file`, in order: relative to the
/// paper's data root (the scene's parent directory), to the scene's own directory, and by its
/// name beside the scene; from any working directory (the scene path is made absolute first).
fn file_candidates(scene: &Path, file: &str) -> Vec<PathBuf> {
    let scene = std::path::absolute(scene).unwrap_or_else(|_| scene.to_path_buf());
    let dir = scene.parent().unwrap_or(Path::new("."));
    let mut candidates = vec![dir.parent().unwrap_or(dir).join(file), dir.join(file)];
    if let Some(name) = Path::new(file).file_name() {
        candidates.push(dir.join(name));
    }
    candidates.dedup();
    candidates
}

/// The file a paper scene at `scene` means by `file`, where one exists ([`import`]'s search).
///
/// ```
/// use std::path::Path;
/// use diffsoft::scene::paper;
///
/// let scene = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../verification/paper/bridgesus/bridgesus.json"));
/// assert!(paper::find_file(scene, "bridgesus/bridgesus200_tet_cen.obj").is_some_and(|p| p.is_file()));
/// assert!(paper::find_file(scene, "no such mesh.obj").is_none());
/// ```
pub fn find_file(scene: &Path, file: &str) -> Option<PathBuf> {
    if file.is_empty() {
        return None;
    }
    file_candidates(scene, file).into_iter().find(|p| p.is_file())
}

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
    import_with(path, value, opts, None)
}

/// Import a paper scene rebuilt from the files it named when it was first read: `carried` maps
/// each name as the scene gives it to where that file now is, and no other file is looked for
/// (a scene unpickled elsewhere must not pick up whatever lies at its names there).
pub fn import_carried(
    path: &Path,
    value: &Value,
    opts: LoadOptions,
    carried: &HashMap<String, PathBuf>,
) -> Result<Scene, SceneError> {
    import_with(path, value, opts, Some(carried))
}

fn import_with(
    path: &Path,
    value: &Value,
    opts: LoadOptions,
    carried: Option<&HashMap<String, PathBuf>>,
) -> Result<Scene, SceneError> {
    let mut cx = Ctx {
        path,
        notes: Vec::new(),
        passive: opts.passive,
        carried,
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
    let params = match value.get("Parameters") {
        None => {
            cx.notes.push(
                "no \"Parameters\": the reference's defaults applied (200 Hz, no gravity, collisions off)".into(),
            );
            &empty
        }
        Some(Value::Array(a)) if a.len() == 1 => &a[0],
        Some(p) => {
            return Err(cx.invalid(format!(
                "\"Parameters\" must be a list of exactly one object, got {}",
                excerpt(p)
            )))
        }
    };
    cx.check_keys("Parameters[0]", params, PARAM_USED, PARAM_IGNORED, &[])?;
    let hz = cx.number(params, "Simulation HZ", 200.0, "Parameters[0]")?;
    if !(hz.is_finite() && hz > 0.0) {
        return Err(cx.invalid(format!(
            "\"Simulation HZ\" must be positive, got {}",
            crate::base::number(hz)
        )));
    }
    let underwater = cx.number(params, "Is underwater", 0.0, "Parameters[0]")? != 0.0;
    let gravity = match params.get("Gravity") {
        None => Vector3::zeros(),
        Some(g) => {
            let a = g
                .as_array()
                .filter(|a| a.len() == 3)
                .ok_or_else(|| cx.invalid(format!("\"Gravity\" must be [x, y, z], got {g}")))?;
            let c: Vec<f64> = a.iter().filter_map(|x| x.as_f64()).collect();
            if c.len() != 3 {
                return Err(cx.invalid(format!("\"Gravity\" must hold three numbers, got {g}")));
            }
            Vector3::new(c[0], c[1], c[2])
        }
    };
    if underwater {
        cx.notes
            .push("\"Is underwater\": water drag is not simulated; gravity is off as in the reference".into());
    }
    let collisions = cx.flag(params, "Handle collision", false, "Parameters[0]")?;
    let (friction, friction_source) = paper_friction(&mut cx, value.get("Friction coefficients"))?;
    let mut builder = ModelBuilder::new().gravity(if underwater { Vector3::zeros() } else { gravity });
    let meshes_json = value
        .get("Meshes")
        .and_then(|m| m.as_array())
        .ok_or_else(|| cx.invalid("\"Meshes\" must be a list".into()))?;
    let mut meshes = Vec::new();
    let mut body_names: Vec<String> = Vec::new();
    let mut actuator_names: Vec<String> = Vec::new();
    for (k, mj) in meshes_json.iter().enumerate() {
        let w = format!("Meshes[{k}]");
        cx.check_keys(&w, mj, MESH_USED, MESH_IGNORED, MESH_UNSUPPORTED)?;
        let file = mj
            .get("Obj filename")
            .and_then(|f| f.as_str())
            .ok_or_else(|| cx.invalid(format!("{w}: \"Obj filename\" is required")))?;
        let loaded = mesh::load(cx.resolve(file)?)?;
        let scale = cx.number(mj, "Scale", 0.05, &w)?;
        if !(scale.is_finite() && scale > 0.0) {
            return Err(cx.invalid(format!(
                "{w}: \"Scale\" must be positive, got {}",
                crate::base::number(scale)
            )));
        }
        if mj.get("Scale").is_none() {
            cx.notes
                .push(format!("{w}: no \"Scale\": the reference's default 0.05 applied"));
        }
        if !cx.flag(mj, "Is Mass Same", true, &w)? {
            return Err(cx.invalid(format!(
                "{w}: \"Is Mass Same\": false (uniform vertex masses) is not supported"
            )));
        }
        let total = cx.number(mj, "Mass", 10.0, &w)?;
        if !(total.is_finite() && total > 0.0) {
            return Err(cx.invalid(format!(
                "{w}: \"Mass\" (the body's total mass, kg) must be finite and positive, got {}",
                crate::base::number(total)
            )));
        }
        let material = Material {
            youngs_modulus: cx.number(mj, "Youngs Modulus", 2e5, &w)?,
            poisson_ratio: cx.number(mj, "Poisson Ratio", 0.4, &w)?,
        };
        super::scaled_size(&w, scale, &loaded.mesh.vertices).map_err(|m| cx.invalid(m))?;
        let m = loaded.mesh.scaled(scale);
        let stem = Path::new(file)
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("body")
            .to_string();
        // Bodies are named by their files' stems; two meshes with one stem (`box.obj` and
        // `sub/box.obj`, or one file twice) are told apart by their place in "Meshes".
        let name = if body_names.contains(&stem) {
            let name = format!("{stem}_{k}");
            cx.notes.push(format!(
                "{w}: body named '{name}' (the name '{stem}' of its file is taken by an earlier mesh)"
            ));
            name
        } else {
            stem
        };
        body_names.push(name.clone());
        let mut spec = BodySpec::new(&name, m, material, MassSpec::Total(total));
        spec.gravity = cx.number(mj, "Enable Gravity", 1.0, &w)? != 0.0;
        if let Some(av) = mj.get("Attach Verts") {
            let ids = cx.indices(av, &w, "Attach Verts")?;
            let stiffness = mj
                .get("Attach Stiffness")
                .and_then(|s| s.as_f64())
                .ok_or_else(|| cx.invalid(format!("{w}: \"Attach Verts\" needs \"Attach Stiffness\"")))?;
            let verts = super::select(
                &cx.shown(),
                &name,
                &super::format::VertexSelector::Indices(ids),
                &loaded.mesh,
                &loaded.info,
            )?;
            if stiffness >= DIRICHLET_STIFFNESS {
                cx.notes.push(format!(
                    "{w}: {} attached vertices with stiffness {stiffness:e} >= {DIRICHLET_STIFFNESS:e} imposed exactly (Dirichlet)",
                    verts.len()
                ));
                spec.fixed = verts;
            } else {
                spec.attachments = verts.into_iter().map(|v| (v, stiffness)).collect();
            }
        } else if let Some(k) = mj.get("Attach Stiffness") {
            cx.notes.push(format!(
                "{w}: \"Attach Stiffness\" {k} without \"Attach Verts\" attaches nothing; ignored"
            ));
        }
        if let Some(bones) = mj.get("Bones") {
            let (list, notes) = paper_bones(&cx, &w, bones, &loaded.mesh, &loaded.info)?;
            spec.bones = list;
            cx.notes.extend(notes);
            if !spec.bones.is_empty() {
                cx.notes.push(format!(
                    "{w}: {} bones; joint positions are used as given (the reference does not scale them)",
                    spec.bones.len()
                ));
            }
        }
        let stiffness = cx.number(mj, "Muscle Stiffness", 5e5, &w)?;
        if let Some(groups) = mj.get("Volume Verts") {
            spec.actuators = paper_pneumatic(&mut cx, &w, groups, &spec.mesh, &loaded.info, stiffness)?;
        }
        if let Some(file) = mj.get("Muscle filename") {
            let file = file
                .as_str()
                .ok_or_else(|| cx.invalid(format!("{w}: \"Muscle filename\" must be a file name")))?;
            let muscle_path = cx.resolve(file)?;
            let muscles = paper_muscles(&mut cx, &w, &muscle_path, &spec.mesh, scale, stiffness)?;
            spec.actuators.extend(muscles);
        }
        // Actuator names are the scene's: a later mesh's group whose name an earlier mesh took
        // is prefixed with its body's name.
        for a in &mut spec.actuators {
            if actuator_names.contains(&a.name) {
                let renamed = format!("{name}_{}", a.name);
                cx.notes.push(format!(
                    "{w}: actuator '{}' named '{renamed}' (an earlier mesh has an actuator '{}')",
                    a.name, a.name
                ));
                a.name = renamed;
            }
            actuator_names.push(a.name.clone());
        }
        builder = builder.body(spec);
        meshes.push(loaded.info);
    }
    let mut bodies = meshes_json.len();
    if let Some(cloths) = value.get("Clothes") {
        let list = cloths
            .as_array()
            .ok_or_else(|| cx.invalid("\"Clothes\" must be a list".into()))?;
        for (k, cj) in list.iter().enumerate() {
            builder = builder.cloth(paper_cloth(&mut cx, k, cj)?);
            bodies += 1;
        }
    }
    let self_collision = cx.flag(params, "Self-collision", false, "Parameters[0]")?;
    if collisions && self_collision && bodies >= 2 {
        cx.notes.push(format!(
            "\"Self-collision\": the bodies collide with each other (vertex-face and edge-edge pairs, thickness {CLOTH_THICKNESS} m, friction {friction} {friction_source}; the reference hard-codes 1 and its thickness is 1e-4 m); self-collision within a body is not simulated"
        ));
        builder = builder.collisions(crate::contact::pair::BodyCollision {
            thickness: CLOTH_THICKNESS,
            friction,
        });
    } else if self_collision {
        cx.notes
            .push("\"Self-collision\": self-collision within a body is not simulated".into());
    }
    if let Some(obs) = value.get("Obstacles") {
        let obs = obs
            .as_array()
            .ok_or_else(|| cx.invalid(format!("\"Obstacles\" must be a list, got {}", excerpt(obs))))?;
        for (k, oj) in obs.iter().enumerate() {
            let w = format!("Obstacles[{k}]");
            cx.check_keys(&w, oj, OBSTACLE_KEYS, &[], &[])?;
            if !collisions {
                cx.notes.push(format!(
                    "{w}: \"Handle collision\" is off: obstacle ignored, as in the reference"
                ));
                continue;
            }
            let file = oj
                .get("Obj filename")
                .and_then(|f| f.as_str())
                .ok_or_else(|| cx.invalid(format!("{w}: \"Obj filename\" is required")))?;
            let s = mesh::surface::load_obj(cx.resolve(file)?)?;
            cx.notes.push(format!(
                "{w}: triangle mesh {file} at scale 1 and thickness 1e-4 as in the reference (its \"Scale\" and \"Collision tolerance\" are not read there); friction {friction} {friction_source} (the reference hard-codes 1)"
            ));
            let shape = TriMeshObstacle::new(s.vertices, s.triangles).map_err(|e| cx.invalid(format!("{w}: {e}")))?;
            builder = builder.obstacle(Obstacle::new(file, shape, friction, 1e-4));
        }
    }
    let model = builder.build().map_err(|source| SceneError::Model {
        path: cx.shown(),
        source,
    })?;
    // Reference stop rule |dq|_2 / (3N) < 5e-7 as a relative RMS change: |dq|_2 / sqrt(N) / L.
    let n = model.n() as f64;
    let tolerance = 5e-7 * 3.0 * n / n.sqrt() / model.length_scale;
    let max_iterations = cx.number(params, "Max Iteration", 30.0, "Parameters[0]")?;
    if !(max_iterations.fract() == 0.0 && (1.0..=MAX_ITERATION_CAP).contains(&max_iterations)) {
        return Err(cx.invalid(format!(
            "Parameters[0]: \"Max Iteration\" must be a whole number from 1 to {MAX_ITERATION_CAP:e}, got {}",
            crate::base::number(max_iterations)
        )));
    }
    let damping = cx.number(params, "Damping coefficient", 0.9999, "Parameters[0]")?;
    if !(damping > 0.0 && damping <= 1.0) {
        return Err(cx.invalid(format!(
            "Parameters[0]: \"Damping coefficient\" (velocity kept per step) must be in (0, 1], got {}",
            crate::base::number(damping)
        )));
    }
    let settings = Settings {
        dt: 1.0 / hz,
        max_iterations: max_iterations as usize,
        damping,
        tolerance,
        ..Settings::default()
    };
    cx.notes.push(format!(
        "stopping rule of the reference (|dq|_2 / 3N < 5e-7) as relative RMS tolerance {tolerance:.3e}; damping {}; at most {} iterations",
        settings.damping, settings.max_iterations
    ));
    Ok(Scene {
        path: path.to_path_buf(),
        format: SceneFormat::Paper,
        model,
        settings,
        meshes,
        notes: cx.notes,
    })
}

/// One entry of the paper's "Clothes": a triangle mesh (OBJ `f` lines) with "Area Density",
/// "Stretching", "Bending" and attachments. The parameters are used as the paper describes its
/// cloth; where the reference implementation differs, a note says how.
fn paper_cloth(cx: &mut Ctx<'_>, k: usize, cj: &Value) -> Result<crate::cloth::ClothSpec, SceneError> {
    let w = format!("Clothes[{k}]");
    cx.check_keys(&w, cj, CLOTH_USED, CLOTH_IGNORED, &[])?;
    let file = cj
        .get("Obj filename")
        .and_then(|f| f.as_str())
        .ok_or_else(|| cx.invalid(format!("{w}: \"Obj filename\" is required")))?;
    let path = cx.resolve(file)?;
    let scale = cx.number(cj, "Scale", 1.0, &w)?;
    if !(scale.is_finite() && scale > 0.0) {
        return Err(cx.invalid(format!(
            "{w}: \"Scale\" must be positive, got {}",
            crate::base::number(scale)
        )));
    }
    if cj.get("Scale").is_none() {
        cx.notes.push(format!(
            "{w}: no \"Scale\": scale 1 (the reference's default for cloth is 0.05, which would shrink {file} to a twentieth of the scene it is modelled in)"
        ));
    }
    let surface = mesh::surface::load_obj(&path)?;
    super::scaled_size(&w, scale, &surface.vertices).map_err(|m| cx.invalid(m))?;
    let surface = surface.scaled(scale);
    let area_density = cx.number(cj, "Area Density", 1.5, &w)?;
    let stretching = cx.number(cj, "Stretching", 200.0, &w)?;
    let bending = cx.number(cj, "Bending", 0.0, &w)?;
    cx.notes.push(format!(
        "{w}: cloth {file}: {} vertices, {} triangles; area density {area_density} kg/m^2, in-plane stretching {stretching} N/m (2D as-rigid-as-possible per triangle), bending {bending} N m (cotangent Laplacian); gravity on. The reference instead uses edge springs of weight sqrt(200), no bending, 1.5 kg/m^2 and no gravity on cloth",
        surface.vertices.len(),
        surface.triangles.len()
    ));
    let name = Path::new(file)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("cloth")
        .to_string();
    let mut spec = crate::cloth::ClothSpec::new(&name, surface, stretching, bending, area_density);
    spec.source = path.display().to_string();
    if let Some(av) = cj.get("Attach Verts") {
        let ids = cx.indices(av, &w, "Attach Verts")?;
        let n = spec.surface.vertices.len();
        if let Some(bad) = ids.iter().find(|&&v| v >= n) {
            return Err(cx.invalid(format!(
                "{w}: \"Attach Verts\": vertex {bad} out of range ({n} vertices in {file})"
            )));
        }
        let stiffness = cj
            .get("Attach Stiffness")
            .and_then(|s| s.as_f64())
            .ok_or_else(|| cx.invalid(format!("{w}: \"Attach Verts\" needs \"Attach Stiffness\"")))?;
        if stiffness >= DIRICHLET_STIFFNESS {
            spec.fixed = ids;
        } else {
            spec.attachments = ids.into_iter().map(|v| (v, stiffness)).collect();
        }
    } else if let Some(k) = cj.get("Attach Stiffness") {
        cx.notes.push(format!(
            "{w}: \"Attach Stiffness\" {k} without \"Attach Verts\" attaches nothing; ignored"
        ));
    }
    Ok(spec)
}

/// A JSON value as the error messages show it: its text, cut at 80 characters.
fn excerpt(v: &Value) -> String {
    let text = v.to_string();
    match text.char_indices().nth(80) {
        Some((cut, _)) => format!("{}...", &text[..cut]),
        None => text,
    }
}

/// The top-level "Friction coefficients" (`[[mu, ...], ...]`): the first entry is the friction
/// of every contact, as in the reference; a note says so where the others differ. Absent: the
/// reference's default 0.1. Returns the coefficient and where it came from (for the notes).
fn paper_friction(cx: &mut Ctx<'_>, v: Option<&Value>) -> Result<(f64, &'static str), SceneError> {
    let Some(v) = v else {
        return Ok((
            0.1,
            "(the reference's default: the scene gives no \"Friction coefficients\")",
        ));
    };
    let bad = |cx: &Ctx<'_>, what: String| {
        cx.invalid(format!(
            "\"Friction coefficients\" must be a list of lists of numbers, e.g. [[0.1]]; {what}, in {}",
            excerpt(v)
        ))
    };
    let rows = match v.as_array() {
        Some(rows) if !rows.is_empty() => rows,
        _ => return Err(bad(cx, "not a non-empty list".into())),
    };
    let mut values = Vec::new();
    for (i, row) in rows.iter().enumerate() {
        let row = match row.as_array() {
            Some(r) if !r.is_empty() => r,
            _ => return Err(bad(cx, format!("entry [{i}] is not a non-empty list"))),
        };
        for (j, x) in row.iter().enumerate() {
            let mu = x
                .as_f64()
                .ok_or_else(|| bad(cx, format!("entry [{i}][{j}] is not a number")))?;
            // Checked even where no contact reads it: a negative coefficient is a broken file.
            if !(mu.is_finite() && mu >= 0.0) {
                return Err(cx.invalid(format!(
                    "\"Friction coefficients\"[{i}][{j}] must be finite and >= 0, got {}",
                    crate::base::number(mu)
                )));
            }
            values.push(mu);
        }
    }
    let mu = values[0];
    if values.iter().any(|&x| x != mu) {
        cx.notes.push(format!(
            "\"Friction coefficients\": only the first entry ({}) is read, as in the reference; the others are ignored",
            crate::base::number(mu)
        ));
    }
    Ok((mu, "from \"Friction coefficients\""))
}

/// The paper's "Bones" list: "Parent ID" (-1 for the root), "Joint Type" ("ALL", "ROTATIONAL",
/// "PRISMATIC"), "Joint Pos", "Joint Axis", "Vertices" (file indices).
/// Also returns notes on suspicious data (joints mirrored in x against their vertices).
fn paper_bones(
    cx: &Ctx<'_>,
    w: &str,
    bones: &Value,
    mesh: &crate::mesh::TetMesh,
    info: &crate::mesh::MeshInfo,
) -> Result<(Vec<crate::skeleton::BoneSpec>, Vec<String>), SceneError> {
    use crate::skeleton::{free::Free, prismatic::Prismatic, rotational::Rotational, BoneSpec, Joint};
    let list = bones
        .as_array()
        .ok_or_else(|| cx.invalid(format!("{w}: \"Bones\" must be a list")))?;
    let vec3 = |b: &Value, key: &str, k: usize| -> Result<Vector3<f64>, SceneError> {
        let a = b.get(key).and_then(|v| v.as_array()).filter(|a| a.len() == 3);
        let c: Option<Vec<f64>> = a.and_then(|a| a.iter().map(|x| x.as_f64()).collect());
        match c {
            Some(c) if c.iter().all(|x| x.is_finite()) => Ok(Vector3::new(c[0], c[1], c[2])),
            _ => Err(cx.invalid(format!("{w}: Bones[{k}]: \"{key}\" must be three numbers"))),
        }
    };
    let mut out = Vec::new();
    let mut notes = Vec::new();
    for (k, b) in list.iter().enumerate() {
        let keys = ["Parent ID", "Joint Type", "Joint Pos", "Joint Axis", "Vertices"];
        if let Some(obj) = b.as_object() {
            if let Some(bad) = obj.keys().find(|key| !keys.contains(&key.as_str())) {
                return Err(cx.invalid(format!("{w}: Bones[{k}]: unknown key \"{bad}\"")));
            }
        }
        let parent = match b.get("Parent ID") {
            None => return Err(cx.invalid(format!("{w}: Bones[{k}]: \"Parent ID\" is required"))),
            Some(p) => p.as_i64().ok_or_else(|| {
                cx.invalid(format!(
                    "{w}: Bones[{k}]: \"Parent ID\" must be a whole number (-1 for the root), got {}",
                    excerpt(p)
                ))
            })?,
        };
        let parent = if parent == -1 {
            None
        } else if parent >= 0 && (parent as usize) < list.len() && parent as usize != k {
            Some(parent as usize)
        } else {
            return Err(cx.invalid(format!(
                "{w}: Bones[{k}]: \"Parent ID\" {parent} does not name another bone (-1 for the root)"
            )));
        };
        let ty = b.get("Joint Type").and_then(|t| t.as_str()).unwrap_or("");
        let joint: Box<dyn Joint> = match ty {
            "ALL" => Box::new(Free::default()),
            "ROTATIONAL" => {
                let axis = vec3(b, "Joint Axis", k)?;
                if crate::base::unit_vector(axis).is_none() {
                    return Err(cx.invalid(format!("{w}: Bones[{k}]: rotational joint with a zero axis")));
                }
                let p = vec3(b, "Joint Pos", k)?;
                super::joint_position_near(&format!("{w}: Bones[{k}]"), &p, &mesh.vertices)
                    .map_err(|m| cx.invalid(m))?;
                Box::new(Rotational::new(p, axis))
            }
            "PRISMATIC" => {
                let axis = vec3(b, "Joint Axis", k)?;
                if crate::base::unit_vector(axis).is_none() {
                    return Err(cx.invalid(format!("{w}: Bones[{k}]: prismatic joint with a zero axis")));
                }
                Box::new(Prismatic::new(axis))
            }
            other => {
                return Err(cx.invalid(format!(
                    "{w}: Bones[{k}]: unknown \"Joint Type\" \"{other}\" (ALL, ROTATIONAL, PRISMATIC)"
                )))
            }
        };
        let ids: Vec<usize> = b
            .get("Vertices")
            .and_then(|v| v.as_array())
            .and_then(|a| {
                a.iter()
                    .map(|x| x.as_u64().map(|u| u as usize))
                    .collect::<Option<Vec<_>>>()
            })
            .ok_or_else(|| {
                cx.invalid(format!(
                    "{w}: Bones[{k}]: \"Vertices\" must be a list of vertex indices"
                ))
            })?;
        let vertices = super::select(
            &cx.shown(),
            &format!("{w} bone {k}"),
            &super::format::VertexSelector::Indices(ids),
            mesh,
            info,
        )?;
        if ty == "ROTATIONAL" && !vertices.is_empty() {
            // A joint on the other side (in x) of the vertices it moves: the paper's Baymax has
            // this for both hips and both shoulders. Reported, used as given.
            let c = vertices.iter().map(|&v| mesh.vertices[v]).sum::<Vector3<f64>>() / vertices.len() as f64;
            let p = vec3(b, "Joint Pos", k)?;
            let mirrored = Vector3::new(-p.x, p.y, p.z);
            if p.x * c.x < 0.0 && (mirrored - c).norm() < 0.75 * (p - c).norm() {
                notes.push(format!(
                    "{w}: Bones[{k}]: joint position ({:.4}, {:.4}, {:.4}) is on the other side in x of the {} vertices it moves (centroid x = {:.3}); used as given",
                    p.x,
                    p.y,
                    p.z,
                    vertices.len(),
                    c.x
                ));
            }
        }
        out.push(BoneSpec {
            name: format!("bone{k}"),
            parent,
            joint,
            vertices,
            torque: None,
        });
    }
    Ok((out, notes))
}
