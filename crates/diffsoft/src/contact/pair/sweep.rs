//! Continuous collision tests of a pair moving linearly during a step (docs/method.md Eq. C6):
//! the first time at which a vertex passes through a face, or an edge through an edge.
//!
//! Four points moving linearly, `x_k(t) = x_k^0 + t (x_k^1 - x_k^0)` for `t` in `[0, 1]`, are
//! coplanar where the cubic `f(t) = (x_1 - x_0) . ((x_2 - x_0) x (x_3 - x_0))` vanishes (with
//! the vertex or first edge end as `x_0`). The roots in `[0, 1]` are bracketed between the
//! cubic's turning points and refined by bisection; a root is a crossing when the vertex lies
//! in the face (or the two edges cross) at that time. The tests are exact up to the roots'
//! precision, so a crossing that the step's end positions no longer show (a vertex that went
//! through a face and out past its edge) is found too.

use nalgebra::Vector3;

/// Relative slack of the inside tests at a root: a vertex passing exactly through the edge
/// between two faces is found in both rather than in neither.
const INSIDE_SLACK: f64 = 1e-9;

/// Bisection steps per bracket (2^-60 of the bracket: the root to double precision).
const BISECTIONS: usize = 60;

/// The coefficients `[c0, c1, c2, c3]` of the coplanarity cubic of four moving points.
fn coplanarity(x0: &[Vector3<f64>; 4], x1: &[Vector3<f64>; 4]) -> [f64; 4] {
    let (u0, v0, w0) = (x0[1] - x0[0], x0[2] - x0[0], x0[3] - x0[0]);
    let du = (x1[1] - x1[0]) - u0;
    let dv = (x1[2] - x1[0]) - v0;
    let dw = (x1[3] - x1[0]) - w0;
    let vw = v0.cross(&w0);
    let mixed = dv.cross(&w0) + v0.cross(&dw);
    let dvdw = dv.cross(&dw);
    [
        u0.dot(&vw),
        du.dot(&vw) + u0.dot(&mixed),
        du.dot(&mixed) + u0.dot(&dvdw),
        du.dot(&dvdw),
    ]
}

fn eval(c: &[f64; 4], t: f64) -> f64 {
    ((c[3] * t + c[2]) * t + c[1]) * t + c[0]
}

/// Whether the cubic `c` has opposite signs at 0 and 1: the four points end on the other side
/// of each other (a pass through and back, or a start or end exactly coplanar, is not a
/// crossing).
fn changes_side(c: &[f64; 4]) -> bool {
    let end = c[0] + c[1] + c[2] + c[3];
    c[0] * end < 0.0
}

/// The roots of the cubic `c` in `[0, 1]`, in increasing order (at most three), into `out`;
/// returns how many. A cubic that vanishes identically (points coplanar throughout) has none.
fn roots_in_unit(c: &[f64; 4], out: &mut [f64; 3]) -> usize {
    let scale = c.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if scale == 0.0 || !scale.is_finite() {
        return 0;
    }
    // Turning points: roots of 3 c3 t^2 + 2 c2 t + c1 in (0, 1).
    let mut knots = [0.0; 4];
    let mut nk = 1;
    let (qa, qb, qc) = (3.0 * c[3], 2.0 * c[2], c[1]);
    let mut turning = |t: f64| {
        if t > 0.0 && t < 1.0 {
            knots[nk] = t;
            nk += 1;
        }
    };
    if qa.abs() > 1e-14 * scale {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 {
            let s = disc.sqrt();
            // Numerically stable pair.
            let q = -0.5 * (qb + qb.signum() * s);
            if q != 0.0 {
                turning(q / qa);
                turning(qc / q);
            } else {
                turning(0.0);
            }
        }
    } else if qb.abs() > 1e-14 * scale {
        turning(-qc / qb);
    }
    let knots = &mut knots[..nk];
    knots.sort_by(f64::total_cmp);
    let mut bounds = [0.0; 5];
    bounds[..nk].copy_from_slice(knots);
    bounds[nk] = 1.0;
    let mut n = 0;
    let mut push = |t: f64, out: &mut [f64; 3]| {
        if n < 3 && (n == 0 || t > out[n - 1]) {
            out[n] = t;
            n += 1;
        }
    };
    for w in bounds[..=nk].windows(2) {
        let (mut lo, mut hi) = (w[0], w[1]);
        let (flo, fhi) = (eval(c, lo), eval(c, hi));
        if flo == 0.0 {
            push(lo, out);
            continue;
        }
        if fhi == 0.0 {
            push(hi, out);
            continue;
        }
        if flo.signum() == fhi.signum() {
            continue;
        }
        for _ in 0..BISECTIONS {
            let mid = 0.5 * (lo + hi);
            let fm = eval(c, mid);
            if fm == 0.0 {
                lo = mid;
                hi = mid;
                break;
            }
            if fm.signum() == flo.signum() {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        push(0.5 * (lo + hi), out);
    }
    n
}

fn at(x0: &[Vector3<f64>; 4], x1: &[Vector3<f64>; 4], t: f64) -> [Vector3<f64>; 4] {
    std::array::from_fn(|k| x0[k] + (x1[k] - x0[k]) * t)
}

/// Where `p` lies in triangle `abc` (coplanar with it), with [`INSIDE_SLACK`]: its barycentric
/// coordinates, clamped to the triangle.
fn in_triangle(x: &[Vector3<f64>; 4]) -> Option<[f64; 3]> {
    let (p, a, b, c) = (x[0], x[1], x[2], x[3]);
    let (e0, e1, ap) = (b - a, c - a, p - a);
    let (d00, d01, d11) = (e0.dot(&e0), e0.dot(&e1), e1.dot(&e1));
    let (d20, d21) = (ap.dot(&e0), ap.dot(&e1));
    let den = d00 * d11 - d01 * d01;
    // Degenerate (or non-finite) triangles hold no vertex.
    if den.is_nan() || den <= 0.0 {
        return None;
    }
    let v = (d11 * d20 - d01 * d21) / den;
    let w = (d00 * d21 - d01 * d20) / den;
    let s = INSIDE_SLACK;
    if !(v >= -s && w >= -s && v + w <= 1.0 + s) {
        return None;
    }
    let (v, w) = (v.max(0.0), w.max(0.0));
    let sum = (v + w).max(1.0);
    let (v, w) = (v / sum, w / sum);
    Some([1.0 - v - w, v, w])
}

/// Where coplanar segments `x0 x1` and `x2 x3` cross, with [`INSIDE_SLACK`]: the parameters
/// along each, clamped to `[0, 1]` (`None` for parallel segments: no single crossing point).
fn segments_cross(x: &[Vector3<f64>; 4]) -> Option<(f64, f64)> {
    let (s, t) = super::geometry::line_parameters(&x[0], &x[1], &x[2], &x[3])?;
    let k = INSIDE_SLACK;
    ((-k..=1.0 + k).contains(&s) && (-k..=1.0 + k).contains(&t)).then(|| (s.clamp(0.0, 1.0), t.clamp(0.0, 1.0)))
}

/// A crossing found by [`vertex_face`] or [`edge_edge`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// When, as a fraction of the motion (`[0, 1]`).
    pub time: f64,
    /// Coefficients of the relative coordinate `r = sum c_k x_k` of the two points that meet
    /// then (`[1, -u, -v, -w]`: the vertex and the face's point with barycentric coordinates
    /// `u, v, w`; `[1 - s, s, -(1 - t), -t]`: the points at `s` and `t` along the edges).
    pub coefs: [f64; 4],
    /// Unit normal of the face (or of the plane of the two edges) then, pointing to the side
    /// the vertex (the first edge) starts on.
    pub normal: Vector3<f64>,
}

/// The normal `n` turned to the side `f0` (the coplanarity cubic at the start) says.
fn oriented(n: Vector3<f64>, f0: f64) -> Option<Vector3<f64>> {
    let len = n.norm();
    (len > 0.0 && f0 != 0.0 && len.is_finite()).then(|| n * (f0.signum() / len))
}

/// The first root of the coplanarity cubic of `x0 -> x1` at which `meet` finds the crossing
/// (given the points then and the cubic's value at the start), when the points end on the
/// other side of each other.
fn first_hit(
    x0: &[Vector3<f64>; 4],
    x1: &[Vector3<f64>; 4],
    meet: impl Fn(&[Vector3<f64>; 4], f64) -> Option<([f64; 4], Vector3<f64>)>,
) -> Option<Hit> {
    let cubic = coplanarity(x0, x1);
    if !changes_side(&cubic) {
        return None;
    }
    let mut roots = [0.0; 3];
    let n = roots_in_unit(&cubic, &mut roots);
    roots[..n].iter().find_map(|&time| {
        let (coefs, normal) = meet(&at(x0, x1, time), cubic[0])?;
        Some(Hit { time, coefs, normal })
    })
}

/// The first crossing in `[0, 1]` of vertex `x[0]` through face `x[1] x[2] x[3]`, all moving
/// linearly from `x0` to `x1`, when the vertex ends on the other side of the face's plane.
pub fn vertex_face(x0: &[Vector3<f64>; 4], x1: &[Vector3<f64>; 4]) -> Option<Hit> {
    first_hit(x0, x1, |x, f0| {
        let [u, v, w] = in_triangle(x)?;
        // f = (a - p) . ((b - p) x (c - p)) = -(p - a) . ((b - a) x (c - a)).
        let normal = oriented((x[2] - x[1]).cross(&(x[3] - x[1])), -f0)?;
        Some(([1.0, -u, -v, -w], normal))
    })
}

/// The first crossing in `[0, 1]` of edge `x[0] x[1]` through edge `x[2] x[3]`, all moving
/// linearly from `x0` to `x1`, when the edges end on the other side of each other.
pub fn edge_edge(x0: &[Vector3<f64>; 4], x1: &[Vector3<f64>; 4]) -> Option<Hit> {
    first_hit(x0, x1, |x, f0| {
        let (s, t) = segments_cross(x)?;
        // f = (b - a) . ((c - a) x (d - a)) = ((b - a) x (d - c)) . (a - c): its sign at the
        // start is the side of the first edge along (b - a) x (d - c).
        let normal = oriented((x[1] - x[0]).cross(&(x[3] - x[2])), f0)?;
        Some(([1.0 - s, s, -(1.0 - t), -t], normal))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> Vector3<f64> {
        Vector3::new(x, y, z)
    }

    #[test]
    fn a_vertex_through_a_face_is_found_at_its_time_whatever_its_speed() {
        let face = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 0.0, 1.0)];
        for speed in [1e-3, 1.0, 1e3, 1e6] {
            // Starts 0.25 above, ends `speed` below: crosses at 0.25 / (0.25 + speed).
            let x0 = [v(0.2, 0.25, 0.2), face[0], face[1], face[2]];
            let x1 = [v(0.2, -speed, 0.2), face[0], face[1], face[2]];
            let hit = vertex_face(&x0, &x1).unwrap();
            let t = hit.time;
            // The vertex starts above: the normal points up whichever way the face turns.
            assert!((hit.normal - v(0.0, 1.0, 0.0)).norm() < 1e-12, "{hit:?}");
            let flipped = vertex_face(&[x0[0], x0[1], x0[3], x0[2]], &[x1[0], x1[1], x1[3], x1[2]]).unwrap();
            assert!((flipped.normal - hit.normal).norm() < 1e-12, "{flipped:?}");
            let expect = 0.25 / (0.25 + speed);
            assert!((t - expect).abs() < 1e-12 * (1.0 + expect), "{speed}: {t} vs {expect}");
        }
        // Passing beside the face, or stopping short of it: no crossing.
        let x0 = [v(1.2, 0.25, 1.2), face[0], face[1], face[2]];
        let x1 = [v(1.2, -5.0, 1.2), face[0], face[1], face[2]];
        assert_eq!(vertex_face(&x0, &x1).map(|h| h.time), None);
        let x0 = [v(0.2, 0.25, 0.2), face[0], face[1], face[2]];
        let x1 = [v(0.2, 0.01, 0.2), face[0], face[1], face[2]];
        assert_eq!(vertex_face(&x0, &x1).map(|h| h.time), None);
    }

    #[test]
    fn a_face_sweeping_over_a_still_vertex_and_a_rotating_face_are_found() {
        // The face moves up through a still vertex.
        let p = v(0.3, 0.5, 0.3);
        let f0 = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 0.0, 1.0)];
        let f1 = f0.map(|x| x + v(0.0, 2.0, 0.0));
        let t = vertex_face(&[p, f0[0], f0[1], f0[2]], &[p, f1[0], f1[1], f1[2]])
            .unwrap()
            .time;
        assert!((t - 0.25).abs() < 1e-12, "{t}");
        // A face tilting through the vertex: the cubic's root, checked by the inside test at
        // that time (the vertex is coplanar there, so the plane distance vanishes).
        // At time t the plane is y = 2 t - 3 t z: through p (z = 0.3, y = 0.5) at t = 0.5 / 1.1.
        let g1 = [v(0.0, 2.0, 0.0), v(1.0, 2.0, 0.0), v(0.0, -1.0, 1.0)];
        let x0 = [p, f0[0], f0[1], f0[2]];
        let x1 = [p, g1[0], g1[1], g1[2]];
        let t = vertex_face(&x0, &x1).unwrap().time;
        assert!((t - 0.5 / 1.1).abs() < 1e-12, "{t}");
        let x = at(&x0, &x1, t);
        let n = (x[2] - x[1]).cross(&(x[3] - x[1])).normalize();
        assert!(n.dot(&(x[0] - x[1])).abs() < 1e-12);
    }

    #[test]
    fn two_edges_passing_through_each_other_are_found_and_skew_passes_are_not() {
        // Edge along x at height 1 moving down through an edge along z at height 0.
        let x0 = [v(-1.0, 1.0, 0.0), v(1.0, 1.0, 0.0), v(0.0, 0.0, -1.0), v(0.0, 0.0, 1.0)];
        let x1 = [
            v(-1.0, -3.0, 0.0),
            v(1.0, -3.0, 0.0),
            v(0.0, 0.0, -1.0),
            v(0.0, 0.0, 1.0),
        ];
        let hit = edge_edge(&x0, &x1).unwrap();
        assert!((hit.time - 0.25).abs() < 1e-12, "{hit:?}");
        assert_eq!(hit.coefs, [0.5, 0.5, -0.5, -0.5]);
        // The first edge starts above: the normal points up.
        assert!((hit.normal - v(0.0, 1.0, 0.0)).norm() < 1e-12, "{hit:?}");
        // The same motion beside the other edge's end.
        let x0b = x0.map(|x| x + v(0.0, 0.0, 2.0));
        let x1b = x1.map(|x| x + v(0.0, 0.0, 2.0));
        let (x0b, x1b) = ([x0b[0], x0b[1], x0[2], x0[3]], [x1b[0], x1b[1], x1[2], x1[3]]);
        assert_eq!(edge_edge(&x0b, &x1b), None);
    }

    #[test]
    fn the_cubic_roots_are_found_in_order_including_three_in_the_interval() {
        // (t - 0.2)(t - 0.5)(t - 0.9) = t^3 - 1.6 t^2 + 0.73 t - 0.09.
        let c = [-0.09, 0.73, -1.6, 1.0];
        let mut r = [0.0; 3];
        assert_eq!(roots_in_unit(&c, &mut r), 3);
        for (got, want) in r.iter().zip([0.2, 0.5, 0.9]) {
            assert!((got - want).abs() < 1e-12, "{r:?}");
        }
        // No root in [0, 1]; identically zero.
        assert_eq!(roots_in_unit(&[1.0, 1.0, 1.0, 1.0], &mut r), 0);
        assert_eq!(roots_in_unit(&[0.0; 4], &mut r), 0);
    }
}
