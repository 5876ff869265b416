//! Frictional contact with static obstacles (docs/method.md section 4, Eqs. 19-21 and C1-C2,
//! after Ly et al. 2020).
//!
//! A [`Contact`] linearises one vertex's non-penetration constraint as a half-space
//! `n . (x - c) >= 0` around the closest obstacle point `c` (offset by the obstacle's thickness)
//! and remembers the vertex's position at the start of the step (its anchor: sticking means no
//! tangential displacement during the step). [`project`] is the per-vertex Coulomb cone
//! projection used inside every global solver: given the vertex's free update `x_hat` and its
//! diagonal weight `w` (the vertex moves as `x = x_hat + lambda / w` under a contact impulse
//! `lambda`), it returns the impulse that
//!
//! * is zero when `x_hat` already separates;
//! * otherwise has a normal part `lambda_N >= 0` that puts the vertex on the plane, and a
//!   tangential part that sticks (`x_T = anchor_T`) when `|lambda_T| <= mu lambda_N`, or slides
//!   on the cone boundary against the slip direction (maximal dissipation) otherwise.

mod obstacle;
pub mod pair;
mod plane;
mod shape;
mod trimesh;

pub use obstacle::Obstacle;
pub use plane::Plane;
pub use shape::Shape;
pub use trimesh::TriMeshObstacle;

use nalgebra::Vector3;
use serde::Serialize;

/// One vertex in (possible) contact with one obstacle during one step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Contact {
    /// Vertex (global numbering).
    pub vertex: usize,
    /// Obstacle index.
    pub obstacle: usize,
    /// Unit normal of the half-space.
    pub normal: Vector3<f64>,
    /// A point of the (thickness-offset) plane.
    pub point: Vector3<f64>,
    /// The vertex's position at the start of the step.
    pub anchor: Vector3<f64>,
    /// Friction coefficient.
    pub friction: f64,
}

/// The state a contact ended in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactState {
    /// No impulse (moving away).
    Separate,
    /// Inside the friction cone.
    Stick,
    /// On the cone boundary.
    Slide,
}

/// Coulomb cone projection: the impulse `lambda` such that `x = x_hat + lambda / w` obeys the
/// contact (see the module docs).
#[inline]
pub fn project(x_hat: &Vector3<f64>, w: f64, c: &Contact) -> (Vector3<f64>, ContactState) {
    let gap = c.normal.dot(&(x_hat - c.point));
    if gap >= 0.0 {
        return (Vector3::zeros(), ContactState::Separate);
    }
    let lambda_n = -w * gap;
    let rel = x_hat - c.anchor;
    let tangential = rel - c.normal * c.normal.dot(&rel);
    let stick = -w * tangential;
    let stick_norm = stick.norm();
    if stick_norm <= c.friction * lambda_n {
        (c.normal * lambda_n + stick, ContactState::Stick)
    } else {
        (
            c.normal * lambda_n + stick * (c.friction * lambda_n / stick_norm),
            ContactState::Slide,
        )
    }
}

/// Candidate contacts for a step: every free vertex whose start position `q` or predicted
/// position `pred` is within `margin` of an obstacle, or whose path crosses one.
///
/// ```
/// use diffsoft::contact::{detect, Obstacle};
/// use nalgebra::Vector3;
///
/// let ground = [Obstacle::plane("ground", Vector3::zeros(), Vector3::y(), 0.5)];
/// let q = [Vector3::new(0.0, 0.01, 0.0), Vector3::new(1.0, 0.01, 0.0), Vector3::new(2.0, 5.0, 0.0)];
/// let pred = [Vector3::new(0.0, -0.01, 0.0), Vector3::new(1.0, -0.01, 0.0), Vector3::new(2.0, 4.9, 0.0)];
/// let mut contacts = Vec::new();
/// // Vertex 1 is fixed, vertex 2 far away: only vertex 0 is a candidate.
/// detect(&ground, &[false, true, false], &q, &pred, 1e-3, &mut contacts);
/// assert_eq!(contacts.len(), 1);
/// assert_eq!((contacts[0].vertex, contacts[0].friction), (0, 0.5));
/// assert_eq!(contacts[0].anchor, q[0]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn detect(
    obstacles: &[Obstacle],
    fixed: &[bool],
    q: &[Vector3<f64>],
    pred: &[Vector3<f64>],
    margin: f64,
    out: &mut Vec<Contact>,
) {
    out.clear();
    for (i, (a, b)) in q.iter().zip(pred).enumerate() {
        if fixed[i] {
            continue;
        }
        let m = margin.max((b - a).norm());
        for (k, o) in obstacles.iter().enumerate() {
            if let Some((_, normal, point)) = o.query(a, b, m) {
                out.push(Contact {
                    vertex: i,
                    obstacle: k,
                    normal,
                    point,
                    anchor: *a,
                    friction: o.friction,
                });
                break;
            }
        }
    }
}

/// Deepest penetration (`<= 0` means none) over all vertices, and the vertex where it occurs.
pub fn max_penetration(obstacles: &[Obstacle], q_start: &[Vector3<f64>], q: &[Vector3<f64>]) -> (f64, Option<usize>) {
    let mut worst = (0.0, None);
    for (i, (a, x)) in q_start.iter().zip(q).enumerate() {
        for o in obstacles {
            if let Some((d, _, _)) = o.query(a, x, 0.0) {
                if -d > worst.0 {
                    worst = (-d, Some(i));
                }
            }
        }
    }
    worst
}

/// The deepest vertex of `q` inside an obstacle: below a one-sided obstacle's surface (a
/// half-space such as the ground) or inside a closed triangle mesh ([`Shape::inside_depth`]),
/// the obstacle's contact thickness not counted: `(depth, vertex, obstacle)`, or `None` when no
/// vertex is deeper than `tolerance`. An open surface has no inside; a body through one is
/// found by [`initial_crossing`].
pub fn initial_penetration(obstacles: &[Obstacle], q: &[Vector3<f64>], tolerance: f64) -> Option<(f64, usize, usize)> {
    let mut worst: Option<(f64, usize, usize)> = None;
    for (k, o) in obstacles.iter().enumerate() {
        for (i, x) in q.iter().enumerate() {
            let depth = if o.shape.two_sided() {
                // Inside a closed surface (its thickness not counted either).
                o.shape.inside_depth(x).unwrap_or(f64::NEG_INFINITY)
            } else {
                o.query(x, x, 0.0)
                    .map_or(f64::NEG_INFINITY, |(d, _, _)| -(d + o.thickness))
            };
            if depth > tolerance && worst.is_none_or(|w| depth > w.0) {
                worst = Some((depth, i, k));
            }
        }
    }
    worst
}

/// The tet edge that passes deepest through a two-sided obstacle (a surface: a triangle mesh)
/// at positions `q`, beyond `tolerance` plus the obstacle's thickness: `(depth, edge, obstacle
/// index)`, the depth being the smaller of the edge ends' distances to the surface.
pub fn initial_crossing(
    obstacles: &[Obstacle],
    tets: &[[usize; 4]],
    q: &[Vector3<f64>],
    tolerance: f64,
) -> Option<(f64, [usize; 2], usize)> {
    const EDGES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];
    let mut worst: Option<(f64, [usize; 2], usize)> = None;
    for (k, o) in obstacles.iter().enumerate().filter(|(_, o)| o.shape.two_sided()) {
        for t in tets {
            for (i, j) in EDGES {
                let (a, b) = (t[i], t[j]);
                if let Some(depth) = o.shape.passes_through(&q[a], &q[b]) {
                    if depth > o.thickness + tolerance && worst.is_none_or(|w| depth > w.0) {
                        worst = Some((depth, [a, b], k));
                    }
                }
            }
        }
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ground(mu: f64) -> Contact {
        Contact {
            vertex: 0,
            obstacle: 0,
            normal: Vector3::y(),
            point: Vector3::zeros(),
            anchor: Vector3::new(0.0, 0.1, 0.0),
            friction: mu,
        }
    }

    #[test]
    fn separating_vertex_gets_no_impulse() {
        let (l, s) = project(&Vector3::new(1.0, 0.05, 0.0), 3.0, &ground(0.5));
        assert_eq!((l, s), (Vector3::zeros(), ContactState::Separate));
    }

    #[test]
    fn sticks_inside_the_cone_and_slides_outside() {
        let w = 2.0;
        // Penetrates by 0.1 and drifts 0.02 sideways: |lambda_T| = 0.04 <= 0.5 * 0.2.
        let x_hat = Vector3::new(0.02, -0.1, 0.0);
        let (l, s) = project(&x_hat, w, &ground(0.5));
        assert_eq!(s, ContactState::Stick);
        let x = x_hat + l / w;
        assert!((x - Vector3::new(0.0, 0.0, 0.0)).norm() < 1e-15, "{x}");
        // Drifts 1.0 sideways: slides, with |lambda_T| = mu lambda_N against the drift.
        let x_hat = Vector3::new(1.0, -0.1, 0.0);
        let (l, s) = project(&x_hat, w, &ground(0.5));
        assert_eq!(s, ContactState::Slide);
        assert!((l.x + 0.5 * l.y).abs() < 1e-15 && l.y > 0.0);
        let x = x_hat + l / w;
        assert!(x.y.abs() < 1e-15 && x.x > 0.0 && x.x < 1.0);
    }
}
