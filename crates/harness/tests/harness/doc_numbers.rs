//! The numbers the README and the docs/ pages quote from the committed reports are checked
//! against those reports, so a regenerated report that moves a number fails here until the text
//! is updated.
//!
//! A quoted number carries an invisible marker right after it:
//! `6.2e-8<!-- @gradients.json:cases[name=free_body].modes[mode=unrolled].worst_rel_error -->`.
//! The path is dotted keys; `key[3]` indexes an array, `key[field=value]` takes the first element
//! whose field equals the value, and a trailing `#` counts (the array, or the elements matching
//! the last filter). The quoted number must equal the report's value rounded to the quoted
//! number's last quoted place (a `%` after the number quotes a fraction in percent). Fenced blocks marked `<!-- @file:NAME -->` on the line before
//! must equal the report file NAME (a table the main job writes) line by line.

use serde_json::Value;

/// The value at `path` in `v` (see the module doc).
fn lookup(v: &Value, path: &str) -> Result<f64, String> {
    let (path, count) = match path.strip_suffix('#') {
        Some(p) => (p, true),
        None => (path, false),
    };
    let mut cur = v.clone();
    // Dots inside a selector (`cases[id=a.b]`) belong to the selector's value.
    let mut segments: Vec<&str> = Vec::new();
    let (mut depth, mut start) = (0usize, 0usize);
    for (i, ch) in path.char_indices() {
        match ch {
            '[' => depth += 1,
            ']' => depth = depth.saturating_sub(1),
            '.' if depth == 0 => {
                segments.push(&path[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    segments.push(&path[start..]);
    for (k, seg) in segments.iter().enumerate() {
        let last = k + 1 == segments.len();
        let (key, sel) = match seg.find('[') {
            Some(i) => (&seg[..i], Some(seg[i + 1..].trim_end_matches(']'))),
            None => (*seg, None),
        };
        if !key.is_empty() {
            cur = cur
                .get(key)
                .cloned()
                .ok_or_else(|| format!("no key '{key}' at '{seg}'"))?;
        }
        match sel {
            None => {}
            Some(s) => match s.split_once('=') {
                None => {
                    let i: usize = s.parse().map_err(|_| format!("bad index '{s}'"))?;
                    cur = cur
                        .get(i)
                        .cloned()
                        .ok_or_else(|| format!("no element {i} at '{seg}'"))?;
                }
                Some((field, want)) => {
                    let arr = cur.as_array().ok_or_else(|| format!("'{seg}' is not an array"))?;
                    let matches = |e: &&Value| match e.get(field) {
                        Some(Value::String(x)) => x == want,
                        // Numbers and booleans compare in their JSON spelling (`3`, `true`).
                        Some(x) => serde_json::to_string(x).is_ok_and(|shown| shown == want),
                        None => false,
                    };
                    if last && count {
                        return Ok(arr.iter().filter(matches).count() as f64);
                    }
                    cur = arr
                        .iter()
                        .find(matches)
                        .cloned()
                        .ok_or_else(|| format!("no element with {field} = {want} at '{seg}'"))?;
                }
            },
        }
    }
    if count {
        return cur
            .as_array()
            .map(|a| a.len() as f64)
            .ok_or_else(|| format!("'{path}' is not an array to count"));
    }
    cur.as_f64().ok_or_else(|| format!("'{path}' is {cur}, not a number"))
}

/// Whether `value` rounds to the quoted `text`: within half a unit of its last quoted place
/// (`20%` quotes 0.20 to the nearest percent).
fn agrees(text: &str, value: f64) -> bool {
    if let Some(percent) = text.strip_suffix('%') {
        return agrees(percent, value * 100.0);
    }
    let Ok(quoted) = text.parse::<f64>() else {
        return false;
    };
    let mut parts = text.split(['e', 'E']);
    let mantissa = parts.next().unwrap_or(text);
    let exponent = parts.next().map_or(0, |e| e.parse::<i32>().unwrap_or(0));
    let decimals = mantissa.split('.').nth(1).map_or(0, |d| d.len() as i32);
    let unit = 10f64.powi(exponent - decimals);
    (value - quoted).abs() <= 0.5 * unit * (1.0 + 1e-9)
}

/// Every marker of `doc`: (line, quoted number, report file, path).
fn markers(doc: &str) -> Vec<(usize, String, String, String)> {
    let mut out = Vec::new();
    for (n, line) in doc.lines().enumerate() {
        let mut rest = line;
        let mut offset = 0;
        while let Some(i) = rest.find("<!-- @") {
            let before = &line[..offset + i];
            let number: String = before
                .chars()
                .rev()
                .take_while(|c| c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '-' | '+' | '%'))
                .collect::<Vec<_>>()
                .into_iter()
                .rev()
                .collect();
            // A '-' right after a digit or a marker is a range dash ("0.37-1.06"), not a sign.
            let number = match number.strip_prefix('-') {
                Some(unsigned)
                    if before[..before.len() - number.len()]
                        .chars()
                        .next_back()
                        .is_some_and(|c| c.is_ascii_digit() || c == '>') =>
                {
                    unsigned.to_string()
                }
                _ => number,
            };
            let end = rest[i..].find("-->").map_or(rest.len(), |e| i + e + 3);
            let body = rest[i + 6..end - 3].trim();
            if let Some((file, path)) = body.split_once(':') {
                if file != "file" {
                    out.push((
                        n + 1,
                        number.trim_start_matches(['e', 'E']).to_string(),
                        file.into(),
                        path.into(),
                    ));
                }
            }
            offset += end;
            rest = &rest[end..];
        }
    }
    out
}

fn documents() -> Vec<std::path::PathBuf> {
    let root = crate::common::root();
    let mut docs = vec![root.join("README.md")];
    for e in std::fs::read_dir(root.join("docs")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "md") {
            docs.push(p);
        }
    }
    docs.sort();
    docs
}

#[test]
fn quoted_numbers_match_the_committed_reports() {
    let root = crate::common::root();
    let mut failures = Vec::new();
    let mut checked = 0;
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).unwrap();
        for (line, number, file, path) in markers(&text) {
            let report: Value = match std::fs::read_to_string(root.join("reports").join(&file)) {
                Ok(t) => serde_json::from_str(&t).unwrap(),
                Err(e) => {
                    failures.push(format!("{}:{line}: reports/{file}: {e}", doc.display()));
                    continue;
                }
            };
            checked += 1;
            match lookup(&report, &path) {
                Ok(v) if agrees(&number, v) => {}
                Ok(v) => failures.push(format!(
                    "{}:{line}: quotes {number} for {file}:{path}, the report has {v:e}",
                    doc.display()
                )),
                Err(e) => failures.push(format!("{}:{line}: {file}:{path}: {e}", doc.display())),
            }
        }
    }
    assert!(checked >= 10, "only {checked} quoted numbers are marked");
    assert!(
        failures.is_empty(),
        "{} quoted numbers drifted:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn quoted_tables_match_the_tables_the_main_job_writes() {
    let root = crate::common::root();
    let mut checked = 0;
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            let Some(name) = line
                .trim()
                .strip_prefix("<!-- @file:")
                .and_then(|r| r.strip_suffix("-->"))
            else {
                continue;
            };
            let name = name.trim();
            assert!(
                lines.get(i + 1).is_some_and(|l| l.starts_with("```")),
                "{}:{}: a fenced block follows",
                doc.display(),
                i + 1
            );
            let block: Vec<&str> = lines[i + 2..]
                .iter()
                .take_while(|l| !l.starts_with("```"))
                .copied()
                .collect();
            let table = std::fs::read_to_string(root.join("reports").join(name)).unwrap();
            let want: Vec<&str> = table.trim_matches('\n').lines().collect();
            assert_eq!(
                block,
                want,
                "{}:{}: the block differs from reports/{name}",
                doc.display(),
                i + 1
            );
            checked += 1;
        }
    }
    assert!(checked >= 1, "no quoted table is marked");
}

#[test]
fn the_rounding_rule() {
    assert!(agrees("6.2e-8", 6.2335e-8));
    assert!(agrees("4.8e-9", 4.7503e-9));
    assert!(!agrees("4.7e-9", 4.7503e-9 + 0.06e-9));
    assert!(agrees("35", 35.0) && !agrees("35", 34.0));
    assert!(agrees("1.73", 1.7349) && !agrees("1.73", 1.736));
    assert!(agrees("0.271", 0.2712));
    assert!(agrees("20%", 0.2005) && !agrees("21%", 0.2005));
}
