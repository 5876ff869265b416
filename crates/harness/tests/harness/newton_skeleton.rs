//! Newton's method with an embedded skeleton (`solver: newton`, docs/method.md Eqs. S7-S9): on
//! the paper's Baymax skeleton it reaches the fixed point of the reduced projective-dynamics
//! step, holds joint limits as the reduced step does, and gives implicit-mode gradients that
//! match central differences and the ones through a converged direct forward (implicit Euler
//! and BDF2).
//!
//! The tests print their measurements (`--nocapture`).

use crate::common::{median, root, with_solver};
use diffsoft::diff::loss::CenterOfMass;
use diffsoft::diff::params::Param;
use diffsoft::diff::{Controls, Gradient, Mode, Options};
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::skeleton::fixed::Fixed;
use diffsoft::skeleton::rotational::Rotational;
use diffsoft::skeleton::BoneSpec;
use diffsoft::solver::Integrator;
use diffsoft::solver::StepStats;
use diffsoft::testing::{Case, Group};
use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Settings, Simulator, SolverKind};
use diffsoft_harness::gradients;
use nalgebra::{Rotation3, Vector3};

/// The paper's Baymax skeleton scene without its ground (through the gradient case's loader).
fn baymax(steps: usize) -> Case {
    diffsoft::testing::baymax_torques(&root().join("verification/paper/baymax/baymax_skeleton.json"), steps).unwrap()
}

/// The `baymax_torques` gradient case (the built-in Baymax scene: named bones, shoulder limits
/// and torques; no ground).
fn baymax_case(steps: usize) -> Case {
    diffsoft::testing::baymax_torques(&root().join("verification/scenes/baymax_skeleton.json"), steps).unwrap()
}

/// Every joint's coordinates by bone name.
type Joints = Vec<(String, Vec<f64>)>;

/// Baymax (no ground) with constant shoulder torques; `steps` steps' statistics and the final
/// positions and joint coordinates.
fn run_baymax(settings: &Settings, steps: usize) -> (Vec<StepStats>, Vec<Vector3<f64>>, Joints) {
    let case = baymax(steps);
    let mut sim = Simulator::new(case.model.clone(), settings.clone()).unwrap();
    // The shoulders (the last two hinges; the free torso has coordinates 0-5).
    sim.set_torque_dof(8, Some(-40.0)).unwrap();
    sim.set_torque_dof(9, Some(25.0)).unwrap();
    let stats: Vec<StepStats> = (0..steps).map(|_| sim.step().unwrap()).collect();
    let sk = sim.skeleton().unwrap().coordinates();
    (stats, sim.state().q.clone(), sk)
}

fn summary(name: &str, stats: &[StepStats]) -> (f64, usize, f64) {
    let its = median(stats.iter().map(|s| s.iterations as f64).collect());
    let max = stats.iter().map(|s| s.iterations).max().unwrap_or(0);
    let ms = median(stats.iter().map(|s| s.wall_ms).collect());
    let cg: usize = stats.iter().map(|s| s.global_iterations).sum();
    let local: f64 = stats.iter().map(|s| s.local_ms).sum();
    let global: f64 = stats.iter().map(|s| s.global_ms).sum();
    eprintln!(
        "{name}: {} steps, median iterations {its}, max {max}, inner iterations {cg}, median {ms:.3} ms/step (local {local:.1} ms, global {global:.1} ms in all), capped solves {}, all converged {}",
        stats.len(),
        stats.iter().map(|s| s.capped_solves).sum::<usize>(),
        stats.iter().all(|s| s.converged)
    );
    (its, max, ms)
}

/// On the paper's Baymax skeleton (free torso, four hinges, shoulder torques), Newton and the
/// direct reduced step, both to 1e-12, end a few steps at the same positions and joints.
#[test]
fn newton_reaches_the_reduced_step_fixed_point_on_baymax() {
    let steps = 5;
    let base = baymax(steps).settings;
    let q0 = baymax(steps).model.rest().to_vec();
    let (sn, qn, jn) = run_baymax(&with_solver(&base, SolverKind::Newton, 1e-12, 200), steps);
    let (sd, qd, jd) = run_baymax(&with_solver(&base, SolverKind::Direct, 1e-12, 100_000), steps);
    summary("baymax newton 1e-12", &sn);
    summary("baymax direct 1e-12", &sd);
    assert!(sn.iter().chain(&sd).all(|s| s.converged));
    let disp = qd.iter().zip(&q0).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    let diff = qn.iter().zip(&qd).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    eprintln!(
        "baymax: max displacement {disp:.6e}, max Newton - direct {diff:.3e} (rel {:.2e})",
        diff / disp
    );
    assert!(diff <= 1e-6 * disp, "{diff} vs displacement {disp}");
    for ((name, a), (_, b)) in jn.iter().zip(&jd) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= 1e-6 * (1.0 + y.abs()), "{name}: {a:?} vs {b:?}");
        }
    }
    assert!(sn.iter().all(|s| s.bone_length_error < 1e-12));
}

/// Newton against the direct reduced step per step on Baymax at tolerances 1e-8 and 1e-10
/// (measurements; both must converge).
#[test]
fn measure_newton_against_direct_on_baymax() {
    let steps = 20;
    let base = baymax(steps).settings;
    for tol in [1e-8, 1e-10] {
        let (sn, qn, _) = run_baymax(&with_solver(&base, SolverKind::Newton, tol, 200), steps);
        let (sd, qd, _) = run_baymax(&with_solver(&base, SolverKind::Direct, tol, 100_000), steps);
        let (_, _, msn) = summary(&format!("baymax newton {tol:e}"), &sn);
        let (_, _, msd) = summary(&format!("baymax direct {tol:e}"), &sd);
        let diff = qn.iter().zip(&qd).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        eprintln!(
            "tolerance {tol:e}: direct / Newton time per step {:.2}, max position difference {diff:.2e}",
            msd / msn
        );
        assert!(sn.iter().chain(&sd).all(|s| s.converged));
    }
}

const G: f64 = 9.81;
const PIVOT: Vector3<f64> = Vector3::new(0.0, 0.1, 0.0);

/// A stiff 0.1 m block whose top face is a bone on a hinge about `z` through [`PIVOT`], with
/// the hinge's limits, displaced rigidly by `angle` (the hinge at that angle); the model and the
/// displaced positions.
fn hinge_model(limits: (f64, f64), angle: f64) -> (diffsoft::Model, Vec<Vector3<f64>>) {
    hinge_model_with(limits, angle, false)
}

/// [`hinge_model`], with `actuated` a pneumatic group on the block's lower half (active at 1.2)
/// and a muscle group along x on its upper half (at 0.5).
fn hinge_model_with(limits: (f64, f64), angle: f64, actuated: bool) -> (diffsoft::Model, Vec<Vector3<f64>>) {
    let mesh = BoxSpec::new([2, 2, 2], [0.1; 3])
        .origin([-0.05, -0.1, -0.05])
        .build()
        .unwrap();
    let top: Vec<usize> = (0..mesh.num_vertices())
        .filter(|&i| mesh.vertices[i].y > -1e-9)
        .collect();
    let mut body = BodySpec::new(
        "bob",
        mesh,
        Material {
            youngs_modulus: 1e6,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(1000.0),
    );
    if actuated {
        use diffsoft::actuator::{centroid, ActuatorSpec};
        let m = &body.mesh;
        let lower: Vec<usize> = (0..m.num_tets()).filter(|&t| centroid(m, t).y < -0.05).collect();
        let upper: Vec<usize> = (0..m.num_tets()).filter(|&t| centroid(m, t).y >= -0.05).collect();
        body.actuators = vec![
            ActuatorSpec::pneumatic("inflate", &lower, 5e5, diffsoft::Schedule::constant(1.2)),
            ActuatorSpec::muscle(
                "contract",
                upper.iter().map(|&t| (t, Vector3::x())).collect(),
                5e5,
                diffsoft::Schedule::constant(0.5),
            ),
        ];
    }
    let mut hinge = Rotational::new(PIVOT, Vector3::z());
    hinge.limits = Some(limits);
    hinge.angle = angle;
    body.bones = vec![
        BoneSpec {
            name: "base".into(),
            parent: None,
            joint: Box::new(Fixed),
            vertices: vec![],
            torque: None,
        },
        BoneSpec {
            name: "hinge".into(),
            parent: Some(0),
            joint: Box::new(hinge),
            vertices: top,
            torque: None,
        },
    ];
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -G, 0.0))
        .body(body)
        .build()
        .unwrap();
    let rot = Rotation3::from_axis_angle(&Vector3::z_axis(), angle);
    let q0: Vec<_> = model.rest().iter().map(|x| PIVOT + rot * (x - PIVOT)).collect();
    (model, q0)
}

/// [`hinge_model`] at rest in a simulator.
fn hinged_block(limits: (f64, f64), angle: f64, settings: Settings) -> Simulator {
    let (model, q0) = hinge_model(limits, angle);
    let n = model.n();
    let mut sim = Simulator::new(model, settings).unwrap();
    sim.set_state(q0, vec![Vector3::zeros(); n]).unwrap();
    sim.set_joint_coordinates("hinge", &[angle]).unwrap();
    sim
}

/// Released at 0.3 rad with limits [-0.2, 0.35], the hinge swings down to -0.2 and rests
/// against it; Newton (the limit as an active set) follows the direct reduced step (the limit
/// as a bound on the increment) step by step, to the same angles and positions.
#[test]
fn newton_holds_joint_limits_like_the_reduced_step() {
    let settings = |solver, max_iterations| Settings {
        dt: 1e-3,
        solver,
        tolerance: 1e-11,
        max_iterations,
        ..Settings::default()
    };
    let mut sn = hinged_block((-0.2, 0.35), 0.3, settings(SolverKind::Newton, 200));
    let mut sd = hinged_block((-0.2, 0.35), 0.3, settings(SolverKind::Direct, 100_000));
    let (mut lowest, mut worst, mut at_limit) = (f64::INFINITY, 0.0f64, 0);
    let mut stats = Vec::new();
    for _ in 0..400 {
        let a = sn.step().unwrap();
        let b = sd.step().unwrap();
        assert!(a.converged && b.converged);
        stats.push(a);
        let an = sn.skeleton().unwrap().bones[1].joint.coordinates()[0];
        let ad = sd.skeleton().unwrap().bones[1].joint.coordinates()[0];
        assert!((-0.2 - 1e-12..=0.35 + 1e-12).contains(&an), "angle {an}");
        lowest = lowest.min(an);
        at_limit += usize::from(an == -0.2);
        let dq = sn
            .state()
            .q
            .iter()
            .zip(&sd.state().q)
            .map(|(x, y)| (x - y).norm())
            .fold(0.0, f64::max);
        worst = worst.max(dq).max((an - ad).abs() * 0.1);
    }
    summary("hinge with limits, newton 1e-11", &stats);
    eprintln!("hinge: lowest angle {lowest}, steps at the limit {at_limit}, max Newton - direct {worst:.2e} m");
    assert!((lowest + 0.2).abs() < 1e-9, "reached {lowest}");
    assert!(at_limit > 10, "{at_limit} steps at the limit");
    assert!(worst < 1e-7, "{worst}");
}

/// The implicit-mode gradient through a Newton forward of `case`, checked group by group
/// against central differences (rtol 1e-5), and against the implicit gradient through a
/// converged direct forward.
fn gradients_through_newton(mut case: Case, label: &str) {
    case.settings.solver = SolverKind::Newton;
    case.settings.tolerance = 1e-12;
    case.settings.max_iterations = 200;
    let grad = |settings: &Settings| -> Gradient { case.gradient(settings, Options::mode(Mode::Implicit)).unwrap() };
    let g = grad(&case.settings);
    for (k, group) in case.groups.iter().enumerate() {
        let c = gradients::check_group(&case, group, &g, 7 + k as u64).unwrap();
        eprintln!(
            "{label} {}: analytic {:.9e}, central difference {:.9e} (step {:.0e}), rel {:.2e}",
            c.group, c.analytic, c.fd_best, c.step_best, c.rel_error_best
        );
        assert!(c.rel_error_best <= 1e-5, "{}: {} vs {}", c.group, c.analytic, c.fd_best);
    }
    // The same converged steps through the direct reduced step give the same gradient.
    let d = grad(&with_solver(&case.settings, SolverKind::Direct, 1e-12, 100_000));
    let rel = |a: &[f64], b: &[f64]| {
        let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(f64::MIN_POSITIVE);
        a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
    };
    let flat3 = |v: &[Vector3<f64>]| v.iter().flat_map(|x| x.iter().copied()).collect::<Vec<f64>>();
    let flat = |v: &[Vec<f64>]| v.iter().flatten().copied().collect::<Vec<f64>>();
    let pairs = [
        ("q0", rel(&flat3(&g.q0), &flat3(&d.q0))),
        ("v0", rel(&flat3(&g.v0), &flat3(&d.v0))),
        ("torques", rel(&flat(&g.torques), &flat(&d.torques))),
        ("joints0", rel(&g.joints0, &d.joints0)),
        ("w_rot", rel(&g.w_rot, &d.w_rot)),
        ("w_vol", rel(&g.w_vol, &d.w_vol)),
        ("mass", rel(&g.mass, &d.mass)),
    ];
    eprintln!(
        "{label}: Newton forward {} iterations, direct forward {} iterations; loss {:.12e} vs {:.12e}",
        g.stats.forward_iterations, d.stats.forward_iterations, g.loss, d.loss
    );
    for (name, r) in pairs {
        eprintln!("{label}: implicit gradient through Newton vs direct, {name}: max difference / max {r:.2e}");
        assert!(r <= 1e-6, "{name}: {r}");
    }
}

/// Baymax with its skeleton and shoulder torques (the `baymax_torques` gradient case, 3 steps),
/// implicit Euler.
#[test]
fn implicit_gradients_through_newton_with_a_skeleton_match_finite_differences() {
    gradients_through_newton(baymax_case(3), "baymax_torques");
}

/// The same with BDF2 (its first step is implicit Euler).
#[test]
fn implicit_gradients_through_newton_with_a_skeleton_under_bdf2() {
    let mut case = baymax_case(3);
    case.settings.integrator = Integrator::Bdf2;
    gradients_through_newton(case, "baymax_torques bdf2");
}

/// The error of Newton's iterate after `k` iterations of one Baymax step (the third, with the
/// body deformed and the arms moving), against the converged step: it falls superlinearly (the
/// bones' curvature term keeps the reduced Hessian exact).
#[test]
fn newton_with_a_skeleton_converges_superlinearly() {
    let base = baymax(3).settings;
    let at = |max_iterations: usize| -> Vec<Vector3<f64>> {
        let s = with_solver(&base, SolverKind::Newton, 1e-15, max_iterations);
        let case = baymax(3);
        let mut sim = Simulator::new(case.model.clone(), with_solver(&base, SolverKind::Newton, 1e-13, 200)).unwrap();
        sim.set_torque_dof(8, Some(-40.0)).unwrap();
        sim.set_torque_dof(9, Some(25.0)).unwrap();
        sim.step().unwrap();
        sim.step().unwrap();
        let (q, v) = (sim.state().q.clone(), sim.state().v.clone());
        let joints = sim.skeleton_state().unwrap();
        let mut sim2 = Simulator::new(case.model.clone(), s).unwrap();
        sim2.set_torque_dof(8, Some(-40.0)).unwrap();
        sim2.set_torque_dof(9, Some(25.0)).unwrap();
        sim2.set_state(q, v).unwrap();
        sim2.set_skeleton_state(&joints).unwrap();
        sim2.set_clock(sim.state().time, 2);
        sim2.step().unwrap();
        sim2.state().q.clone()
    };
    let reference = at(40);
    let errors: Vec<f64> = (1..=6)
        .map(|k| {
            at(k)
                .iter()
                .zip(&reference)
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max)
        })
        .collect();
    eprintln!(
        "baymax step 3, Newton error after k = 1..6 iterations: {:?}",
        errors.iter().map(|e| format!("{e:.2e}")).collect::<Vec<_>>()
    );
    // Superlinear: from the second iteration on, each step gains more than 20x, and the gain
    // grows (the forcing term tightens as the gradient falls).
    let ratio = |k: usize| errors[k + 1] / errors[k];
    assert!((1..4).all(|k| ratio(k) < 0.05), "{errors:?}");
    assert!(ratio(2) < ratio(1) && ratio(3) < ratio(2), "{errors:?}");
}

/// A hinge swinging from 1 rad at a large time step (0.05 s, the block's `g h^2 / d` is 0.5):
/// there the bones' curvature term matters (without it, Gauss-Newton, the median was 13.5
/// iterations instead of 9), and the direct reduced step needs thousands of iterations. Both
/// end at the same positions.
#[test]
fn a_hinge_at_a_large_time_step() {
    let settings = |solver, max_iterations| Settings {
        dt: 0.05,
        solver,
        tolerance: 1e-12,
        max_iterations,
        ..Settings::default()
    };
    let mut sn = hinged_block((-3.0, 3.0), 1.0, settings(SolverKind::Newton, 200));
    let mut sd = hinged_block((-3.0, 3.0), 1.0, settings(SolverKind::Direct, 100_000));
    let (mut stn, mut stdir) = (Vec::new(), Vec::new());
    for _ in 0..20 {
        stn.push(sn.step().unwrap());
        stdir.push(sd.step().unwrap());
    }
    let (its, _, _) = summary("hinge dt 0.05, newton 1e-12", &stn);
    summary("hinge dt 0.05, direct 1e-12", &stdir);
    let dq = sn
        .state()
        .q
        .iter()
        .zip(&sd.state().q)
        .map(|(x, y)| (x - y).norm())
        .fold(0.0, f64::max);
    eprintln!("hinge dt 0.05: max Newton - direct {dq:.2e} m");
    assert!(stn.iter().chain(&stdir).all(|s| s.converged));
    assert!(its <= 12.0, "median {its} Newton iterations");
    assert!(dq < 1e-8, "{dq}");
}

/// A hinge held at its limit by a torque pushing beyond it (the limit active in every step):
/// the implicit gradient through Newton (the limit in its active set) matches central
/// differences and the one through the direct reduced step (the limit as a bound).
#[test]
fn implicit_gradients_through_newton_at_an_active_joint_limit() {
    let steps = 4;
    let (model, q0) = hinge_model((-0.2, 0.35), -0.2);
    let n = model.n();
    let case = Case {
        name: "hinge_at_limit".into(),
        description: "a hinged block pushed against its limit".into(),
        model,
        settings: Settings {
            dt: 0.01,
            solver: SolverKind::Newton,
            tolerance: 1e-12,
            max_iterations: 200,
            ..Settings::default()
        },
        steps,
        loss: Box::new(CenterOfMass {
            direction: Vector3::new(1.0, 0.3, 0.0),
            time_average: false,
            vertices: None,
        }),
        controls: Controls {
            initial: Some((q0, vec![Vector3::new(0.05, 0.0, 0.02); n])),
            torques: Some(vec![vec![-3.0]; steps]),
            ..Controls::default()
        },
        groups: vec![
            Group::InitialPositions,
            Group::InitialVelocities,
            Group::Scalar(Param::YOUNGS_MODULUS),
            Group::Scalar(Param::DENSITY),
            Group::Scalar(Param::GRAVITY_Y),
        ],
    };
    // The limit holds the hinge in every step.
    let mut sim = Simulator::new(case.model.clone(), case.settings.clone()).unwrap();
    let (q, v) = case.controls.initial.clone().unwrap();
    sim.set_state(q, v).unwrap();
    for _ in 0..steps {
        sim.set_torque_dof(0, Some(-3.0)).unwrap();
        assert!(sim.step().unwrap().converged);
        assert_eq!(sim.skeleton().unwrap().bones[1].joint.coordinates()[0], -0.2);
    }
    gradients_through_newton(case, "hinge at its limit");
}

/// The built-in Baymax without its ground (named bones, shoulder torques ramping to 20 N m,
/// shoulder limits): over 80 steps the arms swing up to their limits and rest there; Newton
/// and the direct reduced step, both to 1e-10, follow the same trajectory.
#[test]
fn shoulder_torques_lift_the_arms_to_their_limits_under_newton() {
    let case = baymax_case(1);
    let run = |solver, max_iterations| {
        let settings = with_solver(&case.settings, solver, 1e-10, max_iterations);
        let mut sim = Simulator::new(case.model.clone(), settings).unwrap();
        let mut stats = Vec::new();
        let mut at_limit = 0;
        for _ in 0..80 {
            stats.push(sim.step().unwrap());
            let sk = sim.skeleton().unwrap();
            let angle = |name: &str| sk.bones.iter().find(|b| b.name == name).unwrap().joint.coordinates()[0];
            at_limit +=
                usize::from(angle("left_shoulder") < -1.2 + 1e-9) + usize::from(angle("right_shoulder") > 1.2 - 1e-9);
            assert!(angle("left_shoulder") >= -1.2 && angle("right_shoulder") <= 1.2);
        }
        (stats, sim.state().q.clone(), at_limit)
    };
    let (sn, qn, ln) = run(SolverKind::Newton, 200);
    let (sd, qd, ld) = run(SolverKind::Direct, 100_000);
    summary("baymax arms, newton 1e-10", &sn);
    summary("baymax arms, direct 1e-10", &sd);
    let diff = qn.iter().zip(&qd).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    eprintln!("baymax arms: joint-steps at a limit {ln} (direct {ld}), max Newton - direct {diff:.2e}");
    assert!(sn.iter().chain(&sd).all(|s| s.converged));
    assert!(ln > 20 && ln == ld, "{ln} vs {ld}");
    assert!(diff < 1e-6, "{diff}");
}

/// An actuated body on a skeleton (pneumatic and muscle groups on the hinged block, the
/// unprojected Hessian then applies the actuators' exact linearization): Newton follows the
/// direct reduced step.
#[test]
fn newton_with_a_skeleton_runs_actuated_bodies_like_the_direct_step() {
    let run = |solver, max_iterations| {
        let (model, q0) = hinge_model_with((-0.5, 0.5), 0.3, true);
        let n = model.n();
        let settings = Settings {
            dt: 0.005,
            solver,
            tolerance: 1e-11,
            max_iterations,
            ..Settings::default()
        };
        let mut sim = Simulator::new(model, settings).unwrap();
        sim.set_state(q0, vec![Vector3::zeros(); n]).unwrap();
        let stats: Vec<StepStats> = (0..40).map(|_| sim.step().unwrap()).collect();
        (stats, sim.state().q.clone())
    };
    let (sn, qn) = run(SolverKind::Newton, 200);
    let (sd, qd) = run(SolverKind::Direct, 100_000);
    summary("actuated hinge, newton 1e-11", &sn);
    summary("actuated hinge, direct 1e-11", &sd);
    let diff = qn.iter().zip(&qd).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    eprintln!("actuated hinge: max Newton - direct {diff:.2e} m");
    assert!(sn.iter().chain(&sd).all(|s| s.converged));
    assert!(diff < 1e-8, "{diff}");
}
