//! `reports/gradients.json`: the whole gradient study (checks, system identification,
//! accuracy against cost, memory) and its verdicts.

use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use nalgebra::Vector3;
use serde::Serialize;

use super::check::{check_all, steps_sweep, CaseCheck};
use super::cost::write_cost_svg;
use super::cost::{accuracy_vs_cost, CostReport};
use super::memory::{memory_point, MemoryPoint};
use super::sysid::{sysid, SysId};
use super::{ATOL, GRADCHECK_SCHEMA, GRADIENTS_SCHEMA, RTOL, STORE_BUDGET};
use crate::pool;
use crate::report::{Header, Verdict};
use diffsoft::diff::loss::CenterOfMass;
use diffsoft::diff::{Controls, Mode, Options};
use diffsoft::scene::{self, LoadOptions};
use diffsoft::solver::SolverKind;
use diffsoft::testing::{baymax_ground, baymax_torques, bridgesus, builtin_cases, Case, CaseScenes};

/// `reports/gradients.json`.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct GradientsReport {
    /// Schema and version.
    #[serde(flatten)]
    pub header: Header,
    /// Relative tolerance (1).
    pub rtol: f64,
    /// Absolute tolerance (the loss unit: m for the centre-of-mass losses of the cases).
    pub atol: f64,
    /// Relative steps of the V-curves (1).
    pub steps: Vec<f64>,
    /// The cases.
    pub cases: Vec<CaseCheck>,
    /// System identification of bridgesus, from 10x below and 10x above the true modulus.
    pub sysid: Vec<SysId>,
    /// Why the identification runs on a damped (quasi-static) bridge.
    pub sysid_note: String,
    /// Gradient accuracy against forward iterations and time.
    pub accuracy_vs_cost: Vec<CostReport>,
    /// Memory and time for 10, 100, 1000 steps.
    pub memory: Vec<MemoryPoint>,
    /// The claims.
    pub verdicts: Vec<Verdict>,
    /// Wall time (s).
    pub wall_time_s: f64,
}

/// `diffsoft gradcheck --json`: the gradient checks of the built-in cases (the `cases` of
/// `reports/gradients.json`, without the studies).
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct GradcheckReport {
    /// Schema and version.
    #[serde(flatten)]
    pub header: Header,
    /// Relative tolerance (1).
    pub rtol: f64,
    /// Absolute tolerance (the loss unit: m for the centre-of-mass losses of the cases).
    pub atol: f64,
    /// The cases.
    pub cases: Vec<CaseCheck>,
}

impl GradcheckReport {
    /// The report of these checks.
    pub fn new(cases: Vec<CaseCheck>) -> Self {
        Self {
            header: Header::new(GRADCHECK_SCHEMA),
            rtol: RTOL,
            atol: ATOL,
            cases,
        }
    }
}

/// Inputs of the full gradient study.
#[derive(Debug, Clone)]
pub struct Inputs<'a> {
    /// bridgesus scene.
    pub bridgesus: &'a Path,
    /// Baymax skeleton scene.
    pub baymax_skeleton: &'a Path,
    /// Scene for the memory study (Baymax without skeleton).
    pub memory_scene: &'a Path,
    /// Horizons of the memory study.
    pub memory_steps: &'a [usize],
    /// The paper's ball on its flag cloth (diffsoft scene).
    pub ball_on_cloth: &'a Path,
    /// Steps of the checks.
    pub steps: usize,
    /// Steps of the system identification.
    pub sysid_steps: usize,
}

/// Everything: checks, system identification, accuracy against cost, memory.
pub fn study(inp: &Inputs<'_>, out: &Path) -> Result<GradientsReport> {
    let t0 = Instant::now();
    let cases = builtin_cases(
        &CaseScenes {
            bridgesus: inp.bridgesus.to_path_buf(),
            baymax_skeleton: inp.baymax_skeleton.to_path_buf(),
            ball_on_cloth: inp.ball_on_cloth.to_path_buf(),
        },
        inp.steps,
    )?;
    let mut sys_case = bridgesus(inp.bridgesus, inp.sysid_steps)?;
    sys_case.settings.max_iterations = 30;
    sys_case.settings.damping = 0.9;
    let sys_case = &sys_case;
    // The checks and the two identifications are independent: they share the cores, each run
    // on one thread ([`pool::both`]).
    let lap = Instant::now();
    let ((checks, checks_s), (identified, sysid_s)) = pool::both(
        || (check_all(&cases, 2021), lap.elapsed().as_secs_f64()),
        || {
            let tasks: Vec<pool::Task<'_, Result<SysId, diffsoft::diff::DiffError>>> = [0.1, 10.0]
                .into_iter()
                .map(|factor| -> pool::Task<'_, Result<SysId, diffsoft::diff::DiffError>> {
                    Box::new(move || sysid(sys_case, factor))
                })
                .collect();
            let ids = pool::run(tasks, rayon::current_num_threads(), &indicatif::ProgressBar::hidden());
            (ids, lap.elapsed().as_secs_f64())
        },
        rayon::current_num_threads(),
    );
    for c in &checks {
        crate::say!(
            "  {:<16} {}",
            c.name,
            if c.passes {
                format!(
                    "passes: worst {} {}",
                    c.modes[0].worst.as_deref().unwrap_or("-"),
                    super::check::deciding_error(c.modes[0].worst_analytic, c.modes[0].worst_fd)
                )
            } else {
                format!(
                    "FAILS: {}",
                    c.error.as_deref().unwrap_or("a group exceeds the tolerance")
                )
            }
        );
    }
    crate::say!("  (checks: {checks_s:.1} s)");
    let mut ids = Vec::new();
    for r in identified {
        let s = r.map_err(|panic| anyhow::anyhow!("system identification panicked: {panic}"))??;
        crate::say!(
            "  sys-id bridgesus: E {:.4e} -> {:.6e} (true {:.4e}), {} L-BFGS iterations, {} evaluations, relative error {:.1e}, {:.1} s",
            s.initial_youngs_modulus,
            s.recovered_youngs_modulus,
            s.true_youngs_modulus,
            s.optimizer.iterations,
            s.optimizer.evaluations,
            s.relative_error,
            s.wall_s
        );
        ids.push(s);
    }
    crate::say!("  (system identification, alongside the checks: {sysid_s:.1} s)");
    let took = |what: &str, lap: &mut Instant| {
        crate::say!("  ({what}: {:.1} s)", lap.elapsed().as_secs_f64());
        *lap = Instant::now();
    };
    let mut lap = Instant::now();
    let caps = [1, 2, 3, 5, 10, 20, 30, 50, 100];
    let mut costs = Vec::new();
    for c in [&cases[1], &cases[2]] {
        costs.push(accuracy_vs_cost(c, &caps)?);
    }
    write_cost_svg(&diffsoft::output::own_file(out, "gradient_cost.svg")?, &costs)?;
    took("accuracy against cost", &mut lap);
    let mem_scene = scene::load(inp.memory_scene, LoadOptions::default())?;
    let mut mem_settings = mem_scene.settings.clone();
    // Gradients with contact need the direct solver.
    mem_settings.solver = SolverKind::Direct;
    let mem_case = Case {
        name: "baymax".into(),
        description: "Baymax (paper mesh, no skeleton) in ground contact".into(),
        settings: mem_settings,
        model: mem_scene.model,
        steps: 0,
        loss: Box::new(CenterOfMass {
            direction: Vector3::y(),
            time_average: true,
            vertices: None,
        }),
        controls: Controls::default(),
        groups: Vec::new(),
    };
    // Baymax with its skeleton (no ground), the paper's skeleton scene, as in the check.
    let mut sk_case = baymax_torques(inp.baymax_skeleton, 100)?;
    sk_case.name = "baymax_skeleton".into();
    sk_case.settings = scene::load(inp.baymax_skeleton, LoadOptions::default())?.settings;
    sk_case.settings.anderson = 0;
    // The same on the ground (paper Fig. 5b's scene): contacts on free and bone vertices.
    let mut skg_case = baymax_ground(inp.baymax_skeleton, 100)?;
    skg_case.controls.initial = None;
    skg_case.settings = sk_case.settings.clone();
    let runs: [(&Case, Options); 5] = [
        (&mem_case, Options::mode(Mode::Unrolled)),
        (
            &mem_case,
            Options {
                store_bytes: STORE_BUDGET,
                ..Options::mode(Mode::Unrolled)
            },
        ),
        (&mem_case, Options::mode(Mode::Implicit)),
        (&sk_case, Options::mode(Mode::Unrolled)),
        (&skg_case, Options::mode(Mode::Unrolled)),
    ];
    // Every point is one gradient on one thread, its heap counted on that thread, so the
    // points run side by side; the longest horizons (and the skeleton's, the slowest) first.
    // The points a cost verdict reads (100 unrolled steps) are timed TIMED_RUNS times and keep
    // the run with the median ratio: one wall-clock run, with the other worker busy beside it,
    // moved a ratio of about 2.5 by +-0.5 between runs of the main job.
    let mut points: Vec<(usize, &Case, usize, Options)> = Vec::new();
    let mut runs_of: Vec<usize> = Vec::new();
    for (c, opts) in runs {
        for &steps in inp.memory_steps {
            let repeats = if verdict_point(steps, opts.mode) { TIMED_RUNS } else { 1 };
            for _ in 0..repeats {
                points.push((runs_of.len(), c, steps, opts));
            }
            runs_of.push(repeats);
        }
    }
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by_key(|&i| (std::cmp::Reverse(points[i].2), std::cmp::Reverse(i)));
    let tasks: Vec<pool::Task<'_, Result<MemoryPoint, diffsoft::diff::DiffError>>> = order
        .iter()
        .map(|&i| -> pool::Task<'_, Result<MemoryPoint, diffsoft::diff::DiffError>> {
            let (_, c, steps, opts) = points[i];
            Box::new(move || memory_point(c, steps, opts))
        })
        .collect();
    let results = pool::run(tasks, rayon::current_num_threads(), &indicatif::ProgressBar::hidden());
    let mut by_point: Vec<Vec<MemoryPoint>> = runs_of.iter().map(|_| Vec::new()).collect();
    for (&i, r) in order.iter().zip(results) {
        let p = r.map_err(|panic| anyhow::anyhow!("memory study panicked: {panic}"))??;
        by_point[points[i].0].push(p);
    }
    let mem: Vec<MemoryPoint> = by_point.into_iter().filter_map(median_run).collect();
    for m in &mem {
        crate::say!(
            "  backward {:<16} {:>5} steps {:?}{}: forward {:.0} ms, backward {:.0} ms ({:.2}x), peak heap {:.1} MB",
            m.scene,
            m.steps,
            m.mode,
            if m.store_budget_bytes > 0 {
                format!(" (store {} MB)", m.store_budget_bytes / 1_000_000)
            } else {
                String::new()
            },
            m.forward_ms,
            m.backward_ms,
            m.ratio,
            m.peak_heap_bytes.unwrap_or(0) as f64 / 1e6
        );
    }
    took("memory", &mut lap);
    let mut verdicts = Vec::new();
    for c in &checks {
        verdicts.push(Verdict::new(
            format!(
                "{}: {} gradients match central differences within atol {ATOL:e} + rtol {RTOL:e} |fd| at the best step, every group",
                c.name,
                match c.modes.first().map(|m| m.mode) {
                    Some(Mode::Implicit) => "implicit-mode (Newton's converged steps)",
                    _ => "unrolled",
                }
            ),
            c.passes,
            c.modes.first().and_then(|m| m.worst_rel_error),
            Some(RTOL),
            c.error
                .clone()
                .unwrap_or_else(|| "worst relative error at the best step <= rtol".into()),
        ));
    }
    for m in mem.iter().filter(|m| verdict_point(m.steps, m.mode)) {
        verdicts.push(Verdict::at_most(
            format!(
                "{}: unrolled backward at most 3x the forward over 100 steps ({}; the median of {TIMED_RUNS} wall-clock runs, see benches/gradient.rs for criterion medians)",
                m.scene,
                if m.store_budget_bytes == 0 {
                    "pure checkpointing, every step replayed".to_string()
                } else {
                    format!("recordings kept within {} MB", m.store_budget_bytes / 1_000_000)
                }
            ),
            m.ratio,
            3.0,
        ));
    }
    for s in &ids {
        verdicts.push(Verdict::at_most(
            format!(
                "bridgesus system identification from E = {:.0e} (10x off): L-BFGS iterations to the optimum (about 10 wanted)",
                s.initial_youngs_modulus
            ),
            s.optimizer.iterations as f64,
            15.0,
        ));
        verdicts.push(Verdict::at_most(
            format!(
                "bridgesus system identification from E = {:.0e}: relative error of the recovered E",
                s.initial_youngs_modulus
            ),
            s.relative_error,
            1e-6,
        ));
    }
    let report = GradientsReport {
        header: Header::new(GRADIENTS_SCHEMA),
        rtol: RTOL,
        atol: ATOL,
        steps: steps_sweep(),
        cases: checks,
        sysid: ids,
        sysid_note: "The scene's own dynamics are nearly undamped (0.9999): the final barycentre displacement then oscillates with E, and the loss has local minima (from E = 2e4 with 50 steps L-BFGS stops at a stationary point at E = 3.97e4). With damping 0.9 per step the bridge settles within the horizon and the final displacement is the static sag, which falls monotonically with E.".into(),
        accuracy_vs_cost: costs,
        memory: mem,
        verdicts,
        wall_time_s: t0.elapsed().as_secs_f64(),
    };
    Ok(report)
}

/// Timed runs of each memory point a cost verdict reads (see [`verdict_point`]).
const TIMED_RUNS: usize = 3;

/// Whether the memory point of `steps` steps in `mode` is one a verdict reads (the unrolled
/// backward against the forward over 100 steps).
fn verdict_point(steps: usize, mode: Mode) -> bool {
    steps == 100 && mode == Mode::Unrolled
}

/// The run of a point with the median backward / forward ratio, carrying the number of runs.
fn median_run(mut runs: Vec<MemoryPoint>) -> Option<MemoryPoint> {
    runs.sort_by(|a, b| a.ratio.total_cmp(&b.ratio));
    let n = runs.len();
    let mut p = runs.into_iter().nth(n / 2)?;
    p.timed_runs = n;
    Some(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(ratio: f64) -> MemoryPoint {
        MemoryPoint {
            scene: "s".into(),
            steps: 100,
            mode: Mode::Unrolled,
            store_budget_bytes: 0,
            stored_steps: 0,
            stored_bytes: 0,
            checkpoint_bytes: 0,
            peak_heap_bytes: None,
            forward_ms: 10.0,
            backward_ms: 10.0 * ratio,
            ratio,
            timed_runs: 1,
        }
    }

    #[test]
    fn a_verdict_point_keeps_the_run_with_the_median_ratio() {
        let p = median_run(vec![point(3.1), point(2.2), point(2.6)]).unwrap();
        assert_eq!((p.ratio, p.backward_ms, p.timed_runs), (2.6, 26.0, 3));
        let one = median_run(vec![point(1.5)]).unwrap();
        assert_eq!((one.ratio, one.timed_runs), (1.5, 1));
        assert!(median_run(Vec::new()).is_none());
        assert!(
            verdict_point(100, Mode::Unrolled)
                && !verdict_point(100, Mode::Implicit)
                && !verdict_point(10, Mode::Unrolled)
        );
    }
}
