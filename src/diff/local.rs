//! Derivatives of the local step (METHOD.md Eq. 3) for the backward pass.
//!
//! A tet's weighted projection `p(F) = w_rot U V^T + w_vol U X(sigma) V^T` is an isotropic
//! matrix function of `F = U diag(sigma) V^T`. Its differential, with `G = U^T dF V`, is
//! `dp = U H V^T` where `H_ii = w_vol (J dsigma)_i` (`J = dX/dsigma` of the nearest product,
//! `dsigma = diag G`) and, for `i != j`,
//! `H_ij = c_sym (G_ij + G_ji)/2 + c_anti (G_ij - G_ji)/2` with
//! `c_sym = w_vol (x_i - x_j)/(s_i - s_j)`, `c_anti = w_rot 2/(s_i + s_j) + w_vol (x_i + x_j)/(s_i + s_j)`
//! (the spectral-function differential of Lewis and Sendov). A projection onto a set is the
//! gradient of `|F|^2/2 - dist(F, C)^2/2`, so `dp/dF` is symmetric: the same routine gives the
//! Jacobian-vector and the vector-Jacobian product (a unit test checks the symmetry).
//!
//! The local step enters the right-hand side as `J p = sum_t p_t a_t` (gathered per vertex), and
//! `F_t(x) = sum_a x_a a_{t,a}^T`, so the adjoint of `p_t` given the adjoint `y` of the
//! right-hand side is `F_t(y)`: the backward of one iteration is "deformation gradient of `y`,
//! apply `dp/dF`, gather", the forward's own data path.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::actuator::ActuatorKind;
use crate::kernel::actuator::{muscle_jacobian, nearest_product_jacobian, pair_coefficients};
#[doc(hidden)]
pub use crate::kernel::linearization::TetLinearization;
use crate::kernel::linearization::PAIRS;
use crate::kernel::svd::{svd3_warm, svd3_warm_batch, LANES};
use crate::kernel::volume;
use crate::model::Model;

use super::DiffError;

/// `F_t(x) = sum_a x_a a_{t,a}^T` (the deformation gradient of tet `t`, or the adjoint of its
/// projection when `x` is an adjoint).
#[inline]
pub fn deformation(model: &Model, t: usize, x: &[Vector3<f64>]) -> Matrix3<f64> {
    let [i0, i1, i2, i3] = model.tets[t];
    let x0 = x[i0];
    Matrix3::from_columns(&[x[i1] - x0, x[i2] - x0, x[i3] - x0]) * model.fem.geometry[t].p_inv
}

/// Where the backward of a local step gets each tet's linearization.
#[derive(Debug, Clone, Copy)]
pub enum Linearize<'a> {
    /// Decompose `F` again at the given positions.
    Recompute,
    /// The cache of [`LocalAdjoint::linearize`].
    Cached,
    /// The decompositions the forward recorded at these positions.
    Recorded(&'a [crate::solver::local::TetSvd]),
}

/// Per-tet and per-cell buffers of the local step's backward pass.
#[derive(Debug, Clone)]
pub struct LocalAdjoint {
    /// `dp_t` per tet (what is gathered).
    pub dp: Vec<Matrix3<f64>>,
    /// Warm start of the SVDs.
    pub v_warm: Vec<Matrix3<f64>>,
    /// Cached linearizations (implicit mode: one point, many applications).
    pub cache: Vec<TetLinearization>,
    /// `dp` per actuator cell.
    pub dp_cells: Vec<Matrix3<f64>>,
    /// Activation adjoint per actuator cell.
    pub da_cells: Vec<f64>,
    /// Cloth scratch buffers (`None` without cloth).
    pub cloth: Option<crate::cloth::ClothStep>,
}

impl LocalAdjoint {
    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        let cells = model.actuators.as_ref().map_or(0, |a| a.cells.len());
        Self {
            dp: vec![Matrix3::zeros(); model.tets.len()],
            v_warm: vec![Matrix3::identity(); model.tets.len()],
            cache: Vec::new(),
            dp_cells: vec![Matrix3::zeros(); cells],
            da_cells: vec![0.0; cells],
            cloth: model.cloth.as_ref().map(crate::cloth::ClothStep::new),
        }
    }

    /// Linearize every tet at `q` into the cache (implicit mode).
    pub fn linearize(&mut self, model: &Model, q: &[Vector3<f64>]) -> Result<(), DiffError> {
        let (w_rot, w_vol) = (&model.w_rot, &model.w_vol);
        let v_warm = &mut self.v_warm;
        let out: Result<Vec<TetLinearization>, DiffError> = v_warm
            .par_iter_mut()
            .enumerate()
            .with_min_len(64)
            .map(|(t, vw)| {
                let svd = svd3_warm(&deformation(model, t, q), vw);
                *vw = svd.v;
                TetLinearization::new(&svd, w_rot[t], w_vol[t])
                    .map_err(|m| DiffError::NotDifferentiable(format!("tet {t}: {m}")))
            })
            .collect();
        self.cache = out?;
        Ok(())
    }

    /// The backward of one local step at positions `q` (all vertices): given the adjoint `y` of
    /// the gathered right-hand side (all vertices, zero at fixed ones), write
    /// `out = J (dp/dq)^T J^T y` per vertex and add the weights' adjoints
    /// `<F_t(y), U V^T> - <F_t(y), F_t(x_next)>` to `g_rot[t]` and
    /// `<F_t(y), U X V^T> - <F_t(y), F_t(x_next)>` to `g_vol[t]` (right-hand side minus matrix
    /// term of the solve whose solution is `x_next`), and the activations'
    /// adjoints to `g_act[group]`. `lin` says where the tets' linearizations at `q` come from. Without `x_next` the matrix term is left out (the
    /// caller adds it with [`LocalAdjoint::matrix_terms`]).
    #[allow(clippy::too_many_arguments)]
    pub fn backward(
        &mut self,
        model: &Model,
        q: &[Vector3<f64>],
        y: &[Vector3<f64>],
        x_next: Option<&[Vector3<f64>]>,
        activations: &[f64],
        lin: Linearize<'_>,
        out: &mut [Vector3<f64>],
        g_rot: &mut [f64],
        g_vol: &mut [f64],
        g_act: &mut [f64],
    ) -> Result<(), DiffError> {
        let (w_rot, w_vol) = (&model.w_rot, &model.w_vol);
        let cache = &self.cache;
        let any_vol = w_vol.iter().any(|&w| w > 0.0);
        let fail = |t: usize, m: &str| DiffError::NotDifferentiable(format!("tet {t}: {m}"));
        // LANES tets at a time: batched (AVX2) SVD and volume projection, as the forward.
        self.dp
            .par_chunks_mut(LANES)
            .zip(self.v_warm.par_chunks_mut(LANES))
            .zip(g_rot.par_chunks_mut(LANES).zip(g_vol.par_chunks_mut(LANES)))
            .enumerate()
            .with_min_len(8)
            .try_for_each(|(chunk, ((dp, vw), (gr, gv)))| {
                let t0 = chunk * LANES;
                let len = dp.len();
                let mut process = |k: usize, lin: &TetLinearization| {
                    let t = t0 + k;
                    let fy = deformation(model, t, y);
                    dp[k] = lin.apply(&fy);
                    // d(J p)/dw minus dA/dw x_next (L_t = w A_t^T A_t per weight).
                    let a_term = x_next.map_or(0.0, |x| fy.dot(&deformation(model, t, x)));
                    gr[k] += fy.dot(&lin.rotation) - a_term;
                    gv[k] += fy.dot(&lin.volume) - a_term;
                };
                if let Linearize::Cached = lin {
                    for k in 0..len {
                        process(k, &cache[t0 + k]);
                    }
                } else if let Linearize::Recorded(rec) = lin {
                    for k in 0..len {
                        let t = t0 + k;
                        let r = rec.get(t).ok_or_else(|| fail(t, "no recorded decomposition"))?;
                        let x = (w_vol[t] > 0.0).then_some(r.target);
                        let lin =
                            TetLinearization::with_target(&r.svd, x, w_rot[t], w_vol[t]).map_err(|m| fail(t, m))?;
                        process(k, &lin);
                    }
                } else {
                    let f: [Matrix3<f64>; LANES] = std::array::from_fn(|k| {
                        if k < len {
                            deformation(model, t0 + k, q)
                        } else {
                            Matrix3::identity()
                        }
                    });
                    let v0: [Matrix3<f64>; LANES] =
                        std::array::from_fn(|k| if k < len { vw[k] } else { Matrix3::identity() });
                    if !f.iter().all(|m| m.iter().all(|x| x.is_finite())) {
                        return Err(fail(t0, "non-finite deformation gradient in this chunk"));
                    }
                    let svds = svd3_warm_batch(&f, &v0);
                    let xs = if any_vol {
                        let sig: [Vector3<f64>; LANES] = std::array::from_fn(|k| svds[k].sigma);
                        let mut tw = [0.0; LANES];
                        Some(
                            volume::nearest_product_batch_warm(&sig, 1.0, &mut tw)
                                .map_err(|e| fail(t0, &e.to_string()))?,
                        )
                    } else {
                        None
                    };
                    for k in 0..len {
                        vw[k] = svds[k].v;
                        let t = t0 + k;
                        let x = xs.as_ref().filter(|_| w_vol[t] > 0.0).map(|x| x[k]);
                        let lin =
                            TetLinearization::with_target(&svds[k], x, w_rot[t], w_vol[t]).map_err(|m| fail(t, m))?;
                        process(k, &lin);
                    }
                }
                Ok::<(), DiffError>(())
            })?;
        if let Some(act) = model.actuators.as_ref() {
            self.cells_backward(model, act, q, y, activations)?;
            for (c, dp) in act.cells.iter().zip(&self.dp_cells) {
                self.dp[c.tet] += dp;
            }
            for (c, da) in act.cells.iter().zip(&self.da_cells) {
                g_act[c.group] += da;
            }
        }
        gather(model, &self.dp, out);
        if let (Some(cs), Some(cl)) = (self.cloth.as_mut(), model.cloth.as_ref()) {
            cs.backward_add(cl, q, y, out).map_err(DiffError::NotDifferentiable)?;
        }
        Ok(())
    }

    fn cells_backward(
        &mut self,
        model: &Model,
        act: &crate::actuator::Actuators,
        q: &[Vector3<f64>],
        y: &[Vector3<f64>],
        activations: &[f64],
    ) -> Result<(), DiffError> {
        self.dp_cells
            .par_iter_mut()
            .zip(self.da_cells.par_iter_mut())
            .zip(act.cells.par_iter())
            .with_min_len(64)
            .try_for_each(|((dp, da), c)| {
                let group = &act.groups[c.group];
                let a = activations[c.group];
                let fail = |e: crate::kernel::actuator::ActuatorError| {
                    DiffError::NotDifferentiable(format!("actuator '{}', tet {}: {e}", group.name, c.tet))
                };
                let f = deformation(model, c.tet, q);
                let fy = deformation(model, c.tet, y);
                match group.kind {
                    ActuatorKind::Pneumatic => {
                        // The pneumatic target is the volume projection with product `a`.
                        let svd = crate::kernel::svd::svd3(&f);
                        let x = volume::nearest_product(&svd.sigma, a).map_err(|e| {
                            DiffError::NotDifferentiable(format!("actuator '{}', tet {}: {e}", group.name, c.tet))
                        })?;
                        let (jac, dxda) = nearest_product_jacobian(&svd.sigma, &x, a).map_err(fail)?;
                        let mut pairs = [(0.0, 0.0); 3];
                        for (k, &(i, j)) in PAIRS.iter().enumerate() {
                            let (cs, ca) = pair_coefficients(x[i], x[j], svd.sigma[i], svd.sigma[j]).map_err(fail)?;
                            pairs[k] = (c.weight * cs, c.weight * ca);
                        }
                        let lin = TetLinearization {
                            u: svd.u,
                            v: svd.v,
                            diag: jac * c.weight,
                            pairs,
                            rotation: Matrix3::zeros(),
                            volume: Matrix3::zeros(),
                        };
                        *dp = lin.apply(&fy);
                        *da = c.weight * fy.dot(&svd.compose(&dxda));
                    }
                    ActuatorKind::Muscle => {
                        // p m^T w with p = (1 - a) F m / |F m|; dp/dF is symmetric in the
                        // Frobenius product (a projection onto a sphere), so J^T = J.
                        let m = c.direction;
                        let jac = muscle_jacobian(&f, &m, a).map_err(fail)?;
                        let dfm = fy * m;
                        let l = (f * m).norm();
                        let n = (f * m) / l;
                        let dpv = (dfm - n * n.dot(&dfm)) * ((1.0 - a) / l);
                        *dp = dpv * m.transpose() * c.weight;
                        *da = c.weight * dfm.dot(&jac.wrt_a);
                    }
                }
                Ok(())
            })
    }
}

/// A pair of per-vertex vectors `(a, b)` of a matrix term `a^T (dL/dw) b`.
pub type VectorPair<'a> = (&'a [Vector3<f64>], &'a [Vector3<f64>]);

impl LocalAdjoint {
    /// Subtract the matrix terms `sum_pairs <F_t(a), F_t(b)>` from both weight adjoints of every
    /// tet (`L_t = w A_t^T A_t`, so `a^T (dL/dw_t) b = <F_t(a), F_t(b)>` per unit weight).
    pub fn matrix_terms(model: &Model, pairs: &[VectorPair<'_>], g_rot: &mut [f64], g_vol: &mut [f64]) {
        g_rot
            .par_iter_mut()
            .zip(g_vol.par_iter_mut())
            .enumerate()
            .with_min_len(64)
            .for_each(|(t, (gr, gv))| {
                let mut s = 0.0;
                for (a, b) in pairs {
                    s += deformation(model, t, a).dot(&deformation(model, t, b));
                }
                *gr -= s;
                *gv -= s;
            });
    }
}

/// `out[v] = sum over tets t of v: dp_t a_{t, corner(v)}`.
pub fn gather(model: &Model, dp: &[Matrix3<f64>], out: &mut [Vector3<f64>]) {
    let geo = &model.fem.geometry;
    let adj = &model.vertex_tets;
    out.par_iter_mut().enumerate().with_min_len(256).for_each(|(v, r)| {
        let mut s = Vector3::zeros();
        for &(t, a) in adj.of(v) {
            s += dp[t as usize] * geo[t as usize].grads[a as usize];
        }
        *r = s;
    });
}
