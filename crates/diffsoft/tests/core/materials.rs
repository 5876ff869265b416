//! Material models: a bar hanging under its own weight (x = 0 clamped, gravity along +x) at
//! Poisson ratio 0.3 stretches by the closed form `rho g L^2 / (2E)` with the true models'
//! moduli (corotated, neo_hookean), and by the same form with `E_eff = E/(1 + 2nu/3)` with the
//! paper's projective material; the static state is one implicit Euler step of 1 s solved by
//! Newton's method (its inertia term, `(T/h)^2` relative with the bar's period T = 4L/c of 0.04 s,
//! is negligible). Tolerance 1.5%: the clamped end holds
//! the section's lateral contraction (about 0.6% stiffer at L/a = 10), plus the linear tets'
//! discretisation of the quadratic displacement. Also: solvers that cannot take a model refuse
//! it with a message naming both, and `auto` picks Newton.

use diffsoft::base::{Choice, MaterialModel};
use diffsoft::mesh::generate::beam;
use diffsoft::{BodySpec, MassSpec, Material, Model, ModelBuilder, Settings, Simulator, SolverKind};
use nalgebra::Vector3;

const L: f64 = 1.0;
const A: f64 = 0.1;
const RHO: f64 = 1000.0;
const G: f64 = 9.81;

/// The bar clamped at x = 0 (its material model the default until set).
fn bar_spec(e: f64, nu: f64) -> BodySpec {
    let mesh = beam(L, A, A, 20, 2).build().unwrap();
    let fixed: Vec<usize> = (0..mesh.num_vertices())
        .filter(|&i| mesh.vertices[i].x.abs() < 1e-12)
        .collect();
    let mut spec = BodySpec::new(
        "bar",
        mesh,
        Material {
            youngs_modulus: e,
            poisson_ratio: nu,
        },
        MassSpec::Density(RHO),
    );
    spec.fixed = fixed;
    spec
}

fn bar(model: MaterialModel, e: f64, nu: f64) -> Model {
    let mut spec = bar_spec(e, nu);
    spec.model = model;
    ModelBuilder::new()
        .gravity(Vector3::new(G, 0.0, 0.0))
        .body(spec)
        .build()
        .unwrap()
}

fn static_settings(solver: SolverKind) -> Settings {
    Settings {
        dt: 1.0,
        solver,
        tolerance: 1e-10,
        max_iterations: 200,
        ..Settings::default()
    }
}

/// Mean x displacement of the free end face.
fn tip_stretch(model: Model, solver: SolverKind) -> f64 {
    let rest = model.rest().to_vec();
    let mut sim = Simulator::new(model, static_settings(solver)).unwrap();
    let s = sim.step().unwrap();
    assert!(s.converged, "{s:?}");
    let tip: Vec<usize> = (0..rest.len()).filter(|&i| (rest[i].x - L).abs() < 1e-12).collect();
    tip.iter().map(|&i| sim.state().q[i].x - rest[i].x).sum::<f64>() / tip.len() as f64
}

#[test]
fn hanging_bars_stretch_as_their_moduli_say() {
    let (e, nu) = (1e7, 0.3);
    let closed = |e: f64| RHO * G * L * L / (2.0 * e);
    for model in [MaterialModel::Corotated, MaterialModel::NeoHookean] {
        let d = tip_stretch(bar(model, e, nu), SolverKind::Newton);
        let ratio = d / closed(e);
        assert!((ratio - 1.0).abs() < 0.015, "{}: {ratio}", model.name());
    }
    let proj = Material {
        youngs_modulus: e,
        poisson_ratio: nu,
    };
    let d = tip_stretch(bar(MaterialModel::Projective, e, nu), SolverKind::Newton);
    let eff = proj.projective_response().youngs_modulus;
    assert!(
        (d / closed(eff) - 1.0).abs() < 0.015,
        "projective vs E_eff: {}",
        d / closed(eff)
    );
    // ... and not the stated modulus: 1 + 2 nu / 3 = 1.2 softer.
    assert!(d / closed(e) > 1.15, "{}", d / closed(e));
}

#[test]
fn solvers_refuse_models_they_cannot_take_and_auto_picks_newton() {
    let model = bar(MaterialModel::NeoHookean, 1e6, 0.3);
    for solver in [SolverKind::Direct, SolverKind::Split] {
        let e = Simulator::new(model.clone(), static_settings(solver))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(solver.name()) && e.contains("neo_hookean") && e.contains("'bar'"),
            "{e}"
        );
    }
    let sim = Simulator::new(model, static_settings(SolverKind::Auto)).unwrap();
    assert_eq!(sim.certificate().used, SolverKind::Newton);
    assert!(
        sim.certificate().message.contains("hyperelastic"),
        "{}",
        sim.certificate().message
    );
}

/// A neo-Hookean cube squashed to a tenth of its height (inverted tets on the way) recovers.
#[test]
fn neo_hookean_survives_strong_compression() {
    let mesh = beam(0.1, 0.1, 0.1, 2, 2).build().unwrap();
    let n = mesh.num_vertices();
    let mut spec = BodySpec::new(
        "cube",
        mesh,
        Material {
            youngs_modulus: 1e5,
            poisson_ratio: 0.45,
        },
        MassSpec::Density(RHO),
    );
    spec.model = MaterialModel::NeoHookean;
    let model = ModelBuilder::new().body(spec).build().unwrap();
    let rest = model.rest().to_vec();
    let squashed: Vec<Vector3<f64>> = rest.iter().map(|p| Vector3::new(p.x, p.y * 0.1, p.z)).collect();
    let mut sim = Simulator::new(
        model,
        Settings {
            dt: 1e-2,
            solver: SolverKind::Newton,
            max_iterations: 100,
            ..Settings::default()
        },
    )
    .unwrap();
    sim.set_state(squashed, vec![Vector3::zeros(); n]).unwrap();
    for _ in 0..200 {
        sim.step().unwrap();
    }
    let height = sim.state().q.iter().map(|p| p.y).fold(f64::MIN, f64::max)
        - sim.state().q.iter().map(|p| p.y).fold(f64::MAX, f64::min);
    assert!(height > 0.05, "height {height}");
}

/// The bar thrown at its own clamp (every vertex but the clamped ones at `-speed` along x): with
/// a material far too soft for the impact (E = 1 Pa at 20 m/s, the free end moving 0.2 m, four
/// cells, per step) the cells by the clamp fold through it within the first steps, and the step
/// log counts their tets (`inverted_tets`) and the run summary the steps; a stiff bar thrown
/// slowly (E = 1e7 Pa at 0.1 m/s) folds none.
#[test]
fn tets_folded_through_themselves_are_counted() {
    for (e, speed, folds) in [(1.0, 20.0, true), (1e7, 0.1, false)] {
        let mut spec = bar_spec(e, 0.3);
        spec.initial_velocity = Vector3::new(-speed, 0.0, 0.0);
        let model = ModelBuilder::new().body(spec).build().unwrap();
        let tets = model.tets().len();
        let settings = Settings {
            dt: 0.01,
            tolerance: 1e-8,
            max_iterations: 200,
            ..Settings::default()
        };
        let mut sim = Simulator::new(model, settings).unwrap();
        let stats: Vec<_> = (0..3).map(|_| sim.step().unwrap()).collect();
        let inverted: Vec<usize> = stats.iter().map(|s| s.inverted_tets).collect();
        // Recount from the positions: a tet is inverted where its signed volume is not positive.
        let recount = diffsoft::fem::inverted_tets(sim.model().tets(), &sim.state().q);
        assert_eq!(recount, *inverted.last().unwrap());
        if folds {
            assert!(inverted.iter().all(|&k| k > 0 && k < tets), "{inverted:?} of {tets}");
        } else {
            assert_eq!(inverted, [0, 0, 0]);
        }
        let summary = diffsoft::output::RunSummary::of(&stats);
        assert_eq!(summary.steps_with_inverted_tets, if folds { 3 } else { 0 });
        assert_eq!(summary.max_inverted_tets, inverted.iter().copied().max().unwrap());
    }
}
