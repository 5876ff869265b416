//! The trade-off study on a small cantilever: errors are monotone in each knob where theory
//! says they must be; a sweep split into shards and merged gives the unsharded report (with the
//! deterministic cost axis, timings excluded); the CLI's `--shard` and `merge` do the same.

use std::path::Path;

use diffsoft::base::MaterialModel;
use diffsoft::solver::Integrator;
use diffsoft_harness::shard::Shard;
use diffsoft_harness::tradeoff::{
    self, Cantilever, Family, Knob, SceneSource, Status, TimeAxis, TradeoffPartial, TradeoffSpec,
};
use serde_json::Value;

fn small(steps: usize) -> TradeoffSpec {
    let mut s = TradeoffSpec::new("cantilever", SceneSource::Cantilever(Cantilever::small()), steps);
    s.time_axis = TimeAxis::Iterations;
    s.min_timing_s = 0.0;
    s
}

#[test]
fn errors_are_monotone_in_each_knob() {
    let mut spec = small(10);
    spec.families = vec![Family::Direct];
    spec.caps = vec![1, 2, 4, 8, 16];
    spec.tolerances = vec![1e-3, 1e-5, 1e-7, 1e-9];
    spec.dt_divisors = vec![1, 2, 4, 8];
    spec.reference_divisor = 32;
    let s = tradeoff::run_scene(&spec, Path::new("."), 2, false).unwrap();
    assert!(s.rows.iter().all(|r| r.status == Status::Ran), "every setting runs");
    // The reference's own resolution: differences below it are not ordered.
    let res = s.method.resolution;
    assert!(res > 0.0 && res < 1e-6, "resolution {res}");
    let solver = |d: usize, k: Knob| {
        s.rows
            .iter()
            .find(|r| r.setting.dt_divisor == d && r.setting.knob == k)
            .and_then(|r| r.trajectory)
            .unwrap()
    };
    for &d in &spec.dt_divisors {
        // More iterations: the local-global iteration contracts towards the converged step.
        for w in spec.caps.windows(2) {
            let (a, b) = (solver(d, Knob::Cap(w[0])), solver(d, Knob::Cap(w[1])));
            assert!(
                b.solver_max_relative <= a.solver_max_relative + res,
                "h/{d}: cap {} error {:e} > cap {} error {:e}",
                w[1],
                b.solver_max_relative,
                w[0],
                a.solver_max_relative
            );
        }
        // A tighter tolerance.
        for w in spec.tolerances.windows(2) {
            let (a, b) = (solver(d, Knob::Tolerance(w[0])), solver(d, Knob::Tolerance(w[1])));
            assert!(
                b.solver_max_relative <= a.solver_max_relative + res,
                "h/{d}: tolerance {:e} error {:e} > tolerance {:e} error {:e}",
                w[1],
                b.solver_max_relative,
                w[0],
                a.solver_max_relative
            );
        }
        // The first cap is far from converged, the last much closer: the knob matters.
        let (first, last) = (solver(d, Knob::Cap(1)), solver(d, Knob::Cap(16)));
        assert!(last.solver_max_relative < 0.1 * first.solver_max_relative, "h/{d}");
    }
    // A smaller time step: implicit Euler converges to the small-step reference.
    let tight = Knob::Tolerance(1e-9);
    for w in spec.dt_divisors.windows(2) {
        let (a, b) = (solver(w[0], tight), solver(w[1], tight));
        assert!(
            b.max_relative < a.max_relative,
            "h/{} error {:e} not below h/{} error {:e}",
            w[1],
            b.max_relative,
            w[0],
            a.max_relative
        );
    }
    // The report's own verdicts on the same claims agree.
    for v in &s.verdicts {
        if v.claim.contains("smaller error") {
            assert!(v.holds, "{}: {:?} ({})", v.claim, v.measured, v.comparison);
        }
    }
    // The front is sorted by cost and strictly improving in error, and each recommendation is
    // within its target.
    for w in s.pareto.trajectory.windows(2) {
        assert!(w[0].time <= w[1].time && w[1].error < w[0].error);
    }
    for r in &s.recommendations {
        if let Some(p) = &r.trajectory {
            assert!(p.error <= r.target);
        }
    }
}

fn merge_spec() -> TradeoffSpec {
    let mut spec = small(4);
    spec.families = vec![Family::Direct, Family::Split, Family::Certified];
    spec.caps = vec![1, 3];
    spec.tolerances = vec![1e-6];
    spec.dt_divisors = vec![1, 2];
    spec.reference_divisor = 4;
    spec.gradient_dt_divisors = vec![1];
    // BDF2 rows with their own references and reference gradients, keyed by integrator.
    spec.integrators = vec![Integrator::ImplicitEuler, Integrator::Bdf2];
    spec.integrator_families = vec![Family::Direct];
    // The material-model comparison rides with the first shard.
    spec.models = vec![MaterialModel::Projective, MaterialModel::NeoHookean];
    spec
}

#[test]
fn shards_merge_into_the_unsharded_report() {
    let spec = merge_spec();
    let base = Path::new(".");
    let whole = tradeoff::run_shard(&spec, base, Shard::ALL, 2, false).unwrap();
    let mut expected = serde_json::to_value(tradeoff::merge(vec![whole], &["all".into()]).unwrap()).unwrap();
    let n = 3;
    let mut parts = Vec::new();
    let mut names = Vec::new();
    for k in 0..n {
        let p = tradeoff::run_shard(&spec, base, Shard { index: k, count: n }, 1, false).unwrap();
        // Through JSON, as `diffsoft merge` reads them.
        let text = serde_json::to_string(&p).unwrap();
        parts.push(serde_json::from_str::<TradeoffPartial>(&text).unwrap());
        names.push(format!("part{k}.json"));
    }
    let rows: usize = parts.iter().map(|p| p.rows.len()).sum();
    assert_eq!(rows, spec.grid().len());
    assert!(parts.iter().all(|p| p.rows.len() < rows), "each shard holds a part");
    let mut merged = serde_json::to_value(tradeoff::merge(parts.clone(), &names).unwrap()).unwrap();
    crate::common::strip_keys(&mut expected, crate::common::RUN_DEPENDENT_KEYS);
    crate::common::strip_keys(&mut merged, crate::common::RUN_DEPENDENT_KEYS);
    assert_eq!(crate::common::json_difference(&merged, &expected, ""), None);
    // Gradients were computed and compared with the reference gradient.
    let rows = expected["scenes"][0]["rows"].as_array().unwrap();
    assert!(rows.iter().any(|r| r["gradient"]["error"].is_number()));
    let bdf2 = |r: &&Value| r["id"].as_str().unwrap().starts_with("bdf2/direct/");
    assert_eq!(rows.iter().filter(bdf2).count(), 3 * 2);
    assert!(rows
        .iter()
        .filter(bdf2)
        .any(|r| r["gradient"]["solver_error"].is_number()));
    assert_eq!(
        expected["scenes"][0]["models"]["rows"].as_array().map(Vec::len),
        Some(2 * 2),
        "the model comparison survives the merge"
    );
    let refs = expected["scenes"][0]["dt_references"].as_array().unwrap();
    assert!(refs.iter().any(|r| r["integrator"] == "bdf2"));
    // Every reference gradient of this smooth scene is checked against central differences of
    // its own loss and kept.
    let grefs = expected["scenes"][0]["gradient_references"].as_array().unwrap();
    assert!(!grefs.is_empty());
    for g in grefs {
        assert_eq!(g["fd_check"]["agrees"], true, "{g}");
        assert!(g["gradient"]["values"].is_array(), "{g}");
    }

    // Missing, duplicate and foreign shards are refused with a message.
    let e = tradeoff::merge(parts[..2].to_vec(), &names[..2])
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing 1 of 3 shards: 2/3"), "{e}");
    let dup = vec![parts[0].clone(), parts[0].clone(), parts[2].clone()];
    let e = tradeoff::merge(dup, &names).unwrap_err().to_string();
    assert!(e.contains("both shard 0/3"), "{e}");
    let mut other = parts.clone();
    other[1].spec.steps = 5;
    let e = tradeoff::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("sweep inputs differ") && e.contains("part1.json"), "{e}");
    // Tampered shards: rows are checked against the grid the inputs give, not trusted.
    let mut other = parts.clone();
    other[1].total_rows = 99;
    let e = tradeoff::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("part1.json says its sweep has 99 rows"), "{e}");
    let mut other = parts.clone();
    let stolen = other[0].rows[0].clone();
    other[1].rows.push(stolen);
    let e = tradeoff::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("row 0 is in both part0.json and part1.json"), "{e}");
    let mut other = parts.clone();
    other[2].rows[0].id = "direct/cap=999/h".into();
    let e = tradeoff::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("part2.json: row") && e.contains("where the grid has"), "{e}");
    // Tampered figures inside a row: named by the row and the figure.
    let ran = |p: &TradeoffPartial| p.rows.iter().position(|r| r.trajectory.is_some());
    let (k, i) = (0..n).find_map(|k| ran(&parts[k]).map(|i| (k, i))).unwrap();
    let mut other = parts.clone();
    other[k].rows[i].timing.as_mut().unwrap().cpu_s = Some(-1.0);
    let e = tradeoff::merge(other, &names).unwrap_err().to_string();
    assert!(
        e.contains(&format!("part{k}.json: row")) && e.contains("timing.cpu_s must be finite and not negative, got -1"),
        "{e}"
    );
    let mut other = parts.clone();
    other[k].rows[i].trajectory = None;
    let e = tradeoff::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("trajectory errors are missing"), "{e}");
    let mut other = parts.clone();
    other[k].rows[i].trajectory.as_mut().unwrap().max_relative = f64::NAN;
    let e = tradeoff::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("trajectory.max_relative must be finite"), "{e}");
    let mut other = parts.clone();
    other[k].rows[i].work.as_mut().unwrap().steps += 1;
    let e = tradeoff::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("steps") && e.contains("for a row of"), "{e}");
    let mut other = parts.clone();
    other[k].rows[i].dt *= 2.0;
    let e = tradeoff::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("where the scene's step over"), "{e}");
    let mut other = parts.clone();
    other[0].workers = 0;
    let e = tradeoff::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("part0.json says it ran on 0 workers"), "{e}");
    let mut other = parts.clone();
    other[0].workers = usize::MAX;
    let e = tradeoff::merge(other, &names).unwrap_err().to_string();
    assert!(
        e.contains(&format!("part0.json says it ran on {} workers", usize::MAX)),
        "{e}"
    );
    // Tampered headers, the same in every shard (so they agree with each other): the inputs
    // pass the sweep's own checks, and the scene's and references' figures are those of a run.
    let tampered = |edit: &dyn Fn(&mut TradeoffPartial)| {
        let mut other = parts.clone();
        other.iter_mut().for_each(edit);
        tradeoff::merge(other, &names).unwrap_err().to_string()
    };
    let e = tampered(&|p| p.spec.targets = vec![-1.0]);
    assert!(
        e.contains("part0.json: its sweep inputs") && e.contains("targets must be"),
        "{e}"
    );
    let e = tampered(&|p| p.reference.displacement_scale = 0.0);
    assert!(
        e.contains("reference: displacement_scale must be finite and positive, got 0"),
        "{e}"
    );
    let e = tampered(&|p| p.dt_references[0].displacement_scale = -1.0);
    assert!(
        e.contains("at h/1: displacement_scale must be finite and positive"),
        "{e}"
    );
    let e = tampered(&|p| p.reference.work.steps = 0);
    assert!(e.contains("reference: work counts 0 steps"), "{e}");
    let e = tampered(&|p| p.scene.length_scale = 0.0);
    assert!(
        e.contains("its scene's length_scale must be finite and positive"),
        "{e}"
    );
    let e = tampered(&|p| p.scene.vertices = 0);
    assert!(e.contains("its scene has 0 vertices"), "{e}");
    let e = tampered(&|p| p.wall_time_s = -5.0);
    assert!(e.contains("wall_time_s must be finite and not negative, got -5"), "{e}");
    let e = tampered(&|p| p.reference.tolerance = 1e-3);
    assert!(e.contains("are not the sweep's reference_tolerance"), "{e}");
    let e = tampered(&|p| p.gradient_parameters.clear());
    assert!(e.contains("its gradient parameters are []"), "{e}");
}

/// Iteration caps are bounded: a cap of 2^63 would run a row without end.
#[test]
fn absurd_iteration_caps_are_refused() {
    let mut spec = small(2);
    spec.caps = vec![1, 1 << 63];
    let e = spec.validate().unwrap_err().to_string();
    assert!(
        e.contains("iteration caps must be at most 1000000 per step, got 9223372036854775808"),
        "{e}"
    );
    let mut spec = small(2);
    spec.reference_max_iterations = tradeoff::MAX_CAP + 1;
    assert!(spec.validate().is_err());
    spec.reference_max_iterations = tradeoff::MAX_CAP;
    assert!(spec.validate().is_ok());
}

/// The material model as a knob: against a refined Neo-Hookean reference, the Neo-Hookean rows
/// converge with the time step, and the projective rows stop at the model's own error (it
/// responds with `E_eff = E / (1 + 2 nu / 3)`: 0.83 E at nu = 0.3), far above the Neo-Hookean
/// model's time-discretisation error at the finest step.
#[test]
fn the_material_model_is_a_knob_with_its_own_error() {
    let mut spec = small(10);
    spec.families = vec![Family::Newton];
    spec.caps = vec![];
    spec.tolerances = vec![1e-2];
    spec.dt_divisors = vec![1, 2, 4];
    spec.reference_divisor = 16;
    spec.reference_integrator = Integrator::Bdf2;
    spec.models = vec![
        MaterialModel::Projective,
        MaterialModel::Corotated,
        MaterialModel::NeoHookean,
    ];
    let s = tradeoff::run_scene(&spec, Path::new("."), 2, false).unwrap();
    let m = s.models.as_ref().expect("the sweep names models");
    assert_eq!(m.reference_unconverged_steps, 0);
    assert_eq!(m.rows.len(), 3 * 3);
    let err = |model: MaterialModel, d: usize| {
        let r = m.rows.iter().find(|r| r.model == model && r.dt_divisor == d).unwrap();
        assert_eq!(r.status, "ok", "{}", r.id);
        assert_eq!(r.unconverged_steps, Some(0), "{}", r.id);
        r.max_relative.unwrap()
    };
    let nh: Vec<f64> = [1, 2, 4].iter().map(|&d| err(MaterialModel::NeoHookean, d)).collect();
    assert!(nh[0] > nh[1] && nh[1] > nh[2], "Neo-Hookean converges in h: {nh:?}");
    // BDF2: second order, so a halving of h takes off at least a factor 3 here.
    assert!(nh[1] / nh[2] > 3.0, "{nh:?}");
    let projective = err(MaterialModel::Projective, 4);
    assert!(projective > 10.0 * nh[2], "projective {projective:e} vs {:e}", nh[2]);
    // The corotated model shares the small-strain moduli: closer than the projective one.
    assert!(err(MaterialModel::Corotated, 4) < 0.5 * projective);
    assert!(tradeoff::summary(&s).contains("material models against neo_hookean"));
}
