//! A paper scene's `"Bones"`: an embedded skeleton of the mesh, one bone per entry.

use nalgebra::Vector3;
use serde_json::Value;

use super::context::{excerpt, Ctx};
use crate::scene::SceneError;

/// The paper's "Bones" list: "Parent ID" (-1 for the root), "Joint Type" ("ALL", "ROTATIONAL",
/// "PRISMATIC"), "Joint Pos", "Joint Axis", "Vertices" (file indices).
/// Also returns notes on suspicious data (joints mirrored in x against their vertices).
pub(super) fn paper_bones(
    cx: &Ctx<'_>,
    w: &str,
    bones: &Value,
    mesh: &crate::mesh::TetMesh,
    info: &crate::mesh::MeshInfo,
) -> Result<(Vec<crate::skeleton::BoneSpec>, Vec<String>), SceneError> {
    use crate::skeleton::{free::Free, prismatic::Prismatic, rotational::Rotational, BoneSpec, Joint};
    let list = bones
        .as_array()
        .ok_or_else(|| cx.invalid(format!("{w}: \"Bones\" must be a list")))?;
    let vec3 = |b: &Value, key: &str, k: usize| -> Result<Vector3<f64>, SceneError> {
        let a = b.get(key).and_then(|v| v.as_array()).filter(|a| a.len() == 3);
        let c: Option<Vec<f64>> = a.and_then(|a| a.iter().map(|x| x.as_f64()).collect());
        match c {
            Some(c) if c.iter().all(|x| x.is_finite()) => Ok(Vector3::new(c[0], c[1], c[2])),
            _ => Err(cx.invalid(format!("{w}: Bones[{k}]: \"{key}\" must be three numbers"))),
        }
    };
    let mut out = Vec::new();
    let mut notes = Vec::new();
    for (k, b) in list.iter().enumerate() {
        let keys = ["Parent ID", "Joint Type", "Joint Pos", "Joint Axis", "Vertices"];
        if let Some(obj) = b.as_object() {
            if let Some(bad) = obj.keys().find(|key| !keys.contains(&key.as_str())) {
                return Err(cx.invalid(format!("{w}: Bones[{k}]: unknown key \"{bad}\"")));
            }
        }
        let parent = match b.get("Parent ID") {
            None => return Err(cx.invalid(format!("{w}: Bones[{k}]: \"Parent ID\" is required"))),
            Some(p) => p.as_i64().ok_or_else(|| {
                cx.invalid(format!(
                    "{w}: Bones[{k}]: \"Parent ID\" must be a whole number (-1 for the root), got {}",
                    excerpt(p)
                ))
            })?,
        };
        let parent = if parent == -1 {
            None
        } else if parent >= 0 && (parent as usize) < list.len() && parent as usize != k {
            Some(parent as usize)
        } else {
            return Err(cx.invalid(format!(
                "{w}: Bones[{k}]: \"Parent ID\" {parent} does not name another bone (-1 for the root)"
            )));
        };
        let ty = b.get("Joint Type").and_then(|t| t.as_str()).unwrap_or("");
        let joint: Box<dyn Joint> = match ty {
            "ALL" => Box::new(Free::default()),
            "ROTATIONAL" => {
                let axis = vec3(b, "Joint Axis", k)?;
                if crate::base::unit_vector(axis).is_none() {
                    return Err(cx.invalid(format!("{w}: Bones[{k}]: rotational joint with a zero axis")));
                }
                let p = vec3(b, "Joint Pos", k)?;
                crate::scene::joint_position_near(&format!("{w}: Bones[{k}]"), &p, &mesh.vertices)
                    .map_err(|m| cx.invalid(m))?;
                Box::new(Rotational::new(p, axis))
            }
            "PRISMATIC" => {
                let axis = vec3(b, "Joint Axis", k)?;
                if crate::base::unit_vector(axis).is_none() {
                    return Err(cx.invalid(format!("{w}: Bones[{k}]: prismatic joint with a zero axis")));
                }
                Box::new(Prismatic::new(axis))
            }
            other => {
                return Err(cx.invalid(format!(
                    "{w}: Bones[{k}]: unknown \"Joint Type\" \"{other}\" (ALL, ROTATIONAL, PRISMATIC)"
                )))
            }
        };
        let ids: Vec<usize> = b
            .get("Vertices")
            .and_then(|v| v.as_array())
            .and_then(|a| {
                a.iter()
                    .map(|x| x.as_u64().map(|u| u as usize))
                    .collect::<Option<Vec<_>>>()
            })
            .ok_or_else(|| {
                cx.invalid(format!(
                    "{w}: Bones[{k}]: \"Vertices\" must be a list of vertex indices"
                ))
            })?;
        let vertices = crate::scene::select(
            &cx.shown(),
            &format!("{w} bone {k}"),
            &crate::scene::format::VertexSelector::Indices(ids),
            mesh,
            info,
        )?;
        if ty == "ROTATIONAL" && !vertices.is_empty() {
            // A joint on the other side (in x) of the vertices it moves: the paper's Baymax has
            // this for both hips and both shoulders. Reported, used as given.
            let c = vertices.iter().map(|&v| mesh.vertices[v]).sum::<Vector3<f64>>() / vertices.len() as f64;
            let p = vec3(b, "Joint Pos", k)?;
            let mirrored = Vector3::new(-p.x, p.y, p.z);
            if p.x * c.x < 0.0 && (mirrored - c).norm() < 0.75 * (p - c).norm() {
                notes.push(format!(
                    "{w}: Bones[{k}]: joint position ({:.4}, {:.4}, {:.4}) is on the other side in x of the {} vertices it moves (centroid x = {:.3}); used as given",
                    p.x,
                    p.y,
                    p.z,
                    vertices.len(),
                    c.x
                ));
            }
        }
        out.push(BoneSpec {
            name: format!("bone{k}"),
            parent,
            joint,
            vertices,
            torque: None,
        });
    }
    Ok((out, notes))
}
