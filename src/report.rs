//! Versioned JSON reports: every report starts with a [`Header`] (schema name with version,
//! crate version) and states its claims as [`Verdict`]s.

use serde::Serialize;
use std::path::Path;

/// The crate version written into every report.
pub const CRATE_VERSION: &str = env!("CARGO_PKG_VERSION");

/// First fields of every report.
#[derive(Debug, Clone, Serialize)]
pub struct Header {
    /// Schema name and version, e.g. `diffsoft.bounds/1`.
    pub schema: String,
    /// Version of the crate that wrote the report.
    pub crate_version: &'static str,
}

impl Header {
    /// A header for the given schema name (e.g. `"diffsoft.bounds/1"`).
    pub fn new(schema: &str) -> Self {
        Self {
            schema: schema.to_string(),
            crate_version: CRATE_VERSION,
        }
    }
}

/// A claim checked against a measurement.
#[derive(Debug, Clone, Serialize)]
pub struct Verdict {
    /// The claim, in words, with its source (paper equation or appendix).
    pub claim: String,
    /// Whether the claim holds on this input.
    pub holds: bool,
    /// The measured value the verdict rests on.
    pub measured: Option<f64>,
    /// The value it is compared with (`null` when the claim is not a comparison).
    pub threshold: Option<f64>,
    /// How the comparison reads, e.g. `measured <= threshold`.
    pub comparison: String,
}

impl Verdict {
    /// `holds` iff `measured <= threshold`.
    pub fn at_most(claim: impl Into<String>, measured: f64, threshold: f64) -> Self {
        Self {
            claim: claim.into(),
            holds: measured <= threshold,
            measured: Some(measured),
            threshold: Some(threshold),
            comparison: "measured <= threshold".into(),
        }
    }

    /// `holds` iff `measured < threshold`.
    pub fn below(claim: impl Into<String>, measured: f64, threshold: f64) -> Self {
        Self {
            claim: claim.into(),
            holds: measured < threshold,
            measured: Some(measured),
            threshold: Some(threshold),
            comparison: "measured < threshold".into(),
        }
    }

    /// A verdict with an explicit outcome and a description of the comparison.
    pub fn new(
        claim: impl Into<String>,
        holds: bool,
        measured: Option<f64>,
        threshold: Option<f64>,
        comparison: impl Into<String>,
    ) -> Self {
        Self {
            claim: claim.into(),
            holds,
            measured,
            threshold,
            comparison: comparison.into(),
        }
    }
}

/// Write a report as pretty JSON, creating parent directories; atomically (a temporary file
/// renamed over the target). Errors name the path.
pub fn write_json<T: Serialize>(path: impl AsRef<Path>, report: &T) -> std::io::Result<()> {
    let path = path.as_ref();
    let named = |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: {e}", path.display()));
    if let Some(dir) = path.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).map_err(named)?;
        }
    }
    let mut text = serde_json::to_string_pretty(report).map_err(|e| named(std::io::Error::other(e)))?;
    text.push('\n');
    crate::output::write_atomic(path, text.as_bytes())
}
