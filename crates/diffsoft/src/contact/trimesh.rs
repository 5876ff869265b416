//! Static triangle-mesh obstacles (docs/method.md Eq. C2): an AABB tree over the triangles for closest-point and
//! segment-crossing queries. Open surfaces (a cloth used as ground) and closed ones both work:
//! a contact keeps the side of the surface the vertex was on at the start of the step, and a
//! path that crosses a triangle during the step is caught (no tunnelling through thin sheets).

use nalgebra::Vector3;

use super::Shape;
use crate::base::InputError;

#[derive(Debug, Clone, Copy)]
struct Aabb {
    lo: Vector3<f64>,
    hi: Vector3<f64>,
}

impl Aabb {
    fn empty() -> Self {
        Self {
            lo: Vector3::repeat(f64::INFINITY),
            hi: Vector3::repeat(f64::NEG_INFINITY),
        }
    }
    fn grow(&mut self, p: &Vector3<f64>) {
        self.lo = self.lo.inf(p);
        self.hi = self.hi.sup(p);
    }
    fn union(&mut self, o: &Aabb) {
        self.lo = self.lo.inf(&o.lo);
        self.hi = self.hi.sup(&o.hi);
    }
    fn distance_sq(&self, p: &Vector3<f64>) -> f64 {
        let d = (self.lo - p).sup(&(p - self.hi)).sup(&Vector3::zeros());
        d.norm_squared()
    }
    fn overlaps(&self, o: &Aabb) -> bool {
        (0..3).all(|k| self.lo[k] <= o.hi[k] && o.lo[k] <= self.hi[k])
    }
}

#[derive(Debug, Clone)]
struct Node {
    bbox: Aabb,
    /// Leaf: `(start, count)` into the triangle order; inner: children indices.
    kind: NodeKind,
}

#[derive(Debug, Clone, Copy)]
enum NodeKind {
    Leaf(usize, usize),
    Inner(usize, usize),
}

/// A static triangle mesh with an AABB tree.
#[derive(Debug, Clone)]
pub struct TriMeshObstacle {
    vertices: Vec<Vector3<f64>>,
    triangles: Vec<[usize; 3]>,
    normals: Vec<Vector3<f64>>,
    order: Vec<usize>,
    /// For a closed mesh (every edge in exactly two triangles): `1` when its triangles'
    /// normals point outwards (positive enclosed volume), `-1` when inwards; `None` when open.
    outward: Option<f64>,
    nodes: Vec<Node>,
}

/// Closest point on triangle `abc` to `p` and whether it lies strictly inside the face.
fn closest_on_triangle(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>) -> (Vector3<f64>, bool) {
    // Ericson, Real-Time Collision Detection, 5.1.5.
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (*a, false);
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (*b, false);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (a + ab * (d1 / (d1 - d3)), false);
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (*c, false);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (a + ac * (d2 / (d2 - d6)), false);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return (b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))), false);
    }
    let denom = 1.0 / (va + vb + vc);
    (a + ab * (vb * denom) + ac * (vc * denom), true)
}

/// Parameter `s in [0, 1]` where segment `p -> q` crosses triangle `abc`, if it does.
fn segment_hits_triangle(
    p: &Vector3<f64>,
    q: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> Option<f64> {
    // Moller-Trumbore on the segment.
    let dir = q - p;
    let e1 = b - a;
    let e2 = c - a;
    let h = dir.cross(&e2);
    let det = e1.dot(&h);
    if det.abs() <= 1e-300 {
        return None;
    }
    let inv = 1.0 / det;
    let s = p - a;
    let u = inv * s.dot(&h);
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = s.cross(&e1);
    let v = inv * dir.dot(&qv);
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = inv * e2.dot(&qv);
    (0.0..=1.0).contains(&t).then_some(t)
}

impl TriMeshObstacle {
    /// Build from vertices and triangles (validates indices, finiteness and non-degenerate
    /// triangles).
    ///
    /// ```
    /// use diffsoft::contact::TriMeshObstacle;
    /// use nalgebra::Vector3;
    ///
    /// let v = vec![Vector3::zeros(), Vector3::x(), Vector3::new(1.0, 0.0, 1.0), Vector3::z()];
    /// let plate = TriMeshObstacle::new(v.clone(), vec![[0, 1, 2], [0, 2, 3]])?;
    /// assert_eq!(plate.num_triangles(), 2);
    /// // A vertex moving through the plate is caught, seen from the side it came from.
    /// let (d, normal, _) = plate
    ///     .query(&Vector3::new(0.5, 0.1, 0.5), &Vector3::new(0.5, -0.1, 0.5), 0.0)
    ///     .ok_or("missed")?;
    /// assert!(d < 0.0 && normal == Vector3::y());
    /// // Refused: an index out of range, a zero-area triangle.
    /// assert!(TriMeshObstacle::new(v.clone(), vec![[0, 1, 4]]).is_err());
    /// assert!(TriMeshObstacle::new(v, vec![[0, 1, 1]]).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(vertices: Vec<Vector3<f64>>, triangles: Vec<[usize; 3]>) -> Result<Self, InputError> {
        if triangles.is_empty() {
            return Err(InputError::new("obstacle mesh has no triangles"));
        }
        if !vertices.iter().all(|v| v.iter().all(|c| c.is_finite())) {
            return Err(InputError::new("obstacle mesh has non-finite vertices"));
        }
        let mut normals = Vec::with_capacity(triangles.len());
        for (k, t) in triangles.iter().enumerate() {
            if t.iter().any(|&i| i >= vertices.len()) {
                return Err(InputError::new(format!(
                    "obstacle triangle {k} has a vertex index out of range ({} vertices)",
                    vertices.len()
                )));
            }
            let n = (vertices[t[1]] - vertices[t[0]]).cross(&(vertices[t[2]] - vertices[t[0]]));
            if n.norm() == 0.0 || n.norm().is_nan() {
                return Err(InputError::new(format!(
                    "obstacle triangle {k} is degenerate (zero area)"
                )));
            }
            normals.push(n.normalize());
        }
        let outward = closed_orientation(&vertices, &triangles);
        let mut m = Self {
            vertices,
            triangles,
            normals,
            order: Vec::new(),
            outward,
            nodes: Vec::new(),
        };
        m.order = (0..m.triangles.len()).collect();
        let n = m.order.len();
        m.build(0, n);
        Ok(m)
    }

    /// Number of triangles.
    pub fn num_triangles(&self) -> usize {
        self.triangles.len()
    }

    fn tri_box(&self, t: usize) -> Aabb {
        let mut b = Aabb::empty();
        for &i in &self.triangles[t] {
            b.grow(&self.vertices[i]);
        }
        b
    }

    fn centroid(&self, t: usize) -> Vector3<f64> {
        let [a, b, c] = self.triangles[t];
        (self.vertices[a] + self.vertices[b] + self.vertices[c]) / 3.0
    }

    /// Build the subtree over `order[start..start + count]`; returns its node index.
    fn build(&mut self, start: usize, count: usize) -> usize {
        let mut bbox = Aabb::empty();
        for k in start..start + count {
            bbox.union(&self.tri_box(self.order[k]));
        }
        let idx = self.nodes.len();
        self.nodes.push(Node {
            bbox,
            kind: NodeKind::Leaf(start, count),
        });
        if count > 4 {
            let ext = bbox.hi - bbox.lo;
            let axis = ext.imax();
            let mid = start + count / 2;
            let mut slice: Vec<usize> = self.order[start..start + count].to_vec();
            slice.select_nth_unstable_by(count / 2, |&a, &b| {
                self.centroid(a)[axis].total_cmp(&self.centroid(b)[axis])
            });
            self.order[start..start + count].copy_from_slice(&slice);
            let l = self.build(start, mid - start);
            let r = self.build(mid, start + count - mid);
            self.nodes[idx].kind = NodeKind::Inner(l, r);
        }
        idx
    }

    fn corners(&self, t: usize) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        let [a, b, c] = self.triangles[t];
        (self.vertices[a], self.vertices[b], self.vertices[c])
    }

    /// Closest triangle point within `radius` of `p`: (triangle, point, inside face).
    fn closest(&self, p: &Vector3<f64>, radius: f64) -> Option<(usize, Vector3<f64>, bool)> {
        let mut best: Option<(usize, Vector3<f64>, bool)> = None;
        let mut best_d2 = radius * radius;
        let mut stack = vec![0usize];
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n];
            if node.bbox.distance_sq(p) > best_d2 {
                continue;
            }
            match node.kind {
                NodeKind::Leaf(s, c) => {
                    for &t in &self.order[s..s + c] {
                        let (a, b, cc) = self.corners(t);
                        let (q, inside) = closest_on_triangle(p, &a, &b, &cc);
                        let d2 = (q - p).norm_squared();
                        if d2 <= best_d2 {
                            best_d2 = d2;
                            best = Some((t, q, inside));
                        }
                    }
                }
                NodeKind::Inner(l, r) => {
                    stack.push(l);
                    stack.push(r);
                }
            }
        }
        best
    }

    /// First triangle crossed by the segment `p -> q`, with the crossing parameter.
    fn first_crossing(&self, p: &Vector3<f64>, q: &Vector3<f64>) -> Option<(usize, f64)> {
        let mut seg = Aabb::empty();
        seg.grow(p);
        seg.grow(q);
        let mut best: Option<(usize, f64)> = None;
        let mut stack = vec![0usize];
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n];
            if !node.bbox.overlaps(&seg) {
                continue;
            }
            match node.kind {
                NodeKind::Leaf(s, c) => {
                    for &t in &self.order[s..s + c] {
                        let (a, b, cc) = self.corners(t);
                        if let Some(u) = segment_hits_triangle(p, q, &a, &b, &cc) {
                            if best.is_none_or(|(_, bu)| u < bu) {
                                best = Some((t, u));
                            }
                        }
                    }
                }
                NodeKind::Inner(l, r) => {
                    stack.push(l);
                    stack.push(r);
                }
            }
        }
        best
    }

    /// Contact query for a vertex moving from `from` to `x`: (signed distance, normal toward the
    /// side of `from`, surface point), or `None` when farther than `margin` without crossing.
    pub fn query(
        &self,
        from: &Vector3<f64>,
        x: &Vector3<f64>,
        margin: f64,
    ) -> Option<(f64, Vector3<f64>, Vector3<f64>)> {
        if let Some((t, _)) = self.first_crossing(from, x) {
            let (a, _, _) = self.corners(t);
            let mut n = self.normals[t];
            if n.dot(&(from - a)) < 0.0 {
                n = -n;
            }
            // The crossed triangle's plane, seen from the start side.
            let d = n.dot(&(x - a));
            return Some((d, n, x - n * d));
        }
        let (t, q, inside) = self.closest(x, margin)?;
        let mut n = self.normals[t];
        if n.dot(&(from - q)) < 0.0 || (n.dot(&(from - q)) == 0.0 && n.dot(&(x - q)) < 0.0) {
            n = -n;
        }
        if inside {
            Some((n.dot(&(x - q)), n, q))
        } else {
            let d = x - q;
            let len = d.norm();
            let dir = if len > 0.0 { d / len } else { n };
            Some((len, dir, q))
        }
    }
}

impl Shape for TriMeshObstacle {
    /// Every query answers with a face's normal (also at edges and corners), so the normal is
    /// constant within a contact.
    fn piecewise_planar(&self) -> bool {
        true
    }

    fn query(
        &self,
        from: &Vector3<f64>,
        x: &Vector3<f64>,
        margin: f64,
        thickness: f64,
    ) -> Option<(f64, Vector3<f64>, Vector3<f64>)> {
        TriMeshObstacle::query(self, from, x, margin + thickness).map(|(d, n, c)| (d - thickness, n, c + n * thickness))
    }

    fn validate(&self) -> Result<(), InputError> {
        // Validated on construction.
        Ok(())
    }

    fn two_sided(&self) -> bool {
        true
    }

    fn inside_depth(&self, p: &Vector3<f64>) -> Option<f64> {
        let sign = self.outward?;
        let (t, q, face) = self.closest(p, f64::INFINITY)?;
        // Only a closest point inside a face says on which side `p` is without ambiguity.
        (face && sign * self.normals[t].dot(&(p - q)) < 0.0).then(|| (p - q).norm())
    }

    fn passes_through(&self, a: &Vector3<f64>, b: &Vector3<f64>) -> Option<f64> {
        self.first_crossing(a, b)?;
        let distance = |p: &Vector3<f64>| self.closest(p, f64::INFINITY).map_or(0.0, |(_, q, _)| (p - q).norm());
        Some(distance(a).min(distance(b)))
    }

    fn kind(&self) -> &'static str {
        "triangle mesh"
    }
}

/// The orientation of a closed triangle mesh (see `TriMeshObstacle::outward`).
fn closed_orientation(vertices: &[Vector3<f64>], triangles: &[[usize; 3]]) -> Option<f64> {
    let mut edges = std::collections::HashMap::with_capacity(3 * triangles.len());
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0usize) += 1;
        }
    }
    if edges.values().any(|&c| c != 2) {
        return None;
    }
    let volume: f64 = triangles
        .iter()
        .map(|t| vertices[t[0]].dot(&vertices[t[1]].cross(&vertices[t[2]])))
        .sum();
    (volume != 0.0).then_some(volume.signum())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> TriMeshObstacle {
        let v = vec![
            Vector3::new(-1.0, 0.0, -1.0),
            Vector3::new(1.0, 0.0, -1.0),
            Vector3::new(1.0, 0.0, 1.0),
            Vector3::new(-1.0, 0.0, 1.0),
        ];
        TriMeshObstacle::new(v, vec![[0, 1, 2], [0, 2, 3]]).unwrap()
    }

    #[test]
    fn closest_point_side_and_crossing() {
        let m = square();
        let (d, n, _) = m
            .query(&Vector3::new(0.1, 0.5, 0.2), &Vector3::new(0.1, 0.05, 0.2), 0.1)
            .unwrap();
        assert!((d - 0.05).abs() < 1e-15 && n == Vector3::y());
        assert!(m
            .query(&Vector3::new(0.1, 0.5, 0.2), &Vector3::new(0.1, 0.3, 0.2), 0.1)
            .is_none());
        // Tunnelling: from above to far below in one step is still a contact from above.
        let (d, n, _) = m
            .query(&Vector3::new(0.1, 0.5, 0.2), &Vector3::new(0.1, -3.0, 0.2), 0.01)
            .unwrap();
        assert!((d + 3.0).abs() < 1e-15 && n == Vector3::y());
        // From below, the normal points down.
        let (_, n, _) = m
            .query(&Vector3::new(0.1, -0.5, 0.2), &Vector3::new(0.1, -0.01, 0.2), 0.1)
            .unwrap();
        assert_eq!(n, -Vector3::y());
        // Beyond the edge: distance to the boundary, positive.
        let (d, _, _) = m
            .query(&Vector3::new(1.5, 0.5, 0.0), &Vector3::new(1.05, -0.01, 0.0), 0.1)
            .unwrap();
        assert!(d > 0.0);
    }

    #[test]
    fn bvh_matches_brute_force() {
        let n = 12;
        let mut v = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                let (x, z) = (i as f64 / n as f64, j as f64 / n as f64);
                v.push(Vector3::new(x, 0.1 * (7.0 * x).sin() * (5.0 * z).cos(), z));
            }
        }
        let mut t = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let a = i * (n + 1) + j;
                t.push([a, a + n + 1, a + 1]);
                t.push([a + 1, a + n + 1, a + n + 2]);
            }
        }
        let m = TriMeshObstacle::new(v, t).unwrap();
        let mut s = 1u64;
        for _ in 0..500 {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
            let p = Vector3::new(
                (s >> 40) as f64 / 16777216.0,
                ((s >> 20) & 0xfffff) as f64 / 1048576.0 * 0.4 - 0.2,
                (s & 0xfffff) as f64 / 1048576.0,
            );
            let (_, q, _) = m.closest(&p, 10.0).unwrap();
            let brute = (0..m.num_triangles())
                .map(|k| {
                    let (a, b, c) = m.corners(k);
                    (closest_on_triangle(&p, &a, &b, &c).0 - p).norm()
                })
                .fold(f64::INFINITY, f64::min);
            assert!(((q - p).norm() - brute).abs() < 1e-14);
        }
    }
}
