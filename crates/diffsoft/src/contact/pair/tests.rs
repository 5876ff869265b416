//! Tests of the pair detection: closest-pair ties, the grid cell, boundary faces, the pair
//! Jacobian and the sweep through a whole step.

use super::*;

#[test]
fn of_two_pairs_at_the_same_distance_the_smaller_vertices_are_kept_in_either_order() {
    let pair = |vertices: [usize; 4], distance: f64| PairContact {
        vertices,
        coefs: [1.0, -1.0, 0.0, 0.0],
        normal: Vector3::y(),
        distance,
        regime: Regime::Edge(0),
        swept: false,
    };
    // A vertex nearest an edge is as near both faces on it.
    let (a, b) = (pair([0, 3, 4, 5], 0.25), pair([0, 4, 3, 6], 0.25));
    for order in [[a, b], [b, a]] {
        let mut best = vec![None];
        for c in order {
            keep_closest(&mut best, 0, c);
        }
        assert_eq!(best[0].map(|c| c.vertices), Some([0, 3, 4, 5]));
    }
    // A nearer pair still wins whatever its vertices.
    let mut best = vec![Some(a)];
    keep_closest(&mut best, 0, pair([0, 9, 10, 11], 0.125));
    assert_eq!(best[0].map(|c| c.vertices), Some([0, 9, 10, 11]));
}

/// Two cubes, the second moved straight down through the first within one step: with the
/// pairs linearised at the start already known (so none is a new violation), the pass
/// still finds the surfaces that went through each other, as swept pairs linearised where
/// they met, on the side they started on; with a new violation left, it hands over only
/// that.
#[test]
fn a_body_moved_through_another_within_a_step_is_found_by_the_sweep() {
    use crate::mesh::generate::BoxSpec;
    use crate::{BodySpec, MassSpec, Material, ModelBuilder};
    let m = Material {
        youngs_modulus: 1e5,
        poisson_ratio: 0.3,
    };
    let a = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build().unwrap();
    let b = BoxSpec::new([1, 1, 1], [0.06, 0.06, 0.06])
        .origin([0.013, 0.2, 0.021])
        .build()
        .unwrap();
    let model = ModelBuilder::new()
        .body(BodySpec::new("a", a, m, MassSpec::Density(1000.0)))
        .body(BodySpec::new("b", b, m, MassSpec::Density(1000.0)))
        .collisions(BodyCollision {
            thickness: 1e-3,
            friction: 0.0,
        })
        .build()
        .unwrap();
    let col = model.collision().unwrap();
    let q0 = model.rest().to_vec();
    // b (vertices 8..16) ends wholly below a: no surface crosses at the end.
    let b_moved_by = |d: Vector3<f64>| -> Vec<Vector3<f64>> {
        q0.iter()
            .enumerate()
            .map(|(i, x)| if i >= 8 { x + d } else { *x })
            .collect()
    };
    let q1 = b_moved_by(Vector3::new(0.0, -0.5, 0.0));
    let mut det = Detector::default();
    assert_eq!(det.crossing_count(col, &q1), 0);
    let violations = Query::Violations { tolerance: 0.0 };
    let mut first = Vec::new();
    det.detect(col, &q0, &q1, violations, &mut first);
    assert!(!first.is_empty() && first.iter().all(|p| !p.swept), "{first:?}");
    // Each pass hands over the next violations (the closest new pair per vertex and body);
    // once every one is known, the swept pairs, never mixed with violations.
    let mut known = first;
    let swept = loop {
        det.remember(&known, true);
        let mut next = Vec::new();
        det.detect(col, &q0, &q1, violations, &mut next);
        assert!(!next.is_empty(), "no swept pair after {} known", known.len());
        if next.iter().all(|p| p.swept) {
            break next;
        }
        assert!(next.iter().all(|p| !p.swept), "{next:?}");
        known.extend(next);
        assert!(known.len() < 1000);
    };
    // b's vertices (it is the narrower) through a's faces, each once per body.
    let through: Vec<_> = swept.iter().filter(|p| p.regime != Regime::EdgeEdge).collect();
    assert!(
        !through.is_empty() && through.iter().all(|p| p.vertices[0] >= 8),
        "{swept:?}"
    );
    for p in &swept {
        // Kept on the side it started on: the gap is positive at the start...
        assert!(p.distance > 0.0 && (p.normal.dot(&p.relative(&q0)) - p.distance).abs() < 1e-12);
        assert!(p.normal.dot(&p.relative(&q1)) < 0.0, "{p:?}: violated at the end");
        // ...and the two points it ties meet at some time of the motion.
        let x: [Vector3<f64>; 4] = std::array::from_fn(|k| q0[p.vertices[k]]);
        let y: [Vector3<f64>; 4] = std::array::from_fn(|k| q1[p.vertices[k]]);
        let hit = if p.regime == Regime::EdgeEdge {
            sweep::edge_edge(&x, &y)
        } else {
            sweep::vertex_face(&x, &y)
        }
        .unwrap();
        let at: Vec<_> = q0.iter().zip(&q1).map(|(a, b)| a + (b - a) * hit.time).collect();
        assert!(p.relative(&at).norm() < 1e-12, "{p:?}");
    }
    // Known swept pairs are not handed over again: the next pass gives the next crossings
    // (b's vertices through a's bottom after its top).
    det.remember(&known, true);
    det.remember(&swept, false);
    let mut again = Vec::new();
    det.detect(col, &q0, &q1, violations, &mut again);
    assert!(!again.is_empty() && again.iter().all(|p| p.swept), "{again:?}");
    assert!(
        again.iter().all(|p| swept.iter().all(|q| q.key() != p.key())),
        "{again:?}"
    );
    // A later round that ends elsewhere (b also slid sideways): the same vertex goes through
    // the same face at another point, so the pair is handed over again, linearised where it
    // met this time (in a step, an earlier linearisation of a turned face can hold the end
    // positions on its side while the vertex went through; the ball on the cloth at 200 m/s
    // did so).
    let q2 = b_moved_by(Vector3::new(0.02, -0.5, 0.01));
    let mut relinearised = Vec::new();
    det.detect(col, &q0, &q2, violations, &mut relinearised);
    let renewed: Vec<_> = relinearised
        .iter()
        .filter(|p| swept.iter().any(|q| q.key() == p.key()))
        .collect();
    assert!(!renewed.is_empty(), "{relinearised:?}");
    for p in renewed {
        let old = swept.iter().find(|q| q.key() == p.key()).unwrap();
        assert!(
            (0..4).any(|k| (p.coefs[k] - old.coefs[k]).abs() > 1e-6),
            "{p:?} {old:?}"
        );
        assert!(p.normal.dot(&p.relative(&q2)) < 0.0, "{p:?}: violated at the new end");
    }
}

#[test]
fn the_grid_cell_grows_only_for_boxes_of_very_different_sizes() {
    // Segments along x, each 0.1 long, in a row: about 2 x 1 x 1 entries each at the mean
    // extent, which stays the cell.
    let n = 50;
    let q: Vec<Vector3<f64>> = (0..=n).map(|i| Vector3::new(0.1 * i as f64, 0.0, 0.0)).collect();
    let items: Vec<[usize; 2]> = (0..n).map(|i| [i, i + 1]).collect();
    let mut boxes = Vec::new();
    let cell = swept_boxes(&items, &q, &q, 0.0, 0.0, &mut boxes);
    assert!((cell - 0.1).abs() < 1e-12, "cell {cell}");
    assert!(grid_entries(&boxes, cell, usize::MAX) <= ENTRIES_PER_BOX * boxes.len());
    // Many tiny boxes and a few spanning the whole region: far more than 8 entries per
    // box at the mean extent, so the cell doubles (at most twice).
    let mut q: Vec<Vector3<f64>> = (0..200).map(|i| Vector3::repeat(0.001 * i as f64)).collect();
    let mut items: Vec<[usize; 2]> = (0..199).map(|i| [i, i + 1]).collect();
    for k in 0..20 {
        let s = k as f64 * 1e-3;
        q.push(Vector3::new(-1.0 + s, -1.0, -1.0));
        q.push(Vector3::new(1.0, 1.0 - s, 1.0));
        items.push([q.len() - 2, q.len() - 1]);
    }
    let cell = swept_boxes(&items, &q, &q, 0.0, 0.0, &mut boxes);
    let mean = boxes.iter().map(|b| (b.1 - b.0).max()).sum::<f64>() / boxes.len() as f64;
    assert!(grid_entries(&boxes, mean, usize::MAX) > ENTRIES_PER_BOX * boxes.len());
    assert!(
        cell > 1.5 * mean && cell < 4.5 * mean,
        "cell {cell}, mean extent {mean}"
    );
    assert!(grid_entries(&boxes, cell, usize::MAX) < grid_entries(&boxes, mean, usize::MAX));
}

#[test]
fn boundary_of_two_tets_has_six_faces() {
    let faces = boundary_faces(&[[0, 1, 2, 3], [1, 2, 3, 4]]);
    assert_eq!(faces.len(), 6);
}

#[test]
fn pair_jacobian_matches_differences() {
    let q = vec![
        Vector3::new(0.21, 0.33, 0.45),
        Vector3::new(0.0, 0.02, -0.01),
        Vector3::new(1.0, 0.1, 0.05),
        Vector3::new(0.1, 1.1, -0.02),
        Vector3::new(0.9, 0.2, 0.4),
    ];
    for (verts, regime) in [
        ([0, 1, 2, 3], Regime::Face(1)),
        ([0, 1, 2, 3], Regime::Edge(1)),
        ([0, 1, 2, 3], Regime::Corner(2)),
        ([0, 4, 1, 3], Regime::EdgeEdge),
    ] {
        let x: [Vector3<f64>; 4] = std::array::from_fn(|k| q[verts[k]]);
        let (coefs, normal) = geometry(regime, &x);
        let c = PairContact {
            vertices: verts,
            coefs,
            normal,
            distance: 0.0,
            regime,
            swept: false,
        };
        let (dc, dn) = c.jacobian(&q);
        let h = 1e-6;
        for j in 0..4 {
            for d in 0..3 {
                let mut xp = x;
                let mut xm = x;
                xp[j][d] += h;
                xm[j][d] -= h;
                let (cp, np) = geometry(regime, &xp);
                let (cm, nm) = geometry(regime, &xm);
                for k in 0..4 {
                    assert!(((cp[k] - cm[k]) / (2.0 * h) - dc[3 * j + d][k]).abs() < 1e-7);
                }
                assert!(((np - nm) / (2.0 * h) - dn[3 * j + d]).norm() < 1e-7);
            }
        }
    }
}
