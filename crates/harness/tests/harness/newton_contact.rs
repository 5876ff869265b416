//! Newton's method with obstacle contacts (`solver: newton`, docs/method.md Eq. S6): the active
//! set reaches the fixed point of the direct projective-dynamics step with contacts (landing,
//! sliding, sticking, frictionless and sticky ground), and implicit-mode gradients through a
//! Newton forward match central differences and the direct solver's.
//!
//! The tests print their measurements (`--nocapture`).

use crate::common::{median, with_solver};
use diffsoft::diff::{self, Mode, Options};
use diffsoft::solver::StepStats;
use diffsoft::{Settings, Simulator, SolverKind};
use diffsoft_harness::gradients;

/// The ground-contact case's box with friction `mu`, run `steps` steps by Newton and by the
/// direct solver at tolerance 1e-12: the largest position difference over the run against the
/// largest displacement, and Newton's and the direct solver's statistics.
fn compare(mu: f64, steps: usize) -> (f64, f64, Vec<StepStats>, Vec<StepStats>) {
    let settings = diffsoft::testing::gradcheck_settings(0.01, 10);
    let model = diffsoft::testing::ground_box(mu).unwrap();
    let mut newton = Simulator::new(model.clone(), with_solver(&settings, SolverKind::Newton, 1e-12, 200)).unwrap();
    let mut direct = Simulator::new(model, with_solver(&settings, SolverKind::Direct, 1e-12, 100_000)).unwrap();
    let q0 = newton.state().q.clone();
    let (mut diff, mut disp) = (0.0f64, 0.0f64);
    let (mut sn, mut sd) = (Vec::new(), Vec::new());
    for _ in 0..steps {
        sn.push(newton.step().unwrap());
        sd.push(direct.step().unwrap());
        for ((a, b), o) in newton.state().q.iter().zip(&direct.state().q).zip(&q0) {
            diff = diff.max((a - b).norm());
            disp = disp.max((b - o).norm());
        }
    }
    (diff, disp, sn, sd)
}

fn summary(name: &str, stats: &[StepStats]) -> f64 {
    let its = median(stats.iter().map(|s| s.iterations as f64).collect());
    eprintln!(
        "{name}: {} steps, median iterations {its}, max {}, all converged {}, steps in contact {}, median {:.3} ms/step",
        stats.len(),
        stats.iter().map(|s| s.iterations).max().unwrap_or(0),
        stats.iter().all(|s| s.converged),
        stats.iter().filter(|s| s.contacts > 0).count(),
        median(stats.iter().map(|s| s.wall_ms).collect()),
    );
    its
}

/// A soft box thrown onto the ground lands, slides and sticks (friction 0.5), slides without
/// friction, and sticks at once on very rough ground: Newton at tolerance 1e-12 stays within
/// 1e-6 of the displacement of the direct solve at 1e-12 on every step, converging on each.
#[test]
fn newton_reaches_the_direct_fixed_point_with_ground_contact() {
    for mu in [0.5, 0.0, 5.0] {
        let (diff, disp, sn, sd) = compare(mu, 40);
        eprintln!("ground mu {mu}: max displacement {disp:.3e} m, Newton - direct {diff:.3e} m");
        summary(&format!("newton mu {mu}"), &sn);
        summary(&format!("direct mu {mu}"), &sd);
        assert!(
            sn.iter().all(|s| s.converged),
            "mu {mu}: a Newton step did not converge"
        );
        assert!(
            sn.iter().filter(|s| s.contacts > 0).count() >= 30,
            "mu {mu}: the box must be in contact"
        );
        assert!(diff <= 1e-6 * disp, "mu {mu}: {diff:.3e} vs {disp:.3e}");
    }
}

/// The ground-contact gradient case (the box lands, slides and sticks) through a Newton
/// forward, with implicit Euler and with BDF2: every parameter group's implicit-mode gradient
/// matches central differences (the harness's step sweep and tolerances), and equals the
/// implicit gradient through a direct forward converged to the same tolerance.
#[test]
fn implicit_gradients_through_newton_with_ground_contact_match_finite_differences() {
    let case = diffsoft::testing::with_newton(diffsoft::testing::ground_contact(25).unwrap());
    check_against_direct(&case);
    // With BDF2, gravity.y is a small derivative (1e-3 of the others, through friction) whose
    // central differences bottom out at 5e-6: the Richardson reference decides.
    check_against_direct(&diffsoft::testing::with_bdf2(case));
}

/// The harness's check of `case`, and the implicit gradient through Newton against the one
/// through a converged direct forward.
fn check_against_direct(case: &diffsoft::testing::Case) {
    let check = gradients::check_case(case, 7);
    eprint!("{}", gradients::checks_table(std::slice::from_ref(&check)));
    assert!(check.error.is_none(), "{:?}", check.error);
    assert_eq!(check.modes.len(), 1);
    let m = &check.modes[0];
    assert_eq!(m.mode, Mode::Implicit);
    for g in &m.groups {
        eprintln!(
            "  {}: analytic {:.9e} fd {:.9e} rel {:.2e}",
            g.group, g.analytic, g.fd_best, g.rel_error_best
        );
    }
    let failed = !check.passes;
    assert!(m.stats.contact_sweeps > 0, "the box must touch the ground");
    // The direct solver's converged forward gives the same gradient.
    let grad = |settings: &Settings| case.gradient(settings, Options::mode(Mode::Implicit)).unwrap();
    let gn = grad(&case.settings);
    let gd = grad(&with_solver(&case.settings, SolverKind::Direct, 1e-12, 100_000));
    let diff_v0 = gn
        .v0
        .iter()
        .zip(&gd.v0)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    let scale = gd.v0.iter().map(|a| a.norm()).fold(0.0, f64::max);
    eprintln!(
        "{}: v0 gradient, Newton - direct {diff_v0:.3e} (largest {scale:.3e})",
        case.name
    );
    assert!(diff_v0 <= 1e-6 * scale, "{diff_v0} vs {scale}");
    let (en, ed): (f64, f64) = (
        gn.youngs_modulus(&case.model).iter().sum(),
        gd.youngs_modulus(&case.model).iter().sum(),
    );
    eprintln!(
        "{}: Young's modulus gradient, Newton {en:.9e}, direct {ed:.9e}",
        case.name
    );
    assert!((en - ed).abs() <= 1e-6 * ed.abs(), "{en} vs {ed}");
    let gy = |g: &diff::Gradient| g.accel.iter().map(|a| a.y).sum::<f64>();
    let (yn, yd) = (gy(&gn), gy(&gd));
    eprintln!(
        "{}: gravity gradient (sum of y), Newton {yn:.9e}, direct {yd:.9e}",
        case.name
    );
    assert!((yn - yd).abs() <= 1e-6 * yd.abs(), "{yn} vs {yd}");
    assert!(!failed, "{}: a group fails", case.name);
}
