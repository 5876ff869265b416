//! Where a `diffsoft.Scene` came from, by value: a native scene's document with every mesh
//! inline, or a paper-format scene's file and the files it names, and the parameters the caller
//! set since ([`Data`]); `Scene.load`, which reads a scene file into one; and
//! [`import_paper_files`], which builds a paper scene from the files it carries (what loading
//! and unpickling both call). The `scene_data` module turns a source into dicts and pickles
//! and back, and `scene_core`'s `Scene` holds one; this module depends on neither.

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

/// A paper scene built from one read of each file it names (copies in a temporary directory,
/// as unpickling rebuilds it), and those bytes as its source. Messages and notes name the
/// original files.
fn paper(
    path: &Path,
    abs: &Path,
    text: String,
    doc: &Json,
    opts: lib_scene::LoadOptions,
) -> pyo3::PyResult<(lib_scene::Scene, Source)> {
    let mut files: Vec<(String, Vec<u8>)> = Vec::new();
    let mut found_at: Vec<PathBuf> = Vec::new();
    for name in paper_file_names(doc) {
        let Some(found) = lib_scene::paper::find_file(abs, &name) else {
            // The importer's own error, which says where it looked (it reads no file it cannot
            // find; the files before it are read again, only to fail).
            return Err(match lib_scene::paper::import(path, doc, opts) {
                Err(e) => errors::scene(e),
                Ok(_) => errors::Class::File.err(format!(
                    "{}: \"{name}\" appeared while the scene was read; load it again",
                    path.display()
                )),
            });
        };
        let bytes = std::fs::read(&found).map_err(|e| {
            errors::scene(lib_scene::SceneError::Io {
                path: found.display().to_string(),
                message: e.to_string(),
            })
        })?;
        files.push((name, bytes));
        found_at.push(found);
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
/// files it names (`(name as the scene gives it, contents)`), written under a fresh temporary
/// directory that is removed after. Where `originals` gives the file each came from (a scene
/// just loaded), messages and notes name those instead of the copies.
pub(crate) fn import_paper_files(
    path: &Path,
    doc: &Json,
    opts: lib_scene::LoadOptions,
    files: &[(String, Vec<u8>)],
    originals: &[PathBuf],
) -> pyo3::PyResult<lib_scene::Scene> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static COUNT: AtomicUsize = AtomicUsize::new(0);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    let root = std::env::temp_dir().join(format!(
        "diffsoft-scene-{}-{}-{nanos}",
        std::process::id(),
        COUNT.fetch_add(1, Ordering::Relaxed)
    ));
    let io = |e: std::io::Error| errors::Class::File.err(format!("{}: {e}", root.display()));
    let mut copies: Vec<(String, String)> = Vec::new();
    let result = (|| {
        // Each carried file under a directory of its own, keeping its file name (the mesh
        // readers go by the extension); the scene's names map to these paths and nothing else.
        let mut carried = std::collections::HashMap::new();
        for (k, (key, bytes)) in files.iter().enumerate() {
            let file_name = Path::new(key)
                .file_name()
                .and_then(|n| n.to_str())
                .filter(|n| Path::new(n).components().count() == 1)
                .unwrap_or("file");
            let holder = root.join(format!("carried-{k}"));
            std::fs::create_dir_all(&holder).map_err(io)?;
            let target = holder.join(file_name);
            std::fs::write(&target, bytes).map_err(io)?;
            if let Some(original) = originals.get(k) {
                copies.push((target.display().to_string(), original.display().to_string()));
            }
            carried.insert(key.clone(), target);
        }
        let shown = |mut m: String| {
            for (copy, original) in &copies {
                m = m.replace(copy.as_str(), original);
            }
            m
        };
        let mut scene = crate::fork::install(|| lib_scene::paper::import_carried(path, doc, opts, &carried))
            .map_err(|e| errors::scene_shown(e, shown))?;
        for note in &mut scene.notes {
            *note = shown(std::mem::take(note));
        }
        Ok(scene)
    })();
    let _ = std::fs::remove_dir_all(&root);
    result
}
