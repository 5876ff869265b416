//! Observers of a step's local-global iterations: the forward calls them at each phase (the
//! backward pass records what it needs through one, see `diff::recording`), so the forward step
//! knows nothing of differentiation.

use nalgebra::Vector3;

use super::free_contact::FreeContact;
use super::skeletal::Skeletal;
use crate::constraint::TetSvd;
use crate::contact::Contact;
use crate::skeleton::Skeleton;

/// What one global solve of a step ended with.
pub(crate) struct SolveInfo<'a> {
    /// The contacts on free vertices it solved with.
    pub contacts: &'a [FreeContact],
    /// Their impulses (`None`: an iterative global solver projected them inside its iteration
    /// and keeps none).
    pub impulses: Option<&'a [Vector3<f64>]>,
    /// With a skeleton: the reduced step and the contacts on bone vertices it solved with.
    pub skeletal: Option<(&'a Skeletal, &'a [(usize, Contact)])>,
}

/// Watches the phases of a step. Every method has a do-nothing default.
pub(crate) trait StepObserver {
    /// A step begins.
    fn begin(&mut self) {}

    /// A contact round begins with these contacts on free vertices.
    fn contact_set(&mut self, _contacts: &[FreeContact]) {}

    /// An iteration begins at the free-vertex iterate `x` (the skeleton in its current state).
    fn iterate(&mut self, _x: &[Vector3<f64>], _skeleton: Option<&Skeleton>) {}

    /// Where the local step at this iterate should write every tet's decomposition (`None`:
    /// nowhere). `replace_last`: the iterate's local step runs again (an Anderson rejection) and
    /// replaces the previous record.
    fn decompositions(&mut self, _tets: usize, _replace_last: bool) -> Option<&mut [TetSvd]> {
        None
    }

    /// Whether it records the iterations (the backward pass linearizes the last one): Newton's
    /// method then ends with one local-global iteration at its converged iterate, observed.
    fn records_iterations(&self) -> bool {
        false
    }

    /// A global solve ended.
    fn solved(&mut self, _info: SolveInfo<'_>) {}

    /// The step ends at the free-vertex positions `x` (the skeleton in its final state).
    fn end(&mut self, _x: &[Vector3<f64>], _skeleton: Option<&Skeleton>) {}
}

/// Watches nothing.
pub(crate) struct NoObserver;

impl StepObserver for NoObserver {}
