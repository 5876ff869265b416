//! Scene files: the strict diffsoft format, the paper importer, and `diffsoft simulate`.

use crate::common::{cube_scene, root, tmp_dir, write};
use diffsoft::scene::{self, LoadOptions, SceneFormat};
use diffsoft::solver::SolverKind;

fn paper(name: &str) -> std::path::PathBuf {
    root().join("verification/paper").join(name)
}

/// A scratch copy of the directory of paper scene `name` (to edit its files), and the
/// original scene's path.
fn paper_copy(tag: &str, name: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    let dir = tmp_dir(tag);
    let src = paper(name);
    for entry in std::fs::read_dir(src.parent().unwrap()).unwrap() {
        let p = entry.unwrap().path();
        std::fs::copy(&p, dir.join(p.file_name().unwrap())).unwrap();
    }
    (dir, src)
}

#[test]
fn paper_scenes_import_with_the_reference_defaults() {
    let s = scene::load(paper("bridgesus/bridgesus.json"), LoadOptions::default()).unwrap();
    assert_eq!(s.format, SceneFormat::Paper);
    assert_eq!((s.model.n(), s.model.tets().len()), (212, 668));
    assert!((s.settings.dt - 0.005).abs() < 1e-15);
    assert!((s.settings.damping - 0.9999).abs() < 1e-15);
    assert_eq!(
        s.model.fixed().iter().filter(|&&f| f).count(),
        65,
        "65 attach verts at 1e20 become Dirichlet"
    );
    assert!((s.model.bodies()[0].mass - 10.0).abs() < 1e-9, "default Mass 10");
    assert!(s.notes.iter().any(|n| n.contains("Dirichlet")));
    // The bridge has no "Scale": the reference's default 0.05 applies.
    let b = scene::load(paper("bridge/bridge.json"), LoadOptions::default()).unwrap();
    assert!(b.notes.iter().any(|n| n.contains("default 0.05")));
    let (lo, hi) = diffsoft::mesh::TetMesh {
        vertices: b.model.rest().to_vec(),
        tets: vec![],
    }
    .bounding_box();
    assert!(
        ((hi - lo).x - 14.9 * 0.05).abs() < 0.01,
        "scaled by 0.05: {}",
        (hi - lo).x
    );
    // Baymax's ground is a triangle-mesh obstacle.
    let y = scene::load(paper("baymax/baymax.json"), LoadOptions::default()).unwrap();
    assert_eq!(y.model.obstacles().len(), 1);
    assert!((y.settings.dt - 0.01).abs() < 1e-15);
}

#[test]
fn paper_scenes_with_cloth_actuators_and_skeletons_load() {
    // The ball-on-cloth scene: a tet ball, a triangle cloth, contacts between them.
    let cb = scene::load(paper("cloth_ball/cloth_ball.json"), LoadOptions::default()).unwrap();
    let cloth = cb.model.cloth().expect("cloth");
    assert_eq!((cb.model.n(), cb.model.tets().len()), (43 + 81, 80));
    assert_eq!((cloth.bodies.len(), cloth.num_triangles()), (1, 128));
    assert_eq!(cloth.bodies[0].area_density, 3.0);
    assert_eq!(cb.model.attachments().len(), 4);
    let col = cb.model.collision().expect("collisions between bodies");
    assert_eq!(col.names.len(), 2);
    assert!((col.settings.friction - 0.1).abs() < 1e-15);
    assert!(cb.notes.iter().any(|n| n.contains("edge springs")), "{:?}", cb.notes);
    // Actuators are simulated: the drone and the octopus load (crates/harness/tests/harness/actuators.rs).
    for file in ["droneman/droneman.json", "octopus/octopus.json"] {
        assert!(scene::load(paper(file), LoadOptions::default())
            .unwrap()
            .model
            .actuators()
            .is_some());
    }
    // fish.json has a trailing comma (invalid strict JSON): it still parses, with its skeleton.
    let fish = scene::load(paper("fish/fish.json"), LoadOptions::default()).unwrap();
    assert_eq!(fish.model.n(), 759);
    assert_eq!(fish.model.skeleton().map(|s| s.bones.len()), Some(4));
    assert!(fish.notes.iter().any(|n| n.contains("Is underwater")));
}

#[test]
fn diffsoft_scenes_reject_unknown_keys_and_meaningless_values() {
    let dir = tmp_dir("scene-errors");
    let ok = cube_scene(&dir, r#", "density": 1000, "fixed": {"indices": [0]}"#, "");
    let s = scene::load(&ok, LoadOptions::default()).unwrap();
    assert_eq!(s.format, SceneFormat::Diffsoft);
    assert_eq!(s.settings.solver, SolverKind::Auto);
    for (body, top, expect) in [
        (r#", "density": 1000, "colour": "red""#, "", "unknown field `colour`"),
        (
            r#", "density": 1000"#,
            r#", "solver": {"dt": 0.1}"#,
            "the time step is given twice",
        ),
        ("", "", "exactly one of density and total_mass"),
        (
            r#", "density": 1000, "total_mass": 3"#,
            "",
            "exactly one of density and total_mass",
        ),
        (
            r#", "density": -5"#,
            "",
            "density and total mass must be finite and positive (density -5)",
        ),
        (
            r#", "total_mass": -1"#,
            "",
            "density and total mass must be finite and positive (total mass -1, over a volume of",
        ),
        (
            r#", "density": 1000, "fixed": {"indices": [9]}"#,
            "",
            "vertex 9 is not a vertex",
        ),
        (
            r#", "density": 1000, "fixed": {"box": {"min": [5,5,5], "max": [6,6,6]}}"#,
            "",
            "contains no vertex",
        ),
        (
            r#", "density": 1000"#,
            r#", "obstacles": [{"plane": {"point": [0,0,0], "normal": [0,0,0]}, "friction": 0.3}]"#,
            "normal must be non-zero",
        ),
        (
            r#", "density": 1000"#,
            r#", "obstacles": [{"plane": {"point": [0,0,0], "normal": [0,1,0]}, "friction": -1}]"#,
            "friction",
        ),
        // A placement the mesh cannot survive is named, not blamed on an element it collapses.
        (
            r#", "density": 1000, "translate": [1e300, 0, 0]"#,
            "",
            "body 'c': translate 1e300 m is beyond 1e8 times the 1 m size of its mesh",
        ),
        (
            r#", "density": 1000, "rotate": [0, -1e300, 0]"#,
            "",
            "body 'c': rotate component 1e300 rad is beyond 1e6 rad",
        ),
        (
            r#", "density": 1000, "scale": 1e-3, "translate": [0, 2e5, 0]"#,
            "",
            "translate 200000 m is beyond 1e8 times the 0.001 m size",
        ),
    ] {
        let p = cube_scene(&dir, body, top);
        let e = scene::load(&p, LoadOptions::default()).unwrap_err().to_string();
        assert!(
            e.contains("scene.json") && e.contains(expect),
            "expected '{expect}' in: {e}"
        );
    }
    // serde names the line of an unknown key.
    let p = cube_scene(&dir, r#", "density": 1000, "colour": "red""#, "");
    let e = scene::load(&p, LoadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("line 7"), "{e}");
    // A missing mesh names the mesh file.
    let p = write(
        &dir,
        "missing.json",
        r#"{"schema": "diffsoft.scene/1", "time_step": 0.01, "bodies": [{"name": "x", "mesh": "nope.msh", "material": {"youngs_modulus": 1, "poisson_ratio": 0.1}, "density": 1}]}"#,
    );
    let e = scene::load(&p, LoadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("nope.msh"), "{e}");
    // Not a scene at all.
    let p = write(&dir, "other.json", r#"{"hello": 1}"#);
    assert!(scene::load(&p, LoadOptions::default())
        .unwrap_err()
        .to_string()
        .contains("not a scene"));
}

/// A paper scene with a negative friction coefficient is refused, naming the field, even where
/// no contact reads it (the bridge has no collisions).
#[test]
fn paper_scenes_refuse_negative_friction() {
    let (dir, src) = paper_copy("paper-friction", "bridgesus/bridgesus.json");
    let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&src).unwrap()).unwrap();
    v["Friction coefficients"] = serde_json::json!([[-0.1]]);
    let p = write(&dir, "neg.json", &v.to_string());
    let e = scene::load(&p, LoadOptions::default()).unwrap_err().to_string();
    assert!(
        e.contains("\"Friction coefficients\"[0][0] must be finite and >= 0, got -0.1"),
        "{e}"
    );
}

/// Malformed values in a paper scene are refused, naming the key, instead of read as the
/// reference's defaults: a friction coefficient that is not `[[number]]`, a "Parameters" that
/// is not a list of one object, a flag that is not a boolean, a bone parent below -1; a missing
/// "Parameters" is noted with the defaults applied, and friction entries past the first that
/// differ from it are noted as ignored.
#[test]
fn paper_scenes_refuse_malformed_values() {
    use serde_json::json;
    let (dir, src) = paper_copy("paper-malformed", "baymax/baymax.json");
    let base: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&src).unwrap()).unwrap();
    let refused = |name: &str, edit: &dyn Fn(&mut serde_json::Value), want: &str| {
        let mut v = base.clone();
        edit(&mut v);
        let p = write(&dir, name, &v.to_string());
        let e = scene::load(&p, LoadOptions::default()).unwrap_err().to_string();
        assert!(
            e.contains(want) && e.contains(name),
            "{name}: expected '{want}' in: {e}"
        );
    };
    for (k, bad) in [
        json!([0.7]),
        json!(0.7),
        json!([]),
        json!([[]]),
        json!(null),
        json!([["a"]]),
    ]
    .into_iter()
    .enumerate()
    {
        refused(
            &format!("friction{k}.json"),
            &|v| v["Friction coefficients"] = bad.clone(),
            "\"Friction coefficients\" must be a list of lists of numbers",
        );
    }
    for (k, bad) in [json!({}), json!([]), json!([{}, {}])].into_iter().enumerate() {
        refused(
            &format!("params{k}.json"),
            &|v| v["Parameters"] = bad.clone(),
            "\"Parameters\" must be a list of exactly one object",
        );
    }
    for key in ["Handle collision", "Self-collision"] {
        refused(
            "flag.json",
            &|v| v["Parameters"][0][key] = json!("yes"),
            &format!("Parameters[0]: \"{key}\" must be true or false, got \"yes\""),
        );
    }
    refused(
        "mass.json",
        &|v| v["Meshes"][0]["Is Mass Same"] = json!(1),
        "Meshes[0]: \"Is Mass Same\" must be true or false, got 1",
    );
    // A missing "Parameters" runs with the defaults, and says so.
    let mut v = base.clone();
    v.as_object_mut().unwrap().remove("Parameters");
    let sc = scene::load(write(&dir, "noparams.json", &v.to_string()), LoadOptions::default()).unwrap();
    assert!(
        sc.notes.iter().any(|n| n.contains("no \"Parameters\"")),
        "{:?}",
        sc.notes
    );
    // A friction matrix: its first entry is read, and the note says the others are not.
    let mut v = base.clone();
    v["Friction coefficients"] = json!([[0.2, 0.9], [0.9, 0.2]]);
    let sc = scene::load(write(&dir, "matrix.json", &v.to_string()), LoadOptions::default()).unwrap();
    assert!(
        sc.notes
            .iter()
            .any(|n| n.contains("only the first entry (0.2) is read")),
        "{:?}",
        sc.notes
    );
    // A bone whose parent is below -1.
    let (dir, src) = paper_copy("paper-parent", "baymax/baymax_skeleton.json");
    let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&src).unwrap()).unwrap();
    v["Meshes"][0]["Bones"][1]["Parent ID"] = json!(-2);
    let p = write(&dir, "parent.json", &v.to_string());
    let e = scene::load(&p, LoadOptions::default()).unwrap_err().to_string();
    assert!(
        e.contains("Bones[1]: \"Parent ID\" -2 does not name another bone (-1 for the root)"),
        "{e}"
    );
}

/// The octopus scene's load error after `edit` changed the fields of its muscle file's lines
/// (`muscle sample x y z`, one `Vec` per line).
fn octopus_with_muscle_lines(tag: &str, edit: impl FnOnce(&mut [Vec<String>])) -> String {
    let (dir, _) = paper_copy(tag, "octopus/octopus.json");
    let muscle = dir.join("octopus.muscle");
    let text = std::fs::read_to_string(&muscle).unwrap();
    let mut lines: Vec<Vec<String>> = text
        .lines()
        .map(|l| l.split_whitespace().map(String::from).collect())
        .collect();
    edit(&mut lines);
    let text: Vec<String> = lines.iter().map(|l| l.join(" ")).collect();
    std::fs::write(&muscle, text.join("\n")).unwrap();
    scene::load(dir.join("octopus.json"), LoadOptions::default())
        .unwrap_err()
        .to_string()
}

/// A muscle file that gives one muscle's sample number twice (its polyline's order would be
/// open) is refused, naming both lines.
#[test]
fn paper_muscle_files_refuse_repeated_samples() {
    let e = octopus_with_muscle_lines("paper-muscle-repeat", |lines| {
        assert_eq!(lines[0][0], lines[4][0], "lines 1 and 5 are one muscle's");
        lines[4][1] = lines[0][1].clone();
    });
    assert!(
        e.contains("line 5: muscle 0 sample 0 was already given on line 1"),
        "{e}"
    );
}

/// A muscle file's negative muscle or sample number is named on its line, not reported later
/// as a muscle without segments.
#[test]
fn paper_muscle_files_refuse_negative_numbers() {
    let e = octopus_with_muscle_lines("paper-muscle", |lines| lines[0][0] = "-1".into());
    assert!(
        e.contains("line 1: muscle and sample numbers count from 0, got -1"),
        "{e}"
    );
}

/// Initial positions a run is to start from get the obstacle checks the scene's own initial
/// state gets (`check_initial_positions`, `Simulator::set_initial_state`; Python's
/// `set('initial_positions')` runs them before each run): a body pushed into the ground is
/// refused, naming the positions, the body and the obstacle; the same positions lifted clear of
/// it run.
#[test]
fn initial_positions_given_to_a_run_are_checked_like_the_scenes_own() {
    use diffsoft::solver::{check_initial_positions, Simulator};
    use nalgebra::Vector3;
    let case = diffsoft::testing::ground_contact(2).unwrap();
    let v0 = case.model.initial_velocity().to_vec();
    let shifted = |dy: f64| -> Vec<Vector3<f64>> {
        case.model
            .rest()
            .iter()
            .map(|q| q + Vector3::new(0.0, dy, 0.0))
            .collect()
    };
    let e = check_initial_positions(&case.model, &shifted(-5.0))
        .unwrap_err()
        .to_string();
    for want in ["initial positions given", "inside obstacle 'ground'", "body '"] {
        assert!(e.contains(want), "{want}: {e}");
    }
    let mut sim = Simulator::new(case.model.clone(), case.settings.clone()).unwrap();
    let e = sim.set_initial_state(&shifted(-5.0), &v0).unwrap_err().to_string();
    assert!(
        e.contains("initial positions given") && e.contains("inside obstacle"),
        "{e}"
    );
    assert_eq!(sim.state().q, case.model.rest(), "a refused state is not taken");
    sim.set_initial_state(&shifted(0.5), &v0).unwrap();
    assert!(check_initial_positions(&case.model, &shifted(0.5)[1..]).is_err());
}

/// A run started from a state of its own (`Simulator::set_initial_state`, `set_state`, a
/// gradient's or rollout's initial state) is checked for divergence against an energy scale
/// that counts that state's velocities, as it counts the model's own initial velocities (the
/// backward pass's replays of steps keep the forward's scale): a
/// free body thrown at 1e5 m/s as a whole runs (it was refused as diverged for its own kinetic
/// energy, about 1e9 times the scale of a body at rest), and one whose velocity grows by itself
/// past 1e8 times the scale is still refused.
#[test]
fn a_state_a_run_starts_from_sets_the_divergence_checks_energy_scale() {
    use diffsoft::solver::Simulator;
    use nalgebra::Vector3;
    let case = diffsoft::testing::free_body(2).unwrap();
    let q0 = case.model.rest().to_vec();
    let fast = vec![Vector3::new(1e5, 0.0, 0.0); q0.len()];
    let mut sim = Simulator::new(case.model.clone(), case.settings.clone()).unwrap();
    sim.set_initial_state(&q0, &fast).unwrap();
    for _ in 0..2 {
        sim.step().unwrap();
    }
    let v = sim.state().v.iter().map(|v| v.x).sum::<f64>() / q0.len() as f64;
    assert!((v - 1e5).abs() < 1.0, "mean velocity {v}");
    let mut sim = Simulator::new(case.model.clone(), case.settings.clone()).unwrap();
    sim.set_state(q0.clone(), fast.clone()).unwrap();
    sim.step().unwrap();
    // The gradient's forward pass starts from its controls' state the same way.
    let controls = diffsoft::diff::Controls {
        initial: Some((q0.clone(), fast.clone())),
        ..case.controls.clone()
    };
    let g = diffsoft::diff::gradient(
        &case.model,
        &case.settings,
        2,
        &controls,
        case.loss.as_ref(),
        diffsoft::diff::Options::default(),
    );
    assert!(g.is_ok(), "{:?}", g.err());
    // The check itself still holds: a state from the model's scale whose kinetic energy then
    // exceeds 1e8 times that scale in one step (set without `start_from`) is refused.
    let mut sim = Simulator::new(case.model.clone(), case.settings.clone()).unwrap();
    sim.set_state_from(&q0, &fast).unwrap();
    let e = sim.step().unwrap_err().to_string();
    assert!(e.contains("exceeds 1e8 x the scene's energy scale"), "{e}");
}

/// Paper scenes whose values the importer would otherwise cast or drop are refused naming the
/// key (a "Max Iteration" that is not a whole number from 1, a damping outside (0, 1], a
/// negative mass, an "Obstacles" that is not a list, a fractional bone parent), and two meshes
/// that would take one body or actuator name are told apart instead of refused with names the
/// file never uses.
#[test]
fn paper_scenes_refuse_cast_values_and_name_their_bodies_apart() {
    use serde_json::json;
    let (dir, src) = paper_copy("paper-casts", "droneman/droneman.json");
    let base: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&src).unwrap()).unwrap();
    let refused = |name: &str, edit: &dyn Fn(&mut serde_json::Value), want: &str| {
        let mut v = base.clone();
        edit(&mut v);
        let e = scene::load(write(&dir, name, &v.to_string()), LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(want) && e.contains(name),
            "{name}: expected '{want}' in: {e}"
        );
    };
    for (k, bad) in [json!(-5), json!(0.5), json!(2.7), json!(1e300), json!(0)]
        .into_iter()
        .enumerate()
    {
        refused(
            &format!("maxit{k}.json"),
            &|v| v["Parameters"][0]["Max Iteration"] = bad.clone(),
            "Parameters[0]: \"Max Iteration\" must be a whole number from 1",
        );
    }
    for (k, bad) in [json!(-1), json!(0), json!(2)].into_iter().enumerate() {
        refused(
            &format!("damping{k}.json"),
            &|v| v["Parameters"][0]["Damping coefficient"] = bad.clone(),
            "Parameters[0]: \"Damping coefficient\" (velocity kept per step) must be in (0, 1]",
        );
    }
    refused(
        "mass.json",
        &|v| v["Meshes"][1]["Mass"] = json!(-1),
        "Meshes[1]: \"Mass\" (the body's total mass, kg) must be finite and positive, got -1",
    );
    for (k, bad) in [json!({"Obj filename": "droneman/ball_tet.obj"}), json!("ground.obj")]
        .into_iter()
        .enumerate()
    {
        refused(
            &format!("obstacles{k}.json"),
            &|v| v["Obstacles"] = bad.clone(),
            "\"Obstacles\" must be a list",
        );
    }
    // Two meshes of one file, each with pneumatic groups: both load, the second body and its
    // groups named apart (the first keeps the names a one-mesh scene gives).
    let mut v = base.clone();
    let first = v["Meshes"][0].clone();
    v["Meshes"][1] = first;
    let sc = scene::load(write(&dir, "twice.json", &v.to_string()), LoadOptions::default()).unwrap();
    let names: Vec<&str> = sc.model.bodies().iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, ["droneman600_tet", "droneman600_tet_1"]);
    let act = sc.model.actuators().expect("pneumatic groups");
    let groups: Vec<&str> = act.groups.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(groups.len(), 16, "{groups:?}");
    assert!(
        groups.contains(&"pneumatic0") && groups.contains(&"droneman600_tet_1_pneumatic0"),
        "{groups:?}"
    );
    assert!(
        sc.notes.iter().any(|n| n.contains("body named 'droneman600_tet_1'")),
        "{:?}",
        sc.notes
    );
    // A bone parent that is not a whole number is named as such, not as missing.
    let (dir, src) = paper_copy("paper-parent-float", "baymax/baymax_skeleton.json");
    let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&src).unwrap()).unwrap();
    v["Meshes"][0]["Bones"][1]["Parent ID"] = json!(0.5);
    let e = scene::load(write(&dir, "parent.json", &v.to_string()), LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("Bones[1]: \"Parent ID\" must be a whole number (-1 for the root), got 0.5"),
        "{e}"
    );
}

/// A muscle whose polyline lies on another's gets no tets of its own: the error says so (the
/// tets near it went to the other muscle), instead of claiming no tet is near it.
#[test]
fn paper_muscles_on_one_polyline_are_named() {
    let e = octopus_with_muscle_lines("paper-muscle-same-line", |lines| {
        let first = lines[0][0].clone();
        let second = lines.iter().find(|l| l[0] != first).unwrap()[0].clone();
        let copies: Vec<Vec<String>> = lines
            .iter()
            .filter(|l| l[0] == first)
            .map(|l| {
                let mut c = l.clone();
                c[0] = second.clone();
                c
            })
            .collect();
        for (k, l) in lines.iter_mut().filter(|l| l[0] == second).enumerate() {
            *l = copies[k % copies.len()].clone();
        }
    });
    assert!(
        e.contains("every tet within") && e.contains("is at least as near to muscle(s)"),
        "{e}"
    );
}

/// A step that runs long stops within itself when its run is cancelled (a Python Ctrl-C, the
/// command line's SIGINT), not only before the next step: two identical cloths lying on each
/// other make the second step's contact solves run for minutes; cancelled while it runs, the
/// step returns `Interrupted` and leaves the state the step started from. (The 120 s wait is
/// a liveness bound only: the step stops within a fraction of a second of the cancel.)
#[test]
fn a_long_step_stops_within_itself_when_its_run_is_cancelled() {
    use diffsoft::base::cancel::Cancel;
    use diffsoft::solver::Simulator;
    let mut doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root().join("verification/scenes/box_on_cloth.json")).unwrap())
            .unwrap();
    let o = doc.as_object_mut().unwrap();
    o.remove("bodies");
    let mut second = o["cloths"][0].clone();
    second["name"] = "cloth2".into();
    o["cloths"].as_array_mut().unwrap().push(second);
    let dir = tmp_dir("cancel-in-step");
    let path = write(&dir, "two_cloths.json", &doc.to_string());
    let sc = scene::load(&path, LoadOptions::default()).unwrap();
    let mut sim = Simulator::new(sc.model, sc.settings).unwrap();
    sim.step().unwrap();
    let before = sim.state().clone();
    let token = Cancel::new();
    let (tx, rx) = std::sync::mpsc::channel();
    let worker = {
        let token = token.clone();
        std::thread::spawn(move || {
            let r = token.scope(|| sim.step());
            tx.send(()).unwrap();
            (r, sim)
        })
    };
    std::thread::sleep(std::time::Duration::from_millis(300));
    token.cancel();
    assert!(
        rx.recv_timeout(std::time::Duration::from_secs(120)).is_ok(),
        "the cancelled step did not stop"
    );
    let (r, sim) = worker.join().unwrap();
    assert!(matches!(r, Err(diffsoft::SolverError::Interrupted)), "{r:?}");
    assert_eq!(sim.state().step, before.step);
    assert_eq!(sim.state().q, before.q);
    assert_eq!(sim.state().v, before.v);
}
