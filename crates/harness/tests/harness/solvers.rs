//! The global solvers agree where they all converge; certification refuses or falls back where
//! the split iteration diverges; contact keeps bodies out of obstacles; failures are errors.

use crate::common::root;
use diffsoft::mesh::{self, generate::BoxSpec};
use diffsoft::scene::{self, LoadOptions};
use diffsoft::solver::CertifyPolicy;
use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Settings, Simulator, SolverError, SolverKind};
use diffsoft_harness::physics;
use nalgebra::Vector3;

#[test]
fn direct_split_chebyshev_and_certified_reach_the_same_state() {
    let rows = physics::solver_agreement().unwrap();
    assert_eq!(rows.len(), 8);
    for r in &rows {
        assert_eq!(r.used, r.solver, "{r:?}: converges on this M-matrix mesh at 1 ms");
        assert!(r.max_difference < 1e-8, "{r:?}");
        assert_eq!(
            r.contacts > 0,
            r.ground,
            "{r:?}: the tip touches the ground exactly when there is one"
        );
    }
}

#[test]
fn certified_solver_falls_back_on_a_paper_mesh_where_split_diverges() {
    let path = root().join("verification/paper/bridgesus/bridgesus.json");
    let mut sc = scene::load(&path, LoadOptions::default()).unwrap();
    assert_eq!(sc.settings.solver, SolverKind::Auto);
    assert_eq!(sc.settings.certify, CertifyPolicy::Fallback);
    // This test is about the split iteration's certificate: ask for it.
    sc.settings.solver = SolverKind::Split;
    let mut sim = Simulator::new(sc.model.clone(), sc.settings.clone()).unwrap();
    let c = sim.certificate().clone();
    assert_eq!(c.used, SolverKind::Direct);
    assert_eq!(c.converges, Some(false));
    assert!(
        c.spectral_radius.unwrap() > 1.0 && c.message.contains("falling back"),
        "{}",
        c.message
    );
    let mut direct = Simulator::new(
        sc.model.clone(),
        Settings {
            solver: SolverKind::Direct,
            ..sc.settings.clone()
        },
    )
    .unwrap();
    for _ in 0..20 {
        sim.step().unwrap();
        direct.step().unwrap();
    }
    assert_eq!(sim.state().q, direct.state().q, "the fallback run is the direct run");
    // Refusing says why, with the spectral radius.
    let refuse = Settings {
        certify: CertifyPolicy::Refuse,
        ..sc.settings.clone()
    };
    let e = Simulator::new(sc.model.clone(), refuse).unwrap_err();
    assert!(matches!(e, SolverError::Uncertified(_)));
    assert!(e.to_string().contains("rho(G21)"), "{e}");
    // Unchecked, the split iteration diverges: a clear error, not a panic or NaN.
    let unchecked = Settings {
        certify: CertifyPolicy::Off,
        ..sc.settings.clone()
    };
    let mut sim = Simulator::new(sc.model, unchecked).unwrap();
    let e = (0..5).find_map(|_| sim.step().err()).expect("diverges");
    assert!(matches!(e, SolverError::Diverged(_)), "{e}");
    assert!(e.to_string().contains("spectral radius"), "{e}");
}

#[test]
fn ball_dropped_on_the_ground_never_penetrates() {
    let ball = mesh::load(root().join("verification/paper/droneman/ball_tet.obj"))
        .unwrap()
        .mesh;
    for solver in [SolverKind::Direct, SolverKind::Chebyshev] {
        let (pen, lowest, contacts) = physics::ball_drop(ball.clone(), solver).unwrap();
        assert!(contacts > 0, "the ball reached the ground");
        assert!(
            pen <= 1e-9 && lowest > -1e-9,
            "{solver:?}: penetration {pen}, lowest vertex {lowest}"
        );
    }
}

#[test]
fn bad_settings_and_states_are_errors() {
    let mesh = BoxSpec::new([4, 2, 2], [1.0, 0.2, 0.2]).build().unwrap();
    let body = BodySpec::new(
        "beam",
        mesh,
        Material {
            youngs_modulus: 2e5,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(500.0),
    );
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .build()
        .unwrap();
    for dt in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = Simulator::new(
            model.clone(),
            Settings {
                dt,
                ..Settings::default()
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("time step"), "{e}");
    }
    let e = Simulator::new(
        model.clone(),
        Settings {
            damping: 1.5,
            ..Settings::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("damping"), "{e}");
    let mut sim = Simulator::new(model.clone(), Settings::default()).unwrap();
    let n = model.n();
    let mut q = model.rest().to_vec();
    q[3].x = f64::NAN;
    assert!(sim.set_state(q, vec![Vector3::zeros(); n]).is_err());
    let bad = BodySpec::new(
        "bad",
        BoxSpec::new([1, 1, 1], [1.0; 3]).build().unwrap(),
        Material {
            youngs_modulus: -1.0,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(1.0),
    );
    let e = ModelBuilder::new().body(bad).build().unwrap_err();
    assert!(e.to_string().contains("Young's modulus"), "{e}");
    let bad = BodySpec::new(
        "bad",
        BoxSpec::new([1, 1, 1], [1.0; 3]).build().unwrap(),
        Material {
            youngs_modulus: 1.0,
            poisson_ratio: 0.5,
        },
        MassSpec::Density(1.0),
    );
    assert!(ModelBuilder::new().body(bad).build().is_err());
}

#[test]
fn certification_also_rejects_iterations_too_slow_for_their_cap() {
    // An M-matrix mesh: the split iteration converges for every dt, but slowly at large dt.
    let mesh = BoxSpec::new([4, 4, 4], [1.0; 3]).build().unwrap();
    let body = BodySpec::new(
        "cube",
        mesh,
        Material {
            youngs_modulus: 1e6,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(1000.0),
    );
    let model = ModelBuilder::new().body(body).build().unwrap();
    let s = Settings {
        dt: 0.05,
        solver: SolverKind::Split,
        certify: CertifyPolicy::Fallback,
        inner_max_iterations: 50,
        ..Settings::default()
    };
    let sim = Simulator::new(model.clone(), s.clone()).unwrap();
    let c = sim.certificate();
    assert_eq!(c.converges, Some(true));
    assert!(c.predicted_iterations.is_none() || c.predicted_iterations.unwrap() > 50.0);
    assert_eq!(c.used, SolverKind::Direct, "{}", c.message);
    assert!(c.message.contains("above the cap of 50"), "{}", c.message);
    let e = Simulator::new(
        model.clone(),
        Settings {
            certify: CertifyPolicy::Refuse,
            ..s.clone()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("inner iterations"), "{e}");
    // With a generous cap the same iteration is certified and used.
    let ok = Simulator::new(
        model,
        Settings {
            inner_max_iterations: 100_000,
            ..s
        },
    )
    .unwrap();
    assert_eq!(ok.certificate().used, SolverKind::Split, "{}", ok.certificate().message);
}

/// A beam of about `tets` tets, clamped at `z = 0`, under gravity.
fn clamped_beam(tets: usize, youngs_modulus: f64) -> diffsoft::Model {
    let mesh = mesh::generate::box_with_about(tets, 4.0).build().unwrap();
    let mut body = BodySpec::new(
        "beam",
        mesh,
        Material {
            youngs_modulus,
            poisson_ratio: 0.4,
        },
        MassSpec::Density(1000.0),
    );
    body.fixed = (0..body.mesh.vertices.len())
        .filter(|&i| body.mesh.vertices[i].z < 1e-9)
        .collect();
    ModelBuilder::new().body(body).build().unwrap()
}

#[test]
fn auto_picks_direct_on_a_stiff_clamped_beam() {
    let model = clamped_beam(1500, 1e6);
    // The split iteration needs hundreds of inner iterations per solve here.
    let split = Simulator::new(
        model.clone(),
        Settings {
            solver: SolverKind::Split,
            ..Settings::default()
        },
    )
    .unwrap();
    let predicted = split.certificate().predicted_iterations.unwrap_or(f64::INFINITY);
    assert!(predicted > 200.0, "{}", split.certificate().message);
    let sim = Simulator::new(model, Settings::default()).unwrap();
    let c = sim.certificate();
    assert_eq!(c.requested, SolverKind::Auto);
    assert_eq!(c.used, SolverKind::Direct, "{}", c.message);
    assert!(c.message.starts_with("auto: direct"), "{}", c.message);
    let direct = c.candidates.iter().find(|k| k.solver == SolverKind::Direct).unwrap();
    assert!(direct.eligible && direct.predicted_ms.is_some(), "{c:?}");
}

#[test]
fn auto_picks_split_where_it_converges_in_a_handful_of_iterations() {
    // A soft beam at a tiny time step: inertia dominates and the split iteration contracts
    // by orders of magnitude per iteration.
    let model = clamped_beam(5000, 1e4);
    let s = Settings {
        dt: 1e-5,
        ..Settings::default()
    };
    let mut sim = Simulator::new(model, s).unwrap();
    let c = sim.certificate().clone();
    assert_eq!(c.used, SolverKind::Split, "{}", c.message);
    assert!(
        c.message.contains("row-sum bound") && c.message.contains("cheaper than direct"),
        "{}",
        c.message
    );
    let split = c.candidates.iter().find(|k| k.solver == SolverKind::Split).unwrap();
    let n = split.predicted_iterations.unwrap();
    assert!(n <= 5.0, "{c:?}");
    let stats = sim.step().unwrap();
    assert!(
        (stats.global_iterations as f64) <= 2.0 * n * stats.iterations as f64,
        "{stats:?} against {n} predicted per solve"
    );
}
