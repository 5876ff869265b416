//! Bodies that start inside each other: the check made before the first step when collisions
//! between bodies are on.
//!
//! A point of one body is inside another when it lies in one of the other's tets (barycentric
//! coordinates, a spatial hash over the tets' boxes) farther than the collision thickness from
//! its surface. The points tried are every surface vertex (soft or cloth) and every tet centroid
//! and surface triangle's centre (so that two coincident bodies, whose vertices all lie on each
//! other's surface, or a cloth through a body with its vertices on the body's surface, are
//! found too). Surfaces that cross without either holding a point of the other (two boxes crossed
//! like a plus sign, cloth through cloth) are found by their crossing edges
//! ([`super::Detector::deepest_crossing`]).

use nalgebra::{Matrix3, Vector3};

use super::geometry::vertex_face;
use super::grid::Grid;
use super::Colliders;

/// A point of one body inside another, deeper than the collision thickness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inside {
    /// Body holding the point (index into [`Colliders::names`]).
    pub body: usize,
    /// The point: a vertex (global numbering) or, for a tet's centroid, `None`.
    pub vertex: Option<usize>,
    /// Tet whose centroid it is (global numbering; `None` for a vertex).
    pub tet: Option<usize>,
    /// Body it is inside.
    pub other: usize,
    /// Distance from the point to the other body's surface (m).
    pub depth: f64,
    /// The point is the centre of a surface triangle with a corner at `vertex`.
    pub triangle: bool,
}

/// The first point (surface vertices, then tet centroids, then surface triangles' centres) of a body that lies inside
/// another soft body deeper than the collision thickness, at positions `q`. `tets` are the
/// model's tets and `tet_ranges[k]` those of soft body `k` (collider body `k`).
pub fn inside(
    col: &Colliders,
    tets: &[[usize; 4]],
    tet_ranges: &[std::ops::Range<usize>],
    q: &[Vector3<f64>],
) -> Option<Inside> {
    let thickness = col.settings.thickness;
    // Which soft body each tet belongs to, and a hash over the tets' boxes.
    let mut owner = Vec::new();
    let mut boxes = Vec::new();
    for (b, r) in tet_ranges.iter().enumerate() {
        for t in r.clone() {
            let [a, bb, c, d] = tets[t].map(|i| q[i]);
            owner.push((b, t));
            boxes.push((a.inf(&bb).inf(&c).inf(&d), a.sup(&bb).sup(&c).sup(&d)));
        }
    }
    if boxes.is_empty() {
        return None;
    }
    let mut tet_grid = Grid::default();
    tet_grid.build(col.mean_edge.max(f64::MIN_POSITIVE), &boxes);
    let mut tri_boxes = Vec::with_capacity(col.triangles.len());
    for t in &col.triangles {
        let [a, b, c] = t.map(|i| q[i]);
        tri_boxes.push((a.inf(&b).inf(&c), a.sup(&b).sup(&c)));
    }
    let mut tri_grid = Grid::default();
    tri_grid.build(col.mean_edge.max(f64::MIN_POSITIVE), &tri_boxes);

    // The body whose tet holds `p` (not `body` itself), if any.
    let holder = |p: &Vector3<f64>, body: usize, skip: &[usize]| {
        let mut found = None;
        tet_grid.query(p, p, |k| {
            let (b, t) = owner[k as usize];
            if found.is_some() || b == body || skip.contains(&b) {
                return;
            }
            if in_tet(p, &tets[t].map(|i| q[i])) {
                found = Some(b);
            }
        });
        found
    };
    // Whether `p` is within the thickness of `other`'s surface.
    let near_surface = |p: &Vector3<f64>, other: usize| {
        let pad = Vector3::repeat(thickness);
        let mut near = false;
        tri_grid.query(&(p - pad), &(p + pad), |t| {
            let t = t as usize;
            if near || col.triangle_body[t] as usize != other {
                return;
            }
            let [a, b, c] = col.triangles[t].map(|i| q[i]);
            near = vertex_face(p, &a, &b, &c).is_some_and(|(_, d)| d <= thickness);
        });
        near
    };
    let depth = |p: &Vector3<f64>, other: usize| {
        col.triangles
            .iter()
            .zip(&col.triangle_body)
            .filter(|(_, &b)| b as usize == other)
            .filter_map(|(t, _)| vertex_face(p, &q[t[0]], &q[t[1]], &q[t[2]]).map(|(_, d)| d))
            .fold(f64::INFINITY, f64::min)
    };
    let check = |p: Vector3<f64>, body: usize, vertex: Option<usize>, tet: Option<usize>| {
        let mut skip = Vec::new();
        while let Some(other) = holder(&p, body, &skip) {
            if !near_surface(&p, other) {
                return Some(Inside {
                    body,
                    vertex,
                    tet,
                    other,
                    depth: depth(&p, other),
                    triangle: false,
                });
            }
            skip.push(other);
        }
        None
    };
    for (&v, &b) in col.vertices.iter().zip(&col.vertex_body) {
        if let Some(found) = check(q[v], b as usize, Some(v), None) {
            return Some(found);
        }
    }
    for &(b, t) in &owner {
        let c = tets[t].iter().map(|&i| q[i]).sum::<Vector3<f64>>() / 4.0;
        if let Some(found) = check(c, b, None, Some(t)) {
            return Some(found);
        }
    }
    // Surface triangles' centres: a cloth through a body with its vertices on the body's
    // surface holds no vertex inside it.
    for (t, &b) in col.triangles.iter().zip(&col.triangle_body) {
        let c = t.iter().map(|&i| q[i]).sum::<Vector3<f64>>() / 3.0;
        if let Some(found) = check(c, b as usize, Some(t[0]), None) {
            return Some(Inside {
                triangle: true,
                ..found
            });
        }
    }
    None
}

/// Whether `p` lies in the tet `x` (boundary included, to a relative 1e-12).
fn in_tet(p: &Vector3<f64>, x: &[Vector3<f64>; 4]) -> bool {
    let m = Matrix3::from_columns(&[x[1] - x[0], x[2] - x[0], x[3] - x[0]]);
    let Some(inv) = m.try_inverse() else {
        return false;
    };
    let l = inv * (p - x[0]);
    let eps = 1e-12;
    l.x >= -eps && l.y >= -eps && l.z >= -eps && l.x + l.y + l.z <= 1.0 + eps
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_in_and_out_of_a_tet() {
        let x = [Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::z()];
        assert!(in_tet(&Vector3::repeat(0.1), &x));
        assert!(in_tet(&Vector3::zeros(), &x));
        assert!(!in_tet(&Vector3::repeat(0.5), &x));
        assert!(!in_tet(&Vector3::new(-0.1, 0.1, 0.1), &x));
    }
}
