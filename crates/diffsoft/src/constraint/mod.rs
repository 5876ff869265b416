//! The projective constraints of a model, one [`ConstraintSet`] per kind (docs/method.md
//! section 2): each set holds every element of its kind and knows
//!
//! * its share of the constant matrix `L = sum_i w_i G_i^T G_i` (Eq. 5; for tets Eq. 22),
//! * its local step: the projection of every element onto its constraint set (Eq. 3), in
//!   parallel, and the gather of `J p` into the global step's right-hand side,
//! * its linearization and adjoint for the backward pass (docs/method.md section 7, Eqs. G1-G4).
//!
//! The kinds, one file each: [`elasticity`] (corotated + volume per tet), [`pneumatic`] and
//! [`muscle`] (actuator cells), [`cloth_stretch`] and [`cloth_bend`] (cloth triangles and
//! bending stencils), [`attachment`] (penalty pins). [`sets_for`] is the one place that
//! registers them; [`Constraints`] runs the local step, the stiffness assembly and the adjoint
//! as one loop over the sets. Adding a kind means a file with its `ConstraintSet` and one line
//! in [`sets_for`].
//!
//! Tet-stencil kinds (elasticity, pneumatic, muscle) put their weighted projections `w p` into
//! one shared per-tet buffer, so the gather `J p = sum_t (w p)_t A_t` runs once over the
//! vertex-to-tet adjacency; the elasticity set writes that buffer first and the actuator sets
//! add to it. Kinds with other stencils (cloth) gather per vertex afterwards.

pub(crate) mod attachment;
mod cells;
pub(crate) mod cloth_bend;
pub(crate) mod cloth_stretch;
pub(crate) mod elasticity;
mod error;
pub(crate) mod hyperelastic;
pub(crate) mod muscle;
pub(crate) mod pneumatic;
mod sets;

pub use elasticity::TetSvd;
pub use error::{ConstraintError, NotDifferentiable};
pub(crate) use sets::{sum_corners, Constraints};

use nalgebra::{Matrix3, Vector3};

use crate::model::Model;

/// Where the backward pass gets the elasticity's linearization of a local step.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Linearize<'a> {
    /// Decompose `F` again at the given positions.
    Recompute,
    /// The cache of the last [`ConstraintSet::linearize`].
    Cached,
    /// The decompositions the forward recorded at these positions.
    Recorded(&'a [TetSvd]),
}

/// What a set's local step reads and writes besides its own buffers.
pub(crate) struct ProjectContext<'a> {
    /// `w p` per tet, gathered afterwards through the tets (the elasticity set overwrites it,
    /// tet-stencil sets after it add).
    pub per_tet: &'a mut [Matrix3<f64>],
    /// Activation of each actuator group in this step.
    pub activations: &'a [f64],
    /// Every tet's decomposition, recorded for the backward pass when given.
    pub record: Option<&'a mut [TetSvd]>,
}

/// The parameter adjoints a set's backward adds to.
pub(crate) struct ParamGrads<'a> {
    /// `dL/dw_rot` per tet.
    pub w_rot: &'a mut [f64],
    /// `dL/dw_vol` per tet.
    pub w_vol: &'a mut [f64],
    /// `dL/da` per actuator group (this step).
    pub activations: &'a mut [f64],
}

/// What a set's adjoint reads and writes besides its own buffers.
pub(crate) struct AdjointContext<'a, 'g> {
    /// Positions of the local step being differentiated (all vertices).
    pub q: &'a [Vector3<f64>],
    /// The adjoint of the gathered right-hand side (all vertices, zero at fixed ones).
    pub y: &'a [Vector3<f64>],
    /// The solution of the solve that used this local step, for the weights' matrix terms
    /// (`None`: the caller adds them, see [`ConstraintSet::matrix_terms`]).
    pub x_next: Option<&'a [Vector3<f64>]>,
    /// Activation of each actuator group in this step.
    pub activations: &'a [f64],
    /// Where the elasticity's linearization comes from.
    pub lin: Linearize<'a>,
    /// `dp` per tet, gathered afterwards (the elasticity set overwrites it; tet-stencil sets
    /// after it add).
    pub per_tet: &'a mut [Matrix3<f64>],
    /// Parameter adjoints.
    pub grads: ParamGrads<'g>,
}

/// How a kind's constraints enter the Hessian of the step energy that Newton's method uses
/// (docs/method.md Eq. S4, `H = A - J K~ J^T`): every kind declares it, so no kind can be left
/// out of the Hessian by omission.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum HessianTerm {
    /// The projection does not depend on the positions (an attachment's target): `K = 0`, the
    /// kind's whole Hessian block `w G^T G` is in `A`.
    Constant,
    /// Tet elasticity: the per-tet linearization from the local step's decompositions, clamped
    /// per tet for the projected Hessian (`solver::hessian::ElasticHessian`).
    ElasticTets,
    /// The exact `K` from the kind's own linearization and adjoint in the unprojected Hessian;
    /// the projected Hessian leaves it out (the block `w G^T G` in `A` is positive
    /// semidefinite).
    Exact,
    /// The kind builds and applies its own `K~` for Newton's Hessian
    /// ([`ConstraintSet::linearize_hessian`], [`ConstraintSet::apply_hessian_add`]), exact or
    /// projected; its exact `K` is also its backward linearization (hyperelastic tets).
    Own,
    /// Newton's method cannot take this kind (the reason, for the error message).
    Unsupported(&'static str),
}

/// One kind of projective constraint over every element of a model that has it.
///
/// A set owns its buffers (sized once, on first use); the model's static data (tets, weights,
/// cells, cloth) is passed in. Methods other than [`ConstraintSet::name`] and
/// [`ConstraintSet::hessian_term`] have do-nothing defaults so a kind implements only what it
/// has.
pub(crate) trait ConstraintSet: Send + Sync + std::fmt::Debug {
    /// Name of the kind (diagnostics).
    fn name(&self) -> &'static str;

    /// How the kind enters Newton's Hessian (no default: a new kind must say).
    fn hessian_term(&self) -> HessianTerm;

    /// Add the per-tet coefficients `w / V` of its isotropic tet terms `w A^T A` (Eq. 22) to
    /// `k` (the elasticity set comes first and overwrites).
    fn tet_coefficients(&self, _model: &Model, _k: &mut [f64]) {}

    /// Add its other blocks of `L` (Eq. 5) to the stiffness pattern's values.
    fn add_blocks(&self, _model: &Model, _values: &mut [f64]) {}

    /// The local step (Eq. 3): project every element at positions `q` (all vertices), keep
    /// `w p` for the gather (tet stencils: into `ctx.per_tet`), return the constraint energy.
    fn project(
        &mut self,
        _model: &Model,
        _q: &[Vector3<f64>],
        _ctx: &mut ProjectContext<'_>,
    ) -> Result<f64, ConstraintError> {
        Ok(0.0)
    }

    /// Add `J p` over its own (non-tet) stencils: `rhs[v] += sum w p c_v`.
    fn gather_add(&self, _model: &Model, _rhs: &mut [Vector3<f64>]) {}

    /// Call `add(vertex, w p)` for the projections that do not depend on the positions (an
    /// attachment's target): the constant part of `J p`, added once per step.
    fn constant_rhs(&self, _model: &Model, _add: &mut dyn FnMut(usize, Vector3<f64>)) {}

    /// Linearize the projections at `q` and keep the linearization (implicit mode).
    fn linearize(&mut self, _model: &Model, _q: &[Vector3<f64>]) -> Result<(), NotDifferentiable> {
        Ok(())
    }

    /// The adjoint of one local step (Eq. G2): given the adjoint `ctx.y` of the gathered
    /// right-hand side, put `(dp/dF)^T F(y)` per tet into `ctx.per_tet` (tet stencils) and add
    /// the parameter adjoints.
    fn adjoint(&mut self, _model: &Model, _ctx: &mut AdjointContext<'_, '_>) -> Result<(), NotDifferentiable> {
        Ok(())
    }

    /// Add the adjoint through its own (non-tet) stencils to `out` (all vertices), linearized
    /// at `q`, for the adjoint `y` of the right-hand side.
    fn adjoint_gather_add(
        &mut self,
        _model: &Model,
        _q: &[Vector3<f64>],
        _y: &[Vector3<f64>],
        _out: &mut [Vector3<f64>],
    ) -> Result<(), NotDifferentiable> {
        Ok(())
    }

    /// Kinds with [`HessianTerm::Own`]: build `K~` at `q` for Newton's Hessian, exact or with
    /// each element's block projected to be positive semidefinite; returns the clamped modes.
    fn linearize_hessian(&mut self, _model: &Model, _q: &[Vector3<f64>], _projected: bool) -> usize {
        0
    }

    /// Kinds with [`HessianTerm::Own`]: add `J K~ J^T y` (the last [`ConstraintSet::linearize_hessian`])
    /// to `out` (all vertices).
    fn apply_hessian_add(&self, _model: &Model, _y: &[Vector3<f64>], _out: &mut [Vector3<f64>]) {}

    /// Subtract the weights' matrix terms `sum_pairs a^T (dL/dw) b` from the weight adjoints
    /// (Eq. G3), for solves whose matrix term the adjoint left out (`x_next = None`).
    fn matrix_terms(&self, _model: &Model, _pairs: &[VectorPair<'_>], _grads: &mut ParamGrads<'_>) {}

    /// The adjoint of [`ConstraintSet::constant_rhs`]: given `adjoint(vertex)` of the
    /// right-hand side, add the parameter adjoints (attachment targets) to `targets`.
    fn constant_rhs_adjoint(
        &self,
        _model: &Model,
        _adjoint: &dyn Fn(usize) -> Option<Vector3<f64>>,
        _targets: &mut [Vector3<f64>],
    ) {
    }
}

/// A pair of per-vertex vectors `(a, b)` of a matrix term `a^T (dL/dw) b`.
pub(crate) type VectorPair<'a> = (&'a [Vector3<f64>], &'a [Vector3<f64>]);

/// The constraint sets of `model`, in the order their contributions are summed: the one place
/// where kinds are registered.
pub(crate) fn sets_for(model: &Model) -> Vec<Box<dyn ConstraintSet>> {
    let mut sets: Vec<Box<dyn ConstraintSet>> = Vec::new();
    if !model.tets.is_empty() {
        sets.push(Box::new(elasticity::Elasticity::new(model)));
    }
    if let Some(s) = pneumatic::Pneumatic::new(model) {
        sets.push(Box::new(s));
    }
    if let Some(s) = muscle::Muscle::new(model) {
        sets.push(Box::new(s));
    }
    if let Some(s) = hyperelastic::Hyperelastic::new(model) {
        sets.push(Box::new(s));
    }
    if let Some(s) = cloth_stretch::ClothStretch::new(model) {
        sets.push(Box::new(s));
    }
    if let Some(s) = cloth_bend::ClothBend::new(model) {
        sets.push(Box::new(s));
    }
    if !model.attachments.is_empty() {
        sets.push(Box::new(attachment::Attachments));
    }
    sets
}

/// `L` (per axis) of `model`: every set's share, as values in the model's stiffness pattern.
///
/// ```
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{stiffness_values, BodySpec, MassSpec, Material, ModelBuilder};
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let model = ModelBuilder::new().body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0))).build()?;
/// let l = stiffness_values(&model)?;
/// assert_eq!(l.len(), model.fem().pattern.nnz());
/// // Without pins a Laplacian: positive diagonal, constants in its kernel.
/// let diag = model.fem().pattern.diagonal(&l);
/// assert!(diag.iter().all(|&d| d > 0.0));
/// assert!(l.iter().sum::<f64>().abs() < 1e-9 * diag.iter().sum::<f64>());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// A tet whose stiffness weight underflows or overflows double precision, named with its body.
pub fn stiffness_values(model: &Model) -> Result<Vec<f64>, crate::base::InputError> {
    Constraints::stiffness_values(model, &sets_for(model)).map_err(crate::base::InputError::new)
}
