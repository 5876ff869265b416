//! Where a paper scene's file names lead: relative to the paper's data root, to the scene's
//! own folder, or beside the scene; or, for a scene rebuilt from the files it carried, only to
//! those.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use super::carried::CarriedFile;

/// Where the file names of one import lead.
#[derive(Debug, Clone, Copy)]
pub(super) enum Files<'a> {
    /// To the files [`find_file`] finds beside the scene.
    Search,
    /// Only to these files on disk, by the name the scene gives each ([`super::import_carried`]).
    Paths(&'a HashMap<String, PathBuf>),
    /// Only to these contents, by the name the scene gives each
    /// ([`super::import_carried_bytes`]).
    Carried(&'a HashMap<String, CarriedFile>),
}

/// Where a paper scene at `scene` looks for a file it names `file`, in order: relative to the
/// paper's data root (the scene's parent directory), to the scene's own directory, and by its
/// name beside the scene; from any working directory (the scene path is made absolute first).
pub(super) fn file_candidates(scene: &Path, file: &str) -> Vec<PathBuf> {
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
/// [`import`]: super::import
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

/// Where a file the scene names is read from (where [`Files`] led its name).
#[derive(Debug, Clone)]
pub(super) enum FileSource<'a> {
    /// A file on disk, read when it is needed.
    Disk(PathBuf),
    /// Contents carried in memory.
    Carried(&'a CarriedFile),
}

impl FileSource<'_> {
    /// The path that messages name for the file.
    pub(super) fn shown(&self) -> String {
        match self {
            FileSource::Disk(path) => path.display().to_string(),
            FileSource::Carried(file) => file.shown().display().to_string(),
        }
    }
}

/// The file that a scene naming `file` needs besides it, where its format is a pair of files:
/// the other half of a TetGen pair (`m.node` and `m.ele`, in the case of `file`'s extension, as
/// [`crate::mesh::load`] pairs them), which a scene rebuilt from carried files must carry under
/// this name. `None` for a single-file format.
///
/// ```
/// use diffsoft::scene::paper;
///
/// assert_eq!(paper::companion_file("bodies/m.node").as_deref(), Some("bodies/m.ele"));
/// assert_eq!(paper::companion_file("M.ELE").as_deref(), Some("M.NODE"));
/// assert_eq!(paper::companion_file("fish/fish.obj"), None);
/// ```
pub fn companion_file(file: &str) -> Option<String> {
    let path = Path::new(file);
    let ext = path.extension()?.to_str()?;
    let (node, ele) = crate::mesh::tetgen_extensions(ext);
    let other = match ext.to_ascii_lowercase().as_str() {
        "node" => ele,
        "ele" => node,
        _ => return None,
    };
    Some(path.with_extension(other).to_string_lossy().into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candidates_run_from_the_data_root_to_the_scene_folder() {
        let scene = Path::new("/data/paper/fish/fish.json");
        assert_eq!(
            file_candidates(scene, "fish/fish.obj"),
            vec![
                PathBuf::from("/data/paper/fish/fish.obj"),
                PathBuf::from("/data/paper/fish/fish/fish.obj"),
                PathBuf::from("/data/paper/fish/fish.obj"),
            ]
        );
        // A bare name: the data root's and the scene folder's candidates, once each.
        assert_eq!(
            file_candidates(scene, "a.obj"),
            vec![
                PathBuf::from("/data/paper/a.obj"),
                PathBuf::from("/data/paper/fish/a.obj")
            ]
        );
    }
}
