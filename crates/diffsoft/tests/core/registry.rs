//! The parameter registry (`diffsoft::diff::params::PARAMETERS`) and the one settings struct
//! (`Settings`): every registered scalar reads back what it sets and its derivative agrees
//! with central differences, with no code outside its entry; what the Python stub and
//! docs/python.md say about parameters is what the registry holds; settings are set by name,
//! checked, and the scene file takes the time step under either spelling.

use std::collections::HashSet;

use diffsoft::diff::params::{self, Param, ParamKind, PARAMETERS, SCALAR};
use diffsoft::diff::{self, loss, Controls, Mode, Options};
use diffsoft::scene::{self, LoadOptions};
use diffsoft::Settings;

use crate::common::{cube_scene, root, tmp_dir, write};

#[test]
fn the_registry_is_well_formed() {
    let mut names = HashSet::new();
    for p in PARAMETERS {
        assert!(names.insert(p.name), "{} is registered twice", p.name);
        assert!(
            p.name
                .split('.')
                .all(|w| !w.is_empty() && w.chars().all(|c| c.is_ascii_lowercase() || c == '_')),
            "{}: names are lower_snake_case words joined by '.'",
            p.name
        );
        assert!(!p.units.is_empty() && !p.description.is_empty(), "{}", p.name);
        match p.kind {
            ParamKind::Scalar { .. } => {
                assert_eq!(p.shape, SCALAR, "{}", p.name);
                let q: Param = p.name.parse().unwrap();
                assert_eq!(q.name(), p.name);
                assert_eq!(q.to_string(), p.name);
                assert!(std::ptr::eq(q.spec(), p));
            }
            ParamKind::Array(_) => {
                assert!(p.shape.starts_with('(') && p.shape != SCALAR, "{}: {}", p.name, p.shape);
                assert!(p.name.parse::<Param>().is_err(), "an array is not a scalar: {}", p.name);
            }
        }
    }
    for (c, name) in [
        (Param::YOUNGS_MODULUS, "youngs_modulus"),
        (Param::POISSON_RATIO, "poisson_ratio"),
        (Param::DENSITY, "density"),
        (Param::INITIAL_VELOCITY_X, "initial_velocity.x"),
        (Param::INITIAL_VELOCITY_Y, "initial_velocity.y"),
        (Param::INITIAL_VELOCITY_Z, "initial_velocity.z"),
        (Param::GRAVITY_X, "gravity.x"),
        (Param::GRAVITY_Y, "gravity.y"),
        (Param::GRAVITY_Z, "gravity.z"),
    ] {
        assert_eq!(c.name(), name);
    }
    assert_eq!(Param::INITIAL_VELOCITY_Z.initial_velocity_axis(), Some(2));
    assert_eq!(Param::GRAVITY_Z.initial_velocity_axis(), None);
    let e = "stiffness".parse::<Param>().unwrap_err().to_string();
    for p in params::scalars() {
        assert!(e.contains(p.name), "the error lists every scalar: {e}");
    }
}

/// Whatever a scalar entry's `get`, `set` and `derivative` are, they agree with each other:
/// `get` reads back what `set` wrote, and `derivative` (picked out of a reverse-mode gradient)
/// matches central differences of the loss through `set`, for the centre of mass along each
/// axis. A new scalar entry is tested here without any code of its own (it must apply to this
/// scene: a body with a pinned vertex, gravity, an initial velocity and a ground plane).
#[test]
fn every_registered_scalar_sets_reads_and_differentiates_consistently() {
    let dir = tmp_dir("registry-scalars");
    let path = cube_scene(
        &dir,
        r#", "density": 1000, "initial_velocity": [0.3, 0.5, -0.2], "fixed": {"indices": [0]}"#,
        // Ground far below (no contact in these steps): a parameter of obstacles applies too.
        r#", "obstacles": [{"plane": {"point": [0, -5, 0], "normal": [0, 1, 0]}, "friction": 0.4}]"#,
    );
    let sc = scene::load(&path, LoadOptions::default()).unwrap();
    let settings = Settings {
        solver: diffsoft::SolverKind::Direct,
        tolerance: 0.0,
        max_iterations: 8,
        ..sc.settings.clone()
    };
    let steps = 6;
    let losses = ["final_com.x", "final_com.y", "final_com.z"];
    let grads: Vec<_> = losses
        .iter()
        .map(|l| {
            let l = loss::by_name(l).unwrap();
            diff::gradient(
                &sc.model,
                &settings,
                steps,
                &Controls::default(),
                l.as_ref(),
                Options::mode(Mode::Unrolled),
            )
            .unwrap()
        })
        .collect();
    for spec in params::scalars() {
        let p = Param::of(spec).unwrap();
        let v = p.get(&sc.model).unwrap_or_else(|e| panic!("{p}: {e}"));
        let moved = if v == 0.0 { 0.25 } else { v * 1.1 };
        let mut m = sc.model.clone();
        p.set(&mut m, moved).unwrap();
        assert!((p.get(&m).unwrap() - moved).abs() <= 1e-12 * moved.abs(), "{p}");
        assert!(p.set(&mut m, f64::NAN).is_err(), "{p}: NaN is refused");
        let h = 1e-5 * v.abs().max(1.0);
        for (name, g) in losses.iter().zip(&grads) {
            let l = loss::by_name(name).unwrap();
            let at = |x: f64| {
                let mut m = sc.model.clone();
                p.set(&mut m, x).unwrap();
                diff::loss_value(&m, &settings, steps, &Controls::default(), l.as_ref()).unwrap()
            };
            let fd = (at(v + h) - at(v - h)) / (2.0 * h);
            let d = p.derivative(&sc.model, g);
            assert!(
                (d - fd).abs() <= 1e-5 * d.abs().max(fd.abs()) + 1e-9,
                "d {name} / d {p}: reverse mode {d:e}, central differences {fd:e}"
            );
        }
    }
}

/// The ``tokens`` of the docstring that follows `def <name>(` in a stub.
fn docstring_tokens(stub: &str, def: &str) -> Vec<String> {
    let start = stub.find(def).unwrap_or_else(|| panic!("no {def} in the stub"));
    let rest = &stub[start..];
    let open = rest.find("\"\"\"").unwrap() + 3;
    let close = open + rest[open..].find("\"\"\"").unwrap();
    rest[open..close]
        .split("``")
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect()
}

/// The Python stub names parameters only as examples (the lists are `scalar_parameters()` and
/// `array_parameters()`, read from the registry): each name it gives is registered.
#[test]
fn the_python_stub_names_registered_parameters() {
    let stub = std::fs::read_to_string(root().join("python/diffsoft/_diffsoft.pyi")).unwrap();
    let tokens = docstring_tokens(&stub, "def set(");
    assert!(tokens.len() >= 4, "{tokens:?}");
    // Parameter names, not the calls that list them.
    for t in tokens.iter().filter(|t| !t.ends_with(')')) {
        assert!(
            params::lookup(t).is_some(),
            "the stub's Scene.set names '{t}', not a registered parameter"
        );
    }
}

/// docs/python.md's table of array parameters is the registry's arrays with their shapes, and
/// every scalar it names is registered.
#[test]
fn docs_python_parameters_are_the_registry() {
    let doc = std::fs::read_to_string(root().join("docs/python.md")).unwrap();
    let start = doc.find("### Parameters").expect("a Parameters section");
    let section = &doc[start..start + doc[start..].find("\n### Errors").unwrap()];
    let mut arrays = Vec::new();
    for row in section.lines().filter(|l| l.starts_with("| `")) {
        let cells: Vec<&str> = row.split('|').map(|c| c.trim().trim_matches('`')).collect();
        let spec =
            params::lookup(cells[1]).unwrap_or_else(|| panic!("docs/python.md: '{}' is not registered", cells[1]));
        assert_eq!(spec.shape, cells[2], "docs/python.md: the shape of {}", spec.name);
        assert!(!spec.is_scalar(), "{}", spec.name);
        arrays.push(spec.name);
    }
    assert_eq!(
        arrays,
        params::array_names(),
        "docs/python.md lists every array, in registry order"
    );
    let prose: String = section
        .lines()
        .filter(|l| !l.starts_with('|'))
        .collect::<Vec<_>>()
        .join("\n");
    for name in prose.split('`').skip(1).step_by(2) {
        let lower = name.chars().all(|c| c.is_ascii_lowercase() || c == '_' || c == '.');
        let axis = [".x", ".y", ".z"].iter().any(|a| name.ends_with(a));
        if lower && (axis || name.contains('_')) {
            assert!(
                params::lookup(name).is_some(),
                "docs/python.md names '{name}', not a registered parameter"
            );
        }
    }
}

#[test]
fn settings_are_set_by_name_and_checked() {
    let mut s = Settings::default();
    s.set("solver", serde_json::json!("split")).unwrap();
    s.set("tolerance", serde_json::json!(1e-8)).unwrap();
    s.set("max_iterations", serde_json::json!(200)).unwrap();
    s.set("dt", serde_json::json!(0.005)).unwrap();
    s.set("integrator", serde_json::json!("bdf2")).unwrap();
    assert_eq!(s.solver, diffsoft::SolverKind::Split);
    assert_eq!((s.tolerance, s.max_iterations, s.dt), (1e-8, 200, 0.005));
    assert_eq!(s.integrator, diffsoft::solver::Integrator::Bdf2);
    let before = serde_json::to_value(&s).unwrap();
    for (name, value, expect) in [
        ("tolerence", serde_json::json!(1e-3), "unknown setting 'tolerence'"),
        (
            "solver",
            serde_json::json!("fastest"),
            "settings: solver: unknown variant `fastest`",
        ),
        ("max_iterations", serde_json::json!(-3), "settings: max_iterations"),
        (
            "dt",
            serde_json::json!(-1.0),
            "time step must be finite and positive, got -1",
        ),
        (
            "tolerance",
            serde_json::json!(-1.0),
            "tolerance must be finite and >= 0, got -1",
        ),
        ("damping", serde_json::json!(2.0), "damping must be in (0, 1], got 2"),
        (
            "contact_rounds",
            serde_json::json!(0),
            "contact_rounds (an iteration cap) must be at least 1, got 0",
        ),
        ("dt", serde_json::json!(f64::NAN), "dt must be a finite number"),
    ] {
        let e = s.set(name, value).unwrap_err().to_string();
        assert!(e.contains(expect), "{name}: expected '{expect}' in: {e}");
    }
    assert_eq!(
        serde_json::to_value(&s).unwrap(),
        before,
        "a refused setting changes nothing"
    );
    let names = Settings::names();
    assert_eq!(names.first().map(String::as_str), Some("dt"));
    for name in &names {
        assert!(
            Settings::describe(name).is_some_and(|d| !d.is_empty()),
            "{name} is documented"
        );
    }
    assert_eq!(
        names.len(),
        serde_json::to_value(Settings::default())
            .unwrap()
            .as_object()
            .unwrap()
            .len()
    );
}

/// The tolerance rule, in one place: settings relative to the model's length scale.
#[test]
fn tolerances_are_relative_to_the_length_scale() {
    let dir = tmp_dir("registry-length-scale");
    let sc = scene::load(cube_scene(&dir, r#", "density": 1000"#, ""), LoadOptions::default()).unwrap();
    let l = sc.model.length_scale();
    let s = Settings {
        tolerance: 1e-6,
        inner_tolerance: 1e-10,
        contact_margin: 1e-3,
        ..Settings::default()
    };
    assert_eq!(s.absolute_tolerance(&sc.model), 1e-6 * l);
    assert_eq!(s.inner_absolute_tolerance(&sc.model), 1e-10 * l);
    assert_eq!(s.absolute_contact_margin(&sc.model), 1e-3 * l);
}

/// A scene's time step is `solver.dt` or, the older spelling, the top-level `time_step`: one
/// of the two. The `solver` section takes every setting.
#[test]
fn the_scene_time_step_has_two_spellings_and_one_meaning() {
    let dir = tmp_dir("registry-time-step");
    let body = r#", "density": 1000"#;
    let old = scene::load(cube_scene(&dir, body, ""), LoadOptions::default()).unwrap();
    assert_eq!(old.settings.dt, 0.01);
    let text = std::fs::read_to_string(dir.join("scene.json")).unwrap();
    let canonical = write(
        &dir,
        "canonical.json",
        &text.replace(
            r#""time_step": 0.01,"#,
            r#""solver": {"dt": 0.004, "eigen_method": "dense", "inner_tolerance": 1e-12},"#,
        ),
    );
    let s = scene::load(&canonical, LoadOptions::default()).unwrap().settings;
    assert_eq!((s.dt, s.inner_tolerance), (0.004, 1e-12));
    assert_eq!(s.eigen_method, diffsoft::analysis::spectral::EigenMethod::Dense);
    let none = write(&dir, "none.json", &text.replace(r#""time_step": 0.01,"#, ""));
    let e = scene::load(&none, LoadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("no time step") && e.contains("solver.dt"), "{e}");
    let twice = cube_scene(&dir, body, r#", "solver": {"dt": 0.1}"#);
    let e = scene::load(&twice, LoadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("given twice"), "{e}");
    let unknown = cube_scene(&dir, body, r#", "solver": {"time_step": 0.1}"#);
    let e = scene::load(&unknown, LoadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("unknown field `time_step`") && e.contains("line"), "{e}");
}

/// A time step so short that `M/h^2` overflows (1e-200 s) is refused naming the time step and
/// the vertex, instead of surfacing as non-finite positions in the first iteration; 1e-150 s
/// still builds (its run is refused later, by the energy check, with its own message).
#[test]
fn a_time_step_whose_inverse_square_overflows_is_named() {
    let case = diffsoft::testing::free_body(1).unwrap();
    let settings = case.settings.with_dt(1e-200);
    let e = diffsoft::Simulator::new(case.model.clone(), settings)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("time step 1e-200 s") && e.contains("over h^2 overflows double precision"),
        "{e}"
    );
    assert!(diffsoft::Simulator::new(case.model.clone(), case.settings.with_dt(1e-150)).is_ok());
}
