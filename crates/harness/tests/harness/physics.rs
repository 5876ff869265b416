//! Physics checks of the forward solver against closed forms (the studies live in
//! `diffsoft_harness::physics`, shared with the main job's `reports/physics.json`).

use diffsoft::mesh::generate::BoxSpec;
use diffsoft::solver::CertifyPolicy;
use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Settings, Simulator, SolverKind};
use diffsoft_harness::physics;
use nalgebra::{Rotation3, Vector3};

fn cube(n: usize, size: f64) -> diffsoft::mesh::TetMesh {
    BoxSpec::new([n, n, n], [size; 3]).jitter(0.1, 3).build().unwrap()
}

fn settings(dt: f64, solver: SolverKind) -> Settings {
    Settings {
        dt,
        solver,
        certify: CertifyPolicy::Fallback,
        tolerance: 1e-12,
        inner_tolerance: 1e-13,
        max_iterations: 50,
        ..Settings::default()
    }
}

fn material(e: f64, nu: f64) -> Material {
    Material {
        youngs_modulus: e,
        poisson_ratio: nu,
    }
}

/// Implicit Euler of a rigid translation is exact: x_N = x_0 + N h v_0 + h^2 g N (N+1) / 2.
#[test]
fn free_fall_matches_implicit_euler_exactly() {
    for solver in [SolverKind::Direct, SolverKind::Split, SolverKind::Chebyshev] {
        let err = physics::free_fall(solver, 50).unwrap();
        assert!(err < 1e-10, "{solver:?}: free fall relative error {err:e}");
    }
}

/// No gravity, no velocity, rest shape: nothing moves.
#[test]
fn rest_state_without_external_force_does_not_move() {
    let body = BodySpec::new("cube", cube(3, 0.5), material(1e5, 0.4), MassSpec::Density(1000.0));
    let model = ModelBuilder::new().body(body).build().unwrap();
    let rest = model.rest().to_vec();
    let mut sim = Simulator::new(model, settings(0.01, SolverKind::Direct)).unwrap();
    for _ in 0..20 {
        let s = sim.step().unwrap();
        assert!(s.elastic_energy < 1e-20);
    }
    for (q, r) in sim.state().q.iter().zip(&rest) {
        assert!((q - r).norm() < 1e-13, "{q} vs {r}");
    }
}

/// Without gravity or contact, internal forces sum to zero: total momentum is conserved for any
/// initial velocity field (the direct solver conserves it exactly; iterative ones at convergence).
#[test]
fn momentum_is_conserved_without_gravity_or_contact() {
    for solver in [SolverKind::Direct, SolverKind::Chebyshev] {
        let body = BodySpec::new("cube", cube(3, 0.5), material(1e5, 0.3), MassSpec::Density(1000.0));
        let model = ModelBuilder::new().body(body).build().unwrap();
        let n = model.n();
        let mass = model.mass().to_vec();
        let mut sim = Simulator::new(model, settings(0.005, solver)).unwrap();
        let mut seed = 5u64;
        let mut rnd = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let v: Vec<Vector3<f64>> = (0..n).map(|_| Vector3::new(rnd(), rnd(), rnd())).collect();
        let q = sim.state().q.clone();
        sim.set_state(q, v).unwrap();
        let momentum = |s: &Simulator| -> Vector3<f64> { s.state().v.iter().zip(&mass).map(|(v, m)| v * *m).sum() };
        let p0 = momentum(&sim);
        let scale: f64 = sim.state().v.iter().zip(&mass).map(|(v, m)| v.norm() * m).sum();
        for _ in 0..40 {
            sim.step().unwrap();
        }
        let p1 = momentum(&sim);
        assert!((p1 - p0).norm() <= 1e-10 * scale, "{solver:?}: momentum {p0} -> {p1}");
    }
}

/// A rigidly rotated and translated rest shape has zero elastic energy and force: it stays put.
#[test]
fn rigid_motion_of_the_rest_shape_produces_no_elastic_force() {
    let body = BodySpec::new("cube", cube(3, 0.5), material(1e6, 0.45), MassSpec::Density(1000.0));
    let model = ModelBuilder::new().body(body).build().unwrap();
    let r = Rotation3::from_scaled_axis(Vector3::new(0.7, -1.9, 2.4));
    let t = Vector3::new(10.0, -3.0, 7.0);
    let moved: Vec<Vector3<f64>> = model.rest().iter().map(|x| r * x + t).collect();
    let n = model.n();
    let mut sim = Simulator::new(model, settings(0.01, SolverKind::Direct)).unwrap();
    sim.set_state(moved.clone(), vec![Vector3::zeros(); n]).unwrap();
    let s = sim.step().unwrap();
    assert!(s.elastic_energy < 1e-18, "elastic energy {}", s.elastic_energy);
    for (q, x) in sim.state().q.iter().zip(&moved) {
        assert!((q - x).norm() < 1e-12, "moved by {}", (q - x).norm());
    }
}

#[test]
fn block_on_incline_sticks_below_the_friction_angle() {
    for (angle, mu) in [(20.0, 0.5), (30.0, 0.7), (10.0, 0.2)] {
        let r = physics::incline(angle, mu).unwrap();
        assert!(r.should_stick);
        // Stuck: the contact vertices are at rest on the plane. They may shift by the Poisson
        // spreading of the bottom face while the block settles (~1e-5 m here), and the
        // centroid by the block's elastic shear; a sliding block would move ~1e-2 m.
        assert!(r.contact_speed < 1e-6, "{r:?}");
        assert!(r.contact_slip < 1e-4 && r.centroid_displacement.abs() < 1e-4, "{r:?}");
        assert!(r.max_penetration < 1e-9, "{r:?}");
    }
}

#[test]
fn block_on_incline_slides_above_the_friction_angle() {
    for (angle, mu) in [(35.0, 0.5), (40.0, 0.2), (30.0, 0.0)] {
        let r = physics::incline(angle, mu).unwrap();
        assert!(!r.should_stick && r.contact_speed > 0.1, "{r:?}");
        let ratio = r.centroid_displacement / r.predicted_displacement;
        assert!((ratio - 1.0).abs() < 0.02, "slid {ratio} x Coulomb's prediction: {r:?}");
        assert!(r.max_penetration < 1e-9, "{r:?}");
    }
}

/// The static tip deflection of a clamped beam approaches Euler-Bernoulli as the mesh is
/// refined (linear tets lock in bending, so they converge from below). The main job runs finer
/// levels into reports/physics.json.
#[test]
fn cantilever_approaches_euler_bernoulli() {
    let rows = physics::cantilever(&[1, 2]).unwrap();
    assert!(rows.iter().all(|r| r.converged));
    assert!(rows[1].relative_error < rows[0].relative_error, "{rows:?}");
    assert!(
        rows.iter()
            .all(|r| r.tip_deflection > 0.0 && r.tip_deflection < r.euler_bernoulli),
        "{rows:?}"
    );
}
