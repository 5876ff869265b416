//! The global step of projective dynamics (METHOD.md Eq. 5): solve
//! `(M/h^2 + L) q = M s_n / h^2 + J p` on the free vertices, for x, y and z at once (the axes
//! share the per-axis matrix). Every solver implements [`GlobalSolver`]:
//!
//! * [`Direct`](super::direct::Direct): sparse Cholesky, factored once and reused;
//! * [`Stationary`]: the paper's iterations in position form, plain (Eq. 19, `W = M/h^2`) or
//!   split (Eq. 21, `W = M/h^2 + D`), optionally relaxed (`x += gamma (x_hat - x)`) and
//!   Chebyshev-accelerated (Wang 2015).
//!
//! With contacts, the Coulomb cone projection of [`crate::contact::project`] acts on each
//! contact vertex's update inside the iteration (for [`Stationary`], as in the paper) or inside a
//! projected Gauss-Seidel on the contact-space (Delassus) operator (for `Direct`).

use nalgebra::Vector3;
use serde::Serialize;

use super::SolverError;
use crate::contact::{project, Contact};
use crate::fem::SymCsc;
use crate::model::Model;

/// Which global solver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum SolverKind {
    /// Sparse Cholesky of `M/h^2 + L`, factored once.
    Direct,
    /// Eq. 19: `M/h^2 x' = b - L x`.
    Plain,
    /// Eq. 21: `(M/h^2 + D) x' = b - (L - D) x`.
    Split,
    /// Eq. 21, relaxed and Chebyshev-accelerated with parameters from the spectral analysis.
    Chebyshev,
}

/// The global system restricted to the free (non-Dirichlet) vertices.
#[derive(Debug, Clone)]
pub struct GlobalSystem {
    /// Time step.
    pub h: f64,
    /// Free vertex -> global vertex.
    pub free: Vec<usize>,
    /// Global vertex -> free index (`usize::MAX` for fixed vertices).
    pub index: Vec<usize>,
    /// `L` on the free vertices (with attachment springs).
    pub l: SymCsc,
    /// Lumped mass of the free vertices.
    pub mass: Vec<f64>,
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
    /// Lumped mass of the bone vertices.
    pub mass_rigid: Vec<f64>,
    /// `-L_rd x_d` for the bone vertices.
    pub coupling_rigid: Vec<Vector3<f64>>,
}

impl GlobalSystem {
    /// Assemble for time step `h`.
    pub fn new(model: &Model, h: f64) -> Result<Self, SolverError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(SolverError::input(format!(
                "time step must be finite and positive, got {h}"
            )));
        }
        let n = model.n();
        let full = model.fem.pattern.to_sym_csc(crate::constraint::stiffness_values(model));
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
        Ok(Self {
            h,
            l_diag: l.diagonal(),
            mass: free.iter().map(|&v| model.mass[v]).collect(),
            free,
            index,
            l,
            attachment,
            coupling,
            mass_rigid: rigid.iter().map(|&v| model.mass[v]).collect(),
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
        let ih2 = 1.0 / (self.h * self.h);
        for ((y, x), m) in y.iter_mut().zip(x).zip(&self.mass) {
            *y += x * (m * ih2);
        }
    }
}

/// A contact in the free numbering.
#[derive(Debug, Clone, Copy)]
pub struct FreeContact {
    /// Free index of the vertex (for a pair between bodies: of the stencil's first entry).
    pub index: usize,
    /// The contact, on the stencil's relative coordinate.
    pub contact: Contact,
    /// Free vertices and coefficients of the relative coordinate the contact acts on.
    pub stencil: Stencil,
    /// For a contact between bodies: the pair it linearises (`None`: an obstacle contact).
    pub pair: Option<crate::contact::pair::PairContact>,
}

impl FreeContact {
    /// A contact of free vertex `index` with an obstacle.
    pub fn single(index: usize, contact: Contact) -> Self {
        Self {
            index,
            contact,
            stencil: Stencil::single(index),
            pair: None,
        }
    }
}

/// The free vertices and coefficients of a contact's relative coordinate `r = sum_k c_k x_k`
/// (one vertex with coefficient 1 for an obstacle contact; up to four for a pair of bodies).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stencil {
    /// Number of entries.
    pub len: u8,
    /// Free indices.
    pub index: [usize; 4],
    /// Coefficients.
    pub coef: [f64; 4],
}

impl Stencil {
    /// One vertex with coefficient 1.
    pub fn single(index: usize) -> Self {
        Self {
            len: 1,
            index: [index, 0, 0, 0],
            coef: [1.0, 0.0, 0.0, 0.0],
        }
    }

    /// `(free index, coefficient)` pairs.
    pub fn entries(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.index
            .iter()
            .copied()
            .zip(self.coef.iter().copied())
            .take(self.len as usize)
    }

    /// `sum_k c_k x_k`.
    pub fn apply(&self, x: &[Vector3<f64>]) -> Vector3<f64> {
        self.entries().fold(Vector3::zeros(), |acc, (i, c)| acc + x[i] * c)
    }

    /// `x_k += c_k l` for every entry.
    pub fn scatter(&self, l: &Vector3<f64>, x: &mut [Vector3<f64>]) {
        for (i, c) in self.entries() {
            x[i] += l * c;
        }
    }
}

/// What one global solve did.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct GlobalStats {
    /// Inner iterations (0 for a direct solve without contacts).
    pub iterations: usize,
    /// Largest update of the last inner iteration (m), or 0 for a direct solve.
    pub last_update: f64,
    /// Contact iterations (projected Gauss-Seidel sweeps for `Direct`).
    pub contact_iterations: usize,
    /// Whether the inner iteration met its tolerance before its cap.
    pub converged: bool,
}

/// Solves the global step.
pub trait GlobalSolver: Send {
    /// Which solver this is.
    fn kind(&self) -> SolverKind;

    /// Solve `(M/h^2 + L) x = b` on the free vertices with the given contacts; `x` holds an
    /// initial guess on entry and the solution on exit.
    fn solve(
        &mut self,
        sys: &GlobalSystem,
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
        contacts: &[FreeContact],
    ) -> Result<GlobalStats, SolverError>;

    /// The direct solver behind this one, if it is one (the skeletal step needs it).
    fn as_direct(&mut self) -> Option<&mut super::direct::Direct> {
        None
    }
}

/// Tolerances of the inner iterations.
#[derive(Debug, Clone, Copy)]
pub struct InnerControl {
    /// Stop when the largest update is below this (m).
    pub tolerance: f64,
    /// Iteration cap.
    pub max_iterations: usize,
}

/// The paper's stationary iterations in position form.
#[derive(Debug, Clone)]
pub struct Stationary {
    kind: SolverKind,
    /// Left-hand-side diagonal `W`.
    w: Vec<f64>,
    /// The part of `L` moved to the left (`D` for split, 0 for plain).
    shift: Vec<f64>,
    /// Relaxation `gamma` without contacts.
    relaxation: f64,
    /// Relaxation with contacts (kept <= 1 so projected iterates stay feasible).
    contact_relaxation: f64,
    /// Spectral radius of the relaxed iteration, for Chebyshev.
    chebyshev_rho: Option<f64>,
    control: InnerControl,
    lx: Vec<Vector3<f64>>,
    x_hat: Vec<Vector3<f64>>,
    x_prev: Vec<Vector3<f64>>,
}

impl Stationary {
    /// Plain (Eq. 19) or split (Eq. 21) with relaxation `gamma` (1 is the paper's), a contact
    /// relaxation, and Chebyshev acceleration when `chebyshev_rho` is given.
    pub fn new(
        sys: &GlobalSystem,
        kind: SolverKind,
        relaxation: f64,
        contact_relaxation: f64,
        chebyshev_rho: Option<f64>,
        control: InnerControl,
    ) -> Self {
        let ih2 = 1.0 / (sys.h * sys.h);
        let plain = kind == SolverKind::Plain;
        let w = sys
            .mass
            .iter()
            .zip(&sys.l_diag)
            .map(|(m, d)| m * ih2 + if plain { 0.0 } else { *d })
            .collect();
        let shift = if plain { vec![0.0; sys.n()] } else { sys.l_diag.clone() };
        let n = sys.n();
        Self {
            kind,
            w,
            shift,
            relaxation,
            contact_relaxation,
            chebyshev_rho,
            control,
            lx: vec![Vector3::zeros(); n],
            x_hat: vec![Vector3::zeros(); n],
            x_prev: vec![Vector3::zeros(); n],
        }
    }
}

impl GlobalSolver for Stationary {
    fn kind(&self) -> SolverKind {
        self.kind
    }

    fn solve(
        &mut self,
        sys: &GlobalSystem,
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
        contacts: &[FreeContact],
    ) -> Result<GlobalStats, SolverError> {
        let n = sys.n();
        let with_contacts = !contacts.is_empty();
        let gamma = if with_contacts {
            self.contact_relaxation
        } else {
            self.relaxation
        };
        let rho = if with_contacts { None } else { self.chebyshev_rho };
        self.x_prev.copy_from_slice(x);
        let mut omega = 1.0;
        let mut stats = GlobalStats::default();
        let mut first_update = f64::NAN;
        for k in 0..self.control.max_iterations {
            sys.l.matvec3(x, &mut self.lx);
            for i in 0..n {
                self.x_hat[i] = (b[i] - self.lx[i] + x[i] * self.shift[i]) / self.w[i];
            }
            for c in contacts {
                let i = c.index;
                let (lambda, _) = project(&self.x_hat[i], self.w[i], &c.contact);
                self.x_hat[i] += lambda / self.w[i];
            }
            // Chebyshev weights (Wang 2015): omega_1 = 1, omega_2 = 2/(2 - rho^2),
            // omega_{k+1} = 4/(4 - rho^2 omega_k).
            if let Some(r) = rho {
                let r2 = r * r;
                omega = match k {
                    0 => 1.0,
                    1 => 2.0 / (2.0 - r2),
                    _ => 4.0 / (4.0 - r2 * omega),
                };
            }
            let mut update = 0.0f64;
            for ((xi, xh), xp) in x.iter_mut().zip(&self.x_hat).zip(self.x_prev.iter_mut()) {
                let relaxed = *xi + (xh - *xi) * gamma;
                let next = if rho.is_some() {
                    *xp + (relaxed - *xp) * omega
                } else {
                    relaxed
                };
                update = update.max((xh - *xi).amax());
                *xp = *xi;
                *xi = next;
            }
            stats.iterations = k + 1;
            stats.last_update = update;
            if k == 0 {
                first_update = update;
            }
            if !update.is_finite() || update > 1e12 * first_update.max(self.control.tolerance) {
                return Err(SolverError::Diverged(format!(
                    "{:?} global iteration diverged after {} iterations (update grew from {first_update:.3e} to {update:.3e}); \
                     its spectral radius at this time step is >= 1 (run with certification to check)",
                    self.kind,
                    k + 1
                )));
            }
            if update <= self.control.tolerance {
                stats.converged = true;
                break;
            }
        }
        if with_contacts {
            stats.contact_iterations = stats.iterations;
        }
        Ok(stats)
    }
}
