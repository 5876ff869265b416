//! Hyperelastic tets (docs/method.md section 2.4, Eqs. H1-H6): bodies whose material is the
//! fixed-corotated or the stable Neo-Hookean energy. They are not projective constraints, but
//! they enter the step through the same seam: each tet adds `c_t A^T A` to `L` (the weight
//! `c_t = 2 mu V` of `model::HyperTets`) and writes `c_t F - V P(F)` as its "weighted projection",
//! so the global step's gradient `A x - b - J p` gains exactly `V P(F) : dF/dx`, the energy's
//! gradient, and the Hessian `A - J K J^T` with `K_t = c_t I - V dP/dF` gains `V dP/dF` (Eq. H6).
//! `c_t` cancels from both, so it is not a parameter; it makes the factored `M/h^2 + L` a good
//! preconditioner of Newton's conjugate gradients.
//!
//! Local-global iterations would be a fixed-Hessian descent without a line search here, so only
//! Newton's method takes these tets (`HessianTerm::Own`). Their parameter adjoints
//! (`dL/dmu`, `dL/dlambda` per tet) go into the tets' `w_rot` and `w_vol` slots, which the
//! elasticity kind leaves to them (their projective weights are zero).

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::{
    AdjointContext, ConstraintError, ConstraintSet, HessianTerm, Linearize, NotDifferentiable, ProjectContext,
};
use crate::kernel::hyperelastic::{self, Mat9, Polars};
use crate::kernel::svd::LANES;
use crate::model::{HyperTets, Model};

/// The hyperelastic tets of a model with their buffers.
#[derive(Debug, Clone)]
pub(crate) struct Hyperelastic {
    /// `c F - V P(F)` per hyperelastic tet at the last local step.
    wp: Vec<Matrix3<f64>>,
    /// `V Psi(F)` per hyperelastic tet.
    energy: Vec<f64>,
    /// `K_t = c I - V dP/dF` per tet at the last linearization (backward pass, exact).
    cache: Vec<Mat9>,
    /// `K~_t` of Newton's Hessian (exact or with `dP/dF` projected to its positive part).
    hessian: Vec<Mat9>,
}

impl Hyperelastic {
    /// The set of `model`'s hyperelastic tets (`None` without any).
    pub(crate) fn new(model: &Model) -> Option<Self> {
        let h = model.hyper.as_ref()?;
        Some(Self {
            wp: vec![Matrix3::zeros(); h.len()],
            energy: vec![0.0; h.len()],
            cache: Vec::new(),
            hessian: Vec::new(),
        })
    }
}

fn hyper(model: &Model) -> &HyperTets {
    model.hyper.as_ref().expect("a hyperelastic set has hyperelastic tets")
}

/// `c I - V M` (or `- V M+` for the positive part).
fn k_of(c: f64, volume: f64, d: &Mat9) -> Mat9 {
    Mat9::identity() * c - d * volume
}

/// `dP/dF` of the hyperelastic tets of batch `c` (`len` of them, from tet `c * LANES`) at `q`,
/// their polar decompositions computed together: `each(i, t, dP/dF)` per tet, `i` its index
/// among the hyperelastic tets and `t` its tet.
fn for_batch(
    model: &Model,
    h: &HyperTets,
    q: &[Vector3<f64>],
    c: usize,
    len: usize,
    mut each: impl FnMut(usize, usize, Mat9),
) {
    let i0 = c * LANES;
    let mut f = [Matrix3::identity(); LANES];
    for (k, fk) in f[..len].iter_mut().enumerate() {
        *fk = model.tet_deformation(h.tets[i0 + k], q);
    }
    let polars = Polars::new(&h.energy[i0..i0 + len], &f[..len]);
    for (k, fk) in f[..len].iter().enumerate() {
        let i = i0 + k;
        each(
            i,
            h.tets[i],
            h.energy[i].stress_derivative_at(h.lame[i], fk, &polars, k),
        );
    }
}

/// `out[v] += M a_v` over the tet's vertices (the gather of one tet's per-tet matrix).
fn gather_add(model: &Model, t: usize, m: &Matrix3<f64>, out: &mut [Vector3<f64>]) {
    let g = &model.fem.geometry[t];
    for (a, &v) in model.tets[t].iter().enumerate() {
        out[v] += m * g.grads[a];
    }
}

impl ConstraintSet for Hyperelastic {
    fn name(&self) -> &'static str {
        "hyperelastic"
    }

    fn hessian_term(&self) -> HessianTerm {
        HessianTerm::Own
    }

    fn tet_coefficients(&self, model: &Model, k: &mut [f64]) {
        let h = hyper(model);
        for (i, &t) in h.tets.iter().enumerate() {
            k[t] += h.weight[i] / model.fem.geometry[t].volume;
        }
    }

    fn project(
        &mut self,
        model: &Model,
        q: &[Vector3<f64>],
        ctx: &mut ProjectContext<'_>,
    ) -> Result<f64, ConstraintError> {
        let h = hyper(model);
        // LANES tets at a time: their polar decompositions through the batched SVD.
        self.wp
            .par_chunks_mut(LANES)
            .zip(self.energy.par_chunks_mut(LANES))
            .enumerate()
            .with_min_len(8)
            .try_for_each(|(c, (wp, e))| {
                let i0 = c * LANES;
                let len = wp.len();
                let mut f = [Matrix3::identity(); LANES];
                for (k, fk) in f[..len].iter_mut().enumerate() {
                    let t = h.tets[i0 + k];
                    *fk = model.tet_deformation(t, q);
                    if !fk.iter().all(|x| x.is_finite()) {
                        return Err(ConstraintError::NonFinite(format!(
                            "tet {t}: deformation gradient is not finite"
                        )));
                    }
                }
                let polars = Polars::new(&h.energy[i0..i0 + len], &f[..len]);
                for k in 0..len {
                    let (i, t) = (i0 + k, h.tets[i0 + k]);
                    let vol = model.fem.geometry[t].volume;
                    let (stress, psi) = h.energy[i].stress_and_energy_at(h.lame[i], &f[k], &polars, k);
                    wp[k] = f[k] * h.weight[i] - stress * vol;
                    e[k] = vol * psi;
                }
                Ok(())
            })?;
        for (i, &t) in h.tets.iter().enumerate() {
            ctx.per_tet[t] += self.wp[i];
        }
        Ok(self.energy.iter().sum())
    }

    fn linearize(&mut self, model: &Model, q: &[Vector3<f64>]) -> Result<(), NotDifferentiable> {
        let h = hyper(model);
        self.cache.resize(h.len(), Mat9::zeros());
        self.cache
            .par_chunks_mut(LANES)
            .enumerate()
            .with_min_len(8)
            .for_each(|(c, ks)| {
                for_batch(model, h, q, c, ks.len(), |i, t, d| {
                    ks[i - c * LANES] = k_of(h.weight[i], model.fem.geometry[t].volume, &d);
                });
            });
        Ok(())
    }

    fn adjoint(&mut self, model: &Model, ctx: &mut AdjointContext<'_, '_>) -> Result<(), NotDifferentiable> {
        let h = hyper(model);
        if !matches!(ctx.lin, Linearize::Cached) {
            self.linearize(model, ctx.q)?;
        }
        for (i, &t) in h.tets.iter().enumerate() {
            let fy = model.tet_deformation(t, ctx.y);
            // K_t is symmetric: its adjoint is itself.
            ctx.per_tet[t] += hyperelastic::apply(&self.cache[i], &fy);
            // d(c F - V P)/d(mu, lambda) = -V dP/d(mu, lambda); c is not a parameter (Eq. H6).
            let f = model.tet_deformation(t, ctx.q);
            let (dmu, dla) = h.energy[i].stress_parameter_derivatives(h.lame[i], &f);
            let vol = model.fem.geometry[t].volume;
            ctx.grads.w_rot[t] -= vol * fy.dot(&dmu);
            ctx.grads.w_vol[t] -= vol * fy.dot(&dla);
        }
        Ok(())
    }

    fn linearize_hessian(&mut self, model: &Model, q: &[Vector3<f64>], projected: bool) -> usize {
        let h = hyper(model);
        self.hessian.resize(h.len(), Mat9::zeros());
        self.hessian
            .par_chunks_mut(LANES)
            .enumerate()
            .with_min_len(8)
            .map(|(c, ks)| {
                let mut clamped_here = 0;
                for_batch(model, h, q, c, ks.len(), |i, t, d| {
                    let (d, clamped) = if projected {
                        hyperelastic::positive_part(&d)
                    } else {
                        (d, 0)
                    };
                    clamped_here += clamped;
                    ks[i - c * LANES] = k_of(h.weight[i], model.fem.geometry[t].volume, &d);
                });
                clamped_here
            })
            .sum()
    }

    fn apply_hessian_add(&self, model: &Model, y: &[Vector3<f64>], out: &mut [Vector3<f64>]) {
        let h = hyper(model);
        for (i, &t) in h.tets.iter().enumerate() {
            let m = hyperelastic::apply(&self.hessian[i], &model.tet_deformation(t, y));
            gather_add(model, t, &m, out);
        }
    }
}
