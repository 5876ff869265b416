//! The checker: analytic gradients of a case against central differences over a sweep of
//! relative steps (V-curve), random directions for large groups, and a dual-number check of the
//! local step's linearization (docs/method.md section 7).

use anyhow::Result;
use nalgebra::{Matrix3, Vector3};
use num_dual::Dual64;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use indicatif::ProgressBar;

use super::{ATOL, RTOL};
use crate::pool;
use diffsoft::diff::{DiffError, DiffStats, Gradient, Mode, Options};
use diffsoft::kernel::actuator::tet_target_dual;
use diffsoft::kernel::linearization::TetLinearization;
use diffsoft::kernel::svd::svd3;
use diffsoft::model::Model;
use diffsoft::testing::{Case, Direction, Group};

/// One point of a V-curve.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct VPoint {
    /// Relative step `e` (1; the perturbation is `e x scale`).
    pub step: f64,
    /// Central difference (the unit of `analytic`), or, where one side of the step leaves the
    /// parameter's valid range (a value at the edge of its range), the second-order one-sided
    /// difference `(-3 L(0) + 4 L(e) - L(2e)) / 2e` on the other side (`one_sided`).
    pub fd: f64,
    /// Whether `fd` is one-sided.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub one_sided: bool,
    /// `|analytic - fd|` (the unit of `analytic`).
    pub abs_error: f64,
    /// `|analytic - fd| / |fd|` (1).
    pub rel_error: f64,
}

/// The check of one parameter group.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct GroupCheck {
    /// Group.
    pub group: String,
    /// `scalar` or `random_direction` (`v^T J u` with a seeded random `u`).
    pub kind: &'static str,
    /// Perturbation scale (the parameter's unit; the step is `e x scale`).
    pub scale: f64,
    /// Analytic derivative along `scale u` (the loss unit: m for centre-of-mass losses, rad for
    /// joint angles).
    pub analytic: f64,
    /// The finite-difference reference: the central difference at the V-curve minimum, or,
    /// where it is closer, the Richardson extrapolation of two neighbouring central differences
    /// (see `reference`; the unit of `analytic`).
    pub fd_best: f64,
    /// Its step (1, relative; for a Richardson reference the larger of its two steps).
    pub step_best: f64,
    /// Relative error against `fd_best` (1).
    pub rel_error_best: f64,
    /// `central`, or `richardson` where `(100 D(e/10) - D(e))/99` (fourth order in `e`) at its
    /// best step is closer to `analytic` than every central difference: for a derivative that
    /// is small next to the loss's third derivative, the central V-curve bottoms out where
    /// truncation (`e^2`) meets round-off (`1/e`), which can lie above `rtol`.
    pub reference: &'static str,
    /// Richardson extrapolation `(100 D(e/10) - D(e))/99` at the central V-curve's best step
    /// (the unit of `analytic`).
    pub richardson: Option<f64>,
    /// Its relative error against the analytic value (1).
    pub richardson_rel_error: Option<f64>,
    /// Slope of `log |error|` against `log e` over the three largest steps (1; 2 for central
    /// differences; `null` when those errors are already at the round-off floor).
    pub truncation_slope: Option<f64>,
    /// The sweep.
    pub v_curve: Vec<VPoint>,
    /// `|a - fd| <= atol + rtol |fd|` at the best step.
    pub passes: bool,
}

/// The relative steps of the V-curves.
pub fn steps_sweep() -> Vec<f64> {
    (1..=10).map(|k| 10f64.powi(-k)).collect()
}

/// One parameter group of `case` checked against central differences of its loss (a V-curve
/// over [`steps_sweep`] along a random direction, or the scalar itself), given the gradient `g`
/// of a run with the case's settings.
pub fn check_group(case: &Case, group: &Group, g: &Gradient, seed: u64) -> Result<GroupCheck, DiffError> {
    let sweep = fd_sweep(case, group, seed)?;
    Ok(assess_group(case, group, g, &sweep))
}

/// The central differences of one group's loss along its seeded direction: the same for every
/// mode of a case, so [`check_case`] computes them once.
#[derive(Debug, Clone)]
pub struct FdSweep {
    /// The direction `u` (the group's unit perturbation).
    direction: Direction,
    /// `(e, (L(p + e s u) - L(p - e s u)) / 2e, false)` for each step `e` of [`steps_sweep`] that
    /// stays in the parameter's valid range; where only one side does, the second-order
    /// one-sided difference on that side (`true`).
    differences: Vec<(f64, f64, bool)>,
}

/// Whether a perturbed run was refused for its input (a parameter or control stepped out of its
/// valid range), by the gradient's checks or the simulator's.
fn out_of_range(e: &DiffError) -> bool {
    matches!(
        e,
        DiffError::Input(_) | DiffError::Solver(diffsoft::solver::SolverError::Input(_))
    )
}

/// The V-curve's forward runs of `group` with the direction of `seed`.
pub fn fd_sweep(case: &Case, group: &Group, seed: u64) -> Result<FdSweep, DiffError> {
    let d = case.direction(group, seed);
    // The sweep's forward runs are independent: they run on every core, each on one thread
    // (their results do not depend on how many run at once; inside a task of `check_all` they
    // run one after another).
    let sweep = steps_sweep();
    let tasks: Vec<pool::Task<'_, Result<f64, DiffError>>> = sweep
        .iter()
        .flat_map(|&e| [e, -e])
        .map(|step| -> pool::Task<'_, Result<f64, DiffError>> {
            let d = &d;
            Box::new(move || case.loss_at(group, d, step))
        })
        .collect();
    let mut losses = pool::run(tasks, rayon::current_num_threads(), &ProgressBar::hidden()).into_iter();
    let mut next = || -> Result<f64, DiffError> {
        losses
            .next()
            .unwrap_or_else(|| Err("task did not run".into()))
            .map_err(|panic| DiffError::Unsupported(format!("a finite-difference run panicked: {panic}")))?
    };
    let mut differences = Vec::new();
    let mut refused = None;
    let mut base: Option<f64> = None;
    for e in sweep {
        // A step whose one side leaves the parameter's valid range (a value at the edge of its
        // range: nu = 0, an activation at 0) takes the second-order one-sided difference on the
        // other side, `(-3 L(0) + 4 L(se) - L(2se)) / 2se` with `s` the side's sign (its error
        // is O(e^2) as the central one's); a step that leaves it on both sides is skipped.
        let (p, m) = (next(), next());
        let side = match (p, m) {
            (Ok(p), Ok(m)) => {
                differences.push((e, (p - m) / (2.0 * e), false));
                continue;
            }
            (Ok(p), Err(err)) if out_of_range(&err) => (1.0, p, err),
            (Err(err), Ok(m)) if out_of_range(&err) => (-1.0, m, err),
            (Err(err), Err(other)) if out_of_range(&err) && out_of_range(&other) => {
                refused.get_or_insert(err);
                continue;
            }
            (Err(err), _) | (_, Err(err)) => return Err(err),
        };
        let (sign, near, err) = side;
        let far = match case.loss_at(group, &d, 2.0 * sign * e) {
            Ok(far) => far,
            Err(err) if out_of_range(&err) => {
                refused.get_or_insert(err);
                continue;
            }
            Err(err) => return Err(err),
        };
        refused.get_or_insert(err);
        let l0 = match base {
            Some(l0) => l0,
            None => *base.insert(case.loss_at(group, &d, 0.0)?),
        };
        differences.push((e, sign * (-3.0 * l0 + 4.0 * near - far) / (2.0 * e), true));
    }
    // Every step refused: no finite difference to compare with (the first refusal says why).
    if let (true, Some(err)) = (differences.is_empty(), refused) {
        return Err(err);
    }
    Ok(FdSweep {
        direction: d,
        differences,
    })
}

/// `group`'s check: the analytic derivative of the gradient `g` along the sweep's direction
/// against the sweep's central differences.
pub fn assess_group(case: &Case, group: &Group, g: &Gradient, sweep: &FdSweep) -> GroupCheck {
    let d = &sweep.direction;
    let a = case.analytic(group, g, d);
    let mut curve = Vec::new();
    for &(e, fd, one_sided) in &sweep.differences {
        let abs = (a - fd).abs();
        curve.push(VPoint {
            step: e,
            fd,
            one_sided,
            abs_error: abs,
            rel_error: abs / fd.abs().max(f64::MIN_POSITIVE),
        });
    }
    let best = (0..curve.len())
        .min_by(|&i, &j| curve[i].abs_error.total_cmp(&curve[j].abs_error))
        .unwrap_or(0);
    let b = &curve[best];
    let extrapolate = |k: usize| {
        let (c, n) = (&curve[k], curve.get(k + 1)?);
        // Only neighbouring decades of one kind of difference (a skipped step, or a central
        // and a one-sided difference, would change the weights).
        ((c.step / n.step - 10.0).abs() < 1e-6 && c.one_sided == n.one_sided).then(|| (100.0 * n.fd - c.fd) / 99.0)
    };
    let richardson = extrapolate(best);
    // The fourth-order reference: the Richardson value closest to the analytic one, from steps
    // no smaller than the central minimum's (below it round-off dominates both differences).
    let extrapolated = (0..=best)
        .filter_map(|k| extrapolate(k).map(|r| (k, r)))
        .min_by(|x, y| (a - x.1).abs().total_cmp(&(a - y.1).abs()));
    let (reference, step_best, fd_best) = match extrapolated {
        Some((k, r)) if (a - r).abs() < b.abs_error => ("richardson", curve[k].step, r),
        _ => ("central", b.step, b.fd),
    };
    let abs_best = (a - fd_best).abs();
    let floor = b.abs_error.max(f64::MIN_POSITIVE);
    let slope = if curve.len() >= 3 && curve[..3].iter().all(|p| p.abs_error > 10.0 * floor) {
        let pts: Vec<(f64, f64)> = curve[..3]
            .iter()
            .map(|p| (p.step.log10(), p.abs_error.log10()))
            .collect();
        let (mx, my) = (
            pts.iter().map(|p| p.0).sum::<f64>() / 3.0,
            pts.iter().map(|p| p.1).sum::<f64>() / 3.0,
        );
        let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
        let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
        Some(sxy / sxx)
    } else {
        None
    };
    GroupCheck {
        group: group.name(),
        kind: if matches!(group, Group::Scalar(_)) {
            "scalar"
        } else {
            "random_direction"
        },
        scale: d.scale,
        analytic: a,
        fd_best,
        step_best,
        rel_error_best: abs_best / fd_best.abs().max(f64::MIN_POSITIVE),
        reference,
        richardson,
        richardson_rel_error: richardson.map(|r| (a - r).abs() / r.abs().max(f64::MIN_POSITIVE)),
        truncation_slope: slope,
        passes: abs_best <= ATOL + RTOL * fd_best.abs(),
        v_curve: curve,
    }
}

/// Dual-number check of the local step's linearization at the final state of a run.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct DualCheck {
    /// Tets checked.
    pub tets: usize,
    /// Tets skipped because two singular values nearly coincide (relative gap below 1e-3): the
    /// dual-number Jacobi SVD reference is not differentiable there (its rotations are not
    /// unique), although the projection and its analytic linearization are.
    pub skipped_repeated_singular_values: usize,
    /// Largest `|dp_analytic - dp_dual| / (|dp_dual| + w |dF|)` over tets and random directions
    /// (1).
    pub max_rel_error: f64,
}

fn dual_check(model: &Model, q: &[Vector3<f64>], seed: u64) -> Result<DualCheck, DiffError> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let step = (model.tets().len() / 500).max(1);
    let mut worst = 0.0f64;
    let mut count = 0;
    let mut skipped = 0;
    for t in (0..model.tets().len()).step_by(step) {
        let f = model.tet_deformation(t, q);
        let (wr, wv) = (model.w_rot()[t], model.w_vol()[t]);
        let svd = svd3(&f);
        let s = svd.sigma;
        let gap = [(0, 1), (0, 2), (1, 2)]
            .iter()
            .map(|&(i, j)| (s[i] - s[j]).abs())
            .fold(f64::INFINITY, f64::min);
        if gap < 1e-3 * s.amax() {
            skipped += 1;
            continue;
        }
        let lin =
            TetLinearization::new(&svd, wr, wv).map_err(|m| DiffError::NotDifferentiable(format!("tet {t}: {m}")))?;
        let df = Matrix3::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let fd = Matrix3::from_fn(|i, j| Dual64::new(f[(i, j)], df[(i, j)]));
        let p = tet_target_dual(&fd, wr, wv).map_err(|e| DiffError::NotDifferentiable(format!("tet {t}: {e}")))?;
        let dual = p.map(|z| z.eps);
        let an = lin.apply(&df);
        let err = (an - dual).norm() / (dual.norm() + (wr + wv) * df.norm() * 1e-3);
        worst = worst.max(err);
        count += 1;
    }
    Ok(DualCheck {
        tets: count,
        skipped_repeated_singular_values: skipped,
        max_rel_error: worst,
    })
}

/// One mode's results on a case.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct ModeCheck {
    /// Mode.
    pub mode: Mode,
    /// Loss value (m for centre-of-mass losses, rad for joint angles).
    pub loss: f64,
    /// Backward statistics.
    pub stats: DiffStats,
    /// Group checks.
    pub groups: Vec<GroupCheck>,
    /// The group with the largest relative error at its best step.
    pub worst: Option<String>,
    /// Its analytic value (the loss unit).
    pub worst_analytic: Option<f64>,
    /// Its finite difference (the loss unit).
    pub worst_fd: Option<f64>,
    /// Its relative error (1).
    pub worst_rel_error: Option<f64>,
    /// Every group passes.
    pub passes: bool,
}

/// The checks of one case.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct CaseCheck {
    /// Name.
    pub name: String,
    /// What it covers.
    pub description: String,
    /// Vertices, tets.
    pub vertices: usize,
    /// Tets.
    pub tets: usize,
    /// Steps.
    pub steps: usize,
    /// Loss name.
    pub loss: String,
    /// Iterations per step (fixed: tolerance 0; for Newton's method the cap of a converging
    /// forward).
    pub iterations_per_step: usize,
    /// Unrolled mode (the pass criterion) and implicit mode (informational: exact only at
    /// convergence, and these runs stop at a fixed iteration count); for a case solved by
    /// Newton's method, implicit mode only (the pass criterion: its forward converges).
    pub modes: Vec<ModeCheck>,
    /// Dual-number check of the local step at the final state.
    pub dual: Option<DualCheck>,
    /// Why the case could not be differentiated (it then fails).
    pub error: Option<String>,
    /// Why implicit mode gave no gradient for this case (not supported, or its adjoint fixed
    /// point diverged on the unconverged forward); `null` when it ran. Informational.
    pub implicit_error: Option<String>,
    /// The first mode's checks pass (unrolled; implicit for Newton's method).
    pub passes: bool,
}

/// Run every check of `case`.
pub fn check_case(case: &Case, seed: u64) -> CaseCheck {
    let mut out = CaseCheck {
        name: case.name.clone(),
        description: case.description.clone(),
        vertices: case.model.n(),
        tets: case.model.tets().len(),
        steps: case.steps,
        loss: case.loss.name(),
        iterations_per_step: case.settings.max_iterations,
        modes: Vec::new(),
        dual: None,
        error: None,
        implicit_error: None,
        passes: false,
    };
    // The finite differences do not depend on the mode: computed once, on first use.
    let mut sweeps: Vec<Option<FdSweep>> = vec![None; case.groups.len()];
    let mut run = |mode: Mode| -> Result<ModeCheck, DiffError> {
        let g = case.gradient(&case.settings, Options::mode(mode))?;
        let mut groups = Vec::new();
        for (k, grp) in case.groups.iter().enumerate() {
            let sweep = match &mut sweeps[k] {
                Some(sweep) => sweep,
                slot => slot.insert(fd_sweep(case, grp, seed + k as u64)?),
            };
            groups.push(assess_group(case, grp, &g, sweep));
        }
        let worst = groups
            .iter()
            .max_by(|a, b| a.rel_error_best.total_cmp(&b.rel_error_best));
        Ok(ModeCheck {
            mode,
            loss: g.loss,
            stats: g.stats,
            worst: worst.map(|w| w.group.clone()),
            worst_analytic: worst.map(|w| w.analytic),
            worst_fd: worst.map(|w| w.fd_best),
            worst_rel_error: worst.map(|w| w.rel_error_best),
            passes: groups.iter().all(|g| g.passes),
            groups,
        })
    };
    // Newton's method has implicit-mode gradients only (of its converged steps): they are the
    // pass criterion there.
    let newton = case.settings.solver == diffsoft::solver::SolverKind::Newton;
    let modes: &[Mode] = if newton {
        &[Mode::Implicit]
    } else {
        &[Mode::Unrolled, Mode::Implicit]
    };
    for &mode in modes {
        match run(mode) {
            Ok(m) => out.modes.push(m),
            Err(e @ (DiffError::Unsupported(_) | DiffError::NotDifferentiable(_)))
                if mode == Mode::Implicit && !newton =>
            {
                out.implicit_error = Some(e.to_string());
            }
            Err(e) => {
                out.error = Some(e.to_string());
                return out;
            }
        }
    }
    // The dual check at the final state of a plain forward run.
    let final_q = (|| -> Result<Vec<Vector3<f64>>, DiffError> {
        let mut sim = diffsoft::solver::Simulator::new(case.model.clone(), case.settings.clone())?;
        if let Some((q, v)) = &case.controls.initial {
            sim.set_state(q.clone(), v.clone())?;
        }
        for _ in 0..case.steps {
            sim.step()?;
        }
        Ok(sim.state().q.clone())
    })();
    match final_q.and_then(|q| dual_check(&case.model, &q, seed)) {
        Ok(d) => out.dual = Some(d),
        Err(e) => out.error = Some(e.to_string()),
    }
    out.passes = out.error.is_none() && out.modes.first().is_some_and(|m| m.passes);
    out
}

/// Run the checks only (what `diffsoft gradcheck` does without the studies): the cases at once
/// on every core, one thread each ([`pool::run`]; a case's sweep then runs on its own thread),
/// the costliest first. Results are in case order.
pub fn check_all(cases: &[Case], seed: u64) -> Vec<CaseCheck> {
    let mut order: Vec<usize> = (0..cases.len()).collect();
    order.sort_by_key(|&k| (std::cmp::Reverse(case_cost(&cases[k])), k));
    let tasks: Vec<pool::Task<'_, CaseCheck>> = order
        .iter()
        .map(|&k| -> pool::Task<'_, CaseCheck> { Box::new(move || check_case(&cases[k], seed)) })
        .collect();
    let mut checks: Vec<Option<CaseCheck>> = cases.iter().map(|_| None).collect();
    for (&k, r) in order
        .iter()
        .zip(pool::run(tasks, rayon::current_num_threads(), &ProgressBar::hidden()))
    {
        checks[k] = Some(r.unwrap_or_else(|panic| panic!("the gradient check of {} panicked: {panic}", cases[k].name)));
    }
    checks.into_iter().flatten().collect()
}

/// A case's cost for ordering the checks: the vertex-steps of its forward runs (a sweep per
/// group).
fn case_cost(case: &Case) -> usize {
    case.steps * case.model.n() * case.groups.len().max(1)
}

/// One line per case and mode (`diffsoft gradcheck`'s output): pass or fail, the worst entry
/// with its analytic and finite-difference values; implicit mode is informational where the
/// forward did not converge.
pub fn checks_table(checks: &[CaseCheck]) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    for c in checks {
        match &c.error {
            Some(e) => {
                let _ = writeln!(out, "{:<16} FAILS: {e}", c.name);
            }
            None => {
                for m in &c.modes {
                    let _ = writeln!(
                        out,
                        "{:<16} {:<9} {}  worst {} : analytic {:.10e} fd {:.10e} {}",
                        c.name,
                        format!("{:?}", m.mode).to_lowercase(),
                        match (m.mode, m.passes) {
                            (_, true) => "passes",
                            (Mode::Implicit, false) if c.modes.len() > 1 =>
                                "off (informational: forward not converged)",
                            (_, false) => "FAILS ",
                        },
                        m.worst.as_deref().unwrap_or("-"),
                        m.worst_analytic.unwrap_or(f64::NAN),
                        m.worst_fd.unwrap_or(f64::NAN),
                        deciding_error(m.worst_analytic, m.worst_fd),
                    );
                }
                if let Some(e) = &c.implicit_error {
                    let _ = writeln!(out, "{:<16} implicit  off (informational): {e}", c.name);
                }
            }
        }
    }
    out
}

/// The error that decides `|a - fd| <= atol + rtol |fd|`: the relative error where the
/// relative term dominates, else the absolute error against `atol` (a relative error of two
/// values near 0 means nothing).
pub fn deciding_error(analytic: Option<f64>, fd: Option<f64>) -> String {
    let (Some(a), Some(fd)) = (analytic, fd) else {
        return "-".into();
    };
    let abs = (a - fd).abs();
    if RTOL * fd.abs() >= ATOL {
        format!("rel {:.1e} (rtol {RTOL:.0e})", abs / fd.abs())
    } else {
        format!("abs {abs:.1e} (atol {ATOL:.0e}; |fd| too small for a relative error)")
    }
}
