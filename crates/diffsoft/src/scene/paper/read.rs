//! Reading the files a paper scene names from where their names led ([`FileSource`]): on disk
//! or carried in memory, parsed by the same readers either way, every message naming the file
//! as shown.

use std::borrow::Cow;

use super::context::Ctx;
use super::files::{companion_file, FileSource};
use crate::mesh::{self, surface::TriSurface, LoadOptions, LoadedMesh, MeshError, MeshErrorKind};
use crate::scene::SceneError;

/// The text of `src` (UTF-8, a leading byte-order mark removed); an I/O error naming it where
/// it cannot be read or is not UTF-8 text.
pub(super) fn text<'a>(src: &FileSource<'a>) -> Result<Cow<'a, str>, SceneError> {
    contents(src).map_err(|e| SceneError::Io {
        path: src.shown(),
        message: e.to_string(),
    })
}

/// The triangle surface in OBJ file `src`, as [`mesh::surface::load_obj`] reads one.
pub(super) fn surface(src: &FileSource<'_>) -> Result<TriSurface, MeshError> {
    let shown = src.shown();
    let text = contents(src).map_err(|e| MeshError::file(&shown, MeshErrorKind::Io(e.to_string())))?;
    mesh::surface::parse_obj(&shown, &text)
}

/// The tet mesh the scene names `file`, read as [`mesh::load`] reads it from disk: by the
/// extension of `file` (`.obj`, `.msh`, or one half of a TetGen `.node`/`.ele` pair, whose
/// other half the scene reaches under the name [`companion_file`] gives).
pub(super) fn tet_mesh(cx: &Ctx<'_>, file: &str) -> Result<LoadedMesh, SceneError> {
    let src = cx.resolve(file)?;
    if let FileSource::Disk(path) = &src {
        return Ok(mesh::load(path)?);
    }
    let shown = src.shown();
    let ext = std::path::Path::new(file)
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let opts = LoadOptions::default();
    Ok(match ext.as_str() {
        "obj" => mesh::parse_obj_text(&shown, &mesh_text(&src)?, opts)?,
        "msh" => mesh::parse_gmsh_text(&shown, &mesh_text(&src)?, opts)?,
        "node" | "ele" => {
            let other = companion_file(file).unwrap_or_default();
            let pair = cx.resolve(&other).map_err(|_| {
                cx.invalid(format!(
                    "cannot find \"{other}\", the other half of the TetGen pair \"{file}\": this scene was rebuilt from the files it named when it was first read, and this name was not one of them"
                ))
            })?;
            let (node, ele) = if ext == "node" { (&src, &pair) } else { (&pair, &src) };
            mesh::parse_tetgen_str(&node.shown(), &mesh_text(node)?, &ele.shown(), &mesh_text(ele)?)?
        }
        _ => return Err(mesh::unsupported_extension(&shown, &ext).into()),
    })
}

/// The text of mesh file `src`, or the error [`mesh::load`] gives for it.
fn mesh_text<'a>(src: &FileSource<'a>) -> Result<Cow<'a, str>, MeshError> {
    contents(src).map_err(|e| mesh::text_error(&src.shown(), &e))
}

/// The text of `src`, read as [`crate::base::input_file::read_text`] reads a file; its errors
/// do not name the file.
fn contents<'a>(src: &FileSource<'a>) -> std::io::Result<Cow<'a, str>> {
    match src {
        FileSource::Disk(path) => crate::base::input_file::read_text(path).map(Cow::Owned),
        FileSource::Carried(file) => file.text().map(Cow::Borrowed),
    }
}
