//! What the two actuator kinds share: their cells among the model's actuator cells, and adding
//! per-cell results into the per-tet buffers and the group adjoints.

use nalgebra::Matrix3;

use crate::actuator::{ActuatorKind, Actuators};
use crate::model::Model;

/// The model's actuators (a cell set exists only when it has some).
pub(super) fn actuators(model: &Model) -> &Actuators {
    model
        .actuators
        .as_ref()
        .expect("an actuator set exists only with actuators")
}

/// Indices of the model's actuator cells of `kind`, in the model's order (`None`: none).
pub(super) fn cells_of(model: &Model, kind: ActuatorKind) -> Option<Vec<usize>> {
    let act = model.actuators.as_ref()?;
    let cells: Vec<usize> = (0..act.cells.len())
        .filter(|&i| act.groups[act.cells[i].group].kind == kind)
        .collect();
    (!cells.is_empty()).then_some(cells)
}

/// `per_tet[tet of cell] += m` for every cell, in order.
pub(super) fn add_to_tets(act: &Actuators, cells: &[usize], m: &[Matrix3<f64>], per_tet: &mut [Matrix3<f64>]) {
    for (&i, m) in cells.iter().zip(m) {
        per_tet[act.cells[i].tet] += m;
    }
}

/// `grads[group of cell] += da` for every cell, in order.
pub(super) fn add_to_groups(act: &Actuators, cells: &[usize], da: &[f64], grads: &mut [f64]) {
    for (&i, da) in cells.iter().zip(da) {
        grads[act.cells[i].group] += da;
    }
}
