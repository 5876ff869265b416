//! Where a `diffsoft.Scene` came from, by value: a native scene's document with every mesh
//! inline, or a paper-format scene's file and the files it names, and the parameters the caller
//! set since ([`Data`]). `crate::scene_data` turns it into dicts and pickles.

use std::path::Path;
use std::sync::Arc;

use diffsoft::scene::{self as lib_scene, SceneFormat};
use serde_json::Value as Json;

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

/// The source of a scene just loaded from `path`: native scenes as their document with the
/// meshes inline, paper scenes as their files.
pub(crate) fn source_of_file(path: &Path, format: SceneFormat) -> Result<Source, lib_scene::SceneError> {
    let shown = path.display().to_string();
    let io = |e: std::io::Error| lib_scene::SceneError::Io {
        path: shown.clone(),
        message: e.to_string(),
    };
    let text = std::fs::read_to_string(path).map_err(io)?;
    let syntax = |e: serde_json::Error| lib_scene::SceneError::Syntax {
        path: shown.clone(),
        message: e.to_string(),
    };
    let mut doc = lib_scene::json::parse_lenient(&text).map_err(syntax)?;
    let abs = std::path::absolute(path).map_err(io)?;
    let dir = abs.parent().unwrap_or(Path::new("."));
    match format {
        SceneFormat::Diffsoft => {
            lib_scene::inline::inline_meshes(&mut doc, dir, &shown)?;
            Ok(Source::Document(Arc::new(doc)))
        }
        SceneFormat::Paper => {
            let dir_name = dir
                .file_name()
                .map_or("scene".into(), |n| n.to_string_lossy().into_owned());
            let mut names = Vec::new();
            strings(&doc, &mut names);
            // Every string that names a file by the importer's own search, carried under the
            // name as written (a relative name, one through `..`, or an absolute one): the
            // rebuilt scene resolves its names through these files alone.
            let mut files: Vec<(String, Vec<u8>)> = Vec::new();
            for s in names {
                if files.iter().any(|(k, _)| *k == s) {
                    continue;
                }
                if let Some(found) = lib_scene::paper::find_file(&abs, &s) {
                    files.push((s, std::fs::read(found).map_err(io)?));
                }
            }
            let name = path
                .file_name()
                .map_or("scene.json".into(), |n| n.to_string_lossy().into_owned());
            Ok(Source::Paper(Arc::new(PaperFiles {
                dir: dir_name,
                name,
                text,
                files,
            })))
        }
    }
}

/// Every string in `v`.
fn strings(v: &Json, out: &mut Vec<String>) {
    match v {
        Json::String(s) => out.push(s.clone()),
        Json::Array(a) => a.iter().for_each(|x| strings(x, out)),
        Json::Object(o) => o.values().for_each(|x| strings(x, out)),
        _ => {}
    }
}
