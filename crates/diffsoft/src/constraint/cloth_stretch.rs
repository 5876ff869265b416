//! Cloth stretching (2D as-rigid-as-possible): per triangle, the in-plane deformation gradient
//! `F = [x1-x0, x2-x0] P^-1` (3 x 2) is projected onto the matrices with orthonormal columns,
//! `R = U V^T` of the thin SVD; energy `k_s A / 2 |F - R|^2`, weight `w = k_s A`. Its share of
//! `L` is the triangle's 3 x 3 block `w g_a . g_b`.

use nalgebra::{Matrix3x2, Vector3};
use rayon::prelude::*;

use super::{ConstraintError, ConstraintSet, NotDifferentiable, ProjectContext};
use crate::cloth::{deformation_gradient, Cloth};
use crate::kernel::polar32::Polar;
use crate::model::Model;

/// Every cloth triangle of a model, with its buffers.
#[derive(Debug, Clone)]
pub(crate) struct ClothStretch {
    /// `w R` per triangle (forward) or `w dR` (adjoint).
    weighted: Vec<Matrix3x2<f64>>,
    /// Stretching energy per triangle.
    energy: Vec<f64>,
}

fn cloth(model: &Model) -> &Cloth {
    model.cloth.as_ref().expect("a cloth set exists only with cloth")
}

impl ClothStretch {
    /// The triangles of `model`'s cloth (`None` without cloth).
    pub(crate) fn new(model: &Model) -> Option<Self> {
        let n = model.cloth.as_ref()?.num_triangles();
        Some(Self {
            weighted: vec![Matrix3x2::zeros(); n],
            energy: vec![0.0; n],
        })
    }

    /// `rhs[v] += sum_t weighted_t g_{t,v}` for every vertex.
    fn gather(&self, cloth: &Cloth, rhs: &mut [Vector3<f64>]) {
        let geo = &cloth.geometry;
        rhs.par_iter_mut().enumerate().with_min_len(256).for_each(|(v, r)| {
            for &(t, a) in cloth.vertex_triangles.of(v) {
                *r += self.weighted[t as usize] * geo[t as usize].grads[a as usize];
            }
        });
    }
}

impl ConstraintSet for ClothStretch {
    fn name(&self) -> &'static str {
        "cloth stretching"
    }

    fn hessian_term(&self) -> super::HessianTerm {
        super::HessianTerm::Unsupported("cloth")
    }

    fn add_blocks(&self, model: &Model, values: &mut [f64]) {
        let cl = cloth(model);
        for ((g, slots), w) in cl.geometry.iter().zip(&cl.tri_slots).zip(&cl.w_stretch) {
            let k = g.local_laplacian();
            for a in 0..3 {
                for b in 0..3 {
                    values[slots[3 * a + b] as usize] += w * k[a][b];
                }
            }
        }
    }

    fn project(
        &mut self,
        model: &Model,
        q: &[Vector3<f64>],
        _ctx: &mut ProjectContext<'_>,
    ) -> Result<f64, ConstraintError> {
        let cloth = cloth(model);
        self.weighted
            .par_iter_mut()
            .zip(self.energy.par_iter_mut())
            .enumerate()
            .with_min_len(256)
            .try_for_each(|(t, (out, e))| {
                let f = deformation_gradient(q, &cloth.triangles[t], &cloth.geometry[t]);
                if !f.iter().all(|x| x.is_finite()) {
                    return Err(ConstraintError::NonFinite(format!(
                        "cloth triangle {t}: in-plane deformation gradient is not finite"
                    )));
                }
                let p = Polar::new(&f);
                let w = cloth.w_stretch[t];
                *out = p.r * w;
                *e = 0.5 * w * p.distance_squared();
                Ok(())
            })?;
        let energy: f64 = self.energy.iter().sum();
        if energy.is_finite() {
            Ok(energy)
        } else {
            Err(ConstraintError::NonFinite(
                "cloth constraint energy is not finite".into(),
            ))
        }
    }

    fn gather_add(&self, model: &Model, rhs: &mut [Vector3<f64>]) {
        self.gather(cloth(model), rhs);
    }

    fn adjoint_gather_add(
        &mut self,
        model: &Model,
        q: &[Vector3<f64>],
        y: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
    ) -> Result<(), NotDifferentiable> {
        let cloth = cloth(model);
        self.weighted
            .par_iter_mut()
            .enumerate()
            .with_min_len(256)
            .try_for_each(|(t, dp)| {
                let (tri, g) = (&cloth.triangles[t], &cloth.geometry[t]);
                let p = Polar::new(&deformation_gradient(q, tri, g));
                if p.collapsed {
                    return Err(NotDifferentiable(format!(
                        "cloth triangle {t} is collapsed to a segment: its in-plane projection has no derivative"
                    )));
                }
                *dp = p.differential(&deformation_gradient(y, tri, g)) * cloth.w_stretch[t];
                Ok(())
            })?;
        self.gather(cloth, out);
        Ok(())
    }
}
