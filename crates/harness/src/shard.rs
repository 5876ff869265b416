//! Sharding of sweeps: `--shard K/N` runs the items `i` of a sweep with `i mod N == K`
//! (`0 <= K < N`, the numbering of Slurm array task ids and Kubernetes completion indices), and
//! writes a partial report; `verify::merge::merge_files` checks that the partial reports are the `N` distinct
//! shards of one sweep and merges them into the report the unsharded run writes.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// One shard of a sweep: items `i` with `i mod count == index`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Shard {
    /// Shard number, `0 <= index < count`.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl Shard {
    /// The whole sweep as one shard.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Whether item `i` belongs to this shard.
    pub fn owns(&self, i: usize) -> bool {
        i % self.count == self.index
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Errors parsing a shard or merging partial reports.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ShardError {
    /// `--shard` is not `K/N` with `0 <= K < N`.
    #[error("shard '{0}': expected K/N with 0 <= K < N (e.g. 0/4 ... 3/4; K is the array task index)")]
    Syntax(String),
    /// A partial report cannot be read.
    #[error("{path}: {message}")]
    Read {
        /// File.
        path: String,
        /// What failed.
        message: String,
    },
    /// The partial reports do not form one sweep.
    #[error("cannot merge: {0}")]
    Mismatch(String),
    /// `--shard K/N` with more shards than the sweep has items.
    #[error("{0}")]
    TooMany(String),
}

impl FromStr for Shard {
    type Err = ShardError;
    fn from_str(s: &str) -> Result<Self, ShardError> {
        let bad = || ShardError::Syntax(s.to_string());
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let index: usize = k.trim().parse().map_err(|_| bad())?;
        let count: usize = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

/// Check that `shards` (one per partial report, named by `paths`) are exactly the shards
/// `0/N ... N-1/N` of one sweep, each once. Works in the number of reports given, whatever `N`
/// a report claims (a tampered count of 2^64 - 1 is an error, not an allocation).
pub fn check_cover(shards: &[Shard], paths: &[String]) -> Result<(), ShardError> {
    let Some(first) = shards.first() else {
        return Err(ShardError::Mismatch("no partial reports given".into()));
    };
    let n = first.count;
    let mut given: Vec<(usize, &str)> = Vec::with_capacity(shards.len());
    for (s, p) in shards.iter().zip(paths) {
        if s.count != n {
            return Err(ShardError::Mismatch(format!(
                "{p} is shard {s} but {} is shard {first}: different shard counts",
                paths[0]
            )));
        }
        if s.count == 0 || s.index >= s.count {
            return Err(ShardError::Mismatch(format!(
                "{p} claims shard {s}: the index must be below the count"
            )));
        }
        given.push((s.index, p));
    }
    given.sort_unstable();
    for w in given.windows(2) {
        if w[0].0 == w[1].0 {
            return Err(ShardError::Mismatch(format!(
                "{} and {} are both shard {}/{n}",
                w[1].1, w[0].1, w[0].0
            )));
        }
    }
    if given.len() < n {
        // The first few missing indices, found by walking the sorted given ones.
        let mut missing = Vec::new();
        let mut next = given.iter().map(|g| g.0).peekable();
        let mut k = 0;
        while k < n && missing.len() < 8 {
            if next.peek() == Some(&k) {
                next.next();
            } else {
                missing.push(format!("{k}/{n}"));
            }
            k += 1;
        }
        let more = n - given.len() - missing.len();
        return Err(ShardError::Mismatch(format!(
            "missing {} of {n} shards: {}{}",
            n - given.len(),
            missing.join(", "),
            if more > 0 {
                format!(" and {more} more")
            } else {
                String::new()
            }
        )));
    }
    Ok(())
}

/// Check, before a sharded run, that `shard` has work: a count above the sweep's `items` would
/// leave shards empty (and a merge would need that many files).
///
/// ```
/// use diffsoft_harness::shard::{check_items, Shard};
///
/// assert!(check_items(Shard { index: 0, count: 4 }, 10, "cases").is_ok());
/// let e = check_items(Shard { index: 0, count: 40 }, 10, "cases").unwrap_err();
/// assert!(e.to_string().contains("--shard 0/40: more shards than the sweep's 10 cases"));
/// ```
pub fn check_items(shard: Shard, items: usize, what: &str) -> Result<(), ShardError> {
    if shard.count > items.max(1) {
        return Err(ShardError::TooMany(format!(
            "--shard {shard}: more shards than the sweep's {items} {what}; use at most {}",
            items.max(1)
        )));
    }
    Ok(())
}

/// Check that every partial report has the same value of a field (the sweep's inputs, the crate
/// version): partial reports of different sweeps or builds do not merge. The error names the
/// first part that differs (`caps: [1,3] in a.json, [1,10] in b.json`), as JSON.
pub fn check_same<T: PartialEq + Serialize>(what: &str, values: &[T], paths: &[String]) -> Result<(), ShardError> {
    for (v, p) in values.iter().zip(paths).skip(1) {
        if v != &values[0] {
            let (a, b) = (
                serde_json::to_value(&values[0]).unwrap_or_default(),
                serde_json::to_value(v).unwrap_or_default(),
            );
            let (at, x, y) = first_difference(&a, &b, "").unwrap_or_else(|| (String::new(), a, b));
            let short = |v: &serde_json::Value| {
                let t = v.to_string();
                if t.chars().count() > 200 {
                    format!("{}...", t.chars().take(200).collect::<String>())
                } else {
                    t
                }
            };
            let field = if at.is_empty() {
                String::new()
            } else {
                format!(" at {}", at.trim_start_matches('.'))
            };
            return Err(ShardError::Mismatch(format!(
                "{what} differ{field}: {} in {}, {} in {p}",
                short(&x),
                paths[0],
                short(&y)
            )));
        }
    }
    Ok(())
}

/// The first place (a `.key` / `[i]` path) where two JSON values differ, and the two values
/// there.
fn first_difference(
    a: &serde_json::Value,
    b: &serde_json::Value,
    path: &str,
) -> Option<(String, serde_json::Value, serde_json::Value)> {
    use serde_json::Value;
    match (a, b) {
        (Value::Object(x), Value::Object(y)) if x.len() == y.len() && x.keys().all(|k| y.contains_key(k)) => x
            .iter()
            .find_map(|(k, u)| first_difference(u, &y[k], &format!("{path}.{k}"))),
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => x
            .iter()
            .zip(y)
            .enumerate()
            .find_map(|(i, (u, v))| first_difference(u, v, &format!("{path}[{i}]"))),
        _ if a == b => None,
        _ => Some((path.to_string(), a.clone(), b.clone())),
    }
}

/// A partial report written by one shard: what [`check_partials`] compares before a merge.
pub trait Partial {
    /// The shard this report holds.
    fn shard(&self) -> Shard;
    /// Its schema (a partial schema such as `diffsoft.tradeoff_partial/1`).
    fn schema(&self) -> &str;
    /// The crate version that wrote it.
    fn crate_version(&self) -> &str;
}

/// The checks every merge starts with: the partial reports (named by `paths`) are the
/// distinct shards of one sweep ([`check_cover`]), each has the partial schema `schema`, and
/// one crate version wrote them all.
pub fn check_partials<P: Partial>(parts: &[P], paths: &[String], schema: &str) -> Result<(), ShardError> {
    let shards: Vec<Shard> = parts.iter().map(Partial::shard).collect();
    check_cover(&shards, paths)?;
    for (p, path) in parts.iter().zip(paths) {
        if p.schema() != schema {
            return Err(ShardError::Mismatch(format!(
                "{path}: schema {} is not {schema}",
                p.schema()
            )));
        }
    }
    let versions: Vec<&str> = parts.iter().map(Partial::crate_version).collect();
    check_same("crate versions", &versions, paths)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_rejects() {
        assert_eq!("2/4".parse::<Shard>().unwrap(), Shard { index: 2, count: 4 });
        for bad in ["4/4", "1/0", "a/2", "3", "-1/2"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }

    #[test]
    fn shards_partition_the_items() {
        let n = 3;
        for i in 0..20 {
            let owners = (0..n).filter(|&k| Shard { index: k, count: n }.owns(i)).count();
            assert_eq!(owners, 1);
        }
    }

    /// Partial reports of different sweeps are named by the first field that differs, not by
    /// a dump of both inputs.
    #[test]
    fn differing_inputs_name_the_first_field_that_differs() {
        let p: Vec<String> = ["a.json", "b.json"].iter().map(|s| s.to_string()).collect();
        let v = |caps: &[u32]| serde_json::json!({"name": "beam", "caps": caps, "steps": 50});
        check_same("sweep inputs", &[v(&[1, 3]), v(&[1, 3])], &p).unwrap();
        let e = check_same("sweep inputs", &[v(&[1, 3]), v(&[1, 10])], &p)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "cannot merge: sweep inputs differ at caps[1]: 3 in a.json, 10 in b.json"
        );
    }

    #[test]
    fn cover_detects_missing_and_duplicate_shards() {
        let p: Vec<String> = ["a", "b", "c"].iter().map(|s| s.to_string()).collect();
        let s = |k| Shard { index: k, count: 3 };
        assert!(check_cover(&[s(0), s(1), s(2)], &p).is_ok());
        let e = check_cover(&[s(0), s(2)], &p).unwrap_err().to_string();
        assert!(e.contains("missing 1 of 3 shards: 1/3"), "{e}");
        let e = check_cover(&[s(0), s(0), s(2)], &p).unwrap_err().to_string();
        assert!(e.contains("both shard 0/3"), "{e}");
        // Tampered shards: an index past the count, a count no set of files could cover.
        let e = check_cover(&[s(0), Shard { index: 5, count: 3 }], &p)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("b claims shard 5/3: the index must be below the count"),
            "{e}"
        );
        let huge = |k| Shard {
            index: k,
            count: usize::MAX,
        };
        let e = check_cover(&[huge(0), huge(1)], &p).unwrap_err().to_string();
        assert!(
            e.contains(&format!("missing {} of {} shards: 2/", usize::MAX - 2, usize::MAX)) && e.contains("more"),
            "{e}"
        );
    }
}
