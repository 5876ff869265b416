//! The report page: `reports/index.html`, one self-contained HTML file a person opens to see
//! what holds and what does not. It shows every verdict of every JSON report in the
//! directory as a table (claim, measured, threshold, comparison, report), failing verdicts
//! first, the provenance of each report with a link to its JSON file, and every SVG plot
//! embedded (as a data URL: no network, no script).
//!
//! The page is a function of the directory's files only (no date of its own), so the same
//! reports give the same page: the main job writes it last ([`write`]), and
//! `diffsoft report-page` rewrites it from the reports there are.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

mod encode;
mod html;
mod reports;

/// The page's file name inside the reports directory.
pub const FILE: &str = "index.html";

/// A rendered page and what its summary line counts.
#[derive(Debug, Clone)]
pub struct Page {
    /// The HTML document.
    pub html: String,
    /// Verdicts on the page (every one of every report).
    pub verdicts: usize,
    /// Of them, those that fail.
    pub failing: usize,
    /// Of the failing ones, those whose case says it is expected to fail (`expected_to_hold: false`).
    pub expected_failing: usize,
    /// JSON reports read.
    pub reports: usize,
    /// SVG plots embedded.
    pub plots: usize,
}

/// Render the page of the reports directory `dir` (every `*.json` and `*.svg` under it).
///
/// Errors name the file, and for a malformed verdict its JSON path and key; a directory
/// without any JSON report is an error.
///
/// ```
/// let dir = std::env::temp_dir().join(format!("diffsoft-page-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir)?;
/// std::fs::write(
///     dir.join("a.json"),
///     r#"{"schema": "diffsoft.a/1", "verdicts": [
///         {"claim": "x < 1", "holds": true, "measured": 0.5, "threshold": 1, "comparison": "measured < threshold"},
///         {"claim": "y <= 2", "holds": false, "measured": 3, "threshold": 2, "comparison": "measured <= threshold"}]}"#,
/// )?;
/// let page = diffsoft_harness::page::render(&dir)?;
/// assert_eq!((page.verdicts, page.failing, page.reports), (2, 1, 1));
/// // Escaped, and the failing verdict first.
/// let (fails, holds) = (page.html.find("y &lt;= 2").unwrap(), page.html.find("x &lt; 1").unwrap());
/// assert!(fails < holds);
/// std::fs::remove_dir_all(&dir)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn render(dir: &Path) -> Result<Page> {
    let contents = reports::read(dir)?;
    let (html, counts) = html::render(&contents);
    Ok(Page {
        html,
        verdicts: counts.verdicts,
        failing: counts.failing,
        expected_failing: counts.expected_failing,
        reports: contents.reports.len(),
        plots: contents.plots.len(),
    })
}

/// Render the page of `dir` and write it to `dir/index.html` atomically (a temporary file
/// beside it, renamed over it). Returns the page and the path written.
pub fn write(dir: &Path) -> Result<(Page, PathBuf)> {
    let page = render(dir)?;
    let path = diffsoft::output::own_file(dir, FILE)?;
    crate::report::write_atomic(&path, page.html.as_bytes()).with_context(|| "cannot write the report page")?;
    Ok((page, path))
}
