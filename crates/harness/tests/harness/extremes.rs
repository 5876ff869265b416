//! The extremes suite: the fast subset ends without a NaN, a panic or an unexplained failure;
//! shards merge into the unsharded report; random extreme inputs never panic nor end in a silent
//! NaN; a zero-thickness mesh obstacle is refused.

use std::sync::OnceLock;

use diffsoft::diff::loss::CenterOfMass;
use diffsoft::diff::{self, Controls, Options, Param};
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::solver::CertifyPolicy;
use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Settings, Simulator, SolverError, SolverKind};
use diffsoft_harness::extremes::{self, ExtremesPartial, GradientStatus, Outcome, Subset};
use diffsoft_harness::shard::Shard;
use nalgebra::Vector3;
use proptest::prelude::*;

fn fast() -> &'static extremes::ExtremesReport {
    static R: OnceLock<extremes::ExtremesReport> = OnceLock::new();
    R.get_or_init(|| extremes::run(Subset::Fast, false))
}

#[test]
fn fast_subset_has_no_nan_panic_or_unexplained_failure() {
    let r = fast();
    let failing: Vec<String> = r
        .cases
        .iter()
        .filter(|c| !c.passes)
        .map(|c| format!("{}: {}", c.name, c.explanation))
        .collect();
    assert!(failing.is_empty(), "{failing:#?}\n{}", extremes::table(r));
    assert_eq!(r.counts.failed, 0);
    for c in &r.cases {
        assert_ne!(c.gradient.status, GradientStatus::NonFinite, "{}", c.name);
        if c.outcome != Outcome::Stable {
            let m = c.message.as_deref().unwrap_or("");
            assert!(
                m.len() > 10,
                "{}: an explained outcome needs a message, got {m:?}",
                c.name
            );
        }
        if let Some(v) = &c.gradient.values {
            assert!(v.iter().all(|x| x.is_finite()), "{}", c.name);
        }
    }
    // Every extreme the suite promises is covered, in the fast subset too.
    let all: Vec<&str> = extremes::all().iter().map(|c| c.category).collect();
    for cat in [
        "stiffness",
        "density",
        "time step",
        "degenerate tets",
        "inverted tets",
        "mesh size",
        "rigid motion",
        "activation",
        "joint angle",
        "contact speed",
        "friction",
    ] {
        assert!(all.contains(&cat), "{cat}");
        assert!(r.cases.iter().any(|c| c.category == cat), "fast subset lacks {cat}");
    }
    // The three explained outcomes all occur, and the rejections name what is wrong.
    let rejected: Vec<&str> = r
        .cases
        .iter()
        .filter(|c| c.outcome == Outcome::RejectedInput)
        .filter_map(|c| c.message.as_deref())
        .collect();
    assert!(
        rejected.iter().any(|m| m.contains("sliver.obj:7: tet 1")),
        "{rejected:?}"
    );
    assert!(rejected.iter().any(|m| m.contains("Young's modulus")), "{rejected:?}");
}

/// What a sharded and an unsharded extremes run differ in.
const EXTREMES_RUN_KEYS: &[&str] = &["wall_s", "wall_time_s", "shards", "provenance", "shard_provenance"];

#[test]
fn shards_merge_into_the_unsharded_report() {
    let n = 3;
    let mut parts = Vec::new();
    let mut names = Vec::new();
    for k in 0..n {
        let p = extremes::run_shard(Subset::Fast, Shard { index: k, count: n }, false);
        let text = serde_json::to_string(&p).unwrap();
        parts.push(serde_json::from_str::<ExtremesPartial>(&text).unwrap());
        names.push(format!("x{k}.json"));
    }
    let merged = extremes::merge(parts.clone(), &names).unwrap();
    // Each shard's provenance survives its partial report's round trip, in shard order.
    assert_eq!(merged.shard_provenance.len(), n);
    for (got, part) in merged.shard_provenance.iter().zip(&parts) {
        assert!(got.is_some() && *got == part.provenance, "{got:?}");
    }
    let mut a = serde_json::to_value(&merged).unwrap();
    let mut b = serde_json::to_value(fast()).unwrap();
    crate::common::strip_keys(&mut a, EXTREMES_RUN_KEYS);
    crate::common::strip_keys(&mut b, EXTREMES_RUN_KEYS);
    assert_eq!(crate::common::json_difference(&a, &b, ""), None);
    let e = extremes::merge(parts[1..].to_vec(), &names[1..])
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing 1 of 3 shards: 0/3"), "{e}");
    // A tampered case: its verdict must follow from its own outcome and checks.
    let mut other = parts.clone();
    let flipped = &mut other[1].cases[0];
    flipped.passes = !flipped.passes;
    let index = flipped.index;
    let e = extremes::merge(other, &names).unwrap_err().to_string();
    assert!(
        e.contains(&format!("x1.json: case {index}")) && e.contains("but its outcome, checks and gradient give"),
        "{e}"
    );
    let mut other = parts.clone();
    other[2].cases[0].name = "something else".into();
    let e = extremes::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("is not the case the list has at that place"), "{e}");
    // A check's `holds` follows from its own measurement, threshold and comparison.
    let (k, c) = (0..n)
        .find_map(|k| {
            let c = parts[k]
                .cases
                .iter()
                .position(|c| c.checks.iter().any(|x| x.threshold.is_some()))?;
            Some((k, c))
        })
        .expect("a bounded check");
    let check = parts[k].cases[c]
        .checks
        .iter()
        .position(|x| x.threshold.is_some())
        .unwrap();
    let mut other = parts.clone();
    let x = &mut other[k].cases[c].checks[check];
    x.holds = !x.holds;
    let e = extremes::merge(other, &names).unwrap_err().to_string();
    assert!(
        e.contains(&format!("x{k}.json: case")) && e.contains("says holds ="),
        "{e}"
    );
    let mut other = parts.clone();
    other[k].cases[c].checks[check].measured = None;
    other[k].cases[c].checks[check].holds = true;
    let e = extremes::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("measurement null"), "{e}");
    // A gradient's status follows from its values.
    let (k, c) = (0..n)
        .find_map(|k| {
            let c = parts[k]
                .cases
                .iter()
                .position(|c| c.gradient.status == GradientStatus::Finite)?;
            Some((k, c))
        })
        .expect("a case with a finite gradient");
    let mut other = parts.clone();
    other[k].cases[c].gradient.values = Some(Vec::new());
    let e = extremes::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("its gradient has 0 values for"), "{e}");
    let mut other = parts.clone();
    other[k].cases[c].gradient.values = None;
    let e = extremes::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("its gradient is 'finite' but holds no values"), "{e}");
    // A stable case ran every step; a shard's time is a time.
    let (k, c) = (0..n)
        .find_map(|k| {
            let c = parts[k].cases.iter().position(|c| c.outcome == Outcome::Stable)?;
            Some((k, c))
        })
        .expect("a stable case");
    let mut other = parts.clone();
    other[k].cases[c].steps_run = 0;
    let e = extremes::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("is stable (every step ran), but ran 0 steps"), "{e}");
    // A stable case carries the checks its run records, all of them in order: none dropped
    // (an empty list), none renamed, none reordered.
    let (k, c) = (0..n)
        .find_map(|k| {
            let c = parts[k]
                .cases
                .iter()
                .position(|c| c.outcome == Outcome::Stable && c.checks.len() >= 2)?;
            Some((k, c))
        })
        .expect("a stable case with two checks");
    let mut other = parts.clone();
    other[k].cases[c].checks.clear();
    let e = extremes::merge(other, &names).unwrap_err().to_string();
    assert!(
        e.contains(&format!("x{k}.json: case"))
            && e.contains("records the checks [], where a stable run of this case records"),
        "{e}"
    );
    let mut other = parts.clone();
    other[k].cases[c].checks[0].quantity = "something else".into();
    let e = extremes::merge(other, &names).unwrap_err().to_string();
    assert!(e.contains("records the checks [\"something else\""), "{e}");
    let mut other = parts.clone();
    other[k].cases[c].checks.swap(0, 1);
    assert!(extremes::merge(other, &names).is_err());
    // Every case of the run records exactly what its case declares.
    for part in &parts {
        for r in &part.cases {
            let case = &extremes::all()[r.index];
            let got: Vec<&str> = r.checks.iter().map(|x| x.quantity.as_str()).collect();
            if r.outcome == Outcome::Stable {
                assert_eq!(got, case.checks, "{}", r.name);
            }
        }
    }
    let mut other = parts.clone();
    other[1].wall_time_s = -1.0;
    let e = extremes::merge(other, &names).unwrap_err().to_string();
    assert!(
        e.contains("x1.json: wall_time_s must be finite and not negative"),
        "{e}"
    );
}

#[test]
fn zero_thickness_mesh_obstacle_is_refused() {
    use diffsoft::contact::{Obstacle, TriMeshObstacle};
    let plate = TriMeshObstacle::new(
        vec![
            Vector3::new(-1.0, 0.0, -1.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 0.0, 1.0),
        ],
        vec![[0, 2, 1]],
    )
    .unwrap();
    let mesh = BoxSpec::new([1, 1, 1], [0.1; 3])
        .origin([0.0, 0.1, 0.0])
        .build()
        .unwrap();
    let body = || {
        BodySpec::new(
            "b",
            mesh.clone(),
            Material {
                youngs_modulus: 1e5,
                poisson_ratio: 0.3,
            },
            MassSpec::Density(1000.0),
        )
    };
    let obstacle = |thickness| Obstacle::new("plate", plate.clone(), 0.5, thickness);
    let e: SolverError = ModelBuilder::new()
        .body(body())
        .obstacle(obstacle(0.0))
        .build()
        .unwrap_err()
        .into();
    assert!(matches!(e, SolverError::Input(_)));
    let m = e.to_string();
    assert!(
        m.contains("obstacle 'plate'") && m.contains("thickness must be at least"),
        "{m}"
    );
    assert!(ModelBuilder::new()
        .body(body())
        .obstacle(obstacle(1e-4))
        .build()
        .is_ok());
}

/// What one random extreme run may end in: every step with finite states, or an error with a
/// message. Panics fail the property (proptest catches them).
fn run_extreme(e: f64, rho: f64, dt: f64, omega: f64, solver: SolverKind) -> Result<(), TestCaseError> {
    let mesh = BoxSpec::new([1, 1, 2], [0.1, 0.1, 0.2]).jitter(0.1, 3).build().unwrap();
    let model = match ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(BodySpec::new(
            "b",
            mesh,
            Material {
                youngs_modulus: e,
                poisson_ratio: 0.3,
            },
            MassSpec::Density(rho),
        ))
        .build()
    {
        Ok(m) => m,
        Err(err) => {
            prop_assert!(!err.to_string().is_empty());
            return Ok(());
        }
    };
    let c = Vector3::new(0.05, 0.05, 0.1);
    let v: Vec<Vector3<f64>> = model
        .rest()
        .iter()
        .map(|x| Vector3::new(-(x.y - c.y), x.x - c.x, 0.0) * omega)
        .collect();
    let settings = Settings {
        dt,
        solver,
        certify: CertifyPolicy::Fallback,
        ..Settings::default()
    };
    let mut sim = match Simulator::new(model.clone(), settings.clone()) {
        Ok(s) => s,
        Err(err) => {
            prop_assert!(!err.to_string().is_empty());
            return Ok(());
        }
    };
    sim.set_state(model.rest().to_vec(), v.clone()).unwrap();
    for _ in 0..5 {
        match sim.step() {
            Ok(st) => prop_assert!(st.kinetic_energy.is_finite()),
            Err(err) => {
                // Detected: a message, never a silent NaN.
                prop_assert!(err.to_string().len() > 10, "{err}");
                return Ok(());
            }
        }
    }
    let st = sim.state();
    prop_assert!(st.q.iter().chain(&st.v).all(|x| x.iter().all(|c| c.is_finite())));
    let mut gs = settings;
    gs.solver = SolverKind::Direct;
    let loss = CenterOfMass {
        direction: Vector3::new(1.0, 1.0, 0.0),
        time_average: true,
        vertices: Some(vec![0]),
    };
    let controls = Controls {
        initial: Some((model.rest().to_vec(), v)),
        ..Controls::default()
    };
    match diff::gradient(&model, &gs, 5, &controls, &loss, Options::default()) {
        Ok(g) => {
            for p in [Param::YOUNGS_MODULUS, Param::DENSITY] {
                let d = p.derivative(&model, &g);
                prop_assert!(d.is_finite(), "d/d{p} = {d}");
            }
        }
        Err(err) => prop_assert!(!err.to_string().is_empty()),
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn random_extremes_never_panic_nor_end_in_nan(
        log_e in 0.0f64..12.0,
        log_rho in -3.0f64..5.0,
        log_dt in -7.0f64..0.0,
        log_omega in -1.0f64..3.0,
        kind in 0usize..4,
    ) {
        let solver = [SolverKind::Direct, SolverKind::Plain, SolverKind::Split, SolverKind::Chebyshev][kind];
        run_extreme(10f64.powf(log_e), 10f64.powf(log_rho), 10f64.powf(log_dt), 10f64.powf(log_omega), solver)?;
    }
}
