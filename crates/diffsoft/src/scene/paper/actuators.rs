//! The actuators a paper scene's mesh declares: `"Volume Verts"` lists as pneumatic groups and
//! a `"Muscle filename"` file (lines `muscle sample x y z`) as muscle groups (see the parent
//! module's documentation for how each maps to diffsoft's actuators).

use nalgebra::Vector3;
use serde_json::Value;

use super::context::Ctx;
use super::files::FileSource;
use super::read;
use crate::scene::SceneError;

/// The paper's "Volume Verts" groups as pneumatic groups (see the module docs).
pub(super) fn paper_pneumatic(
    cx: &mut Ctx<'_>,
    w: &str,
    groups: &Value,
    mesh: &crate::mesh::TetMesh,
    info: &crate::mesh::MeshInfo,
    stiffness: f64,
) -> Result<Vec<crate::actuator::ActuatorSpec>, SceneError> {
    use crate::actuator::{tets_of_vertices, ActuatorSpec};
    use crate::base::Schedule;
    let list = groups
        .as_array()
        .ok_or_else(|| cx.invalid(format!("{w}: \"Volume Verts\" must be a list of vertex lists")))?;
    let mut out = Vec::new();
    for (k, g) in list.iter().enumerate() {
        let ids: Vec<usize> = g
            .as_array()
            .and_then(|a| {
                a.iter()
                    .map(|x| x.as_u64().map(|u| u as usize))
                    .collect::<Option<Vec<_>>>()
            })
            .ok_or_else(|| cx.invalid(format!("{w}: \"Volume Verts\"[{k}] must be a list of vertex indices")))?;
        let verts = crate::scene::select(
            &cx.shown(),
            &format!("{w} Volume Verts[{k}]"),
            &crate::scene::format::VertexSelector::Indices(ids),
            mesh,
            info,
        )?;
        let tets = tets_of_vertices(mesh, &verts, 2);
        if tets.is_empty() {
            return Err(cx.invalid(format!("{w}: \"Volume Verts\"[{k}]: no tet has two of these vertices")));
        }
        out.push(ActuatorSpec::pneumatic(
            &format!("pneumatic{k}"),
            &tets,
            stiffness,
            Schedule::constant(1.0),
        ));
    }
    let counts: Vec<String> = out.iter().map(|a| a.cells.len().to_string()).collect();
    cx.notes.push(format!(
        "{w}: \"Volume Verts\": {} pneumatic groups pneumatic0..{} on the tets with at least two listed vertices ({} tets), stiffness {stiffness:e}, activation 1 until set (the reference uses edge-length actuators along each list instead)",
        out.len(),
        out.len().saturating_sub(1),
        counts.join(", ")
    ));
    Ok(out)
}

/// The paper's muscle file `src` (`muscle sample x y z` per line, mesh units) as muscle groups.
pub(super) fn paper_muscles(
    cx: &mut Ctx<'_>,
    w: &str,
    src: &FileSource<'_>,
    mesh: &crate::mesh::TetMesh,
    scale: f64,
    stiffness: f64,
) -> Result<Vec<crate::actuator::ActuatorSpec>, SceneError> {
    use crate::actuator::{nearest_segments, ActuatorSpec};
    use crate::base::Schedule;
    let shown = src.shown();
    let text = read::text(src)?;
    // Per muscle: (sample number, point, line number) in file order.
    let mut samples: std::collections::BTreeMap<i64, Vec<(i64, Vector3<f64>, usize)>> = Default::default();
    for (n, line) in text.lines().enumerate() {
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.is_empty() {
            continue;
        }
        let bad = || SceneError::Invalid {
            path: shown.clone(),
            message: format!("line {}: expected `muscle sample x y z`, got {line:?}", n + 1),
        };
        if fields.len() != 5 {
            return Err(bad());
        }
        let id: i64 = fields[0].parse().map_err(|_| bad())?;
        let sample: i64 = fields[1].parse().map_err(|_| bad())?;
        if id < 0 || sample < 0 {
            return Err(SceneError::Invalid {
                path: shown.clone(),
                message: format!(
                    "line {}: muscle and sample numbers count from 0, got {id} and {sample}",
                    n + 1
                ),
            });
        }
        let mut p = [0.0; 3];
        for (k, f) in fields[2..].iter().enumerate() {
            p[k] = f.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(bad)?;
        }
        samples
            .entry(id)
            .or_default()
            .push((sample, Vector3::from(p) * scale, n + 1));
    }
    // The sample numbers order each muscle's polyline: one given twice leaves its order open.
    for (id, line) in samples.iter_mut() {
        line.sort_by_key(|s| (s.0, s.2));
        if let Some(w) = line.windows(2).find(|w| w[0].0 == w[1].0) {
            return Err(SceneError::Invalid {
                path: shown.clone(),
                message: format!(
                    "line {}: muscle {id} sample {} was already given on line {}",
                    w[1].2, w[1].0, w[0].2
                ),
            });
        }
    }
    if samples.is_empty() {
        return Err(SceneError::Invalid {
            path: shown,
            message: "no muscle samples".into(),
        });
    }
    let edges: Vec<f64> = mesh
        .tets
        .iter()
        .flat_map(|t| {
            [
                (t[0], t[1]),
                (t[0], t[2]),
                (t[0], t[3]),
                (t[1], t[2]),
                (t[1], t[3]),
                (t[2], t[3]),
            ]
        })
        .map(|(a, b)| (mesh.vertices[a] - mesh.vertices[b]).norm())
        .collect();
    let radius = 0.5 * edges.iter().sum::<f64>() / edges.len().max(1) as f64;
    // Nearest muscle (and segment) of every tet.
    let mut best: Vec<(f64, usize, Vector3<f64>)> = vec![(f64::INFINITY, 0, Vector3::zeros()); mesh.num_tets()];
    let ids: Vec<i64> = samples.keys().copied().collect();
    for (k, id) in ids.iter().enumerate() {
        let pts: Vec<Vector3<f64>> = samples[id].iter().map(|s| s.1).collect();
        let near = nearest_segments(mesh, &pts).ok_or_else(|| SceneError::Invalid {
            path: shown.clone(),
            message: format!("muscle {id} has no segment of positive length"),
        })?;
        for (t, (d, m)) in near.into_iter().enumerate() {
            if d < best[t].0 {
                best[t] = (d, k, m);
            }
        }
    }
    let mut out = Vec::new();
    for (k, id) in ids.iter().enumerate() {
        let fibres: Vec<(usize, Vector3<f64>)> = best
            .iter()
            .enumerate()
            .filter(|(_, b)| b.1 == k && b.0 <= radius)
            .map(|(t, b)| (t, b.2))
            .collect();
        if fibres.is_empty() {
            // Tets near this polyline that went to other muscles (nearer, or as near and first
            // in the file): this one's polyline restates theirs.
            let pts: Vec<Vector3<f64>> = samples[id].iter().map(|s| s.1).collect();
            let near = nearest_segments(mesh, &pts).unwrap_or_default();
            let taken: std::collections::BTreeSet<i64> = near
                .iter()
                .zip(&best)
                .filter(|((d, _), b)| *d <= radius && b.1 != k)
                .map(|(_, b)| ids[b.1])
                .collect();
            let near_any = !taken.is_empty();
            return Err(cx.invalid(if near_any {
                format!(
                    "{w}: muscle {id}: every tet within {radius:.3e} of its polyline is at least as near to muscle(s) {taken:?} (a polyline on top of another's?)"
                )
            } else {
                format!("{w}: muscle {id}: no tet centroid within {radius:.3e} of its polyline")
            }));
        }
        out.push(ActuatorSpec::muscle(
            &format!("muscle{id}"),
            fibres,
            stiffness,
            Schedule::constant(0.0),
        ));
    }
    let counts: Vec<String> = out.iter().map(|a| a.cells.len().to_string()).collect();
    cx.notes.push(format!(
        "{w}: {} muscles from {shown} (scaled by {scale}): each tet within {radius:.3e} (half the mean edge length) of a polyline joins the nearest muscle along its nearest segment ({} tets), stiffness {stiffness:e}, activation 0 until set",
        out.len(),
        counts.join(", ")
    ));
    Ok(out)
}
