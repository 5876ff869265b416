//! Geometric quality of a tet mesh: volumes, edges, altitudes, dihedral angles.
//!
//! The sign structure of the stiffness matrix `L` follows from the dihedral angles: the entry
//! of edge `ij` is positive exactly when the dihedral angle at the opposite edge is obtuse
//! (docs/method.md section 1). The `L`-based counts live in `fem::sign_pattern`.

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

use super::TetMesh;

/// Gradients of the four barycentric shape functions of a tet with edge matrix `p`:
/// the columns `a_i` of `A = [-P^-T s, P^-T]` (Eq. 23). `None` if `p` is singular.
pub fn barycentric_gradients(p: &Matrix3<f64>) -> Option<[Vector3<f64>; 4]> {
    let p_inv_t = p.try_inverse()?.transpose();
    let a1 = p_inv_t.column(0).into_owned();
    let a2 = p_inv_t.column(1).into_owned();
    let a3 = p_inv_t.column(2).into_owned();
    Some([-(a1 + a2 + a3), a1, a2, a3])
}

/// The six edges of a tet as local vertex pairs; `OPPOSITE[e]` is the pair of the other two.
pub const EDGES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];
/// For each edge in [`EDGES`], the opposite edge.
pub const OPPOSITE: [(usize, usize); 6] = [(2, 3), (1, 3), (1, 2), (0, 3), (0, 2), (0, 1)];

/// The six dihedral angles (radians) of a tet, one per edge in [`EDGES`] order.
pub fn dihedral_angles(grads: &[Vector3<f64>; 4]) -> [f64; 6] {
    // The faces meeting at edge (a, b) are those opposite the other two vertices (c, d);
    // their inward normals are a_c/|a_c| and a_d/|a_d|, so cos(theta) = -<a_c, a_d>/(|a_c||a_d|).
    std::array::from_fn(|e| {
        let (c, d) = OPPOSITE[e];
        let cos = -grads[c].dot(&grads[d]) / (grads[c].norm() * grads[d].norm());
        cos.clamp(-1.0, 1.0).acos()
    })
}

/// Geometric quality summary of a mesh.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct MeshQuality {
    /// Number of vertices.
    pub vertices: usize,
    /// Number of tets.
    pub tets: usize,
    /// Sum of tet volumes (m^3).
    pub total_volume: f64,
    /// Smallest tet volume (m^3).
    pub min_volume: f64,
    /// Largest tet volume (m^3).
    pub max_volume: f64,
    /// Shortest edge (m).
    pub min_edge: f64,
    /// Longest edge (m).
    pub max_edge: f64,
    /// Mean edge length over tet edges (m; edges shared by several tets counted once per tet).
    pub mean_edge: f64,
    /// Smallest altitude (vertex to opposite face) over all tets (m).
    pub min_altitude: f64,
    /// Smallest normalised volume `6 sqrt(2) V / l_rms^3` (1; 1 = regular tet).
    pub min_normalized_volume: f64,
    /// Smallest dihedral angle (degrees).
    pub min_dihedral_deg: f64,
    /// Largest dihedral angle (degrees).
    pub max_dihedral_deg: f64,
    /// Tets with at least one dihedral angle above 90 degrees (+1e-9 rad).
    pub tets_with_obtuse_dihedral: usize,
}

/// Compute the quality summary (one pass over the tets).
///
/// ```
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::mesh::quality::quality;
///
/// let mesh = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1]).build()?;
/// let q = quality(&mesh);
/// assert_eq!((q.vertices, q.tets), (12, 12));
/// assert!((q.total_volume - 0.002).abs() < 1e-15);
/// // Kuhn tets are orthoschemes: no dihedral angle is obtuse.
/// assert_eq!(q.tets_with_obtuse_dihedral, 0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn quality(mesh: &TetMesh) -> MeshQuality {
    let mut q = MeshQuality {
        vertices: mesh.num_vertices(),
        tets: mesh.num_tets(),
        total_volume: 0.0,
        min_volume: f64::INFINITY,
        max_volume: 0.0,
        min_edge: f64::INFINITY,
        max_edge: 0.0,
        mean_edge: 0.0,
        min_altitude: f64::INFINITY,
        min_normalized_volume: f64::INFINITY,
        min_dihedral_deg: 180.0,
        max_dihedral_deg: 0.0,
        tets_with_obtuse_dihedral: 0,
    };
    let mut edge_sum = 0.0;
    for (t, tet) in mesh.tets.iter().enumerate() {
        let p = mesh.edge_matrix(t);
        let v = p.determinant() / 6.0;
        q.total_volume += v;
        q.min_volume = q.min_volume.min(v);
        q.max_volume = q.max_volume.max(v);
        let (_, nv) = super::volume_and_quality(&mesh.vertices, tet);
        q.min_normalized_volume = q.min_normalized_volume.min(nv);
        for (a, b) in EDGES {
            let l = (mesh.vertices[tet[a]] - mesh.vertices[tet[b]]).norm();
            q.min_edge = q.min_edge.min(l);
            q.max_edge = q.max_edge.max(l);
            edge_sum += l;
        }
        if let Some(g) = barycentric_gradients(&p) {
            for gi in &g {
                q.min_altitude = q.min_altitude.min(1.0 / gi.norm());
            }
            let angles = dihedral_angles(&g);
            let mut obtuse = false;
            for &th in &angles {
                q.min_dihedral_deg = q.min_dihedral_deg.min(th.to_degrees());
                q.max_dihedral_deg = q.max_dihedral_deg.max(th.to_degrees());
                obtuse |= th > std::f64::consts::FRAC_PI_2 + 1e-9;
            }
            q.tets_with_obtuse_dihedral += obtuse as usize;
        }
    }
    q.mean_edge = edge_sum / (6 * mesh.num_tets()).max(1) as f64;
    q
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_tet_dihedral_is_arccos_one_third() {
        let s = 1.0 / 2f64.sqrt();
        let m = TetMesh::new(
            vec![
                Vector3::new(1.0, 0.0, -s),
                Vector3::new(-1.0, 0.0, -s),
                Vector3::new(0.0, 1.0, s),
                Vector3::new(0.0, -1.0, s),
            ],
            vec![[0, 1, 2, 3]],
        )
        .unwrap();
        let q = quality(&m);
        let expect = (1.0f64 / 3.0).acos().to_degrees();
        assert!((q.min_dihedral_deg - expect).abs() < 1e-10);
        assert!((q.max_dihedral_deg - expect).abs() < 1e-10);
        assert!((q.min_normalized_volume - 1.0).abs() < 1e-12);
        assert_eq!(q.tets_with_obtuse_dihedral, 0);
    }

    #[test]
    fn trirectangular_corner_has_three_right_angles() {
        let m = TetMesh::new(
            vec![Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::z()],
            vec![[0, 1, 2, 3]],
        )
        .unwrap();
        let p = m.edge_matrix(0);
        let ang = dihedral_angles(&barycentric_gradients(&p).unwrap());
        let right = ang
            .iter()
            .filter(|a| (**a - std::f64::consts::FRAC_PI_2).abs() < 1e-12)
            .count();
        assert_eq!(right, 3);
    }
}
