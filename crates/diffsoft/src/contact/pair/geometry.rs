//! The pair primitives: which features of a vertex-face or edge-edge pair are closest
//! ([`Regime`]), the pair's coefficients and normal within a regime ([`geometry`], generic for
//! dual numbers), closest features and distances ([`vertex_face`], [`edge_edge`]) and the
//! segment-triangle crossing test ([`segment_crosses`]).

use nalgebra::{RealField, Vector3};
use serde::Serialize;

/// Which features of a pair are closest (fixed for a step; the pair's geometry is smooth in
/// the start positions within it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Regime {
    /// A vertex and the interior of a face; the normal is the face normal times the sign.
    Face(i8),
    /// A vertex and an edge of a face (corners `k`, `(k + 1) % 3`).
    Edge(u8),
    /// A vertex and a corner of a face.
    Corner(u8),
    /// Two edges, closest points interior to both.
    EdgeEdge,
}

/// Coefficients and unit normal of a pair in a regime (generic, for dual numbers).
pub fn geometry<T: RealField + Copy>(regime: Regime, x: &[Vector3<T>; 4]) -> ([T; 4], Vector3<T>) {
    let one = T::one();
    let zero = T::zero();
    match regime {
        Regime::Face(sign) => {
            let (p, a, b, c) = (x[0], x[1], x[2], x[3]);
            let (e0, e1) = (b - a, c - a);
            let nf = e0.cross(&e1);
            let n = nf / nf.norm() * T::from_f64(sign as f64).unwrap();
            let ap = p - a;
            let (d00, d01, d11) = (e0.dot(&e0), e0.dot(&e1), e1.dot(&e1));
            let (d20, d21) = (ap.dot(&e0), ap.dot(&e1));
            let den = d00 * d11 - d01 * d01;
            let v = (d11 * d20 - d01 * d21) / den;
            let w = (d00 * d21 - d01 * d20) / den;
            let u = one - v - w;
            ([one, -u, -v, -w], n)
        }
        Regime::Edge(k) => {
            let (k, l) = (k as usize, (k as usize + 1) % 3);
            let (a, b) = (x[1 + k], x[1 + l]);
            let e = b - a;
            let t = (x[0] - a).dot(&e) / e.dot(&e);
            let r = x[0] - (a + e * t);
            let mut c = [one, zero, zero, zero];
            c[1 + k] = -(one - t);
            c[1 + l] = -t;
            (c, r / r.norm())
        }
        Regime::Corner(k) => {
            let r = x[0] - x[1 + k as usize];
            let mut c = [one, zero, zero, zero];
            c[1 + k as usize] = -one;
            (c, r / r.norm())
        }
        Regime::EdgeEdge => {
            let (a, b, c, d) = (x[0], x[1], x[2], x[3]);
            let (d1, d2, r) = (b - a, d - c, a - c);
            let (a11, a22, a12) = (d1.dot(&d1), d2.dot(&d2), d1.dot(&d2));
            let (e1, e2) = (d1.dot(&r), d2.dot(&r));
            let den = a11 * a22 - a12 * a12;
            let s = (a12 * e2 - a22 * e1) / den;
            let t = (a11 * e2 - a12 * e1) / den;
            let gap = (a + d1 * s) - (c + d2 * t);
            ([one - s, s, -(one - t), -t], gap / gap.norm())
        }
    }
}

/// The closest features of vertex `p` and face `abc` (Ericson 5.1.5) and the distance.
pub fn vertex_face(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>) -> Option<(Regime, f64)> {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return Some((Regime::Corner(0), ap.norm()));
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return Some((Regime::Corner(1), bp.norm()));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return Some((Regime::Edge(0), (p - (a + ab * v)).norm()));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return Some((Regime::Corner(2), cp.norm()));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return Some((Regime::Edge(2), (p - (a + ac * w)).norm()));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return Some((Regime::Edge(1), (p - (b + (c - b) * w)).norm()));
    }
    let nf = ab.cross(&ac);
    let len = nf.norm();
    if len == 0.0 {
        return None;
    }
    let s = nf.dot(&ap) / len;
    Some((Regime::Face(if s >= 0.0 { 1 } else { -1 }), s.abs()))
}

/// Parameters `(s, t)` of the closest points `a + s (b - a)` and `c + t (d - c)` of the lines
/// through `ab` and `cd` (`None` when they are parallel or not finite).
pub(crate) fn line_parameters(
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
    d: &Vector3<f64>,
) -> Option<(f64, f64)> {
    let (d1, d2, r) = (b - a, d - c, a - c);
    let (a11, a22, a12) = (d1.dot(&d1), d2.dot(&d2), d1.dot(&d2));
    let den = a11 * a22 - a12 * a12;
    if den.is_nan() || den <= 1e-12 * a11 * a22 {
        return None;
    }
    let (e1, e2) = (d1.dot(&r), d2.dot(&r));
    Some(((a12 * e2 - a22 * e1) / den, (a11 * e2 - a12 * e1) / den))
}

/// Closest points of segments `ab` and `cd` when they are interior to both (parameters in
/// `(eps, 1 - eps)`) and the segments are not parallel: `(s, t, distance)`.
pub fn edge_edge(a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>, d: &Vector3<f64>) -> Option<(f64, f64, f64)> {
    let (s, t) = line_parameters(a, b, c, d)?;
    let (d1, d2) = (b - a, d - c);
    const EPS: f64 = 1e-6;
    if !(EPS..=1.0 - EPS).contains(&s) || !(EPS..=1.0 - EPS).contains(&t) {
        return None;
    }
    Some((s, t, ((a + d1 * s) - (c + d2 * t)).norm()))
}

/// Segment `ab` crosses triangle `t` (Moller-Trumbore on the segment).
pub fn segment_crosses(a: &Vector3<f64>, b: &Vector3<f64>, t: [&Vector3<f64>; 3]) -> bool {
    let d = b - a;
    let e1 = t[1] - t[0];
    let e2 = t[2] - t[0];
    let p = d.cross(&e2);
    let det = e1.dot(&p);
    if det.abs() < 1e-300 {
        return false;
    }
    let inv = 1.0 / det;
    let s = a - t[0];
    let u = s.dot(&p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let qv = s.cross(&e1);
    let v = d.dot(&qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    let tt = e2.dot(&qv) * inv;
    (0.0..=1.0).contains(&tt)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_face_regimes_and_geometry_agree() {
        let a = Vector3::new(0.0, 0.0, 0.0);
        let b = Vector3::new(1.0, 0.0, 0.0);
        let c = Vector3::new(0.0, 1.0, 0.0);
        for (p, expect, dist) in [
            (Vector3::new(0.2, 0.3, 0.5), Regime::Face(1), 0.5),
            (Vector3::new(0.2, 0.3, -0.4), Regime::Face(-1), 0.4),
            (Vector3::new(0.5, -1.0, 0.0), Regime::Edge(0), 1.0),
            (Vector3::new(-1.0, -1.0, 0.0), Regime::Corner(0), 2f64.sqrt()),
            (Vector3::new(1.0, 1.0, 0.0), Regime::Edge(1), 0.5f64.sqrt()),
        ] {
            let (r, d) = vertex_face(&p, &a, &b, &c).unwrap();
            assert_eq!(r, expect, "{p}");
            assert!((d - dist).abs() < 1e-12);
            let (coefs, n) = geometry(r, &[p, a, b, c]);
            let rel = p * coefs[0] + a * coefs[1] + b * coefs[2] + c * coefs[3];
            assert!((n.dot(&rel) - d).abs() < 1e-12, "{r:?}");
            assert!((rel - n * d).norm() < 1e-12, "{r:?}: relative vector along the normal");
        }
    }

    #[test]
    fn segment_crossing() {
        let t = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
        ];
        let tr = [&t[0], &t[1], &t[2]];
        assert!(segment_crosses(
            &Vector3::new(0.2, 0.2, -1.0),
            &Vector3::new(0.2, 0.2, 1.0),
            tr
        ));
        assert!(!segment_crosses(
            &Vector3::new(0.2, 0.2, 0.1),
            &Vector3::new(0.2, 0.2, 1.0),
            tr
        ));
        assert!(!segment_crosses(
            &Vector3::new(0.8, 0.8, -1.0),
            &Vector3::new(0.8, 0.8, 1.0),
            tr
        ));
    }
}
