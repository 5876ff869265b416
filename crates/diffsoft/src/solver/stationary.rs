//! The paper's stationary global iterations in position form (docs/method.md section 4): plain
//! (Eq. 19, `W = M/h^2`) or split (Eq. 21, `W = M/h^2 + D`), optionally relaxed
//! (`x += gamma (x_hat - x)`) and Chebyshev-accelerated (Wang 2015, Eq. S2). With contacts, the
//! Coulomb cone projection (Eq. C1) acts on each contact vertex's update inside the iteration,
//! as in the paper.

use nalgebra::Vector3;

use super::assembled::GlobalSystem;
use super::free_contact::FreeContact;
use super::global::{GlobalSolver, GlobalStats, InnerControl, SolverKind};
use super::SolverError;
use crate::contact::project;

/// The paper's stationary iterations in position form.
#[derive(Debug, Clone)]
pub(crate) struct Stationary {
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
    x_hat: Vec<Vector3<f64>>,
    x_prev: Vec<Vector3<f64>>,
    /// Each contact's impulse at the last projection (for output only: the backward pass
    /// treats these solvers as keeping none).
    lambda: Vec<Vector3<f64>>,
}

impl Stationary {
    /// Plain (Eq. 19) or split (Eq. 21) with relaxation `gamma` (1 is the paper's), a contact
    /// relaxation, and Chebyshev acceleration when `chebyshev_rho` is given.
    pub(crate) fn new(
        sys: &GlobalSystem,
        kind: SolverKind,
        relaxation: f64,
        contact_relaxation: f64,
        chebyshev_rho: Option<f64>,
        control: InnerControl,
    ) -> Self {
        let plain = kind == SolverKind::Plain;
        let w = sys
            .mass_h2
            .iter()
            .zip(&sys.l_diag)
            .map(|(m, d)| m + if plain { 0.0 } else { *d })
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
            x_hat: vec![Vector3::zeros(); n],
            x_prev: vec![Vector3::zeros(); n],
            // Room for a contact on every vertex, so the solve does not allocate in a step.
            lambda: Vec::with_capacity(n),
        }
    }
}

impl GlobalSolver for Stationary {
    fn kind(&self) -> SolverKind {
        self.kind
    }

    fn contact_impulses(&self) -> Option<&[Vector3<f64>]> {
        Some(&self.lambda)
    }

    fn solve(
        &mut self,
        sys: &GlobalSystem,
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
        contacts: &[FreeContact],
    ) -> Result<GlobalStats, SolverError> {
        let with_contacts = !contacts.is_empty();
        let gamma = if with_contacts {
            self.contact_relaxation
        } else {
            self.relaxation
        };
        let rho = if with_contacts { None } else { self.chebyshev_rho };
        self.x_prev.copy_from_slice(x);
        // Reserved for one contact per vertex; grows only beyond that.
        self.lambda.clear();
        self.lambda.resize(contacts.len(), Vector3::zeros());
        let mut omega = 1.0;
        let mut stats = GlobalStats::default();
        let mut first_update = f64::NAN;
        for k in 0..self.control.max_iterations {
            // x_hat = W^-1 (b - L x + shift x), each row where its product with x is made.
            let (shift, w, xr) = (&self.shift, &self.w, &*x);
            sys.l
                .map_rows3(xr, &mut self.x_hat, |i, lx| (b[i] - lx + xr[i] * shift[i]) / w[i]);
            for (c, kept) in contacts.iter().zip(self.lambda.iter_mut()) {
                let i = c.index;
                let (lambda, _) = project(&self.x_hat[i], self.w[i], &c.contact);
                self.x_hat[i] += lambda / self.w[i];
                *kept = lambda;
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
