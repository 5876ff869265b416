//! Linear tetrahedral FEM operators: per-tet geometry (Eq. 23), lumped mass and the
//! per-axis stiffness ("Laplacian") matrix `L = sum_t mu_t V_t A_t^T A_t` (Eq. 22).
//!
//! The three axes decouple (`L (x) I3`), so everything here is the `n x n` block. The sparsity
//! pattern of `L` is built once ([`StiffnessPattern`]); assembling new values (other material,
//! per-element weights) is a scatter into that pattern, with no sorting or allocation per tet.

mod csc;
mod pattern;

pub use csc::SymCsc;
pub use pattern::StiffnessPattern;

use faer::sparse::SparseColMat;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::mesh::quality::barycentric_gradients;
use crate::mesh::TetMesh;

/// Errors from building FEM operators.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FemError {
    /// A tet's edge matrix is singular or its volume is not positive.
    #[error("tet {tet}: rest edge matrix is singular or inverted (volume {volume:e})")]
    DegenerateTet {
        /// Tet index.
        tet: usize,
        /// Signed volume.
        volume: f64,
    },
    /// A material coefficient is not a finite positive number.
    #[error("{name} must be finite and positive, got {}", crate::base::number(*value))]
    BadCoefficient {
        /// Which coefficient.
        name: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A per-element coefficient vector has the wrong length.
    #[error("{name}: expected {expected} per-tet values, got {got}")]
    WrongLength {
        /// Which coefficient.
        name: &'static str,
        /// Number of tets.
        expected: usize,
        /// Given length.
        got: usize,
    },
}

/// Rest geometry of one tet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TetGeometry {
    /// Rest edge matrix `P = [q1-q0, q2-q0, q3-q0]` (Eq. 23).
    pub p: Matrix3<f64>,
    /// `P^-1`, so that `F = [x1-x0, x2-x0, x3-x0] P^-1`.
    pub p_inv: Matrix3<f64>,
    /// Rest volume `det P / 6 > 0`.
    pub volume: f64,
    /// Columns `a_i` of the gradient operator `A = [-P^-T s, P^-T]` (Eq. 23).
    pub grads: [Vector3<f64>; 4],
}

impl TetGeometry {
    /// Geometry of a tet given its edge matrix; `None` if singular or inverted.
    ///
    /// ```
    /// use diffsoft::fem::TetGeometry;
    /// use nalgebra::Matrix3;
    ///
    /// let g = TetGeometry::from_edge_matrix(Matrix3::identity()).ok_or("degenerate")?;
    /// assert!((g.volume - 1.0 / 6.0).abs() < 1e-15);
    /// // The shape-function gradients sum to zero: each row of the local block does too.
    /// let k = g.local_laplacian();
    /// assert!(k.iter().all(|row| row.iter().sum::<f64>().abs() < 1e-15));
    /// // Inverted (negative determinant): refused.
    /// assert!(TetGeometry::from_edge_matrix(-Matrix3::identity()).is_none());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn from_edge_matrix(p: Matrix3<f64>) -> Option<Self> {
        let volume = p.determinant() / 6.0;
        if volume.is_nan() || volume <= 0.0 {
            return None;
        }
        let p_inv = p.try_inverse()?;
        let grads = barycentric_gradients(&p)?;
        Some(Self {
            p,
            p_inv,
            volume,
            grads,
        })
    }

    /// Local stiffness block `V A^T A` (4 x 4, without the material factor): entry
    /// `(i, j) = V <a_i, a_j>`.
    pub fn local_laplacian(&self) -> [[f64; 4]; 4] {
        std::array::from_fn(|i| std::array::from_fn(|j| self.volume * self.grads[i].dot(&self.grads[j])))
    }
}

/// A material coefficient, uniform or per tet.
#[derive(Debug, Clone, Copy)]
pub enum Coefficient<'a> {
    /// The same value for every tet.
    Uniform(f64),
    /// One value per tet.
    PerTet(&'a [f64]),
}

impl Coefficient<'_> {
    fn check(&self, name: &'static str, tets: usize) -> Result<(), FemError> {
        let bad = |value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(FemError::BadCoefficient { name, value })
            }
        };
        match self {
            Coefficient::Uniform(v) => bad(*v),
            Coefficient::PerTet(v) => {
                if v.len() != tets {
                    return Err(FemError::WrongLength {
                        name,
                        expected: tets,
                        got: v.len(),
                    });
                }
                v.iter().try_for_each(|&x| bad(x))
            }
        }
    }

    fn at(&self, t: usize) -> f64 {
        match self {
            Coefficient::Uniform(v) => *v,
            Coefficient::PerTet(v) => v[t],
        }
    }
}

/// FEM operators of one mesh: per-tet geometry and the sparsity pattern of `L`.
#[derive(Debug, Clone)]
pub struct FemOperators {
    /// Tets (copied from the mesh).
    pub tets: Vec<[usize; 4]>,
    /// Rest geometry per tet.
    pub geometry: Vec<TetGeometry>,
    /// Sparsity pattern of `L` with per-tet scatter slots.
    pub pattern: StiffnessPattern,
}

impl FemOperators {
    /// Compute per-tet geometry (in parallel) and the sparsity pattern.
    ///
    /// ```
    /// use diffsoft::fem::{Coefficient, FemOperators};
    /// use diffsoft::mesh::generate::BoxSpec;
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let fem = FemOperators::new(&mesh)?;
    /// assert_eq!(fem.num_vertices(), 8);
    /// assert!((fem.total_volume() - 1e-3).abs() < 1e-15);
    /// let mass = fem.lumped_mass(Coefficient::Uniform(1000.0))?;
    /// assert!((mass.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    /// assert!(fem.lumped_mass(Coefficient::Uniform(-1.0)).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(mesh: &TetMesh) -> Result<Self, FemError> {
        let geometry: Vec<TetGeometry> = (0..mesh.num_tets())
            .into_par_iter()
            .map(|t| {
                let p = mesh.edge_matrix(t);
                TetGeometry::from_edge_matrix(p).ok_or(FemError::DegenerateTet {
                    tet: t,
                    volume: p.determinant() / 6.0,
                })
            })
            .collect::<Result<_, _>>()?;
        let pattern = StiffnessPattern::new(mesh.num_vertices(), &mesh.tets);
        Ok(Self {
            tets: mesh.tets.clone(),
            geometry,
            pattern,
        })
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.pattern.n
    }

    /// Total rest volume.
    pub fn total_volume(&self) -> f64 {
        self.geometry.iter().map(|g| g.volume).sum()
    }

    /// Lumped mass: each tet gives `rho V / 4` to each corner (Eq. 22).
    pub fn lumped_mass(&self, rho: Coefficient<'_>) -> Result<Vec<f64>, FemError> {
        rho.check("density", self.tets.len())?;
        let mut m = vec![0.0; self.num_vertices()];
        for (t, (tet, g)) in self.tets.iter().zip(&self.geometry).enumerate() {
            let share = rho.at(t) * g.volume / 4.0;
            for &i in tet {
                m[i] += share;
            }
        }
        Ok(m)
    }

    /// Values of `L = sum_t mu_t V_t A_t^T A_t` in the pattern's order (Eq. 22).
    pub fn laplacian_values(&self, mu: Coefficient<'_>) -> Result<Vec<f64>, FemError> {
        mu.check("stiffness mu", self.tets.len())?;
        let mut values = vec![0.0; self.pattern.nnz()];
        for (t, g) in self.geometry.iter().enumerate() {
            let k = g.local_laplacian();
            let slots = &self.pattern.tet_slots[t];
            let c = mu.at(t);
            for a in 0..4 {
                for b in 0..4 {
                    values[slots[4 * a + b] as usize] += c * k[a][b];
                }
            }
        }
        Ok(values)
    }

    /// `L` as a symmetric CSC matrix.
    ///
    /// ```
    /// use diffsoft::fem::{Coefficient, FemOperators};
    /// use diffsoft::mesh::generate::BoxSpec;
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let l = FemOperators::new(&mesh)?.laplacian_csc(Coefficient::Uniform(1e5))?;
    /// // A Laplacian: constants are in its kernel.
    /// let mut y = vec![0.0; l.n];
    /// l.matvec(&vec![1.0; l.n], &mut y);
    /// assert!(y.iter().all(|v| v.abs() < 1e-9));
    /// assert!(l.diagonal().iter().all(|&d| d > 0.0));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn laplacian_csc(&self, mu: Coefficient<'_>) -> Result<SymCsc, FemError> {
        Ok(self.pattern.to_sym_csc(self.laplacian_values(mu)?))
    }

    /// `L` as a faer sparse matrix (both triangles stored).
    pub fn laplacian(&self, mu: Coefficient<'_>) -> Result<SparseColMat<usize, f64>, FemError> {
        Ok(self.pattern.to_faer(self.laplacian_values(mu)?))
    }
}

/// Sign structure of a stiffness matrix: how far it is from an M-matrix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, schemars::JsonSchema)]
pub struct SignPattern {
    /// Positive off-diagonal entries `L_ij > 0`, `i != j`, counting both triangles.
    pub positive_offdiagonal_entries: usize,
    /// The same as edges (unordered pairs): `positive_offdiagonal_entries / 2`.
    pub positive_offdiagonal_edges: usize,
    /// Rows with `sum_{j != i} |L_ij| > L_ii` (not weakly diagonally dominant).
    pub rows_not_diagonally_dominant: usize,
    /// True when every off-diagonal entry is `<= 0` (then `L` is an M-matrix).
    pub is_m_matrix: bool,
}

/// Count positive off-diagonal entries and non-dominant rows. An entry counts as positive when
/// `L_ij > tol sqrt(L_ii L_jj)` with `tol = 1e-12`, so right-angle round-off is not counted.
///
/// ```
/// use diffsoft::fem::{sign_pattern, Coefficient, FemOperators};
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::TetMesh;
/// use nalgebra::Vector3;
///
/// // Kuhn tets have no obtuse dihedral angle: an M-matrix.
/// let kuhn = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1]).build()?;
/// let l = FemOperators::new(&kuhn)?.laplacian_csc(Coefficient::Uniform(1.0))?;
/// let signs = sign_pattern(&l);
/// assert!(signs.is_m_matrix);
/// assert_eq!(signs.positive_offdiagonal_entries, 0);
/// // A flat tet whose apex lies over its base has obtuse angles at the apex's edges.
/// let v = vec![Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::new(0.3, 0.3, 0.1)];
/// let flat = TetMesh::new(v, vec![[0, 1, 2, 3]])?;
/// let l = FemOperators::new(&flat)?.laplacian_csc(Coefficient::Uniform(1.0))?;
/// let signs = sign_pattern(&l);
/// assert!(!signs.is_m_matrix);
/// assert_eq!(signs.positive_offdiagonal_edges, 3);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn sign_pattern(l: &SymCsc) -> SignPattern {
    const TOL: f64 = 1e-12;
    let diag = l.diagonal();
    let mut positive = 0;
    let mut non_dominant = 0;
    for j in 0..l.n {
        let mut off = 0.0;
        for (i, v) in l.column(j) {
            if i != j {
                off += v.abs();
                if v > TOL * (diag[i] * diag[j]).sqrt() {
                    positive += 1;
                }
            }
        }
        if off > diag[j] * (1.0 + TOL) {
            non_dominant += 1;
        }
    }
    SignPattern {
        positive_offdiagonal_entries: positive,
        positive_offdiagonal_edges: positive / 2,
        rows_not_diagonally_dominant: non_dominant,
        is_m_matrix: positive == 0,
    }
}

/// Tets whose signed volume at positions `x` is zero or negative: folded through themselves.
/// Every tet of a model has a positive rest volume ([`TetGeometry::from_edge_matrix`] refuses
/// others), so this counts the tets a deformation inverted or flattened.
///
/// ```
/// use diffsoft::fem::inverted_tets;
/// use nalgebra::Vector3;
///
/// let mut x = vec![Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::z()];
/// assert_eq!(inverted_tets(&[[0, 1, 2, 3]], &x), 0);
/// x[3].z = -0.5; // the apex pushed through the opposite face
/// assert_eq!(inverted_tets(&[[0, 1, 2, 3]], &x), 1);
/// ```
pub fn inverted_tets(tets: &[[usize; 4]], x: &[Vector3<f64>]) -> usize {
    let inverted = |t: &[usize; 4]| {
        let o = x[t[0]];
        (x[t[1]] - o).cross(&(x[t[2]] - o)).dot(&(x[t[3]] - o)) <= 0.0
    };
    tets.par_iter().with_min_len(4096).filter(|t| inverted(t)).count()
}
