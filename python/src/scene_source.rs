//! Where a `diffsoft.Scene` came from, by value: a native scene's document with every mesh
//! inline, or a paper-format scene's file and the files it names, and the parameters the caller
//! set since ([`Data`]); `Scene.load`, which reads a scene file into one; and
//! [`import_paper_files`], which builds a paper scene from the contents of the files it
//! carries, in memory (what loading and unpickling both call). The `scene_data` module turns a
//! source into dicts and pickles and back, and `scene_core`'s `Scene` holds one; this module
//! depends on neither.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use diffsoft::scene as lib_scene;
use serde_json::Value as Json;

use crate::errors;
use crate::params::Value;

/// Where a scene came from, by value.
#[derive(Debug, Clone)]
pub(crate) enum Source {
    /// A `diffsoft.scene/1` document with every mesh inline.
    Document(Arc<Json>),
    /// A paper-format scene file and the files it names.
    Paper(Arc<PaperFiles>),
}

/// A paper-format scene as files: its text and every file it names, each under the name the
/// scene gives it.
#[derive(Debug)]
pub(crate) struct PaperFiles {
    /// The scene's directory name under the root.
    pub(crate) dir: String,
    /// The scene file's name.
    pub(crate) name: String,
    /// The scene file's text.
    pub(crate) text: String,
    /// `(name as the scene gives it, contents)`.
    pub(crate) files: Vec<(String, Vec<u8>)>,
}

/// What a scene holds besides its model: its source and the parameters the caller set.
#[derive(Debug, Clone, Default)]
pub(crate) struct Data {
    pub(crate) source: Option<Source>,
    /// `Scene.set` calls in order, each name's last value only (a set overwrites what an
    /// earlier set of the same name wrote).
    pub(crate) sets: Vec<(String, Value)>,
}

impl Data {
    /// Data of a scene from `source`.
    pub(crate) fn new(source: Source) -> Self {
        Self {
            source: Some(source),
            sets: Vec::new(),
        }
    }

    /// Remember that `name` was set to `value`.
    pub(crate) fn record(&mut self, name: &str, value: &Value) {
        self.sets.retain(|(n, _)| n != name);
        self.sets.push((name.to_string(), value.clone()));
    }
}

/// `Scene.load`: the scene file at `path` and the source it pickles as, built from one read of
/// each file: the scene file's text is read once (a named pipe fed once loads), a native scene's
/// meshes are read once and inlined, and the scene is built from that document; a paper scene's
/// files are read once and the scene is built from those bytes, as unpickling rebuilds it. The
/// reads run on a thread that Ctrl-C abandons (a pipe nobody writes to does not hang the call).
pub(crate) fn load(
    py: pyo3::Python<'_>,
    path: PathBuf,
    opts: lib_scene::LoadOptions,
) -> pyo3::PyResult<(lib_scene::Scene, Source)> {
    crate::interrupt::abandonable(py, move || build(&path, opts))?
}

fn build(path: &Path, opts: lib_scene::LoadOptions) -> pyo3::PyResult<(lib_scene::Scene, Source)> {
    let shown = path.display().to_string();
    let syntax = |message: String| lib_scene::SceneError::Syntax {
        path: shown.clone(),
        message,
    };
    let io = |message: String| lib_scene::SceneError::Io {
        path: shown.clone(),
        message,
    };
    let text = diffsoft::base::input_file::read_text(path).map_err(|e| errors::scene(io(e.to_string())))?;
    let doc = lib_scene::json::parse_lenient(&text).map_err(|e| errors::scene(syntax(e.to_string())))?;
    let is_diffsoft = doc
        .get("schema")
        .and_then(Json::as_str)
        .is_some_and(|s| s.starts_with("diffsoft.scene"));
    let abs = std::path::absolute(path).map_err(|e| errors::scene(io(e.to_string())))?;
    if is_diffsoft {
        // Parsed strictly first, as the library's `load` does, so that errors carry line and
        // column.
        lib_scene::json::typed_from_str::<lib_scene::format::SceneFile>(&text).map_err(|m| errors::scene(syntax(m)))?;
        let mut doc = doc;
        let dir = abs.parent().unwrap_or(Path::new("."));
        lib_scene::inline::inline_meshes(&mut doc, dir, &shown).map_err(errors::scene)?;
        let scene = lib_scene::from_value(doc.clone(), path).map_err(errors::scene)?;
        Ok((scene, Source::Document(Arc::new(doc))))
    } else if doc.get("Meshes").is_some() || doc.get("Parameters").is_some() {
        paper(path, &abs, text, &doc, opts)
    } else {
        Err(errors::scene(syntax(format!(
            "not a scene: expected \"schema\": \"{}\" or a paper scene with \"Meshes\"",
            lib_scene::format::SCENE_SCHEMA
        ))))
    }
}

/// The names of the files a paper scene's importer reads (`scene::paper`): each mesh's
/// `"Obj filename"` and `"Muscle filename"`, each cloth's `"Obj filename"`, and each obstacle's
/// `"Obj filename"` when `"Handle collision"` is on (the importer ignores obstacles otherwise).
/// Strings under other keys (`"Material Identifier"`, `"Sampling filename"`, ...) name no file
/// it reads. Each name once, in the order given.
fn paper_file_names(doc: &Json) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let mut add = |v: Option<&Json>| {
        if let Some(s) = v.and_then(Json::as_str) {
            if !out.iter().any(|n| n == s) {
                out.push(s.to_string());
            }
        }
    };
    let list = |key: &str| doc.get(key).and_then(Json::as_array).map_or(&[][..], Vec::as_slice);
    for m in list("Meshes") {
        add(m.get("Obj filename"));
        add(m.get("Muscle filename"));
    }
    for c in list("Clothes") {
        add(c.get("Obj filename"));
    }
    let collisions = doc.pointer("/Parameters/0/Handle collision").and_then(Json::as_bool) == Some(true);
    if collisions {
        for o in list("Obstacles") {
            add(o.get("Obj filename"));
        }
    }
    out
}

/// A paper scene built from one read of each file it names (parsed from those bytes in memory,
/// as unpickling rebuilds it), and those bytes as its source. Messages and notes name the
/// files read. A name in a TetGen pair brings the other half of the pair, read beside it, under
/// the name [`lib_scene::paper::companion_file`] gives.
fn paper(
    path: &Path,
    abs: &Path,
    text: String,
    doc: &Json,
    opts: lib_scene::LoadOptions,
) -> pyo3::PyResult<(lib_scene::Scene, Source)> {
    // The importer's own error where a file cannot be found or read: it says where it looked
    // (it reads no file it cannot find; the files before it are read again, only to fail).
    let importer_error = |name: &str| match lib_scene::paper::import(path, doc, opts) {
        Err(e) => errors::scene(e),
        Ok(_) => errors::Class::File.err(format!(
            "{}: \"{name}\" appeared while the scene was read; load it again",
            path.display()
        )),
    };
    let mut files: Vec<(String, Vec<u8>)> = Vec::new();
    let mut found_at: Vec<PathBuf> = Vec::new();
    for name in paper_file_names(doc) {
        if files.iter().any(|(n, _)| *n == name) {
            continue;
        }
        let Some(found) = lib_scene::paper::find_file(abs, &name) else {
            return Err(importer_error(&name));
        };
        let companion = lib_scene::paper::companion_file(&name).and_then(|other| {
            let file_name = Path::new(&other).file_name()?.to_owned();
            Some((other, found.with_file_name(file_name)))
        });
        for (name, found) in std::iter::once((name, found)).chain(companion) {
            if files.iter().any(|(n, _)| *n == name) {
                continue;
            }
            // A file that cannot be read: the importer's error, unless it is only the other
            // half of a pair that the importer would also fail to read.
            let bytes = std::fs::read(&found).map_err(|e| {
                if found.is_file() {
                    errors::scene(lib_scene::SceneError::Io {
                        path: found.display().to_string(),
                        message: e.to_string(),
                    })
                } else {
                    importer_error(&name)
                }
            })?;
            files.push((name, bytes));
            found_at.push(found);
        }
    }
    let paper = PaperFiles {
        dir: abs
            .parent()
            .and_then(Path::file_name)
            .map_or("scene".into(), |n| n.to_string_lossy().into_owned()),
        name: path
            .file_name()
            .map_or("scene.json".into(), |n| n.to_string_lossy().into_owned()),
        text,
        files,
    };
    let scene = import_paper_files(path, doc, opts, &paper.files, &found_at)?;
    Ok((scene, Source::Paper(Arc::new(paper))))
}

/// A paper scene at `path` (named in messages; no file is read there) built from `files`, the
/// files it names (`(name as the scene gives it, contents)`), in memory: no other file is read
/// and none is written. Messages and notes name each file as `shown` gives where it came from
/// (a scene just loaded), else by the name the scene gives it (an unpickled one).
pub(crate) fn import_paper_files(
    path: &Path,
    doc: &Json,
    opts: lib_scene::LoadOptions,
    files: &[(String, Vec<u8>)],
    shown: &[PathBuf],
) -> pyo3::PyResult<lib_scene::Scene> {
    let carried: std::collections::HashMap<String, lib_scene::paper::CarriedFile> = files
        .iter()
        .enumerate()
        .map(|(k, (name, bytes))| {
            let shown = shown.get(k).cloned().unwrap_or_else(|| PathBuf::from(name));
            (name.clone(), lib_scene::paper::CarriedFile::new(shown, bytes.clone()))
        })
        .collect();
    crate::fork::install(|| lib_scene::paper::import_carried_bytes(path, doc, opts, &carried)).map_err(errors::scene)
}
