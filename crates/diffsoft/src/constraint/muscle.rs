//! Muscle fibres (docs/method.md section 5): each fibre `F m` of an actuated tet is pulled to
//! length `1 - a` along itself, target `p = (1 - a) F m / |F m|`, weight `k V`. Its share of `L`
//! is the rank-one block `w (A m)(A m)^T` on the tet's corners.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::cells::{actuators, add_to_groups, add_to_tets, cells_of};
use super::{AdjointContext, ConstraintError, ConstraintSet, NotDifferentiable, ProjectContext};
use crate::actuator::ActuatorKind;
use crate::kernel::actuator::{muscle_jacobian, muscle_target};
use crate::model::Model;

/// Every muscle fibre of a model, with its buffers.
#[derive(Debug, Clone)]
pub(crate) struct Muscle {
    /// Indices of the fibres in the model's actuator cells.
    cells: Vec<usize>,
    /// `w p m^T` per fibre.
    weighted: Vec<Matrix3<f64>>,
    /// Energy per fibre.
    energy: Vec<f64>,
    /// `dp` per fibre (adjoint).
    dp: Vec<Matrix3<f64>>,
    /// Activation adjoint per fibre.
    da: Vec<f64>,
}

impl Muscle {
    /// The muscle fibres of `model` (`None` if it has none).
    pub(crate) fn new(model: &Model) -> Option<Self> {
        let cells = cells_of(model, ActuatorKind::Muscle)?;
        let n = cells.len();
        Some(Self {
            cells,
            weighted: vec![Matrix3::zeros(); n],
            energy: vec![0.0; n],
            dp: vec![Matrix3::zeros(); n],
            da: vec![0.0; n],
        })
    }
}

impl ConstraintSet for Muscle {
    fn name(&self) -> &'static str {
        "muscle"
    }

    fn hessian_term(&self) -> super::HessianTerm {
        super::HessianTerm::Exact
    }

    fn add_blocks(&self, model: &Model, values: &mut [f64]) {
        // A fibre's constraint is on F m = sum_a x_a (a_a . m): a rank-one block.
        let act = actuators(model);
        for &i in &self.cells {
            let c = &act.cells[i];
            let g = &model.fem.geometry[c.tet];
            let gm: [f64; 4] = std::array::from_fn(|a| g.grads[a].dot(&c.direction));
            let slots = &model.fem.pattern.tet_slots[c.tet];
            for a in 0..4 {
                for b in 0..4 {
                    values[slots[4 * a + b] as usize] += c.weight * gm[a] * gm[b];
                }
            }
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
            .zip(self.energy.par_iter_mut())
            .zip(self.cells.par_iter())
            .with_min_len(64)
            .try_for_each(|((out, e), &i)| {
                let c = &act.cells[i];
                let group = &act.groups[c.group];
                let f = model.tet_deformation(c.tet, q);
                let fm = f * c.direction;
                let p = muscle_target(&fm, activations[c.group]).map_err(|source| ConstraintError::Actuator {
                    group: group.name.clone(),
                    tet: c.tet,
                    source,
                })?;
                *out = (p * c.direction.transpose()) * c.weight;
                *e = 0.5 * c.weight * (fm - p).norm_squared();
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
                let f = model.tet_deformation(c.tet, q);
                let fy = model.tet_deformation(c.tet, y);
                // p m^T w with p = (1 - a) F m / |F m|; dp/dF is symmetric in the Frobenius
                // product (a projection onto a sphere), so J^T = J.
                let m = c.direction;
                let jac = muscle_jacobian(&f, &m, a)
                    .map_err(|e| NotDifferentiable(format!("actuator '{}', tet {}: {e}", group.name, c.tet)))?;
                let dfm = fy * m;
                let l = (f * m).norm();
                let n = (f * m) / l;
                let dpv = (dfm - n * n.dot(&dfm)) * ((1.0 - a) / l);
                *dp = dpv * m.transpose() * c.weight;
                *da = c.weight * dfm.dot(&jac.wrt_a);
                Ok(())
            })?;
        add_to_tets(act, &self.cells, &self.dp, ctx.per_tet);
        add_to_groups(act, &self.cells, &self.da, ctx.grads.activations);
        Ok(())
    }
}
