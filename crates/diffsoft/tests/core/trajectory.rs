//! Whole trajectories: `rollout` keeps every state as the simulator steps, and `vjp` (a
//! cotangent on the trajectory) is the gradient of `sum <C, q>` in both modes, with contact,
//! actuators and a skeleton.

use diffsoft::diff::{self, params, Controls, Cotangent, Mode, Options};
use diffsoft::testing::Case;
use diffsoft::Simulator;
use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};

fn random(n: usize, seed: u64) -> Vec<Vector3<f64>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            Vector3::new(
                rng.random::<f64>() - 0.5,
                rng.random::<f64>() - 0.5,
                rng.random::<f64>() - 0.5,
            )
        })
        .collect()
}

fn value(case: &Case, controls: &Controls, c: &[Vector3<f64>]) -> f64 {
    let r = diff::rollout(&case.model, &case.settings, case.steps, controls).unwrap();
    r.positions.iter().zip(c).map(|(q, c)| q.dot(c)).sum()
}

/// `<vjp, u>` against a central difference along `u` of the initial velocities.
fn check_vjp(case: &Case, mode: Mode, tol: f64) {
    let n = case.model.n();
    let steps = case.steps;
    let c = random((steps + 1) * n, 11);
    let cot = Cotangent::new(n, steps, c.clone(), None).unwrap();
    let g = diff::vjp(
        &case.model,
        &case.settings,
        steps,
        &case.controls,
        &cot,
        Options::mode(mode),
    )
    .unwrap();
    let (q0, v0) = case
        .controls
        .initial
        .clone()
        .unwrap_or_else(|| (case.model.rest().to_vec(), case.model.initial_velocity().to_vec()));
    assert!((g.loss - value(case, &case.controls, &c)).abs() < 1e-9 * g.loss.abs().max(1.0));
    let u = random(n, 12);
    let h = 1e-6;
    let at = |e: f64| {
        let v: Vec<_> = v0.iter().zip(&u).map(|(v, u)| v + u * e).collect();
        let controls = Controls {
            initial: Some((q0.clone(), v)),
            ..case.controls.clone()
        };
        value(case, &controls, &c)
    };
    let fd = (at(h) - at(-h)) / (2.0 * h);
    let ad: f64 = g.v0.iter().zip(&u).map(|(g, u)| g.dot(u)).sum();
    assert!(
        (ad - fd).abs() <= tol * fd.abs().max(1e-8),
        "{} ({mode:?}): vjp {ad:e}, central difference {fd:e}",
        case.name
    );
}

#[test]
fn rollout_keeps_the_simulators_states() {
    let case = diffsoft::testing::free_body(5).unwrap();
    let r = diff::rollout(&case.model, &case.settings, 5, &case.controls).unwrap();
    assert_eq!(r.positions.len(), 6 * case.model.n());
    assert_eq!(r.steps(), 5);
    let mut sim = Simulator::new(case.model.clone(), case.settings.clone()).unwrap();
    if let Some((q, v)) = &case.controls.initial {
        sim.set_state_from(q, v).unwrap();
    }
    let n = case.model.n();
    for k in 1..=5 {
        sim.step().unwrap();
        assert_eq!(&r.positions[k * n..(k + 1) * n], &sim.state().q[..]);
        assert_eq!(&r.velocities[k * n..(k + 1) * n], &sim.state().v[..]);
    }
}

#[test]
fn vjp_matches_central_differences_free_body() {
    check_vjp(&diffsoft::testing::free_body(4).unwrap(), Mode::Unrolled, 1e-6);
}

#[test]
fn vjp_matches_central_differences_in_contact() {
    check_vjp(&diffsoft::testing::ground_contact(6).unwrap(), Mode::Unrolled, 1e-5);
}

#[test]
fn vjp_matches_central_differences_with_actuators() {
    check_vjp(&diffsoft::testing::actuated(4).unwrap(), Mode::Unrolled, 1e-6);
}

#[test]
fn vjp_implicit_matches_unrolled_at_convergence() {
    let mut case = diffsoft::testing::free_body(3).unwrap();
    case.settings.tolerance = 1e-14;
    case.settings.max_iterations = 500;
    let n = case.model.n();
    let cot = Cotangent::new(n, 3, random(4 * n, 5), Some(random(4 * n, 6))).unwrap();
    let run = |mode| {
        diff::vjp(
            &case.model,
            &case.settings,
            3,
            &case.controls,
            &cot,
            Options::mode(mode),
        )
        .unwrap()
    };
    let (u, i) = (run(Mode::Unrolled), run(Mode::Implicit));
    for (a, b) in u.v0.iter().zip(&i.v0) {
        assert!((a - b).norm() <= 1e-6 * (1.0 + a.norm()), "{a:?} vs {b:?}");
    }
}

#[test]
fn cotangents_of_the_wrong_size_are_refused() {
    let case = diffsoft::testing::free_body(2).unwrap();
    let n = case.model.n();
    let e = Cotangent::new(n, 2, vec![Vector3::zeros(); 2 * n], None).unwrap_err();
    assert!(e.to_string().contains("expected (steps + 1) * n"), "{e}");
    let mut bad = vec![Vector3::zeros(); 3 * n];
    bad[n + 1].y = f64::NAN;
    let e = Cotangent::new(n, 2, bad, None).unwrap_err();
    assert!(e.to_string().contains("state 1, vertex 1"), "{e}");
    let cot = Cotangent::new(n, 3, vec![Vector3::zeros(); 4 * n], None).unwrap();
    let e = diff::vjp(&case.model, &case.settings, 2, &case.controls, &cot, Options::default()).unwrap_err();
    assert!(e.to_string().contains("covers 3 steps"), "{e}");
}

#[test]
fn array_parameters_round_trip_and_validate() {
    let case = diffsoft::testing::actuated(2).unwrap();
    let mut model = case.model.clone();
    let e: Vec<f64> = (0..model.tets().len()).map(|t| 1e4 + t as f64).collect();
    params::set_youngs_modulus_per_tet(&mut model, &e).unwrap();
    for (a, b) in params::youngs_modulus_per_tet(&model).iter().zip(&e) {
        assert!((a - b).abs() <= 1e-9 * b);
    }
    let mut bad = e.clone();
    bad[2] = 0.0;
    let err = params::set_youngs_modulus_per_tet(&mut model, &bad).unwrap_err();
    assert!(err.to_string().contains("tet 2"), "{err}");
    let t: Vec<_> = params::attachment_targets(&model)
        .iter()
        .map(|t| t + Vector3::x())
        .collect();
    params::set_attachment_targets(&mut model, &t).unwrap();
    assert_eq!(params::attachment_targets(&model), t);
    assert!(params::set_attachment_targets(&mut model, &t[1..]).is_err());
}

/// An implicit tolerance is a relative residual: 1 or more is met before the adjoint solve
/// starts (the gradient would be its zero starting guess, with no error), and NaN or a
/// negative value means nothing; each is refused up front, whatever front end passes it.
#[test]
fn implicit_tolerances_outside_zero_to_one_are_refused() {
    let case = diffsoft::testing::free_body(3).unwrap();
    let n = case.model.n();
    let cot = Cotangent::new(n, 3, random(4 * n, 5), None).unwrap();
    for t in [1.0, 10.0, 1e300, f64::INFINITY, f64::NAN, -1e-3] {
        let e = diff::vjp(
            &case.model,
            &case.settings,
            3,
            &case.controls,
            &cot,
            Options {
                implicit_tolerance: Some(t),
                ..Options::mode(Mode::Implicit)
            },
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("implicit tolerance is a relative residual and must be in [0, 1)"),
            "{t}: {e}"
        );
    }
    let ok = Options {
        implicit_tolerance: Some(1e-10),
        ..Options::mode(Mode::Implicit)
    };
    assert!(diff::vjp(&case.model, &case.settings, 3, &case.controls, &cot, ok).is_ok());
}

/// A time step so short that the positions' round-off over one step is an absurd velocity
/// (1e-100 s): the divergence it causes names the time step as the cause; a short but
/// resolvable one (1e-20 s) runs.
#[test]
fn a_time_step_below_double_precision_is_named_when_the_run_diverges() {
    let case = diffsoft::testing::free_body(1).unwrap();
    let mut settings = case.settings.clone();
    settings.dt = 1e-100;
    let e = Simulator::new(case.model.clone(), settings.clone())
        .unwrap()
        .step()
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("the time step 1e-100 s is below what double precision resolves"),
        "{e}"
    );
    settings.dt = 1e-20;
    Simulator::new(case.model.clone(), settings).unwrap().step().unwrap();
}
