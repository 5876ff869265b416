//! Cloth bending: per interior vertex, the cotangent Laplacian `Delta_i x` (the mean-curvature
//! normal) is projected onto the vectors of its rest length `|Delta_i X|`; energy
//! `k_b A_i / 2 |Delta_i x - p_i|^2`. A flat rest shape gives `p_i = 0`: bending is then a
//! constant quadratic form. Its share of `L` is the stencil's block `w c_a c_b`.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::{ConstraintError, ConstraintSet, NotDifferentiable, ProjectContext};
use crate::cloth::Cloth;
use crate::model::Model;

/// Every bending stencil of a model's cloth, with its buffers.
#[derive(Debug, Clone)]
pub(crate) struct ClothBend {
    /// `w p` per stencil (forward) or `w dp` (adjoint).
    weighted: Vec<Vector3<f64>>,
    /// Bending energy per stencil.
    energy: Vec<f64>,
}

fn cloth(model: &Model) -> &Cloth {
    model.cloth.as_ref().expect("a bending set exists only with cloth")
}

impl ClothBend {
    /// The bending stencils of `model`'s cloth (`None` without cloth).
    pub(crate) fn new(model: &Model) -> Option<Self> {
        let n = model.cloth.as_ref()?.bends.len();
        Some(Self {
            weighted: vec![Vector3::zeros(); n],
            energy: vec![0.0; n],
        })
    }

    /// `rhs[v] += sum_i weighted_i c_{i,v}` for every vertex.
    fn gather(&self, cloth: &Cloth, rhs: &mut [Vector3<f64>]) {
        let bends = &cloth.bends;
        rhs.par_iter_mut().enumerate().with_min_len(256).for_each(|(v, r)| {
            for &(b, k) in cloth.vertex_bends.of(v) {
                let b = b as usize;
                *r += self.weighted[b] * bends.coefs[bends.offsets[b] + k as usize];
            }
        });
    }
}

/// The bending projection: the vector of length `rest` closest to `lap` (`0` on a flat rest
/// shape; the rest direction where `lap` vanishes).
#[inline]
pub fn bending_target(lap: Vector3<f64>, rest: f64, rest_dir: &Vector3<f64>) -> Vector3<f64> {
    if rest == 0.0 {
        return Vector3::zeros();
    }
    let n = lap.norm();
    if n > 0.0 {
        lap * (rest / n)
    } else {
        rest_dir * rest
    }
}

impl ConstraintSet for ClothBend {
    fn name(&self) -> &'static str {
        "cloth bending"
    }

    fn hessian_term(&self) -> super::HessianTerm {
        super::HessianTerm::Unsupported("cloth")
    }

    fn add_blocks(&self, model: &Model, values: &mut [f64]) {
        let bends = &cloth(model).bends;
        for i in 0..bends.len() {
            let (_, c) = bends.stencil(i);
            let slots = &bends.slots[bends.slot_offsets[i]..bends.slot_offsets[i + 1]];
            let k = c.len();
            for a in 0..k {
                for b in 0..k {
                    values[slots[k * a + b] as usize] += bends.weight[i] * c[a] * c[b];
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
        let bends = &cloth(model).bends;
        self.weighted
            .par_iter_mut()
            .zip(self.energy.par_iter_mut())
            .enumerate()
            .with_min_len(256)
            .for_each(|(i, (out, e))| {
                let lap = bends.apply(i, q);
                let p = bending_target(lap, bends.rest[i], &bends.rest_dir[i]);
                let w = bends.weight[i];
                *out = p * w;
                *e = 0.5 * w * (lap - p).norm_squared();
            });
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
        let bends = &cloth.bends;
        self.weighted
            .par_iter_mut()
            .enumerate()
            .with_min_len(256)
            .try_for_each(|(i, dp)| {
                let rest = bends.rest[i];
                if rest == 0.0 {
                    *dp = Vector3::zeros();
                    return Ok(());
                }
                let lap = bends.apply(i, q);
                let n = lap.norm();
                if n == 0.0 {
                    return Err(NotDifferentiable(format!(
                        "bending stencil {i}: the Laplacian vanishes, its projection has no derivative"
                    )));
                }
                let u = lap / n;
                let dl = bends.apply(i, y);
                *dp = (dl - u * u.dot(&dl)) * (rest / n * bends.weight[i]);
                Ok(())
            })?;
        self.gather(cloth, out);
        Ok(())
    }
}
