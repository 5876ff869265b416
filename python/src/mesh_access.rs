//! A scene's mesh as arrays: its tets, the outward boundary triangles and each body's ranges
//! (`Scene.tets`, `Scene.surface_triangles`, `Scene.bodies`).

use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::scene_core::Scene;

/// `(rows, K)` int64 array of index rows.
pub(crate) fn index_array<'py, const K: usize>(py: Python<'py>, rows: &[[usize; K]]) -> PyResult<Bound<'py, PyAny>> {
    use numpy::PyArrayMethods;
    let flat: Vec<i64> = rows.iter().flatten().map(|&i| i as i64).collect();
    Ok(numpy::PyArray1::from_vec(py, flat).reshape([rows.len(), K])?.into_any())
}

/// `Scene.surface_triangles`: the boundary faces of the tets (faces of exactly one tet),
/// oriented outward, sorted by vertex ids (made a `(k, 3)` int64 array by [`index_array`]).
pub(crate) fn surface_triangles(s: &Scene) -> Vec<[usize; 3]> {
    use std::collections::HashMap;
    let model = &s.inner.model;
    let rest = model.rest();
    // For each face: (how many tets, the face, the vertex opposite it).
    let mut faces: HashMap<[usize; 3], (usize, [usize; 3], usize)> = HashMap::new();
    for t in model.tets() {
        for skip in 0..4 {
            let f: Vec<usize> = (0..4).filter(|&k| k != skip).map(|k| t[k]).collect();
            let face = [f[0], f[1], f[2]];
            let mut key = face;
            key.sort_unstable();
            faces.entry(key).and_modify(|e| e.0 += 1).or_insert((1, face, t[skip]));
        }
    }
    let mut out: Vec<[usize; 3]> = faces
        .into_values()
        .filter(|(count, _, _)| *count == 1)
        .map(|(_, [a, b, c], opposite)| {
            let n = (rest[b] - rest[a]).cross(&(rest[c] - rest[a]));
            if n.dot(&(rest[opposite] - rest[a])) > 0.0 {
                [a, c, b]
            } else {
                [a, b, c]
            }
        })
        .collect();
    out.sort_unstable();
    out
}

/// A body of `Scene.bodies`: name, kind, vertex range and its tet or triangle range (the key
/// `tets` or `triangles`).
pub(crate) struct BodyRow {
    name: String,
    kind: &'static str,
    vertices: (usize, usize),
    elements: (&'static str, (usize, usize)),
}

/// `Scene.bodies`: each body's name, kind (`soft`, `cloth`) and vertex range `(start, stop)`
/// (rows of the position arrays), and its tet (soft) or triangle (cloth) range; made dicts by
/// [`body_dicts`].
pub(crate) fn bodies(s: &Scene) -> Vec<BodyRow> {
    let model = &s.inner.model;
    let mut out = Vec::new();
    for b in model.bodies() {
        out.push(BodyRow {
            name: b.name.clone(),
            kind: "soft",
            vertices: (b.vertices.start, b.vertices.end),
            elements: ("tets", (b.tets.start, b.tets.end)),
        });
    }
    if let Some(c) = model.cloth() {
        for b in &c.bodies {
            out.push(BodyRow {
                name: b.name.clone(),
                kind: "cloth",
                vertices: (b.vertices.start, b.vertices.end),
                elements: ("triangles", (b.triangles.start, b.triangles.end)),
            });
        }
    }
    out
}

/// The dicts of `Scene.bodies`.
pub(crate) fn body_dicts(py: Python<'_>, rows: Vec<BodyRow>) -> PyResult<Vec<Bound<'_, PyDict>>> {
    rows.into_iter()
        .map(|r| {
            let d = PyDict::new(py);
            d.set_item("name", r.name)?;
            d.set_item("kind", r.kind)?;
            d.set_item("vertices", r.vertices)?;
            d.set_item(r.elements.0, r.elements.1)?;
            Ok(d)
        })
        .collect()
}
