//! Merging the partial reports of a sharded sweep (`diffsoft merge`): reads the files, tells
//! the kind from their schema and hands them to the trade-off or extremes merge.

use std::path::{Path, PathBuf};

use super::shard::{check_same, ShardError};
use super::{extremes, tradeoff};

/// A merged report of either kind.
#[derive(Debug, Clone)]
pub enum Merged {
    /// A trade-off report.
    Tradeoff(Box<tradeoff::TradeoffReport>),
    /// An extremes report.
    Extremes(Box<extremes::ExtremesReport>),
}

fn parse<T: serde::de::DeserializeOwned>(v: serde_json::Value, path: &str) -> Result<T, ShardError> {
    serde_json::from_value(v).map_err(|e| ShardError::Read {
        path: path.to_string(),
        message: format!("not a valid partial report: {e}"),
    })
}

fn read_value(path: &Path) -> Result<serde_json::Value, ShardError> {
    let shown = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ShardError::Read {
        path: shown.clone(),
        message: e.to_string(),
    })?;
    serde_json::from_str(&text).map_err(|e| ShardError::Read {
        path: shown,
        message: e.to_string(),
    })
}

/// Read partial reports (`diffsoft tradeoff --shard` or `diffsoft extremes --shard` output) and
/// merge them; every file must be a partial report of the same kind.
pub fn merge_files(paths: &[PathBuf]) -> Result<Merged, ShardError> {
    let shown: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
    let mut values = Vec::with_capacity(paths.len());
    for p in paths {
        values.push(read_value(p)?);
    }
    let schemas: Vec<String> = values
        .iter()
        .map(|v| v.get("schema").and_then(|s| s.as_str()).unwrap_or("").to_string())
        .collect();
    check_same("schemas", &schemas, &shown)?;
    match schemas.first().map(String::as_str) {
        Some(tradeoff::PARTIAL_SCHEMA) => {
            let mut parts = Vec::new();
            for (v, p) in values.into_iter().zip(&shown) {
                parts.push(parse(v, p)?);
            }
            Ok(Merged::Tradeoff(Box::new(tradeoff::merge(parts, &shown)?)))
        }
        Some(extremes::PARTIAL_SCHEMA) => {
            let mut parts = Vec::new();
            for (v, p) in values.into_iter().zip(&shown) {
                parts.push(parse(v, p)?);
            }
            Ok(Merged::Extremes(Box::new(extremes::merge(parts, &shown)?)))
        }
        other => Err(ShardError::Mismatch(format!(
            "{} has schema {:?}; expected a partial report ({} or {}), written with --shard",
            shown.first().map_or("", String::as_str),
            other.unwrap_or(""),
            tradeoff::PARTIAL_SCHEMA,
            extremes::PARTIAL_SCHEMA
        ))),
    }
}
