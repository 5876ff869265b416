//! A paper scene's `"Meshes"` entry as a soft body: its tet mesh at `"Scale"`, `"Mass"` lumped
//! by volume, its material, gravity, attachments, bones and actuators, named apart from the
//! bodies and actuators before it.

use serde_json::Value;

use super::actuators::{paper_muscles, paper_pneumatic};
use super::attach::body_attachments;
use super::bones::paper_bones;
use super::context::Ctx;
use super::keys::{MESH_IGNORED, MESH_UNSUPPORTED, MESH_USED};
use super::naming::Names;
use super::{read, settings};
use crate::base::Material;
use crate::mesh::MeshInfo;
use crate::model::{BodySpec, MassSpec};
use crate::scene::SceneError;

/// `"Meshes"[k]` (`mj`) as a body, with its mesh's loading details; `names` holds the names of
/// the bodies and actuators of the meshes before it.
pub(super) fn paper_body(
    cx: &mut Ctx<'_>,
    names: &mut Names,
    k: usize,
    mj: &Value,
) -> Result<(BodySpec, MeshInfo), SceneError> {
    let w = format!("Meshes[{k}]");
    cx.check_keys(&w, mj, MESH_USED, MESH_IGNORED, MESH_UNSUPPORTED)?;
    let file = mj
        .get("Obj filename")
        .and_then(|f| f.as_str())
        .ok_or_else(|| cx.invalid(format!("{w}: \"Obj filename\" is required")))?;
    let loaded = read::tet_mesh(cx, file)?;
    let scale = settings::scale(cx, mj, 0.05, &w)?;
    if mj.get("Scale").is_none() {
        cx.notes
            .push(format!("{w}: no \"Scale\": the reference's default 0.05 applied"));
    }
    if !cx.flag(mj, "Is Mass Same", true, &w)? {
        return Err(cx.invalid(format!(
            "{w}: \"Is Mass Same\": false (uniform vertex masses) is not supported"
        )));
    }
    let total = settings::total_mass(cx, mj, &w)?;
    let material = Material {
        youngs_modulus: cx.number(mj, "Youngs Modulus", 2e5, &w)?,
        poisson_ratio: cx.number(mj, "Poisson Ratio", 0.4, &w)?,
    };
    crate::scene::scaled_size(&w, scale, &loaded.mesh.vertices).map_err(|m| cx.invalid(m))?;
    let m = loaded.mesh.scaled(scale);
    let name = names.body(&mut cx.notes, &w, k, file);
    let mut spec = BodySpec::new(&name, m, material, MassSpec::Total(total));
    spec.gravity = cx.number(mj, "Enable Gravity", 1.0, &w)? != 0.0;
    body_attachments(cx, &w, &name, mj, &loaded.mesh, &loaded.info, &mut spec)?;
    if let Some(bones) = mj.get("Bones") {
        let (list, notes) = paper_bones(cx, &w, bones, &loaded.mesh, &loaded.info)?;
        spec.bones = list;
        cx.notes.extend(notes);
        if !spec.bones.is_empty() {
            cx.notes.push(format!(
                "{w}: {} bones; joint positions are used as given (the reference does not scale them)",
                spec.bones.len()
            ));
        }
    }
    let stiffness = cx.number(mj, "Muscle Stiffness", 5e5, &w)?;
    if let Some(groups) = mj.get("Volume Verts") {
        spec.actuators = paper_pneumatic(cx, &w, groups, &spec.mesh, &loaded.info, stiffness)?;
    }
    if let Some(file) = mj.get("Muscle filename") {
        let file = file
            .as_str()
            .ok_or_else(|| cx.invalid(format!("{w}: \"Muscle filename\" must be a file name")))?;
        let muscle_file = cx.resolve(file)?;
        let muscles = paper_muscles(cx, &w, &muscle_file, &spec.mesh, scale, stiffness)?;
        spec.actuators.extend(muscles);
    }
    names.actuators(&mut cx.notes, &w, &name, &mut spec.actuators);
    Ok((spec, loaded.info))
}
