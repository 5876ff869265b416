//! The constraints' part of the step energy's Hessian for Newton's method (docs/method.md
//! Eq. S4): [`ConstraintHessian`] from every kind's declared term, with the elastic part
//! projected per tet so that it is positive semidefinite ([`ElasticHessian`]).
//!
//! A tet's constraint energy is `E_t(F) = w_rot/2 |F - U V^T|^2 + w_vol/2 |F - U X V^T|^2`, the
//! squared distance of `F` to the rotations and to the unit-volume set. Its `F`-space Hessian
//! is `w I - dp/dF` (`w = w_rot + w_vol`, `p` the weighted projection of the local step), and
//! `dp/dF` is the local step's linearization `K_t` that the backward pass already has
//! ([`TetLinearization`]). In the basis `G = U^T dF V` that map is block diagonal: a 3 x 3 block
//! on `diag G` (the volume projection's Jacobian, scaled) and, for every pair `i < j`, the
//! symmetric and the antisymmetric (twist) part of `(G_ij, G_ji)` with eigenvalues `c_sym` and
//! `c_anti`. For the corotated term alone `c_sym = 0` and `c_anti = 2 w_rot/(s_i + s_j)`, so the
//! Hessian's twist eigenvalues are `w_rot (1 - 2/(s_i + s_j))` and all others `w_rot` (the
//! analytic eigensystem of Smith et al. 2019); the volume term adds its own block and pair
//! coefficients. The projected Hessian clamps every negative eigenvalue to zero, which here is
//! clamping every eigenvalue of `K_t` to at most `w`: `H_t = w I - K~_t` with `K~_t` the clamped
//! linearization. The step Hessian is then `H = A - J K~ J^T` with `A = M/h^2 + L` the
//! projective-dynamics matrix, positive definite since `M/h^2` is. The same buffers also hold
//! the unprojected `K_t` (Newton tries the exact Hessian first, see `newton.rs`).

use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use rayon::prelude::*;

use crate::constraint::{sum_corners, Constraints, HessianTerm, Linearize, ParamGrads, TetSvd};
use crate::kernel::linearization::TetLinearization;
use crate::model::Model;

/// Clamp a tet's linearization `K_t` (eigenvalues in the SVD basis, see the module docs) so
/// that `w I - K_t` is positive semidefinite; returns how many modes were clamped.
pub(crate) fn clamp_linearization(lin: &mut TetLinearization, w: f64) -> usize {
    let mut clamped = 0;
    for pair in &mut lin.pairs {
        for c in [&mut pair.0, &mut pair.1] {
            if *c > w {
                *c = w;
                clamped += 1;
            }
        }
    }
    // The block on diag G: symmetric (the Jacobian of a projection); clamp its eigenvalues.
    let d = lin.diag;
    if d != Matrix3::zeros() {
        let sym = (d + d.transpose()) * 0.5;
        let eig = SymmetricEigen::new(sym);
        let over = eig.eigenvalues.iter().filter(|&&l| l > w).count();
        if over > 0 {
            let l = eig.eigenvalues.map(|l| l.min(w));
            lin.diag = eig.eigenvectors * Matrix3::from_diagonal(&l) * eig.eigenvectors.transpose();
            clamped += over;
        } else {
            lin.diag = sym;
        }
    }
    clamped
}

/// The projected elastic Hessian of every tet at one point, applied as `J K~ J^T`.
#[derive(Debug, Clone)]
pub(crate) struct ElasticHessian {
    /// Clamped linearization `K~_t` per tet.
    lins: Vec<TetLinearization>,
    /// Clamped modes per tet at the last build (summed afterwards).
    clamped: Vec<u8>,
    /// `K~_t F_t(y) a_{t,i}` for the four corners of every tet (the gather's input,
    /// `constraint::sum_corners`).
    corners: Vec<[Vector3<f64>; 4]>,
}

impl ElasticHessian {
    /// Buffers for the tets of `model`.
    pub(crate) fn new(model: &Model) -> Self {
        let n = model.tets.len();
        Self {
            lins: vec![TetLinearization::zero(); n],
            clamped: vec![0; n],
            corners: vec![[Vector3::zeros(); 4]; n],
        }
    }

    /// Build every tet's linearization from the decompositions `rec` of the local step at the
    /// current iterate, clamped (`project`: the projected Hessian) or not (the exact one);
    /// returns the number of clamped modes. A tet where the projection is not differentiable
    /// (two singular values summing to zero, a volume projection on a branch point) gets
    /// `K~_t = 0`, i.e. the projective-dynamics block `w I`.
    pub(crate) fn build(&mut self, model: &Model, rec: &[TetSvd], project: bool) -> usize {
        let (w_rot, w_vol) = (&model.w_rot, &model.w_vol);
        self.lins
            .par_iter_mut()
            .zip(self.clamped.par_iter_mut())
            .enumerate()
            .with_min_len(64)
            .for_each(|(t, (lin, c))| {
                let r = &rec[t];
                let x = (w_vol[t] > 0.0).then_some(r.target);
                *c = 0;
                *lin = match TetLinearization::with_target(&r.svd, x, w_rot[t], w_vol[t]) {
                    Ok(mut l) if project => {
                        *c = clamp_linearization(&mut l, w_rot[t] + w_vol[t]) as u8;
                        l
                    }
                    Ok(l) => l,
                    Err(_) => TetLinearization::zero(),
                };
            });
        self.clamped.iter().map(|&c| c as usize).sum()
    }

    /// `out = J K~ J^T y` on every vertex (`y` given on every vertex, zero at fixed ones).
    pub(crate) fn apply(&mut self, model: &Model, y: &[Vector3<f64>], out: &mut [Vector3<f64>]) {
        let (lins, geo) = (&self.lins, &model.fem.geometry);
        self.corners
            .par_iter_mut()
            .enumerate()
            .with_min_len(128)
            .for_each(|(t, c)| {
                let k = lins[t].apply(&model.tet_deformation(t, y));
                for (ci, a) in c.iter_mut().zip(&geo[t].grads) {
                    *ci = k * a;
                }
            });
        sum_corners(model, &self.corners, out);
    }
}

/// Every constraint set's exact linearization `K` at the iterate, for kinds whose Hessian term
/// is [`HessianTerm::Exact`], with scratch for the parameter adjoints its application also
/// produces (discarded).
struct ExactK {
    constraints: Constraints,
    w_rot: Vec<f64>,
    w_vol: Vec<f64>,
    activations: Vec<f64>,
}

/// The constraints' part `J K~ J^T` of the step Hessian `H = A - J K~ J^T` (Eq. S4), built from
/// every kind's [`HessianTerm`]: the per-tet elastic linearization (clamped for the projected
/// Hessian), and where a kind has an exact `K` of its own (actuators), every set's exact `K` for
/// the unprojected Hessian (the projected one leaves those kinds' `K` out).
pub(crate) struct ConstraintHessian {
    elastic: ElasticHessian,
    /// Every set, for the kinds with an exact `K` of their own ([`HessianTerm::Exact`]) or their
    /// own `K~` ([`HessianTerm::Own`]); `None` without such kinds.
    exact: Option<Box<ExactK>>,
    /// Some kind's term is [`HessianTerm::Exact`].
    needs_exact: bool,
    /// Some kind's term is [`HessianTerm::Own`].
    has_own: bool,
    unprojected: bool,
}

impl ConstraintHessian {
    /// Buffers for `model`, whose kinds Newton's method supports (see
    /// [`ConstraintHessian::unsupported`]).
    pub(crate) fn new(model: &Model) -> Self {
        let constraints = Constraints::new(model);
        let needs_exact = constraints.hessian_terms().any(|(_, t)| t == HessianTerm::Exact);
        let has_own = constraints.hessian_terms().any(|(_, t)| t == HessianTerm::Own);
        let exact = (needs_exact || has_own).then(|| {
            Box::new(ExactK {
                constraints,
                w_rot: vec![0.0; model.tets.len()],
                w_vol: vec![0.0; model.tets.len()],
                activations: vec![0.0; model.actuators.as_ref().map_or(0, |a| a.groups.len())],
            })
        });
        Self {
            elastic: ElasticHessian::new(model),
            exact,
            needs_exact,
            has_own,
            unprojected: true,
        }
    }

    /// The first kind of `model` that cannot enter the Hessian, with the reason.
    pub(crate) fn unsupported(model: &Model) -> Option<&'static str> {
        Constraints::new(model).hessian_terms().find_map(|(_, t)| match t {
            HessianTerm::Unsupported(why) => Some(why),
            _ => None,
        })
    }

    /// Prepare the Hessian at the iterate `q` (every vertex; `rec` its decompositions):
    /// unprojected (`K~ = K`) or projected (Eq. S4). Returns whether the unprojected one could
    /// be linearized.
    pub(crate) fn prepare(&mut self, model: &Model, rec: &[TetSvd], q: &[Vector3<f64>], unprojected: bool) -> bool {
        self.unprojected = unprojected;
        self.elastic.build(model, rec, !unprojected);
        let Some(ex) = self.exact.as_mut() else {
            return true;
        };
        if unprojected && self.needs_exact {
            // Every set's exact K, the own terms' included (their linearization is exact).
            return ex.constraints.linearize(model, q).is_ok();
        }
        if self.has_own {
            ex.constraints.linearize_hessian(model, q, !unprojected);
        }
        true
    }

    /// Whether the last [`ConstraintHessian::prepare`] was unprojected.
    pub(crate) fn unprojected(&self) -> bool {
        self.unprojected
    }

    /// `out = J K~ J^T y` on every vertex (`y` zero at fixed vertices) at the iterate `q`;
    /// `false` where an actuator's projection is not differentiable.
    pub(crate) fn apply(
        &mut self,
        model: &Model,
        q: &[Vector3<f64>],
        activations: &[f64],
        y: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
    ) -> bool {
        match (self.unprojected && self.needs_exact, self.exact.as_mut()) {
            (true, Some(ex)) => {
                let grads = ParamGrads {
                    w_rot: &mut ex.w_rot,
                    w_vol: &mut ex.w_vol,
                    activations: &mut ex.activations,
                };
                ex.constraints
                    .adjoint(model, q, y, None, activations, Linearize::Cached, out, grads)
                    .is_ok()
            }
            (_, ex) => {
                self.elastic.apply(model, y, out);
                if let (true, Some(ex)) = (self.has_own, ex) {
                    ex.constraints.apply_hessian_add(model, y, out);
                }
                true
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::linearization::tests::mat;
    use crate::kernel::svd::svd3;

    /// The tet energy `w_rot/2 |F - R|^2 + w_vol/2 |F - U X V^T|^2` at `f`.
    fn energy(f: &Matrix3<f64>, w_rot: f64, w_vol: f64) -> f64 {
        let s = svd3(f);
        let x = crate::kernel::volume::nearest_product(&s.sigma, 1.0).unwrap();
        0.5 * w_rot * (s.sigma - Vector3::repeat(1.0)).norm_squared() + 0.5 * w_vol * (s.sigma - x).norm_squared()
    }

    /// Without clamping, `w I - K` is the energy's Hessian (second differences), and clamping
    /// leaves a positive semidefinite map that equals it where nothing was clamped.
    #[test]
    fn clamped_hessian_is_psd_and_exact_where_unclamped() {
        let (w_rot, w_vol) = (2.0, 0.7);
        let w = w_rot + w_vol;
        let mut clamped_any = false;
        for k in 0..40 {
            // Strong compressions so that some twist modes go negative.
            let f = Matrix3::identity() * (0.3 + 0.02 * k as f64) + mat(k) * 0.4;
            let s = svd3(&f);
            let x = crate::kernel::volume::nearest_product(&s.sigma, 1.0).unwrap();
            let mut lin = TetLinearization::with_target(&s, Some(x), w_rot, w_vol).unwrap();
            let exact = lin;
            let n = clamp_linearization(&mut lin, w);
            clamped_any |= n > 0;
            // PSD: <d, (w I - K~) d> >= 0 for random d.
            for j in 0..20 {
                let d = mat(1000 * k + j);
                let q = w * d.norm_squared() - d.dot(&lin.apply(&d));
                assert!(q >= -1e-10 * w * d.norm_squared(), "{q}");
            }
            if n == 0 {
                let d = mat(77 + k);
                let e = 1e-4;
                let second = (energy(&(f + d * e), w_rot, w_vol) - 2.0 * energy(&f, w_rot, w_vol)
                    + energy(&(f - d * e), w_rot, w_vol))
                    / (e * e);
                let an = w * d.norm_squared() - d.dot(&exact.apply(&d));
                assert!((second - an).abs() <= 1e-5 * (1.0 + an.abs()), "{second} vs {an}");
            }
        }
        assert!(clamped_any, "the compressed tets have negative twist modes");
    }
}
