//! Scenes: the JSON description of what to simulate, turned into a [`Model`] and [`Settings`].
//!
//! Two formats are read by [`load`]:
//!
//! * the diffsoft format ([`mod@format`], `schema: "diffsoft.scene/1"`), strict: unknown keys are
//!   errors;
//! * the paper's own scene files ([`paper`]: "Simulation HZ", "Meshes", "Youngs Modulus",
//!   "Attach Verts", "Obstacles", ...), with the reference implementation's defaults; every key
//!   is either used, known and ignored (reported in the scene's notes), or an error.
//!
//! A scene builds only what it names: no obstacles, no collision code.

pub mod format;
pub mod inline;
pub mod json;
pub mod paper;
mod tagged;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::{Rotation3, Vector3};
use serde::Serialize;

use crate::base::{InputError, Material};
use crate::contact::{Obstacle, Plane, Shape, TriMeshObstacle};
use crate::mesh::{self, MeshInfo, TetMesh};
use crate::model::{BodySpec, MassSpec, Model, ModelBuilder};
use crate::skeleton::BoneSpec;
use crate::solver::Settings;
use format::{SceneFile, SurfaceSource, TetMeshSource, VertexSelector, SCENE_SCHEMA};

/// Errors reading a scene; each names the scene file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SceneError {
    /// Cannot read the file.
    #[error("{path}: {message}")]
    Io {
        /// Scene path.
        path: String,
        /// What failed.
        message: String,
    },
    /// Invalid JSON or unknown / missing keys (with line and column).
    #[error("{path}: {message}")]
    Syntax {
        /// Scene path.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// A value is meaningless or refers to something missing.
    #[error("{path}: {message}")]
    Invalid {
        /// Scene path.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// The scene uses a feature this version cannot simulate.
    #[error("{path}: unsupported: {message}")]
    Unsupported {
        /// Scene path.
        path: String,
        /// What is unsupported.
        message: String,
    },
    /// A mesh referenced by the scene is invalid.
    #[error(transparent)]
    Mesh(#[from] mesh::MeshError),
    /// The assembled model is invalid.
    #[error("{path}: invalid input: {source}")]
    Model {
        /// Scene path.
        path: String,
        /// Cause.
        source: InputError,
    },
}

/// Which format a scene came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SceneFormat {
    /// `diffsoft.scene/1`.
    Diffsoft,
    /// The paper's reference implementation.
    Paper,
}

/// A scene ready to simulate.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Scene file.
    pub path: PathBuf,
    /// Format.
    pub format: SceneFormat,
    /// The assembled model.
    pub model: Model,
    /// Solver settings.
    pub settings: Settings,
    /// The meshes read (one per body).
    pub meshes: Vec<MeshInfo>,
    /// What the importer did with keys it does not simulate, defaults it applied, etc.
    pub notes: Vec<String>,
}

/// Options for reading scenes.
#[derive(Debug, Clone, Copy, Default)]
pub struct LoadOptions {
    /// Paper scenes: drop features this version cannot simulate with a note instead of an
    /// error (none of the paper's own files needs it).
    pub passive: bool,
}

/// A cloth of the diffsoft format: the mesh placed, vertex selections resolved (OBJ order).
fn cloth_from_file(scene: &str, dir: &Path, c: &format::ClothFile) -> Result<crate::cloth::ClothSpec, SceneError> {
    let invalid = |message: String| SceneError::Invalid {
        path: scene.to_string(),
        message,
    };
    if !(c.scale.is_finite() && c.scale > 0.0) {
        return Err(invalid(format!(
            "cloth '{}': scale must be finite and positive, got {}",
            c.name, c.scale
        )));
    }
    let (s, source) = surface_of(scene, dir, &c.mesh, &format!("cloth '{}' mesh", c.name))?;
    let (rot, t) = placement(
        scene,
        &format!("cloth '{}'", c.name),
        c.scale,
        &c.rotate,
        &c.translate,
        &s.vertices,
    )?;
    let surface = mesh::surface::TriSurface {
        vertices: s.vertices.iter().map(|v| rot * (v * c.scale) + t).collect(),
        triangles: s.triangles,
    };
    let pick = |sel: &VertexSelector| -> Result<Vec<usize>, SceneError> {
        let n = surface.vertices.len();
        match sel {
            VertexSelector::Indices(ids) => {
                if let Some(bad) = ids.iter().find(|&&i| i >= n) {
                    return Err(invalid(format!(
                        "cloth '{}': vertex {bad} out of range ({n} vertices in {source})",
                        c.name
                    )));
                }
                Ok(ids.clone())
            }
            VertexSelector::Box { min, max } => {
                let (lo, hi) = (finite3(scene, "box min", min)?, finite3(scene, "box max", max)?);
                let v: Vec<usize> = (0..n)
                    .filter(|&i| {
                        let p = surface.vertices[i];
                        (0..3).all(|k| p[k] >= lo[k] && p[k] <= hi[k])
                    })
                    .collect();
                if v.is_empty() {
                    return Err(invalid(format!("cloth '{}': the box selects no vertex", c.name)));
                }
                Ok(v)
            }
        }
    };
    let fixed = match &c.fixed {
        Some(sel) => pick(sel)?,
        None => Vec::new(),
    };
    let mut attachments = Vec::new();
    for a in &c.attachments {
        attachments.extend(pick(&a.vertices)?.into_iter().map(|v| (v, a.stiffness)));
    }
    let mut spec = crate::cloth::ClothSpec::new(&c.name, surface, c.stretching, c.bending, c.area_density);
    spec.source = source;
    spec.gravity = c.gravity;
    spec.initial_velocity = finite3(scene, "initial_velocity", &c.initial_velocity)?;
    spec.fixed = fixed;
    spec.attachments = attachments;
    Ok(spec)
}

/// A triangle surface of the diffsoft format and where it came from (`what` names an inline
/// one in messages).
fn surface_of(
    scene: &str,
    dir: &Path,
    src: &SurfaceSource,
    what: &str,
) -> Result<(mesh::surface::TriSurface, String), SceneError> {
    match src {
        SurfaceSource::File(f) => {
            let path = dir.join(f);
            Ok((mesh::surface::load_obj(&path)?, path.display().to_string()))
        }
        SurfaceSource::Arrays(a) => {
            let name = format!("{scene}: {what}");
            Ok((inline::surface(&name, a)?, name))
        }
    }
}

/// Build a scene of the diffsoft format from its JSON document, as [`load`] does from a file:
/// `path` names the scene in messages and its directory is where relative mesh paths resolve
/// (a document whose meshes are all inline needs no file). Meshes may be inline arrays (see
/// [`format::TetMeshSource`]).
///
/// ```
/// use diffsoft::scene;
///
/// let doc = serde_json::json!({
///     "schema": "diffsoft.scene/1", "time_step": 0.01, "gravity": [0, -9.81, 0],
///     "bodies": [{ "name": "tet", "density": 1000,
///         "material": { "youngs_modulus": 1e5, "poisson_ratio": 0.3 },
///         "mesh": { "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], "tets": [[0, 2, 1, 3]] } }]
/// });
/// let sc = scene::from_value(doc, std::path::Path::new("<dict>"))?;
/// assert_eq!((sc.model.n(), sc.model.tets().len()), (4, 1));
/// let bad = serde_json::json!({ "schema": "diffsoft.scene/1", "time_step": 0.01, "bodies": [{ "name": "b",
///     "density": 1, "material": { "youngs_modulus": 1, "poisson_ratio": 0.3 }, "mesh": 3 }] });
/// let err = scene::from_value(bad, std::path::Path::new("<dict>")).unwrap_err().to_string();
/// assert!(err.contains("a mesh is a file path or"), "{err}");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn from_value(value: serde_json::Value, path: &Path) -> Result<Scene, SceneError> {
    let shown = path.display().to_string();
    let solver_gives_dt = value.pointer("/solver/dt").is_some();
    let file: SceneFile =
        json::typed_from_value(value).map_err(|message| SceneError::Syntax { path: shown, message })?;
    from_diffsoft(path, file, solver_gives_dt)
}

/// Read a scene file of either format.
///
/// ```
/// use diffsoft::{scene, Simulator};
///
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../verification/paper/bridgesus/bridgesus.json");
/// let sc = scene::load(path, Default::default())?;
/// assert_eq!(sc.settings.dt, 0.005);
/// let mut sim = Simulator::new(sc.model, sc.settings)?;
/// assert!(sim.step()?.iterations >= 1);
/// assert!(scene::load("no/such/scene.json", Default::default()).is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn load(path: impl AsRef<Path>, opts: LoadOptions) -> Result<Scene, SceneError> {
    let path = path.as_ref();
    let shown = path.display().to_string();
    let text = crate::base::input_file::read_text(path).map_err(|e| SceneError::Io {
        path: shown.clone(),
        message: e.to_string(),
    })?;
    let value: serde_json::Value = json::parse_lenient(&text).map_err(|e| SceneError::Syntax {
        path: shown.clone(),
        message: e.to_string(),
    })?;
    let is_diffsoft = value
        .get("schema")
        .and_then(|s| s.as_str())
        .is_some_and(|s| s.starts_with("diffsoft.scene"));
    if is_diffsoft {
        // Strict: parse the text itself so errors carry line and column.
        let file: SceneFile = json::typed_from_str(&text).map_err(|message| SceneError::Syntax {
            path: shown.clone(),
            message,
        })?;
        let solver_gives_dt = value.pointer("/solver/dt").is_some();
        from_diffsoft(path, file, solver_gives_dt)
    } else if value.get("Meshes").is_some() || value.get("Parameters").is_some() {
        paper::import(path, &value, opts)
    } else {
        Err(SceneError::Syntax {
            path: shown,
            message: format!("not a scene: expected \"schema\": \"{SCENE_SCHEMA}\" or a paper scene with \"Meshes\""),
        })
    }
}

/// Resolve vertex ids of the mesh file to mesh vertices.
fn select(
    scene: &str,
    body: &str,
    sel: &VertexSelector,
    mesh: &TetMesh,
    info: &MeshInfo,
) -> Result<Vec<usize>, SceneError> {
    match sel {
        VertexSelector::Indices(ids) => {
            let map: HashMap<i64, usize> = info.file_ids.iter().enumerate().map(|(i, &id)| (id, i)).collect();
            ids.iter()
                .map(|&id| {
                    map.get(&(id as i64)).copied().ok_or_else(|| SceneError::Invalid {
                        path: scene.to_string(),
                        message: format!("body '{body}': vertex {id} is not a vertex of any tet of {}", info.path),
                    })
                })
                .collect()
        }
        VertexSelector::Box { min, max } => {
            let v: Vec<usize> = (0..mesh.num_vertices())
                .filter(|&i| (0..3).all(|k| mesh.vertices[i][k] >= min[k] && mesh.vertices[i][k] <= max[k]))
                .collect();
            if v.is_empty() {
                return Err(SceneError::Invalid {
                    path: scene.to_string(),
                    message: format!("body '{body}': the box {min:?}..{max:?} contains no vertex"),
                });
            }
            Ok(v)
        }
    }
}

/// Bones of a body from the diffsoft format.
fn bones_from_file(
    scene: &str,
    body: &str,
    sk: &format::SkeletonFile,
    mesh: &TetMesh,
    info: &MeshInfo,
) -> Result<Vec<BoneSpec>, SceneError> {
    use crate::base::Schedule;
    use crate::skeleton::{fixed::Fixed, free::Free, prismatic::Prismatic, rotational::Rotational, Joint};
    use format::JointFile;
    let invalid = |message: String| SceneError::Invalid {
        path: scene.to_string(),
        message: format!("body '{body}': {message}"),
    };
    let names: Vec<&str> = sk.bones.iter().map(|b| b.name.as_str()).collect();
    let mut out = Vec::new();
    for (i, b) in sk.bones.iter().enumerate() {
        if names[..i].contains(&b.name.as_str()) {
            return Err(invalid(format!("two bones are named '{}'", b.name)));
        }
        let parent = match &b.parent {
            None => None,
            Some(p) => Some(
                names
                    .iter()
                    .position(|n| n == p)
                    .ok_or_else(|| invalid(format!("bone '{}': no parent bone named '{p}'", b.name)))?,
            ),
        };
        let limits = |l: &Option<[f64; 2]>| -> Result<Option<(f64, f64)>, SceneError> {
            match l {
                Some([lo, hi]) if lo.is_finite() && hi.is_finite() && lo <= hi => Ok(Some((*lo, *hi))),
                Some(l) => Err(invalid(format!(
                    "bone '{}': limits must be finite with min <= max, got {l:?}",
                    b.name
                ))),
                None => Ok(None),
            }
        };
        // The initial coordinate: finite, representable to the solver's precision (beyond 1e6
        // its float spacing exceeds 1e-10), and inside the joint's limits when it has them
        // (a joint that starts outside them would be snapped in by the first step).
        let initial = |what: &str, unit: &str, v: f64, l: Option<(f64, f64)>| -> Result<f64, SceneError> {
            if !(v.is_finite() && v.abs() <= 1e6) {
                return Err(invalid(format!(
                    "bone '{}': initial {what} {} {unit} is not a finite value within +-1e6",
                    b.name,
                    crate::base::number(v)
                )));
            }
            match l {
                Some((lo, hi)) if !(lo..=hi).contains(&v) => Err(invalid(format!(
                    "bone '{}': initial {what} {} {unit} is outside its limits [{}, {}]",
                    b.name,
                    crate::base::number(v),
                    crate::base::number(lo),
                    crate::base::number(hi)
                ))),
                _ => Ok(v),
            }
        };
        let joint: Box<dyn Joint> = match &b.joint {
            JointFile::Free {} => Box::new(Free::default()),
            JointFile::Fixed {} => Box::new(Fixed),
            JointFile::Rotational {
                position,
                axis,
                angle,
                limits: l,
            } => {
                let a = finite3(scene, "joint axis", axis)?;
                if crate::base::unit_vector(a).is_none() {
                    return Err(invalid(format!("bone '{}': joint axis must be non-zero", b.name)));
                }
                let p = finite3(scene, "joint position", position)?;
                joint_position_near(&format!("bone '{}'", b.name), &p, &mesh.vertices).map_err(&invalid)?;
                let mut r = Rotational::new(p, a);
                r.limits = limits(l)?;
                r.set_coordinates(&[initial("angle", "rad", *angle, r.limits)?]);
                Box::new(r)
            }
            JointFile::Prismatic {
                axis,
                extension,
                limits: l,
            } => {
                let a = finite3(scene, "joint axis", axis)?;
                if crate::base::unit_vector(a).is_none() {
                    return Err(invalid(format!("bone '{}': joint axis must be non-zero", b.name)));
                }
                let mut p = Prismatic::new(a);
                p.limits = limits(l)?;
                p.set_coordinates(&[initial("extension", "m", *extension, p.limits)?]);
                Box::new(p)
            }
        };
        let vertices = match &b.vertices {
            Some(sel) => select(scene, body, sel, mesh, info)?,
            None => Vec::new(),
        };
        out.push(BoneSpec {
            name: b.name.clone(),
            parent,
            joint,
            vertices,
            torque: b.torque.as_ref().map(|t| Schedule {
                times: t.times.clone(),
                values: t.values.clone(),
            }),
        });
    }
    Ok(out)
}

/// Tets of a body selected by a [`format::TetSelector`].
fn select_tets(
    scene: &str,
    what: &str,
    sel: &format::TetSelector,
    mesh: &TetMesh,
    info: &MeshInfo,
) -> Result<Vec<usize>, SceneError> {
    use format::TetSelector;
    let invalid = |message: String| SceneError::Invalid {
        path: scene.to_string(),
        message: format!("{what}: {message}"),
    };
    let tets = match sel {
        TetSelector::All {} => (0..mesh.num_tets()).collect(),
        TetSelector::Indices(ids) => {
            if let Some(t) = ids.iter().find(|&&t| t >= mesh.num_tets()) {
                return Err(invalid(format!("tet {t} out of range ({} tets)", mesh.num_tets())));
            }
            ids.clone()
        }
        TetSelector::Box { min, max } => (0..mesh.num_tets())
            .filter(|&t| {
                let c = crate::actuator::centroid(mesh, t);
                (0..3).all(|k| c[k] >= min[k] && c[k] <= max[k])
            })
            .collect(),
        TetSelector::Vertices { indices, min_shared } => {
            if !(1..=4).contains(min_shared) {
                return Err(invalid(format!("min_shared must be 1 to 4, got {min_shared}")));
            }
            let map: HashMap<i64, usize> = info.file_ids.iter().enumerate().map(|(i, &id)| (id, i)).collect();
            let verts = indices
                .iter()
                .map(|&id| {
                    map.get(&(id as i64))
                        .copied()
                        .ok_or_else(|| invalid(format!("vertex {id} is not a vertex of any tet of {}", info.path)))
                })
                .collect::<Result<Vec<_>, _>>()?;
            crate::actuator::tets_of_vertices(mesh, &verts, *min_shared)
        }
    };
    if tets.is_empty() {
        return Err(invalid("selects no tet".into()));
    }
    Ok(tets)
}

/// One actuator group from the diffsoft format.
fn actuator_from_file(
    scene: &str,
    body: &str,
    a: &format::ActuatorFile,
    mesh: &TetMesh,
    info: &MeshInfo,
) -> Result<crate::actuator::ActuatorSpec, SceneError> {
    use crate::actuator::{fibres_along, fibres_from_polyline, ActuatorSpec};
    use crate::base::Schedule;
    let what = format!("body '{body}', actuator '{}'", a.name);
    let invalid = |message: String| SceneError::Invalid {
        path: scene.to_string(),
        message: format!("{what}: {message}"),
    };
    let activation = match &a.activation {
        format::ActivationFile::Constant(v) => Schedule::constant(*v),
        format::ActivationFile::Series(t) => Schedule {
            times: t.times.clone(),
            values: t.values.clone(),
        },
    };
    match (&a.pneumatic, &a.muscle) {
        (Some(p), None) => {
            let tets = select_tets(scene, &what, &p.tets, mesh, info)?;
            Ok(ActuatorSpec::pneumatic(&a.name, &tets, a.stiffness, activation))
        }
        (None, Some(m)) => {
            let fibres = match (&m.tets, &m.direction, &m.polyline, m.radius) {
                (Some(sel), Some(d), None, None) => {
                    let d = finite3(scene, &format!("{what}: direction"), d)?;
                    fibres_along(&select_tets(scene, &what, sel, mesh, info)?, d)
                }
                (None, None, Some(line), Some(r)) => {
                    if !(r.is_finite() && r > 0.0) {
                        return Err(invalid(format!(
                            "radius must be finite and positive, got {}",
                            crate::base::number(r)
                        )));
                    }
                    let pts = line
                        .iter()
                        .map(|p| finite3(scene, &format!("{what}: polyline point"), p))
                        .collect::<Result<Vec<_>, _>>()?;
                    let f = fibres_from_polyline(mesh, &pts, r);
                    if f.is_empty() {
                        return Err(invalid(format!(
                            "no tet centroid lies within {r} of the polyline (or it has no segment of positive length)"
                        )));
                    }
                    f
                }
                _ => {
                    return Err(invalid(
                        "a muscle takes either `tets` and `direction`, or `polyline` and `radius`".into(),
                    ))
                }
            };
            Ok(ActuatorSpec::muscle(&a.name, fibres, a.stiffness, activation))
        }
        _ => Err(invalid("give exactly one of `pneumatic` and `muscle`".into())),
    }
}

/// The rotation and translation that place a body or cloth (`who`) whose mesh `vertices` are
/// scaled by `scale`: finite, a rotation vector of at most 1e6 rad (beyond, its float spacing
/// exceeds 1e-10 rad) and a translation of at most 1e8 times the scaled mesh's size (beyond,
/// the placed coordinates keep fewer than about 8 significant digits of the mesh's shape, and
/// its elements would degenerate). Errors name `who` and the field.
fn placement(
    scene: &str,
    who: &str,
    scale: f64,
    rotate: &[f64; 3],
    translate: &[f64; 3],
    vertices: &[Vector3<f64>],
) -> Result<(Rotation3<f64>, Vector3<f64>), SceneError> {
    let invalid = |message: String| SceneError::Invalid {
        path: scene.to_string(),
        message: format!("{who}: {message}"),
    };
    let r = finite3(scene, &format!("{who}: rotate"), rotate)?;
    if r.amax() > 1e6 {
        return Err(invalid(format!(
            "rotate component {} rad is beyond 1e6 rad (give the angle modulo 2 pi)",
            crate::base::number(r.amax())
        )));
    }
    let t = finite3(scene, &format!("{who}: translate"), translate)?;
    let size = scaled_size(who, scale, vertices).map_err(|m| SceneError::Invalid {
        path: scene.to_string(),
        message: m,
    })?;
    if size.is_finite() && size > 0.0 && t.amax() > 1e8 * size {
        return Err(invalid(format!(
            "translate {} m is beyond 1e8 times the {} m size of its mesh: the placed coordinates would lose the mesh's shape",
            crate::base::number(t.amax()),
            crate::base::number(size)
        )));
    }
    Ok((Rotation3::from_scaled_axis(r), t))
}

fn finite3(scene: &str, what: &str, v: &[f64; 3]) -> Result<Vector3<f64>, SceneError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(Vector3::from(*v))
    } else {
        Err(SceneError::Invalid {
            path: scene.to_string(),
            message: format!("{what} must be finite, got {v:?}"),
        })
    }
}

/// The corners of the bounding box of `vertices` (infinite, inverted, when there are none).
fn bounds(vertices: &[Vector3<f64>]) -> (Vector3<f64>, Vector3<f64>) {
    vertices.iter().fold(
        (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY)),
        |(lo, hi), v| (lo.inf(v), hi.sup(v)),
    )
}

/// Largest and smallest size (m) a scaled mesh may span: its element volumes (size cubed) and
/// the products of stiffness with them stay inside f64's range, with room to spare.
const MESH_SIZE_RANGE: (f64, f64) = (1e-90, 1e90);

/// The size (largest bounding-box side, m) of `vertices` scaled by `scale`, which must be
/// finite and positive and leave the mesh between [`MESH_SIZE_RANGE`]'s bounds: beyond them
/// volumes over- or underflow and the elements read as degenerate. Errors name `who`.
pub(crate) fn scaled_size(who: &str, scale: f64, vertices: &[Vector3<f64>]) -> Result<f64, String> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(format!(
            "{who}: scale must be finite and positive, got {}",
            crate::base::number(scale)
        ));
    }
    let (lo, hi) = bounds(vertices);
    let size = (hi - lo).amax() * scale;
    let (min, max) = MESH_SIZE_RANGE;
    if vertices.is_empty() || (size.is_finite() && (min..=max).contains(&size)) {
        return Ok(size);
    }
    Err(format!(
        "{who}: scale {} makes the mesh {} m across, outside {min:e} to {max:e} m, where its element sizes leave f64's range; rescale the units",
        crate::base::number(scale),
        crate::base::number(size)
    ))
}

/// A joint at `p` (m) for a body whose mesh has `vertices`: within 1e8 times the mesh's size of
/// the mesh's bounding box (the rule of a body's `translate`: further out, lever arms of that
/// length keep fewer than about 8 significant digits of the body's shape). Errors name `who`.
pub(crate) fn joint_position_near(who: &str, p: &Vector3<f64>, vertices: &[Vector3<f64>]) -> Result<(), String> {
    let (lo, hi) = bounds(vertices);
    let size = (hi - lo).amax();
    if !(size.is_finite() && size > 0.0) {
        return Ok(());
    }
    let outside = (p - hi).sup(&(lo - p)).max();
    if outside > 1e8 * size {
        return Err(format!(
            "{who}: joint position {p:?} m is {} m from the body's mesh, beyond 1e8 times its {} m size: its lever arms would lose the mesh's shape",
            crate::base::number(outside),
            crate::base::number(size)
        ));
    }
    Ok(())
}

fn from_diffsoft(path: &Path, file: SceneFile, solver_gives_dt: bool) -> Result<Scene, SceneError> {
    let scene = path.display().to_string();
    let dir = path.parent().unwrap_or(Path::new("."));
    let invalid = |message: String| SceneError::Invalid {
        path: scene.clone(),
        message,
    };
    if file.schema != SCENE_SCHEMA {
        return Err(invalid(format!(
            "schema is '{}', this version reads '{SCENE_SCHEMA}'",
            file.schema
        )));
    }
    let settings = file.settings(solver_gives_dt).map_err(&invalid)?;
    let mut builder = ModelBuilder::new().gravity(finite3(&scene, "gravity", &file.gravity)?);
    let mut meshes = Vec::new();
    for b in &file.bodies {
        let loaded = match &b.mesh {
            TetMeshSource::File(f) => mesh::load(dir.join(f))?,
            TetMeshSource::Arrays(a) => inline::tet_mesh(&format!("{scene}: body '{}' mesh", b.name), a)?,
        };
        if !(b.scale.is_finite() && b.scale > 0.0) {
            return Err(invalid(format!(
                "body '{}': scale must be finite and positive, got {}",
                b.name, b.scale
            )));
        }
        let (rot, t) = placement(
            &scene,
            &format!("body '{}'", b.name),
            b.scale,
            &b.rotate,
            &b.translate,
            &loaded.mesh.vertices,
        )?;
        let m = loaded.mesh.map_vertices(|v| rot * (v * b.scale) + t);
        let mass = match (b.density, b.total_mass) {
            (Some(d), None) => MassSpec::Density(d),
            (None, Some(m)) => MassSpec::Total(m),
            _ => {
                return Err(invalid(format!(
                    "body '{}': give exactly one of density and total_mass",
                    b.name
                )))
            }
        };
        let mut spec = BodySpec::new(
            &b.name,
            m.clone(),
            Material {
                youngs_modulus: b.material.youngs_modulus,
                poisson_ratio: b.material.poisson_ratio,
            },
            mass,
        );
        spec.model = b.material.model;
        spec.gravity = b.gravity;
        spec.initial_velocity = finite3(&scene, "initial_velocity", &b.initial_velocity)?;
        spec.volume_constraint = b.constraints.volume;
        if let Some(sel) = &b.fixed {
            spec.fixed = select(&scene, &b.name, sel, &m, &loaded.info)?;
        }
        for a in &b.attachments {
            for v in select(&scene, &b.name, &a.vertices, &m, &loaded.info)? {
                spec.attachments.push((v, a.stiffness));
            }
        }
        if let Some(sk) = &b.skeleton {
            spec.bones = bones_from_file(&scene, &b.name, sk, &m, &loaded.info)?;
        }
        for a in &b.actuators {
            spec.actuators
                .push(actuator_from_file(&scene, &b.name, a, &m, &loaded.info)?);
        }
        builder = builder.body(spec);
        meshes.push(loaded.info);
    }
    for c in &file.cloths {
        builder = builder.cloth(cloth_from_file(&scene, dir, c)?);
    }
    if let Some(c) = file.collisions {
        builder = builder.collisions(c);
    }
    for (k, o) in file.obstacles.iter().enumerate() {
        let name = o.name.clone().unwrap_or_else(|| format!("obstacle {k}"));
        let shape = match (&o.plane, &o.mesh) {
            (Some(p), None) => {
                let n = finite3(&scene, "plane normal", &p.normal)?;
                let Some(normal) = crate::base::unit_vector(n) else {
                    return Err(invalid(format!("obstacle '{name}': plane normal must be non-zero")));
                };
                let plane = Plane {
                    point: finite3(&scene, "plane point", &p.point)?,
                    normal,
                };
                Arc::new(plane) as Arc<dyn Shape>
            }
            (None, Some(m)) => {
                let s = surface_of(&scene, dir, &m.file, &format!("obstacle '{name}' mesh"))?.0;
                scaled_size(&format!("obstacle '{name}' mesh"), m.scale, &s.vertices).map_err(&invalid)?;
                let s = s.scaled(m.scale);
                Arc::new(
                    TriMeshObstacle::new(s.vertices, s.triangles)
                        .map_err(|e| invalid(format!("obstacle '{name}': {e}")))?,
                )
            }
            _ => {
                return Err(invalid(format!(
                    "obstacle '{name}': give exactly one of plane and mesh"
                )))
            }
        };
        builder = builder.obstacle(Obstacle {
            name,
            shape,
            friction: o.friction,
            thickness: o.thickness,
        });
    }
    let model = builder.build().map_err(|source| SceneError::Model {
        path: scene.clone(),
        source,
    })?;
    Ok(Scene {
        path: path.to_path_buf(),
        format: SceneFormat::Diffsoft,
        model,
        settings,
        meshes,
        notes: Vec::new(),
    })
}
