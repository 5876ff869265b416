//! Physics checks of the forward solver against closed forms (issue: forward solver).

mod common;

use diffsoft::contact::Obstacle;
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::solver::{BodySpec, CertifyPolicy, MassSpec, Material, ModelBuilder, Settings, Simulator, SolverKind};
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

/// Implicit Euler of a rigid translation is exact: x_N = x_0 + N h v_0 + h^2 g N (N+1) / 2.
#[test]
fn free_fall_matches_implicit_euler_exactly() {
    let g = Vector3::new(0.3, -9.81, 0.1);
    let v0 = Vector3::new(1.0, 2.0, -0.5);
    for solver in [SolverKind::Direct, SolverKind::Split, SolverKind::Chebyshev] {
        let mut body = BodySpec::new(
            "cube",
            cube(3, 0.5),
            Material {
                youngs_modulus: 1e5,
                poisson_ratio: 0.3,
            },
            MassSpec::Density(1000.0),
        );
        body.initial_velocity = v0;
        let model = ModelBuilder::new().gravity(g).body(body).build().unwrap();
        let rest = model.rest.clone();
        let h = 0.01;
        let mut sim = Simulator::new(model, settings(h, solver)).unwrap();
        let n = 50;
        for _ in 0..n {
            sim.step().unwrap();
        }
        let nf = n as f64;
        let shift = v0 * (nf * h) + g * (h * h * nf * (nf + 1.0) / 2.0);
        let mut worst = 0.0f64;
        for (q, x0) in sim.state().q.iter().zip(&rest) {
            let expect = x0 + shift;
            worst = worst.max((q - expect).norm() / expect.norm().max(shift.norm()));
        }
        assert!(worst < 1e-10, "{solver:?}: free fall relative error {worst:e}");
    }
}

fn material(e: f64, nu: f64) -> Material {
    Material {
        youngs_modulus: e,
        poisson_ratio: nu,
    }
}

/// No gravity, no velocity, rest shape: nothing moves.
#[test]
fn rest_state_without_external_force_does_not_move() {
    let body = BodySpec::new("cube", cube(3, 0.5), material(1e5, 0.4), MassSpec::Density(1000.0));
    let model = ModelBuilder::new().body(body).build().unwrap();
    let rest = model.rest.clone();
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
        let mass = model.mass.clone();
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
    let moved: Vec<Vector3<f64>> = model.rest.iter().map(|x| r * x + t).collect();
    let n = model.n();
    let mut sim = Simulator::new(model, settings(0.01, SolverKind::Direct)).unwrap();
    sim.set_state(moved.clone(), vec![Vector3::zeros(); n]).unwrap();
    let s = sim.step().unwrap();
    assert!(s.elastic_energy < 1e-18, "elastic energy {}", s.elastic_energy);
    for (q, x) in sim.state().q.iter().zip(&moved) {
        assert!((q - x).norm() < 1e-12, "moved by {}", (q - x).norm());
    }
}

/// A block on a plane inclined by `angle` sticks when tan(angle) < mu_f and otherwise slides
/// with a = g (sin - mu cos): implicit Euler gives exactly d_N = a h^2 N (N + 1) / 2 for a
/// rigid slide. Returns (down-slope displacement of the centroid, Coulomb's prediction,
/// largest tangential displacement and final tangential speed of a vertex that touches the
/// plane).
fn incline(angle_deg: f64, mu: f64) -> (f64, f64, f64, f64) {
    let th = angle_deg.to_radians();
    let g = 9.81;
    let normal = Vector3::new(-th.sin(), th.cos(), 0.0);
    let down_slope = Vector3::new(-th.cos(), -th.sin(), 0.0);
    let size = 0.2;
    let mesh = BoxSpec::new([2, 2, 2], [size; 3])
        .origin([-size / 2.0, 0.0, -size / 2.0])
        .build()
        .unwrap();
    let rot = Rotation3::from_axis_angle(&Vector3::z_axis(), th);
    let mesh = mesh.map_vertices(|v| rot * v);
    let mut body = BodySpec::new("block", mesh, material(1e7, 0.3), MassSpec::Density(1000.0));
    body.volume_constraint = true;
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -g, 0.0))
        .body(body)
        .obstacle(Obstacle::plane("incline", Vector3::zeros(), normal, mu))
        .build()
        .unwrap();
    let h = 0.002;
    let steps = 150;
    let c0: Vector3<f64> = model.rest.iter().sum::<Vector3<f64>>() / model.n() as f64;
    let bottom: Vec<usize> = (0..model.n())
        .filter(|&i| normal.dot(&model.rest[i]).abs() < 1e-12)
        .collect();
    assert_eq!(bottom.len(), 9);
    let start: Vec<Vector3<f64>> = bottom.iter().map(|&i| model.rest[i]).collect();
    let mut sim = Simulator::new(model, settings(h, SolverKind::Direct)).unwrap();
    let mut pen = 0.0f64;
    for _ in 0..steps {
        pen = pen.max(sim.step().unwrap().max_penetration);
    }
    let c1: Vector3<f64> = sim.state().q.iter().sum::<Vector3<f64>>() / sim.state().q.len() as f64;
    let d = (c1 - c0).dot(&down_slope);
    let a = g * (th.sin() - mu * th.cos());
    let n = steps as f64;
    let expect = if a > 0.0 { a * h * h * n * (n + 1.0) / 2.0 } else { 0.0 };
    assert!(pen < 1e-9, "penetration {pen}");
    let slip = bottom
        .iter()
        .zip(&start)
        .map(|(&i, x0)| {
            let u = sim.state().q[i] - x0;
            (u - normal * normal.dot(&u)).norm()
        })
        .fold(0.0, f64::max);
    let speed = bottom
        .iter()
        .map(|&i| {
            let v = sim.state().v[i];
            (v - normal * normal.dot(&v)).norm()
        })
        .fold(0.0, f64::max);
    (d, expect, slip, speed)
}

#[test]
fn block_on_incline_sticks_below_the_friction_angle() {
    for (angle, mu) in [(20.0, 0.5), (30.0, 0.7), (10.0, 0.2)] {
        let (d, _, slip, speed) = incline(angle, mu);
        // Stuck: the contact vertices are at rest on the plane. They may shift by the Poisson
        // spreading of the bottom face while the block settles (~1e-5 m here), and the
        // centroid by the block's elastic shear; a sliding block would move ~1e-2 m.
        assert!(
            speed < 1e-6,
            "angle {angle}, mu {mu}: contact vertices still slide at {speed} m/s"
        );
        assert!(
            slip < 1e-4 && d.abs() < 1e-4,
            "angle {angle}, mu {mu}: slip {slip} m, centroid {d} m"
        );
    }
}

#[test]
fn block_on_incline_slides_above_the_friction_angle() {
    for (angle, mu) in [(35.0, 0.5), (40.0, 0.2), (30.0, 0.0)] {
        let (d, expect, slip, speed) = incline(angle, mu);
        assert!(expect > 0.0 && slip > 0.5 * expect && speed > 0.1);
        assert!(
            (d / expect - 1.0).abs() < 0.02,
            "angle {angle}, mu {mu}: slid {d} m, Coulomb predicts {expect} m"
        );
    }
}
