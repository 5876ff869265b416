//! Helpers of the integration tests of every crate: scratch directories and files, the
//! repository root, a small scene, comparisons.
//!
//! They panic on I/O errors (they are for tests).

use std::path::{Path, PathBuf};

/// A fresh directory for one test.
pub fn tmp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("diffsoft-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Write `text` to `dir/file` and return the path.
pub fn write(dir: &std::path::Path, file: &str, text: &str) -> PathBuf {
    let p = dir.join(file);
    std::fs::write(&p, text).unwrap();
    p
}

/// The repository root (for files under `verification/`): two levels above this crate.
pub fn root() -> PathBuf {
    let p = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    p.canonicalize().unwrap_or(p)
}

/// Relative difference.
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

/// A diffsoft scene with one two-tet body `c` (under gravity) in `dir/scene.json`, with
/// `body_extra` appended to the body object and `top_extra` to the top level.
pub fn cube_scene(dir: &std::path::Path, body_extra: &str, top_extra: &str) -> std::path::PathBuf {
    write(
        dir,
        "cube.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\nt 0 1 2 3\nt 1 2 3 4\n",
    );
    write(
        dir,
        "scene.json",
        &format!(
            r#"{{
  "schema": "diffsoft.scene/1",
  "time_step": 0.01,
  "gravity": [0, -9.81, 0],
  "bodies": [{{
    "name": "c", "mesh": "cube.obj",
    "material": {{ "youngs_modulus": 1e5, "poisson_ratio": 0.3 }}{body_extra}
  }}]{top_extra}
}}"#
        ),
    )
}

/// The first place where two JSON values differ (path, left, right), for readable failures.
pub fn json_difference(a: &serde_json::Value, b: &serde_json::Value, path: &str) -> Option<String> {
    use serde_json::Value;
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            for k in x.keys().chain(y.keys()) {
                let p = format!("{path}.{k}");
                match (x.get(k), y.get(k)) {
                    (Some(u), Some(v)) => {
                        if let Some(d) = json_difference(u, v, &p) {
                            return Some(d);
                        }
                    }
                    (u, v) => return Some(format!("{p}: {u:?} vs {v:?}")),
                }
            }
            None
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => x
            .iter()
            .zip(y)
            .enumerate()
            .find_map(|(i, (u, v))| json_difference(u, v, &format!("{path}[{i}]"))),
        _ => (a != b).then(|| format!("{path}: {a} vs {b}")),
    }
}

/// `settings` with another solver, tolerance and iteration cap.
pub fn with_solver(
    settings: &crate::Settings,
    solver: crate::SolverKind,
    tolerance: f64,
    max_iterations: usize,
) -> crate::Settings {
    crate::Settings {
        solver,
        tolerance,
        max_iterations,
        ..settings.clone()
    }
}

/// The median (the mean of the middle two for an even count).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Assert that two gradients of `model` agree on each of `params` to `rtol` (relative to the
/// larger magnitude); `what` names the two in the message.
pub fn assert_params_agree(
    model: &crate::Model,
    a: &crate::Gradient,
    b: &crate::Gradient,
    params: &[crate::diff::Param],
    rtol: f64,
    what: (&str, &str),
) {
    for p in params {
        let (x, y) = (p.derivative(model, a), p.derivative(model, b));
        assert!(
            (x - y).abs() <= rtol * x.abs().max(y.abs()),
            "{p}: {} {x:e}, {} {y:e}",
            what.0,
            what.1
        );
    }
}

/// Remove `keys` from every object in `v`, recursively (timings, provenance and the like before
/// comparing two reports).
pub fn strip_keys(v: &mut serde_json::Value, keys: &[&str]) {
    match v {
        serde_json::Value::Object(m) => {
            for k in keys {
                m.remove(*k);
            }
            m.values_mut().for_each(|x| strip_keys(x, keys));
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(|x| strip_keys(x, keys)),
        _ => {}
    }
}

/// What a sharded and an unsharded run of a study may differ in: wall-clock measurements,
/// workers and shards, plots and provenance.
pub const RUN_DEPENDENT_KEYS: &[&str] = &[
    "timing",
    "wall_s",
    "cpu_s",
    "cpu_s_per_sim_s",
    "reference_cpu_s_per_sim_s",
    "wall_time_s",
    "workers",
    "shards",
    "svg",
    "provenance",
    "shard_provenance",
];

/// The `.json` files in `dir`, sorted.
pub fn json_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    files.sort();
    files
}

/// A JSON value as the project writes it: pretty, with a final newline.
pub fn pretty_json(v: &serde_json::Value) -> String {
    let mut t = serde_json::to_string_pretty(v).unwrap();
    t.push('\n');
    t
}
