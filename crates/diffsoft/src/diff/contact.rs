//! Derivatives of the contact solve (docs/method.md section 4) for the backward pass.
//!
//! The direct solver's global step with contacts returns `x = A^-1 (r + E lambda)`, where the
//! impulses are the fixed point of the projected Gauss-Seidel:
//! `lambda_j = Pi_j(x_j - lambda_j / w_j)`, `Pi_j` the Coulomb cone projection
//! ([`crate::contact::project`]) and `w_j = 1 / (A^-1)_{jj}`. Linearizing at that fixed point,
//! with `D_j = dPi_j/dx_hat` and `G_j = dPi_j/d anchor` (both 3x3, zero for separating
//! contacts, `-w I` and `w P_T` for sticking ones) and the Delassus entries
//! `Delta_ij = (A^-1)_{c_i c_j}`,
//!
//! `(I + D/w - D Delta) d lambda = D E^T A^-1 dr + G d anchor`.
//!
//! The adjoint of `x` therefore maps to `r_bar = z + A^-1 E D^T mu`, with `z = A^-1 x_bar` and
//! `mu` the solution of the transposed system `mu_i + D_i^T mu_i / w_i - sum_j Delta_ij D_j^T mu_j = z_{c_i}`
//! (with `w_i = 1/Delta_ii` the diagonal terms cancel); the anchors (start-of-step positions)
//! receive `G_j^T mu_j`. Only contacts with a non-zero `D_j` (touching ones) couple, so the
//! system is solved densely over those (an LU of `3a x 3a` for `a` of them), and the others'
//! `mu` follow from their own rows. The factor is kept while the Delassus block stays (the
//! local-global iterations of one contact round in unrolled mode, every iteration of an
//! implicit adjoint's fixed point): a system whose cone Jacobians moved is solved by iterative
//! refinement preconditioned with it, and factored again only when that slows. Gauss-Seidel
//! (for sticking contacts, on the SPD Delassus system: the forward PGS's own rate, thousands of
//! sweeps where a cloth drapes a body) remains for sets beyond [`DENSE_MAX_UNKNOWNS`] and as
//! the fallback when the dense path does not reach the tolerance.
//! Plane normals and points are constant; for triangle-mesh obstacles their change with the
//! closest point is ignored (exact only for planes).

use nalgebra::{Matrix3, Vector3};

use crate::contact::Contact;
use crate::solver::dense_lu::DenseLu;
use crate::solver::direct::Direct;
use crate::solver::free_contact::FreeContact;

use super::DiffError;

/// `(dlambda/dx_hat, dlambda/d anchor)` of the Coulomb cone projection at `x_hat`.
pub fn project_jacobian(x_hat: &Vector3<f64>, w: f64, c: &Contact) -> (Matrix3<f64>, Matrix3<f64>) {
    let n = c.normal;
    let gap = n.dot(&(x_hat - c.point));
    if gap >= 0.0 {
        return (Matrix3::zeros(), Matrix3::zeros());
    }
    let lambda_n = -w * gap;
    let p = Matrix3::identity() - n * n.transpose();
    let stick = -w * (p * (x_hat - c.anchor));
    let sn = stick.norm();
    if sn <= c.friction * lambda_n {
        (-Matrix3::identity() * w, p * w)
    } else {
        // lambda = n lambda_n + mu lambda_n u, u = stick / |stick|.
        let u = stick / sn;
        let du = (Matrix3::identity() - u * u.transpose()) / sn; // d u / d stick
        let dln = -w * n.transpose(); // d lambda_n / d x_hat
        let d = (n + u * c.friction) * dln + du * (c.friction * lambda_n) * (-w * p);
        let g = du * (c.friction * lambda_n) * (w * p);
        (d, g)
    }
}

/// How close a contact may come to a switch of the projection's regime (separating, sticking,
/// sliding), relative to the solve's scale, before its step counts as non-smooth: there the
/// derivative jumps, and a gradient is one of two one-sided derivatives (or between them).
pub const KINK_MARGIN: f64 = 1e-6;

/// `(candidate normal impulse -w gap, relative distance to the stick/slip boundary, gap)` of
/// a contact at `x_hat` (the second `INFINITY` without friction or when separating).
fn regime_distance(x_hat: &Vector3<f64>, w: f64, c: &Contact) -> (f64, f64, f64) {
    let n = c.normal;
    let gap = n.dot(&(x_hat - c.point));
    let lambda_n = -w * gap;
    if lambda_n <= 0.0 || c.friction <= 0.0 {
        return (lambda_n, f64::INFINITY, gap);
    }
    let p = Matrix3::identity() - n * n.transpose();
    let stick = w * (p * (x_hat - c.anchor)).norm();
    let limit = c.friction * lambda_n;
    (lambda_n, (stick - limit).abs() / limit, gap)
}

/// Contacts of one solve within [`KINK_MARGIN`] of a regime switch: touching with no force
/// (a predicted gap within 1e-9 of the model's length scale of zero, or a candidate normal
/// impulse near zero relative to the largest in the solve), or a sticking force near the
/// friction cone's boundary. `distances` holds `(-w gap, friction distance, gap)` per contact.
fn near_kinks(distances: &[(f64, f64, f64)], length_scale: f64) -> usize {
    let scale = distances.iter().map(|d| d.0.abs()).fold(0.0, f64::max);
    distances
        .iter()
        .filter(|(lambda_n, friction, gap)| {
            gap.abs() <= 1e-9 * length_scale || lambda_n.abs() <= KINK_MARGIN * scale || *friction <= KINK_MARGIN
        })
        .count()
}

/// Largest dense system (three unknowns per active contact) [`ContactAdjoint::apply`] solves
/// by LU; larger contact sets go to Gauss-Seidel. At this size the factor is 46 MB and takes
/// about as long as a few thousand Gauss-Seidel sweeps of the same contacts, which
/// ill-conditioned sets (a cloth draped over a body) need per solve.
const DENSE_MAX_UNKNOWNS: usize = 2400;

/// Refinement steps with a factor of the very system being solved (the first gives the LU
/// solution; later ones only polish rounding).
const EXACT_REFINEMENTS: usize = 4;

/// Refinement steps with a factor of an earlier system of the same contacts (the cone
/// Jacobians of sliding contacts move from one local-global iteration to the next), used as a
/// preconditioner before the system is factored again.
const STALE_REFINEMENTS: usize = 12;

/// A refinement step must shrink the residual at least this much, or the factor is taken
/// again (stale) or the solve falls back to Gauss-Seidel (exact).
const REFINEMENT_RATE: f64 = 0.25;

/// What of the previous [`ContactAdjoint::apply`] still holds for the next call.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reuse {
    /// Nothing: other contacts, or another global matrix.
    Nothing,
    /// The same contacts' stencils under the same global matrix: the Delassus block is kept,
    /// the cone Jacobians are taken again at the new impulses and solution (two local-global
    /// iterations of one contact round).
    Delassus,
    /// The same linearized system with a new right-hand side (an implicit adjoint's
    /// iterations): everything is kept and the previous solution is the starting point.
    Everything,
}

/// The transposed contact system over the contacts whose cone Jacobian is not zero, dense
/// (`3a x 3a` for `a` such contacts, block `(p, q)` equal to `I` on the diagonal and
/// `-Delta_pq D_q^T` off it), with an LU factor kept across calls while the Delassus block
/// stays.
#[derive(Debug, Default)]
struct DenseAdjoint {
    /// Whether `factor` holds the LU factor of the system of `factored_active` and
    /// `factored_dt` under the current Delassus block.
    valid: bool,
    factored_active: Vec<usize>,
    factored_dt: Vec<Matrix3<f64>>,
    factor: Vec<f64>,
    lu: DenseLu,
    /// The current call's active contacts and their `D_j^T`.
    active: Vec<usize>,
    dt: Vec<Matrix3<f64>>,
    /// Right-hand side, iterate, residual and correction (three entries per active contact).
    b: Vec<f64>,
    x: Vec<f64>,
    r: Vec<f64>,
    dx: Vec<f64>,
    /// `D_q^T x_q` per active contact (the product's inner vector).
    w: Vec<Vector3<f64>>,
}

impl DenseAdjoint {
    /// `r = b - M x` for the current active contacts and `D^T`, with `delta` the row-major
    /// `m x m` Delassus block; returns `|r|_inf`.
    fn residual(&mut self, delta: &[f64], m: usize) -> f64 {
        let a = self.active.len();
        self.w.clear();
        self.w
            .extend((0..a).map(|q| self.dt[q] * Vector3::new(self.x[3 * q], self.x[3 * q + 1], self.x[3 * q + 2])));
        let mut worst = 0.0f64;
        for (p, &i) in self.active.iter().enumerate() {
            let row = &delta[i * m..(i + 1) * m];
            let mut acc = Vector3::zeros();
            for (q, &j) in self.active.iter().enumerate() {
                if q != p {
                    acc += self.w[q] * row[j];
                }
            }
            for d in 0..3 {
                let e = self.b[3 * p + d] - (self.x[3 * p + d] - acc[d]);
                self.r[3 * p + d] = e;
                worst = worst.max(e.abs());
            }
        }
        worst
    }

    /// Build and factor the current system; false if it is singular.
    fn refactor(&mut self, delta: &[f64], m: usize) -> bool {
        let a = self.active.len();
        let k = 3 * a;
        self.factor.clear();
        self.factor.resize(k * k, 0.0);
        for (p, &i) in self.active.iter().enumerate() {
            for (q, &j) in self.active.iter().enumerate() {
                for r in 0..3 {
                    let row = &mut self.factor[(3 * p + r) * k + 3 * q..(3 * p + r) * k + 3 * q + 3];
                    if p == q {
                        row[r] = 1.0;
                    } else {
                        let dij = delta[i * m + j];
                        for (c, e) in row.iter_mut().enumerate() {
                            *e = -dij * self.dt[q][(r, c)];
                        }
                    }
                }
            }
        }
        self.valid = self.lu.factor(&mut self.factor, k);
        self.factored_active.clone_from(&self.active);
        self.factored_dt.clone_from(&self.dt);
        self.valid
    }
}

/// The adjoint of one global solve with contacts (see the module docs).
#[derive(Debug, Default)]
pub struct ContactAdjoint {
    d: Vec<Matrix3<f64>>,
    g: Vec<Matrix3<f64>>,
    mu: Vec<Vector3<f64>>,
    rhs: Vec<Vector3<f64>>,
    delta: Vec<f64>,
    /// `D_j^T mu_j` per contact.
    v: Vec<Vector3<f64>>,
    /// The dense path's system over the active contacts ([`ContactAdjoint::solve_dense`]).
    dense: DenseAdjoint,
    /// Gauss-Seidel sweeps and dense refinement steps used, summed.
    pub sweeps: usize,
    /// Largest final relative residual of the transposed contact system.
    pub worst_residual: f64,
    /// Per contact of the last solve: [`regime_distance`].
    distances: Vec<(f64, f64, f64)>,
    /// The model's length scale (m): a predicted gap below 1e-9 of it is zero.
    pub length_scale: f64,
    /// Contacts near a regime switch ([`KINK_MARGIN`]), summed over solves since the caller
    /// last reset it.
    pub near_kinks: usize,
}

/// `(dlambda/dn, dlambda/d point)` of the Coulomb cone projection at `x_hat` (the derivatives
/// with respect to the half-space's normal and point, for contacts between bodies whose
/// geometry moves with the start positions).
pub fn project_geometry_jacobian(x_hat: &Vector3<f64>, w: f64, c: &Contact) -> (Matrix3<f64>, Matrix3<f64>) {
    let n = c.normal;
    let gap = n.dot(&(x_hat - c.point));
    if gap >= 0.0 {
        return (Matrix3::zeros(), Matrix3::zeros());
    }
    let lambda_n = -w * gap;
    let rel = x_hat - c.anchor;
    let p = Matrix3::identity() - n * n.transpose();
    let stick = -w * (p * rel);
    let sn = stick.norm();
    if sn <= c.friction * lambda_n {
        // lambda = -w (x_hat - a) + w n (n . (point - a)).
        let b = c.point - c.anchor;
        (
            (Matrix3::identity() * n.dot(&b) + n * b.transpose()) * w,
            n * n.transpose() * w,
        )
    } else {
        // lambda = (n + mu u) lambda_n, u = stick / |stick|, stick = -w P(n) rel.
        let u = stick / sn;
        let du = (Matrix3::identity() - u * u.transpose()) / sn;
        let dstick_dn = (Matrix3::identity() * n.dot(&rel) + n * rel.transpose()) * w;
        let dir = n + u * c.friction;
        let dn =
            (Matrix3::identity() + du * dstick_dn * c.friction) * lambda_n - dir * (x_hat - c.point).transpose() * w;
        let dp = dir * n.transpose() * w;
        (dn, dp)
    }
}

/// What the backward pass knows of a step's start, for contacts between bodies (their
/// coefficients and normals depend on the start positions).
#[derive(Debug, Clone, Copy)]
pub struct PairInputs<'a> {
    /// Positions at the start of the step (global numbering).
    pub q_start: &'a [Vector3<f64>],
    /// Global vertex -> free index (`usize::MAX` for fixed vertices).
    pub free_index: &'a [usize],
    /// Collision thickness.
    pub thickness: f64,
}

impl ContactAdjoint {
    /// Buffers for a model of this length scale (m), which sets what a zero gap is.
    pub fn with_length_scale(length_scale: f64) -> Self {
        Self {
            length_scale,
            ..Self::default()
        }
    }

    /// Given `z = A^-1 x_bar` (in place, free numbering), the contacts and the impulses they ended
    /// with and the solution `x` of the solve: turn `z` into `r_bar` and add the adjoints of the
    /// start positions (anchors; for contacts between bodies also their coefficients and
    /// normals, through `pairs`) to `anchor_bar` (global vertex numbering). `impulse_bar`, when
    /// given, is a direct adjoint of the impulses themselves (one per contact; the skeleton's
    /// step reuses them in its next iteration).
    ///
    /// `reuse` says what of the previous call still holds ([`Reuse`]): its Delassus block, or
    /// the whole linearized system (then the previous solution is the starting point too).
    /// `dense`: the system may be solved by the dense path (otherwise, and when that path
    /// declines, by Gauss-Seidel).
    #[allow(clippy::too_many_arguments)]
    pub fn apply(
        &mut self,
        direct: &mut Direct,
        contacts: &[FreeContact],
        impulses: &[Vector3<f64>],
        impulse_bar: Option<&[Vector3<f64>]>,
        x: &[Vector3<f64>],
        z: &mut [Vector3<f64>],
        anchor_bar: &mut [Vector3<f64>],
        pairs: Option<PairInputs<'_>>,
        tolerance: f64,
        max_sweeps: usize,
        reuse: Reuse,
        dense: bool,
    ) -> Result<(), DiffError> {
        let m = contacts.len();
        if m == 0 {
            return Ok(());
        }
        // What the caller says holds, checked against the sizes kept.
        let reuse = match reuse {
            Reuse::Everything if self.d.len() == m && self.mu.len() == m => Reuse::Everything,
            Reuse::Everything | Reuse::Delassus if self.delta.len() == m * m => Reuse::Delassus,
            _ => Reuse::Nothing,
        };
        if reuse != Reuse::Everything {
            self.prepare(direct, contacts, impulses, x, reuse == Reuse::Delassus)?;
        }
        let reuse = reuse == Reuse::Everything;
        self.rhs.clear();
        self.rhs.extend(contacts.iter().map(|c| c.stencil.apply(z)));
        if let Some(lb) = impulse_bar {
            if lb.len() != m {
                return Err(DiffError::Input(format!(
                    "{} impulse adjoints for {m} contacts",
                    lb.len()
                )));
            }
            for (r, l) in self.rhs.iter_mut().zip(lb) {
                *r += l;
            }
        }
        if !reuse {
            self.mu.clear();
            self.mu.extend_from_slice(&self.rhs);
        }
        if !(dense && self.solve_dense(tolerance)) {
            self.solve_transposed(tolerance, max_sweeps)?;
        }
        self.finish(direct, contacts, impulses, x, z, anchor_bar, pairs)
    }

    /// The step's linearized contact system: the Delassus block `Delta = C A^-1 C^T` between
    /// the contacts' stencils (kept from the previous call when `same_delassus`) and each cone
    /// projection's Jacobians at the impulse it ended with.
    fn prepare(
        &mut self,
        direct: &mut Direct,
        contacts: &[FreeContact],
        impulses: &[Vector3<f64>],
        x: &[Vector3<f64>],
        same_delassus: bool,
    ) -> Result<(), DiffError> {
        let m = contacts.len();
        if impulses.len() != m {
            return Err(DiffError::Unsupported(
                "contacts were solved by an iterative global solver: gradients with contact need `solver: direct`"
                    .into(),
            ));
        }
        if !same_delassus {
            for c in contacts {
                for (i, _) in c.stencil.entries() {
                    direct.inverse_column(i);
                }
            }
            direct.delassus_matrix(contacts.iter().map(|c| &c.stencil), &mut self.delta);
            self.dense.valid = false;
        }
        self.d.clear();
        self.g.clear();
        self.distances.clear();
        for (j, (c, l)) in contacts.iter().zip(impulses).enumerate() {
            let djj = self.delta[j * m + j];
            let w = 1.0 / djj;
            let x_hat = c.stencil.apply(x) - l * djj;
            let (d, g) = project_jacobian(&x_hat, w, &c.contact);
            self.d.push(d);
            self.g.push(g);
            self.distances.push(regime_distance(&x_hat, w, &c.contact));
        }
        self.near_kinks += near_kinks(&self.distances, self.length_scale);
        Ok(())
    }

    /// `mu = rhs + Delta' D^T mu` (off-diagonal `Delta`) by a dense LU of the contacts with a
    /// non-zero cone Jacobian, the factor kept across calls while the Delassus block stays and
    /// used to precondition iterative refinement when only the Jacobians moved (refactored
    /// when the refinement slows). To the residual `tolerance` relative to the largest entry of
    /// `rhs` and `mu`, the same scale as the Gauss-Seidel's change; false (nothing solved,
    /// `mu` a valid start) when the set is too large for the dense path, the system singular
    /// or the refinement does not reach the tolerance.
    fn solve_dense(&mut self, tolerance: f64) -> bool {
        let m = self.d.len();
        let dense = &mut self.dense;
        dense.active.clear();
        dense.active.extend((0..m).filter(|&j| self.d[j] != Matrix3::zeros()));
        let a = dense.active.len();
        let k = 3 * a;
        if k > DENSE_MAX_UNKNOWNS {
            return false;
        }
        dense.dt.clear();
        dense.dt.extend(dense.active.iter().map(|&j| self.d[j].transpose()));
        dense.b.clear();
        dense
            .b
            .extend(dense.active.iter().flat_map(|&j| self.rhs[j].iter().copied()));
        for buf in [&mut dense.x, &mut dense.r, &mut dense.dx] {
            buf.clear();
            buf.resize(k, 0.0);
        }
        let rhs_scale = self.rhs.iter().map(|v| v.amax()).fold(0.0, f64::max);
        // No touching contact: every mu is its right-hand side, one pass.
        let mut solved = a == 0;
        if solved {
            self.sweeps += 1;
        }
        let mut exact = dense.valid && dense.factored_active == dense.active && dense.factored_dt == dense.dt;
        let stale = dense.valid && dense.factored_active == dense.active;
        if !solved && !stale {
            if !dense.refactor(&self.delta, m) {
                return false;
            }
            exact = true;
        }
        while !solved {
            // From x = 0: the first correction is the factor's solution of b.
            dense.x.iter_mut().for_each(|x| *x = 0.0);
            dense.r.copy_from_slice(&dense.b);
            let mut previous = f64::INFINITY;
            let steps = if exact { EXACT_REFINEMENTS } else { STALE_REFINEMENTS };
            for _ in 0..steps {
                dense.dx.copy_from_slice(&dense.r);
                if !dense.lu.solve_factored(&dense.factor, &mut dense.dx, k) {
                    break;
                }
                for (x, dx) in dense.x.iter_mut().zip(&dense.dx) {
                    *x += dx;
                }
                self.sweeps += 1;
                let residual = dense.residual(&self.delta, m);
                let scale = dense
                    .x
                    .iter()
                    .fold(rhs_scale, |s, x| s.max(x.abs()))
                    .max(f64::MIN_POSITIVE);
                if residual / scale <= tolerance {
                    self.worst_residual = self.worst_residual.max(residual / scale);
                    solved = true;
                    break;
                }
                if residual.is_nan() || residual >= REFINEMENT_RATE * previous {
                    break;
                }
                previous = residual;
            }
            if solved {
                break;
            }
            if exact || !dense.refactor(&self.delta, m) {
                return false;
            }
            exact = true;
        }
        // mu and v on every contact: the active ones from the solution, the others from
        // their equation `mu_i = rhs_i + sum_j Delta_ij v_j`.
        self.v.clear();
        self.v.resize(m, Vector3::zeros());
        for (p, &j) in dense.active.iter().enumerate() {
            let mu = Vector3::new(dense.x[3 * p], dense.x[3 * p + 1], dense.x[3 * p + 2]);
            self.mu[j] = mu;
            self.v[j] = dense.dt[p] * mu;
        }
        for i in 0..m {
            if self.d[i] == Matrix3::zeros() {
                let row = &self.delta[i * m..(i + 1) * m];
                self.mu[i] = dense
                    .active
                    .iter()
                    .fold(self.rhs[i], |acc, &j| acc + self.v[j] * row[j]);
            }
        }
        true
    }

    /// `mu = rhs + Delta' D^T mu` (off-diagonal `Delta`) by Gauss-Seidel from the current `mu`,
    /// to `tolerance` relative change or `max_sweeps`.
    fn solve_transposed(&mut self, tolerance: f64, max_sweeps: usize) -> Result<(), DiffError> {
        let m = self.d.len();
        // v_j = D_j^T mu_j; mu_i = rhs_i + sum_{j != i} Delta_ij v_j (Gauss-Seidel).
        let scale = self
            .rhs
            .iter()
            .map(|v| v.amax())
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        let mut residual = f64::INFINITY;
        let mut v = std::mem::take(&mut self.v);
        v.clear();
        v.extend(self.mu.iter().zip(&self.d).map(|(mu, d)| d.transpose() * mu));
        let mut sweeps = 0;
        while sweeps < max_sweeps {
            sweeps += 1;
            let mut change = 0.0f64;
            for i in 0..m {
                let mut acc = self.rhs[i];
                let row = &self.delta[i * m..(i + 1) * m];
                for (j, vj) in v.iter().enumerate() {
                    if j != i {
                        acc += vj * row[j];
                    }
                }
                change = change.max((acc - self.mu[i]).amax());
                self.mu[i] = acc;
                v[i] = self.d[i].transpose() * acc;
            }
            residual = change / scale.max(self.mu.iter().map(|v| v.amax()).fold(0.0, f64::max));
            if residual <= tolerance {
                break;
            }
        }
        self.sweeps += sweeps;
        self.worst_residual = self.worst_residual.max(residual);
        self.v = v;
        if !residual.is_finite() {
            return Err(DiffError::NotDifferentiable(
                "the linearized contact system diverged".into(),
            ));
        }
        Ok(())
    }

    /// From the solved `mu`: `z += A^-1 C^T v` and the adjoints of the start positions.
    #[allow(clippy::too_many_arguments)]
    fn finish(
        &mut self,
        direct: &mut Direct,
        contacts: &[FreeContact],
        impulses: &[Vector3<f64>],
        x: &[Vector3<f64>],
        z: &mut [Vector3<f64>],
        anchor_bar: &mut [Vector3<f64>],
        pairs: Option<PairInputs<'_>>,
    ) -> Result<(), DiffError> {
        let m = contacts.len();
        let v = std::mem::take(&mut self.v);
        for (j, c) in contacts.iter().enumerate() {
            if c.pair.is_none() {
                anchor_bar[c.contact.vertex] += self.g[j].transpose() * self.mu[j];
            }
            direct.add_inverse_columns(&c.stencil, &v[j], z);
        }
        // Contacts between bodies: their coefficients, normal, point and anchor move with the
        // start positions (z is now r_bar = z + A^-1 E v).
        for (j, c) in contacts.iter().enumerate() {
            let Some(pair) = c.pair.as_ref() else {
                continue;
            };
            let inputs = pairs.ok_or_else(|| {
                DiffError::Unsupported("contacts between bodies need the step's start positions".into())
            })?;
            let q = inputs.q_start;
            let djj = self.delta[j * m + j];
            let x_hat = c.stencil.apply(x) - impulses[j] * djj;
            let (hn, hp) = project_geometry_jacobian(&x_hat, 1.0 / djj, &c.contact);
            let mu = self.mu[j];
            let anchor_bar_j = self.g[j].transpose() * mu;
            let point_bar = hp.transpose() * mu;
            let n_bar = hn.transpose() * mu + point_bar * inputs.thickness;
            let mut c_bar = [0.0; 4];
            let mut e = 0;
            for (k, (&vtx, cb)) in pair.vertices.iter().zip(c_bar.iter_mut()).enumerate() {
                let fi = inputs.free_index[vtx];
                if fi == usize::MAX {
                    // point = n th - sum_fixed c_k q_k.
                    *cb -= point_bar.dot(&q[vtx]);
                    continue;
                }
                debug_assert_eq!(c.stencil.index[e], fi);
                e += 1;
                // anchor = sum_free c_k q_k; the solve's impulse enters as c_k lambda (x_k) and
                // the relative coordinate as c_k x_k.
                anchor_bar[vtx] += anchor_bar_j * pair.coefs[k];
                *cb += anchor_bar_j.dot(&q[vtx]) + z[fi].dot(&impulses[j]) + v[j].dot(&x[fi]);
            }
            let (dc, dn) = pair.jacobian(q);
            for (jj, &vtx) in pair.vertices.iter().enumerate() {
                let grad = Vector3::from_fn(|d, _| {
                    let col = 3 * jj + d;
                    dn[col].dot(&n_bar) + dc[col].iter().zip(&c_bar).map(|(a, b)| a * b).sum::<f64>()
                });
                anchor_bar[vtx] += grad;
            }
        }
        self.v = v;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::project;

    fn contact(mu: f64) -> Contact {
        Contact {
            vertex: 0,
            obstacle: 0,
            normal: Vector3::new(0.2, 1.0, -0.1).normalize(),
            point: Vector3::new(0.0, 0.01, 0.0),
            anchor: Vector3::new(0.03, 0.1, 0.02),
            friction: mu,
        }
    }

    /// A linearized contact system of `m` contacts sharing vertices (a Delassus block
    /// `B B^T` of a random stencil matrix `B`, so neighbouring contacts couple strongly), each
    /// contact separating, sticking or sliding by its index; `shift` moves the sliding
    /// contacts' slip.
    fn system(m: usize, shift: f64) -> ContactAdjoint {
        let cols = m + 4;
        let b: Vec<f64> = (0..m * cols)
            .map(|i| {
                let (r, c) = (i / cols, i % cols);
                if c == r || c == r + 1 || c == r + 3 {
                    1.0 + ((r * 7 + c * 3) % 5) as f64 * 0.2
                } else {
                    0.0
                }
            })
            .collect();
        let mut ca = ContactAdjoint {
            delta: (0..m * m)
                .map(|i| {
                    let (r, c) = (i / m, i % m);
                    (0..cols).map(|k| b[r * cols + k] * b[c * cols + k]).sum::<f64>()
                })
                .collect(),
            ..ContactAdjoint::default()
        };
        for j in 0..m {
            let w = 1.0 / ca.delta[j * m + j];
            let mut c = contact(0.4);
            c.normal = Vector3::new(0.1 * (j as f64).sin(), 1.0, 0.05).normalize();
            let x_hat = match j % 3 {
                0 => Vector3::new(0.0, 0.5, 0.0),                     // separating
                1 => c.anchor + Vector3::new(0.001, -0.2, 0.0),       // sticking
                _ => c.anchor + Vector3::new(0.3 + shift, -0.5, 0.2), // sliding
            };
            ca.d.push(project_jacobian(&x_hat, w, &c).0);
            ca.rhs
                .push(Vector3::new(1.0 + j as f64, -0.5 * j as f64, (j as f64).cos()));
        }
        ca.mu = ca.rhs.clone();
        ca
    }

    /// Largest entry of `mu - rhs - Delta' D^T mu` over the largest entry of `rhs`.
    fn residual(ca: &ContactAdjoint) -> f64 {
        let m = ca.d.len();
        let scale = ca.rhs.iter().map(|v| v.amax()).fold(0.0, f64::max);
        (0..m)
            .map(|i| {
                let mut acc = ca.rhs[i];
                for j in (0..m).filter(|&j| j != i) {
                    acc += ca.d[j].transpose() * ca.mu[j] * ca.delta[i * m + j];
                }
                (ca.mu[i] - acc).amax() / scale
            })
            .fold(0.0, f64::max)
    }

    /// The dense path solves the transposed contact system to its tolerance, agrees with
    /// Gauss-Seidel run to convergence, and solves a system whose sliding contacts moved
    /// with its earlier factor (refinement) without factoring again.
    #[test]
    fn dense_adjoint_matches_gauss_seidel_and_reuses_its_factor() {
        let m = 30;
        let mut dense = system(m, 0.0);
        for j in 0..m {
            let w = 1.0 / dense.delta[j * m + j];
            match j % 3 {
                0 => assert_eq!(dense.d[j], Matrix3::zeros()),
                1 => assert_eq!(dense.d[j], -Matrix3::identity() * w),
                _ => assert!(dense.d[j] != Matrix3::zeros() && dense.d[j] != dense.d[j].transpose()),
            }
        }
        assert!(dense.solve_dense(1e-14));
        assert!(residual(&dense) < 1e-13, "{}", residual(&dense));
        let mut gs = system(m, 0.0);
        gs.solve_transposed(1e-15, 1_000_000).unwrap();
        for (a, b) in dense.mu.iter().zip(&gs.mu) {
            assert!((a - b).amax() <= 1e-10 * b.amax().max(1.0), "{a} vs {b}");
        }
        // The separating contacts' mu follows from the others (their v is zero).
        for j in (0..m).step_by(3) {
            assert_eq!(dense.v[j], Vector3::zeros());
        }
        // Sliding contacts moved a little: the old factor preconditions the new system.
        let moved = system(m, 1e-3);
        assert!(moved.d[2] != dense.d[2]);
        let factor = dense.dense.factor.clone();
        dense.d.clone_from(&moved.d);
        let sweeps = dense.sweeps;
        assert!(dense.solve_dense(1e-14));
        assert!(residual(&dense) < 1e-13, "{}", residual(&dense));
        assert_eq!(dense.dense.factor, factor, "refactored a system its old factor solves");
        assert!(
            dense.sweeps - sweeps > 1,
            "no refinement needed: the systems did not differ"
        );
        // A sticking contact that slides instead: the old factor no longer converges fast
        // enough and the system is factored again.
        dense.d[1] = dense.d[2];
        assert!(dense.solve_dense(1e-14));
        assert!(residual(&dense) < 1e-13, "{}", residual(&dense));
        assert_ne!(dense.dense.factor, factor);
        assert_eq!(dense.dense.factored_dt[0], dense.d[1].transpose());
    }

    /// Both Jacobians match central differences in the stick and slide states.
    #[test]
    fn projection_jacobians_match_differences() {
        for (x_hat, mu) in [
            (Vector3::new(0.04, -0.1, 0.01), 0.8), // stick
            (Vector3::new(0.9, -0.1, 0.3), 0.5),   // slide
            (Vector3::new(-0.4, -0.02, 0.7), 0.1), // slide
        ] {
            let mut c = contact(mu);
            let w = 2.5;
            let (d, g) = project_jacobian(&x_hat, w, &c);
            let e = 1e-7;
            for k in 0..3 {
                let mut dx = Vector3::zeros();
                dx[k] = e;
                let fd = (project(&(x_hat + dx), w, &c).0 - project(&(x_hat - dx), w, &c).0) / (2.0 * e);
                assert!((fd - d.column(k)).norm() < 1e-6, "{fd} vs {}", d.column(k));
                let a0 = c.anchor;
                c.anchor = a0 + dx;
                let p = project(&x_hat, w, &c).0;
                c.anchor = a0 - dx;
                let m = project(&x_hat, w, &c).0;
                c.anchor = a0;
                let fd = (p - m) / (2.0 * e);
                assert!((fd - g.column(k)).norm() < 1e-6, "{fd} vs {}", g.column(k));
            }
        }
    }
}
