//! A paper scene's `"Clothes"` entry as a cloth body (a triangle mesh, see [`crate::cloth`]).

use std::path::Path;

use serde_json::Value;

use super::attach::cloth_attachments;
use super::context::Ctx;
use super::keys::{CLOTH_IGNORED, CLOTH_USED};
use super::{read, settings};
use crate::cloth::ClothSpec;
use crate::scene::SceneError;

/// One entry of the paper's "Clothes": a triangle mesh (OBJ `f` lines) with "Area Density",
/// "Stretching", "Bending" and attachments. The parameters are used as the paper describes its
/// cloth; where the reference implementation differs, a note says how.
pub(super) fn paper_cloth(cx: &mut Ctx<'_>, k: usize, cj: &Value) -> Result<ClothSpec, SceneError> {
    let w = format!("Clothes[{k}]");
    cx.check_keys(&w, cj, CLOTH_USED, CLOTH_IGNORED, &[])?;
    let file = cj
        .get("Obj filename")
        .and_then(|f| f.as_str())
        .ok_or_else(|| cx.invalid(format!("{w}: \"Obj filename\" is required")))?;
    let src = cx.resolve(file)?;
    let scale = settings::scale(cx, cj, 1.0, &w)?;
    if cj.get("Scale").is_none() {
        cx.notes.push(format!(
            "{w}: no \"Scale\": scale 1 (the reference's default for cloth is 0.05, which would shrink {file} to a twentieth of the scene it is modelled in)"
        ));
    }
    let surface = read::surface(&src)?;
    crate::scene::scaled_size(&w, scale, &surface.vertices).map_err(|m| cx.invalid(m))?;
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
    let mut spec = ClothSpec::new(&name, surface, stretching, bending, area_density);
    spec.source = src.shown();
    cloth_attachments(cx, &w, file, cj, &mut spec)?;
    Ok(spec)
}
