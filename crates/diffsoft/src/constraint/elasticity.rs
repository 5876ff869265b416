//! Tet elasticity: per tet a corotated constraint (`F` onto the rotations, weight `w_rot`) and
//! a volume constraint (`F` onto `det F = 1`, weight `w_vol`), both on the deformation gradient
//! (docs/method.md section 2). Their weighted projections combine into one matrix per tet,
//! `p = w_rot U V^T + w_vol U X V^T = U diag(w_rot + w_vol x) V^T`, computed `LANES` tets at a
//! time by one fused kernel (warm-started SVD, volume projection, composition; AVX2 where the
//! CPU has it), chunks in parallel, into preallocated buffers. The adjoint applies the
//! projection's spectral-function differential ([`TetLinearization`], Eq. G2) with the same
//! batched kernels.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::{
    AdjointContext, ConstraintError, ConstraintSet, Linearize, NotDifferentiable, ParamGrads, ProjectContext,
    VectorPair,
};
use crate::kernel::linearization::TetLinearization;
use crate::kernel::svd::{self, svd3_warm_batch, LaneMatrix, IDENTITY_LANES, LANES};
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

/// The corotated and volume constraints of every tet, with their buffers.
#[derive(Debug, Clone)]
pub(crate) struct Elasticity {
    /// Last `V` of each tet's SVD (warm start of the next local step), one structure-of-arrays
    /// block per chunk of `LANES` tets, where the batched SVD reads and writes it.
    v_warm: Vec<LaneMatrix>,
    /// Constraint energy per tet.
    energy: Vec<f64>,
    /// Last volume-projection multiplier of each tet (warm start).
    t_warm: Vec<f64>,
    /// Warm start of the adjoint's SVDs.
    v_warm_adjoint: Vec<Matrix3<f64>>,
    /// Linearizations at one point (implicit mode: one point, many applications).
    cache: Vec<TetLinearization>,
    /// Per tet: whether its body has the volume term (its weight `w_vol = nu E V / (1 + nu)` may
    /// be 0, at Poisson ratio 0, and `dL/dw_vol` still needs the volume target there).
    volume_on: Vec<bool>,
}

impl Elasticity {
    /// Buffers for the tets of `model`.
    pub(crate) fn new(model: &Model) -> Self {
        let n = model.tets.len();
        Self {
            v_warm: vec![IDENTITY_LANES; n.div_ceil(LANES)],
            energy: vec![0.0; n],
            t_warm: vec![0.0; n],
            v_warm_adjoint: vec![Matrix3::identity(); n],
            cache: Vec::new(),
            volume_on: (0..n)
                .map(|t| {
                    model.w_vol[t] > 0.0
                        || model
                            .bodies
                            .iter()
                            .any(|b| b.volume_constraint && !b.model.is_hyperelastic() && b.tets.contains(&t))
                })
                .collect(),
        }
    }
}

impl ConstraintSet for Elasticity {
    fn name(&self) -> &'static str {
        "elasticity"
    }

    fn hessian_term(&self) -> super::HessianTerm {
        super::HessianTerm::ElasticTets
    }

    fn tet_coefficients(&self, model: &Model, k: &mut [f64]) {
        for (t, k) in k.iter_mut().enumerate() {
            *k = (model.w_rot[t] + model.w_vol[t]) / model.fem.geometry[t].volume;
        }
    }

    fn project(
        &mut self,
        model: &Model,
        q: &[Vector3<f64>],
        ctx: &mut ProjectContext<'_>,
    ) -> Result<f64, ConstraintError> {
        let tets = &model.tets;
        let record = ctx.record.as_deref_mut();
        if record.as_ref().is_some_and(|r| r.len() != tets.len()) {
            return Err(ConstraintError::NonFinite(format!(
                "local step record has {} entries for {} tets",
                record.map_or(0, |r| r.len()),
                tets.len()
            )));
        }
        let geo = &model.fem.geometry;
        let (w_rot, w_vol) = (&model.w_rot, &model.w_vol);
        type Bufs<'b> = (
            ((&'b mut [Matrix3<f64>], &'b mut LaneMatrix), &'b mut [f64]),
            &'b mut [f64],
        );
        let body = |chunk: usize, (((out, v), e), tw): Bufs<'_>, svd_out: Option<&mut [TetSvd]>| {
            let t0 = chunk * LANES;
            let len = out.len();
            // Each tet's F = D P^-1 straight into its lane (unused lanes: F = I), with the
            // operations of nalgebra's product: (d_i0 p_0j + d_i1 p_1j) + d_i2 p_2j.
            let mut f = IDENTITY_LANES;
            for k in 0..len {
                let [i0, i1, i2, i3] = tets[t0 + k];
                let x0 = q[i0];
                let d = [q[i1] - x0, q[i2] - x0, q[i3] - x0];
                let p = &geo[t0 + k].p_inv;
                for i in 0..3 {
                    for j in 0..3 {
                        f[i][j][k] = d[0][i] * p[(0, j)] + d[1][i] * p[(1, j)] + d[2][i] * p[(2, j)];
                    }
                }
            }
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
                Some(source) => ConstraintError::Projection { tet: t0 + k, source },
                None => ConstraintError::NonFinite(format!("tet {}: deformation gradient is not finite", t0 + k)),
            })
        };
        let bufs = ctx
            .per_tet
            .par_chunks_mut(LANES)
            .zip(self.v_warm.par_iter_mut())
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
        Ok(self.energy.iter().sum())
    }

    fn linearize(&mut self, model: &Model, q: &[Vector3<f64>]) -> Result<(), NotDifferentiable> {
        let n = model.tets.len();
        if self.cache.len() != n {
            // Sized once, on the first linearization.
            self.cache.resize(n, TetLinearization::zero());
        }
        let volume_on = &self.volume_on;
        // LANES tets at a time through the batched kernels, as the forward's local step.
        self.v_warm_adjoint
            .par_chunks_mut(LANES)
            .zip(self.cache.par_chunks_mut(LANES))
            .enumerate()
            .with_min_len(8)
            .try_for_each(|(chunk, (vw, lins))| {
                linearize_chunk(model, q, chunk * LANES, vw, volume_on, |k, lin| lins[k] = *lin)
            })
    }

    fn adjoint(&mut self, model: &Model, ctx: &mut AdjointContext<'_, '_>) -> Result<(), NotDifferentiable> {
        let (w_rot, w_vol) = (&model.w_rot, &model.w_vol);
        let cache = &self.cache;
        let volume_on = &self.volume_on;
        let fail = |t: usize, m: &str| NotDifferentiable(format!("tet {t}: {m}"));
        let (q, y, x_next, lin) = (ctx.q, ctx.y, ctx.x_next, ctx.lin);
        // LANES tets at a time: batched (AVX2) SVD and volume projection, as the forward.
        ctx.per_tet
            .par_chunks_mut(LANES)
            .zip(self.v_warm_adjoint.par_chunks_mut(LANES))
            .zip(
                ctx.grads
                    .w_rot
                    .par_chunks_mut(LANES)
                    .zip(ctx.grads.w_vol.par_chunks_mut(LANES)),
            )
            .enumerate()
            .with_min_len(8)
            .try_for_each(|(chunk, ((dp, vw), (gr, gv)))| {
                let t0 = chunk * LANES;
                let len = dp.len();
                let mut process = |k: usize, lin: &TetLinearization| {
                    let t = t0 + k;
                    if absent(w_rot[t], w_vol[t]) {
                        // A hyperelastic tet: its parameter slots belong to that kind.
                        dp[k] = Matrix3::zeros();
                        return;
                    }
                    let fy = model.tet_deformation(t, y);
                    dp[k] = lin.apply(&fy);
                    // d(J p)/dw minus dA/dw x_next (L_t = w A_t^T A_t per weight).
                    let a_term = x_next.map_or(0.0, |x| fy.dot(&model.tet_deformation(t, x)));
                    gr[k] += fy.dot(&lin.rotation) - a_term;
                    gv[k] += fy.dot(&lin.volume) - a_term;
                };
                if let Linearize::Cached = lin {
                    for k in 0..len {
                        process(k, &cache[t0 + k]);
                    }
                } else if let Linearize::Recorded(rec) = lin {
                    for k in 0..len {
                        let t = t0 + k;
                        if absent(w_rot[t], w_vol[t]) {
                            process(k, &TetLinearization::zero());
                            continue;
                        }
                        let r = rec.get(t).ok_or_else(|| fail(t, "no recorded decomposition"))?;
                        // The forward records the volume target where the weight is positive;
                        // at weight 0 (a volume term at Poisson ratio 0) it is computed here.
                        let x = if w_vol[t] > 0.0 {
                            Some(r.target)
                        } else if volume_on[t] {
                            Some(volume::nearest_product(&r.svd.sigma, 1.0).map_err(|e| fail(t, &e.to_string()))?)
                        } else {
                            None
                        };
                        let lin =
                            TetLinearization::with_target(&r.svd, x, w_rot[t], w_vol[t]).map_err(|m| fail(t, m))?;
                        process(k, &lin);
                    }
                } else {
                    linearize_chunk(model, q, t0, vw, volume_on, process)?;
                }
                Ok(())
            })
    }

    fn matrix_terms(&self, model: &Model, pairs: &[VectorPair<'_>], grads: &mut ParamGrads<'_>) {
        grads
            .w_rot
            .par_iter_mut()
            .zip(grads.w_vol.par_iter_mut())
            .enumerate()
            .with_min_len(64)
            .for_each(|(t, (gr, gv))| {
                if absent(model.w_rot[t], model.w_vol[t]) {
                    return;
                }
                let mut s = 0.0;
                for (a, b) in pairs {
                    s += model.tet_deformation(t, a).dot(&model.tet_deformation(t, b));
                }
                *gr -= s;
                *gv -= s;
            });
    }
}

/// The linearizations of the tets `t0..t0 + vw.len()` at `q` (batched SVD warm-started from
/// `vw`, updated, and batched volume projection), handed to `emit(k, lin)` for tet `t0 + k`.
fn linearize_chunk(
    model: &Model,
    q: &[Vector3<f64>],
    t0: usize,
    vw: &mut [Matrix3<f64>],
    volume_on: &[bool],
    mut emit: impl FnMut(usize, &TetLinearization),
) -> Result<(), NotDifferentiable> {
    let (w_rot, w_vol) = (&model.w_rot, &model.w_vol);
    let fail = |t: usize, m: &str| NotDifferentiable(format!("tet {t}: {m}"));
    let len = vw.len();
    let f: [Matrix3<f64>; LANES] = std::array::from_fn(|k| {
        if k < len {
            model.tet_deformation(t0 + k, q)
        } else {
            Matrix3::identity()
        }
    });
    let v0: [Matrix3<f64>; LANES] = std::array::from_fn(|k| if k < len { vw[k] } else { Matrix3::identity() });
    if !f.iter().all(|m| m.iter().all(|x| x.is_finite())) {
        return Err(fail(t0, "non-finite deformation gradient in this chunk"));
    }
    let svds = svd3_warm_batch(&f, &v0);
    let xs = if volume_on[t0..t0 + len].iter().any(|&on| on) {
        let sig: [Vector3<f64>; LANES] = std::array::from_fn(|k| svds[k].sigma);
        let mut tw = [0.0; LANES];
        Some(volume::nearest_product_batch_warm(&sig, 1.0, &mut tw).map_err(|e| fail(t0, &e.to_string()))?)
    } else {
        None
    };
    for k in 0..len {
        vw[k] = svds[k].v;
        let t = t0 + k;
        if absent(w_rot[t], w_vol[t]) {
            emit(k, &TetLinearization::zero());
            continue;
        }
        let x = xs.as_ref().filter(|_| volume_on[t]).map(|x| x[k]);
        let lin = TetLinearization::with_target(&svds[k], x, w_rot[t], w_vol[t]).map_err(|m| fail(t, m))?;
        emit(k, &lin);
    }
    Ok(())
}

/// Whether a tet has no projective elasticity (both weights zero: a tet of a hyperelastic
/// body, whose kind owns its parameter adjoints).
fn absent(w_rot: f64, w_vol: f64) -> bool {
    w_rot == 0.0 && w_vol == 0.0
}

/// One chunk's inputs and outputs (`len <= LANES` tets).
struct Chunk<'a> {
    w_rot: &'a [f64],
    w_vol: &'a [f64],
    v_warm: &'a mut LaneMatrix,
    t_warm: &'a mut [f64],
    out: &'a mut [Matrix3<f64>],
    energy: &'a mut [f64],
    svd_out: Option<&'a mut [TetSvd]>,
}

/// A failed tet of a chunk: its lane and the projection error (`None`: non-finite `F`).
type ChunkError = (usize, Option<ProjectionError>);

/// Dispatch to the AVX2 build of [`chunk_kernel`] when the CPU has it.
fn project_chunk(f: &LaneMatrix, c: Chunk<'_>) -> Result<(), ChunkError> {
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
unsafe fn chunk_avx2(f: &LaneMatrix, c: Chunk<'_>) -> Result<(), ChunkError> {
    chunk_kernel(f, c)
}

/// SVD (warm-started), volume projection (warm-started) and
/// `p = w_rot U V^T + w_vol U X V^T = U diag(w_rot + w_vol x) V^T` per tet, with the energies
/// from the singular values: `|F - U V^T|^2 = sum (s - 1)^2`, `|F - U X V^T|^2 = sum (s - x)^2`.
/// Everything is inlined into one function so the AVX2 build covers all of it and the
/// per-lane arrays stay in registers or on this frame.
#[inline(always)]
fn chunk_kernel(f: &LaneMatrix, mut c: Chunk<'_>) -> Result<(), ChunkError> {
    let len = c.out.len();
    // Unused lanes of the last chunk start from V = I, as their F = I (so they keep it).
    for (i, row) in c.v_warm.iter_mut().enumerate() {
        for (j, lanes) in row.iter_mut().enumerate() {
            for lane in &mut lanes[len..] {
                *lane = if i == j { 1.0 } else { 0.0 };
            }
        }
    }
    // Structure-of-arrays, read lane by lane below (no array of `Svd3` is built).
    let svds = svd::batch_lanes(f, c.v_warm);
    *c.v_warm = svds.v;
    let targets = if c.w_vol.iter().any(|&w| w > 0.0) {
        let mut sig = [Vector3::zeros(); LANES];
        for (k, s) in sig.iter_mut().enumerate() {
            *s = svds.sigma_of(k);
        }
        let mut t = [0.0; LANES];
        t[..len].copy_from_slice(c.t_warm);
        let x = volume::batch_generic(&sig, 1.0, &mut t).map_err(|err| (0, Some(err)))?;
        c.t_warm.copy_from_slice(&t[..len]);
        Some(x)
    } else {
        None
    };
    for k in 0..len {
        let s = svds.sigma_of(k);
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
        c.out[k] = svds.compose(k, &diag);
        c.energy[k] = en;
        if let Some(rec) = c.svd_out.as_deref_mut() {
            rec[k] = TetSvd {
                svd: svds.lane(k),
                target: match (&targets, c.w_vol[k] > 0.0) {
                    (Some(x), true) => x[k],
                    _ => Vector3::zeros(),
                },
            };
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::svd::{lane_matrix, svd3};

    /// A deformed state of `model`: a shear and a stretch plus a per-vertex wobble.
    fn deformed(model: &Model, amount: f64) -> Vec<Vector3<f64>> {
        model
            .rest
            .iter()
            .enumerate()
            .map(|(i, x)| {
                let wobble = Vector3::new((i as f64 * 1.3).sin(), (i as f64 * 0.7).cos(), (i as f64 * 2.1).sin());
                Matrix3::new(
                    1.0 + amount,
                    0.3 * amount,
                    0.0,
                    0.0,
                    1.0 - 0.5 * amount,
                    0.2 * amount,
                    0.0,
                    0.0,
                    1.0,
                ) * x
                    + wobble * 0.02 * amount
            })
            .collect()
    }

    /// Each tet's output is its own `w p` from the one-tet SVD (to round-off: the batch sweeps
    /// until every lane has converged), on a mesh whose last chunk is partial, over several
    /// local steps; each tet's warm start is its own last `V`, and the unused lanes keep `I`.
    #[test]
    fn every_tet_gets_its_own_projection_and_warm_start() {
        let model = crate::model::fixtures::free_box([3, 1, 1], [0.6, 0.2, 0.2]).unwrap();
        let n = model.tets.len();
        assert!(!n.is_multiple_of(LANES), "{n} tets fill every chunk");
        let mut set = Elasticity::new(&model);
        let mut per_tet = vec![Matrix3::zeros(); n];
        let mut record = vec![TetSvd::default(); n];
        for step in 1..=3 {
            let q = deformed(&model, 0.1 * step as f64);
            let mut ctx = ProjectContext {
                per_tet: &mut per_tet,
                activations: &[],
                record: Some(&mut record),
            };
            set.project(&model, &q, &mut ctx).unwrap();
            for t in 0..n {
                let f = model.tet_deformation(t, &q);
                let svd = svd3(&f);
                let mut p = svd.rotation() * model.w_rot[t];
                if model.w_vol[t] > 0.0 {
                    p += svd.compose(&volume::nearest_product(&svd.sigma, 1.0).unwrap()) * model.w_vol[t];
                }
                assert!((per_tet[t] - p).norm() <= 1e-10 * p.norm(), "step {step} tet {t}");
                let warm = lane_matrix(&set.v_warm[t / LANES], t % LANES);
                assert_eq!(warm, record[t].svd.v, "step {step} tet {t}: warm start");
            }
            let last = &set.v_warm[n / LANES];
            for k in n % LANES..LANES {
                assert_eq!(lane_matrix(last, k), Matrix3::identity(), "unused lane {k}");
            }
        }
    }
}
