//! The local step of projective dynamics (METHOD.md Eq. 3): for each tet, project the
//! deformation gradient onto the corotated and volume constraint sets, in parallel, into
//! preallocated buffers; then gather `J p` per vertex (`sum_t w_t p_t a_{t,i}`) without write
//! conflicts. Nothing allocates per iteration.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::SolverError;
use crate::actuator::ActuatorKind;
use crate::kernel::actuator::{muscle_target, pneumatic_target};
use crate::kernel::svd::{self, LANES};
use crate::kernel::{volume, ProjectionError};
use crate::model::Model;

/// One tet's decomposition at a local step: the SVD of `F` and the volume projection's target
/// singular values (zero where the tet has no volume constraint). Recorded for the backward pass,
/// which linearizes the projection at the same point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TetSvd {
    /// `F = U diag(sigma) V^T`.
    pub svd: svd::Svd3,
    /// Target singular values of the volume constraint.
    pub target: Vector3<f64>,
}

impl Default for TetSvd {
    fn default() -> Self {
        Self {
            svd: svd::Svd3 {
                u: Matrix3::identity(),
                sigma: Vector3::repeat(1.0),
                v: Matrix3::identity(),
            },
            target: Vector3::zeros(),
        }
    }
}

/// Per-tet buffers of the local step.
#[derive(Debug, Clone)]
pub struct LocalStep {
    /// `w_rot p_rot + w_vol p_vol` per tet (what the right-hand side needs).
    pub weighted: Vec<Matrix3<f64>>,
    /// Last `V` of each tet's SVD (warm start for the next one).
    pub v_warm: Vec<Matrix3<f64>>,
    /// Constraint energy per tet.
    pub energy: Vec<f64>,
    /// Last volume-projection multiplier of each tet (warm start for the next one).
    pub t_warm: Vec<f64>,
    /// Actuator buffers (`None` when the model has no actuators).
    pub actuators: Option<ActuatorStep>,
    /// Cloth buffers (`None` when the model has no cloth).
    pub cloth: Option<crate::cloth::ClothStep>,
}

/// Per-cell buffers of the actuator projections and the current activations.
#[derive(Debug, Clone)]
pub struct ActuatorStep {
    /// Activation of each group.
    pub activations: Vec<f64>,
    /// `w p` per cell, as it enters the right-hand side (`w p m^T` for a fibre).
    pub weighted: Vec<Matrix3<f64>>,
    /// Last `V` of each pneumatic cell's SVD (warm start).
    pub v_warm: Vec<Matrix3<f64>>,
    /// Constraint energy per cell.
    pub energy: Vec<f64>,
}

impl ActuatorStep {
    /// Project every actuator cell at positions `q` (in parallel) and add the results to the
    /// per-tet `weighted`; returns the actuators' energy.
    fn project(
        &mut self,
        model: &Model,
        q: &[Vector3<f64>],
        weighted: &mut [Matrix3<f64>],
    ) -> Result<f64, SolverError> {
        let Some(act) = model.actuators.as_ref() else {
            return Ok(0.0);
        };
        let (tets, geo, activations) = (&model.tets, &model.fem.geometry, &self.activations);
        self.weighted
            .par_iter_mut()
            .zip(self.v_warm.par_iter_mut())
            .zip(self.energy.par_iter_mut())
            .zip(act.cells.par_iter())
            .with_min_len(64)
            .try_for_each(|(((out, v), e), c)| {
                let [i0, i1, i2, i3] = tets[c.tet];
                let x0 = q[i0];
                let f = Matrix3::from_columns(&[q[i1] - x0, q[i2] - x0, q[i3] - x0]) * geo[c.tet].p_inv;
                let group = &act.groups[c.group];
                let a = activations[c.group];
                let fail = |source| SolverError::Actuator {
                    group: group.name.clone(),
                    tet: c.tet,
                    source,
                };
                match group.kind {
                    ActuatorKind::Pneumatic => {
                        if !f.iter().all(|x| x.is_finite()) {
                            return Err(fail(crate::kernel::actuator::ActuatorError::NonFinite));
                        }
                        let d = svd::svd3_warm(&f, v);
                        *v = d.v;
                        let p = pneumatic_target(&d, a).map_err(fail)?;
                        *out = p * c.weight;
                        *e = crate::kernel::energy(c.weight, &f, &p);
                    }
                    ActuatorKind::Muscle => {
                        let fm = f * c.direction;
                        let p = muscle_target(&fm, a).map_err(fail)?;
                        *out = (p * c.direction.transpose()) * c.weight;
                        *e = 0.5 * c.weight * (fm - p).norm_squared();
                    }
                }
                Ok(())
            })?;
        for (c, w) in act.cells.iter().zip(&self.weighted) {
            weighted[c.tet] += w;
        }
        Ok(self.energy.iter().sum())
    }
}

impl LocalStep {
    /// Buffers for `tets` tets (no actuators).
    pub fn new(tets: usize) -> Self {
        Self {
            weighted: vec![Matrix3::zeros(); tets],
            v_warm: vec![Matrix3::identity(); tets],
            energy: vec![0.0; tets],
            t_warm: vec![0.0; tets],
            actuators: None,
            cloth: None,
        }
    }

    /// Buffers for `model`, with actuator buffers when it has actuators (activations at their
    /// schedules' values at time 0).
    pub fn for_model(model: &Model) -> Self {
        let mut s = Self::new(model.tets.len());
        s.cloth = model.cloth.as_ref().map(crate::cloth::ClothStep::new);
        s.actuators = model.actuators.as_ref().map(|act| {
            let n = act.cells.len();
            ActuatorStep {
                activations: act.groups.iter().map(|g| g.activation.at(0.0)).collect(),
                weighted: vec![Matrix3::zeros(); n],
                v_warm: vec![Matrix3::identity(); n],
                energy: vec![0.0; n],
            }
        });
        s
    }

    /// Project every tet of `model` at positions `q`; returns the total constraint energy.
    /// Tets are decomposed `LANES` at a time by one fused kernel (SVD, volume projection,
    /// composition), chunks in parallel.
    pub fn project(&mut self, model: &Model, q: &[Vector3<f64>]) -> Result<f64, SolverError> {
        self.project_recording(model, q, None)
    }

    /// [`LocalStep::project`], also writing every tet's decomposition into `record` (one entry
    /// per tet) when given.
    pub fn project_recording(
        &mut self,
        model: &Model,
        q: &[Vector3<f64>],
        record: Option<&mut [TetSvd]>,
    ) -> Result<f64, SolverError> {
        let tets = &model.tets;
        if record.as_ref().is_some_and(|r| r.len() != tets.len()) {
            return Err(SolverError::input(format!(
                "local step record has {} entries for {} tets",
                record.map_or(0, |r| r.len()),
                tets.len()
            )));
        }
        let geo = &model.fem.geometry;
        let (w_rot, w_vol) = (&model.w_rot, &model.w_vol);
        type Bufs<'b> = (
            ((&'b mut [Matrix3<f64>], &'b mut [Matrix3<f64>]), &'b mut [f64]),
            &'b mut [f64],
        );
        let body = |chunk: usize, (((out, v), e), tw): Bufs<'_>, svd_out: Option<&mut [TetSvd]>| {
            let t0 = chunk * LANES;
            let len = out.len();
            let f: [Matrix3<f64>; LANES] = std::array::from_fn(|k| {
                if k < len {
                    let [i0, i1, i2, i3] = tets[t0 + k];
                    let x0 = q[i0];
                    Matrix3::from_columns(&[q[i1] - x0, q[i2] - x0, q[i3] - x0]) * geo[t0 + k].p_inv
                } else {
                    Matrix3::identity()
                }
            });
            let chunk = Chunk {
                w_rot: &w_rot[t0..t0 + len],
                w_vol: &w_vol[t0..t0 + len],
                v_warm: v,
                t_warm: tw,
                out,
                energy: e,
                svd_out,
            };
            project_chunk(&f, chunk).map_err(|(k, err)| match err {
                Some(source) => SolverError::Projection { tet: t0 + k, source },
                None => SolverError::NonFinite(format!("tet {}: deformation gradient is not finite", t0 + k)),
            })
        };
        let bufs = self
            .weighted
            .par_chunks_mut(LANES)
            .zip(self.v_warm.par_chunks_mut(LANES))
            .zip(self.energy.par_chunks_mut(LANES))
            .zip(self.t_warm.par_chunks_mut(LANES));
        match record {
            Some(rec) => bufs
                .zip(rec.par_chunks_mut(LANES))
                .enumerate()
                .with_min_len(32)
                .try_for_each(|(chunk, (b, r))| body(chunk, b, Some(r)))?,
            None => bufs
                .enumerate()
                .with_min_len(32)
                .try_for_each(|(chunk, b)| body(chunk, b, None))?,
        }
        let mut energy: f64 = self.energy.iter().sum();
        if let Some(act) = self.actuators.as_mut() {
            energy += act.project(model, q, &mut self.weighted)?;
        }
        if let (Some(cs), Some(cl)) = (self.cloth.as_mut(), model.cloth.as_ref()) {
            energy += cs.project(cl, q)?;
        }
        Ok(energy)
    }

    /// `rhs[v] = sum over tets t of v: weighted_t a_{t, corner(v)}` for every vertex.
    pub fn gather(&self, model: &Model, rhs: &mut [Vector3<f64>]) {
        let geo = &model.fem.geometry;
        let adj = &model.vertex_tets;
        rhs.par_iter_mut().enumerate().with_min_len(256).for_each(|(v, r)| {
            let mut s = Vector3::zeros();
            for &(t, a) in adj.of(v) {
                s += self.weighted[t as usize] * geo[t as usize].grads[a as usize];
            }
            *r = s;
        });
        if let (Some(cs), Some(cl)) = (self.cloth.as_ref(), model.cloth.as_ref()) {
            cs.gather_add(cl, rhs);
        }
    }
}

/// One chunk's inputs and outputs (`len <= LANES` tets).
struct Chunk<'a> {
    w_rot: &'a [f64],
    w_vol: &'a [f64],
    v_warm: &'a mut [Matrix3<f64>],
    t_warm: &'a mut [f64],
    out: &'a mut [Matrix3<f64>],
    energy: &'a mut [f64],
    svd_out: Option<&'a mut [TetSvd]>,
}

/// A failed tet of a chunk: its lane and the projection error (`None`: non-finite `F`).
type ChunkError = (usize, Option<ProjectionError>);

/// Dispatch to the AVX2 build of [`chunk_kernel`] when the CPU has it.
fn project_chunk(f: &[Matrix3<f64>; LANES], c: Chunk<'_>) -> Result<(), ChunkError> {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { chunk_avx2(f, c) };
        }
    }
    chunk_kernel(f, c)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn chunk_avx2(f: &[Matrix3<f64>; LANES], c: Chunk<'_>) -> Result<(), ChunkError> {
    chunk_kernel(f, c)
}

/// SVD (warm-started), volume projection (warm-started) and
/// `p = w_rot U V^T + w_vol U X V^T = U diag(w_rot + w_vol x) V^T` per tet, with the energies
/// from the singular values: `|F - U V^T|^2 = sum (s - 1)^2`, `|F - U X V^T|^2 = sum (s - x)^2`.
/// Everything is inlined into one function so the AVX2 build covers all of it and the
/// per-lane arrays stay in registers or on this frame.
#[inline(always)]
fn chunk_kernel(f: &[Matrix3<f64>; LANES], mut c: Chunk<'_>) -> Result<(), ChunkError> {
    let len = c.out.len();
    let v0: [Matrix3<f64>; LANES] = std::array::from_fn(|k| if k < len { c.v_warm[k] } else { Matrix3::identity() });
    let svds = svd::batch_generic(f, &v0);
    let sig: [Vector3<f64>; LANES] = std::array::from_fn(|k| svds[k].sigma);
    let targets = if c.w_vol.iter().any(|&w| w > 0.0) {
        let mut t: [f64; LANES] = std::array::from_fn(|k| if k < len { c.t_warm[k] } else { 0.0 });
        let x = volume::batch_generic(&sig, 1.0, &mut t).map_err(|err| (0, Some(err)))?;
        c.t_warm.copy_from_slice(&t[..len]);
        Some(x)
    } else {
        None
    };
    for k in 0..len {
        let svd = &svds[k];
        c.v_warm[k] = svd.v;
        let s = svd.sigma;
        let mut diag = Vector3::repeat(c.w_rot[k]);
        let mut en = 0.5 * c.w_rot[k] * (s - Vector3::repeat(1.0)).norm_squared();
        if let Some(x) = &targets {
            if c.w_vol[k] > 0.0 {
                diag += x[k] * c.w_vol[k];
                en += 0.5 * c.w_vol[k] * (s - x[k]).norm_squared();
            }
        }
        if !en.is_finite() {
            return Err((k, None));
        }
        c.out[k] = svd.compose(&diag);
        c.energy[k] = en;
        if let Some(rec) = c.svd_out.as_deref_mut() {
            rec[k] = TetSvd {
                svd: *svd,
                target: match (&targets, c.w_vol[k] > 0.0) {
                    (Some(x), true) => x[k],
                    _ => Vector3::zeros(),
                },
            };
        }
    }
    Ok(())
}
