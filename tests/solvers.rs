//! The global solvers agree where they all converge; certification refuses or falls back where
//! the split iteration diverges; contact keeps bodies out of obstacles; failures are errors.

mod common;

use common::root;
use diffsoft::contact::Obstacle;
use diffsoft::mesh::{self, generate::BoxSpec};
use diffsoft::scene::{self, LoadOptions};
use diffsoft::solver::{
    BodySpec, CertifyPolicy, MassSpec, Material, Model, ModelBuilder, Settings, Simulator, SolverError, SolverKind,
};
use nalgebra::Vector3;

fn settings(dt: f64, solver: SolverKind, certify: CertifyPolicy) -> Settings {
    Settings {
        dt,
        solver,
        certify,
        tolerance: 1e-12,
        inner_tolerance: 1e-14,
        max_iterations: 200,
        inner_max_iterations: 20_000,
        ..Settings::default()
    }
}

/// A Kuhn-split (M-matrix) beam pinned at one end under gravity, optionally above the ground.
fn beam_model(ground: bool) -> Model {
    let mesh = BoxSpec::new([8, 2, 2], [1.0, 0.2, 0.2])
        .origin([0.0, 0.0, -0.1])
        .build()
        .unwrap();
    let mut body = BodySpec::new(
        "beam",
        mesh.clone(),
        Material {
            youngs_modulus: 2e5,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(500.0),
    );
    body.fixed = (0..mesh.num_vertices())
        .filter(|&i| mesh.vertices[i].x < 1e-9)
        .collect();
    let mut b = ModelBuilder::new().gravity(Vector3::new(0.0, -9.81, 0.0)).body(body);
    if ground {
        b = b.obstacle(Obstacle::plane(
            "ground",
            Vector3::new(0.0, -0.005, 0.0),
            Vector3::y(),
            0.4,
        ));
    }
    b.build().unwrap()
}

fn run(model: Model, s: Settings, steps: usize) -> (Vec<Vector3<f64>>, SolverKind, f64, usize) {
    let mut sim = Simulator::new(model, s).unwrap();
    let mut pen = 0.0f64;
    let mut contacts = 0;
    for _ in 0..steps {
        let st = sim.step().unwrap();
        pen = pen.max(st.max_penetration);
        contacts = contacts.max(st.contacts);
    }
    (sim.state().q.clone(), sim.certificate().used, pen, contacts)
}

fn max_diff(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).norm()).fold(0.0, f64::max)
}

#[test]
fn direct_split_chebyshev_and_certified_reach_the_same_state() {
    for ground in [false, true] {
        // rho(G19) = 0.45 here (1.81 at 2 ms, where certification refuses the plain iteration).
        let dt = 1e-3;
        let (reference, _, _, contacts) = run(
            beam_model(ground),
            settings(dt, SolverKind::Direct, CertifyPolicy::Off),
            60,
        );
        assert_eq!(contacts > 0, ground, "the beam's tip reaches the ground");
        for (kind, policy) in [
            (SolverKind::Split, CertifyPolicy::Off),
            (SolverKind::Split, CertifyPolicy::Fallback),
            (SolverKind::Chebyshev, CertifyPolicy::Refuse),
            (SolverKind::Plain, CertifyPolicy::Refuse),
        ] {
            let s = settings(dt, kind, policy);
            let (q, used, pen, _) = run(beam_model(ground), s, 60);
            assert_eq!(used, kind, "{kind:?} converges on this M-matrix mesh at dt {dt}");
            let d = max_diff(&q, &reference);
            assert!(
                d < 1e-8,
                "ground {ground}: {kind:?}/{policy:?} differs from direct by {d:e} m"
            );
            assert!(pen < 1e-9, "penetration {pen}");
        }
    }
}

#[test]
fn certified_solver_falls_back_on_a_paper_mesh_where_split_diverges() {
    let path = root().join("verification/paper/bridgesus/bridgesus.json");
    let sc = scene::load(&path, LoadOptions::default()).unwrap();
    assert_eq!(sc.settings.solver, SolverKind::Split);
    assert_eq!(sc.settings.certify, CertifyPolicy::Fallback);
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
    let mut body = BodySpec::new(
        "ball",
        ball,
        Material {
            youngs_modulus: 2e4,
            poisson_ratio: 0.4,
        },
        MassSpec::Total(1.0),
    );
    body.initial_velocity = Vector3::new(0.5, -3.0, 0.0);
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .obstacle(Obstacle::plane("ground", Vector3::zeros(), Vector3::y(), 0.3))
        .build()
        .unwrap();
    for solver in [SolverKind::Direct, SolverKind::Chebyshev] {
        let s = Settings {
            dt: 0.005,
            solver,
            ..Settings::default()
        };
        let mut sim = Simulator::new(model.clone(), s).unwrap();
        let mut worst = 0.0f64;
        let mut touched = false;
        for _ in 0..200 {
            let st = sim.step().unwrap();
            worst = worst.max(st.max_penetration);
            touched |= st.contacts > 0;
            let lowest = sim.state().q.iter().map(|q| q.y).fold(f64::INFINITY, f64::min);
            assert!(lowest > -1e-9, "{solver:?}: vertex below the ground at y = {lowest}");
        }
        assert!(touched, "the ball reached the ground");
        assert!(worst <= 1e-9, "{solver:?}: max penetration {worst}");
    }
}

#[test]
fn bad_settings_and_states_are_errors() {
    let model = beam_model(false);
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
    let mut q = model.rest.clone();
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
