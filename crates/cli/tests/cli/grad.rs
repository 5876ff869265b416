//! `diffsoft grad`: the gradient from the command line.

use std::process::Command;

fn grad_cli(scene: &std::path::Path, set: Option<f64>, json: &std::path::Path) -> (f64, f64) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_diffsoft"));
    cmd.args(["--threads", "1", "grad", "--scene"])
        .arg(scene)
        .args([
            "--steps",
            "5",
            "--loss",
            "final_com.y",
            "--param",
            "youngs_modulus",
            "--tolerance",
            "0",
        ])
        .args(["--max-iterations", "10", "--json"])
        .arg(json);
    if let Some(e) = set {
        cmd.arg("--set").arg(format!("youngs_modulus={e:.17e}"));
    }
    let out = cmd.output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
    // The report holds what the run was given: the --set values and the solver's settings.
    assert_eq!(v["overrides"]["youngs_modulus"].as_f64(), set, "{v}");
    assert_eq!(v["settings"]["max_iterations"], 10, "{v}");
    assert_eq!(v["settings"]["tolerance"], 0.0, "{v}");
    (
        v["loss"].as_f64().unwrap(),
        v["gradient"]["youngs_modulus"].as_f64().unwrap(),
    )
}

/// `grad --implicit-tolerance` reaches the implicit adjoint: a looser tolerance takes fewer
/// backward iterations and gives nearly the same gradient; a negative one is an error.
#[test]
fn grad_cli_implicit_tolerance_takes_effect() {
    let dir = crate::common::tmp_dir("grad-implicit-tolerance");
    let scene = crate::common::root().join("verification/paper/bridgesus/bridgesus.json");
    let run = |tol: &str| {
        let json = dir.join(format!("g{tol}.json"));
        let out = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
            .args(["--threads", "1", "grad"])
            .arg(&scene)
            .args(["--steps", "10", "--param", "youngs_modulus", "--mode", "implicit"])
            .args([
                "--tolerance",
                "1e-10",
                "--max-iterations",
                "200",
                "--implicit-tolerance",
                tol,
                "--json",
            ])
            .arg(&json)
            .output()
            .unwrap();
        (out, json)
    };
    let read = |json: &std::path::Path| {
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
        (
            v["gradient"]["youngs_modulus"].as_f64().unwrap(),
            v["stats"]["backward_iterations"].as_u64().unwrap(),
        )
    };
    let (tight, jt) = run("1e-12");
    assert!(tight.status.success(), "{}", String::from_utf8_lossy(&tight.stderr));
    let (loose, jl) = run("1e-4");
    assert!(loose.status.success(), "{}", String::from_utf8_lossy(&loose.stderr));
    let ((gt, it), (gl, il)) = (read(&jt), read(&jl));
    assert!(il < it, "backward iterations: {il} at 1e-4, {it} at 1e-12");
    assert!((gl - gt).abs() <= 1e-3 * gt.abs(), "gradients {gl:e} and {gt:e}");
    let (bad, _) = run("-1");
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--implicit-tolerance"));
}

/// The implicit adjoint's default tolerance is matched to the forward's (docs/method.md Eq. G5):
/// at the scene's own stopping rule it takes fewer backward iterations than 1e-12 and moves the
/// gradient by at most a tenth of what the forward's stopping error already moves it (the gap
/// between the implicit gradient and the unrolled one, which differentiates the iterations
/// actually run).
#[test]
fn grad_cli_matched_implicit_tolerance_costs_less_than_the_forward_error() {
    let dir = crate::common::tmp_dir("grad-matched-tolerance");
    let scene = crate::common::root().join("verification/paper/bridgesus/bridgesus.json");
    let run = |name: &str, extra: &[&str]| {
        let json = dir.join(format!("{name}.json"));
        let out = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
            .args(["--threads", "1", "grad"])
            .arg(&scene)
            .args(["--steps", "20", "--param", "youngs_modulus", "--loss", "mean_com.y"])
            .args(extra)
            .arg("--json")
            .arg(&json)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
        (
            v["gradient"]["youngs_modulus"].as_f64().unwrap(),
            v["stats"]["backward_iterations"].as_u64().unwrap(),
        )
    };
    let (matched, im) = run("matched", &["--mode", "implicit"]);
    let (tight, it) = run("tight", &["--mode", "implicit", "--implicit-tolerance", "1e-12"]);
    let (unrolled, _) = run("unrolled", &["--mode", "unrolled"]);
    let forward_gap = (tight - unrolled).abs();
    assert!(
        forward_gap > 0.0,
        "the forward stops short of convergence: its gap is measurable"
    );
    assert!(
        (matched - tight).abs() <= 0.1 * forward_gap,
        "matched {matched:e}, tight {tight:e}, unrolled {unrolled:e}"
    );
    assert!(im < it, "backward iterations: {im} matched, {it} at 1e-12");
}

/// `diffsoft grad` against central differences of its own loss taken through `--set`.
#[test]
fn grad_cli_agrees_with_outside_finite_differences() {
    let dir = crate::common::tmp_dir("grad-cli");
    let scene = crate::common::root().join("verification/paper/bridgesus/bridgesus.json");
    let json = dir.join("g.json");
    let (_, g) = grad_cli(&scene, None, &json);
    let e0 = 2e5;
    let mut best = f64::INFINITY;
    for k in 2..8 {
        let h = e0 * 10f64.powi(-k);
        let (lp, _) = grad_cli(&scene, Some(e0 + h), &json);
        let (lm, _) = grad_cli(&scene, Some(e0 - h), &json);
        let fd = (lp - lm) / (2.0 * h);
        best = best.min((fd - g).abs() / fd.abs());
    }
    assert!(best < 1e-6, "best relative difference {best:e} (gradient {g:e})");
}

/// `grad --param`'s help lists the registry's scalars with their units, and the solver flags of
/// `simulate` and `grad` are documented by the settings they override; both commands take
/// them, and `grad --dt` reaches the run.
#[test]
fn cli_names_come_from_the_registry_and_the_settings() {
    let help = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
            .args(args)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let grad = help(&["grad", "--help"]);
    for p in diffsoft::diff::params::scalars() {
        assert!(
            grad.contains(&format!("{} ({})", p.name, p.units)),
            "{} missing in:\n{grad}",
            p.name
        );
    }
    let short = help(&["grad", "-h"]);
    assert!(
        short.contains("youngs_modulus, poisson_ratio, density, initial_velocity.x|y|z, gravity.x|y|z"),
        "{short}"
    );
    let simulate = help(&["simulate", "--help"]);
    for name in [
        "solver",
        "integrator",
        "certify",
        "dt",
        "max_iterations",
        "tolerance",
        "anderson",
    ] {
        let doc = diffsoft::Settings::describe(name).unwrap();
        let first = doc.split_whitespace().take(4).collect::<Vec<_>>().join(" ");
        let flag = format!("--{}", name.replace('_', "-"));
        for (cmd, text) in [("simulate", &simulate), ("grad", &grad)] {
            let at = text
                .find(&format!("{flag} <"))
                .unwrap_or_else(|| panic!("{cmd}: no {flag}"));
            let flat = text[at..].split_whitespace().take(40).collect::<Vec<_>>().join(" ");
            assert!(flat.contains(&first), "{cmd} {flag}: expected '{first}' in: {flat}");
        }
    }
    let dir = crate::common::tmp_dir("grad-dt");
    let scene = crate::common::root().join("verification/paper/bridgesus/bridgesus.json");
    let run = |dt: &str| {
        Command::new(env!("CARGO_BIN_EXE_diffsoft"))
            .args(["--threads", "1", "grad"])
            .arg(&scene)
            .args([
                "--steps",
                "2",
                "--param",
                "density",
                "--tolerance",
                "0",
                "--max-iterations",
                "3",
            ])
            .args(["--dt", dt, "--json"])
            .arg(dir.join(format!("g{dt}.json")))
            .output()
            .unwrap()
    };
    let ok = run("0.001");
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let bad = run("-1");
    assert_eq!(bad.status.code(), Some(1));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("time step must be finite and positive, got -1"), "{err}");
}

/// A parameter that applies to nothing in the scene (a body's density with cloth alone) is an
/// error naming it, whether differentiated or set (it returned 0 and changed nothing).
#[test]
fn a_parameter_that_applies_to_nothing_is_refused() {
    let dir = crate::common::tmp_dir("grad-nothing-applies");
    let flag = crate::common::root().join("verification/paper/cloth_ball/flag2.obj");
    let scene = dir.join("cloth_only.json");
    let text = format!(
        r#"{{ "schema": "diffsoft.scene/1", "time_step": 0.005, "gravity": [0, -9.81, 0],
            "cloths": [{{ "name": "flag", "mesh": {:?}, "stretching": 2000, "bending": 0.0005,
                          "area_density": 0.3, "fixed": {{ "indices": [3, 6, 7] }} }}] }}"#,
        flag.to_str().unwrap()
    );
    std::fs::write(&scene, text).unwrap();
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_diffsoft"))
            .args(["--threads", "1", "grad"])
            .arg(&scene)
            .args(["--steps", "2"])
            .args(args)
            .output()
            .unwrap()
    };
    for args in [
        &["--param", "density"][..],
        &["--param", "gravity.y", "--set", "density=5"][..],
    ] {
        let out = run(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains("nothing that 'density' applies to"), "{args:?}: {err}");
    }
    let out = run(&["--param", "gravity.y"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}
