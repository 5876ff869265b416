//! The JSON Schemas in `schemas/`: the committed files are exactly what `diffsoft schemas`
//! generates from the Rust types (so they never drift), every name follows
//! `diffsoft.<name>/<version>`, reports hold no unnamed tuples, and every scene and suite file of
//! the repository parses as what its schema describes. `python/tests/test_schemas.py` validates
//! the reports and scenes against these schemas.

use std::collections::BTreeSet;

use crate::common::root;
use diffsoft::scene::format::{SceneFile, SCENE_SCHEMA};
use diffsoft_harness::schemas::{file_name, schemas, SCHEMA_DIR};
use serde_json::Value;

const REGENERATE: &str = "run `cargo run --release -- schemas` and commit schemas/";

#[test]
fn committed_schemas_equal_the_generated_ones() {
    let dir = root().join(SCHEMA_DIR);
    let generated = schemas();
    let mut stale = Vec::new();
    for (file, schema) in &generated {
        match std::fs::read_to_string(dir.join(file)) {
            Ok(committed) if committed == crate::common::pretty_json(schema) => {}
            Ok(_) => stale.push(format!("{SCHEMA_DIR}/{file} differs from the Rust types")),
            Err(e) => stale.push(format!("{SCHEMA_DIR}/{file}: {e}")),
        }
    }
    let wanted: BTreeSet<&str> = generated.iter().map(|(f, _)| f.as_str()).collect();
    for path in crate::common::json_files(&dir) {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if !wanted.contains(name.as_str()) {
            stale.push(format!("{SCHEMA_DIR}/{name} is no longer generated (remove it)"));
        }
    }
    assert!(stale.is_empty(), "{}; {REGENERATE}", stale.join("; "));
}

#[test]
fn every_schema_is_named_diffsoft_name_version() {
    let generated = schemas();
    let mut ids = BTreeSet::new();
    for (file, schema) in &generated {
        let id = schema["$id"].as_str().unwrap_or_else(|| panic!("{file}: no $id"));
        assert_eq!(schema["title"], id, "{file}");
        assert_eq!(file, &file_name(id));
        let (name, version) = id
            .strip_prefix("diffsoft.")
            .and_then(|r| r.split_once('/'))
            .unwrap_or_else(|| panic!("{id}: not diffsoft.<name>/<version>"));
        assert!(
            name.chars().all(|c| c.is_ascii_lowercase() || c == '_'),
            "{id}: one snake_case name, no dots"
        );
        assert!(version.parse::<u32>().is_ok_and(|v| v >= 1), "{id}");
        // A report's `schema` field must name exactly this schema.
        assert_eq!(schema["properties"]["schema"]["const"], id, "{file}");
        assert!(ids.insert(id.to_string()), "{id} twice");
    }
    for id in [
        "diffsoft.bounds/1",
        "diffsoft.bounds_suite/1",
        "diffsoft.physics/2",
        "diffsoft.skeleton/2",
        "diffsoft.actuators/2",
        "diffsoft.jacobians/3",
        "diffsoft.gradients/1",
        "diffsoft.gradcheck/1",
        "diffsoft.tradeoff/1",
        "diffsoft.tradeoff_partial/1",
        "diffsoft.extremes/1",
        "diffsoft.extremes_partial/1",
        "diffsoft.cloth/2",
        "diffsoft.sweep/1",
        "diffsoft.quality/1",
        "diffsoft.run/2",
        "diffsoft.grad/1",
        "diffsoft.scene/1",
        "diffsoft.suite/1",
    ] {
        assert!(ids.contains(id), "no schema {id}");
    }
}

/// Unnamed tuples serialise as arrays of mixed meaning; reports name their fields instead.
#[test]
fn no_schema_holds_an_unnamed_tuple() {
    fn walk(v: &Value, path: &str, found: &mut Vec<String>) {
        match v {
            Value::Object(m) => {
                if m.contains_key("prefixItems") {
                    found.push(path.to_string());
                }
                for (k, c) in m {
                    walk(c, &format!("{path}/{k}"), found);
                }
            }
            Value::Array(a) => a
                .iter()
                .enumerate()
                .for_each(|(i, c)| walk(c, &format!("{path}/{i}"), found)),
            _ => {}
        }
    }
    let mut found = Vec::new();
    for (file, schema) in schemas() {
        walk(&schema, &file, &mut found);
    }
    assert!(found.is_empty(), "tuples at {found:?}");
}

/// Scene files declare `diffsoft.scene/1` and parse as the type the scene schema is made from
/// (unknown keys are refused, as `additionalProperties: false` says).
#[test]
fn every_scene_of_the_repository_parses_as_a_scene() {
    let mut n = 0;
    for dir in ["verification/scenes", "python/tests/data"] {
        for path in crate::common::json_files(&root().join(dir)) {
            let text = std::fs::read_to_string(&path).unwrap();
            let v: Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert_eq!(v["schema"], SCENE_SCHEMA, "{}", path.display());
            serde_json::from_str::<SceneFile>(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            n += 1;
        }
    }
    assert!(n >= 7, "only {n} scenes found");
    let bad = r#"{"schema": "diffsoft.scene/1", "time_step": 0.01, "colour": "red"}"#;
    let err = serde_json::from_str::<SceneFile>(bad).unwrap_err().to_string();
    assert!(err.contains("colour"), "{err}");
    let scene = schemas().into_iter().find(|(f, _)| f == "scene.schema.json").unwrap().1;
    assert_eq!(scene["additionalProperties"], false);
}

#[test]
fn the_suite_file_parses_as_a_suite() {
    let suite = diffsoft_harness::suite::Suite::load(&root().join("verification/suite.json")).unwrap();
    assert_eq!(suite.schema, diffsoft_harness::suite::SUITE_SCHEMA);
}
