//! The cloth part of the local step: project every triangle and bending stencil (in parallel,
//! into preallocated buffers) and add `J p` to the right-hand side per vertex.

use nalgebra::{Matrix3x2, Vector3};
use rayon::prelude::*;

use super::{deformation_gradient, Cloth};
use crate::kernel::polar32::Polar;
use crate::solver::SolverError;

/// Buffers of the cloth projections.
#[derive(Debug, Clone)]
pub struct ClothStep {
    /// `w R` per triangle.
    pub tri_weighted: Vec<Matrix3x2<f64>>,
    /// Stretching energy per triangle.
    pub tri_energy: Vec<f64>,
    /// `w p` per bending stencil.
    pub bend_weighted: Vec<Vector3<f64>>,
    /// Bending energy per stencil.
    pub bend_energy: Vec<f64>,
}

impl ClothStep {
    /// Buffers for `cloth`.
    pub fn new(cloth: &Cloth) -> Self {
        Self {
            tri_weighted: vec![Matrix3x2::zeros(); cloth.num_triangles()],
            tri_energy: vec![0.0; cloth.num_triangles()],
            bend_weighted: vec![Vector3::zeros(); cloth.bends.len()],
            bend_energy: vec![0.0; cloth.bends.len()],
        }
    }

    /// Project every triangle and bending stencil at positions `q`; returns the cloth's
    /// constraint energy.
    pub fn project(&mut self, cloth: &Cloth, q: &[Vector3<f64>]) -> Result<f64, SolverError> {
        self.tri_weighted
            .par_iter_mut()
            .zip(self.tri_energy.par_iter_mut())
            .enumerate()
            .with_min_len(256)
            .try_for_each(|(t, (out, e))| {
                let f = deformation_gradient(q, &cloth.triangles[t], &cloth.geometry[t]);
                if !f.iter().all(|x| x.is_finite()) {
                    return Err(SolverError::NonFinite(format!(
                        "cloth triangle {t}: in-plane deformation gradient is not finite"
                    )));
                }
                let p = Polar::new(&f);
                let w = cloth.w_stretch[t];
                *out = p.r * w;
                *e = 0.5 * w * p.distance_squared();
                Ok(())
            })?;
        let bends = &cloth.bends;
        self.bend_weighted
            .par_iter_mut()
            .zip(self.bend_energy.par_iter_mut())
            .enumerate()
            .with_min_len(256)
            .for_each(|(i, (out, e))| {
                let lap = bends.apply(i, q);
                let p = bending_target(lap, bends.rest[i], &bends.rest_dir[i]);
                let w = bends.weight[i];
                *out = p * w;
                *e = 0.5 * w * (lap - p).norm_squared();
            });
        let energy = self.tri_energy.iter().sum::<f64>() + self.bend_energy.iter().sum::<f64>();
        if energy.is_finite() {
            Ok(energy)
        } else {
            Err(SolverError::NonFinite("cloth constraint energy is not finite".into()))
        }
    }

    /// `rhs[v] += sum_t w_t R_t g_{t,v} + sum_i w_i p_i c_{i,v}` for every vertex.
    pub fn gather_add(&self, cloth: &Cloth, rhs: &mut [Vector3<f64>]) {
        let (geo, bends) = (&cloth.geometry, &cloth.bends);
        rhs.par_iter_mut().enumerate().with_min_len(256).for_each(|(v, r)| {
            for &(t, a) in cloth.vertex_triangles.of(v) {
                *r += self.tri_weighted[t as usize] * geo[t as usize].grads[a as usize];
            }
            for &(b, k) in cloth.vertex_bends.of(v) {
                let b = b as usize;
                *r += self.bend_weighted[b] * bends.coefs[bends.offsets[b] + k as usize];
            }
        });
    }
}

impl ClothStep {
    /// The linearised cloth projections applied to `y` (the backward pass): for every vertex,
    /// `out[v] += sum_t w_t dR_t[F_t(y)] g_{t,v} + sum_i w_i dp_i[Delta_i y] c_{i,v}`, with the
    /// projections linearised at `q`. Uses this step's buffers as scratch. Fails at a collapsed
    /// triangle or a vanishing curved Laplacian (no derivative there).
    pub fn backward_add(
        &mut self,
        cloth: &Cloth,
        q: &[Vector3<f64>],
        y: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
    ) -> Result<(), String> {
        self.tri_weighted
            .par_iter_mut()
            .enumerate()
            .with_min_len(256)
            .try_for_each(|(t, dp)| {
                let (tri, g) = (&cloth.triangles[t], &cloth.geometry[t]);
                let p = Polar::new(&deformation_gradient(q, tri, g));
                if p.collapsed {
                    return Err(format!(
                        "cloth triangle {t} is collapsed to a segment: its in-plane projection has no derivative"
                    ));
                }
                *dp = p.differential(&deformation_gradient(y, tri, g)) * cloth.w_stretch[t];
                Ok(())
            })?;
        let bends = &cloth.bends;
        self.bend_weighted
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
                    return Err(format!(
                        "bending stencil {i}: the Laplacian vanishes, its projection has no derivative"
                    ));
                }
                let u = lap / n;
                let dl = bends.apply(i, y);
                *dp = (dl - u * u.dot(&dl)) * (rest / n * bends.weight[i]);
                Ok(())
            })?;
        self.gather_add(cloth, out);
        Ok(())
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
