//! Reverse-mode gradients of whole simulations against finite differences, the CLI's gradient
//! against finite differences taken from outside through `--set`, and the implicit mode at
//! convergence.

use diffsoft::diff::{self, loss, Controls, DiffError, Mode, Options, Param};
use diffsoft::testing::Case;
use diffsoft_harness::gradients::check_case;

fn assert_passes(case: &Case) {
    let c = check_case(case, 7);
    assert!(c.error.is_none(), "{}: {:?}", c.name, c.error);
    let m = &c.modes[0];
    assert_eq!(m.mode, Mode::Unrolled);
    for g in &m.groups {
        assert!(
            g.passes,
            "{} / {}: analytic {:e}, best fd {:e} (step {:e}), rel {:e}",
            c.name, g.group, g.analytic, g.fd_best, g.step_best, g.rel_error_best
        );
    }
    let d = c.dual.as_ref().expect("dual check ran");
    assert!(d.max_rel_error < 1e-8, "{}: dual check {:e}", c.name, d.max_rel_error);
    assert!(d.tets > 0, "{}: the dual check skipped every tet", c.name);
}

/// Largest difference of the initial-state derivatives (`dL/dq_0`, `dL/dv_0`) of `g` from those
/// of `reference`, relative to the reference's largest.
pub(crate) fn initial_state_error(g: &diff::Gradient, reference: &diff::Gradient) -> f64 {
    let components =
        |g: &diff::Gradient| -> Vec<f64> { g.q0.iter().chain(&g.v0).flat_map(|v| v.iter().copied()).collect() };
    let r = components(reference);
    let size = r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    components(g)
        .iter()
        .zip(&r)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
        / size
}

/// Assert that one of `g`'s warnings (over `steps` steps) contains `text`.
fn assert_warns(g: &diff::Gradient, steps: usize, text: &str) {
    let warned = g.stats.warnings(steps);
    assert!(warned.iter().any(|w| w.contains(text)), "{warned:?}");
}

#[test]
fn free_body_gradients_match_finite_differences() {
    assert_passes(&diffsoft::testing::free_body(4).unwrap());
}

#[test]
fn contact_gradients_match_finite_differences() {
    assert_passes(&diffsoft::testing::ground_contact(8).unwrap());
}

#[test]
fn actuator_and_attachment_gradients_match_finite_differences() {
    assert_passes(&diffsoft::testing::actuated(4).unwrap());
}

/// Values at the edge of their valid range are checked, not failed by the check's own step
/// leaving the range: a muscle held at activation 0 (its range is [0, 1]) is perturbed inwards,
/// and it and a Poisson ratio of 0 (range [0, 0.5)) take second-order one-sided differences
/// `(-3 L(0) + 4 L(e) - L(2e)) / 2e`, which pass as the central ones do inside the range. At
/// nu = 0 the volume term's weight is 0 but its derivative is not: the backward pass computes
/// the volume target there too (it used to leave `dL/dw_vol` without it, and `dL/dnu` was
/// -0.057 against the differences' 0.0051 on this beam).
#[test]
fn gradients_at_the_edge_of_a_parameter_range_are_checked_one_sided() {
    let mut case = diffsoft::testing::actuated(4).unwrap();
    for row in case.controls.activations.as_mut().unwrap() {
        row[1] = 0.0; // the muscle layer (the second group) at rest
    }
    case.groups = vec![diffsoft::testing::Group::Activations];
    assert_passes(&case);
    let c = check_case(&case, 7);
    // Perturbed inwards, every step's other side leaves the range: one-sided throughout.
    let curve = &c.modes[0].groups[0].v_curve;
    assert!(!curve.is_empty() && curve.iter().all(|p| p.one_sided), "{curve:?}");
    let mut case = diffsoft::testing::actuated(4).unwrap();
    Param::POISSON_RATIO.set(&mut case.model, 0.0).unwrap();
    case.groups = vec![diffsoft::testing::Group::Scalar(Param::POISSON_RATIO)];
    assert_passes(&case);
    let c = check_case(&case, 7);
    let curve = &c.modes[0].groups[0].v_curve;
    assert!(!curve.is_empty() && curve.iter().all(|p| p.one_sided), "{curve:?}");
}

#[test]
fn bridgesus_material_gradients_match_finite_differences() {
    let mut case = diffsoft::testing::bridgesus(
        &crate::common::root().join("verification/paper/bridgesus/bridgesus.json"),
        3,
    )
    .unwrap();
    case.settings.max_iterations = 10;
    assert_passes(&case);
}

/// With the forward converged, the implicit and the unrolled gradients agree.
#[test]
fn implicit_matches_unrolled_at_convergence() {
    let mut case = diffsoft::testing::free_body(3).unwrap();
    case.settings.tolerance = 1e-14;
    case.settings.max_iterations = 500;
    let run = |mode| {
        diff::gradient(
            &case.model,
            &case.settings,
            case.steps,
            &case.controls,
            case.loss.as_ref(),
            Options::mode(mode),
        )
        .unwrap()
    };
    let (u, i) = (run(Mode::Unrolled), run(Mode::Implicit));
    for p in [
        Param::YOUNGS_MODULUS,
        Param::POISSON_RATIO,
        Param::DENSITY,
        Param::GRAVITY_Y,
    ] {
        let (a, b) = (p.derivative(&case.model, &u), p.derivative(&case.model, &i));
        assert!(
            (a - b).abs() <= 1e-7 * a.abs().max(b.abs()),
            "{p}: unrolled {a:e} implicit {b:e}"
        );
    }
    // And they differ when the forward is truncated hard (so the test can tell them apart).
    let mut short = case.settings.clone();
    short.tolerance = 0.0;
    short.max_iterations = 2;
    let gu = diff::gradient(
        &case.model,
        &short,
        3,
        &case.controls,
        case.loss.as_ref(),
        Options::mode(Mode::Unrolled),
    )
    .unwrap();
    let gi = diff::gradient(
        &case.model,
        &short,
        3,
        &case.controls,
        case.loss.as_ref(),
        Options::mode(Mode::Implicit),
    )
    .unwrap();
    let (a, b) = (
        Param::YOUNGS_MODULUS.derivative(&case.model, &gu),
        Param::YOUNGS_MODULUS.derivative(&case.model, &gi),
    );
    assert!(
        (a - b).abs() > 1e-6 * a.abs(),
        "truncated: unrolled {a:e} implicit {b:e}"
    );
    // The converged forward is at its fixed points; the truncated one is not, and implicit
    // mode says so, estimating the gap to the run's own derivative (unrolled mode's, at a fixed
    // iteration count) to an order of magnitude (0.4-13 times on other scenes, 33 here).
    assert!(
        i.stats.forward_gap < 1e-8 && i.stats.warnings(case.steps).is_empty(),
        "{:?}",
        i.stats
    );
    assert_eq!(
        u.stats.forward_gap, 0.0,
        "unrolled mode differentiates the iterations run"
    );
    let gap = gi.stats.forward_gap;
    let off = (a - b).abs() / a.abs();
    assert!(
        gap > diff::FORWARD_GAP_WARNING && (gap / 10.0..gap * 100.0).contains(&off),
        "gap {gap:e}, off by {off:e}"
    );
    assert_warns(&gi, 3, "implicit mode differentiates the converged steps");
}

/// Unrolled mode on a forward stopped by its tolerance differentiates the iterations that ran,
/// whose derivative contracts at the iteration's rate and can lag the values the tolerance
/// tests: on bridgesus (10 steps, final barycentre height) the share of a step's adjoint left
/// in its starting guess (`unrolled_leftover`) estimates how far the gradient's components are
/// from the converged steps' derivative. Measured against implicit mode on a forward converged
/// to 1e-12 (itself within 4e-10 of a fixed 3000 iterations per step): 0.5-2 times the largest
/// component error at tolerances 1e-6 to 1e-12 (docs/gradients.md). The bounds below leave a
/// factor of 5 either way, an order-of-magnitude estimate's tolerance.
#[test]
fn unrolled_leftover_estimates_the_distance_to_the_converged_derivative() {
    let mut case = diffsoft::testing::bridgesus(
        &crate::common::root().join("verification/paper/bridgesus/bridgesus.json"),
        10,
    )
    .unwrap();
    case.settings.max_iterations = 5000;
    let run = |tolerance: f64, max_iterations: usize, mode| {
        let mut s = case.settings.clone();
        s.tolerance = tolerance;
        s.max_iterations = max_iterations;
        diff::gradient(
            &case.model,
            &s,
            case.steps,
            &case.controls,
            case.loss.as_ref(),
            Options::mode(mode),
        )
        .unwrap()
    };
    let reference = run(1e-12, 5000, Mode::Implicit);
    for tolerance in [1e-6, 1e-8] {
        let g = run(tolerance, 5000, Mode::Unrolled);
        let off = initial_state_error(&g, &reference);
        let left = g.stats.unrolled_leftover;
        eprintln!("tolerance {tolerance:e}: leftover {left:e}, components off by {off:e}");
        assert!(
            left > diff::UNROLLED_LEFTOVER_WARNING && (off / 5.0..off * 5.0).contains(&left),
            "tolerance {tolerance:e}: leftover {left:e}, components off by {off:e}"
        );
        assert_warns(&g, case.steps, "unrolled mode differentiates the iterations that ran");
    }
    // Converged tightly, nothing is left and nothing is said; implicit mode and a fixed
    // iteration count (the exact derivative of what ran) report no leftover.
    let tight = run(1e-12, 5000, Mode::Unrolled);
    assert!(
        tight.stats.unrolled_leftover < diff::UNROLLED_LEFTOVER_WARNING,
        "{:?}",
        tight.stats
    );
    assert!(
        tight.stats.warnings(case.steps).is_empty(),
        "{:?}",
        tight.stats.warnings(case.steps)
    );
    assert_eq!(reference.stats.unrolled_leftover, 0.0);
    assert_eq!(run(0.0, 5, Mode::Unrolled).stats.unrolled_leftover, 0.0);
}

/// Implicit mode through contacts between bodies: a box thrown onto a cloth
/// (`verification/scenes/box_on_cloth.json`, in contact from step 2) carries the forward's
/// stopping error into the gradient amplified (20 steps at tolerance 1e-10: the initial-state
/// gradient 8.3e-4 off the converged derivative, 390 times the unweighted gap of 2.1e-6), so
/// `forward_gap` weighs such steps by `PAIR_CONTACT_GAP_WEIGHT` and warns. Reference: implicit
/// mode on a forward converged to 1e-14 (within about 1e-7 of a fixed 6 000 iterations per
/// step, docs/gradients.md). Bounds: the error is a real one (above the warning threshold), and
/// the weighted gap (2.5 times it here; 0.66-140 times over 10-40 steps) is within an order of
/// magnitude of it, as an estimate's tolerance.
#[test]
fn implicit_gradients_through_contacts_between_bodies_warn_of_the_forward_gap() {
    let path = crate::common::root().join("verification/scenes/box_on_cloth.json");
    let scene = diffsoft::scene::load(&path, diffsoft::scene::LoadOptions::default()).unwrap();
    let com_y = loss::CenterOfMass {
        direction: nalgebra::Vector3::y(),
        time_average: false,
        vertices: None,
    };
    let run = |tolerance: f64| {
        let mut s = scene.settings.clone();
        s.tolerance = tolerance;
        s.max_iterations = 20_000;
        diff::gradient(
            &scene.model,
            &s,
            20,
            &Controls::default(),
            &com_y,
            Options::mode(Mode::Implicit),
        )
        .unwrap()
    };
    let reference = run(1e-14);
    let g = run(1e-10);
    let off = initial_state_error(&g, &reference);
    let gap = g.stats.forward_gap;
    eprintln!("box on cloth, tolerance 1e-10: components off by {off:e}, forward_gap {gap:e}");
    assert!(
        off > diff::FORWARD_GAP_WARNING && (off / 5.0..off * 50.0).contains(&gap),
        "off {off:e}, gap {gap:e}"
    );
    assert_warns(&g, 20, "implicit mode differentiates the converged steps");
}

/// What the backward pass does not cover is refused with a clear error, and bad
/// skeleton controls and losses are rejected.
#[test]
fn skeleton_limits_of_the_backward_pass_are_refused_clearly() {
    let path = crate::common::root().join("verification/scenes/baymax_skeleton.json");
    let case = diffsoft::testing::baymax_torques(&path, 2).unwrap();
    let run = |model: &diffsoft::Model, controls: &Controls, l: &dyn loss::Loss, mode| {
        diff::gradient(model, &case.settings, 2, controls, l, Options::mode(mode)).map(|g| g.loss)
    };
    // Unrolled mode through Anderson acceleration (the built-in scene's own setting).
    let with_anderson = diffsoft::scene::load(&path, diffsoft::scene::LoadOptions::default()).unwrap();
    assert!(with_anderson.settings.anderson > 0);
    match diff::gradient(
        &case.model,
        &with_anderson.settings,
        2,
        &case.controls,
        case.loss.as_ref(),
        Options::default(),
    ) {
        Err(DiffError::Unsupported(m)) => assert!(m.contains("Anderson"), "{m}"),
        other => panic!("expected Unsupported, got {:?}", other.map(|g| g.loss)),
    }
    // A torque on the free root, a short torque row, a joint loss on a bone that does not exist.
    let mut t = case.controls.torques.clone().unwrap();
    t[0][0] = 1.0;
    let bad = Controls {
        torques: Some(t),
        ..Controls::default()
    };
    assert!(
        matches!(run(&case.model, &bad, case.loss.as_ref(), Mode::Unrolled), Err(DiffError::Input(m)) if m.contains("one-DoF"))
    );
    let mut t = case.controls.torques.clone().unwrap();
    t[1].pop();
    let bad = Controls {
        torques: Some(t),
        ..Controls::default()
    };
    assert!(matches!(
        run(&case.model, &bad, case.loss.as_ref(), Mode::Unrolled),
        Err(DiffError::Input(_))
    ));
    let l = loss::by_name("joint_angle.tail").unwrap();
    assert!(
        matches!(run(&case.model, &case.controls, l.as_ref(), Mode::Unrolled), Err(DiffError::Input(m)) if m.contains("tail"))
    );
}

/// Through active joint limits: strong shoulder torques drive both arms onto their limits
/// within the first steps, and the gradient with respect to the torques and the initial state
/// still matches finite differences (the limits enter as equality constraints of the reduced
/// step, Eqs. 17-18).
#[test]
fn skeleton_gradients_through_active_joint_limits() {
    let path = crate::common::root().join("verification/scenes/baymax_skeleton.json");
    let mut case = diffsoft::testing::baymax_torques(&path, 6).unwrap();
    let dofs = case.model.skeleton().unwrap().dofs;
    let sk = case.model.skeleton().unwrap();
    let (l, r) = (
        sk.scalar_dof("left_shoulder").unwrap(),
        sk.scalar_dof("right_shoulder").unwrap(),
    );
    let mut rows = vec![vec![0.0; dofs]; case.steps];
    for row in &mut rows {
        row[l] = -400.0;
        row[r] = 400.0;
    }
    case.controls.torques = Some(rows);
    case.groups = vec![
        diffsoft::testing::Group::Torques,
        diffsoft::testing::Group::InitialVelocities,
        diffsoft::testing::Group::Scalar(Param::YOUNGS_MODULUS),
    ];
    // The limits are active at the end of the run.
    let mut sim = diffsoft::solver::Simulator::new(case.model.clone(), case.settings.clone()).unwrap();
    for _ in 0..case.steps {
        sim.set_torque("left_shoulder", Some(-400.0)).unwrap();
        sim.set_torque("right_shoulder", Some(400.0)).unwrap();
        sim.step().unwrap();
    }
    let coords = sim.skeleton().unwrap().coordinates();
    let angle = |name: &str| coords.iter().find(|c| c.0 == name).unwrap().1[0];
    eprintln!("shoulders {} {}", angle("left_shoulder"), angle("right_shoulder"));
    let c = check_case(&case, 11);
    for g in &c.modes[0].groups {
        eprintln!(
            "{}: analytic {:e}, best fd {:e} (step {:e}), rel {:e}",
            g.group, g.analytic, g.fd_best, g.step_best, g.rel_error_best
        );
    }
    assert!(
        (angle("left_shoulder") + 1.2).abs() < 1e-9,
        "left shoulder at {}",
        angle("left_shoulder")
    );
    assert!(
        (angle("right_shoulder") - 1.2).abs() < 1e-9,
        "right shoulder at {}",
        angle("right_shoulder")
    );
    assert_passes(&case);
}

#[test]
fn bad_losses_and_parameters_are_rejected() {
    assert!(matches!(loss::by_name("final_com.w"), Err(DiffError::Input(_))));
    assert!(matches!(loss::by_name("com"), Err(DiffError::Input(_))));
    assert!(matches!("stiffness".parse::<Param>(), Err(DiffError::Input(_))));
    let mut case = diffsoft::testing::free_body(1).unwrap();
    assert!(Param::POISSON_RATIO.set(&mut case.model, 0.5).is_err());
    assert!(Param::DENSITY.set(&mut case.model, -1.0).is_err());
    assert!(Param::YOUNGS_MODULUS.set(&mut case.model, f64::NAN).is_err());
}

/// Losses compose: the gradient of a weighted sum is the weighted sum of gradients.
#[test]
fn losses_compose_linearly() {
    let case = diffsoft::testing::free_body(2).unwrap();
    let a = loss::by_name("final_com.y").unwrap();
    let b = loss::by_name("mean_com.x").unwrap();
    let sum = loss::Sum::default()
        .add(
            2.0,
            loss::CenterOfMass {
                direction: nalgebra::Vector3::y(),
                time_average: false,
                vertices: None,
            },
        )
        .add(
            -0.5,
            loss::CenterOfMass {
                direction: nalgebra::Vector3::x(),
                time_average: true,
                vertices: None,
            },
        );
    let g = |l: &dyn loss::Loss| {
        diff::gradient(&case.model, &case.settings, 2, &case.controls, l, Options::default()).unwrap()
    };
    let (ga, gb, gs) = (g(a.as_ref()), g(b.as_ref()), g(&sum));
    assert!((gs.loss - (2.0 * ga.loss - 0.5 * gb.loss)).abs() < 1e-12);
    for i in 0..case.model.n() {
        let want = ga.v0[i] * 2.0 - gb.v0[i] * 0.5;
        assert!((gs.v0[i] - want).norm() < 1e-10 * (1.0 + want.norm()));
    }
}

/// Baymax with its skeleton: torques, initial state and material through the reduced step.
#[test]
fn skeleton_gradients_match_finite_differences() {
    let case = diffsoft::testing::baymax_torques(
        &crate::common::root().join("verification/scenes/baymax_skeleton.json"),
        4,
    )
    .unwrap();
    let c = check_case(&case, 7);
    for g in &c.modes[0].groups {
        eprintln!(
            "{} / {}: analytic {:e}, best fd {:e} (step {:e}), rel {:e}, slope {:?}",
            c.name, g.group, g.analytic, g.fd_best, g.step_best, g.rel_error_best, g.truncation_slope
        );
    }
    assert!(c.implicit_error.is_none(), "{:?}", c.implicit_error);
    assert_passes(&case);
}

/// Keeping the forward's recordings (all steps, or the first few within a budget) gives the
/// replayed gradient to round-off (a replay warm-starts its decompositions differently).
#[test]
fn stored_recordings_give_the_replayed_gradient() {
    let case = diffsoft::testing::ground_contact(8).unwrap();
    let run = |store_bytes| {
        diff::gradient(
            &case.model,
            &case.settings,
            case.steps,
            &case.controls,
            case.loss.as_ref(),
            Options {
                store_bytes,
                ..Options::default()
            },
        )
        .unwrap()
    };
    let replayed = run(0);
    assert_eq!(replayed.stats.stored_steps, 0);
    let all = run(usize::MAX);
    assert_eq!(all.stats.stored_steps, case.steps);
    let per_step = all.stats.stored_bytes / case.steps;
    let some = run(3 * per_step + per_step / 2);
    assert!(
        some.stats.stored_steps > 0 && some.stats.stored_steps < case.steps,
        "{}",
        some.stats.stored_steps
    );
    for g in [&all, &some] {
        for (a, b) in g.v0.iter().chain(&g.q0).zip(replayed.v0.iter().chain(&replayed.q0)) {
            assert!((a - b).norm() <= 1e-8 * (1.0 + b.norm()), "{a} vs {b}");
        }
        let (a, b) = (
            Param::YOUNGS_MODULUS.derivative(&case.model, g),
            Param::YOUNGS_MODULUS.derivative(&case.model, &replayed),
        );
        assert!((a - b).abs() <= 1e-8 * b.abs(), "{a} vs {b}");
    }
}

/// Baymax with its skeleton on frictional ground: contacts on free vertices inside the
/// reduced step (their impulses feed the next iteration's bone right-hand side).
#[test]
fn skeleton_gradients_in_ground_contact() {
    let case = diffsoft::testing::baymax_ground(
        &crate::common::root().join("verification/scenes/baymax_skeleton.json"),
        6,
    )
    .unwrap();
    let g = diff::gradient(
        &case.model,
        &case.settings,
        case.steps,
        &case.controls,
        case.loss.as_ref(),
        Options::default(),
    )
    .unwrap();
    eprintln!("contact sweeps {} ms {}", g.stats.contact_sweeps, g.stats.contact_ms);
    let c = check_case(&case, 5);
    eprintln!("{:?}", c.error);
    for gr in &c.modes[0].groups {
        eprintln!(
            "{}: analytic {:e}, best fd {:e} (step {:e}), rel {:e}",
            gr.group, gr.analytic, gr.fd_best, gr.step_best, gr.rel_error_best
        );
    }
    // Contacts on free and on bone vertices during the run.
    let mut sim = diffsoft::solver::Simulator::new(case.model.clone(), case.settings.clone()).unwrap();
    let (q, v) = case.controls.initial.clone().unwrap();
    sim.set_state(q, v).unwrap();
    let (mut free, mut rigid) = (0, 0);
    for _ in 0..case.steps {
        let st = sim.step().unwrap();
        free += usize::from(st.contacts > st.bone_contacts);
        rigid += usize::from(st.bone_contacts > 0);
    }
    eprintln!("steps with contacts: free {free}, bone {rigid}");
    assert!(free > 0 && rigid > 0, "contacts: free {free}, bone {rigid}");
    assert_passes(&case);
}

/// With the forward converged, the implicit and the unrolled gradients agree through the
/// skeleton's reduced step too (free fall and on the ground, torques, initial state, material).
#[test]
fn skeleton_implicit_matches_unrolled_at_convergence() {
    let path = crate::common::root().join("verification/scenes/baymax_skeleton.json");
    for mut case in [
        diffsoft::testing::baymax_torques(&path, 3).unwrap(),
        diffsoft::testing::baymax_ground(&path, 6).unwrap(),
    ] {
        case.settings.tolerance = 1e-13;
        case.settings.max_iterations = 1000;
        let run = |mode| {
            diff::gradient(
                &case.model,
                &case.settings,
                case.steps,
                &case.controls,
                case.loss.as_ref(),
                Options::mode(mode),
            )
            .unwrap()
        };
        let (u, i) = (run(Mode::Unrolled), run(Mode::Implicit));
        eprintln!(
            "{}: {} forward iterations, implicit residual {:e}, {} adjoint iterations",
            case.name, u.stats.forward_iterations, i.stats.implicit_residual, i.stats.backward_iterations
        );
        let close = |a: f64, b: f64, what: &str| {
            assert!(
                (a - b).abs() <= 1e-7 * a.abs().max(b.abs()) + 1e-12,
                "{}: {what}: unrolled {a:e} implicit {b:e}",
                case.name
            );
        };
        close(
            Param::YOUNGS_MODULUS.derivative(&case.model, &u),
            Param::YOUNGS_MODULUS.derivative(&case.model, &i),
            "E",
        );
        let dot = |g: &diff::Gradient| {
            g.torques.iter().flatten().map(|x| x * 0.37).sum::<f64>()
                + g.v0.iter().map(|v| v.x - 0.5 * v.y + 0.2 * v.z).sum::<f64>()
        };
        close(dot(&u), dot(&i), "torques and initial velocities");
    }
}

/// A box that starts undeformed meets the tolerance in its first step's first iteration (its
/// first iterate is the fixed point). The forward counts such steps, because unrolled mode
/// differentiates the iterations run: through that one iteration its derivative with respect to
/// the initial shape is off by percents, while implicit mode and a fixed iteration count agree
/// with each other.
#[test]
fn steps_converged_in_one_iteration_are_counted() {
    let case = diffsoft::testing::ground_contact(25).unwrap();
    let u: Vec<f64> = (0..case.model.n() * 3)
        .map(|i| ((i * 7919) % 13) as f64 - 6.0)
        .collect();
    let run = |tolerance: f64, max_iterations: usize, mode: Mode| {
        let mut s = case.settings.clone();
        s.tolerance = tolerance;
        s.max_iterations = max_iterations;
        let g = case.gradient(&s, Options::mode(mode)).unwrap();
        let d: f64 = g.q0.iter().flat_map(|v| v.iter()).zip(&u).map(|(a, b)| a * b).sum();
        (g.stats.one_iteration_steps, d)
    };
    let (n_tol, unrolled_tol) = run(1e-13, 2000, Mode::Unrolled);
    let (_, implicit_tol) = run(1e-13, 2000, Mode::Implicit);
    let (n_fixed, unrolled_fixed) = run(0.0, 100, Mode::Unrolled);
    eprintln!("initial-shape derivative: unrolled (tolerance) {unrolled_tol:e}, implicit {implicit_tol:e}, unrolled (100 iterations) {unrolled_fixed:e}");
    assert_eq!(n_tol, 1, "the first step converges in its first iteration");
    assert_eq!(n_fixed, 0, "with tolerance 0 no step is counted");
    assert!((implicit_tol - unrolled_fixed).abs() <= 1e-6 * implicit_tol.abs());
    assert!(
        (unrolled_tol - implicit_tol).abs() >= 1e-3 * implicit_tol.abs(),
        "the counted step does change the unrolled derivative"
    );
}

/// Implicit mode with contacts: the adjoint fixed point with Anderson mixing (the default)
/// reaches the plain iteration's gradient in fewer iterations.
#[test]
fn anderson_mixing_of_the_contact_adjoint_keeps_the_gradient() {
    let mut case = diffsoft::testing::ground_contact(25).unwrap();
    case.settings.tolerance = 1e-13;
    case.settings.max_iterations = 2000;
    let run = |memory: usize| {
        let opts = Options {
            implicit_anderson: memory,
            implicit_max_iterations: 5000,
            ..Options::mode(Mode::Implicit)
        };
        case.gradient(&case.settings, opts).unwrap()
    };
    let (plain, mixed) = (run(0), run(8));
    eprintln!(
        "adjoint iterations: plain {}, Anderson {}",
        plain.stats.backward_iterations, mixed.stats.backward_iterations
    );
    assert!(mixed.stats.backward_iterations < plain.stats.backward_iterations);
    let params = [
        Param::YOUNGS_MODULUS,
        Param::DENSITY,
        Param::GRAVITY_Y,
        Param::INITIAL_VELOCITY_X,
    ];
    crate::common::assert_params_agree(&case.model, &plain, &mixed, &params, 1e-9, ("plain", "Anderson"));
}
