//! The local step of projective dynamics (METHOD.md Eq. 3): for each tet, project the
//! deformation gradient onto the corotated and volume constraint sets, in parallel, into
//! preallocated buffers; then gather `J p` per vertex (`sum_t w_t p_t a_{t,i}`) without write
//! conflicts. Nothing allocates per iteration.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::model::Model;
use super::SolverError;
use crate::constraint::svd::svd3_warm;
use crate::constraint::{corotated, energy, volume};

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
    pub fn project(&mut self, model: &Model, q: &[Vector3<f64>]) -> Result<f64, SolverError> {
        let tets = &model.tets;
        let geo = &model.fem.geometry;
        let (w_rot, w_vol) = (&model.w_rot, &model.w_vol);
        self.weighted
            .par_iter_mut()
            .zip(self.v_warm.par_iter_mut())
            .zip(self.energy.par_iter_mut())
            .enumerate()
            .with_min_len(256)
            .try_for_each(|(t, ((out, v), e))| {
                let [i0, i1, i2, i3] = tets[t];
                let x0 = q[i0];
                let ds = Matrix3::from_columns(&[q[i1] - x0, q[i2] - x0, q[i3] - x0]);
                let f = ds * geo[t].p_inv;
                let svd = svd3_warm(&f, v);
                *v = svd.v;
                let rot = corotated::project(&svd);
                let mut p = rot * w_rot[t];
                let mut en = energy(w_rot[t], &f, &rot);
                if w_vol[t] > 0.0 {
                    let pv =
                        volume::project(&svd, 1.0).map_err(|err| SolverError::Projection { tet: t, source: err })?;
                    p += pv * w_vol[t];
                    en += energy(w_vol[t], &f, &pv);
                }
                if !en.is_finite() {
                    return Err(SolverError::NonFinite(format!(
                        "tet {t}: deformation gradient is not finite"
                    )));
                }
                *out = p;
                *e = en;
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
