//! `"Attach Verts"` with `"Attach Stiffness"` on a mesh or a cloth: springs to the listed
//! vertices' rest positions, or Dirichlet vertices where the stiffness is at least
//! [`DIRICHLET_STIFFNESS`] (the bridges' 1e20 is a Dirichlet condition imposed by penalty).

use serde_json::Value;

use super::context::Ctx;
use crate::cloth::ClothSpec;
use crate::mesh::{MeshInfo, TetMesh};
use crate::model::BodySpec;
use crate::scene::format::VertexSelector;
use crate::scene::SceneError;

/// Attach stiffness at or above which attachments become Dirichlet vertices.
pub const DIRICHLET_STIFFNESS: f64 = 1e12;

/// The attachments of the mesh `mj` (at `w`) to the body `spec` named `name`, whose file's mesh
/// is `mesh` (`info` its loading details): the vertices are checked as the scene format
/// checks them; a Dirichlet condition is noted.
pub(super) fn body_attachments(
    cx: &mut Ctx<'_>,
    w: &str,
    name: &str,
    mj: &Value,
    mesh: &TetMesh,
    info: &MeshInfo,
    spec: &mut BodySpec,
) -> Result<(), SceneError> {
    let Some(av) = mj.get("Attach Verts") else {
        note_lone_stiffness(cx, w, mj);
        return Ok(());
    };
    let ids = cx.indices(av, w, "Attach Verts")?;
    let stiffness = stiffness(cx, w, mj)?;
    let verts = crate::scene::select(&cx.shown(), name, &VertexSelector::Indices(ids), mesh, info)?;
    if stiffness >= DIRICHLET_STIFFNESS {
        cx.notes.push(format!(
            "{w}: {} attached vertices with stiffness {stiffness:e} >= {DIRICHLET_STIFFNESS:e} imposed exactly (Dirichlet)",
            verts.len()
        ));
        spec.fixed = verts;
    } else {
        spec.attachments = verts.into_iter().map(|v| (v, stiffness)).collect();
    }
    Ok(())
}

/// The attachments of the cloth `cj` (at `w`, read from `file`) to `spec`: each listed vertex
/// must be one of the cloth's.
pub(super) fn cloth_attachments(
    cx: &mut Ctx<'_>,
    w: &str,
    file: &str,
    cj: &Value,
    spec: &mut ClothSpec,
) -> Result<(), SceneError> {
    let Some(av) = cj.get("Attach Verts") else {
        note_lone_stiffness(cx, w, cj);
        return Ok(());
    };
    let ids = cx.indices(av, w, "Attach Verts")?;
    let n = spec.surface.vertices.len();
    if let Some(bad) = ids.iter().find(|&&v| v >= n) {
        return Err(cx.invalid(format!(
            "{w}: \"Attach Verts\": vertex {bad} out of range ({n} vertices in {file})"
        )));
    }
    let stiffness = stiffness(cx, w, cj)?;
    if stiffness >= DIRICHLET_STIFFNESS {
        spec.fixed = ids;
    } else {
        spec.attachments = ids.into_iter().map(|v| (v, stiffness)).collect();
    }
    Ok(())
}

/// The `"Attach Stiffness"` that `"Attach Verts"` of `obj` (at `w`) needs.
fn stiffness(cx: &Ctx<'_>, w: &str, obj: &Value) -> Result<f64, SceneError> {
    obj.get("Attach Stiffness")
        .and_then(|s| s.as_f64())
        .ok_or_else(|| cx.invalid(format!("{w}: \"Attach Verts\" needs \"Attach Stiffness\"")))
}

/// Notes an `"Attach Stiffness"` of `obj` (at `w`) given without `"Attach Verts"`.
fn note_lone_stiffness(cx: &mut Ctx<'_>, w: &str, obj: &Value) {
    if let Some(k) = obj.get("Attach Stiffness") {
        cx.notes.push(format!(
            "{w}: \"Attach Stiffness\" {k} without \"Attach Verts\" attaches nothing; ignored"
        ));
    }
}
