//! A scene's mesh as arrays: its tets, the outward boundary triangles and each body's ranges
//! (`Scene.tets`, `Scene.surface_triangles`, `Scene.bodies`).

use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::scene_core::Scene;

/// `Scene.tets`: every tet, global vertex numbering, `(m, 4)` int64.
pub(crate) fn tets<'py>(py: Python<'py>, s: &Scene) -> PyResult<Bound<'py, PyAny>> {
    index_array(py, s.inner.model.tets())
}

/// `(rows, K)` int64 array of index rows.
pub(crate) fn index_array<'py, const K: usize>(py: Python<'py>, rows: &[[usize; K]]) -> PyResult<Bound<'py, PyAny>> {
    use numpy::PyArrayMethods;
    let flat: Vec<i64> = rows.iter().flatten().map(|&i| i as i64).collect();
    Ok(numpy::PyArray1::from_vec(py, flat).reshape([rows.len(), K])?.into_any())
}

/// `Scene.surface_triangles`: the boundary faces of the tets (faces of exactly one tet),
/// oriented outward, `(k, 3)` int64, sorted by vertex ids.
pub(crate) fn surface_triangles<'py>(py: Python<'py>, s: &Scene) -> PyResult<Bound<'py, PyAny>> {
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
    index_array(py, &out)
}

/// `Scene.bodies`: each body's name, kind (`soft`, `cloth`) and vertex range `(start, stop)`
/// (rows of the position arrays), and its tet (soft) or triangle (cloth) range.
pub(crate) fn bodies<'py>(py: Python<'py>, s: &Scene) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let model = &s.inner.model;
    let mut out = Vec::new();
    for b in model.bodies() {
        let d = PyDict::new(py);
        d.set_item("name", &b.name)?;
        d.set_item("kind", "soft")?;
        d.set_item("vertices", (b.vertices.start, b.vertices.end))?;
        d.set_item("tets", (b.tets.start, b.tets.end))?;
        out.push(d);
    }
    if let Some(c) = model.cloth() {
        for b in &c.bodies {
            let d = PyDict::new(py);
            d.set_item("name", &b.name)?;
            d.set_item("kind", "cloth")?;
            d.set_item("vertices", (b.vertices.start, b.vertices.end))?;
            d.set_item("triangles", (b.triangles.start, b.triangles.end))?;
            out.push(d);
        }
    }
    Ok(out)
}
