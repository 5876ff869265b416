//! Pneumatic cells (docs/method.md section 5, Eqs. 39-40): each actuated tet's `F` is projected
//! onto the matrices whose singular values multiply to the group's activation `a` (the volume
//! projection with target `a`); weight `k V`. Its share of `L` is the isotropic tet term
//! `k V A^T A`, added to the tet's coefficient.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::cells::{actuators, add_to_groups, add_to_tets, cells_of};
use super::{AdjointContext, ConstraintError, ConstraintSet, NotDifferentiable, ProjectContext};
use crate::actuator::ActuatorKind;
use crate::kernel::actuator::{nearest_product_jacobian, pair_coefficients, pneumatic_target, ActuatorError};
use crate::kernel::linearization::{TetLinearization, PAIRS};
use crate::kernel::{svd, volume};
use crate::model::Model;

/// Every pneumatic cell of a model, with its buffers.
#[derive(Debug, Clone)]
pub(crate) struct Pneumatic {
    /// Indices of the pneumatic cells in the model's actuator cells.
    cells: Vec<usize>,
    /// `w p` per cell.
    weighted: Vec<Matrix3<f64>>,
    /// Last `V` of each cell's SVD (warm start).
    v_warm: Vec<Matrix3<f64>>,
    /// Energy per cell.
    energy: Vec<f64>,
    /// `dp` per cell (adjoint).
    dp: Vec<Matrix3<f64>>,
    /// Activation adjoint per cell.
    da: Vec<f64>,
}

impl Pneumatic {
    /// The pneumatic cells of `model` (`None` if it has none).
    pub(crate) fn new(model: &Model) -> Option<Self> {
        let cells = cells_of(model, ActuatorKind::Pneumatic)?;
        let n = cells.len();
        Some(Self {
            cells,
            weighted: vec![Matrix3::zeros(); n],
            v_warm: vec![Matrix3::identity(); n],
            energy: vec![0.0; n],
            dp: vec![Matrix3::zeros(); n],
            da: vec![0.0; n],
        })
    }
}

impl ConstraintSet for Pneumatic {
    fn name(&self) -> &'static str {
        "pneumatic"
    }

    fn hessian_term(&self) -> super::HessianTerm {
        super::HessianTerm::Exact
    }

    fn tet_coefficients(&self, model: &Model, k: &mut [f64]) {
        let act = actuators(model);
        for &i in &self.cells {
            let c = &act.cells[i];
            k[c.tet] += c.weight / model.fem.geometry[c.tet].volume;
        }
    }

    fn project(
        &mut self,
        model: &Model,
        q: &[Vector3<f64>],
        ctx: &mut ProjectContext<'_>,
    ) -> Result<f64, ConstraintError> {
        let act = actuators(model);
        let activations = ctx.activations;
        self.weighted
            .par_iter_mut()
            .zip(self.v_warm.par_iter_mut())
            .zip(self.energy.par_iter_mut())
            .zip(self.cells.par_iter())
            .with_min_len(64)
            .try_for_each(|(((out, v), e), &i)| {
                let c = &act.cells[i];
                let group = &act.groups[c.group];
                let fail = |source| ConstraintError::Actuator {
                    group: group.name.clone(),
                    tet: c.tet,
                    source,
                };
                let f = model.tet_deformation(c.tet, q);
                if !f.iter().all(|x| x.is_finite()) {
                    return Err(fail(ActuatorError::NonFinite));
                }
                let d = svd::svd3_warm(&f, v);
                *v = d.v;
                let p = pneumatic_target(&d, activations[c.group]).map_err(fail)?;
                *out = p * c.weight;
                *e = crate::kernel::energy(c.weight, &f, &p);
                Ok(())
            })?;
        add_to_tets(act, &self.cells, &self.weighted, ctx.per_tet);
        Ok(self.energy.iter().sum())
    }

    fn adjoint(&mut self, model: &Model, ctx: &mut AdjointContext<'_, '_>) -> Result<(), NotDifferentiable> {
        let act = actuators(model);
        let (q, y, activations) = (ctx.q, ctx.y, ctx.activations);
        self.dp
            .par_iter_mut()
            .zip(self.da.par_iter_mut())
            .zip(self.cells.par_iter())
            .with_min_len(64)
            .try_for_each(|((dp, da), &i)| {
                let c = &act.cells[i];
                let group = &act.groups[c.group];
                let a = activations[c.group];
                let fail = |e: &dyn std::fmt::Display| {
                    NotDifferentiable(format!("actuator '{}', tet {}: {e}", group.name, c.tet))
                };
                let f = model.tet_deformation(c.tet, q);
                let fy = model.tet_deformation(c.tet, y);
                // The pneumatic target is the volume projection with product `a`.
                let s = svd::svd3(&f);
                let x = volume::nearest_product(&s.sigma, a).map_err(|e| fail(&e))?;
                let (jac, dxda) = nearest_product_jacobian(&s.sigma, &x, a).map_err(|e| fail(&e))?;
                let mut pairs = [(0.0, 0.0); 3];
                for (k, &(i, j)) in PAIRS.iter().enumerate() {
                    let (cs, ca) = pair_coefficients(x[i], x[j], s.sigma[i], s.sigma[j]).map_err(|e| fail(&e))?;
                    pairs[k] = (c.weight * cs, c.weight * ca);
                }
                let lin = TetLinearization {
                    u: s.u,
                    v: s.v,
                    diag: jac * c.weight,
                    pairs,
                    rotation: Matrix3::zeros(),
                    volume: Matrix3::zeros(),
                };
                *dp = lin.apply(&fy);
                *da = c.weight * fy.dot(&s.compose(&dxda));
                Ok(())
            })?;
        add_to_tets(act, &self.cells, &self.dp, ctx.per_tet);
        add_to_groups(act, &self.cells, &self.da, ctx.grads.activations);
        Ok(())
    }
}
