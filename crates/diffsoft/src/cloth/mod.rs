//! Cloth: triangle-mesh bodies in the same projective-dynamics system as the soft bodies
//! (paper Eqs. 2-5, with the constraints of Bouaziz et al. 2014 for surfaces).
//!
//! * **Stretching**: per triangle, the in-plane deformation gradient `F = [x1-x0, x2-x0] P^-1`
//!   (3 x 2, `P` the rest edges in the triangle's own 2D frame) is projected onto the 3 x 2
//!   matrices with orthonormal columns (2D as-rigid-as-possible), `R = U V^T` of the thin SVD;
//!   energy `k_s A / 2 |F - R|^2`, weight `w = k_s A` (`k_s` in N/m, `A` the rest area).
//! * **Bending**: per interior vertex, the cotangent Laplacian
//!   `Delta_i x = 1/(2 A_i) sum_j (cot a_ij + cot b_ij)(x_j - x_i)` (the mean-curvature normal,
//!   `A_i` a third of the incident area) is projected onto the vectors of its rest length
//!   `|Delta_i X|`; energy `k_b A_i / 2 |Delta_i x - p_i|^2` (`k_b` in N m). A flat rest shape
//!   gives `p_i = 0`: bending is then a constant quadratic form.
//! * **Mass**: area density `rho_A` (kg/m^2), `rho_A A / 3` on each triangle corner.
//!
//! All weights enter the constant global matrix; the local step projects triangles and bending
//! stencils in parallel (`constraint::cloth_stretch`, `constraint::cloth_bend`). The 3 x 2 polar
//! decomposition and its differential are in [`crate::kernel::polar32`].

use std::ops::Range;

use nalgebra::{Matrix2, Vector2, Vector3};
use serde::Serialize;

use crate::base::InputError;
use crate::mesh::surface::TriSurface;

/// Smallest normalised triangle quality `2 A / l_max^2` accepted (an equilateral triangle has
/// `sqrt(3)/2`).
pub const MIN_TRIANGLE_QUALITY: f64 = 1e-9;

/// One cloth body as given to the model builder.
#[derive(Debug, Clone)]
pub struct ClothSpec {
    /// Name (reports, messages).
    pub name: String,
    /// Where the mesh came from (for messages).
    pub source: String,
    /// The triangle mesh in simulation coordinates.
    pub surface: TriSurface,
    /// In-plane stretching stiffness `k_s` (N/m).
    pub stretching: f64,
    /// Bending stiffness `k_b` (N m).
    pub bending: f64,
    /// Area density (kg/m^2).
    pub area_density: f64,
    /// Whether gravity acts on the cloth.
    pub gravity: bool,
    /// Initial velocity of every vertex.
    pub initial_velocity: Vector3<f64>,
    /// Vertices held at their rest position (Dirichlet), cloth numbering.
    pub fixed: Vec<usize>,
    /// Penalty attachments to the rest position: (vertex, weight in N/m), cloth numbering.
    pub attachments: Vec<(usize, f64)>,
}

impl ClothSpec {
    /// A cloth with gravity, zero initial velocity and no pins.
    ///
    /// ```
    /// use diffsoft::cloth::{grid, ClothSpec};
    /// use diffsoft::ModelBuilder;
    ///
    /// let mut flag = ClothSpec::new("flag", grid(2, 1.0), 100.0, 1e-3, 0.1);
    /// assert!(flag.gravity && flag.fixed.is_empty());
    /// flag.fixed = vec![0, 1, 2]; // one edge held
    /// let model = ModelBuilder::new().cloth(flag).build()?;
    /// let cloth = model.cloth().ok_or("no cloth")?;
    /// assert_eq!(cloth.num_triangles(), 8);
    /// assert!((model.mass().iter().sum::<f64>() - 0.1).abs() < 1e-12); // 0.1 kg/m^2 x 1 m^2
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(name: &str, surface: TriSurface, stretching: f64, bending: f64, area_density: f64) -> Self {
        Self {
            name: name.to_string(),
            source: name.to_string(),
            surface,
            stretching,
            bending,
            area_density,
            gravity: true,
            initial_velocity: Vector3::zeros(),
            fixed: Vec::new(),
            attachments: Vec::new(),
        }
    }
}

/// Where a cloth body lives in the assembled system.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct ClothBody {
    /// Name.
    pub name: String,
    /// Its vertices in the global numbering.
    pub vertices: Range<usize>,
    /// Its triangles in the cloth's triangle numbering.
    pub triangles: Range<usize>,
    /// Stretching stiffness (N/m).
    pub stretching: f64,
    /// Bending stiffness (N m).
    pub bending: f64,
    /// Area density (kg/m^2).
    pub area_density: f64,
    /// Total mass (kg).
    pub mass: f64,
    /// Rest area (m^2).
    pub area: f64,
    /// Interior vertices that carry a bending constraint.
    pub bending_vertices: usize,
    /// Whether gravity acts on it (`gravity.*` parameters reach it then).
    pub gravity: bool,
}

/// Rest geometry of one triangle: `F = sum_a x_a g_a^T` (3 x 2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleGeometry {
    /// Rest area.
    pub area: f64,
    /// Gradients of the three barycentric functions in the triangle's rest frame.
    pub grads: [Vector2<f64>; 3],
}

impl TriangleGeometry {
    /// From the rest positions; `None` for a degenerate triangle (quality below
    /// [`MIN_TRIANGLE_QUALITY`]) or non-finite input.
    ///
    /// ```
    /// use diffsoft::cloth::TriangleGeometry;
    /// use nalgebra::Vector3;
    ///
    /// let g = TriangleGeometry::new(&Vector3::zeros(), &Vector3::x(), &Vector3::z()).ok_or("degenerate")?;
    /// assert!((g.area - 0.5).abs() < 1e-15);
    /// // The barycentric gradients sum to zero.
    /// assert!((g.grads[0] + g.grads[1] + g.grads[2]).norm() < 1e-15);
    /// // Three points on a line are no triangle.
    /// assert!(TriangleGeometry::new(&Vector3::zeros(), &Vector3::x(), &(Vector3::x() * 2.0)).is_none());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(x0: &Vector3<f64>, x1: &Vector3<f64>, x2: &Vector3<f64>) -> Option<Self> {
        let e1 = x1 - x0;
        let e2 = x2 - x0;
        let n = e1.cross(&e2);
        let area = 0.5 * n.norm();
        let lmax = e1.norm_squared().max(e2.norm_squared()).max((x2 - x1).norm_squared());
        if !(area.is_finite() && lmax > 0.0 && 2.0 * area / lmax >= MIN_TRIANGLE_QUALITY) {
            return None;
        }
        let t1 = e1.normalize();
        let t2 = n.normalize().cross(&t1);
        let p = Matrix2::new(e1.dot(&t1), e2.dot(&t1), e1.dot(&t2), e2.dot(&t2));
        let pinv = p.try_inverse()?;
        let g1 = Vector2::new(pinv[(0, 0)], pinv[(0, 1)]);
        let g2 = Vector2::new(pinv[(1, 0)], pinv[(1, 1)]);
        Some(Self {
            area,
            grads: [-(g1 + g2), g1, g2],
        })
    }

    /// The per-axis 3 x 3 block `g_a . g_b`.
    pub fn local_laplacian(&self) -> [[f64; 3]; 3] {
        std::array::from_fn(|a| std::array::from_fn(|b| self.grads[a].dot(&self.grads[b])))
    }
}

/// Bending stencils in compressed form: stencil `i` couples `vertices[offsets[i]..offsets[i+1]]`
/// (the centre first) with Laplacian coefficients `coefs[..]` (summing to zero).
#[derive(Debug, Clone, Default)]
pub struct Bends {
    /// Offsets into `vertices` / `coefs`, length `stencils + 1`.
    pub offsets: Vec<usize>,
    /// Global vertex indices.
    pub vertices: Vec<usize>,
    /// Coefficients of `Delta_i x = sum_k c_k x_k` (1/m^2).
    pub coefs: Vec<f64>,
    /// Weight `k_b A_i` per stencil.
    pub weight: Vec<f64>,
    /// Rest length `|Delta_i X|` (0 on a flat rest shape).
    pub rest: Vec<f64>,
    /// Rest direction `Delta_i X / |Delta_i X|` (zero where the rest length is 0).
    pub rest_dir: Vec<Vector3<f64>>,
    /// Pattern slots, `k x k` row-major per stencil, concatenated; stencil `i` starts at
    /// `slot_offsets[i]`.
    pub slots: Vec<u32>,
    /// Offsets into `slots`.
    pub slot_offsets: Vec<usize>,
}

impl Bends {
    /// Number of stencils.
    pub fn len(&self) -> usize {
        self.weight.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.weight.is_empty()
    }

    /// Vertices and coefficients of stencil `i`.
    pub fn stencil(&self, i: usize) -> (&[usize], &[f64]) {
        let r = self.offsets[i]..self.offsets[i + 1];
        (&self.vertices[r.clone()], &self.coefs[r])
    }

    /// `Delta_i x`.
    pub fn apply(&self, i: usize, x: &[Vector3<f64>]) -> Vector3<f64> {
        let (v, c) = self.stencil(i);
        v.iter().zip(c).fold(Vector3::zeros(), |acc, (&v, &c)| acc + x[v] * c)
    }
}

/// For each vertex, the elements that contain it (CSR): `(element, position)`.
#[derive(Debug, Clone, Default)]
pub struct Incidence {
    /// Offsets, length `n + 1`.
    pub offsets: Vec<usize>,
    /// `(element, position within it)`.
    pub entries: Vec<(u32, u8)>,
}

impl Incidence {
    /// Build from element vertex lists.
    ///
    /// ```
    /// use diffsoft::cloth::Incidence;
    ///
    /// let triangles = [[0, 1, 2], [0, 2, 3]];
    /// let inc = Incidence::new(4, triangles.iter().map(|t| &t[..]));
    /// assert_eq!(inc.of(0), &[(0, 0), (1, 0)]); // (triangle, corner)
    /// assert_eq!(inc.of(3), &[(1, 2)]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new<'a>(n: usize, elements: impl Iterator<Item = &'a [usize]> + Clone) -> Self {
        let mut offsets = vec![0usize; n + 1];
        for e in elements.clone() {
            for &v in e {
                offsets[v + 1] += 1;
            }
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut entries = vec![(0u32, 0u8); offsets[n]];
        for (k, e) in elements.enumerate() {
            for (p, &v) in e.iter().enumerate() {
                entries[fill[v]] = (k as u32, p as u8);
                fill[v] += 1;
            }
        }
        Self { offsets, entries }
    }

    /// The entries of vertex `v`.
    pub fn of(&self, v: usize) -> &[(u32, u8)] {
        &self.entries[self.offsets[v]..self.offsets[v + 1]]
    }
}

/// All cloth of a model, assembled.
#[derive(Debug, Clone)]
pub struct Cloth {
    /// The cloth bodies.
    pub bodies: Vec<ClothBody>,
    /// Triangles (global vertex numbering).
    pub triangles: Vec<[usize; 3]>,
    /// Rest geometry per triangle.
    pub geometry: Vec<TriangleGeometry>,
    /// Stretching weight `k_s A` per triangle.
    pub w_stretch: Vec<f64>,
    /// Bending stencils.
    pub bends: Bends,
    /// Pattern slots of each triangle's 3 x 3 block (row-major).
    pub tri_slots: Vec<[u32; 9]>,
    /// Vertex -> (triangle, corner).
    pub vertex_triangles: Incidence,
    /// Vertex -> (bending stencil, position).
    pub vertex_bends: Incidence,
}

/// A cloth body's triangles, rest geometry, masses and bending stencils before assembly.
#[derive(Debug)]
pub(crate) struct Prepared {
    pub geometry: Vec<TriangleGeometry>,
    pub mass: Vec<f64>,
    pub area: f64,
    /// Per stencil: body-local vertices (centre first) and coefficients.
    pub stencils: Vec<(Vec<usize>, Vec<f64>, f64)>,
}

/// Validate a cloth spec and compute its rest geometry (body-local numbering).
pub(crate) fn prepare(spec: &ClothSpec) -> Result<Prepared, InputError> {
    let what = format!("cloth '{}' ({})", spec.name, spec.source);
    let bad = |m: String| InputError::new(format!("{what}: {m}"));
    for (name, v) in [
        ("stretching stiffness", spec.stretching),
        ("area density", spec.area_density),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(bad(format!(
                "{name} must be finite and positive, got {}",
                crate::base::number(v)
            )));
        }
    }
    if !(spec.bending.is_finite() && spec.bending >= 0.0) {
        return Err(bad(format!(
            "bending stiffness must be finite and >= 0, got {}",
            crate::base::number(spec.bending)
        )));
    }
    if !spec.initial_velocity.iter().all(|v| v.is_finite()) {
        return Err(bad("initial velocity must be finite".into()));
    }
    let s = &spec.surface;
    let n = s.vertices.len();
    if s.triangles.is_empty() {
        return Err(bad("no triangles".into()));
    }
    for (i, v) in s.vertices.iter().enumerate() {
        if !v.iter().all(|c| c.is_finite()) {
            return Err(bad(format!("vertex {i} is not finite: {v:?}")));
        }
    }
    // A triangle given twice (by its vertices, or by their positions through repeated
    // vertices) would count its stiffness and mass twice.
    let place = |i: usize| {
        let v = &s.vertices[i];
        [v.x, v.y, v.z].map(|c| (c + 0.0).to_bits())
    };
    let mut by_vertices = std::collections::HashMap::with_capacity(s.triangles.len());
    let mut by_place = std::collections::HashMap::with_capacity(s.triangles.len());
    for (t, tri) in s.triangles.iter().enumerate() {
        if tri.iter().any(|&v| v >= n) {
            continue; // reported below
        }
        let mut key = *tri;
        key.sort_unstable();
        if let Some(first) = by_vertices.insert(key, t) {
            return Err(bad(format!(
                "triangle {t} repeats triangle {first} (the same three vertices {tri:?})"
            )));
        }
        let mut key = tri.map(place);
        key.sort_unstable();
        if let Some(first) = by_place.insert(key, t) {
            return Err(bad(format!(
                "triangle {t} (vertices {tri:?}) lies on triangle {first}: their corners are at the same three positions (merge the repeated vertices)"
            )));
        }
    }
    let mut used = vec![false; n];
    let mut geometry = Vec::with_capacity(s.triangles.len());
    let mut mass = vec![0.0; n];
    let mut area = 0.0;
    for (t, tri) in s.triangles.iter().enumerate() {
        if tri.iter().any(|&v| v >= n) {
            return Err(bad(format!(
                "triangle {t}: vertex index out of range ({tri:?}, {n} vertices)"
            )));
        }
        if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            return Err(bad(format!("triangle {t} repeats a vertex: {tri:?}")));
        }
        let g = TriangleGeometry::new(&s.vertices[tri[0]], &s.vertices[tri[1]], &s.vertices[tri[2]])
            .ok_or_else(|| {
                bad(format!(
                    "triangle {t} (vertices {tri:?}) is degenerate: area below {MIN_TRIANGLE_QUALITY:e} x its longest edge squared"
                ))
            })?;
        for &v in tri {
            used[v] = true;
            mass[v] += spec.area_density * g.area / 3.0;
        }
        area += g.area;
        geometry.push(g);
    }
    if let Some(v) = used.iter().position(|u| !u) {
        return Err(bad(format!(
            "vertex {v} belongs to no triangle (a free particle without stiffness)"
        )));
    }
    let stencils = if spec.bending > 0.0 {
        bending_stencils(s, &geometry)
    } else {
        Vec::new()
    };
    Ok(Prepared {
        geometry,
        mass,
        area,
        stencils,
    })
}

/// Cotangent-Laplacian stencils of the interior vertices (every incident edge shared by
/// exactly two triangles): `(vertices, coefficients, vertex area A_i)`.
fn bending_stencils(s: &TriSurface, geometry: &[TriangleGeometry]) -> Vec<(Vec<usize>, Vec<f64>, f64)> {
    use std::collections::BTreeMap;
    let n = s.vertices.len();
    // Edge -> number of triangles; per vertex: neighbour -> summed cot weight.
    let mut edge_count: BTreeMap<(usize, usize), usize> = BTreeMap::new();
    let mut weights: Vec<BTreeMap<usize, f64>> = vec![BTreeMap::new(); n];
    let mut vertex_area = vec![0.0; n];
    for (tri, g) in s.triangles.iter().zip(geometry) {
        for k in 0..3 {
            let (i, j, o) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
            *edge_count.entry((i.min(j), i.max(j))).or_insert(0) += 1;
            let a = s.vertices[i] - s.vertices[o];
            let b = s.vertices[j] - s.vertices[o];
            let cot = a.dot(&b) / a.cross(&b).norm();
            *weights[i].entry(j).or_insert(0.0) += cot;
            *weights[j].entry(i).or_insert(0.0) += cot;
            vertex_area[tri[k]] += g.area / 3.0;
        }
    }
    let mut out = Vec::new();
    for i in 0..n {
        if weights[i].is_empty()
            || weights[i]
                .keys()
                .any(|&j| edge_count.get(&(i.min(j), i.max(j))) != Some(&2))
        {
            continue;
        }
        let ai = vertex_area[i];
        let mut verts = vec![i];
        let mut coefs = vec![0.0];
        for (&j, &w) in &weights[i] {
            let c = w / (2.0 * ai);
            verts.push(j);
            coefs.push(c);
            coefs[0] -= c;
        }
        out.push((verts, coefs, ai));
    }
    out
}

/// A square cloth of `n x n` cells of side `size`, centred at the origin in the plane y = 0
/// (vertex `(i, j)` is `j (n + 1) + i`; each cell split along its diagonal).
///
/// ```
/// use diffsoft::cloth::grid;
///
/// let g = grid(2, 1.0);
/// assert_eq!((g.vertices.len(), g.triangles.len()), (9, 8));
/// assert_eq!(g.vertices[4], nalgebra::Vector3::zeros()); // the centre
/// assert_eq!(g.vertices[8].x, 0.5);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn grid(n: usize, size: f64) -> TriSurface {
    let mut vertices = Vec::with_capacity((n + 1) * (n + 1));
    for j in 0..=n {
        for i in 0..=n {
            let t = |k: usize| k as f64 * size / n as f64 - 0.5 * size;
            vertices.push(Vector3::new(t(i), 0.0, t(j)));
        }
    }
    let id = |i: usize, j: usize| j * (n + 1) + i;
    let mut triangles = Vec::with_capacity(2 * n * n);
    for j in 0..n {
        for i in 0..n {
            triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    TriSurface { vertices, triangles }
}

impl Cloth {
    /// Number of triangles.
    pub fn num_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// The cloth body that owns global vertex `v`, if any.
    pub fn body_of(&self, v: usize) -> Option<usize> {
        self.bodies.iter().position(|b| b.vertices.contains(&v))
    }

    /// Largest and smallest principal stretch over all triangles at positions `q` (singular
    /// values of the in-plane deformation gradient).
    pub fn stretch_range(&self, q: &[Vector3<f64>]) -> (f64, f64) {
        let mut lo = f64::INFINITY;
        let mut hi: f64 = 0.0;
        for (tri, g) in self.triangles.iter().zip(&self.geometry) {
            let f = deformation_gradient(q, tri, g);
            let (s1, s2) = crate::kernel::polar32::singular_values(&f);
            hi = hi.max(s1);
            lo = lo.min(s2);
        }
        (hi, lo)
    }
}

/// `F = sum_a x_a g_a^T` of one triangle.
#[inline]
pub fn deformation_gradient(q: &[Vector3<f64>], tri: &[usize; 3], g: &TriangleGeometry) -> nalgebra::Matrix3x2<f64> {
    q[tri[0]] * g.grads[0].transpose() + q[tri[1]] * g.grads[1].transpose() + q[tri[2]] * g.grads[2].transpose()
}

/// Rest length and direction of a bending stencil's Laplacian, with lengths below `1e-9` of
/// `|sum |c_k| X_k|`'s scale set to exactly 0 (a flat rest shape: linear bending).
pub(crate) fn rest_curvature(verts: &[usize], coefs: &[f64], x: &[Vector3<f64>]) -> (f64, Vector3<f64>) {
    let c = verts
        .iter()
        .zip(coefs)
        .fold(Vector3::zeros(), |acc, (&v, &c)| acc + (x[v] - x[verts[0]]) * c);
    let scale: f64 = verts
        .iter()
        .zip(coefs)
        .map(|(&v, &c)| c.abs() * (x[v] - x[verts[0]]).norm())
        .sum();
    let len = c.norm();
    if len <= 1e-9 * scale {
        (0.0, Vector3::zeros())
    } else {
        (len, c / len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(nx: usize, ny: usize, size: f64) -> TriSurface {
        let mut vertices = Vec::new();
        for j in 0..=ny {
            for i in 0..=nx {
                vertices.push(Vector3::new(
                    i as f64 * size / nx as f64,
                    0.0,
                    j as f64 * size / ny as f64,
                ));
            }
        }
        let mut triangles = Vec::new();
        let id = |i: usize, j: usize| j * (nx + 1) + i;
        for j in 0..ny {
            for i in 0..nx {
                triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        TriSurface { vertices, triangles }
    }

    #[test]
    fn triangle_gradients_reproduce_affine_maps() {
        let x = [
            Vector3::new(0.1, 0.2, -0.3),
            Vector3::new(1.0, 0.4, 0.2),
            Vector3::new(0.3, 1.1, 0.5),
        ];
        let g = TriangleGeometry::new(&x[0], &x[1], &x[2]).unwrap();
        // At rest F has orthonormal columns; gradients sum to zero.
        let f = deformation_gradient(&x, &[0, 1, 2], &g);
        let ftf = f.transpose() * f;
        assert!((ftf - Matrix2::identity()).norm() < 1e-12, "{ftf}");
        assert!((g.grads[0] + g.grads[1] + g.grads[2]).norm() < 1e-12);
        let expected = 0.5 * (x[1] - x[0]).cross(&(x[2] - x[0])).norm();
        assert!((g.area - expected).abs() < 1e-15);
        // Scaling the triangle by 2 doubles both singular values.
        let y: Vec<_> = x.iter().map(|v| v * 2.0).collect();
        let (s1, s2) = crate::kernel::polar32::singular_values(&deformation_gradient(&y, &[0, 1, 2], &g));
        assert!((s1 - 2.0).abs() < 1e-12 && (s2 - 2.0).abs() < 1e-12);
        assert!(TriangleGeometry::new(&x[0], &x[1], &(x[0] * 0.5 + x[1] * 0.5)).is_none());
    }

    #[test]
    fn flat_grid_has_linear_bending_with_zero_row_sums() {
        let s = grid(4, 3, 1.0);
        let spec = ClothSpec::new("c", s.clone(), 100.0, 1e-3, 0.5);
        let p = prepare(&spec).unwrap();
        // Interior vertices of a 5 x 4 grid: 3 x 2.
        assert_eq!(p.stencils.len(), 6);
        for (v, c, _) in &p.stencils {
            assert!(c.iter().sum::<f64>().abs() < 1e-9);
            let (len, _) = rest_curvature(v, c, &s.vertices);
            assert_eq!(len, 0.0);
        }
        let total: f64 = p.mass.iter().sum();
        assert!((total - 0.5).abs() < 1e-12 && (p.area - 1.0).abs() < 1e-12);
        // Bending a row upward produces a Laplacian pointing up at its middle.
        let mut y = s.vertices.clone();
        for (k, v) in y.iter_mut().enumerate() {
            let i = k % 5;
            v.y = -((i as f64 - 2.0) * 0.25).powi(2);
        }
        let (v, c, _) = &p.stencils[1];
        let lap = v.iter().zip(c).fold(Vector3::zeros(), |a, (&v, &c)| a + y[v] * c);
        assert!(lap.y < 0.0, "{lap}");
    }

    #[test]
    fn bad_cloth_is_rejected_with_its_element() {
        let mut s = grid(1, 1, 1.0);
        s.triangles.push([0, 1, 1]);
        let e = prepare(&ClothSpec::new("c", s, 1.0, 0.0, 1.0)).unwrap_err().to_string();
        assert!(e.contains("triangle 2 repeats a vertex"), "{e}");
        // A triangle given twice, by its vertices or by their positions.
        let mut s = grid(1, 1, 1.0);
        let t = s.triangles[0];
        s.triangles.push([t[2], t[0], t[1]]);
        let e = prepare(&ClothSpec::new("c", s, 1.0, 0.0, 1.0)).unwrap_err().to_string();
        assert!(e.contains("triangle 2 repeats triangle 0"), "{e}");
        let mut s = grid(1, 1, 1.0);
        let t = s.triangles[1];
        s.vertices.push(s.vertices[t[0]]);
        s.triangles.push([4, t[1], t[2]]);
        let e = prepare(&ClothSpec::new("c", s, 1.0, 0.0, 1.0)).unwrap_err().to_string();
        assert!(
            e.contains("triangle 2 (vertices [4,") && e.contains("lies on triangle 1"),
            "{e}"
        );
        let mut s = grid(1, 1, 1.0);
        s.vertices.push(Vector3::zeros());
        let e = prepare(&ClothSpec::new("c", s, 1.0, 0.0, 1.0)).unwrap_err().to_string();
        assert!(e.contains("vertex 4 belongs to no triangle"), "{e}");
        let e = prepare(&ClothSpec::new("c", grid(1, 1, 1.0), -1.0, 0.0, 1.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("stretching stiffness"), "{e}");
        let mut s = grid(1, 1, 1.0);
        s.vertices[3].x = f64::NAN;
        let e = prepare(&ClothSpec::new("c", s, 1.0, 0.0, 1.0)).unwrap_err().to_string();
        assert!(e.contains("vertex 3 is not finite"), "{e}");
    }
}
