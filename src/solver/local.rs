//! The local step of projective dynamics (METHOD.md Eq. 3): for each tet, project the
//! deformation gradient onto the corotated and volume constraint sets, in parallel, into
//! preallocated buffers; then gather `J p` per vertex (`sum_t w_t p_t a_{t,i}`) without write
//! conflicts. Nothing allocates per iteration.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::model::Model;
use super::SolverError;
use crate::constraint::svd::{svd3_warm_batch, LANES};
use crate::constraint::volume;

/// Per-tet buffers of the local step.
#[derive(Debug, Clone)]
pub struct LocalStep {
    /// `w_rot p_rot + w_vol p_vol` per tet (what the right-hand side needs).
    pub weighted: Vec<Matrix3<f64>>,
    /// Last `V` of each tet's SVD (warm start for the next one).
    pub v_warm: Vec<Matrix3<f64>>,
    /// Constraint energy per tet.
    pub energy: Vec<f64>,
}

impl LocalStep {
    /// Buffers for `tets` tets.
    pub fn new(tets: usize) -> Self {
        Self {
            weighted: vec![Matrix3::zeros(); tets],
            v_warm: vec![Matrix3::identity(); tets],
            energy: vec![0.0; tets],
        }
    }

    /// Project every tet of `model` at positions `q`; returns the total constraint energy.
    /// Tets are decomposed four at a time ([`svd3_warm_batch`]), chunks in parallel.
    pub fn project(&mut self, model: &Model, q: &[Vector3<f64>]) -> Result<f64, SolverError> {
        let tets = &model.tets;
        let geo = &model.fem.geometry;
        let (w_rot, w_vol) = (&model.w_rot, &model.w_vol);
        self.weighted
            .par_chunks_mut(LANES)
            .zip(self.v_warm.par_chunks_mut(LANES))
            .zip(self.energy.par_chunks_mut(LANES))
            .enumerate()
            .with_min_len(64)
            .try_for_each(|(chunk, ((out, v), e))| {
                let t0 = chunk * LANES;
                let len = out.len();
                let f: [Matrix3<f64>; LANES] = std::array::from_fn(|k| {
                    if k < len {
                        let [i0, i1, i2, i3] = tets[t0 + k];
                        let x0 = q[i0];
                        Matrix3::from_columns(&[q[i1] - x0, q[i2] - x0, q[i3] - x0]) * geo[t0 + k].p_inv
                    } else {
                        Matrix3::identity()
                    }
                });
                let v0: [Matrix3<f64>; LANES] =
                    std::array::from_fn(|k| if k < len { v[k] } else { Matrix3::identity() });
                let svds = svd3_warm_batch(&f, &v0);
                let sig: [Vector3<f64>; LANES] = std::array::from_fn(|k| svds[k].sigma);
                let any_volume = (0..len).any(|k| w_vol[t0 + k] > 0.0);
                let targets = if any_volume {
                    Some(
                        volume::nearest_product_batch(&sig, 1.0)
                            .map_err(|err| SolverError::Projection { tet: t0, source: err })?,
                    )
                } else {
                    None
                };
                for k in 0..len {
                    let t = t0 + k;
                    let svd = &svds[k];
                    v[k] = svd.v;
                    // p = w_rot U V^T + w_vol U X V^T = U diag(w_rot + w_vol x) V^T; energies from
                    // the singular values: |F - U V^T|^2 = sum (s - 1)^2, |F - U X V^T|^2 = sum (s - x)^2.
                    let s = svd.sigma;
                    let mut diag = Vector3::repeat(w_rot[t]);
                    let mut en = 0.5 * w_rot[t] * (s - Vector3::repeat(1.0)).norm_squared();
                    if let Some(x) = &targets {
                        if w_vol[t] > 0.0 {
                            diag += x[k] * w_vol[t];
                            en += 0.5 * w_vol[t] * (s - x[k]).norm_squared();
                        }
                    }
                    if !en.is_finite() {
                        return Err(SolverError::NonFinite(format!(
                            "tet {t}: deformation gradient is not finite"
                        )));
                    }
                    out[k] = svd.compose(&diag);
                    e[k] = en;
                }
                Ok(())
            })?;
        Ok(self.energy.iter().sum())
    }

    /// `rhs[v] = sum over tets t of v: weighted_t a_{t, corner(v)}` for every vertex.
    pub fn gather(&self, model: &Model, rhs: &mut [Vector3<f64>]) {
        let geo = &model.fem.geometry;
        let adj = &model.vertex_tets;
        rhs.par_iter_mut().enumerate().with_min_len(256).for_each(|(v, r)| {
            let mut s = Vector3::zeros();
            for &(t, a) in adj.of(v) {
                s += self.weighted[t as usize] * geo[t as usize].grads[a as usize];
            }
            *r = s;
        });
    }
}
