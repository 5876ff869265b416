//! System identification (paper Sec. 5): recover Young's modulus with L-BFGS on `log E`.

use std::time::Instant;

use anyhow::Result;
use nalgebra::Vector3;
use serde::Serialize;

use diffsoft::diff::loss::{Loss, LossGrad};
use diffsoft::diff::optim::{lbfgs, Lbfgs, Minimum};
use diffsoft::diff::{self, DiffError, Mode, Options, Param};
use diffsoft::model::Model;
use diffsoft::testing::Case;

/// System identification (paper Sec. 5): recover Young's modulus from the final barycentre
/// displacement with L-BFGS on `log E`.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct SysId {
    /// Scene.
    pub scene: String,
    /// Steps simulated per evaluation.
    pub steps: usize,
    /// Velocity damping factor per step used (1; quasi-static: the bridge settles within the
    /// horizon).
    pub damping: f64,
    /// The true modulus, the scene's (Pa).
    pub true_youngs_modulus: f64,
    /// The starting guess (Pa).
    pub initial_youngs_modulus: f64,
    /// The target: the barycentre's displacement at the true modulus (m).
    pub target_displacement: [f64; 3],
    /// The recovered modulus (Pa).
    pub recovered_youngs_modulus: f64,
    /// `|E - E_true| / E_true` (1).
    pub relative_error: f64,
    /// Optimizer result (iterations, evaluations, history of `log E`).
    pub optimizer: Minimum,
    /// Wall time (s).
    pub wall_s: f64,
}

/// Run the identification: loss `|d(E) - d*|^2 / |d*|^2` of the barycentre displacement after
/// `steps` steps, parameter `log E`, started at `factor x E_true`.
pub fn sysid(case: &Case, factor: f64) -> Result<SysId, DiffError> {
    let t0 = Instant::now();
    let e_true = Param::YOUNGS_MODULUS.get(&case.model)?;
    let total: f64 = case.model.mass().iter().sum();
    let com0: Vector3<f64> = case
        .model
        .rest()
        .iter()
        .zip(case.model.mass())
        .map(|(x, m)| x * *m)
        .sum::<Vector3<f64>>()
        / total;
    // The displacement at the true modulus, per axis: one run, its final centre of mass.
    let run = diff::rollout(&case.model, &case.settings, case.steps, &case.controls)?;
    let last = &run.positions[case.steps * run.n..];
    let com: Vector3<f64> = last
        .iter()
        .zip(case.model.mass())
        .map(|(x, m)| x * *m)
        .sum::<Vector3<f64>>()
        / total;
    let target: [f64; 3] = (com - com0).into();
    let d2: f64 = target.iter().map(|t| t * t).sum();
    // Axes the load does not move (symmetry: round-off only) carry no information.
    let misfit = Misfit {
        com0,
        target: Vector3::from(target),
        axes: target.map(|t| t.abs() > 1e-9 * d2.sqrt()),
        d2,
    };
    // One forward and one backward per evaluation: the misfit of all axes is one loss.
    let eval = |x: &[f64]| -> Result<(f64, Vec<f64>), DiffError> {
        let mut model = case.model.clone();
        let e = x[0].exp();
        Param::YOUNGS_MODULUS.set(&mut model, e)?;
        let gr = diff::gradient(
            &model,
            &case.settings,
            case.steps,
            &case.controls,
            &misfit,
            Options::mode(Mode::Unrolled),
        )?;
        let (f, g) = (gr.loss, Param::YOUNGS_MODULUS.derivative(&model, &gr) * e);
        if std::env::var_os("DIFFSOFT_TRACE").is_some() {
            crate::warn!("sysid eval E {e:.6e} f {f:.3e} g {g:.3e} target {target:?} d2 {d2:.3e}");
        }
        Ok((f, vec![g]))
    };
    let x0 = (e_true * factor).ln();
    let r = lbfgs(
        Lbfgs {
            max_iterations: 30,
            gradient_tolerance: 1e-14,
            f_tolerance: 1e-16,
            ..Default::default()
        },
        vec![x0],
        eval,
    )?;
    let e = r.x[0].exp();
    Ok(SysId {
        scene: case.name.clone(),
        steps: case.steps,
        damping: case.settings.damping,
        true_youngs_modulus: e_true,
        initial_youngs_modulus: e_true * factor,
        target_displacement: target,
        recovered_youngs_modulus: e,
        relative_error: (e - e_true).abs() / e_true,
        optimizer: r,
        wall_s: t0.elapsed().as_secs_f64(),
    })
}

/// The identification's loss: `sum_k (c_k - c0_k - t_k)^2 / |t|^2` over the axes the load
/// moves, `c` the final centre of mass, `c0` the rest one and `t` the target displacement.
struct Misfit {
    com0: Vector3<f64>,
    target: Vector3<f64>,
    axes: [bool; 3],
    d2: f64,
}

impl Loss for Misfit {
    fn term(
        &self,
        model: &Model,
        n: usize,
        steps: usize,
        q: &[Vector3<f64>],
        _v: &[Vector3<f64>],
        g: LossGrad<'_>,
    ) -> f64 {
        if n != steps {
            return 0.0;
        }
        let mass = model.mass();
        let total: f64 = mass.iter().sum();
        let com: Vector3<f64> = q.iter().zip(mass).map(|(x, m)| x * *m).sum::<Vector3<f64>>() / total;
        // dL/dc, zero on the axes left out.
        let r = (com - self.com0 - self.target).zip_map(&Vector3::from(self.axes.map(f64::from)), |r, on| r * on);
        let dc = r * (2.0 / self.d2);
        for ((gq, gm), (x, m)) in g.q.iter_mut().zip(g.mass.iter_mut()).zip(q.iter().zip(mass)) {
            *gq += dc * (*m / total);
            *gm += dc.dot(&(x - com)) / total;
        }
        r.norm_squared() / self.d2
    }

    fn name(&self) -> String {
        "displacement_misfit".into()
    }
}
