//! What the page shows, read from a reports directory: every JSON report with its header
//! (schema, crate version, provenance) and its verdicts, and every SVG plot.
//!
//! A verdict is any JSON object with both a `claim` and a `holds` key (the serialised
//! [`Verdict`](crate::report::Verdict)), wherever it sits in a report: the studies nest them
//! differently (`verdicts`, `meshes[].bounds.appendix_a.verdicts`, `scenes[].verdicts`,
//! `cases[].verdict`).

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use serde_json::{Map, Value};

/// One verdict of a report, with where it sits.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Found {
    /// The claim in words.
    pub claim: String,
    /// Whether it holds.
    pub holds: bool,
    /// The measured value (`None`: `null` or absent).
    pub measured: Option<f64>,
    /// The value it is compared with (`None`: `null` or absent).
    pub threshold: Option<f64>,
    /// How the comparison reads (empty when absent).
    pub comparison: String,
    /// The enclosing object says `"expected_to_hold": false` (a validation case known to fail).
    pub expected_to_fail: bool,
    /// Where in the report, e.g. `meshes[bridge] › bounds › appendix_a` (empty at the top).
    pub place: String,
}

/// The provenance block of a report, as far as it is there.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Origin {
    pub git_commit: Option<String>,
    pub date_utc: Option<String>,
    pub cpu_model: Option<String>,
    pub cpus: Option<u64>,
    pub threads: Option<u64>,
    pub rustc_version: Option<String>,
    pub os: Option<String>,
}

/// One JSON report.
#[derive(Debug, Clone)]
pub(crate) struct Report {
    /// Path relative to the reports directory, `/`-separated.
    pub file: String,
    /// `schema` (e.g. `diffsoft.bounds/1`), if any.
    pub schema: Option<String>,
    /// `crate_version`, if any.
    pub crate_version: Option<String>,
    /// The top-level `provenance`, if any.
    pub provenance: Option<Origin>,
    /// Its verdicts in document order.
    pub verdicts: Vec<Found>,
}

/// One SVG plot.
#[derive(Debug, Clone)]
pub(crate) struct Plot {
    /// Path relative to the reports directory, `/`-separated.
    pub file: String,
    /// The file's bytes.
    pub svg: Vec<u8>,
}

/// Everything in a reports directory the page shows, files in path order.
#[derive(Debug, Clone)]
pub(crate) struct Contents {
    pub reports: Vec<Report>,
    pub plots: Vec<Plot>,
}

/// Read every `*.json` and `*.svg` under `dir` (recursively; hidden files and symbolic links to
/// directories skipped). Errors name the file, and for a malformed verdict the JSON path and key.
pub(crate) fn read(dir: &Path) -> Result<Contents> {
    let meta = std::fs::metadata(dir).with_context(|| format!("reports directory {}", dir.display()))?;
    if !meta.is_dir() {
        bail!("reports directory {}: not a directory", dir.display());
    }
    let mut files = Vec::new();
    walk(dir, "", &mut files)?;
    files.sort_by(|a, b| a.0.cmp(&b.0));
    let (mut reports, mut plots) = (Vec::new(), Vec::new());
    for (rel, path) in files {
        if rel.ends_with(".json") {
            let text = std::fs::read_to_string(&path).with_context(|| format!("{}", path.display()))?;
            let value: Value =
                serde_json::from_str(&text).with_context(|| format!("{}: not valid JSON", path.display()))?;
            reports.push(report(&rel, &value).with_context(|| format!("{}", path.display()))?);
        } else {
            let svg = std::fs::read(&path).with_context(|| format!("{}", path.display()))?;
            let head = String::from_utf8_lossy(&svg[..svg.len().min(4096)]).into_owned();
            if !head.contains("<svg") {
                bail!("{}: not an SVG image (no <svg element at its start)", path.display());
            }
            plots.push(Plot { file: rel, svg });
        }
    }
    if reports.is_empty() {
        bail!("reports directory {}: no JSON report in it", dir.display());
    }
    Ok(Contents { reports, plots })
}

/// Collect `(relative path, path)` of the JSON and SVG files under `dir`.
fn walk(dir: &Path, prefix: &str, out: &mut Vec<(String, PathBuf)>) -> Result<()> {
    let entries = std::fs::read_dir(dir).with_context(|| format!("{}", dir.display()))?;
    for entry in entries {
        let entry = entry.with_context(|| format!("{}", dir.display()))?;
        let path = entry.path();
        let name = entry
            .file_name()
            .into_string()
            .map_err(|n| anyhow!("{}: file name {n:?} is not UTF-8", dir.display()))?;
        if name.starts_with('.') {
            continue;
        }
        let rel = format!("{prefix}{name}");
        let kind = entry.file_type().with_context(|| format!("{}", path.display()))?;
        if kind.is_dir() {
            walk(&path, &format!("{rel}/"), out)?;
        } else if name.ends_with(".json") || name.ends_with(".svg") {
            // A link to a file counts as the file; a link to a directory is not followed.
            if std::fs::metadata(&path)
                .with_context(|| format!("{}", path.display()))?
                .is_file()
            {
                out.push((rel, path));
            }
        }
    }
    Ok(())
}

/// The header and verdicts of the report `value` at `file`.
fn report(file: &str, value: &Value) -> Result<Report> {
    let top = value
        .as_object()
        .ok_or_else(|| anyhow!("the report is not a JSON object"))?;
    let text = |key: &str| -> Result<Option<String>> {
        match top.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(Value::String(s)) => Ok(Some(s.clone())),
            Some(_) => bail!("/{key}: expected a string"),
        }
    };
    let provenance = match top.get("provenance") {
        None | Some(Value::Null) => None,
        Some(Value::Object(p)) => Some(origin(p)?),
        Some(_) => bail!("/provenance: expected an object"),
    };
    let mut verdicts = Vec::new();
    let mut path = Vec::new();
    collect(value, None, &mut path, &mut verdicts)?;
    Ok(Report {
        file: file.to_string(),
        schema: text("schema")?,
        crate_version: text("crate_version")?,
        provenance,
        verdicts,
    })
}

fn origin(p: &Map<String, Value>) -> Result<Origin> {
    let text = |key: &str| -> Result<Option<String>> {
        match p.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(Value::String(s)) => Ok(Some(s.clone())),
            Some(_) => bail!("/provenance/{key}: expected a string"),
        }
    };
    let count = |key: &str| -> Result<Option<u64>> {
        match p.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(v) => v
                .as_u64()
                .map(Some)
                .ok_or_else(|| anyhow!("/provenance/{key}: expected a non-negative integer")),
        }
    };
    Ok(Origin {
        git_commit: text("git_commit")?,
        date_utc: text("date_utc")?,
        cpu_model: text("cpu_model")?,
        cpus: count("cpus")?,
        threads: count("threads")?,
        rustc_version: text("rustc_version")?,
        os: text("os")?,
    })
}

/// One step of the path from a report's root to a value.
enum Step {
    /// An object's key.
    Key(String),
    /// An array's element, with its `name` or `id` when it has one.
    Index(usize, Option<String>),
}

/// The path as a JSON pointer (`/meshes/2/bounds/appendix_b/verdicts/0`), for errors.
fn pointer(path: &[Step]) -> String {
    path.iter()
        .map(|s| match s {
            Step::Key(k) => format!("/{}", k.replace('~', "~0").replace('/', "~1")),
            Step::Index(i, _) => format!("/{i}"),
        })
        .collect()
}

/// The path for a reader: array elements by name where they have one, and the verdict's own
/// trailing `verdicts[i]` or `verdict` left out (`meshes[bridge] › bounds › appendix_a`).
fn place(path: &[Step]) -> String {
    let mut steps: &[Step] = path;
    match steps {
        [rest @ .., Step::Key(k), Step::Index(..)] if k == "verdicts" => steps = rest,
        [rest @ .., Step::Key(k)] if k == "verdict" => steps = rest,
        _ => {}
    }
    let mut parts: Vec<String> = Vec::new();
    for s in steps {
        match s {
            Step::Key(k) => parts.push(k.clone()),
            Step::Index(i, label) => {
                let label = label.clone().unwrap_or_else(|| i.to_string());
                match parts.last_mut() {
                    Some(last) => last.push_str(&format!("[{label}]")),
                    None => parts.push(format!("[{label}]")),
                }
            }
        }
    }
    parts.join(" › ")
}

/// Walk `value` (inside the object `parent`, if any) and push its verdicts in document order.
fn collect(
    value: &Value,
    parent: Option<&Map<String, Value>>,
    path: &mut Vec<Step>,
    out: &mut Vec<Found>,
) -> Result<()> {
    match value {
        Value::Object(map) => {
            if map.contains_key("claim") && map.contains_key("holds") {
                out.push(verdict(map, parent, path)?);
                return Ok(());
            }
            for (k, v) in map {
                path.push(Step::Key(k.clone()));
                collect(v, Some(map), path, out)?;
                path.pop();
            }
        }
        Value::Array(items) => {
            for (i, v) in items.iter().enumerate() {
                let label = ["name", "id"]
                    .iter()
                    .find_map(|k| v.get(k).and_then(Value::as_str))
                    .map(str::to_string);
                path.push(Step::Index(i, label));
                // The element's enclosing object is the array's.
                collect(v, parent, path, out)?;
                path.pop();
            }
        }
        _ => {}
    }
    Ok(())
}

fn verdict(map: &Map<String, Value>, parent: Option<&Map<String, Value>>, path: &[Step]) -> Result<Found> {
    let at = |key: &str| format!("{}/{key}", pointer(path));
    let claim = map["claim"]
        .as_str()
        .ok_or_else(|| anyhow!("{}: expected a string", at("claim")))?
        .to_string();
    let holds = map["holds"]
        .as_bool()
        .ok_or_else(|| anyhow!("{}: expected true or false", at("holds")))?;
    let number = |key: &str| -> Result<Option<f64>> {
        match map.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(v) => v
                .as_f64()
                .filter(|x| x.is_finite())
                .map(Some)
                .ok_or_else(|| anyhow!("{}: expected a finite number or null", at(key))),
        }
    };
    let comparison = match map.get("comparison") {
        None | Some(Value::Null) => String::new(),
        Some(Value::String(s)) => s.clone(),
        Some(_) => bail!("{}: expected a string", at("comparison")),
    };
    let expected_to_fail = parent.and_then(|p| p.get("expected_to_hold")) == Some(&Value::Bool(false));
    Ok(Found {
        claim,
        holds,
        measured: number("measured")?,
        threshold: number("threshold")?,
        comparison,
        expected_to_fail,
        place: place(path),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn verdicts(v: &Value) -> Result<Vec<Found>> {
        Ok(report("r.json", v)?.verdicts)
    }

    #[test]
    fn finds_verdicts_wherever_they_are_nested() {
        let v = json!({
            "schema": "diffsoft.x/1",
            "verdicts": [{"claim": "top", "holds": true, "measured": 1.0, "threshold": 2.0, "comparison": "measured <= threshold"}],
            "meshes": [{"name": "bridge", "bounds": {"appendix_a": {"verdicts": [{"claim": "a", "holds": false, "measured": null, "threshold": null}]}}}],
            "cases": [{"id": "c.1", "expected_to_hold": false, "verdict": {"claim": "known", "holds": false}}],
            "summary": {"holds": 3},
            "appendix_b": {"holds": true},
        });
        let found = verdicts(&v).unwrap();
        let mut claims: Vec<_> = found
            .iter()
            .map(|f| (f.claim.as_str(), f.place.as_str(), f.expected_to_fail))
            .collect();
        claims.sort();
        assert_eq!(
            claims,
            [
                ("a", "meshes[bridge] › bounds › appendix_a", false),
                ("known", "cases[c.1]", true),
                ("top", "", false)
            ]
        );
        let by_claim = |c: &str| found.iter().find(|f| f.claim == c).unwrap();
        assert_eq!(
            (by_claim("top").measured, by_claim("top").threshold),
            (Some(1.0), Some(2.0))
        );
        assert_eq!((by_claim("a").measured, by_claim("a").comparison.as_str()), (None, ""));
    }

    #[test]
    fn malformed_verdicts_name_the_json_path_and_key() {
        let e = verdicts(&json!({"scenes": [{"verdicts": [{"claim": "x", "holds": "yes"}]}]})).unwrap_err();
        assert_eq!(e.to_string(), "/scenes/0/verdicts/0/holds: expected true or false");
        let e = verdicts(&json!({"verdicts": [{"claim": 3, "holds": true}]})).unwrap_err();
        assert_eq!(e.to_string(), "/verdicts/0/claim: expected a string");
        let e = verdicts(&json!({"v": {"claim": "x", "holds": true, "measured": "big"}})).unwrap_err();
        assert_eq!(e.to_string(), "/v/measured: expected a finite number or null");
        let e = report("r.json", &json!([1])).unwrap_err();
        assert!(e.to_string().contains("not a JSON object"), "{e}");
        let e = report("r.json", &json!({"provenance": {"cpus": -1}})).unwrap_err();
        assert_eq!(e.to_string(), "/provenance/cpus: expected a non-negative integer");
    }
}
