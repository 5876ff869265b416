//! `diffsoft simulate`: frames, run log, certificate messages and exit codes, Newton.

use std::process::Command;

use serde_json::Value;

use crate::common::{root, tmp_dir};

fn paper(name: &str) -> std::path::PathBuf {
    root().join("verification/paper").join(name)
}

#[test]
fn simulate_writes_vtk_frames_and_a_run_log() {
    let dir = tmp_dir("cli-simulate");
    let out = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
        .args([
            "simulate",
            paper("bridgesus/bridgesus.json").to_str().unwrap(),
            // The certificate checked below is the split iteration's fallback.
            "--solver",
            "split",
            "--steps",
            "6",
            "--every",
            "3",
            "--out",
            dir.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("falling back to the direct solver"), "{stdout}");
    let log: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("run.json")).unwrap()).unwrap();
    assert_eq!(log["schema"], "diffsoft.run/2");
    assert_eq!(log["steps"].as_array().unwrap().len(), 6);
    assert_eq!(log["certificate"]["used"], "direct");
    assert_eq!(log["frames"].as_array().unwrap().len(), 3);
    for f in ["frame_00000.vtu", "frame_00002.vtu", "frames.pvd"] {
        assert!(dir.join(f).exists(), "{f}");
    }
    // The frame is a VTK XML unstructured grid with the mesh's points and tets (its arrays are
    // decoded and checked in crates/diffsoft/tests/core/vtk_frames.rs).
    let vtu = std::fs::read_to_string(dir.join("frame_00002.vtu")).unwrap();
    assert!(
        vtu.contains("<VTKFile type=\"UnstructuredGrid\""),
        "{}",
        &vtu[..200.min(vtu.len())]
    );
    assert!(
        vtu.contains("NumberOfPoints=\"212\" NumberOfCells=\"668\""),
        "{}",
        &vtu[..400.min(vtu.len())]
    );
    // Divergence is a clear failure with exit status 1, not a panic.
    let out = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
        .args([
            "simulate",
            paper("bridgesus/bridgesus.json").to_str().unwrap(),
            // The unchecked split iteration diverges on this mesh.
            "--solver",
            "split",
            "--steps",
            "5",
            "--certify",
            "off",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("diverged"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
        .args([
            "simulate",
            paper("bridgesus/bridgesus.json").to_str().unwrap(),
            // Certification refuses the split iteration on this mesh.
            "--solver",
            "split",
            "--steps",
            "5",
            "--certify",
            "refuse",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("rejected by certification"));
}

/// `--solver newton` is accepted by `simulate` and reported in its output.
#[test]
fn the_cli_runs_newton() {
    let dir = tmp_dir("newton-cli");
    let out = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
        .args([
            "simulate",
            root()
                .join("verification/paper/bridgesus/bridgesus.json")
                .to_str()
                .unwrap(),
            "--steps",
            "3",
            "--every",
            "0",
            "--solver",
            "newton",
            "--out",
            dir.join("run").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("Newton"), "{stdout}");
}

/// The paper's cloth_ball: its ball (E = 2e-5 Pa) cannot carry its own weight, which the run
/// notes before its first step, and from step 103 on it folds through itself, which the run
/// warns about after its last (with the inverted tets in the run log); the paper's bridge, whose
/// material carries it, gets neither.
#[test]
fn a_body_too_soft_for_its_weight_is_noted_and_its_folding_warned_about() {
    for (scene, steps, soft) in [
        ("cloth_ball/cloth_ball.json", "110", true),
        ("bridge/bridge.json", "3", false),
    ] {
        let dir = tmp_dir("cli-soft-body");
        let out = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
            .args([
                "simulate",
                paper(scene).to_str().unwrap(),
                "--steps",
                steps,
                "--every",
                "0",
            ])
            .args(["--threads", "1", "--out", dir.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert_eq!(stdout.contains("too soft to carry its own weight"), soft, "{stdout}");
        assert_eq!(stdout.contains("steps ended with inverted tets"), soft, "{stdout}");
        let log: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("run.json")).unwrap()).unwrap();
        let folded = log["summary"]["steps_with_inverted_tets"].as_u64().unwrap();
        assert_eq!(folded > 0, soft, "{folded}");
    }
}

/// Chebyshev with certification off at a step where it needs more inner iterations than its cap
/// runs unchecked, as `certify: off` says (it was an internal error), and says what it costs.
#[test]
fn chebyshev_with_certification_off_runs_unchecked() {
    let dir = tmp_dir("cli-chebyshev-off");
    let scene = crate::common::cube_scene(
        &dir,
        r#", "density": 1000"#,
        r#", "solver": { "solver": "chebyshev", "certify": "off", "inner_max_iterations": 2 }"#,
    );
    let out = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
        .args(["simulate", scene.to_str().unwrap(), "--steps", "1"])
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(
        !stderr.contains("panicked") && !stderr.contains("internal error"),
        "{stderr}"
    );
    assert!(out.status.success(), "{stderr}");
    assert!(stdout.contains("above the cap of 2"), "{stdout}");
    assert!(
        stdout.contains("certification off: the iteration runs unchecked"),
        "{stdout}"
    );
}

/// `--activation NAME=A` holds a group for the whole run, and the run log records it beside the
/// settings (the frames alone showed the held value).
#[test]
fn held_activations_are_recorded_in_the_run_log() {
    let dir = tmp_dir("cli-activation");
    let out = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
        .args(["--threads", "1", "simulate"])
        .arg(paper("droneman/droneman.json"))
        .args(["--steps", "2", "--every", "0", "--out"])
        .arg(&dir)
        .args(["--activation", "pneumatic3=0.25", "--activation", "pneumatic0=0.5"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let log: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("run.json")).unwrap()).unwrap();
    assert_eq!(
        log["activations"],
        serde_json::json!({ "pneumatic0": 0.5, "pneumatic3": 0.25 }),
        "{}",
        log["activations"]
    );
    // A value is a number, so the last '=' ends the name: `a=b=0.5` holds group `a=b`, and a
    // group that is not there is named as given.
    let out = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
        .args(["--threads", "1", "simulate"])
        .arg(paper("droneman/droneman.json"))
        .args(["--steps", "1", "--every", "0", "--out"])
        .arg(dir.join("eq"))
        .args(["--activation", "pneumatic=3=0.25"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("--activation pneumatic=3=0.25") && !e.contains("is not a number"),
        "{e}"
    );
}
