//! The global system of projective dynamics restricted to the free (non-Dirichlet) vertices:
//! the per-axis matrix `M/h^2 + L` (docs/method.md Eq. 5), the pull of the fixed vertices, and
//! with a skeleton the blocks between free and bone vertices (Eq. 18), assembled from a model.

use nalgebra::Vector3;

use super::SolverError;
use crate::fem::SymCsc;
use crate::model::Model;

/// The global system restricted to the free (non-Dirichlet) vertices.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct GlobalSystem {
    /// Free vertex -> global vertex.
    pub free: Vec<usize>,
    /// Global vertex -> free index (`usize::MAX` for fixed vertices).
    pub index: Vec<usize>,
    /// `L` on the free vertices (with attachment springs).
    pub l: SymCsc,
    /// Lumped mass of the free vertices.
    pub mass: Vec<f64>,
    /// `M/h^2` on the free vertices: the inertia term of the matrix.
    pub mass_h2: Vec<f64>,
    /// `diag(L)` on the free vertices.
    pub l_diag: Vec<f64>,
    /// Attachment weight per free vertex (empty without attachments).
    pub attachment: Vec<f64>,
    /// `-L_fd x_d`: the constant pull of the fixed vertices on the free ones.
    pub coupling: Vec<Vector3<f64>>,
    /// Bone vertices (global numbering, in the skeleton's order); empty without a skeleton.
    pub rigid: Vec<usize>,
    /// Global vertex -> index among the bone vertices (`usize::MAX` for others).
    pub rigid_index: Vec<usize>,
    /// For each bone vertex, its couplings `(free index, L value)` to free vertices.
    pub l_rf: Vec<Vec<(usize, f64)>>,
    /// `L` among bone vertices (dense, `n_rigid x n_rigid`, row-major).
    pub l_rr: Vec<f64>,
    /// `M/h^2` on the bone vertices.
    pub mass_rigid_h2: Vec<f64>,
    /// `-L_rd x_d` for the bone vertices.
    pub coupling_rigid: Vec<Vector3<f64>>,
}

impl GlobalSystem {
    /// Assemble `M/h^2 + L` for time step `h` (the step itself is kept by the simulator's
    /// integrator; the system keeps only the assembled matrix).
    pub fn new(model: &Model, h: f64) -> Result<Self, SolverError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(SolverError::input(format!(
                "time step must be finite and positive, got {}",
                crate::base::number(h)
            )));
        }
        let n = model.n();
        let values = crate::constraint::stiffness_values(model).map_err(|e| SolverError::input(e.to_string()))?;
        let full = model.fem.pattern.to_sym_csc(values);
        let rigid: Vec<usize> = model.skeleton.as_ref().map_or(Vec::new(), |s| s.rigid.clone());
        let mut rigid_index = vec![usize::MAX; n];
        for (k, &v) in rigid.iter().enumerate() {
            rigid_index[v] = k;
        }
        let keep: Vec<bool> = (0..n)
            .map(|i| !model.fixed[i] && rigid_index[i] == usize::MAX)
            .collect();
        let (l, free) = full.principal_submatrix(&keep);
        let mut index = vec![usize::MAX; n];
        for (k, &v) in free.iter().enumerate() {
            index[v] = k;
        }
        let mut coupling = vec![Vector3::zeros(); free.len()];
        if model.fixed.iter().any(|&f| f) {
            for (k, &j) in free.iter().enumerate() {
                for (i, v) in full.column(j) {
                    if model.fixed[i] {
                        coupling[k] -= v * model.rest[i];
                    }
                }
            }
        }
        let nr = rigid.len();
        let mut l_rf = vec![Vec::new(); nr];
        let mut l_rr = vec![0.0; nr * nr];
        let mut coupling_rigid = vec![Vector3::zeros(); nr];
        for (r, &v) in rigid.iter().enumerate() {
            for (i, val) in full.column(v) {
                if index[i] != usize::MAX {
                    l_rf[r].push((index[i], val));
                } else if rigid_index[i] != usize::MAX {
                    l_rr[r * nr + rigid_index[i]] = val;
                } else if model.fixed[i] {
                    coupling_rigid[r] -= val * model.rest[i];
                }
            }
        }
        let mut attachment = Vec::new();
        if !model.attachments.is_empty() {
            attachment = vec![0.0; free.len()];
            for a in &model.attachments {
                if index[a.vertex] != usize::MAX {
                    attachment[index[a.vertex]] += a.weight;
                }
            }
        }
        let ih2 = 1.0 / (h * h);
        // `M/h^2` must be a number: a step so short (about 1e-154 s and below) or a mass so
        // large that it overflows would only show as non-finite positions in the first
        // iteration, naming neither.
        if let Some(&v) = free.iter().find(|&&v| !(model.mass[v] * ih2).is_finite()) {
            return Err(SolverError::input(format!(
                "time step {} s: vertex {v}'s mass {} kg over h^2 overflows double precision; use a longer time step",
                crate::base::number(h),
                crate::base::number(model.mass[v])
            )));
        }
        Ok(Self {
            l_diag: l.diagonal(),
            mass: free.iter().map(|&v| model.mass[v]).collect(),
            mass_h2: free.iter().map(|&v| model.mass[v] * ih2).collect(),
            free,
            index,
            l,
            attachment,
            coupling,
            mass_rigid_h2: rigid.iter().map(|&v| model.mass[v] * ih2).collect(),
            rigid,
            rigid_index,
            l_rf,
            l_rr,
            coupling_rigid,
        })
    }

    /// Number of free vertices.
    pub fn n(&self) -> usize {
        self.free.len()
    }

    /// `y = (M/h^2 + L) x`.
    pub fn apply(&self, x: &[Vector3<f64>], y: &mut [Vector3<f64>]) {
        self.l.matvec3(x, y);
        for ((y, x), m) in y.iter_mut().zip(x).zip(&self.mass_h2) {
            *y += x * *m;
        }
    }
}
