//! The command-line tool: JSON fields of `bounds`, clear errors with exit status 1, `sweep`
//! outputs, and the suite's rejection of unknown keys.

use crate::common::{root, tmp_dir, write};
use crate::run::{diffsoft, generate_box};
use serde_json::Value;

#[test]
fn bounds_writes_the_documented_json_fields() {
    let dir = tmp_dir("cli-bounds");
    let json = dir.join("b.json");
    let mesh = root().join("verification/paper/bridgesus/bridgesus200_tet_cen.obj");
    let out = diffsoft(&[
        "bounds",
        "--mesh",
        mesh.to_str().unwrap(),
        "--rho",
        "2",
        "--mu",
        "2e5",
        "--dt",
        "0.005",
        "--scale",
        "0.05",
        "--empirical",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("Eq. 19") && stdout.contains("Appendix B"), "{stdout}");
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(r["schema"], "diffsoft.bounds/1");
    assert_eq!(r["crate_version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(r["mesh"]["vertices"], 212);
    assert_eq!(r["mesh"]["tets"], 668);
    assert!(r["jacobi"]["spectral_radius"].as_f64().unwrap() > 0.0);
    assert!(r["jacobi"]["critical_dt"].as_f64().unwrap() > 0.0);
    assert!(r["split"]["spectral_radius"].as_f64().unwrap() > 0.0);
    assert!(
        r["split"]["critical_dt"].is_number(),
        "bridgesus is not an M-matrix mesh"
    );
    assert!(r["appendix_a"]["verdicts"]
        .as_array()
        .unwrap()
        .iter()
        .all(|v| v["holds"].is_boolean()));
    assert!(r["appendix_b"]["holds"].is_boolean());
    assert_eq!(r["inputs"]["dt"], 0.005);
    assert_eq!(r["empirical"].as_array().unwrap().len(), 2);
}

#[test]
fn m_matrix_mesh_has_null_split_critical_dt() {
    let dir = tmp_dir("cli-mmatrix");
    let mesh = dir.join("box.msh");
    let gen = generate_box("3,3,3", "1,2,1", &mesh);
    assert!(gen.status.success(), "{}", String::from_utf8_lossy(&gen.stderr));
    let json = dir.join("b.json");
    let out = diffsoft(&[
        "bounds",
        "--mesh",
        mesh.to_str().unwrap(),
        "--rho",
        "1",
        "--mu",
        "1",
        "--dt",
        "10",
        "--scale",
        "0.5",
        "--min-tet-quality",
        "1e-6",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    // The report says how the file was read: its scale and quality threshold.
    assert_eq!(r["mesh"]["source"]["scale"], 0.5);
    assert_eq!(r["mesh"]["source"]["min_quality"], 1e-6);
    assert!(r["split"]["critical_dt"].is_null());
    assert_eq!(r["split"]["converges"], true);
    assert_eq!(r["appendix_b"]["holds"], true);
}

#[test]
fn bad_inputs_fail_with_a_message_naming_file_and_line() {
    let dir = tmp_dir("cli-bad");
    let bad = write(&dir, "bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 7\n");
    let out = diffsoft(&[
        "bounds",
        "--mesh",
        bad.to_str().unwrap(),
        "--rho",
        "1",
        "--mu",
        "1",
        "--dt",
        "1",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.obj:5:") && err.contains("out of range"), "{err}");

    let good = write(&dir, "good.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3\n");
    for bad in ["--rho=-1", "--mu=nan", "--dt=0", "--scale=-2", "--rho=inf"] {
        let flag = bad.split('=').next().unwrap();
        let mut args: Vec<&str> = vec!["bounds", "--mesh", good.to_str().unwrap()];
        for (f, v) in [("--rho", "--rho=1"), ("--mu", "--mu=1"), ("--dt", "--dt=1")] {
            args.push(if f == flag { bad } else { v });
        }
        if flag == "--scale" {
            args.push(bad);
        }
        let out = diffsoft(&args);
        let value = bad;
        assert_eq!(out.status.code(), Some(1), "{flag} {value}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("must be finite and positive"), "{flag}: {err}");
    }
}

#[test]
fn sweep_writes_json_and_svg() {
    let dir = tmp_dir("cli-sweep");
    let (json, svg) = (dir.join("s.json"), dir.join("s.svg"));
    let mesh = root().join("verification/paper/droneman/ball_tet.obj");
    let out = diffsoft(&[
        "sweep",
        "--mesh",
        mesh.to_str().unwrap(),
        "--rho",
        "10",
        "--mu",
        "2e6",
        "--points",
        "9",
        "--mark-dt",
        "0.01",
        "--scale",
        "2",
        "--json",
        json.to_str().unwrap(),
        "--svg",
        svg.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(r["schema"], "diffsoft.sweep/1");
    assert_eq!(r["inputs"]["mesh_scale"], 2.0);
    assert_eq!(r["inputs"]["min_tet_quality"], 1e-9);
    let pts = r["points"].as_array().unwrap();
    assert_eq!(pts.len(), 9);
    // rho(G19) grows like dt^2 along the sweep.
    let (a, b) = (&pts[0], &pts[8]);
    let ratio = b["rho_plain"].as_f64().unwrap() / a["rho_plain"].as_f64().unwrap();
    let dts = b["dt"].as_f64().unwrap() / a["dt"].as_f64().unwrap();
    assert!((ratio / (dts * dts) - 1.0).abs() < 1e-9);
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.starts_with("<svg") && text.contains("rho(G21)"));
}

#[test]
fn suite_rejects_unknown_keys_with_their_name() {
    let dir = tmp_dir("cli-suite");
    let suite = write(
        &dir,
        "suite.json",
        r#"{"schema": "diffsoft.suite/1", "bounds": {"empirical": false, "sweep_points": 3, "meshes": [], "colour": 1}, "t_scaling": {"cell_size": 1, "rho": 1, "mu": 1, "cells_per_axis": [1]}}"#,
    );
    let out = diffsoft(&[
        "verify",
        "--suite",
        suite.to_str().unwrap(),
        "--out",
        dir.join("r").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("suite.json") && err.contains("unknown field `colour`") && err.contains("line 1"),
        "{err}"
    );
}

#[test]
fn quality_reports_the_sign_pattern() {
    let dir = tmp_dir("cli-quality");
    let json = dir.join("q.json");
    let mesh = root().join("verification/paper/octopus/octopus.obj");
    let out = diffsoft(&[
        "quality",
        "--mesh",
        mesh.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(r["schema"], "diffsoft.quality/1");
    assert_eq!(r["source"]["reoriented_tets"], 2160);
    assert!(r["l_sign"]["positive_offdiagonal_entries"].as_u64().unwrap() > 0);
    assert!(r["quality"]["max_dihedral_deg"].as_f64().unwrap() > 90.0);
}

#[test]
fn jacobians_writes_its_report_with_every_check_passing() {
    let dir = tmp_dir("cli-jacobians");
    let out = dir.join("jacobians.json");
    let o = diffsoft(&["jacobians", "--seed", "7", "--json", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(r["schema"], "diffsoft.jacobians/3");
    assert_eq!(r["seed"], 7);
    let checks = r["checks"].as_array().unwrap();
    assert!(checks.len() >= 30, "{} checks", checks.len());
    for c in checks {
        // Each check names its worst entry with both values and its step sweep.
        for key in [
            "atol",
            "rtol",
            "max_abs_error",
            "max_rel_error",
            "worst_index",
            "analytic_at_worst",
            "reference_at_worst",
            "pass",
        ] {
            assert!(!c["versus_fd"][key].is_null(), "{key} missing in {c}");
        }
        assert_eq!(c["sweep"]["steps"].as_array().unwrap().len(), 10);
    }
    assert!(r["verdicts"].as_array().unwrap().iter().all(|v| v["holds"] == true));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("column 0 of B") && text.contains("rotational"), "{text}");
}

#[test]
fn report_page_rewrites_the_page_and_names_a_bad_report() {
    let dir = tmp_dir("cli-report-page");
    write(
        &dir,
        "a.json",
        r#"{"schema": "diffsoft.a/1", "verdicts": [{"claim": "x < 1", "holds": false, "measured": 2, "threshold": 1, "comparison": "measured < threshold"}]}"#,
    );
    let out = diffsoft(&["report-page", "--reports", dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        said.contains("index.html (1 verdicts in 1 reports, 1 fail, 0 plots)"),
        "{said}"
    );
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(html.contains("x &lt; 1") && html.contains("FAILS"));
    write(&dir, "b.json", r#"{"verdicts": [{"claim": "y", "holds": 1}]}"#);
    let out = diffsoft(&["report-page", "--reports", dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("b.json") && err.contains("/verdicts/0/holds"), "{err}");
    // The page of the good reports stays as it was.
    assert_eq!(std::fs::read_to_string(dir.join("index.html")).unwrap(), html);
    // The page's own name taken by a link to another file: refused, that file untouched.
    std::fs::remove_file(dir.join("b.json")).unwrap();
    std::fs::rename(dir.join("index.html"), dir.join("mine.txt")).unwrap();
    std::os::unix::fs::symlink("mine.txt", dir.join("index.html")).unwrap();
    let out = diffsoft(&["report-page", "--reports", dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("index.html: is a symbolic link to mine.txt"), "{err}");
    assert_eq!(std::fs::read_to_string(dir.join("mine.txt")).unwrap(), html);
}
