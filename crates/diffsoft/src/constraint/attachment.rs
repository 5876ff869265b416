//! Attachments (penalty pins): vertex `i` pulled to its target with weight `w`; energy
//! `w/2 |x_i - target|^2`, selection `e_i`. The projection is the target itself, independent of
//! the positions, so an attachment adds `w` to the diagonal of `L` and `w target` to the
//! constant part of the right-hand side.

use nalgebra::Vector3;

use super::ConstraintSet;
use crate::model::Model;

/// Every attachment of a model (no buffers).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Attachments;

impl ConstraintSet for Attachments {
    fn name(&self) -> &'static str {
        "attachment"
    }

    fn hessian_term(&self) -> super::HessianTerm {
        super::HessianTerm::Constant
    }

    fn add_blocks(&self, model: &Model, values: &mut [f64]) {
        for a in &model.attachments {
            values[model.fem.pattern.diag_slot[a.vertex]] += a.weight;
        }
    }

    fn constant_rhs(&self, model: &Model, add: &mut dyn FnMut(usize, Vector3<f64>)) {
        for a in &model.attachments {
            add(a.vertex, a.target * a.weight);
        }
    }

    fn constant_rhs_adjoint(
        &self,
        model: &Model,
        adjoint: &dyn Fn(usize) -> Option<Vector3<f64>>,
        targets: &mut [Vector3<f64>],
    ) {
        for (a, t) in model.attachments.iter().zip(targets.iter_mut()) {
            if let Some(b) = adjoint(a.vertex) {
                *t += b * a.weight;
            }
        }
    }
}
