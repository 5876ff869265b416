//! Actuators in simulation: static closed forms (pneumatic cube, muscle bar), the direction a
//! pneumatic beam bends, activation schedules and the API, the paper's drone and octopus, and
//! bad input (scene keys, ranges, names).

use crate::common::{cube_scene, root, tmp_dir};
use diffsoft::actuator::{fibres_along, ActuatorSpec};
use diffsoft::base::Schedule;
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::scene::{self, LoadOptions};
use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Settings, Simulator, SolverError};
use diffsoft_harness::actuators::{drone, muscle_bar, octopus, pneumatic_beam, pneumatic_cube};
use nalgebra::Vector3;

#[test]
fn a_pneumatic_cube_reaches_its_closed_form_volume() {
    for a in [0.5, 2.0] {
        let c = pneumatic_cube(1e5, a).unwrap();
        assert!(c.relative_error < 1e-9, "{c:?}");
        // And it really changed volume in the activation's direction.
        assert!((c.measured - 1.0).signum() == (a - 1.0).signum());
    }
}

#[test]
fn a_muscle_bar_contracts_along_its_fibres_by_the_closed_form_amount() {
    for a in [0.1, 0.3] {
        let [along, across] = muscle_bar(5e5, a).unwrap();
        assert!(along.relative_error < 1e-9, "{along:?}");
        assert!(across.relative_error < 1e-9, "{across:?}");
        // Shorter along the fibres, and it bulges across them (the volume term resists).
        assert!(along.measured < 1.0 - 0.5 * a && across.measured > 1.0);
    }
}

#[test]
fn a_pneumatic_beam_bends_away_from_expanding_cells_and_toward_contracting_ones() {
    let out = pneumatic_beam(1e5, 1.5).unwrap();
    assert!(out.tip_deflection < -0.05, "{out:?}");
    let inn = pneumatic_beam(1e5, 0.7).unwrap();
    assert!(inn.tip_deflection > 0.05, "{inn:?}");
    for b in [out, inn] {
        let r = b.curvature / b.bimorph_estimate;
        assert!(
            (0.5..=2.0).contains(&r),
            "curvature {} vs bimorph {}",
            b.curvature,
            b.bimorph_estimate
        );
    }
}

fn cube_model(actuators: Vec<ActuatorSpec>) -> Result<diffsoft::Model, SolverError> {
    let mesh = BoxSpec::new([2, 2, 2], [0.1; 3]).build().unwrap();
    let mut b = BodySpec::new(
        "cube",
        mesh,
        Material {
            youngs_modulus: 1e5,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(1000.0),
    );
    b.gravity = false;
    b.actuators = actuators;
    Ok(ModelBuilder::new().body(b).build()?)
}

#[test]
fn activations_follow_their_schedule_unless_set_and_bad_ones_are_refused() {
    let all: Vec<usize> = (0..48).collect();
    let ramp = Schedule {
        times: vec![0.0, 0.1],
        values: vec![1.0, 2.0],
    };
    let model = cube_model(vec![
        ActuatorSpec::pneumatic("cells", &all, 1e5, ramp.clone()),
        ActuatorSpec::muscle("fibres", fibres_along(&all, Vector3::x()), 1e5, Schedule::constant(0.0)),
    ])
    .unwrap();
    let settings = Settings {
        dt: 0.01,
        ..Settings::default()
    };
    let mut sim = Simulator::new(model, settings).unwrap();
    for _ in 0..5 {
        sim.step().unwrap();
    }
    let t = sim.state().time;
    assert!((sim.activations().unwrap()[0] - ramp.at(t)).abs() < 1e-15);
    sim.set_activation("fibres", 0.4).unwrap();
    sim.step().unwrap();
    assert_eq!(sim.activations().unwrap()[1], 0.4);
    sim.follow_schedule("fibres").unwrap();
    sim.step().unwrap();
    assert_eq!(sim.activations().unwrap()[1], 0.0);
    // Out of range, unknown names, a model without actuators: explicit errors.
    for (name, a) in [
        ("cells", 0.0),
        ("cells", -1.0),
        ("cells", f64::NAN),
        ("fibres", 1.5),
        ("fibres", -0.1),
    ] {
        let e = sim.set_activation(name, a).unwrap_err().to_string();
        assert!(e.contains(name) && e.contains("out of range"), "{e}");
    }
    assert!(sim
        .set_activation("nope", 0.5)
        .unwrap_err()
        .to_string()
        .contains("nope"));
    let mut plain = Simulator::new(cube_model(vec![]).unwrap(), Settings::default()).unwrap();
    assert!(plain.activations().is_none(), "no actuator buffers without actuators");
    assert!(plain.set_activation("cells", 1.0).is_err());
    plain.step().unwrap();
}

#[test]
fn bad_actuator_specs_are_named() {
    let cases: Vec<(ActuatorSpec, &str)> = vec![
        (
            ActuatorSpec::pneumatic("p", &[0, 99], 1e5, Schedule::constant(1.0)),
            "tet 99 out of range",
        ),
        (
            ActuatorSpec::pneumatic("p", &[0], -1.0, Schedule::constant(1.0)),
            "stiffness",
        ),
        (
            ActuatorSpec::pneumatic("p", &[0], 1e5, Schedule::constant(0.0)),
            "activation 0 out of range",
        ),
        (
            ActuatorSpec::muscle("m", vec![(0, Vector3::x())], 1e5, Schedule::constant(1.5)),
            "activation 1.5 out of range",
        ),
        (
            ActuatorSpec::muscle("m", vec![(3, Vector3::zeros())], 1e5, Schedule::constant(0.5)),
            "tet 3: fibre direction",
        ),
        (
            ActuatorSpec::pneumatic("p", &[], 1e5, Schedule::constant(1.0)),
            "no tets",
        ),
    ];
    for (spec, want) in cases {
        let name = spec.name.clone();
        let e = cube_model(vec![spec]).unwrap_err().to_string();
        assert!(e.contains(want) && e.contains(&format!("actuator '{name}'")), "{e}");
    }
    let dup = cube_model(vec![
        ActuatorSpec::pneumatic("p", &[0], 1e5, Schedule::constant(1.0)),
        ActuatorSpec::pneumatic("p", &[1], 1e5, Schedule::constant(1.0)),
    ])
    .unwrap_err()
    .to_string();
    assert!(dup.contains("duplicate"), "{dup}");
}

fn actuator_scene(dir: &std::path::Path, actuators: &str) -> std::path::PathBuf {
    cube_scene(dir, &format!(r#", "density": 1000, "actuators": {actuators}"#), "")
}

#[test]
fn scene_actuators_load_and_bad_ones_are_named() {
    let dir = tmp_dir("actuator-scenes");
    let ok = actuator_scene(
        &dir,
        r#"[
      { "name": "p", "pneumatic": { "tets": { "vertices": { "indices": [1, 2, 3, 4], "min_shared": 4 } } },
        "stiffness": 1e5, "activation": { "times": [0, 1], "values": [1, 2] } },
      { "name": "m", "muscle": { "polyline": [[0, 0, 0], [1, 1, 1]], "radius": 0.5 },
        "stiffness": 1e5, "activation": 0.2 },
      { "name": "b", "muscle": { "tets": { "all": {} }, "direction": [0, 0, 2] }, "stiffness": 1e5, "activation": 0 }
    ]"#,
    );
    let sc = scene::load(&ok, LoadOptions::default()).unwrap();
    let act = sc.model.actuators().unwrap();
    assert_eq!(act.groups.len(), 3);
    assert_eq!(
        act.cells[act.groups[0].cells.clone()].len(),
        1,
        "only tet 1 has all four vertices"
    );
    assert!(act
        .cells
        .iter()
        .filter(|c| c.group == 2)
        .all(|c| c.direction == Vector3::z()));
    let mut sim = Simulator::new(sc.model, sc.settings).unwrap();
    sim.step().unwrap();
    for (body, want) in [
        (
            r#"[{ "name": "x", "pneumatic": { "tets": { "all": {} } }, "stiffness": 1e5, "activation": 1, "colour": 1 }]"#,
            "unknown field `colour`",
        ),
        (
            r#"[{ "name": "x", "stiffness": 1e5, "activation": 1 }]"#,
            "exactly one of `pneumatic` and `muscle`",
        ),
        (
            r#"[{ "name": "x", "muscle": { "polyline": [[0, 0, 0], [1, 0, 0]] }, "stiffness": 1e5, "activation": 0 }]"#,
            "`polyline` and `radius`",
        ),
        (
            r#"[{ "name": "x", "muscle": { "polyline": [[5, 5, 5], [6, 5, 5]], "radius": 0.1 }, "stiffness": 1e5, "activation": 0 }]"#,
            "no tet centroid",
        ),
        (
            r#"[{ "name": "x", "pneumatic": { "tets": { "indices": [7] } }, "stiffness": 1e5, "activation": 1 }]"#,
            "tet 7 out of range",
        ),
        (
            r#"[{ "name": "x", "pneumatic": { "tets": { "vertices": { "indices": [0], "min_shared": 5 } } }, "stiffness": 1e5, "activation": 1 }]"#,
            "min_shared",
        ),
        (
            r#"[{ "name": "x", "muscle": { "tets": { "all": {} }, "direction": [0, 0, 1] }, "stiffness": 1e5, "activation": 2 }]"#,
            "activation 2 out of range",
        ),
    ] {
        let p = actuator_scene(&dir, body);
        let e = scene::load(&p, LoadOptions::default()).unwrap_err().to_string();
        assert!(e.contains(want), "{want}: {e}");
    }
}

#[test]
fn the_papers_drone_and_octopus_import_with_their_actuators() {
    let d = scene::load(
        root().join("verification/paper/droneman/droneman.json"),
        LoadOptions::default(),
    )
    .unwrap();
    let act = d.model.actuators().unwrap();
    assert_eq!(act.groups.len(), 8);
    assert!(act.groups.iter().all(|g| (12..=13).contains(&g.cells.len())));
    let o = scene::load(
        root().join("verification/paper/octopus/octopus.json"),
        LoadOptions::default(),
    )
    .unwrap();
    let act = o.model.actuators().unwrap();
    assert_eq!(act.groups.len(), 16);
    assert!(act.groups.iter().all(|g| g.cells.len() > 50));
    assert!(act.cells.iter().all(|c| (c.direction.norm() - 1.0).abs() < 1e-12));
}

#[test]
fn the_drone_closes_and_the_octopus_moves_one_tentacle() {
    let dir = tmp_dir("actuated-paper-scenes");
    let v = root().join("verification/paper");
    let d = drone(&v.join("droneman/droneman.json"), 1.5, 40, &dir.join("drone")).unwrap();
    let r0 = d.series[0].value;
    let closest = d.series.iter().map(|p| p.value).fold(f64::INFINITY, f64::min);
    assert!(closest < 0.9 * r0, "tips from {r0} to at best {closest}");
    assert!(dir.join("drone/frames.pvd").exists());
    let o = octopus(
        &v.join("octopus/octopus.json"),
        "muscle0",
        0.3,
        60,
        &dir.join("octopus"),
    )
    .unwrap();
    let tip = o.series.iter().map(|p| p.value).fold(0.0, f64::max);
    let others = o.control.iter().map(|p| p.value).fold(0.0, f64::max);
    assert!(tip > 0.1 && tip > 3.0 * others, "driven tip {tip}, others {others}");
}
