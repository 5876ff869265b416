//! Extreme eigenvalues of the symmetric operators behind the convergence analysis.
//!
//! Every iteration matrix studied here is similar to a symmetric matrix of the form
//!
//! ```text
//!     S = c * diag(s) L diag(s) + diag(d)
//! ```
//!
//! (`L` the per-axis stiffness matrix): for instance `M^-1 L ~ M^-1/2 L M^-1/2` and
//! `G21 ~ -h^2 W^-1/2 (L - D) W^-1/2` with `W = M + h^2 D` (docs/method.md section 6). Its eigenvalues
//! are computed exactly by a dense symmetric eigensolver for small meshes and by faer's
//! thick-restart Lanczos (Krylov-Schur for symmetric operators, `partial_self_adjoint_eigen`)
//! for large ones.

use std::borrow::Cow;

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::matrix_free::eigen::{partial_self_adjoint_eigen, partial_self_adjoint_eigen_scratch, PartialEigenParams};
use faer::matrix_free::LinOp;
use faer::reborrow::ReborrowMut;
use faer::{Col, Mat, MatMut, MatRef, Par, Side};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::fem::SymCsc;

/// Which eigensolver to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum EigenMethod {
    /// Dense for `n <= DENSE_LIMIT`, Krylov above.
    Auto,
    /// Dense symmetric eigendecomposition (exact to round-off; O(n^3)).
    Dense,
    /// Matrix-free thick-restart Lanczos (faer `partial_self_adjoint_eigen`).
    Krylov,
}

/// Largest `n` for which [`EigenMethod::Auto`] uses the dense solver.
pub const DENSE_LIMIT: usize = 1500;

/// Smallest `n` for which the Krylov solver may be used (its basis needs room to restart).
pub const KRYLOV_MIN_N: usize = 256;

impl EigenMethod {
    /// The concrete method for a problem of size `n`.
    pub fn resolve(self, n: usize) -> EigenMethod {
        match self {
            EigenMethod::Auto if n <= DENSE_LIMIT => EigenMethod::Dense,
            EigenMethod::Auto => EigenMethod::Krylov,
            EigenMethod::Krylov if n < KRYLOV_MIN_N => EigenMethod::Dense,
            m => m,
        }
    }
}

/// Errors from the eigensolvers.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SpectralError {
    /// The dense eigensolver failed to converge.
    #[error("dense symmetric eigensolver did not converge (n = {n})")]
    Dense {
        /// Problem size.
        n: usize,
    },
    /// The Krylov eigensolver did not converge within its restart budget.
    #[error("Krylov eigensolver found no converged eigenvalue after {restarts} restarts (n = {n}, tolerance {tol:e})")]
    Krylov {
        /// Problem size.
        n: usize,
        /// Restart budget.
        restarts: usize,
        /// Absolute residual tolerance.
        tol: f64,
    },
    /// The operator produced a non-finite value.
    #[error("operator has non-finite entries (check mass, stiffness and time step)")]
    NonFinite,
}

/// The symmetric operator `S = c diag(s) L diag(s) + diag(d)`.
#[derive(Debug, Clone)]
pub struct ScaledOperator<'a> {
    /// `L`.
    pub l: &'a SymCsc,
    /// Symmetric scaling `s`.
    pub s: Vec<f64>,
    /// Scalar factor `c`.
    pub c: f64,
    /// Diagonal term `d`.
    pub d: Vec<f64>,
}

impl ScaledOperator<'_> {
    /// Dimension.
    pub fn n(&self) -> usize {
        self.s.len()
    }

    /// `y = S x`.
    pub fn apply_to(&self, x: &[f64], y: &mut [f64], tmp: &mut [f64]) {
        for i in 0..x.len() {
            tmp[i] = self.s[i] * x[i];
        }
        self.l.matvec(tmp, y);
        for i in 0..x.len() {
            y[i] = self.c * self.s[i] * y[i] + self.d[i] * x[i];
        }
    }

    /// Gershgorin bound on the spectral radius, `max_i sum_j |S_ij|`.
    pub fn norm_bound(&self) -> f64 {
        (0..self.n())
            .map(|j| {
                let mut sum = self.d[j].abs();
                for (i, v) in self.l.column(j) {
                    sum += (self.c * self.s[i] * v * self.s[j]).abs();
                }
                sum
            })
            .fold(0.0, f64::max)
    }

    /// The operator as a dense matrix.
    pub fn to_dense(&self) -> Mat<f64> {
        let n = self.n();
        let mut a = Mat::<f64>::zeros(n, n);
        for j in 0..n {
            for (i, v) in self.l.column(j) {
                a[(i, j)] = self.c * self.s[i] * v * self.s[j];
            }
            a[(j, j)] += self.d[j];
        }
        a
    }

    fn check_finite(&self) -> Result<(), SpectralError> {
        let ok = self.c.is_finite() && self.s.iter().all(|v| v.is_finite()) && self.d.iter().all(|v| v.is_finite());
        if ok {
            Ok(())
        } else {
            Err(SpectralError::NonFinite)
        }
    }
}

impl LinOp<f64> for ScaledOperator<'_> {
    fn apply_scratch(&self, _rhs_ncols: usize, _par: Par) -> StackReq {
        StackReq::new::<f64>(self.n())
    }

    fn nrows(&self) -> usize {
        self.n()
    }

    fn ncols(&self) -> usize {
        self.n()
    }

    fn apply(&self, mut out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, _par: Par, stack: &mut MemStack) {
        let n = self.n();
        let (mut tmp, _) = stack.make_with(n, |_| 0.0f64);
        for j in 0..rhs.ncols() {
            // The Lanczos solver passes contiguous columns; strided views are copied.
            let x = rhs.col(j);
            let xs: Cow<'_, [f64]> = match x.try_as_col_major() {
                Some(c) => Cow::Borrowed(c.as_slice()),
                None => Cow::Owned((0..n).map(|i| x[i]).collect()),
            };
            let mut y = out.rb_mut().col_mut(j);
            if let Some(ys) = y.rb_mut().try_as_col_major_mut() {
                self.apply_to(&xs, ys.as_slice_mut(), &mut tmp);
            } else {
                let mut yv = vec![0.0; n];
                self.apply_to(&xs, &mut yv, &mut tmp);
                for (i, v) in yv.into_iter().enumerate() {
                    y[i] = v;
                }
            }
        }
    }

    fn conj_apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, par: Par, stack: &mut MemStack) {
        self.apply(out, rhs, par, stack)
    }
}

/// Smallest and largest eigenvalue by dense symmetric eigendecomposition.
pub fn dense_extremes(op: &ScaledOperator<'_>) -> Result<(f64, f64), SpectralError> {
    op.check_finite()?;
    let n = op.n();
    let a = op.to_dense();
    let ev = a
        .self_adjoint_eigenvalues(Side::Lower)
        .map_err(|_| SpectralError::Dense { n })?;
    Ok((ev[0], ev[n - 1]))
}

/// Result of a Krylov eigenvalue computation.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct KrylovInfo {
    /// Absolute residual tolerance used.
    pub tolerance: f64,
    /// Eigenvalues that met the tolerance.
    pub converged: usize,
}

/// The eigenvalue of largest magnitude (with its sign) by thick-restart Lanczos. The residual
/// tolerance is `rel_tol` times the Gershgorin bound of the operator, which bounds the absolute
/// error of the eigenvalue.
pub fn krylov_largest_magnitude(op: &ScaledOperator<'_>, rel_tol: f64) -> Result<(f64, KrylovInfo), SpectralError> {
    op.check_finite()?;
    let n = op.n();
    let n_eig = 2;
    let params = PartialEigenParams {
        min_dim: 48,
        max_dim: 96.min(n / 2),
        max_restarts: 2000,
        ..Default::default()
    };
    let tol = rel_tol * op.norm_bound();
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed);
    let v0 = Col::<f64>::from_fn(n, |_| rng.random_range(-1.0..1.0));
    let mut vecs = Mat::<f64>::zeros(n, n_eig);
    let mut vals = vec![0.0; n_eig];
    let par = Par::Seq;
    let mut mem = MemBuffer::new(partial_self_adjoint_eigen_scratch(op, n_eig, par, params));
    let info = partial_self_adjoint_eigen(
        vecs.as_mut(),
        &mut vals,
        op,
        v0.as_ref(),
        tol,
        par,
        MemStack::new(&mut mem),
        params,
    );
    if info.n_converged_eigen == 0 {
        return Err(SpectralError::Krylov {
            n,
            restarts: params.max_restarts,
            tol,
        });
    }
    let best = vals[..info.n_converged_eigen]
        .iter()
        .copied()
        .fold(0.0f64, |a, b| if b.abs() > a.abs() { b } else { a });
    if !best.is_finite() {
        return Err(SpectralError::NonFinite);
    }
    Ok((
        best,
        KrylovInfo {
            tolerance: tol,
            converged: info.n_converged_eigen,
        },
    ))
}

/// Relative tolerance of Krylov eigenvalues (times the operator's Gershgorin bound).
pub const KRYLOV_REL_TOL: f64 = 1e-13;

/// Largest eigenvalue of `op`, given a shift `sigma` such that `op + sigma I` is positive
/// semidefinite (the Krylov solver returns the largest magnitude, which for a PSD operator is
/// the largest eigenvalue). Krylov subspaces are shift invariant, so the shift costs nothing.
pub fn largest_eigenvalue(op: &ScaledOperator<'_>, sigma: f64, method: EigenMethod) -> Result<f64, SpectralError> {
    match method.resolve(op.n()) {
        EigenMethod::Krylov => {
            let mut shifted = op.clone();
            for d in &mut shifted.d {
                *d += sigma;
            }
            let (v, _) = krylov_largest_magnitude(&shifted, KRYLOV_REL_TOL)?;
            Ok(v - sigma)
        }
        _ => Ok(dense_extremes(op)?.1),
    }
}

/// Spectral radius (largest |eigenvalue|) of `op`.
pub fn spectral_radius(op: &ScaledOperator<'_>, method: EigenMethod) -> Result<f64, SpectralError> {
    match method.resolve(op.n()) {
        EigenMethod::Krylov => Ok(krylov_largest_magnitude(op, KRYLOV_REL_TOL)?.0.abs()),
        _ => {
            let (lo, hi) = dense_extremes(op)?;
            Ok(lo.abs().max(hi.abs()))
        }
    }
}

crate::choice!(EigenMethod {
    Auto => "auto",
    Dense => "dense",
    Krylov => "krylov",
});
