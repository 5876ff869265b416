//! Meshes given inline in a scene (`"mesh": {"vertices": ..., "tets": ...}`), and the inverse:
//! a scene whose mesh files are replaced by their arrays ([`inline_meshes`]), so that a scene
//! travels without its directory (pickling, other processes and machines) and builds the same
//! model bit for bit.

use std::collections::HashMap;
use std::path::Path;

use nalgebra::Vector3;
use serde_json::{json, Value};

use super::format::{TetArrays, TriArrays};
use super::SceneError;
use crate::mesh::{self, surface::TriSurface, LoadOptions, LoadedMesh, MeshError, MeshErrorKind, MeshFormat, TetMesh};

/// A tet mesh from arrays, validated and oriented as the file readers do (`name` in messages).
pub(crate) fn tet_mesh(name: &str, a: &TetArrays) -> Result<LoadedMesh, SceneError> {
    let vertices = vertices(name, &a.vertices)?;
    let n = vertices.len();
    for (t, tet) in a.tets.iter().enumerate() {
        if let Some(&i) = tet.iter().find(|&&i| i >= n) {
            return Err(MeshError::file(
                name,
                MeshErrorKind::IndexOutOfRange {
                    tet: t,
                    index: i as i128,
                    valid: format!("0..{n}"),
                },
            )
            .into());
        }
    }
    let raw = mesh::RawMesh {
        nodes: a.vertices.clone(),
        node_ids: (0..n as i64).collect(),
        tets: a.tets.clone(),
        tet_lines: Vec::new(),
        skipped_elements: 0,
    };
    Ok(TetMesh::from_raw(
        name,
        MeshFormat::Memory,
        raw,
        LoadOptions::default(),
    )?)
}

/// A triangle surface from arrays (`name` in messages).
pub(crate) fn surface(name: &str, a: &TriArrays) -> Result<TriSurface, SceneError> {
    let vertices = vertices(name, &a.vertices)?;
    let n = vertices.len();
    if a.triangles.is_empty() {
        return Err(MeshError::file(name, MeshErrorKind::Syntax("no triangles".into())).into());
    }
    for (t, tri) in a.triangles.iter().enumerate() {
        if let Some(&i) = tri.iter().find(|&&i| i >= n) {
            return Err(MeshError::file(
                name,
                MeshErrorKind::Syntax(format!("triangle {t}: vertex index {i} out of range (0..{n})")),
            )
            .into());
        }
    }
    Ok(TriSurface {
        vertices,
        triangles: a.triangles.clone(),
    })
}

fn vertices(name: &str, v: &[[f64; 3]]) -> Result<Vec<Vector3<f64>>, SceneError> {
    if let Some(i) = v.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(MeshError::file(name, MeshErrorKind::NonFinite(format!("vertex {i}: {:?}", v[i]))).into());
    }
    Ok(v.iter().map(|p| Vector3::from(*p)).collect())
}

fn surface_json(s: &TriSurface) -> Value {
    json!({
        "vertices": s.vertices.iter().map(|v| [v.x, v.y, v.z]).collect::<Vec<_>>(),
        "triangles": s.triangles,
    })
}

/// `scene` (a `diffsoft.scene/1` document whose relative paths resolve against `dir`) with
/// every mesh file replaced by its arrays: a body's mesh as loaded (the vertices tets use, in
/// file order; tets oriented), its vertex ids (`fixed`, attachments, bones, actuator
/// selections by vertex) renumbered to match; cloth and obstacle surfaces as read. Loading the
/// result builds the same model as loading `scene` from `dir`. `shown` names the scene in
/// messages. Inline meshes are left as they are.
///
/// ```
/// use diffsoft::scene;
///
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../verification/scenes/ball_drop.json");
/// let dir = std::path::Path::new(path).parent().unwrap();
/// let mut doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path)?)?;
/// scene::inline::inline_meshes(&mut doc, dir, path)?;
/// assert!(doc["bodies"][0]["mesh"]["tets"].is_array());
/// let a = scene::load(path, Default::default())?;
/// let b = scene::from_value(doc, &dir.join("inline.json"))?;
/// assert_eq!(a.model.rest(), b.model.rest());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn inline_meshes(scene: &mut Value, dir: &Path, shown: &str) -> Result<(), SceneError> {
    let invalid = |message: String| SceneError::Invalid {
        path: shown.to_string(),
        message,
    };
    if let Some(bodies) = scene.get_mut("bodies").and_then(Value::as_array_mut) {
        for b in bodies {
            let name = b.get("name").and_then(Value::as_str).unwrap_or("?").to_string();
            let Some(file) = b.get("mesh").and_then(Value::as_str) else {
                continue;
            };
            let loaded = mesh::load(dir.join(file))?;
            let ids: HashMap<i64, usize> = loaded
                .info
                .file_ids
                .iter()
                .enumerate()
                .map(|(i, &id)| (id, i))
                .collect();
            let renumber = |v: &mut Value, what: &str| -> Result<(), SceneError> {
                let Some(list) = v.as_array_mut() else { return Ok(()) };
                for x in list {
                    let Some(id) = x.as_i64() else { continue };
                    let i = ids.get(&id).ok_or_else(|| {
                        invalid(format!(
                            "body '{name}', {what}: vertex {id} is not a vertex of any tet of {}",
                            loaded.info.path
                        ))
                    })?;
                    *x = json!(i);
                }
                Ok(())
            };
            if let Some(v) = b.pointer_mut("/fixed/indices") {
                renumber(v, "fixed")?;
            }
            if let Some(list) = b.get_mut("attachments").and_then(Value::as_array_mut) {
                for a in list {
                    if let Some(v) = a.pointer_mut("/vertices/indices") {
                        renumber(v, "attachments")?;
                    }
                }
            }
            if let Some(list) = b.pointer_mut("/skeleton/bones").and_then(Value::as_array_mut) {
                for bone in list {
                    if let Some(v) = bone.pointer_mut("/vertices/indices") {
                        renumber(v, "bone vertices")?;
                    }
                }
            }
            if let Some(list) = b.get_mut("actuators").and_then(Value::as_array_mut) {
                for a in list {
                    for p in ["/pneumatic/tets/vertices/indices", "/muscle/tets/vertices/indices"] {
                        if let Some(v) = a.pointer_mut(p) {
                            renumber(v, "actuator tets")?;
                        }
                    }
                }
            }
            let m = &loaded.mesh;
            b["mesh"] = json!({
                "vertices": m.vertices.iter().map(|v| [v.x, v.y, v.z]).collect::<Vec<_>>(),
                "tets": m.tets,
            });
        }
    }
    if let Some(cloths) = scene.get_mut("cloths").and_then(Value::as_array_mut) {
        for c in cloths {
            if let Some(file) = c.get("mesh").and_then(Value::as_str) {
                let s = mesh::surface::load_obj(dir.join(file))?;
                c["mesh"] = surface_json(&s);
            }
        }
    }
    if let Some(obstacles) = scene.get_mut("obstacles").and_then(Value::as_array_mut) {
        for o in obstacles {
            if let Some(file) = o.pointer("/mesh/file").and_then(Value::as_str) {
                let s = mesh::surface::load_obj(dir.join(file))?;
                o["mesh"]["file"] = surface_json(&s);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    /// An index past `i64::MAX` is quoted as written, not wrapped to a negative number.
    #[test]
    fn a_huge_index_is_quoted_as_written() {
        let a = super::TetArrays {
            vertices: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            tets: vec![[0, 1, 2, usize::MAX]],
        };
        let e = super::tet_mesh("box", &a).unwrap_err().to_string();
        assert!(
            e.contains(&format!("tet 0: vertex index {} out of range (0..4)", usize::MAX)),
            "{e}"
        );
    }
}
