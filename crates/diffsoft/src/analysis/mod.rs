//! Convergence analysis of the paper's contact iterations (docs/method.md sections 4 and 6).
//!
//! With the contact impulse `xi` and right-hand side `f` fixed, the plain iteration (Eq. 19)
//! and the split iteration (Eq. 21) are linear stationary iterations with iteration matrices
//!
//! ```text
//!     G19 = -h^2 M^-1 L                      rho(G19) = h^2 lambda_max(M^-1 L)
//!     G21 = -(M + h^2 D)^-1 h^2 (L - D)      D = diag(L)
//! ```
//!
//! Both are similar to symmetric matrices, so their eigenvalues are real and are computed
//! exactly (dense) or by Lanczos ([`spectral`]). The critical time steps follow in closed form:
//!
//! * `h*_19 = 1 / sqrt(lambda_max(M^-1 L))`;
//! * `G21` converges iff `M + h^2 (2D - L)` is positive definite (its eigenvalues are always
//!   below `+1` because `M + h^2 L > 0`; staying above `-1` gives this condition), so
//!   `h*_21 = 1 / sqrt(lambda_max(M^-1 (L - 2D)))` when that eigenvalue is positive, and (21)
//!   converges for every `h` otherwise. By Sylvester's law of inertia the latter holds iff
//!   `lambda_max(D^-1 L) <= 2`, and `rho(G21) -> max(1, lambda_max(D^-1 L) - 1)` as `h -> inf`.
//!
//! [`appendix`] evaluates the appendix's A/B claims against these exact values,
//! [`empirical`] runs the iterations themselves, and [`sweep`] traces `rho(dt)`.

pub mod appendix;
pub mod bounds;
pub mod empirical;
pub mod spectral;
pub mod sweep;

use serde::Serialize;

use crate::fem::{Coefficient, FemError, FemOperators, SymCsc};
use crate::mesh::TetMesh;
use spectral::{EigenMethod, ScaledOperator, SpectralError};

/// Errors of the analysis module.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum AnalysisError {
    /// FEM assembly failed.
    #[error(transparent)]
    Fem(#[from] FemError),
    /// An eigensolver failed.
    #[error(transparent)]
    Spectral(#[from] SpectralError),
    /// A physical parameter is meaningless.
    #[error("{name} must be finite and positive, got {}", crate::base::number(*value))]
    BadParameter {
        /// Parameter name.
        name: &'static str,
        /// Offending value.
        value: f64,
    },
    /// An attachment refers to a vertex that does not exist.
    #[error("attachment vertex {vertex} out of range (mesh has {n} vertices)")]
    BadAttachment {
        /// Vertex index.
        vertex: usize,
        /// Number of vertices.
        n: usize,
    },
}

/// Check a scalar parameter is finite and positive.
pub fn positive(name: &'static str, value: f64) -> Result<f64, AnalysisError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(AnalysisError::BadParameter { name, value })
    }
}

/// Attachment springs (penalty pins) that add `stiffness` to the diagonal of `L` at `vertices`,
/// as the paper's bridge scenes do ("Attach Stiffness" 1e20).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Attachments {
    /// Pinned vertices (0-based, mesh numbering).
    pub vertices: Vec<usize>,
    /// Spring weight per pinned vertex.
    pub stiffness: f64,
}

/// Attachments at least this many times stiffer than the elastic diagonal of their row are
/// treated in their Dirichlet limit when computing `h*_21` (see [`Spectrum::compute`]).
pub const STIFF_ATTACHMENT_RATIO: f64 = 1e8;

/// The per-axis linear system of one body: lumped mass `M`, stiffness `L` (plus attachments)
/// and its diagonal `D`. Everything the iterations (19) and (21) depend on.
#[derive(Debug, Clone)]
pub struct IterationSystem {
    /// `L`, including attachment springs on the diagonal.
    pub l: SymCsc,
    /// Lumped mass per vertex.
    pub mass: Vec<f64>,
    /// `D = diag(L)`.
    pub diag: Vec<f64>,
    /// Attachment stiffness added to each vertex's diagonal (empty without attachments).
    pub attachment: Vec<f64>,
}

impl IterationSystem {
    /// Assemble for uniform density `rho` and stiffness coefficient `mu` (`L = sum mu V A^T A`).
    ///
    /// ```
    /// use diffsoft::analysis::{Attachments, IterationSystem};
    /// use diffsoft::mesh::generate::BoxSpec;
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let sys = IterationSystem::new(&mesh, 1000.0, 1e5, &Attachments::default())?;
    /// assert_eq!(sys.n(), 8);
    /// assert!((sys.mass.iter().sum::<f64>() - 1.0).abs() < 1e-12); // rho V
    /// assert!(sys.attachment.is_empty());
    /// // A pin as stiff as the paper's: its row is taken in the Dirichlet limit.
    /// let pinned = IterationSystem::new(&mesh, 1000.0, 1e5, &Attachments { vertices: vec![0], stiffness: 1e20 })?;
    /// assert_eq!(pinned.stiff_rows().iter().filter(|&&s| s).count(), 1);
    /// assert!(IterationSystem::new(&mesh, -1.0, 1e5, &Attachments::default()).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(mesh: &TetMesh, rho: f64, mu: f64, attachments: &Attachments) -> Result<Self, AnalysisError> {
        let fem = FemOperators::new(mesh)?;
        Self::from_fem(
            &fem,
            Coefficient::Uniform(positive("density rho", rho)?),
            Coefficient::Uniform(positive("stiffness mu", mu)?),
            attachments,
        )
    }

    /// Assemble from precomputed FEM operators and (possibly per-tet) coefficients.
    ///
    /// ```
    /// use diffsoft::analysis::{Attachments, IterationSystem};
    /// use diffsoft::fem::{Coefficient, FemOperators};
    /// use diffsoft::mesh::generate::BoxSpec;
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let fem = FemOperators::new(&mesh)?;
    /// // A stiffer half: per-tet coefficients.
    /// let mu: Vec<f64> = (0..mesh.num_tets()).map(|t| if t < 3 { 1e6 } else { 1e5 }).collect();
    /// let (rho, none) = (Coefficient::Uniform(1000.0), Attachments::default());
    /// let sys = IterationSystem::from_fem(&fem, rho, Coefficient::PerTet(&mu), &none)?;
    /// let uniform = IterationSystem::new(&mesh, 1000.0, 1e5, &Attachments::default())?;
    /// assert_eq!(sys.mass, uniform.mass);
    /// assert!(sys.diag.iter().zip(&uniform.diag).all(|(a, b)| a >= b));
    /// // One coefficient per tet, or an error.
    /// assert!(IterationSystem::from_fem(&fem, rho, Coefficient::PerTet(&mu[..2]), &none).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn from_fem(
        fem: &FemOperators,
        rho: Coefficient<'_>,
        mu: Coefficient<'_>,
        attachments: &Attachments,
    ) -> Result<Self, AnalysisError> {
        let mass = fem.lumped_mass(rho)?;
        let mut l = fem.laplacian_csc(mu)?;
        let n = fem.num_vertices();
        let mut attachment = Vec::new();
        if !attachments.vertices.is_empty() {
            positive("attachment stiffness", attachments.stiffness)?;
            attachment = vec![0.0; n];
        }
        for &v in &attachments.vertices {
            if v >= n {
                return Err(AnalysisError::BadAttachment { vertex: v, n });
            }
            l.values[fem.pattern.diag_slot[v]] += attachments.stiffness;
            attachment[v] += attachments.stiffness;
        }
        let diag = l.diagonal();
        Ok(Self {
            l,
            mass,
            diag,
            attachment,
        })
    }

    /// A system from an already assembled per-axis `L` (attachments included) and lumped mass;
    /// `attachment` is the spring weight per vertex (empty if none).
    ///
    /// ```
    /// use diffsoft::analysis::IterationSystem;
    /// use diffsoft::fem::{Coefficient, FemOperators};
    /// use diffsoft::mesh::generate::BoxSpec;
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let fem = FemOperators::new(&mesh)?;
    /// let l = fem.laplacian_csc(Coefficient::Uniform(1e5))?;
    /// let sys = IterationSystem::from_parts(l.clone(), vec![0.125; 8], Vec::new())?;
    /// assert_eq!(sys.diag, l.diagonal());
    /// // Every lumped mass must be positive.
    /// assert!(IterationSystem::from_parts(l, vec![0.0; 8], Vec::new()).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn from_parts(l: SymCsc, mass: Vec<f64>, attachment: Vec<f64>) -> Result<Self, AnalysisError> {
        for &m in &mass {
            positive("lumped mass", m)?;
        }
        let diag = l.diagonal();
        Ok(Self {
            l,
            mass,
            diag,
            attachment,
        })
    }

    /// Number of vertices (size of the per-axis system).
    pub fn n(&self) -> usize {
        self.mass.len()
    }

    /// Rows whose attachment is at least [`STIFF_ATTACHMENT_RATIO`] times their elastic diagonal.
    pub fn stiff_rows(&self) -> Vec<bool> {
        if self.attachment.is_empty() {
            return vec![false; self.n()];
        }
        (0..self.n())
            .map(|i| {
                let a = self.attachment[i];
                a > 0.0 && a >= STIFF_ATTACHMENT_RATIO * (self.diag[i] - a)
            })
            .collect()
    }

    /// The system restricted to the rows without stiff attachments (their Dirichlet limit), or
    /// `None` when no row is stiff.
    ///
    /// ```
    /// use diffsoft::analysis::{Attachments, IterationSystem};
    /// use diffsoft::mesh::generate::BoxSpec;
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let free = IterationSystem::new(&mesh, 1000.0, 1e5, &Attachments::default())?;
    /// assert!(free.without_stiff_rows().is_none());
    /// let pins = Attachments { vertices: vec![0, 1], stiffness: 1e20 };
    /// let reduced = IterationSystem::new(&mesh, 1000.0, 1e5, &pins)?.without_stiff_rows().ok_or("no stiff rows")?;
    /// assert_eq!(reduced.n(), 6);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn without_stiff_rows(&self) -> Option<IterationSystem> {
        let stiff = self.stiff_rows();
        if !stiff.iter().any(|&s| s) {
            return None;
        }
        let keep: Vec<bool> = stiff.iter().map(|s| !s).collect();
        let (l, kept) = self.l.principal_submatrix(&keep);
        Some(IterationSystem {
            diag: l.diagonal(),
            l,
            mass: kept.iter().map(|&i| self.mass[i]).collect(),
            attachment: kept.iter().map(|&i| self.attachment[i]).collect(),
        })
    }

    fn op(&self, s: Vec<f64>, c: f64, d: Vec<f64>) -> ScaledOperator<'_> {
        ScaledOperator { l: &self.l, s, c, d }
    }

    /// `M^-1/2 L M^-1/2`, similar to `M^-1 L`.
    pub fn op_minv_l(&self) -> ScaledOperator<'_> {
        let s = self.mass.iter().map(|m| 1.0 / m.sqrt()).collect();
        self.op(s, 1.0, vec![0.0; self.n()])
    }

    /// `M^-1/2 (L - 2D) M^-1/2`, whose largest eigenvalue decides `h*_21`.
    pub fn op_split_critical(&self) -> ScaledOperator<'_> {
        let s = self.mass.iter().map(|m| 1.0 / m.sqrt()).collect();
        let d = self.diag.iter().zip(&self.mass).map(|(d, m)| -2.0 * d / m).collect();
        self.op(s, 1.0, d)
    }

    /// `D^-1/2 L D^-1/2`, similar to `D^-1 L` (the Jacobi matrix of `L`).
    pub fn op_dinv_l(&self) -> ScaledOperator<'_> {
        let s = self.diag.iter().map(|d| 1.0 / d.sqrt()).collect();
        self.op(s, 1.0, vec![0.0; self.n()])
    }

    /// `-h^2 W^-1/2 (L - D) W^-1/2` with `W = M + h^2 D`, similar to `G21`.
    pub fn op_g21(&self, h: f64) -> ScaledOperator<'_> {
        let h2 = h * h;
        let w: Vec<f64> = self.mass.iter().zip(&self.diag).map(|(m, d)| m + h2 * d).collect();
        let s = w.iter().map(|w| 1.0 / w.sqrt()).collect();
        let d = self.diag.iter().zip(&w).map(|(d, w)| h2 * d / w).collect();
        self.op(s, -h2, d)
    }

    /// `-h^2 M^-1/2 L M^-1/2`, similar to `G19`.
    pub fn op_g19(&self, h: f64) -> ScaledOperator<'_> {
        let mut op = self.op_minv_l();
        op.c = -h * h;
        op
    }
}

/// The three eigenvalues that decide convergence of (19) and (21) for every time step.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Spectrum {
    /// `lambda_max(M^-1 L)`, units 1/s^2.
    pub lambda_max_minv_l: f64,
    /// `lambda_max(M^-1 (L - 2D))`, units 1/s^2; (21) converges for every `h` iff `<= 0`.
    pub lambda_max_minv_l_minus_2d: f64,
    /// `lambda_max(D^-1 L)` (dimensionless, at least 1); (21) converges for every `h` iff `<= 2`.
    pub lambda_max_dinv_l: f64,
    /// Scale of the operator behind `h*_21` (`max 2 D_ii / M_ii`): eigenvalues below `1e-12`
    /// of it are round-off.
    pub split_critical_scale: f64,
    /// Rows with stiff attachments eliminated (Dirichlet limit) when computing `h*_21`.
    pub split_critical_eliminated_rows: usize,
    /// Solver used.
    pub method: EigenMethod,
}

impl Spectrum {
    /// Compute the spectrum quantities with the given method.
    ///
    /// Stiff attachment springs (at least [`STIFF_ATTACHMENT_RATIO`] times the elastic diagonal,
    /// like the paper's 1e20) put eigenvalues of size `w / m` into `M^-1 (L - 2D)` next to the
    /// elastic ones that decide `h*_21`; no global eigensolver resolves the latter then (its
    /// absolute error is `eps w / m`). Those rows are eliminated for this one eigenvalue: by the
    /// Schur complement, the neglected term is `O(L_ii / w)` relative.
    ///
    /// ```
    /// use diffsoft::analysis::spectral::EigenMethod;
    /// use diffsoft::analysis::{Attachments, IterationSystem, Spectrum};
    /// use diffsoft::mesh::generate::BoxSpec;
    ///
    /// let mesh = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1]).build()?;
    /// let sys = IterationSystem::new(&mesh, 1000.0, 1e5, &Attachments::default())?;
    /// let spectrum = Spectrum::compute(&sys, EigenMethod::Auto)?;
    /// assert_eq!(spectrum.method, EigenMethod::Dense); // small: dense
    /// // (19) converges below h*_19, where its spectral radius reaches 1.
    /// let h19 = spectrum.critical_dt_plain();
    /// assert!((spectrum.rho_plain(h19) - 1.0).abs() < 1e-12);
    /// // Kuhn tets give an M-matrix: (21) converges for every time step.
    /// assert!(spectrum.critical_dt_split().is_none());
    /// assert!(spectrum.lambda_max_dinv_l <= 2.0 + 1e-12);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn compute(sys: &IterationSystem, method: EigenMethod) -> Result<Self, AnalysisError> {
        let method = method.resolve(sys.n());
        let lambda_max_minv_l = spectral::largest_eigenvalue(&sys.op_minv_l(), 0.0, method)?;
        let reduced = sys.without_stiff_rows();
        let split_sys = reduced.as_ref().unwrap_or(sys);
        // M^-1/2 (L - 2D) M^-1/2 + sigma I >= M^-1/2 L M^-1/2 >= 0 for sigma = max 2 D/M.
        let sigma = split_sys
            .diag
            .iter()
            .zip(&split_sys.mass)
            .map(|(d, m)| 2.0 * d / m)
            .fold(0.0, f64::max);
        let lambda_max_minv_l_minus_2d =
            spectral::largest_eigenvalue(&split_sys.op_split_critical(), sigma, method.resolve(split_sys.n()))?;
        let lambda_max_dinv_l = spectral::largest_eigenvalue(&sys.op_dinv_l(), 0.0, method)?;
        Ok(Self {
            lambda_max_minv_l,
            lambda_max_minv_l_minus_2d,
            lambda_max_dinv_l,
            split_critical_scale: sigma,
            split_critical_eliminated_rows: sys.n() - split_sys.n(),
            method,
        })
    }

    /// `h*_19 = 1 / sqrt(lambda_max(M^-1 L))`: (19) converges iff `h < h*_19`.
    pub fn critical_dt_plain(&self) -> f64 {
        1.0 / self.lambda_max_minv_l.sqrt()
    }

    /// `rho(G19) = h^2 lambda_max(M^-1 L)`.
    pub fn rho_plain(&self, h: f64) -> f64 {
        h * h * self.lambda_max_minv_l
    }

    /// `h*_21`, or `None` when (21) converges for every `h`. A positive eigenvalue below
    /// `1e-12` of the operator's scale is treated as round-off (converges for every `h`).
    pub fn critical_dt_split(&self) -> Option<f64> {
        if self.lambda_max_minv_l_minus_2d > 1e-12 * self.split_critical_scale {
            Some(1.0 / self.lambda_max_minv_l_minus_2d.sqrt())
        } else {
            None
        }
    }

    /// `lim_{h -> inf} rho(G21) = max(1, lambda_max(D^-1 L) - 1)`.
    pub fn rho_split_limit(&self) -> f64 {
        (self.lambda_max_dinv_l - 1.0).max(1.0)
    }
}

/// Smallest and largest eigenvalue of `G21` at time step `h` (the largest is always below 1;
/// the smallest is below -1 exactly when (21) diverges). They give the optimal relaxation
/// `gamma = 2 / (2 - mu_min - mu_max)` of the split iteration, whose relaxed spectral radius
/// `(mu_max - mu_min) / (2 - mu_min - mu_max)` is below 1 for every `h`.
///
pub fn split_extremes(sys: &IterationSystem, h: f64, method: EigenMethod) -> Result<(f64, f64), AnalysisError> {
    positive("time step", h)?;
    let op = sys.op_g21(h);
    match method.resolve(op.n()) {
        EigenMethod::Krylov => {
            let (first, _) = spectral::krylov_largest_magnitude(&op, spectral::KRYLOV_REL_TOL)?;
            // The other end is the largest-magnitude eigenvalue of op - first I.
            let mut shifted = op.clone();
            for d in &mut shifted.d {
                *d -= first;
            }
            let (second, _) = spectral::krylov_largest_magnitude(&shifted, spectral::KRYLOV_REL_TOL)?;
            let other = second + first;
            Ok((first.min(other), first.max(other)))
        }
        _ => Ok(spectral::dense_extremes(&op)?),
    }
}

/// `rho(G21)` at time step `h`.
pub fn rho_split(sys: &IterationSystem, h: f64, method: EigenMethod) -> Result<f64, AnalysisError> {
    positive("time step", h)?;
    Ok(spectral::spectral_radius(&sys.op_g21(h), method)?)
}
