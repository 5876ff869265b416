//! Where a paper scene's file names lead: relative to the paper's data root, to the scene's
//! own folder, or beside the scene.

use std::path::{Path, PathBuf};

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
