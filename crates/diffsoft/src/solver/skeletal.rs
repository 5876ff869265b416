//! The reduced global step with an embedded skeleton (paper Eqs. 7-8, 17-18).
//!
//! Split the vertices into free ones `F` and bone vertices `R` (`q_R = q_R(z)`, rigid per
//! bone). With the per-axis matrix `A = M/h^2 + L`, eliminating the free vertices from
//! `min 1/2 q^T A q - b^T q` leaves a quadratic in the bone vertices with the Schur complement
//! `Sigma = A_RR - A_RF A_FF^-1 A_FR`. `A` is constant, so `A_FF` is factored once and
//! `W = A_FF^-1 A_FR` and `Sigma` are computed once per time step size (one solve per bone
//! vertex). Each local-global iteration then takes one Gauss-Newton step in the joint
//! coordinates, `(B^T Sigma B) dz = B^T (g - Sigma q_R) + tau` with `B = dq_R/dz` (Eqs. 12-16)
//! and `g = b_R - A_RF A_FF^-1 b_F`, joint torques `tau` added to the rigid block (Eq. 18);
//! updates the joints with their exact rules (so bones keep their shape to round-off); and sets
//! the free vertices to `q_F = A_FF^-1 b_F - W q_R`, one free solve per iteration.
//!
//! Contacts act on free vertices (bone vertices sit inside the body): their impulses from the
//! previous iteration enter the skeleton's right-hand side, and after the skeleton update the
//! direct solver's projected Gauss-Seidel finds the current ones.

use faer::Mat;
use nalgebra::{DMatrix, DVector, Vector3};

use super::assembled::GlobalSystem;
use super::direct::Direct;
use super::free_contact::FreeContact;
use super::global::{GlobalStats, InnerControl};
use super::SolverError;
use crate::contact::{project, Contact};
use crate::skeleton::Skeleton;

/// Precomputed Schur complement and buffers of the skeletal step.
#[derive(Debug, Clone)]
pub(crate) struct Skeletal {
    /// `W = A_FF^-1 A_FR`, `n_F x n_R`.
    w: DMatrix<f64>,
    /// `Sigma = A_RR - A_RF W`, `n_R x n_R`.
    sigma: DMatrix<f64>,
    b_jac: DMatrix<f64>,
    q_r: Vec<Vector3<f64>>,
    y0: Vec<Vector3<f64>>,
    y: Vec<Vector3<f64>>,
    torque: Vec<f64>,
    /// Contact impulses of the previous iteration, `(free index, impulse)`.
    impulses: Vec<(usize, Vector3<f64>)>,
    // Per-iteration buffers (allocated once; the contact ones grow to the largest count seen).
    /// `g - Sigma q_R` per bone vertex.
    resid: Vec<Vector3<f64>>,
    /// `B` with its rows grouped by axis, `n_R x 3 dofs`.
    bcat: DMatrix<f64>,
    /// `Sigma bcat`, `n_R x 3 dofs`.
    sb: DMatrix<f64>,
    /// `B^T Sigma B` and then its Cholesky factor.
    s: DMatrix<f64>,
    /// Right-hand side, then the joint increment.
    dz: DVector<f64>,
    /// Contacts on bone vertices and joint limits: `[S^-1 B_c^T, S^-1 E]` (column-major,
    /// `dofs x (3m + limits)`), contact weights and impulses.
    c_g: Vec<f64>,
    /// Rows of `B` at the contact vertices (row-major, `3 dofs` per contact).
    c_rows: Vec<f64>,
    c_w: Vec<f64>,
    c_lambda: Vec<Vector3<f64>>,
    /// Bone vertices of the previous call's contacts (to warm-start `c_lambda`).
    c_prev: Vec<usize>,
    /// Joint limits of this iteration: `(coordinate, lo, hi)` bounds on its increment.
    limits: Vec<(usize, f64, f64)>,
    /// Their multipliers.
    c_mu: Vec<f64>,
    /// The bones' world transforms (scratch).
    world: Vec<nalgebra::Matrix4<f64>>,
}

impl Skeletal {
    /// Precompute `W` and `Sigma` with the factored free block.
    pub(crate) fn new(sys: &GlobalSystem, direct: &Direct, skeleton: &Skeleton) -> Self {
        let (nf, nr) = (sys.n(), sys.rigid.len());
        // A_FR as dense columns, then W = A_FF^-1 A_FR.
        let mut cols = Mat::<f64>::zeros(nf, nr);
        for (r, list) in sys.l_rf.iter().enumerate() {
            for &(f, v) in list {
                cols[(f, r)] = v;
            }
        }
        if nr > 0 && nf > 0 {
            direct.solve_columns(&mut cols);
        }
        let w = DMatrix::from_fn(nf, nr, |i, j| cols[(i, j)]);
        let mut sigma = DMatrix::from_fn(nr, nr, |i, j| sys.l_rr[i * nr + j]);
        for r in 0..nr {
            sigma[(r, r)] += sys.mass_rigid_h2[r];
            for &(f, v) in &sys.l_rf[r] {
                for c in 0..nr {
                    sigma[(r, c)] -= v * w[(f, c)];
                }
            }
        }
        // Symmetrise against round-off.
        let sigma = (&sigma + sigma.transpose()) * 0.5;
        Self {
            w,
            sigma,
            b_jac: DMatrix::zeros(3 * nr, skeleton.dofs),
            q_r: vec![Vector3::zeros(); nr],
            y0: vec![Vector3::zeros(); nf],
            y: vec![Vector3::zeros(); nf],
            torque: vec![0.0; skeleton.dofs],
            impulses: Vec::new(),
            resid: vec![Vector3::zeros(); nr],
            bcat: DMatrix::zeros(nr, 3 * skeleton.dofs),
            sb: DMatrix::zeros(nr, 3 * skeleton.dofs),
            s: DMatrix::zeros(skeleton.dofs, skeleton.dofs),
            dz: DVector::zeros(skeleton.dofs),
            c_g: Vec::new(),
            c_rows: Vec::new(),
            c_w: Vec::new(),
            c_lambda: Vec::new(),
            c_prev: Vec::new(),
            limits: Vec::new(),
            c_mu: Vec::new(),
            world: Vec::with_capacity(skeleton.bones.len()),
        }
    }

    /// `W = A_FF^-1 A_FR` (`n_F x n_R`).
    pub(crate) fn w(&self) -> &DMatrix<f64> {
        &self.w
    }

    /// The Schur complement `Sigma = A_RR - A_RF W` (`n_R x n_R`).
    pub(crate) fn sigma(&self) -> &DMatrix<f64> {
        &self.sigma
    }

    /// The joint increment of the last [`Skeletal::solve`] (after limits and contacts).
    pub(crate) fn last_increment(&self) -> &[f64] {
        self.dz.as_slice()
    }

    /// The residual `g - Sigma q_R` of the last solve, per bone vertex.
    pub(crate) fn last_residual(&self) -> &[Vector3<f64>] {
        &self.resid
    }

    /// Joint limits active in the last solve: `(coordinate, multiplier)` with a nonzero
    /// multiplier.
    pub(crate) fn active_limits(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.limits
            .iter()
            .zip(&self.c_mu)
            .filter(|(_, &mu)| mu != 0.0)
            .map(|(&(k, _, _), &mu)| (k, mu))
    }

    /// Contacts on bone vertices in the last solve: their impulses and the weights `w_j` of the
    /// projected Gauss-Seidel (in the order of the `rigid_contacts` passed to it).
    pub(crate) fn rigid_contact_solution(&self) -> impl Iterator<Item = (Vector3<f64>, f64)> + '_ {
        self.c_lambda.iter().copied().zip(self.c_w.iter().copied())
    }

    /// Forget contact impulses (at the start of a step).
    pub(crate) fn reset_impulses(&mut self) {
        self.impulses.clear();
    }

    /// One reduced global step: updates the skeleton, writes the free positions into `x_f` and
    /// the bone-vertex positions into `q_r_out` (skeleton order).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn solve(
        &mut self,
        sys: &GlobalSystem,
        direct: &mut Direct,
        skeleton: &mut Skeleton,
        b_f: &[Vector3<f64>],
        b_r: &[Vector3<f64>],
        time: f64,
        x_f: &mut [Vector3<f64>],
        q_r_out: &mut [Vector3<f64>],
        contacts: &[FreeContact],
        rigid_contacts: &[(usize, Contact)],
        control: InnerControl,
    ) -> Result<GlobalStats, SolverError> {
        let nr = sys.rigid.len();
        let mut rigid_sweeps = 0;
        direct.solve_free(b_f, &mut self.y0)?;
        // y = A_FF^-1 (b_F + previous impulses), by linearity with cached columns.
        self.y.copy_from_slice(&self.y0);
        for &(i, l) in &self.impulses {
            let col = direct.inverse_column(i);
            for (yk, c) in self.y.iter_mut().zip(col) {
                *yk += l * *c;
            }
        }
        // g = b_R - A_RF y (kept in `resid` until Sigma q_R is subtracted below).
        for (r, g) in self.resid.iter_mut().enumerate() {
            let mut v = b_r[r];
            for &(f, a) in &sys.l_rf[r] {
                v -= self.y[f] * a;
            }
            *g = v;
        }
        skeleton.positions_with(&mut self.world, &mut self.q_r);
        skeleton.jacobian_with(&mut self.world, &mut self.b_jac);
        skeleton.torques(time, &mut self.torque);
        let dofs = skeleton.dofs;
        if dofs > 0 {
            // resid = g - Sigma q_R; SB = (Sigma (x) I3) B; S = B^T SB; rhs = B^T resid + tau.
            // With B's rows regrouped by axis (`bcat[c, d dofs + k] = B[3c + d, k]`) the
            // Kronecker product is one product `Sigma bcat` of contiguous columns.
            for r in 0..nr {
                let mut acc = Vector3::zeros();
                for (c, q) in self.q_r.iter().enumerate() {
                    acc += q * self.sigma[(r, c)];
                }
                self.resid[r] -= acc;
            }
            let (bj, nrr) = (self.b_jac.as_slice(), nr.max(1));
            for (k, col) in bj.chunks_exact(3 * nrr).enumerate() {
                for d in 0..3 {
                    let j = d * dofs + k;
                    let dst = &mut self.bcat.as_mut_slice()[j * nr..(j + 1) * nr];
                    for (c, v) in dst.iter_mut().enumerate() {
                        *v = col[3 * c + d];
                    }
                }
            }
            self.sb.gemm(1.0, &self.sigma, &self.bcat, 0.0);
            let (bc, sbs) = (self.bcat.as_slice(), self.sb.as_slice());
            let column = |j: usize| j * nr..(j + 1) * nr;
            for k1 in 0..dofs {
                for k2 in k1..dofs {
                    let mut acc = 0.0;
                    for d in 0..3 {
                        let (a, b) = (&bc[column(d * dofs + k1)], &sbs[column(d * dofs + k2)]);
                        acc += a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
                    }
                    self.s[(k1, k2)] = acc;
                    self.s[(k2, k1)] = acc;
                }
            }
            for k in 0..dofs {
                let mut acc = self.torque[k];
                for d in 0..3 {
                    let col = &bc[column(d * dofs + k)];
                    acc += col.iter().zip(&self.resid).map(|(b, r)| b * r[d]).sum::<f64>();
                }
                self.dz[k] = acc;
            }
            let chol = match factor_spd(std::mem::replace(&mut self.s, DMatrix::zeros(0, 0))) {
                Ok(chol) => chol,
                Err(e) => {
                    self.s = DMatrix::zeros(dofs, dofs);
                    return Err(e);
                }
            };
            chol.solve_mut(&mut self.dz);
            // Joint limits as bounds on the increment.
            self.limits.clear();
            for b in &skeleton.bones {
                if let Some((lo, hi)) = b.joint.increment_bounds() {
                    self.limits.push((b.dof_offset, lo, hi));
                }
            }
            let violated = self
                .limits
                .iter()
                .any(|&(k, lo, hi)| self.dz[k] < lo || self.dz[k] > hi);
            if !rigid_contacts.is_empty() || violated {
                rigid_sweeps = self.constrained(&chol, rigid_contacts, control);
            } else {
                self.c_mu.clear();
            }
            self.s = chol.unpack();
            if !self.dz.as_slice().iter().all(|v| v.is_finite()) {
                return Err(SolverError::NonFinite(
                    "skeleton step produced a non-finite joint increment".into(),
                ));
            }
            skeleton.update(self.dz.as_slice());
            skeleton.positions_with(&mut self.world, &mut self.q_r);
        }
        // Free vertices given the bones: q_F = A_FF^-1 b_F - W q_R (W column by column).
        x_f.copy_from_slice(&self.y0);
        let nf = x_f.len();
        for (r, col) in self.w.as_slice().chunks_exact(nf.max(1)).enumerate() {
            let qr = self.q_r[r];
            for (x, &wv) in x_f.iter_mut().zip(col) {
                *x -= qr * wv;
            }
        }
        q_r_out.copy_from_slice(&self.q_r);
        let mut stats = direct.apply_contacts(x_f, contacts);
        stats.contact_iterations += rigid_sweeps;
        self.impulses.clear();
        self.impulses.extend(direct.indexed_impulses());
        Ok(stats)
    }

    /// Contacts on bone vertices and joint limits, in the reduced coordinates. With
    /// `dz = dz_0 + G lambda + H mu` (`G = S^-1 B_c^T`, `H` the columns of `S^-1` at limited
    /// coordinates), a projected Gauss-Seidel runs over both kinds of constraint: each contact
    /// sees its vertex at `x_j = q_j + B_j dz` and takes the Coulomb cone update in relaxation
    /// form (`x_hat = x_j - lambda_j / w_j`, `w_j = 1 / lambda_max(B_j G_j)`),
    /// so the fixed point obeys Coulomb's law at the true positions; each limit takes the multiplier that puts its
    /// coordinate's increment back into `[lo, hi]` (zero when it is inside). `dz` is updated after
    /// every change, so limits and contacts act on each other (an arm at its limit pushed by the
    /// ground moves its parent). Multipliers are warm-started when the constraint set repeats.
    /// Returns the sweeps used. Works in preallocated buffers.
    fn constrained(
        &mut self,
        chol: &nalgebra::Cholesky<f64, nalgebra::Dyn>,
        rigid_contacts: &[(usize, Contact)],
        control: InnerControl,
    ) -> usize {
        let m = rigid_contacts.len();
        let nl = self.limits.len();
        let dofs = self.dz.len();
        let b = &self.b_jac;
        let row = |j: usize, a: usize| 3 * rigid_contacts[j].0 + a;
        // G = S^-1 B_c^T (column 3j + a is S^-1 (row a of B_j)^T) and H = S^-1 e_k.
        self.c_g.clear();
        self.c_g.resize(dofs * (3 * m + nl), 0.0);
        for j in 0..m {
            for a in 0..3 {
                let col = &mut self.c_g[(3 * j + a) * dofs..(3 * j + a + 1) * dofs];
                for (k, c) in col.iter_mut().enumerate() {
                    *c = b[(row(j, a), k)];
                }
            }
        }
        for (l, &(k, _, _)) in self.limits.iter().enumerate() {
            self.c_g[(3 * m + l) * dofs + k] = 1.0;
        }
        // The contact rows of B, contiguous (row-major 3 x dofs per contact) for the sweeps.
        self.c_rows.clear();
        self.c_rows.extend_from_slice(&self.c_g[..3 * m * dofs]);
        {
            let mut view = nalgebra::DMatrixViewMut::from_slice(&mut self.c_g, dofs, 3 * m + nl);
            chol.solve_mut(&mut view);
        }
        let col = |c: &[f64], i: usize| -> std::ops::Range<usize> {
            debug_assert!(c.len() >= (i + 1) * dofs);
            i * dofs..(i + 1) * dofs
        };
        // Contact weights `1 / lambda_max(D_jj)` of the diagonal Delassus blocks
        // `D_jj = B_j G_j`: the largest scalar weight with which a contact's own update never
        // overshoots (exact when `D_jj` is isotropic; the trace, 3x smaller, converged 3x slower).
        self.c_w.clear();
        for j in 0..m {
            let mut d = nalgebra::Matrix3::zeros();
            for a in 0..3 {
                for c in 0..3 {
                    let g = &self.c_g[col(&self.c_g, 3 * j + c)];
                    d[(a, c)] = (0..dofs).map(|k| b[(row(j, a), k)] * g[k]).sum::<f64>();
                }
            }
            let lmax = ((d + d.transpose()) * 0.5).symmetric_eigenvalues().max();
            self.c_w.push(1.0 / lmax.max(f64::MIN_POSITIVE));
        }
        // Warm start when the same contact vertices (and the same limits) repeat.
        let same = self.c_prev.len() == m && self.c_prev.iter().zip(rigid_contacts).all(|(&a, c)| a == c.0);
        if !same {
            self.c_prev.clear();
            self.c_prev.extend(rigid_contacts.iter().map(|c| c.0));
            self.c_lambda.clear();
            self.c_lambda.resize(m, Vector3::zeros());
        }
        if self.c_mu.len() != nl {
            self.c_mu.clear();
            self.c_mu.resize(nl, 0.0);
        }
        // dz = dz_0 + G lambda + H mu.
        for (j, l) in self.c_lambda.iter().enumerate() {
            for a in 0..3 {
                let g = &self.c_g[col(&self.c_g, 3 * j + a)];
                for (d, gk) in self.dz.as_mut_slice().iter_mut().zip(g) {
                    *d += gk * l[a];
                }
            }
        }
        for (l, &mu) in self.c_mu.iter().enumerate() {
            let h = &self.c_g[col(&self.c_g, 3 * m + l)];
            for (d, hk) in self.dz.as_mut_slice().iter_mut().zip(h) {
                *d += hk * mu;
            }
        }
        let mut sweeps = 0;
        for sweep in 0..control.max_iterations {
            let mut change = 0.0f64;
            for (j, (r, contact)) in rigid_contacts.iter().enumerate() {
                let mut x = self.q_r[*r];
                // x_j = q_j + B_j dz: the three rows' sums side by side (each in its own
                // order, from -0.0 as `Iterator::sum`), so they are three independent chains.
                let rows = &self.c_rows[3 * j * dofs..3 * (j + 1) * dofs];
                let (r0, rest) = rows.split_at(dofs);
                let (r1, r2) = rest.split_at(dofs);
                let mut sum = [-0.0f64; 3];
                for (((b0, b1), b2), dk) in r0.iter().zip(r1).zip(r2).zip(self.dz.as_slice()) {
                    sum[0] += b0 * dk;
                    sum[1] += b1 * dk;
                    sum[2] += b2 * dk;
                }
                for a in 0..3 {
                    x[a] += sum[a];
                }
                let w = self.c_w[j];
                let x_hat = x - self.c_lambda[j] / w;
                let (new, _) = project(&x_hat, w, contact);
                let delta = new - self.c_lambda[j];
                if delta != Vector3::zeros() {
                    // dz += G_j delta, one pass (per entry the three terms in axis order).
                    let g = &self.c_g[3 * j * dofs..3 * (j + 1) * dofs];
                    let (g0, rest) = g.split_at(dofs);
                    let (g1, g2) = rest.split_at(dofs);
                    for (((d, a0), a1), a2) in self.dz.as_mut_slice().iter_mut().zip(g0).zip(g1).zip(g2) {
                        *d += a0 * delta[0];
                        *d += a1 * delta[1];
                        *d += a2 * delta[2];
                    }
                }
                change = change.max((delta / w).amax());
                self.c_lambda[j] = new;
            }
            for (l, &(k, lo, hi)) in self.limits.iter().enumerate() {
                let h = &self.c_g[col(&self.c_g, 3 * m + l)];
                let hkk = h[k].max(f64::MIN_POSITIVE);
                // The increment without this limit's own multiplier.
                let free = self.dz[k] - hkk * self.c_mu[l];
                let mu = if free < lo {
                    (lo - free) / hkk
                } else if free > hi {
                    (hi - free) / hkk
                } else {
                    0.0
                };
                let delta = mu - self.c_mu[l];
                if delta != 0.0 {
                    for (d, hk) in self.dz.as_mut_slice().iter_mut().zip(h) {
                        *d += hk * delta;
                    }
                }
                change = change.max((delta * hkk).abs());
                self.c_mu[l] = mu;
            }
            sweeps = sweep + 1;
            if change <= control.tolerance {
                break;
            }
        }
        sweeps
    }
}

/// Cholesky of a small symmetric positive (semi)definite matrix, regularising coordinates that
/// move no vertex (zero rows) so they stay put.
fn factor_spd(mut s: DMatrix<f64>) -> Result<nalgebra::Cholesky<f64, nalgebra::Dyn>, SolverError> {
    let n = s.nrows();
    let scale = (0..n)
        .map(|k| s[(k, k)].abs())
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    for k in 0..n {
        s[(k, k)] += 1e-14 * scale;
    }
    s.cholesky().ok_or_else(|| {
        SolverError::Factorization("the reduced skeleton matrix B^T Sigma B is not positive definite".into())
    })
}
