//! Hostile and careless input as a new user would give it: no panic, no abort, no silent wrong
//! answer, no lost or overwritten output. Each test drives the command-line tool or the
//! library the way the user would and checks the exit status, the message and the files.

use std::path::Path;
use std::process::Command;

use crate::common::{cube_scene, root, tmp_dir, write};
use crate::run::{diffsoft, generate_box, json, stderr, stdout};
use diffsoft::diff::{self, Controls, DiffError, Mode, Options, Param};

const DENSITY: &str = r#", "density": 1000"#;

/// A free-falling two-tet cube so stiff (E = 1e20) that the local-global iteration cannot meet
/// its tolerance within the cap: the gradient of such a run is refused unless asked for.
#[test]
fn an_unconverged_forward_is_an_error_unless_allowed() {
    let dir = tmp_dir("hard-unconverged");
    let scene = cube_scene(&dir, DENSITY, "");
    let sc = diffsoft::scene::load(&scene, Default::default()).unwrap();
    let mut model = sc.model.clone();
    Param::YOUNGS_MODULUS.set(&mut model, 1e20).unwrap();
    let loss = diff::loss::by_name("final_com.y").unwrap();
    assert!(sc.settings.tolerance > 0.0);
    let e = diff::gradient(
        &model,
        &sc.settings,
        10,
        &Controls::default(),
        loss.as_ref(),
        Options::default(),
    )
    .unwrap_err();
    assert!(matches!(e, DiffError::Unconverged { of: 10, .. }), "{e}");
    assert!(e.to_string().contains("did not converge"), "{e}");
    let g = diff::gradient(
        &model,
        &sc.settings,
        10,
        &Controls::default(),
        loss.as_ref(),
        Options {
            allow_unconverged: true,
            ..Options::mode(Mode::Unrolled)
        },
    )
    .unwrap();
    assert!(g.stats.unconverged_steps > 0);
    // A fixed iteration count (tolerance 0) is a deliberate, smooth forward: not refused when
    // the backward pass replays it exactly (the moderate material of the scene) ...
    let mut fixed = sc.settings.clone();
    fixed.tolerance = 0.0;
    fixed.max_iterations = 5;
    let g = diff::gradient(
        &sc.model,
        &fixed,
        10,
        &Controls::default(),
        loss.as_ref(),
        Options::default(),
    )
    .unwrap();
    assert!(g.stats.replay_deviation <= 1e-12, "{}", g.stats.replay_deviation);
    // ... but refused when round-off grows so fast at E = 1e20 that the replay leaves the
    // forward's trajectory: the gradient would be of another run.
    let e = diff::gradient(
        &model,
        &fixed,
        10,
        &Controls::default(),
        loss.as_ref(),
        Options::default(),
    )
    .unwrap_err();
    assert!(matches!(e, DiffError::NotReplayable { .. }), "{e}");

    let s = scene.to_str().unwrap();
    let stiff = [
        "grad",
        s,
        "--steps",
        "10",
        "--param",
        "density",
        "--set",
        "youngs_modulus=1e20",
    ];
    let o = diffsoft(&stiff);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(
        stderr(&o).contains("did not converge") && stderr(&o).contains("--allow-unconverged"),
        "{}",
        stderr(&o)
    );
    assert!(!stdout(&o).contains("d loss"), "no gradient is printed: {}", stdout(&o));
    let o = diffsoft(&[&stiff[..], &["--allow-unconverged"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("warning: ") && stdout(&o).contains("did not converge"),
        "{}",
        stdout(&o)
    );
}

#[test]
fn simulate_refuses_stale_output_and_overwrites_only_when_asked() {
    let dir = tmp_dir("hard-stale");
    let scene = cube_scene(&dir, DENSITY, "");
    let out = dir.join("out");
    let (s, o) = (scene.to_str().unwrap(), out.to_str().unwrap());
    let r = diffsoft(&["simulate", s, "--steps", "6", "--out", o]);
    assert!(r.status.success(), "{}", stderr(&r));
    assert_eq!(json(&out.join("run.json"))["status"], "completed");
    assert!(out.join("frame_00006.vtu").exists());
    // A second run into the same directory would leave the first run's frames beside its own.
    let r = diffsoft(&["simulate", s, "--steps", "2", "--out", o]);
    assert_eq!(r.status.code(), Some(1));
    assert!(
        stderr(&r).contains("earlier run") && stderr(&r).contains("--overwrite"),
        "{}",
        stderr(&r)
    );
    assert!(out.join("frame_00006.vtu").exists(), "the refused run touched nothing");
    let r = diffsoft(&["simulate", s, "--steps", "2", "--out", o, "--overwrite"]);
    assert!(r.status.success(), "{}", stderr(&r));
    assert!(!out.join("frame_00006.vtu").exists() && out.join("frame_00002.vtu").exists());
    let log = json(&out.join("run.json"));
    assert_eq!(log["frames"].as_array().unwrap().len(), 3);
    // --every 0: no frames, but the run log is written.
    let quiet = dir.join("quiet");
    let r = diffsoft(&[
        "simulate",
        s,
        "--steps",
        "3",
        "--every",
        "0",
        "--out",
        quiet.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let log = json(&quiet.join("run.json"));
    assert_eq!(
        (log["status"].as_str(), log["steps"].as_array().unwrap().len()),
        (Some("completed"), 3)
    );
    // An output directory that cannot be created is found before the run.
    let r = diffsoft(&["simulate", s, "--steps", "100000000", "--out", "/proc/diffsoft-out"]);
    assert_eq!(r.status.code(), Some(1));
    assert!(stderr(&r).contains("/proc/diffsoft-out"), "{}", stderr(&r));
}

#[test]
fn an_interrupted_simulation_finalises_its_log() {
    let dir = tmp_dir("hard-interrupt");
    let scene = cube_scene(
        &dir,
        DENSITY,
        r#", "obstacles": [{"plane": {"point": [0, -1, 0], "normal": [0, 1, 0]}, "friction": 0.3}]"#,
    );
    let out = dir.join("out");
    let mut child = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
        .args([
            "simulate",
            scene.to_str().unwrap(),
            "--steps",
            "100000000",
            "--every",
            "1000",
        ])
        .args(["--out", out.to_str().unwrap()])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until the run is under way (its log says so), then interrupt it.
    let t0 = std::time::Instant::now();
    while !(out.join("run.json").exists() && json(&out.join("run.json"))["status"] == "running") {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended before it was interrupted: {status}");
        }
        assert!(t0.elapsed().as_secs() < 60, "the run did not start");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    std::thread::sleep(std::time::Duration::from_millis(300));
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    assert!(stderr(&o).contains("interrupted after"), "{}", stderr(&o));
    let log = json(&out.join("run.json"));
    assert_eq!(log["status"], "interrupted");
    let steps = log["steps"].as_array().unwrap().len();
    assert!(
        steps > 0 && log["summary"]["steps"] == steps,
        "{steps} steps in the log"
    );
    for e in std::fs::read_dir(&out).unwrap() {
        let e = e.unwrap();
        let name = e.file_name().to_string_lossy().into_owned();
        assert!(!name.contains(".tmp."), "temporary file left: {name}");
        assert!(e.metadata().unwrap().len() > 0, "empty file left: {name}");
    }
}

#[test]
fn no_output_is_written_over_an_input() {
    let dir = tmp_dir("hard-input");
    let mesh = write(&dir, "m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3\n");
    let before = std::fs::read(&mesh).unwrap();
    let m = mesh.to_str().unwrap();
    let o = diffsoft(&["quality", "--mesh", m, "--json", m]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("over the input"), "{}", stderr(&o));
    let o = diffsoft(&[
        "bounds", "--mesh", m, "--rho", "1000", "--mu", "1e5", "--dt", "0.01", "--json", m,
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(std::fs::read(&mesh).unwrap(), before, "the mesh is untouched");
    let part = write(&dir, "p.json", "{}");
    let p = part.to_str().unwrap();
    let o = diffsoft(&["merge", p, "--out", p]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("over the input"), "{}", stderr(&o));
}

#[test]
fn json_dash_goes_to_standard_output_alone() {
    let mesh = root().join("python/tests/data/beam.obj");
    let o = diffsoft(&[
        "bounds",
        "--mesh",
        mesh.to_str().unwrap(),
        "--rho",
        "1000",
        "--mu",
        "1e5",
        "--dt",
        "0.01",
        "--json",
        "-",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("stdout is exactly the JSON report");
    assert!(v["schema"].as_str().unwrap().contains("bounds"), "{v}");
    assert!(!Path::new("-").exists(), "no file named '-'");
}

#[test]
fn sizes_a_user_types_are_checked_before_allocating() {
    let dir = tmp_dir("hard-sizes");
    let out = dir.join("m.obj");
    for cells in [
        "100000,100000,100000",
        "18446744073709551615,2,2",
        "4294967296,4294967296,1",
    ] {
        let o = diffsoft(&["generate", "--cells", cells, "--out", out.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(1), "--cells {cells}: {}", stderr(&o));
        assert!(stderr(&o).contains("cells"), "--cells {cells}: {}", stderr(&o));
    }
    let scene = cube_scene(&dir, DENSITY, "");
    for steps in ["18446744073709551615", "10000000000000"] {
        let o = diffsoft(&["simulate", scene.to_str().unwrap(), "--steps", steps]);
        assert_eq!(o.status.code(), Some(1), "--steps {steps}: {}", stderr(&o));
        assert!(stderr(&o).contains(&format!("--steps {steps}")), "{}", stderr(&o));
        let o = diffsoft(&[
            "grad",
            "--scene",
            scene.to_str().unwrap(),
            "--steps",
            steps,
            "--param",
            "density",
        ]);
        assert_eq!(o.status.code(), Some(1), "grad --steps {steps}: {}", stderr(&o));
        assert!(stderr(&o).contains("steps"), "{}", stderr(&o));
    }
    let o = diffsoft(&[
        "cloth",
        "--sizes",
        "4000000000",
        "--steps",
        "1",
        "--out",
        dir.join("c").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("4000000000"), "{}", stderr(&o));
}

#[test]
fn counts_and_scales_beyond_reason_are_errors_naming_the_flag() {
    let dir = tmp_dir("hard-flags");
    let mesh = root().join("python/tests/data/beam.obj");
    let m = mesh.to_str().unwrap();
    let max = u64::MAX.to_string();
    let beam = root()
        .join("python/tests/data/beam.json")
        .to_string_lossy()
        .into_owned();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["sweep", "--mesh", m, "--rho", "1000", "--mu", "1e5", "--points", &max],
            "--points",
        ),
        (
            vec![
                "sweep",
                "--mesh",
                m,
                "--rho",
                "1000",
                "--mu",
                "1e5",
                "--points",
                "100000000000",
            ],
            "--points",
        ),
        (
            vec!["gradcheck", "--steps", &max, "--json", "/tmp/diffsoft-never.json"],
            "--steps",
        ),
        (vec!["tradeoff", "--cantilever", "4,1,1", "--steps", &max], "--steps"),
        (
            vec!["tradeoff", "--cantilever", "4,1,1", "--steps", "1000000000000"],
            "--steps",
        ),
        (
            vec![
                "bounds", "--mesh", m, "--rho", "1000", "--mu", "1e5", "--dt", "0.01", "--scale", "1e300",
            ],
            "--scale",
        ),
        (
            vec![
                "bounds", "--mesh", m, "--rho", "1000", "--mu", "1e5", "--dt", "0.01", "--scale", "1e-300",
            ],
            "--scale",
        ),
        // Operators that overflow: the message names the inputs that built them.
        (
            vec!["bounds", "--mesh", m, "--rho", "1000", "--mu", "1e308", "--dt", "0.01"],
            "--mu 1e308",
        ),
        (
            vec!["bounds", "--mesh", m, "--rho", "1000", "--mu", "1e4", "--dt", "1e300"],
            "--dt 1e300",
        ),
        (
            vec![
                "sweep", "--mesh", m, "--rho", "1000", "--mu", "1e4", "--dt-max", "1e300",
            ],
            "to 1e300",
        ),
        // A relative tolerance of 1 or more: refused before any run, not a row the solver rejects.
        (
            vec!["tradeoff", "--cantilever", "2,1,1", "--steps", "2", "--tolerances", "2"],
            "tolerances must be finite, positive and below 1, got 2",
        ),
        (
            vec![
                "grad",
                &beam,
                "--steps",
                "2",
                "--param",
                "youngs_modulus",
                "--mode",
                "implicit",
                "--implicit-tolerance",
                "10",
            ],
            "--implicit-tolerance is a relative residual and must be in (0, 1), got 10",
        ),
        // A plots directory that is a file: refused before the sweep runs.
        (
            vec!["tradeoff", "--cantilever", "2,1,1", "--steps", "2", "--svg-dir", &beam],
            "--svg-dir must name a directory, and this is a regular file",
        ),
        // Values no flag can take: NaN, negative or zero where a time step, a threshold or a
        // step count is meant; a study with no case in the subset asked for.
        (
            vec!["sweep", "--mesh", m, "--rho", "1000", "--mu", "1e5", "--mark-dt", "nan"],
            "--mark-dt",
        ),
        (
            vec!["sweep", "--mesh", m, "--rho", "1000", "--mu", "1e5", "--mark-dt", "-5"],
            "--mark-dt",
        ),
        (
            vec![
                "bounds",
                "--mesh",
                m,
                "--rho",
                "1000",
                "--mu",
                "1e5",
                "--dt",
                "0.01",
                "--min-tet-quality",
                "nan",
            ],
            "--min-tet-quality",
        ),
        (
            vec!["gradcheck", "--steps", "0", "--json", "/tmp/diffsoft-never.json"],
            "--steps",
        ),
        (
            vec![
                "validate",
                "--study",
                "hertz",
                "--subset",
                "fast",
                "--json",
                "/tmp/diffsoft-never.json",
            ],
            "--study hertz",
        ),
        // A loss the scene cannot have, refused before the sweep runs; more shards than items.
        (
            vec![
                "tradeoff",
                "--cantilever",
                "2,1,1",
                "--steps",
                "2",
                "--loss",
                "joint_angle.x",
            ],
            "joint_angle.x: the model has no skeleton",
        ),
        (
            vec![
                "extremes",
                "--subset",
                "fast",
                "--shard",
                "0/100000",
                "--json",
                "/tmp/diffsoft-never.json",
            ],
            "--shard 0/100000: more shards than",
        ),
        (
            vec![
                "cloth",
                "--sizes",
                "4,4",
                "--steps",
                "1",
                "--out",
                "/tmp/diffsoft-never",
            ],
            "--sizes [4, 4]",
        ),
        (
            vec![
                "grad", &beam, "--steps", "2", "--param", "density", "--param", "density",
            ],
            "--param density: given twice",
        ),
        (
            vec![
                "tradeoff",
                "--cantilever",
                "2,1,1",
                "--steps",
                "2",
                "--targets",
                "0.1,0.1",
            ],
            "targets must be distinct",
        ),
    ];
    for (args, flag) in cases {
        let o = diffsoft(&args);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(flag) && !stderr(&o).contains("panicked"),
            "{args:?}: {}",
            stderr(&o)
        );
    }
    let o = diffsoft(&["--threads", "100000", "quality", "--mesh", m]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--threads"), "{}", stderr(&o));
    // The same bound for rayon's variable, which --threads overrides.
    let bin = env!("CARGO_BIN_EXE_diffsoft");
    let run = |args: &[&str]| {
        std::process::Command::new(bin)
            .args(args)
            .env("RAYON_NUM_THREADS", "50000")
            .output()
            .unwrap()
    };
    let o = run(&["quality", "--mesh", m]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("RAYON_NUM_THREADS=50000: at most 4096"),
        "{}",
        stderr(&o)
    );
    let o = run(&["--threads", "1", "quality", "--mesh", m]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = dir.join("huge.obj");
    let o = diffsoft(&[
        "generate",
        "--cells",
        "1,1,1",
        "--size",
        "1e308,1e308,1e308",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("overflows"), "not 'degenerate': {}", stderr(&o));
    assert!(
        stderr(&o).contains("--size 1e308,1e308,1e308"),
        "names the flag: {}",
        stderr(&o)
    );
    // A negative edge length is refused as such, by the flag and by the library (a box of
    // negative size used to be built mirrored).
    let o = diffsoft(&[
        "generate",
        "--cells",
        "2,1,1",
        "--size",
        "1,-1,1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("'--size <SIZE>': must be finite and positive, got -1"),
        "{}",
        stderr(&o)
    );
    let spec = diffsoft::mesh::generate::BoxSpec::new([2, 1, 1], [-1.0, 1.0, 1.0]);
    let e = spec.build().unwrap_err().to_string();
    assert!(
        e.contains("every edge length must be finite and positive, got -1"),
        "{e}"
    );
}

/// `simulate --tolerance` and `--anderson` mean what they mean on `grad`: tolerance 0 runs
/// exactly the cap every step, the settings land in the run log, and bad values are errors
/// naming the setting.
#[test]
fn simulate_takes_tolerance_and_anderson() {
    let dir = tmp_dir("hard-sim-tolerance");
    let scene = root().join("verification/paper/bridgesus/bridgesus.json");
    let out = dir.join("run");
    let s = scene.to_str().unwrap();
    let o = out.to_str().unwrap();
    let ok = diffsoft(&[
        "--threads",
        "1",
        "simulate",
        s,
        "--steps",
        "3",
        "--every",
        "0",
        "--out",
        o,
        "--tolerance",
        "0",
        "--max-iterations",
        "4",
        "--anderson",
        "3",
    ]);
    assert!(ok.status.success(), "{}", stderr(&ok));
    let log = json(&out.join("run.json"));
    assert_eq!(log["settings"]["tolerance"].as_f64(), Some(0.0));
    assert_eq!(log["settings"]["anderson"].as_u64(), Some(3));
    for step in log["steps"].as_array().unwrap() {
        assert_eq!(step["iterations"].as_u64(), Some(4), "{step}");
    }
    // A negative tolerance, and one of the whole length scale or more (every step would stop
    // at its first iteration): refused, naming it.
    for (tolerance, message) in [
        ("-1", "tolerance must be finite and >= 0"),
        ("1e300", "tolerance must be below 1"),
    ] {
        let bad = diffsoft(&[
            "simulate",
            s,
            "--steps",
            "1",
            "--every",
            "0",
            "--out",
            o,
            "--overwrite",
            "--tolerance",
            tolerance,
        ]);
        assert_eq!(bad.status.code(), Some(1), "{}", stderr(&bad));
        assert!(stderr(&bad).contains(message), "{}", stderr(&bad));
    }
}

/// Collisions between bodies whose contact solve stops at its cap: the steps "converge" (the
/// outer test passes on the capped contact iterate), but their states solve no contact problem
/// and an unrolled gradient through them can be off by many orders of magnitude. Such a
/// gradient is refused in both modes, from the library and the CLI, and `simulate` warns.
#[test]
fn a_gradient_through_capped_contact_solves_is_refused() {
    let path = root().join("verification/scenes/ball_on_cloth.json");
    let sc = diffsoft::scene::load(&path, Default::default()).unwrap();
    let mut settings = sc.settings.clone();
    settings.solver = diffsoft::solver::SolverKind::Direct;
    settings.inner_max_iterations = 1;
    let loss = diff::loss::by_name("final_com.y").unwrap();
    for mode in [Mode::Unrolled, Mode::Implicit] {
        let e = diff::gradient(
            &sc.model,
            &settings,
            60,
            &Controls::default(),
            loss.as_ref(),
            Options::mode(mode),
        )
        .unwrap_err();
        match e {
            DiffError::CappedSolves { steps, of: 60, .. } => assert!(steps > 0),
            other => panic!("{mode:?}: {other}"),
        }
        let allowed = diff::gradient(
            &sc.model,
            &settings,
            60,
            &Controls::default(),
            loss.as_ref(),
            Options {
                allow_unconverged: true,
                ..Options::mode(mode)
            },
        );
        if let Ok(g) = allowed {
            assert!(g.stats.unconverged_steps > 0, "{mode:?}: the stats say so");
        }
    }
    // The CLI: exit 1, the reason and the way out named.
    let dir = tmp_dir("hard-capped");
    let mut v = json(&path);
    v["solver"]["inner_max_iterations"] = serde_json::json!(1);
    v["cloths"][0]["mesh"] = serde_json::json!(root().join("verification/paper/cloth_ball/flag2.obj"));
    v["bodies"][0]["mesh"] = serde_json::json!(root().join("verification/paper/droneman/ball_tet.obj"));
    let scene = write(&dir, "capped.json", &v.to_string());
    let o = diffsoft(&["grad", scene.to_str().unwrap(), "--steps", "60", "--param", "density"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("stopped a global or contact solve unconverged"),
        "{}",
        stderr(&o)
    );
    assert!(stderr(&o).contains("--allow-unconverged"), "{}", stderr(&o));
}

/// Input that passes the scene's checks but breaks double precision or memory: a Young's
/// modulus whose weight underflows, and an Anderson memory of a million slots (8 TB). Each is a
/// clear error (exit 1) naming what to change, never a panic (101) or an abort.
#[test]
fn weights_that_underflow_and_huge_anderson_memories_are_errors() {
    let dir = tmp_dir("hard-underflow");
    for e in ["5e-324", "1e-320"] {
        let scene = cube_scene(&dir, DENSITY, "");
        let text = std::fs::read_to_string(&scene).unwrap().replace("1e5", e);
        let scene = write(&dir, "tiny.json", &text);
        for args in [
            vec!["simulate", scene.to_str().unwrap(), "--steps", "2"],
            vec!["grad", scene.to_str().unwrap(), "--steps", "2", "--param", "density"],
        ] {
            let o = diffsoft(&args);
            assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
            let err = stderr(&o);
            assert!(
                err.contains("body 'c', tet 0") && err.contains("rescale the units"),
                "{err}"
            );
        }
    }
    let scene = cube_scene(&dir, DENSITY, "");
    let o = diffsoft(&[
        "simulate",
        scene.to_str().unwrap(),
        "--steps",
        "2",
        "--anderson",
        "1000000",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("anderson memory must be at most 64"),
        "{}",
        stderr(&o)
    );
    let o = diffsoft(&["simulate", scene.to_str().unwrap(), "--steps", "2", "--anderson", "8"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// `--json` writes what the path really is: through a symbolic link (the link stays), into a
/// character device in place (never replaced by a regular file); and a closed or full standard
/// output loses the text only (no panic, the run's files still written).
#[test]
fn outputs_respect_links_devices_and_closed_streams() {
    let dir = tmp_dir("hard-files");
    let scene = cube_scene(&dir, DENSITY, "");
    let s = scene.to_str().unwrap();
    let link = dir.join("link.json");
    let _ = std::fs::remove_file(&link);
    let _ = std::fs::remove_file(dir.join("real.json"));
    std::os::unix::fs::symlink("real.json", &link).unwrap();
    let o = diffsoft(&[
        "grad",
        s,
        "--steps",
        "2",
        "--param",
        "density",
        "--json",
        link.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    assert!(json(&dir.join("real.json"))["schema"].is_string());
    // A device is written in place.
    let o = diffsoft(&["grad", s, "--steps", "2", "--param", "density", "--json", "/dev/null"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata("/dev/null").unwrap().file_type().is_char_device());
    // Standard output full (Linux's /dev/full) or closed: no panic, the log still written.
    let run = dir.join("run-full");
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
        .args([
            "simulate",
            s,
            "--steps",
            "3",
            "--out",
            run.to_str().unwrap(),
            "--overwrite",
        ])
        .stdout(full)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(json(&run.join("run.json"))["status"], "completed");
    let mut child = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
        .args(["grad", s, "--steps", "20", "--param", "density"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // the reader goes away at once
    let o = child.wait_with_output().unwrap();
    assert_ne!(o.status.code(), Some(101), "{}", stderr(&o));
    assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
}

/// Outputs never replace inputs the command line does not name: the scene's mesh (`grad
/// scene.json --json box.obj`), the `.ele` of a `.node` mesh, and one output of the same
/// command (`sweep --json X --svg X`). Each is refused before the work, the file untouched.
#[test]
fn outputs_never_replace_inputs_a_scene_or_mesh_brings() {
    let dir = tmp_dir("hard-family");
    let scene = cube_scene(&dir, DENSITY, "");
    let mesh = dir.join("cube.obj");
    let before = std::fs::read(&mesh).unwrap();
    let o = diffsoft(&[
        "grad",
        scene.to_str().unwrap(),
        "--steps",
        "2",
        "--param",
        "density",
        "--json",
        mesh.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("refusing to write the output over the input"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(&mesh).unwrap(), before);
    let node = write(&dir, "t.node", "5 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n4 1 1 1\n");
    let ele = write(&dir, "t.ele", "2 4 0\n0 0 1 2 3\n1 1 2 3 4\n");
    let ele_before = std::fs::read(&ele).unwrap();
    let mesh_args = ["--mesh", node.to_str().unwrap(), "--rho", "1000", "--mu", "1e5"];
    let mut args = vec!["bounds", "--dt", "0.01", "--json", ele.to_str().unwrap()];
    args.extend(mesh_args);
    let o = diffsoft(&args);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert_eq!(std::fs::read(&ele).unwrap(), ele_before);
    let same = dir.join("same.out");
    let mut args = vec![
        "sweep",
        "--points",
        "3",
        "--json",
        same.to_str().unwrap(),
        "--svg",
        same.to_str().unwrap(),
    ];
    args.extend(mesh_args);
    let o = diffsoft(&args);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("name the same file"), "{}", stderr(&o));
}

/// Under an address-space limit (`ulimit -v`) the memory guard counts the room the limit
/// leaves, not the host's free memory: a gradient whose checkpoints cannot fit is an error
/// naming the limit (exit 1), not an abort.
#[test]
fn the_memory_guard_respects_address_space_limits() {
    let dir = tmp_dir("hard-rlimit");
    let scene = cube_scene(&dir, DENSITY, "");
    let script = format!(
        "ulimit -v 800000 && exec '{}' grad '{}' --steps 30000000 --param density",
        env!("CARGO_BIN_EXE_diffsoft"),
        scene.display()
    );
    let o = Command::new("sh").args(["-c", &script]).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("address-space limit"), "{}", stderr(&o));
}

/// A body that starts inside the ground is refused before the first step, naming the body,
/// the vertex, the obstacle and the depth (it used to be flattened and launched at hundreds of
/// m/s while the run reported no penetration); the run log records the failure instead of
/// staying `starting`.
#[test]
fn a_body_starting_inside_an_obstacle_is_refused_and_logged() {
    let dir = tmp_dir("hard-inside");
    let ground = r#", "obstacles": [{ "name": "ground", "plane": { "point": [0, 0.5, 0], "normal": [0, 1, 0] }, "friction": 0.3 }]"#;
    let scene = cube_scene(&dir, DENSITY, ground);
    let run = dir.join("run");
    let o = diffsoft(&[
        "simulate",
        scene.to_str().unwrap(),
        "--steps",
        "3",
        "--out",
        run.to_str().unwrap(),
        "--overwrite",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("body 'c': vertex") && err.contains("inside obstacle 'ground'"),
        "{err}"
    );
    let log = json(&run.join("run.json"));
    assert_eq!(log["status"], "failed");
    assert!(
        log["error"].as_str().unwrap().contains("inside obstacle 'ground'"),
        "{log}"
    );
    let o = diffsoft(&["grad", scene.to_str().unwrap(), "--steps", "3", "--param", "density"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    // Resting exactly on the ground is not inside it.
    let touching = r#", "obstacles": [{ "name": "ground", "plane": { "point": [0, 0, 0], "normal": [0, 1, 0] }, "friction": 0.3 }]"#;
    let scene = cube_scene(&dir, DENSITY, touching);
    let o = diffsoft(&["simulate", scene.to_str().unwrap(), "--steps", "3"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// What a user gets wrong in a scene that parses: duplicates are errors naming what repeats;
/// tiny but non-zero directions are directions; a file without an extension says so. Every
/// message is one line.
#[test]
fn duplicates_are_errors_and_tiny_directions_are_directions() {
    let dir = tmp_dir("hard-duplicates");
    let check = |scene: &Path, wanted: &str| {
        let o = diffsoft(&["simulate", scene.to_str().unwrap(), "--steps", "1"]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(wanted), "{wanted}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    };
    // The same tet twice, its vertices in another order.
    write(
        &dir,
        "dup.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3\nt 3 2 1 0\n",
    );
    let scene = write(
        &dir,
        "dup_tet.json",
        r#"{ "schema": "diffsoft.scene/1", "time_step": 0.01, "bodies": [{ "name": "a", "mesh": "dup.obj",
             "material": { "youngs_modulus": 1e5, "poisson_ratio": 0.3 }, "density": 1000 }] }"#,
    );
    check(&scene, "dup.obj:6: tet 1 repeats tet 0");
    // One vertex attached twice (in one list or two attachments): its stiffness would double.
    write(&dir, "one.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3\n");
    for attachments in [
        r#"[{ "stiffness": 1e4, "vertices": { "indices": [0, 0] } }]"#,
        r#"[{ "stiffness": 1e4, "vertices": { "indices": [2, 0] } }, { "stiffness": 1e3, "vertices": { "indices": [0] } }]"#,
    ] {
        let scene = write(
            &dir,
            "dup_attach.json",
            &format!(
                r#"{{ "schema": "diffsoft.scene/1", "time_step": 0.01, "bodies": [{{ "name": "a", "mesh": "one.obj",
                 "material": {{ "youngs_modulus": 1e5, "poisson_ratio": 0.3 }}, "density": 1000, "attachments": {attachments} }}] }}"#
            ),
        );
        check(&scene, "body 'a': vertex 0 is attached twice");
    }
    // Two bodies of one name.
    write(&dir, "a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3\n");
    write(&dir, "b.obj", "v 5 0 0\nv 6 0 0\nv 5 1 0\nv 5 0 1\nt 0 1 2 3\n");
    let body = |mesh: &str| {
        format!(
            r#"{{ "name": "twin", "mesh": "{mesh}", "material": {{ "youngs_modulus": 1e5, "poisson_ratio": 0.3 }}, "density": 1000 }}"#
        )
    };
    let scene = write(
        &dir,
        "dup_name.json",
        &format!(
            r#"{{ "schema": "diffsoft.scene/1", "time_step": 0.01, "bodies": [{}, {}] }}"#,
            body("a.obj"),
            body("b.obj")
        ),
    );
    check(&scene, "body name 'twin' is used twice");
    // An actuator that lists a tet twice.
    let scene = cube_scene(
        &dir,
        r#", "density": 1000, "actuators": [{ "name": "p", "pneumatic": { "tets": { "indices": [0, 1, 0] } }, "stiffness": 1e4, "activation": 1.1 }]"#,
        "",
    );
    check(&scene, "actuator 'p': tet 0 is listed twice");
    // A plane normal of 1e-200 (its norm underflows to 0 when squared) is a direction.
    let scene = cube_scene(
        &dir,
        DENSITY,
        r#", "obstacles": [{ "name": "g", "plane": { "point": [0, -1, 0], "normal": [0, 1e-200, 0] }, "friction": 0.3 }]"#,
    );
    let o = diffsoft(&["simulate", scene.to_str().unwrap(), "--steps", "1"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // A mesh named `x.`: no extension, said so (not "extension '.'").
    write(&dir, "x.", "v 0 0 0\n");
    let scene = write(
        &dir,
        "no_ext.json",
        r#"{ "schema": "diffsoft.scene/1", "time_step": 0.01, "bodies": [{ "name": "a", "mesh": "x.",
             "material": { "youngs_modulus": 1e5, "poisson_ratio": 0.3 }, "density": 1000 }] }"#,
    );
    check(&scene, "no file extension (expected .obj");
}

/// Values beyond reason in a scene file are errors naming the element and the field, in both
/// formats: a scale that is negative or leaves the mesh's volumes outside f64's range (bodies,
/// cloths, obstacle meshes), a joint position far beyond its body, a key given twice with
/// different values (the paper format kept the last); harmless oddities are notes.
#[test]
fn scales_joints_and_repeated_keys_beyond_reason_are_errors_naming_the_field() {
    let dir = tmp_dir("hard-ranges");
    let refused = |scene: &Path, wanted: &[&str]| {
        let o = diffsoft(&["simulate", scene.to_str().unwrap(), "--steps", "1"]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{err}");
        for w in wanted {
            assert!(err.contains(w), "{w}: {err}");
        }
    };
    write(&dir, "tri.obj", "v -1 0 -1\nv 1 0 -1\nv 0 0 1\nf 1 2 3\n");
    for (scale, what) in [
        ("-1", "scale must be finite and positive, got -1"),
        ("1e300", "outside 1e-90 to 1e90 m"),
    ] {
        let scene = cube_scene(
            &dir,
            DENSITY,
            &format!(
                r#", "obstacles": [{{ "name": "floor", "mesh": {{ "file": "tri.obj", "scale": {scale} }}, "friction": 0.3 }}]"#
            ),
        );
        refused(&scene, &["obstacle 'floor' mesh", what]);
    }
    for scale in ["1e200", "1e-200"] {
        let scene = cube_scene(&dir, &format!(r#", "density": 1000, "scale": {scale}"#), "");
        refused(&scene, &["body 'c'", &format!("scale {scale}"), "rescale the units"]);
    }
    // A joint 1e300 m away; at 10 m it is used.
    for (x, ok) in [("1e300", false), ("10", true)] {
        let scene = cube_scene(
            &dir,
            &format!(
                r#", "density": 1000, "skeleton": {{ "bones": [{{ "name": "root", "joint": {{ "free": {{}} }}, "vertices": {{ "indices": [0] }} }},
                    {{ "name": "arm", "parent": "root", "joint": {{ "rotational": {{ "position": [{x}, 0, 0], "axis": [0, 0, 1] }} }}, "vertices": {{ "indices": [4] }} }}] }}"#
            ),
            "",
        );
        let o = diffsoft(&["simulate", scene.to_str().unwrap(), "--steps", "1"]);
        if ok {
            assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        } else {
            refused(&scene, &["body 'c': bone 'arm': joint position", "beyond 1e8 times"]);
        }
    }
    // A time step of 1e300 fails in the set-up; the error names it.
    let text = std::fs::read_to_string(cube_scene(&dir, DENSITY, "")).unwrap();
    let huge = write(
        &dir,
        "huge_dt.json",
        &text.replace("\"time_step\": 0.01", "\"time_step\": 1e300"),
    );
    for solver in ["auto", "direct"] {
        let o = diffsoft(&["simulate", huge.to_str().unwrap(), "--steps", "1", "--solver", solver]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("(inputs at the edge of floating point: time_step = 1e300)"),
            "{solver}: {}",
            stderr(&o)
        );
    }
    // A velocity or a torque at the edge of floating point: the failure names it, with its
    // element (these messages named nothing before).
    let fast = cube_scene(&dir, r#", "density": 1000, "initial_velocity": [0, -1e300, 0]"#, "");
    let o = diffsoft(&["simulate", fast.to_str().unwrap(), "--steps", "2"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("initial velocity of vertex 0 = -1e300"),
        "{}",
        stderr(&o)
    );
    let torque = cube_scene(
        &dir,
        r#", "density": 1000, "skeleton": { "bones": [{ "name": "root", "joint": { "free": {} }, "vertices": { "indices": [0] } },
            { "name": "arm", "parent": "root", "joint": { "rotational": { "position": [0.5, 0, 0], "axis": [0, 0, 1] } },
              "vertices": { "indices": [4] }, "torque": { "times": [0, 1], "values": [1e308, 1e308] } }] }"#,
        "",
    );
    let o = diffsoft(&["simulate", torque.to_str().unwrap(), "--steps", "2"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("torque of bone 'arm' = 1e308"), "{}", stderr(&o));
    // The paper format: a key given twice with different values, and an attachment stiffness
    // without vertices (the scene's own directory layout: `bridgesus/bridgesus.json` names its
    // mesh as `bridgesus/...`).
    let paper = dir.join("bridgesus");
    std::fs::create_dir_all(&paper).unwrap();
    let src = root().join("verification/paper/bridgesus");
    for f in ["bridgesus.json", "bridgesus200_tet_cen.obj"] {
        std::fs::copy(src.join(f), paper.join(f)).unwrap();
    }
    let text = std::fs::read_to_string(paper.join("bridgesus.json")).unwrap();
    let twice = text.replacen("\"Youngs Modulus\"", "\"Youngs Modulus\" : 5e3, \"Youngs Modulus\"", 1);
    assert_ne!(twice, text);
    refused(
        &write(&paper, "twice.json", &twice),
        &[
            "twice.json",
            "key \"Youngs Modulus\" is given twice in one object with different values",
            "line ",
        ],
    );
    let start = text.find("\"Attach Verts\"").unwrap();
    let end = start + text[start..].find("\"Attach Stiffness\"").unwrap();
    let lone = format!("{}{}", &text[..start], text[end..].replacen("1e20", "-1", 1));
    let o = diffsoft(&[
        "simulate",
        write(&paper, "lone.json", &lone).to_str().unwrap(),
        "--steps",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("\"Attach Stiffness\" -1 without \"Attach Verts\" attaches nothing; ignored"),
        "{}",
        stdout(&o)
    );
}

/// Two bodies that start through each other, with collisions on, are refused before the first
/// step, naming both and the depth; touching or within the collision thickness is fine.
#[test]
fn bodies_starting_through_each_other_are_refused() {
    let dir = tmp_dir("hard-overlap");
    write(
        &dir,
        "a.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\nt 0 1 2 3\nt 1 2 3 4\n",
    );
    let scene = |name: &str, dy: f64| {
        let body = |n: &str, y: f64| {
            format!(
                r#"{{ "name": "{n}", "mesh": "a.obj", "translate": [0.2, {y}, 0.2], "material": {{ "youngs_modulus": 1e5, "poisson_ratio": 0.3 }}, "density": 1000 }}"#
            )
        };
        write(
            &dir,
            name,
            &format!(
                r#"{{ "schema": "diffsoft.scene/1", "time_step": 0.01, "gravity": [0, 0, 0],
                     "collisions": {{ "thickness": 1e-3, "friction": 0.2 }},
                     "bodies": [{}, {}] }}"#,
                body("lower", 0.0),
                body("upper", dy)
            ),
        )
    };
    let through = scene("through.json", 0.5);
    for cmd in ["simulate", "grad"] {
        let mut args = vec![cmd, through.to_str().unwrap(), "--steps", "2"];
        if cmd == "grad" {
            args.extend(["--param", "density"]);
        }
        let o = diffsoft(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{cmd}: {err}");
        assert!(err.contains("starts") && err.contains("inside body"), "{err}");
        assert!(err.contains("'lower'") && err.contains("'upper'"), "{err}");
    }
    // Apart (0.5 m above the lower body's top vertex): runs.
    let apart = scene("apart.json", 1.5);
    let o = diffsoft(&["simulate", apart.to_str().unwrap(), "--steps", "2"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// A body resting exactly on the ground with no load: its contacts touch with zero gap and zero
/// force, where the loss has a kink (the one-sided derivatives in the initial velocity differ,
/// 0.1 and 0.04). The gradient is one of them or between them: both modes say so, in the
/// output and in the stats; the same body pressed by gravity (a smooth point) does not.
#[test]
fn a_gradient_at_a_contact_kink_is_flagged() {
    let dir = tmp_dir("hard-kink");
    write(
        &dir,
        "cube.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\nt 0 1 2 3\nt 1 2 3 4\n",
    );
    let scene = |gravity: &str| {
        write(
            &dir,
            &format!("scene{gravity}.json"),
            &format!(
                r#"{{ "schema": "diffsoft.scene/1", "time_step": 0.01, "gravity": [0, {gravity}, 0],
                     "bodies": [{{ "name": "c", "mesh": "cube.obj", "material": {{ "youngs_modulus": 1e4, "poisson_ratio": 0.3 }}, "density": 1000 }}],
                     "obstacles": [{{ "name": "ground", "plane": {{ "point": [0, 0, 0], "normal": [0, 1, 0] }}, "friction": 0.3 }}],
                     "solver": {{ "solver": "direct", "tolerance": 1e-10, "max_iterations": 200 }} }}"#
            ),
        )
    };
    let json_path = dir.join("g.json");
    let grad = |scene: &Path, mode: &str| {
        let o = diffsoft(&[
            "grad",
            scene.to_str().unwrap(),
            "--steps",
            "10",
            "--param",
            "initial_velocity.y",
            "--mode",
            mode,
            "--json",
            json_path.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        (
            stderr(&o),
            json(&json_path)["stats"]["nonsmooth_steps"].as_u64().unwrap(),
        )
    };
    let resting = scene("0");
    for mode in ["implicit", "unrolled"] {
        let (err, kinks) = grad(&resting, mode);
        assert!(kinks > 0 && err.contains("switch of regime"), "{mode}: {kinks} {err}");
    }
    let pressed = scene("-9.81");
    for mode in ["implicit", "unrolled"] {
        let (err, kinks) = grad(&pressed, mode);
        assert!(kinks == 0 && !err.contains("switch of regime"), "{mode}: {kinks} {err}");
    }
}

/// More ways to start inside: two coincident bodies (every vertex on the other's surface, found
/// by the tets' centres), a body inside a closed mesh obstacle, a body through an open mesh
/// obstacle (a sheet). Resting on the sheet is fine.
#[test]
fn coincident_bodies_and_bodies_inside_or_through_mesh_obstacles_are_refused() {
    let dir = tmp_dir("hard-inside-mesh");
    write(
        &dir,
        "c.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\nt 0 1 2 3\nt 1 2 3 4\n",
    );
    let box_obj = "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n\
                   f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 8 7\nf 4 7 3\nf 1 5 8\nf 1 8 4\nf 2 3 7\nf 2 7 6\n";
    write(&dir, "block.obj", box_obj);
    write(
        &dir,
        "sheet.obj",
        "v -5 0 -5\nv 5 0 -5\nv 5 0 5\nv -5 0 5\nf 1 2 3\nf 1 3 4\n",
    );
    let body = |name: &str, y: f64| {
        format!(
            r#"{{ "name": "{name}", "mesh": "c.obj", "translate": [0.1, {y}, 0.1], "material": {{ "youngs_modulus": 1e5, "poisson_ratio": 0.3 }}, "density": 1000 }}"#
        )
    };
    let scene = |file: &str, bodies: &str, extra: &str| {
        write(
            &dir,
            file,
            &format!(
                r#"{{ "schema": "diffsoft.scene/1", "time_step": 0.01, "gravity": [0, 0, 0], "bodies": [{bodies}]{extra} }}"#
            ),
        )
    };
    let refused = |scene: &Path, wanted: &[&str]| {
        let o = diffsoft(&["simulate", scene.to_str().unwrap(), "--steps", "1"]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{err}");
        for w in wanted {
            assert!(err.contains(w), "{w}: {err}");
        }
    };
    let coincident = scene(
        "coincident.json",
        &format!("{}, {}", body("a", 0.0), body("b", 0.0)),
        r#", "collisions": { "thickness": 1e-3, "friction": 0.2 }"#,
    );
    refused(&coincident, &["starts inside body", "centre of tet"]);
    let obstacle = |mesh: &str, scale: f64| {
        format!(
            r#", "obstacles": [{{ "name": "ob", "mesh": {{ "file": "{mesh}", "scale": {scale} }}, "friction": 0.3, "thickness": 1e-3 }}]"#
        )
    };
    let inside = scene("inside.json", &body("a", -0.5), &obstacle("block.obj", 3.0));
    refused(&inside, &["body 'a'", "inside obstacle 'ob'"]);
    let through = scene("through.json", &body("a", -0.5), &obstacle("sheet.obj", 1.0));
    refused(
        &through,
        &["body 'a' starts through obstacle 'ob'", "crosses its surface"],
    );
    let resting = scene("resting.json", &body("a", 0.0), &obstacle("sheet.obj", 1.0));
    let o = diffsoft(&["simulate", resting.to_str().unwrap(), "--steps", "1"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// An implicit adjoint stopped at its iteration cap before converging is reported: its
/// residual is in the stats and the gradient's warnings say what it means.
#[test]
fn an_adjoint_stopped_at_its_cap_is_reported() {
    let model = crate::common::ground_box(0.5).unwrap();
    let settings = diffsoft::Settings {
        tolerance: 1e-10,
        max_iterations: 200,
        solver: diffsoft::SolverKind::Direct,
        ..Default::default()
    };
    let loss = diff::loss::by_name("final_com.y").unwrap();
    let run = |cap: usize| {
        diff::gradient(
            &model,
            &settings,
            30,
            &Controls::default(),
            loss.as_ref(),
            Options {
                implicit_max_iterations: cap,
                implicit_anderson: 0,
                ..Options::mode(Mode::Implicit)
            },
        )
    };
    let full = run(300).unwrap();
    assert!(full.stats.warnings(30).is_empty(), "{:?}", full.stats.warnings(30));
    // Six adjoint iterations leave a residual of about 4e-3 on this run.
    let capped = run(6).unwrap();
    let w = capped.stats.warnings(30);
    assert!(capped.stats.implicit_residual > 1e-6, "{:?}", capped.stats);
    assert!(w.iter().any(|w| w.contains("implicit adjoint stopped")), "{w:?}");
    // Two iterations leave the iterates still changing by more than 10%: refused outright.
    let e = run(2).unwrap_err();
    assert!(e.to_string().contains("fixed point diverged"), "{e}");
}

/// `simulate` says when steps stop at the iteration cap (here a free-falling cube so stiff that
/// one iteration does not meet the tolerance), unless a fixed count was asked for; refuses zero steps and a NaN time step naming the flag, and
/// never writes through a link or into a FIFO named like one of its files.
#[test]
fn simulate_warns_of_unconverged_steps_and_refuses_special_files() {
    let dir = tmp_dir("hard-sim-warn");
    let scene = cube_scene(&dir, r#", "density": 1000"#, "");
    let text = std::fs::read_to_string(&scene).unwrap().replace("1e5", "1e17");
    std::fs::write(&scene, text).unwrap();
    let s = scene.to_str().unwrap();
    let o = diffsoft(&["simulate", s, "--steps", "5", "--max-iterations", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("steps stopped at the iteration cap (max_iterations 1)"),
        "{}",
        stdout(&o)
    );
    let o = diffsoft(&[
        "simulate",
        s,
        "--steps",
        "5",
        "--max-iterations",
        "1",
        "--tolerance",
        "0",
    ]);
    assert!(
        !stdout(&o).contains("stopped at the iteration cap"),
        "a fixed count is asked for: {}",
        stdout(&o)
    );
    for (flag, value) in [("--steps", "0"), ("--dt", "nan")] {
        let o = diffsoft(&["simulate", s, flag, value]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains(flag), "{}", stderr(&o));
    }
    // A link named run.json in --out pointing at the scene: refused, the scene intact.
    let before = std::fs::read(&scene).unwrap();
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    std::os::unix::fs::symlink(&scene, out.join("run.json")).unwrap();
    for extra in [&[][..], &["--overwrite"][..]] {
        let mut args = vec!["simulate", s, "--steps", "2", "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = diffsoft(&args);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains("symbolic link"), "{}", stderr(&o));
    }
    assert_eq!(std::fs::read(&scene).unwrap(), before);
    std::fs::remove_file(out.join("run.json")).unwrap();
    // A FIFO named like a frame: refused at once (it would block the run forever).
    let made = Command::new("mkfifo")
        .arg(out.join("frame_00001.vtu"))
        .status()
        .unwrap();
    assert!(made.success());
    let o = diffsoft(&[
        "simulate",
        s,
        "--steps",
        "2",
        "--out",
        out.to_str().unwrap(),
        "--overwrite",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("named pipe"), "{}", stderr(&o));
    assert!(!out.join(".diffsoft-run.lock").exists());
    // --out naming a file says so.
    let o = diffsoft(&["simulate", s, "--steps", "2", "--out", s]);
    assert!(stderr(&o).contains("must name a directory"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&scene).unwrap(), before);
}

/// `schemas --out` writes only regular files of its own names: a link among them (here to a
/// user's file) or a FIFO is refused before anything is written, and `--out` naming a file
/// says so.
#[test]
fn schemas_never_write_through_links_or_into_fifos() {
    let dir = tmp_dir("hard-schemas");
    let precious = write(&dir, "precious.txt", "keep me");
    let out = dir.join("schemas");
    std::fs::create_dir_all(&out).unwrap();
    std::os::unix::fs::symlink(&precious, out.join("scene.schema.json")).unwrap();
    let o = diffsoft(&["schemas", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("scene.schema.json: is a symbolic link"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read_to_string(&precious).unwrap(), "keep me");
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 1, "nothing written");
    std::fs::remove_file(out.join("scene.schema.json")).unwrap();
    let made = Command::new("mkfifo")
        .arg(out.join("run.schema.json"))
        .status()
        .unwrap();
    assert!(made.success());
    let o = diffsoft(&["schemas", "--out", out.to_str().unwrap()]);
    assert!(stderr(&o).contains("named pipe"), "{}", stderr(&o));
    let o = diffsoft(&["schemas", "--out", precious.to_str().unwrap()]);
    assert!(stderr(&o).contains("--out must name a directory"), "{}", stderr(&o));
}

/// A flag that would be ignored or overridden is refused, naming it: `--gmsh-version` for a
/// mesh that is not `.msh`, `--implicit-tolerance` in unrolled mode, a `--set` of one
/// parameter twice (the last one won), `--passive` on a diffsoft scene; a scene's one-key
/// object with two keys names both.
#[test]
fn flags_that_would_be_ignored_or_overridden_are_refused() {
    let dir = tmp_dir("hard-ignored-flags");
    let scene = cube_scene(&dir, DENSITY, "");
    let s = scene.to_str().unwrap();
    let generate = |out: &std::path::Path| {
        diffsoft(&[
            "generate",
            "--cells",
            "1,1,1",
            "--size",
            "1,1,1",
            "--gmsh-version",
            "2.2",
            "--out",
            out.to_str().unwrap(),
        ])
    };
    let obj = dir.join("g.obj");
    let o = generate(&obj);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--gmsh-version 2.2: applies to .msh output only"),
        "{}",
        stderr(&o)
    );
    assert!(!obj.exists());
    let msh = dir.join("g.msh");
    let o = generate(&msh);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::read_to_string(&msh).unwrap().contains("2.2 0 8"));
    let grad = |extra: &[&str]| {
        let mut args = vec!["--threads", "1", "grad", s, "--steps", "2", "--param", "density"];
        args.extend_from_slice(extra);
        diffsoft(&args)
    };
    let o = grad(&["--implicit-tolerance", "1e-8"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--implicit-tolerance 1e-8: applies to --mode implicit only"),
        "{}",
        stderr(&o)
    );
    let o = grad(&["--set", "density=1000", "--set", " density=2000"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("density is set twice"), "{}", stderr(&o));
    assert!(grad(&["--set", "density=1000", "--set", "youngs_modulus=2e5"])
        .status
        .success());
    // `--passive` is for the paper's files; a diffsoft scene ignored it.
    let o = diffsoft(&["simulate", s, "--steps", "1", "--passive"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--passive applies to the paper's scene files only"),
        "{}",
        stderr(&o)
    );
    // A spec file is the whole sweep: grid options beside it were silently dropped.
    for flag in [&["--steps", "10"][..], &["--time-axis", "iterations"], &["--caps", "1"]] {
        let mut args = vec!["tradeoff", "--spec", "sweep.json"];
        args.extend_from_slice(flag);
        let o = diffsoft(&args);
        assert_eq!(o.status.code(), Some(2), "{flag:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("cannot be used with") && stderr(&o).contains(flag[0]),
            "{}",
            stderr(&o)
        );
    }
    let two = std::fs::read_to_string(&scene).unwrap().replacen(
        r#""name""#,
        r#""fixed": {"indices": [0], "box": {"min": [0, 0, 0], "max": [1, 1, 1]}}, "name""#,
        1,
    );
    let bad = write(&dir, "two_keys.json", &two);
    let o = diffsoft(&["simulate", bad.to_str().unwrap(), "--steps", "1"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains(r#"bodies[0].fixed: a vertex selection gives both "indices" and "box": give exactly one of "indices", "box""#),
        "{}",
        stderr(&o)
    );
}

/// A body, bone or actuator with an empty (or blank) name is refused, naming what it is:
/// nothing could address it (`--activation NAME=A`, `joint_angle.NAME`, logs).
#[test]
fn empty_names_are_refused() {
    let dir = tmp_dir("hard-empty-names");
    let text = std::fs::read_to_string(cube_scene(&dir, DENSITY, "")).unwrap();
    let blank = write(
        &dir,
        "blank_body.json",
        &text.replace(r#""name": "c""#, r#""name": "  ""#),
    );
    let bone = cube_scene(
        &dir,
        r#", "density": 1000, "skeleton": { "bones": [{ "name": "", "joint": { "free": {} }, "vertices": { "indices": [0] } }] }"#,
        "",
    );
    for (scene, message) in [
        (&blank, r#"a body has an empty name "  ""#),
        (&bone, r#"a bone has an empty name """#),
    ] {
        let o = diffsoft(&["simulate", scene.to_str().unwrap(), "--steps", "1"]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains(message), "{}", stderr(&o));
    }
}

/// A step that stops at the iteration cap and multiplies the energy of a scene with no energy
/// source is named with the energy it made (a near-incompressible neo-Hookean box landing on the
/// ground gained 600 times its energy and the run ended "completed" with only the generic
/// warning); the same box at nu = 0.3 is capped too but gains nothing, and gets no such warning.
#[test]
fn a_capped_step_that_makes_energy_is_named() {
    let dir = tmp_dir("hard-energy-gain");
    let mesh = dir.join("box.obj");
    let o = generate_box("2,2,2", "0.2,0.2,0.2", &mesh);
    assert!(o.status.success(), "{}", stderr(&o));
    for (nu, warned) in [("0.4999999", true), ("0.3", false)] {
        let scene = write(
            &dir,
            &format!("box_{nu}.json"),
            &format!(
                r#"{{"schema": "diffsoft.scene/1", "time_step": 0.01, "gravity": [0, -9.81, 0],
                "bodies": [{{"name": "b", "mesh": "box.obj", "density": 1000, "translate": [0, 0.05, 0], "initial_velocity": [0, -1, 0],
                  "material": {{"youngs_modulus": 1e5, "poisson_ratio": {nu}, "model": "neo_hookean"}}}}],
                "obstacles": [{{"name": "ground", "plane": {{"point": [0, 0, 0], "normal": [0, 1, 0]}}, "friction": 0.3}}]}}"#
            ),
        );
        let o = diffsoft(&["simulate", scene.to_str().unwrap(), "--steps", "30"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let out = format!("{}{}", stdout(&o), stderr(&o));
        assert_eq!(
            out.contains("stopped at the iteration cap and raised the total energy"),
            warned,
            "nu = {nu}: {out}"
        );
    }
}
