//! Line-oriented tokenising shared by the mesh readers: line numbers, comments, number parsing.

use super::error::{MeshError, MeshErrorKind};

/// A cursor over the non-empty lines of a text file that remembers line numbers.
pub(crate) struct LineCursor<'a> {
    path: &'a str,
    lines: std::iter::Enumerate<std::str::Lines<'a>>,
    comment: Option<char>,
    /// Line number of the last line returned (0 before the first).
    pub last_line: usize,
}

impl<'a> LineCursor<'a> {
    /// A cursor over `text`; everything after `comment` on a line is ignored.
    pub fn new(path: &'a str, text: &'a str, comment: Option<char>) -> Self {
        Self {
            path,
            lines: text.lines().enumerate(),
            comment,
            last_line: 0,
        }
    }

    /// The path used in error messages.
    pub fn path(&self) -> &'a str {
        self.path
    }

    /// The next line with content: (1-based line number, content without comment, trimmed).
    pub fn next_line(&mut self) -> Option<(usize, &'a str)> {
        for (i, raw) in self.lines.by_ref() {
            let content = match self.comment {
                Some(c) => raw.split(c).next().unwrap_or(""),
                None => raw,
            }
            .trim();
            self.last_line = i + 1;
            if !content.is_empty() {
                return Some((i + 1, content));
            }
        }
        None
    }

    /// The next line with content, or a `Truncated` error naming what was expected.
    pub fn expect_line(&mut self, what: &str) -> Result<(usize, &'a str), MeshError> {
        match self.next_line() {
            Some(l) => Ok(l),
            None => Err(MeshError::at(
                self.path,
                self.last_line.max(1),
                MeshErrorKind::Truncated(format!("expected {what}")),
            )),
        }
    }
}

/// Parse a finite `f64`, naming the file and line on failure.
pub(crate) fn parse_coord(path: &str, line: usize, tok: &str) -> Result<f64, MeshError> {
    let v: f64 = tok.parse().map_err(|_| {
        MeshError::at(
            path,
            line,
            MeshErrorKind::BadNumber {
                expected: "a real number",
                found: tok.to_string(),
            },
        )
    })?;
    if !v.is_finite() {
        return Err(MeshError::at(path, line, MeshErrorKind::NonFinite(tok.to_string())));
    }
    Ok(v)
}

/// Parse a signed integer (indices may be written negative in malformed files).
pub(crate) fn parse_int(path: &str, line: usize, tok: &str) -> Result<i64, MeshError> {
    tok.parse().map_err(|_| {
        MeshError::at(
            path,
            line,
            MeshErrorKind::BadNumber {
                expected: "an integer",
                found: tok.to_string(),
            },
        )
    })
}

/// Parse a non-negative count.
pub(crate) fn parse_count(path: &str, line: usize, tok: &str) -> Result<usize, MeshError> {
    tok.parse().map_err(|_| {
        MeshError::at(
            path,
            line,
            MeshErrorKind::BadNumber {
                expected: "a non-negative integer",
                found: tok.to_string(),
            },
        )
    })
}

/// Split a line into exactly-at-least `n` tokens, or a syntax error naming `what`.
pub(crate) fn tokens_at_least<'a>(
    path: &str,
    line: usize,
    content: &'a str,
    n: usize,
    what: &str,
) -> Result<Vec<&'a str>, MeshError> {
    let toks: Vec<&str> = content.split_whitespace().collect();
    if toks.len() < n {
        return Err(MeshError::at(
            path,
            line,
            MeshErrorKind::Syntax(format!(
                "{what} needs at least {n} fields, found {} ('{content}')",
                toks.len()
            )),
        ));
    }
    Ok(toks)
}
