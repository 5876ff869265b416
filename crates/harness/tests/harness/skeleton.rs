//! Embedded skeletons: joint and chain Jacobians against dual numbers and finite differences,
//! the angle and root updates, rigid bones during simulation, a rigid pendulum's period, and
//! skeleton input (paper "Bones" lists, diffsoft scenes, errors).

use crate::common::{cube_scene, root, tmp_dir};
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::scene::{self, LoadOptions};
use diffsoft::skeleton::fixed::Fixed;
use diffsoft::skeleton::free::Free;
use diffsoft::skeleton::prismatic::Prismatic;
use diffsoft::skeleton::rotational::Rotational;
use diffsoft::skeleton::{BoneSpec, Joint};
use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Settings, Simulator, SolverKind};
use diffsoft_harness::jacobians::{self, check_jacobian, check_joint, random_chain};
use nalgebra::{Rotation3, Vector3};
use proptest::prelude::*;
use proptest::test_runner::FileFailurePersistence;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

fn unit(v: [f64; 3]) -> Vector3<f64> {
    let v = Vector3::from(v);
    if v.norm() < 1e-3 {
        Vector3::z()
    } else {
        v.normalize()
    }
}

fn assert_pass(checks: &[diffsoft_harness::jacobians::JacobianCheck]) -> Result<(), TestCaseError> {
    for c in checks {
        prop_assert!(
            c.pass(),
            "{} at {}: dual {:?}, fd {:?}",
            c.name,
            c.configuration,
            c.versus_dual,
            c.versus_fd
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 48,
        failure_persistence: Some(Box::new(FileFailurePersistence::Direct("tests/regressions/skeleton.txt"))),
        ..ProptestConfig::default()
    })]

    /// Every column of `B` of mixed chains 4-7 joints deep, at random configurations, with
    /// angles at `+-pi` and prismatic extensions up to 1e3.
    #[test]
    fn chain_jacobians_match_duals_and_differences(seed in any::<u64>(), depth in 4usize..8, near_pi in any::<bool>(), long in any::<bool>()) {
        let sk = random_chain(depth, &mut ChaCha8Rng::seed_from_u64(seed), near_pi, long);
        prop_assert!(sk.dofs == 6 + depth);
        assert_pass(&check_jacobian(&sk, "B", "random chain"))?;
    }

    /// `dA/dz` of each joint type at random configurations.
    #[test]
    fn joint_derivatives_match_duals_and_differences(
        angle in prop_oneof![-PI..PI, Just(PI - 1e-9), Just(-PI + 1e-9), Just(PI)],
        extension in prop_oneof![-1.0f64..1.0, -1e6f64..1e6],
        axis in prop::array::uniform3(-1.0f64..1.0),
        position in prop::array::uniform3(-3.0f64..3.0),
        rotation in prop::array::uniform3(-1.8f64..1.8),
        translation in prop::array::uniform3(-1e3f64..1e3),
    ) {
        let mut r = Rotational::new(Vector3::from(position), unit(axis));
        r.angle = angle;
        assert_pass(&check_joint(&r, "rotational", "random", 1.0))?;
        let mut p = Prismatic::new(unit(axis));
        p.extension = extension;
        assert_pass(&check_joint(&p, "prismatic", "random", 1.0))?;
        let f = Free {
            rotation: *Rotation3::from_scaled_axis(Vector3::from(rotation)).matrix(),
            translation: Vector3::from(translation),
        };
        assert_pass(&check_joint(&f, "free", "random", 1.0))?;
    }

    /// Eq. 35: the updated angle stays in `(-pi, pi]` and the transform equals the rotation by
    /// `atan(dz)`, across the cut as anywhere else.
    #[test]
    fn angle_update_stays_on_the_circle(angle in -PI..PI, inc in -50.0f64..50.0) {
        let mut r = Rotational::new(Vector3::new(0.1, 0.2, 0.3), unit([0.2, -0.5, 0.8]));
        r.angle = angle;
        let expected = r.transform_at(angle + inc.atan());
        r.update(&[inc]);
        prop_assert!(r.angle > -PI && r.angle <= PI, "{}", r.angle);
        prop_assert!((r.transform() - expected).amax() < 1e-12);
    }
}

#[test]
fn the_jacobians_report_passes_and_shows_second_order_differences() {
    let report = jacobians::run(2021);
    for v in &report.verdicts {
        assert!(v.holds, "{}: {:?}", v.claim, v.measured);
    }
    // Central differences converge at order 2 wherever the map is not linear in z: every
    // rotational and free-joint check (prismatic columns are exact at any step).
    for c in &report.checks {
        let rotation_of_root = ["dA/dz_0", "dA/dz_1", "dA/dz_2"]
            .iter()
            .any(|k| c.name == format!("free root: {k}"));
        if c.name.starts_with("rotational") || rotation_of_root {
            assert!(
                (c.sweep.truncation_slope - 2.0).abs() < 0.3,
                "{} at {}: slope {}",
                c.name,
                c.configuration,
                c.sweep.truncation_slope
            );
        }
    }
    assert!(report.root_update.max_orthogonality_error < 1e-12);
    assert!(report.root_update.max_det_error < 1e-12);
    assert!(report.angle_wrap.iter().all(|a| a.pass));
}

#[test]
fn root_updates_stay_rotations_and_angles_wrap() {
    let mut f = Free::default();
    for k in 0..500 {
        let w = Vector3::new((k as f64).sin(), (2.0 * k as f64).cos(), 0.3) * 0.9;
        f.update(&[w.x, w.y, w.z, 1e3, -1e3, 5.0]);
        assert!((f.rotation.transpose() * f.rotation - nalgebra::Matrix3::identity()).amax() < 1e-12);
        assert!((f.rotation.determinant() - 1.0).abs() < 1e-12);
    }
    let mut r = Rotational::new(Vector3::zeros(), Vector3::z());
    r.angle = PI - 1e-3;
    r.update(&[2e-3]);
    assert!(r.angle < -PI + 2e-3 && r.angle > -PI, "wrapped to {}", r.angle);
}

#[test]
fn bone_vertices_keep_their_rest_distances_in_a_simulation() {
    let sc = scene::load(
        root().join("verification/scenes/baymax_skeleton.json"),
        LoadOptions::default(),
    )
    .unwrap();
    let sk = sc.model.skeleton().expect("bones");
    assert_eq!(sk.bones.len(), 5);
    assert_eq!(sk.dofs, 6 + 4);
    let mut sim = Simulator::new(sc.model, sc.settings).unwrap();
    let (mut worst, mut pen, mut contacts) = (0.0f64, 0.0f64, 0);
    for _ in 0..300 {
        let s = sim.step().unwrap();
        worst = worst.max(s.bone_length_error);
        pen = pen.max(s.max_penetration);
        contacts = contacts.max(s.contacts);
        let sk = sim.skeleton().unwrap();
        for b in &sk.bones {
            if let (Some(c), Some("left_shoulder" | "right_shoulder")) = (b.joint.scalar(), Some(b.name.as_str())) {
                assert!(c.abs() <= 1.2 + 1e-12, "{} at {c} beyond its limit", b.name);
            }
        }
    }
    // Bones keep their shape to round-off (Baymax is ~3 units tall); the arms rest against
    // their limits while the body settles on the ground, and limits never push bone vertices
    // into the ground (they are solved together with the contacts).
    assert!(worst < 1e-12, "bone length error {worst}");
    assert!(
        contacts > 20 && pen < 1e-8,
        "penetration {pen} with up to {contacts} contacts"
    );
    assert!(sim.certificate().used == SolverKind::Direct);
}

const G: f64 = 9.81;
const PIVOT: Vector3<f64> = Vector3::new(0.0, 0.1, 0.0);

/// A stiff 0.1 m block whose top face is a bone on a hinge about `z` through [`PIVOT`].
fn hinged_block(limits: Option<(f64, f64)>) -> diffsoft::Model {
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
    let mut hinge = Rotational::new(PIVOT, Vector3::z());
    hinge.limits = limits;
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
    ModelBuilder::new()
        .gravity(Vector3::new(0.0, -G, 0.0))
        .body(body)
        .build()
        .unwrap()
}

/// `model` displaced rigidly by `angle` about the hinge, at rest.
fn displaced(model: diffsoft::Model, angle: f64, h: f64) -> Simulator {
    let rot = Rotation3::from_axis_angle(&Vector3::z_axis(), angle);
    let q0: Vec<_> = model.rest().iter().map(|x| PIVOT + rot * (x - PIVOT)).collect();
    let n = model.n();
    let settings = Settings {
        dt: h,
        solver: SolverKind::Direct,
        tolerance: 1e-8,
        max_iterations: 200,
        ..Settings::default()
    };
    let mut sim = Simulator::new(model, settings).unwrap();
    sim.set_state(q0, vec![Vector3::zeros(); n]).unwrap();
    sim.set_joint_coordinates("hinge", &[angle]).unwrap();
    sim
}

/// A stiff block hanging from a rotational joint at its top face swings with the period of
/// the rigid physical pendulum `2 pi sqrt(I / (m g d))` (from the lumped masses).
#[test]
fn a_stiff_body_on_a_hinge_swings_like_a_rigid_pendulum() {
    let (g, pivot) = (G, PIVOT);
    let model = hinged_block(None);
    let (mut m, mut i_z, mut md) = (0.0, 0.0, 0.0);
    for (x, mi) in model.rest().iter().zip(model.mass()) {
        let r = x - pivot;
        m += mi;
        i_z += mi * (r.x * r.x + r.y * r.y);
        md += mi * (-r.y);
    }
    let period = 2.0 * PI * (i_z / (g * md)).sqrt();
    let th0: f64 = 0.05;
    let h = 1e-3;
    let mut sim = displaced(model, th0, h);
    let mut angles = Vec::new();
    for _ in 0..3000 {
        let s = sim.step().unwrap();
        assert!(s.converged);
        angles.push(sim.skeleton().unwrap().bones[1].joint.coordinates()[0]);
    }
    // Downward zero crossings, linearly interpolated.
    let crossings: Vec<f64> = (1..angles.len())
        .filter(|&k| angles[k - 1] > 0.0 && angles[k] <= 0.0)
        .map(|k| (k as f64 - 1.0 + angles[k - 1] / (angles[k - 1] - angles[k])) * h)
        .collect();
    assert!(crossings.len() >= 3, "{} crossings", crossings.len());
    let measured = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
    let ratio = measured / period;
    assert!(
        (ratio - 1.0).abs() < 0.02,
        "period {measured} vs rigid {period} (ratio {ratio})"
    );
    // Small amplitude: it swings, it does not fall over or stop.
    let amp = angles[angles.len() - 400..].iter().fold(0.0f64, |a, &x| a.max(x.abs()));
    assert!(amp > 0.5 * th0 && amp < 1.1 * th0, "amplitude {amp}");
}

/// With limits, the hinge stops at them: released at 0.3 rad with limits [-0.2, 0.35], it
/// swings down, reaches -0.2 and never passes it.
#[test]
fn a_hinge_stops_at_its_limit() {
    let mut sim = displaced(hinged_block(Some((-0.2, 0.35))), 0.3, 1e-3);
    let mut lowest = f64::INFINITY;
    for _ in 0..600 {
        let s = sim.step().unwrap();
        assert!(s.converged);
        let a = sim.skeleton().unwrap().bones[1].joint.coordinates()[0];
        assert!((-0.2 - 1e-12..=0.35 + 1e-12).contains(&a), "angle {a}");
        lowest = lowest.min(a);
    }
    assert!((lowest + 0.2).abs() < 1e-9, "reached {lowest}");
}

#[test]
fn paper_bone_lists_import() {
    let sc = scene::load(
        root().join("verification/paper/baymax/baymax_skeleton.json"),
        LoadOptions::default(),
    )
    .unwrap();
    let sk = sc.model.skeleton().expect("bones");
    let kinds: Vec<&str> = sk.bones.iter().map(|b| b.joint.kind()).collect();
    assert_eq!(kinds.iter().filter(|k| **k == "free").count(), 1);
    assert_eq!(kinds.iter().filter(|k| **k == "rotational").count(), 4);
    let fish = scene::load(root().join("verification/paper/fish/fish.json"), LoadOptions::default()).unwrap();
    assert!(fish.model.skeleton().unwrap().bones.len() >= 2);
    // Both take steps with bones held rigid.
    for sc in [sc, fish] {
        let mut sim = Simulator::new(sc.model, sc.settings).unwrap();
        for _ in 0..3 {
            assert!(sim.step().unwrap().bone_length_error < 1e-12);
        }
    }
}

fn bone_scene(dir: &std::path::Path, bones: &str, body_extra: &str) -> std::path::PathBuf {
    cube_scene(
        dir,
        &format!(r#", "density": 1000{body_extra}, "skeleton": {{ "bones": [{bones}] }}"#),
        "",
    )
}

#[test]
fn scene_bones_load_and_bad_bones_are_named() {
    let dir = tmp_dir("bones");
    let root_bone = r#"{"name": "root", "joint": {"free": {}}, "vertices": {"indices": [0, 1]}}"#;
    let ok = bone_scene(
        &dir,
        &format!(
            r#"{root_bone}, {{"name": "arm", "parent": "root", "joint": {{"rotational": {{"position": [0,0,0], "axis": [0,0,1], "limits": [-1, 1]}}}}, "vertices": {{"indices": [4]}}, "torque": {{"times": [0, 1], "values": [0, 2]}}}}"#
        ),
        "",
    );
    let sc = scene::load(&ok, LoadOptions::default()).unwrap();
    assert_eq!(sc.model.skeleton().unwrap().dofs, 7);
    for (bones, extra, expect) in [
        (
            format!(r#"{root_bone}, {{"name": "arm", "parent": "hand", "joint": {{"fixed": {{}}}}}}"#),
            "",
            "no parent bone named 'hand'",
        ),
        (
            format!(r#"{root_bone}, {{"name": "root", "parent": "root", "joint": {{"fixed": {{}}}}}}"#),
            "",
            "two bones are named 'root'",
        ),
        (
            format!(r#"{root_bone}, {{"name": "arm", "parent": "root", "joint": {{"fixed": {{}}}}, "vertices": {{"indices": [1]}}}}"#),
            "",
            "vertex 1 belongs to two bones ('root' and 'arm')",
        ),
        (
            r#"{"name": "root", "joint": {"free": {}}, "vertices": {"indices": [0, 1, 0]}}"#.to_string(),
            "",
            "bone 'root' lists vertex 0 twice",
        ),
        (root_bone.to_string(), r#", "fixed": {"indices": [0]}"#, "vertex 0 is also a fixed"),
        (
            format!(r#"{root_bone}, {{"name": "arm", "parent": "root", "joint": {{"rotational": {{"position": [0,0,0], "axis": [0,0,0]}}}}}}"#),
            "",
            "joint axis must be non-zero",
        ),
        (
            format!(r#"{root_bone}, {{"name": "arm", "parent": "root", "joint": {{"prismatic": {{"axis": [1,0,0], "limits": [2, 1]}}}}}}"#),
            "",
            "limits must be finite with min <= max",
        ),
        (
            format!(r#"{root_bone}, {{"name": "arm", "parent": "root", "joint": {{"rotational": {{"position": [0,0,0], "axis": [0,0,1], "angle": 2, "limits": [-1, 1]}}}}}}"#),
            "",
            "bone 'arm': initial angle 2 rad is outside its limits [-1, 1]",
        ),
        (
            format!(r#"{root_bone}, {{"name": "arm", "parent": "root", "joint": {{"rotational": {{"position": [0,0,0], "axis": [0,0,1], "angle": 1e300}}}}}}"#),
            "",
            "bone 'arm': initial angle 1e300 rad is not a finite value",
        ),
        (
            format!(r#"{root_bone}, {{"name": "arm", "parent": "root", "joint": {{"prismatic": {{"axis": [1,0,0], "extension": -0.5, "limits": [0, 1]}}}}}}"#),
            "",
            "initial extension -0.5 m is outside its limits [0, 1]",
        ),
        (
            format!(r#"{root_bone}, {{"name": "arm", "parent": "root", "joint": {{"hinge": {{}}}}}}"#),
            "",
            "unknown variant `hinge`",
        ),
        (
            format!(r#"{root_bone}, {{"name": "arm", "parent": "root", "joint": {{"fixed": {{}}}}, "torque": {{"times": [1, 0], "values": [0, 1]}}}}"#),
            "",
            "torque",
        ),
        (
            r#"{"name": "a", "parent": "b", "joint": {"fixed": {}}}, {"name": "b", "parent": "a", "joint": {"fixed": {}}}"#.to_string(),
            "",
            "cycle",
        ),
    ] {
        let p = bone_scene(&dir, &bones, extra);
        let e = match scene::load(&p, LoadOptions::default()) {
            Err(e) => e.to_string(),
            Ok(sc) => Simulator::new(sc.model, sc.settings).map(|_| ()).unwrap_err().to_string(),
        };
        assert!(e.contains(expect), "expected '{expect}' in: {e}");
    }
}

#[test]
fn a_body_without_bones_runs_without_the_skeleton_code() {
    let sc = scene::load(
        root().join("verification/scenes/baymax_ground.json"),
        LoadOptions::default(),
    )
    .unwrap();
    assert!(sc.model.skeleton().is_none());
    let mut sim = Simulator::new(sc.model, sc.settings).unwrap();
    let s = sim.step().unwrap();
    assert!(sim.skeleton().is_none());
    assert_eq!(s.bone_length_error, 0.0);
}

#[test]
fn skeleton_scenes_use_the_direct_solver_whatever_is_requested() {
    let mut sc = scene::load(
        root().join("verification/scenes/baymax_skeleton.json"),
        LoadOptions::default(),
    )
    .unwrap();
    for kind in [SolverKind::Plain, SolverKind::Split, SolverKind::Chebyshev] {
        sc.settings.solver = kind;
        let sim = Simulator::new(sc.model.clone(), sc.settings.clone()).unwrap();
        assert_eq!(sim.certificate().used, SolverKind::Direct);
        assert!(sim.certificate().message.contains("skeleton"));
    }
}

#[test]
fn shoulder_torques_lift_the_arms() {
    let sc = scene::load(
        root().join("verification/scenes/baymax_skeleton.json"),
        LoadOptions::default(),
    )
    .unwrap();
    let mut sim = Simulator::new(sc.model, sc.settings).unwrap();
    let mut extreme = (0.0f64, 0.0f64);
    for _ in 0..80 {
        sim.step().unwrap();
        let sk = sim.skeleton().unwrap();
        let angle = |name: &str| sk.bones.iter().find(|b| b.name == name).unwrap().joint.coordinates()[0];
        extreme = (
            extreme.0.min(angle("left_shoulder")),
            extreme.1.max(angle("right_shoulder")),
        );
    }
    let sk = sim.skeleton().unwrap();
    let angle = |name: &str| sk.bones.iter().find(|b| b.name == name).unwrap().joint.coordinates()[0];
    // Left shoulder torque is negative about +z, right positive: the arms rotate up and out
    // to their 1.2 rad limits and stay there.
    assert!(angle("left_shoulder") < -1.0, "left {}", angle("left_shoulder"));
    assert!(angle("right_shoulder") > 1.0, "right {}", angle("right_shoulder"));
    assert!(
        extreme.0 >= -1.2 - 1e-12 && extreme.1 <= 1.2 + 1e-12,
        "limits exceeded: {extreme:?}"
    );
}

/// A hinge held at its upper limit (a sideways pull turns it that way) sits where the loss has
/// a kink (the limit switches between holding and not): the gradient counts those steps and
/// warns. With room to swing the same hinge counts none.
#[test]
fn a_joint_resting_at_its_limit_is_a_counted_kink() {
    use diffsoft::diff::{self, Controls, Mode, Options};
    let settings = Settings {
        dt: 1e-3,
        solver: SolverKind::Direct,
        tolerance: 1e-8,
        max_iterations: 200,
        ..Settings::default()
    };
    let loss = diff::loss::by_name("final_com.x").unwrap();
    let stats = |limits| {
        // Gravity with a sideways part turns the hanging block towards positive angles.
        let mut model = hinged_block(Some(limits));
        let gx: diff::Param = "gravity.x".parse().unwrap();
        gx.set(&mut model, 3.0).unwrap();
        let g = diff::gradient(
            &model,
            &settings,
            20,
            &Controls::default(),
            loss.as_ref(),
            Options::mode(Mode::Unrolled),
        )
        .unwrap();
        g.stats
    };
    let at_limit = stats((-0.2, 0.0));
    assert_eq!(at_limit.joint_limit_steps, 20, "{at_limit:?}");
    assert!(at_limit
        .warnings(20)
        .iter()
        .any(|w| w.contains("joint at one of its limits")));
    let free = stats((-0.2, 0.35));
    assert_eq!(free.joint_limit_steps, 0, "{free:?}");
    // (At tolerance 1e-8 the unrolled gradient's lag behind the converged derivative is
    // warned about too, `unrolled_leftover`; no warning is about a joint limit.)
    assert!(
        !free
            .warnings(20)
            .iter()
            .any(|w| w.contains("joint at one of its limits")),
        "{:?}",
        free.warnings(20)
    );
}

/// `unrolled_leftover` on a skeleton: the hinged block pulled sideways, loss on its joint angle
/// alone (so the whole adjoint enters through the joint), 20 steps stopped by a tolerance. The
/// leftover now counts the joints' share (`|z_0 bar| / |z_N bar|`) beside the free vertices';
/// measured here and on Baymax with its skeleton (30 steps, barycentre and joint-angle losses)
/// the joints' share is 1e-4 to 1e-2 of the free vertices' (docs/gradients.md), so the free
/// vertices set the value. Against implicit mode on a forward converged to 1e-13 the
/// leftover was 0.14-0.28 times the largest component error of the initial-state gradient
/// (tolerances 1e-4 to 1e-8): the bounds leave a factor of 10 (an order-of-magnitude
/// estimate); converged tightly, nothing is left.
#[test]
fn unrolled_leftover_covers_a_skeleton_step() {
    use diffsoft::diff::{self, Controls, Mode, Options};
    let loss = diff::loss::by_name("joint_angle.hinge").unwrap();
    let mut model = hinged_block(None);
    let gx: diff::Param = "gravity.x".parse().unwrap();
    gx.set(&mut model, 3.0).unwrap();
    let run = |tolerance: f64, mode| {
        let settings = Settings {
            dt: 1e-3,
            solver: SolverKind::Direct,
            tolerance,
            max_iterations: 5000,
            ..Settings::default()
        };
        diff::gradient(
            &model,
            &settings,
            20,
            &Controls::default(),
            loss.as_ref(),
            Options::mode(mode),
        )
        .unwrap()
    };
    let reference = run(1e-13, Mode::Implicit);
    for tolerance in [1e-6, 1e-8] {
        let g = run(tolerance, Mode::Unrolled);
        let off = crate::gradients::initial_state_error(&g, &reference);
        let left = g.stats.unrolled_leftover;
        assert!(
            left > diff::UNROLLED_LEFTOVER_WARNING && (off / 10.0..off * 10.0).contains(&left),
            "tolerance {tolerance:e}: leftover {left:e}, components off by {off:e}"
        );
    }
    let tight = run(1e-13, Mode::Unrolled);
    assert!(
        tight.stats.unrolled_leftover < diff::UNROLLED_LEFTOVER_WARNING,
        "{:?}",
        tight.stats
    );
}
