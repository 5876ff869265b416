//! JSON Schemas (draft 2020-12) of every JSON file the crate writes or reads, generated from the
//! Rust types: the reports of the main job and of the CLI commands, the run log, the partial
//! reports of sharded runs (describing what the writer produces), and the scene format and suite
//! file (describing what the reader accepts). `diffsoft schemas` writes them to `schemas/`, and
//! the tests check that the committed files equal [`schemas`].
//!
//! Every schema is named `diffsoft.<name>/<version>`: that string is the schema's `$id` and
//! `title`, the file is `schemas/<name>.schema.json`, and a report's `schema` field must equal it.

use schemars::generate::{Contract, SchemaSettings};
use schemars::JsonSchema;
use serde_json::{json, Value};

use crate::{actuators, cloth, extremes, gradients, jacobians, skeleton, suite, tradeoff, validation};
use crate::{
    PhysicsReport, QualityReport, SuiteBoundsReport, SweepReport, PHYSICS_SCHEMA, QUALITY_SCHEMA, SUITE_BOUNDS_SCHEMA,
    SWEEP_SCHEMA,
};
use diffsoft::analysis::bounds::{self, BoundsReport};
use diffsoft::output::{GradReport, RunLog, GRAD_SCHEMA, RUN_SCHEMA};
use diffsoft::scene::format::{SceneFile, SCENE_SCHEMA};

/// The directory the schemas are committed in (relative to the repository).
pub const SCHEMA_DIR: &str = "schemas";

/// Which way a schema describes its type's JSON.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// A file the crate writes: exactly the fields it writes, numbers possibly `null`.
    Written,
    /// A file the crate reads: what its reader accepts (defaults, unknown keys refused).
    Read,
}

const WRITTEN_NOTE: &str = "Written by diffsoft: every object holds exactly the fields listed. Numbers that are not \
finite (NaN, infinity) are written as null, so every number field also admits null. Units are in each field's \
description (1: dimensionless).";
const READ_NOTE: &str = "Read by diffsoft: what its reader accepts (keys not listed are refused). Units are in each \
field's description (1: dimensionless).";

/// The schema of `T` named `id` (`diffsoft.<name>/<version>`).
fn generate<T: JsonSchema>(id: &str, kind: Kind, what: &str) -> Value {
    let mut settings = SchemaSettings::draft2020_12();
    settings.contract = match kind {
        Kind::Written => Contract::Serialize,
        Kind::Read => Contract::Deserialize,
    };
    let root = settings.into_generator().into_root_schema_for::<T>();
    let mut v = root.to_value();
    if kind == Kind::Written {
        admit_null_numbers(&mut v);
        close_objects(&mut v);
    }
    plain_descriptions(&mut v);
    let obj = v.as_object_mut().expect("a root schema is an object");
    obj.insert("$id".into(), id.into());
    obj.insert("title".into(), id.into());
    let note = match kind {
        Kind::Written => WRITTEN_NOTE,
        Kind::Read => READ_NOTE,
    };
    obj.insert("description".into(), format!("{what}\n\n{note}").into());
    // The `schema` field names exactly this schema.
    if let Some(p) = obj.get_mut("properties").and_then(|p| p.get_mut("schema")) {
        if let Some(p) = p.as_object_mut() {
            p.insert("const".into(), id.into());
            p.insert("description".into(), format!("Schema name and version: `{id}`.").into());
        }
    }
    v
}

/// serde_json writes a non-finite `f64` as `null`: every `number` type also admits `null`.
fn admit_null_numbers(v: &mut Value) {
    match v {
        Value::Object(map) => {
            match map.get_mut("type") {
                Some(t @ Value::String(_)) if t == "number" => *t = json!(["number", "null"]),
                Some(Value::Array(types))
                    if types.iter().any(|t| t == "number") && !types.iter().any(|t| t == "null") =>
                {
                    types.push("null".into())
                }
                _ => {}
            }
            for (key, child) in map.iter_mut() {
                // `enum`, `const` and `default` hold values, not schemas.
                if !matches!(key.as_str(), "enum" | "const" | "default" | "examples") {
                    admit_null_numbers(child);
                }
            }
        }
        Value::Array(items) => items.iter_mut().for_each(admit_null_numbers),
        _ => {}
    }
}

/// A written object holds exactly the fields its type writes: `additionalProperties: false` on
/// every object schema with named properties (not on maps, nor where subschemas add properties).
fn close_objects(v: &mut Value) {
    match v {
        Value::Object(map) => {
            let combined = ["allOf", "anyOf", "oneOf", "$ref"].iter().any(|k| map.contains_key(*k));
            if map.contains_key("properties") && !combined && !map.contains_key("additionalProperties") {
                map.insert("additionalProperties".into(), false.into());
            }
            for (key, child) in map.iter_mut() {
                if !matches!(key.as_str(), "enum" | "const" | "default" | "examples") {
                    close_objects(child);
                }
            }
        }
        Value::Array(items) => items.iter_mut().for_each(close_objects),
        _ => {}
    }
}

/// Rustdoc links in doc comments (`` [`Settings`] ``, `` [`diffsoft::cloth`] ``) read as code
/// spans in descriptions (`` `Settings` ``, `` `cloth` ``).
fn plain_descriptions(v: &mut Value) {
    match v {
        Value::Object(map) => {
            for (key, child) in map.iter_mut() {
                match child {
                    Value::String(text) if key == "description" => *text = unlink(&without_examples(text)),
                    _ if matches!(key.as_str(), "enum" | "const" | "default" | "examples") => {}
                    _ => plain_descriptions(child),
                }
            }
        }
        Value::Array(items) => items.iter_mut().for_each(plain_descriptions),
        _ => {}
    }
}

/// The description without its code examples (a type's doctests are for Rust readers, not for
/// the schema's), and without the blank lines they leave at the end.
fn without_examples(text: &str) -> String {
    let mut out = Vec::new();
    // Inside a fence: whether it is Rust (dropped) or another language (kept, e.g. JSON).
    let mut fence: Option<bool> = None;
    for line in text.lines() {
        let t = line.trim_start();
        if let Some(lang) = t.strip_prefix("```") {
            let rust = match fence {
                None => {
                    let lang = lang.trim();
                    let rust = lang.is_empty() || lang.starts_with("rust") || lang == "no_run";
                    fence = Some(rust);
                    rust
                }
                Some(rust) => {
                    fence = None;
                    rust
                }
            };
            if !rust {
                out.push(line);
            }
            continue;
        }
        if fence != Some(true) {
            out.push(line);
        }
    }
    while out.last().is_some_and(|l| l.trim().is_empty()) {
        out.pop();
    }
    out.join("\n")
}

fn unlink(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(start) = rest.find("[`") {
        out.push_str(&rest[..start]);
        let after = &rest[start + 2..];
        match after.find("`]") {
            Some(end) if !after[..end].contains('`') => {
                let target = &after[..end];
                out.push('`');
                // Links into this crate or the engine's name their item without the crate.
                let target = target
                    .strip_prefix("crate::")
                    .or_else(|| target.strip_prefix("diffsoft::"))
                    .unwrap_or(target);
                out.push_str(target);
                out.push('`');
                rest = &after[end + 2..];
            }
            _ => {
                out.push_str("[`");
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
}

/// The file name of the schema `id`: `diffsoft.<name>/<version>` -> `<name>.schema.json`.
pub fn file_name(id: &str) -> String {
    let name = id.strip_prefix("diffsoft.").unwrap_or(id);
    let name = name.split_once('/').map_or(name, |(n, _)| n);
    format!("{name}.schema.json")
}

/// Every schema as `(file name, schema)`, in a fixed order: the reports, the run log, the grad
/// output, the partial reports, the scene format and the suite file.
pub fn schemas() -> Vec<(String, Value)> {
    use Kind::{Read, Written};
    let list = [
        (
            bounds::SCHEMA,
            generate::<BoundsReport>(
                bounds::SCHEMA,
                Written,
                "`diffsoft bounds --json`: spectral radii and critical time steps of iterations (19) and (21) on one \
                 mesh, with the appendix's verdicts.",
            ),
        ),
        (
            SUITE_BOUNDS_SCHEMA,
            generate::<SuiteBoundsReport>(
                SUITE_BOUNDS_SCHEMA,
                Written,
                "`reports/bounds.json`: the convergence analysis of the suite's meshes, the appendix's arithmetic and \
                 Eq. 29's dependence on the number of tets.",
            ),
        ),
        (
            SWEEP_SCHEMA,
            generate::<SweepReport>(
                SWEEP_SCHEMA,
                Written,
                "`diffsoft sweep --json` and `reports/sweeps/*.json`: rho(G19) and rho(G21) over a range of time steps.",
            ),
        ),
        (
            QUALITY_SCHEMA,
            generate::<QualityReport>(
                QUALITY_SCHEMA,
                Written,
                "`diffsoft quality --json`: mesh counts, volumes, dihedral angles and the sign pattern of L.",
            ),
        ),
        (
            jacobians::SCHEMA,
            generate::<jacobians::JacobiansReport>(
                jacobians::SCHEMA,
                Written,
                "`reports/jacobians.json` and `diffsoft jacobians --json`: Jacobians of the joints, of B = dq/dz and \
                 of the actuator projections against dual numbers and finite differences.",
            ),
        ),
        (
            PHYSICS_SCHEMA,
            generate::<PhysicsReport>(
                PHYSICS_SCHEMA,
                Written,
                "`reports/physics.json`: the forward solver against closed forms.",
            ),
        ),
        (
            skeleton::SCHEMA,
            generate::<skeleton::SkeletonReport>(
                skeleton::SCHEMA,
                Written,
                "`reports/skeleton.json`: the embedded-skeleton study (paper Fig. 5).",
            ),
        ),
        (
            actuators::SCHEMA,
            generate::<actuators::ActuatorsReport>(
                actuators::SCHEMA,
                Written,
                "`reports/actuators.json`: the actuator study (pneumatic cells and muscle fibres).",
            ),
        ),
        (
            gradients::GRADIENTS_SCHEMA,
            generate::<gradients::GradientsReport>(
                gradients::GRADIENTS_SCHEMA,
                Written,
                "`reports/gradients.json`: gradient checks, system identification, accuracy against cost and memory \
                 of the reverse mode.",
            ),
        ),
        (
            gradients::GRADCHECK_SCHEMA,
            generate::<gradients::GradcheckReport>(
                gradients::GRADCHECK_SCHEMA,
                Written,
                "`diffsoft gradcheck --json`: the gradient checks of the built-in cases.",
            ),
        ),
        (
            tradeoff::SCHEMA,
            generate::<tradeoff::TradeoffReport>(
                tradeoff::SCHEMA,
                Written,
                "`reports/tradeoff.json`, `diffsoft tradeoff --json` and merged trade-off reports: accuracy against \
                 cost of solver settings.",
            ),
        ),
        (
            tradeoff::PARTIAL_SCHEMA,
            generate::<tradeoff::TradeoffPartial>(
                tradeoff::PARTIAL_SCHEMA,
                Written,
                "`diffsoft tradeoff --shard K/N --json`: one shard's part of a trade-off sweep, for `diffsoft merge`.",
            ),
        ),
        (
            extremes::SCHEMA,
            generate::<extremes::ExtremesReport>(
                extremes::SCHEMA,
                Written,
                "`reports/extremes.json`, `diffsoft extremes --json` and merged extremes reports: the simulator and its \
                 gradients at the edges of their input ranges.",
            ),
        ),
        (
            extremes::PARTIAL_SCHEMA,
            generate::<extremes::ExtremesPartial>(
                extremes::PARTIAL_SCHEMA,
                Written,
                "`diffsoft extremes --shard K/N --json`: one shard's part of the extremes suite, for `diffsoft merge`.",
            ),
        ),
        (
            cloth::CLOTH_SCHEMA,
            generate::<cloth::ClothReport>(
                cloth::CLOTH_SCHEMA,
                Written,
                "`reports/cloth.json` and `diffsoft cloth --json`: cloth with collisions between bodies, and the cost \
                 of collision detection against mesh size.",
            ),
        ),
        (
            validation::SCHEMA,
            generate::<validation::ValidationReport>(
                validation::SCHEMA,
                Written,
                "`reports/validation.json` and `diffsoft validate --json`: the engine against closed forms of \
                 continuum mechanics, per material model.",
            ),
        ),
        (
            RUN_SCHEMA,
            generate::<RunLog>(
                RUN_SCHEMA,
                Written,
                "`run.json` of `diffsoft simulate --out DIR`: the run log (settings, certificate, every step's figures, \
                 a summary), refreshed during the run.",
            ),
        ),
        (
            GRAD_SCHEMA,
            generate::<GradReport>(
                GRAD_SCHEMA,
                Written,
                "`diffsoft grad --json`: the loss of a simulation and its derivatives with respect to scalar \
                 parameters.",
            ),
        ),
        (
            SCENE_SCHEMA,
            generate::<SceneFile>(SCENE_SCHEMA, Read, "A scene file in the diffsoft format."),
        ),
        (
            suite::SUITE_SCHEMA,
            generate::<suite::Suite>(
                suite::SUITE_SCHEMA,
                Read,
                "`verification/suite.json`: what the main job (`diffsoft verify`) runs.",
            ),
        ),
    ];
    list.into_iter().map(|(id, schema)| (file_name(id), schema)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_follow_one_scheme_and_files_are_distinct() {
        let all = schemas();
        let mut files: Vec<&str> = all.iter().map(|(f, _)| f.as_str()).collect();
        for (file, schema) in &all {
            let id = schema["$id"].as_str().unwrap();
            let (name, version) = id.strip_prefix("diffsoft.").unwrap().split_once('/').unwrap();
            assert!(
                !name.is_empty() && name.chars().all(|c| c.is_ascii_lowercase() || c == '_'),
                "{id}: names are diffsoft.<snake_case>/<version>"
            );
            assert!(version.parse::<u32>().is_ok_and(|v| v >= 1), "{id}");
            assert_eq!(file, &format!("{name}.schema.json"));
            assert_eq!(schema["title"], *id);
        }
        files.sort_unstable();
        files.dedup();
        assert_eq!(files.len(), all.len());
    }

    #[test]
    fn code_examples_are_left_out() {
        assert_eq!(without_examples("A thing.\n\n```\nlet x = 1;\n```\n"), "A thing.");
        assert_eq!(without_examples("a\n\nb"), "a\n\nb");
        assert_eq!(without_examples("a\n```json\n{}\n```"), "a\n```json\n{}\n```");
    }

    #[test]
    fn rustdoc_links_become_code_spans() {
        assert_eq!(
            unlink("see [`crate::cloth`] and [`Settings`], not [x] or [`a`b`]"),
            "see `cloth` and `Settings`, not [x] or [`a`b`]"
        );
        assert_eq!(
            unlink("see [`diffsoft::cloth`] and [`Settings`], not [x] or [`a`b`]"),
            "see `cloth` and `Settings`, not [x] or [`a`b`]"
        );
    }

    #[test]
    fn null_numbers_only_in_written_schemas() {
        let mut v = json!({"type": "number", "properties": {"a": {"type": ["number", "null"]}, "b": {"type": ["integer"]}}, "enum": [{"type": "number"}]});
        admit_null_numbers(&mut v);
        assert_eq!(v["type"], json!(["number", "null"]));
        assert_eq!(v["properties"]["a"]["type"], json!(["number", "null"]));
        assert_eq!(v["properties"]["b"]["type"], json!(["integer"]));
        assert_eq!(v["enum"][0]["type"], "number");
    }
}
