//! Scenes as data: `Scene.from_dict` / `to_dict` (the scene file's structure, meshes inline),
//! and a scene's state by value for pickling and copying: its document (every mesh inline, so
//! it needs no file and no directory), the solver settings and the parameters the caller set.
//! A paper-format scene travels as its file's text and the files it names, rebuilt from their
//! contents in memory (`crate::scene_source::import_paper_files`). (Python objects to JSON:
//! `crate::pyjson`; the mesh accessors: `crate::mesh_access`.)

use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

use diffsoft::scene as lib_scene;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};
use serde_json::Value as Json;

use crate::arrays;
use crate::errors;
use crate::params::{Inputs, Value};
use crate::scene_core::Scene;
use crate::scene_source::{import_paper_files, Data, PaperFiles, Source};

/// Version of the state `__reduce__` writes (checked when it is read back).
const STATE_VERSION: u32 = 2;

/// `Scene.from_dict`: a scene from its document; relative mesh paths resolve against
/// `base_dir` (the working directory when `None`).
pub(crate) fn from_dict(py: Python<'_>, d: &Bound<'_, PyAny>, base_dir: Option<PathBuf>) -> PyResult<Scene> {
    if !d.is_instance_of::<PyDict>() {
        return Err(errors::value(format!(
            "Scene.from_dict: expected a dict, got a {}",
            d.get_type().name()?
        )));
    }
    let mut doc = crate::pyjson::to_json(d, "")?;
    check_inline_vertices(&doc)?;
    if doc.get("schema").is_none() {
        if let Some(o) = doc.as_object_mut() {
            o.insert("schema".into(), Json::String(lib_scene::format::SCENE_SCHEMA.into()));
        }
    }
    let path = match &base_dir {
        Some(dir) => dir.join("<dict>"),
        None => PathBuf::from("<dict>"),
    };
    let dir = base_dir.unwrap_or_default();
    // The meshes are read on a thread that Ctrl-C abandons (a named pipe nobody writes to).
    let inner = crate::interrupt::abandonable(py, move || {
        lib_scene::inline::inline_meshes(&mut doc, &dir, "<dict>")?;
        let scene = lib_scene::from_value(doc.clone(), &path)?;
        Ok::<_, lib_scene::SceneError>((scene, doc))
    })?
    .map_err(errors::scene)?;
    let (inner, doc) = inner;
    Ok(Scene {
        inner,
        inputs: Inputs::default(),
        data: Data::new(Source::Document(Arc::new(doc))),
    })
}

/// Refuse a body's inline mesh with vertices no tet uses: the library drops them and numbers
/// the rest in order (as it does a mesh file's, whose ids the scene keeps), so row `k` of the
/// position arrays would no longer be the caller's vertex `k`. Meshes the library refuses
/// anyway (no tets, an index out of range, not integers) are left to it.
fn check_inline_vertices(doc: &Json) -> PyResult<()> {
    let Some(bodies) = doc.get("bodies").and_then(Json::as_array) else {
        return Ok(());
    };
    for (b, body) in bodies.iter().enumerate() {
        let mesh = body.get("mesh");
        let (Some(n), Some(tets)) = (
            mesh.and_then(|m| m.get("vertices"))
                .and_then(Json::as_array)
                .map(Vec::len),
            mesh.and_then(|m| m.get("tets")).and_then(Json::as_array),
        ) else {
            continue;
        };
        let mut used = vec![false; n];
        let indices: Option<Vec<usize>> = tets
            .iter()
            .flat_map(|t| t.as_array().map_or(&[][..], Vec::as_slice))
            .map(|i| i.as_u64().and_then(|i| usize::try_from(i).ok()).filter(|&i| i < n))
            .collect();
        let Some(indices) = indices.filter(|i| !i.is_empty()) else {
            continue;
        };
        indices.into_iter().for_each(|i| used[i] = true);
        let unused: Vec<String> = (0..n).filter(|&i| !used[i]).map(|i| i.to_string()).collect();
        if !unused.is_empty() {
            let name = body.get("name").and_then(Json::as_str).unwrap_or("?");
            let more = if unused.len() > 10 {
                format!(" and {} more", unused.len() - 10)
            } else {
                String::new()
            };
            return Err(errors::value(format!(
                "bodies[{b}] ('{name}') mesh: {} vertices that no tet uses ({}{more}); remove them (the rows of the position arrays are the mesh's vertices, in order)",
                unused.len(),
                unused[..unused.len().min(10)].join(", ")
            )));
        }
    }
    Ok(())
}

/// `Scene.to_dict`'s document: every mesh inline (plain lists; `json.dump` writes it as a scene
/// file), the solver section as the scene's current settings. No Python code runs.
pub(crate) fn document(s: &Scene) -> PyResult<Json> {
    match &s.data.source {
        Some(Source::Document(doc)) => {
            let mut doc = (**doc).clone();
            if let Some(o) = doc.as_object_mut() {
                o.remove("time_step");
                o.insert("solver".into(), serde_json::to_value(&s.inner.settings).map_err(errors::other)?);
            }
            Ok(doc)
        }
        Some(Source::Paper(_)) => Err(errors::Class::Unsupported.err(format!(
            "{}: to_dict writes diffsoft.scene/1 documents; this scene is in the paper's format (it pickles and copies, but has no diffsoft.scene/1 document)",
            s.inner.path.display()
        ))),
        None => Err(errors::value("this scene has no document")),
    }
}

/// A value that was set, as the Python object `Scene.set` takes.
fn set_value<'py>(py: Python<'py>, s: &Scene, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    use diffsoft::diff::params::ArrayParam;
    let model = &s.inner.model;
    Ok(match v {
        Value::Scalar(_, x) => x.into_pyobject(py)?.into_any(),
        Value::Vectors(_, vs) => arrays::vectors(py, vs.clone())?,
        Value::PerTet(e) => arrays::array(py, e.clone(), &[e.len()])?,
        Value::PerStep(a, rows) => {
            let cols = match a {
                ArrayParam::Activations => model.actuators().map_or(0, |g| g.groups.len()),
                _ => model.skeleton().map_or(0, |k| k.dofs),
            };
            arrays::matrix(py, rows, cols)?
        }
    })
}

/// The state `__reduce__` pickles: a dict of plain Python objects.
pub(crate) fn state<'py>(py: Python<'py>, s: &Scene) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("version", STATE_VERSION)?;
    match &s.data.source {
        Some(Source::Document(doc)) => {
            d.set_item("document", serde_json::to_string(&**doc).map_err(errors::other)?)?;
        }
        Some(Source::Paper(p)) => {
            let files = PyDict::new(py);
            for (k, bytes) in &p.files {
                files.set_item(k, PyBytes::new(py, bytes))?;
            }
            let paper = PyDict::new(py);
            paper.set_item("dir", &p.dir)?;
            paper.set_item("name", &p.name)?;
            paper.set_item("text", &p.text)?;
            paper.set_item("files", files)?;
            d.set_item("paper", paper)?;
        }
        None => return Err(errors::value("this scene has no source to pickle")),
    }
    d.set_item("path", s.inner.path.display().to_string())?;
    d.set_item("notes", s.inner.notes.clone())?;
    d.set_item(
        "settings",
        serde_json::to_string(&s.inner.settings).map_err(errors::other)?,
    )?;
    let sets = s
        .data
        .sets
        .iter()
        .map(|(n, v)| PyTuple::new(py, [n.into_pyobject(py)?.into_any(), set_value(py, s, v)?]))
        .collect::<PyResult<Vec<_>>>()?;
    d.set_item("sets", sets)?;
    Ok(d)
}

fn item<'py>(state: &Bound<'py, PyDict>, key: &str) -> PyResult<Bound<'py, PyAny>> {
    state
        .get_item(key)?
        .ok_or_else(|| errors::value(format!("scene state: no '{key}'")))
}

/// A paper scene from a pickled state, at `path` (the scene's path when it was loaded, named in
/// messages): built from the contents of the files it carries, in memory (no file is read or
/// written), each named in messages by the name the scene gives it.
fn load_paper(py: Python<'_>, path: &Path, paper: &Bound<'_, PyDict>) -> PyResult<lib_scene::Scene> {
    let dir: String = extract(paper, "dir", "paper.dir")?;
    let name: String = extract(paper, "name", "paper.name")?;
    let text: String = extract(paper, "text", "paper.text")?;
    let files = carried_files(paper)?;
    // One normal component each (not `..`, `.`, a root or a path).
    for part in [&dir, &name] {
        let mut parts = Path::new(part).components();
        if !matches!((parts.next(), parts.next()), (Some(Component::Normal(_)), None)) {
            return Err(errors::value(format!("scene state: '{part}' is not a plain name")));
        }
    }
    let doc = lib_scene::json::parse_lenient(&text).map_err(|e| errors::value(format!("scene state: {e}")))?;
    py.detach(|| import_paper_files(path, &doc, lib_scene::LoadOptions::default(), &files, &[]))
}

/// The `files` of a pickled paper scene: `{name: bytes}`.
fn carried_files(paper: &Bound<'_, PyDict>) -> PyResult<Vec<(String, Vec<u8>)>> {
    let files = item(paper, "files")?;
    let files = files
        .cast::<PyDict>()
        .map_err(|_| errors::value("scene state: 'paper.files' is not a dict"))?;
    files
        .iter()
        .map(|(k, v)| {
            let key: String = k
                .extract()
                .map_err(|_| errors::value("scene state: a name of 'paper.files' is not a str"))?;
            let bytes: Vec<u8> = v
                .cast::<PyBytes>()
                .map_err(|_| errors::value(format!("scene state: 'paper.files'['{key}'] is not bytes")))?
                .as_bytes()
                .to_vec();
            Ok((key, bytes))
        })
        .collect()
}

/// Item `key` of a pickled state extracted as `T`, an `InputError` naming it (`shown`) if it is
/// not one.
fn extract<'py, T: pyo3::conversion::FromPyObjectOwned<'py>>(
    state: &Bound<'py, PyDict>,
    key: &str,
    shown: &str,
) -> PyResult<T> {
    item(state, key)?.extract::<T>().map_err(|e| {
        let e: PyErr = e.into();
        errors::value(format!(
            "scene state: '{shown}' is not what a pickled scene holds ({e})"
        ))
    })
}

/// A scene from the state of [`state`] (what unpickling calls).
#[pyfunction]
pub(crate) fn _scene_from_state(py: Python<'_>, state: &Bound<'_, PyDict>) -> PyResult<Scene> {
    let version: u32 = extract(state, "version", "version")?;
    if version != STATE_VERSION {
        return Err(errors::value(format!(
            "scene state version {version}: this version of diffsoft reads version {STATE_VERSION}"
        )));
    }
    let path = PathBuf::from(extract::<String>(state, "path", "path")?);
    let (mut inner, source) = match state.get_item("document")? {
        Some(_) => {
            let text: String = extract(state, "document", "document")?;
            let doc: Json = serde_json::from_str(&text)
                .map_err(|e| errors::value(format!("scene state: 'document' is not JSON ({e})")))?;
            let inner = py
                .detach(|| crate::fork::install(|| lib_scene::from_value(doc.clone(), &path)))
                .map_err(errors::scene)?;
            (inner, Source::Document(Arc::new(doc)))
        }
        None => {
            let paper = item(state, "paper")?;
            let paper = paper
                .cast::<PyDict>()
                .map_err(|_| errors::value("scene state: 'paper' is not a dict"))?;
            let inner = load_paper(py, &path, paper)?;
            let source = Source::Paper(Arc::new(PaperFiles {
                dir: extract(paper, "dir", "paper.dir")?,
                name: extract(paper, "name", "paper.name")?,
                text: extract(paper, "text", "paper.text")?,
                files: carried_files(paper)?,
            }));
            (inner, source)
        }
    };
    inner.path = path;
    inner.notes = extract(state, "notes", "notes")?;
    let settings: String = extract(state, "settings", "settings")?;
    inner.settings = serde_json::from_str(&settings)
        .map_err(|e| errors::value(format!("scene state: 'settings' are not solver settings ({e})")))?;
    let mut scene = Scene {
        inner,
        inputs: Inputs::default(),
        data: Data::new(source),
    };
    let sets = item(state, "sets")?
        .try_iter()
        .map_err(|_| errors::value("scene state: 'sets' is not a list"))?;
    for entry in sets {
        let entry = entry?;
        let (name, value): (String, Bound<'_, PyAny>) = entry
            .extract()
            .map_err(|_| errors::value("scene state: an entry of 'sets' is not a (name, value) pair"))?;
        let v = Value::read(&scene.inner.model, &name, &value)?;
        scene.data.record(&name, &v);
        v.apply(&mut scene.inner.model, &mut scene.inputs)?;
    }
    Ok(scene)
}
