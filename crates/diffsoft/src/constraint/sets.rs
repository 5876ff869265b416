//! The local step, the stiffness assembly and the local step's adjoint, each one loop over the
//! model's constraint sets.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::{
    sets_for, AdjointContext, ConstraintError, ConstraintSet, Linearize, NotDifferentiable, ParamGrads, ProjectContext,
    TetSvd, VectorPair,
};
use crate::fem::Coefficient;
use crate::model::Model;

/// Every constraint set of a model with the shared per-tet buffer of the gather.
pub(crate) struct Constraints {
    sets: Vec<Box<dyn ConstraintSet>>,
    /// `w p` (forward) or `dp` (adjoint) per tet.
    per_tet: Vec<Matrix3<f64>>,
    /// `per_tet[t] a_{t,i}` for the four corners of every tet ([`gather_tets_staged`]).
    corners: Vec<[Vector3<f64>; 4]>,
}

impl std::fmt::Debug for Constraints {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Constraints")
            .field("kinds", &self.sets.iter().map(|s| s.name()).collect::<Vec<_>>())
            .field("tets", &self.per_tet.len())
            .finish()
    }
}

impl Constraints {
    /// The sets of `model` (see [`sets_for`]) and the per-tet buffer.
    pub(crate) fn new(model: &Model) -> Self {
        Self {
            sets: sets_for(model),
            per_tet: vec![Matrix3::zeros(); model.tets.len()],
            corners: vec![[Vector3::zeros(); 4]; model.tets.len()],
        }
    }

    /// Build the `K~` of the kinds with their own Hessian term at `q` (exact or projected);
    /// returns the clamped modes.
    pub(crate) fn linearize_hessian(&mut self, model: &Model, q: &[Vector3<f64>], projected: bool) -> usize {
        self.sets
            .iter_mut()
            .filter(|s| s.hessian_term() == super::HessianTerm::Own)
            .map(|s| s.linearize_hessian(model, q, projected))
            .sum()
    }

    /// Add `J K~ J^T y` of the kinds with their own Hessian term to `out`.
    pub(crate) fn apply_hessian_add(&self, model: &Model, y: &[Vector3<f64>], out: &mut [Vector3<f64>]) {
        for s in self.sets.iter().filter(|s| s.hessian_term() == super::HessianTerm::Own) {
            s.apply_hessian_add(model, y, out);
        }
    }

    /// How each kind enters Newton's Hessian, with its name.
    pub(crate) fn hessian_terms(&self) -> impl Iterator<Item = (&'static str, super::HessianTerm)> + '_ {
        self.sets.iter().map(|s| (s.name(), s.hessian_term()))
    }

    /// `L` (per axis) as values in the model's stiffness pattern: the isotropic tet terms
    /// first (Eq. 22), then every set's other blocks.
    ///
    /// Every tet's coefficient must be a positive normal number: a Young's modulus whose weight
    /// `E V / (1 + nu)` underflows (5e-324 Pa, or 1e-250 Pa on a 1e-50 m mesh) or overflows is
    /// refused with the tet and its body named (an error, never a panic or a singular matrix).
    pub(crate) fn stiffness_values(model: &Model, sets: &[Box<dyn ConstraintSet>]) -> Result<Vec<f64>, String> {
        let mut k = vec![0.0; model.tets.len()];
        for s in sets {
            s.tet_coefficients(model, &mut k);
        }
        if let Some(t) = k.iter().position(|c| !(c.is_normal() && *c > 0.0)) {
            let body = model.bodies.iter().find(|b| b.tets.contains(&t));
            return Err(format!(
                "body '{}', tet {}: its stiffness per volume is {:e} (Young's modulus {:e} Pa, Poisson ratio {}, volume {:e} m^3): its weight underflows or overflows double precision; rescale the units (kPa or MPa, mm) so that E and the element volumes are moderate numbers",
                body.map_or("?", |b| b.name.as_str()),
                body.map_or(t, |b| t - b.tets.start),
                k[t],
                body.map_or(f64::NAN, |b| b.material.youngs_modulus),
                body.map_or(f64::NAN, |b| b.material.poisson_ratio),
                model.fem.geometry[t].volume,
            ));
        }
        let mut values = model
            .fem
            .laplacian_values(Coefficient::PerTet(&k))
            .map_err(|e| e.to_string())?;
        if let Some(v) = values.iter().find(|v| !v.is_finite()) {
            return Err(format!(
                "the stiffness matrix has an entry {v}: the Young's moduli over the element sizes overflow double precision; rescale the units"
            ));
        }
        for s in sets {
            s.add_blocks(model, &mut values);
        }
        Ok(values)
    }

    /// The local step at positions `q` (all vertices): project every set's elements; returns
    /// the total constraint energy. With `record`, every tet's decomposition is written there.
    pub(crate) fn project(
        &mut self,
        model: &Model,
        q: &[Vector3<f64>],
        activations: &[f64],
        record: Option<&mut [TetSvd]>,
    ) -> Result<f64, ConstraintError> {
        let mut ctx = ProjectContext {
            per_tet: &mut self.per_tet,
            activations,
            record,
        };
        let mut energy = 0.0;
        for s in &mut self.sets {
            energy += s.project(model, q, &mut ctx)?;
        }
        Ok(energy)
    }

    /// `rhs = J p` for every vertex, from the last [`Constraints::project`].
    pub(crate) fn gather(&mut self, model: &Model, rhs: &mut [Vector3<f64>]) {
        gather_tets_staged(model, &self.per_tet, &mut self.corners, rhs);
        for s in &self.sets {
            s.gather_add(model, rhs);
        }
    }

    /// Call `add(vertex, w p)` for every projection that does not depend on the positions.
    pub(crate) fn constant_rhs(&self, model: &Model, add: &mut dyn FnMut(usize, Vector3<f64>)) {
        for s in &self.sets {
            s.constant_rhs(model, add);
        }
    }

    /// The adjoint of [`Constraints::constant_rhs`] (attachment targets).
    pub(crate) fn constant_rhs_adjoint(
        &self,
        model: &Model,
        adjoint: &dyn Fn(usize) -> Option<Vector3<f64>>,
        targets: &mut [Vector3<f64>],
    ) {
        for s in &self.sets {
            s.constant_rhs_adjoint(model, adjoint, targets);
        }
    }

    /// Linearize every set at `q` (implicit mode).
    pub(crate) fn linearize(&mut self, model: &Model, q: &[Vector3<f64>]) -> Result<(), NotDifferentiable> {
        for s in &mut self.sets {
            s.linearize(model, q)?;
        }
        Ok(())
    }

    /// The backward of one local step at positions `q` (all vertices): given the adjoint `y` of
    /// the gathered right-hand side (all vertices, zero at fixed ones), write
    /// `out = J (dp/dq)^T J^T y` per vertex and add the parameter adjoints: the weights'
    /// `<F_t(y), P_t/w_t> - <F_t(y), F_t(x_next)>` (right-hand side minus matrix term of the
    /// solve whose solution is `x_next`; without `x_next` the matrix term is left out, see
    /// [`Constraints::matrix_terms`]) and the activations'.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn adjoint(
        &mut self,
        model: &Model,
        q: &[Vector3<f64>],
        y: &[Vector3<f64>],
        x_next: Option<&[Vector3<f64>]>,
        activations: &[f64],
        lin: Linearize<'_>,
        out: &mut [Vector3<f64>],
        grads: ParamGrads<'_>,
    ) -> Result<(), NotDifferentiable> {
        let mut ctx = AdjointContext {
            q,
            y,
            x_next,
            activations,
            lin,
            per_tet: &mut self.per_tet,
            grads,
        };
        for s in &mut self.sets {
            s.adjoint(model, &mut ctx)?;
        }
        gather_tets_staged(model, &self.per_tet, &mut self.corners, out);
        for s in &mut self.sets {
            s.adjoint_gather_add(model, q, y, out)?;
        }
        Ok(())
    }

    /// Subtract every set's weight matrix terms `sum_pairs a^T (dL/dw) b` (Eq. G3).
    pub(crate) fn matrix_terms(&self, model: &Model, pairs: &[VectorPair<'_>], mut grads: ParamGrads<'_>) {
        for s in &self.sets {
            s.matrix_terms(model, pairs, &mut grads);
        }
    }
}

/// [`gather_tets`] in two passes: every tet's four corner terms `m_t a_{t,i}` in tet order
/// into `corners` (streaming through the per-tet matrices and the geometry once), then each
/// vertex's sum over `corners` in the same order as [`gather_tets`], so the result is
/// bit-identical; the second pass reads one 24-byte term per corner instead of the tet's matrix
/// and geometry (about four cache lines), which is what the one-pass gather waits on for meshes
/// beyond the caches.
pub(crate) fn gather_tets_staged(
    model: &Model,
    per_tet: &[Matrix3<f64>],
    corners: &mut [[Vector3<f64>; 4]],
    out: &mut [Vector3<f64>],
) {
    let geo = &model.fem.geometry;
    corners
        .par_iter_mut()
        .zip(per_tet.par_iter().zip(geo.par_iter()))
        .with_min_len(512)
        .for_each(|(c, (m, g))| {
            for (ci, a) in c.iter_mut().zip(&g.grads) {
                *ci = m * a;
            }
        });
    sum_corners(model, corners, out);
}

/// `out[v] = sum over tets t of v: corners[t][corner(v)]`, in the order of [`gather_tets`]:
/// the second pass of [`gather_tets_staged`], for callers that fill the corner terms
/// themselves.
pub(crate) fn sum_corners(model: &Model, corners: &[[Vector3<f64>; 4]], out: &mut [Vector3<f64>]) {
    let adj = &model.vertex_tets;
    out.par_iter_mut().enumerate().with_min_len(256).for_each(|(v, r)| {
        let mut s = Vector3::zeros();
        for &(t, a) in adj.of(v) {
            s += corners[t as usize][a as usize];
        }
        *r = s;
    });
}

/// `out[v] = sum over tets t of v: m_t a_{t, corner(v)}` (`J` applied per tet) in one pass:
/// the form [`gather_tets_staged`] replaced, kept as the reference its test compares with.
#[cfg(test)]
pub(crate) fn gather_tets(model: &Model, per_tet: &[Matrix3<f64>], out: &mut [Vector3<f64>]) {
    let geo = &model.fem.geometry;
    let adj = &model.vertex_tets;
    out.par_iter_mut().enumerate().with_min_len(256).for_each(|(v, r)| {
        let mut s = Vector3::zeros();
        for &(t, a) in adj.of(v) {
            s += per_tet[t as usize] * geo[t as usize].grads[a as usize];
        }
        *r = s;
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The staged gather sums the same products in the same order as the one-pass gather:
    /// equal to the bit, on one thread and on several (the forward and adjoint local steps use
    /// it, so trajectories and gradients do not move).
    #[test]
    fn staged_gather_is_bit_identical_to_the_one_pass_gather() {
        let model = crate::model::fixtures::free_box([9, 5, 4], [1.0, 0.5, 0.4]).unwrap();
        let n = model.tets.len();
        let per_tet: Vec<Matrix3<f64>> = (0..n)
            .map(|t| Matrix3::from_fn(|i, j| (((t * 7 + i * 3 + j) % 13) as f64 - 6.0) * 0.1f64.powi((t % 5) as i32)))
            .collect();
        let mut corners = vec![[Vector3::zeros(); 4]; n];
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut a = vec![Vector3::zeros(); model.rest.len()];
            let mut b = vec![Vector3::repeat(f64::NAN); model.rest.len()];
            pool.install(|| {
                gather_tets(&model, &per_tet, &mut a);
                gather_tets_staged(&model, &per_tet, &mut corners, &mut b);
            });
            assert!(a.iter().any(|v| v.norm() > 0.0));
            let bits = |v: &[Vector3<f64>]| v.iter().flat_map(|x| x.iter().map(|c| c.to_bits())).collect::<Vec<_>>();
            assert_eq!(bits(&a), bits(&b), "{threads} threads");
        }
    }
}
