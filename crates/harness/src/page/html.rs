//! The page itself: one self-contained HTML document (inline style, plots embedded as data
//! URLs, no script) from the [`Contents`] of a reports directory.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use super::encode::{escape, short_number, url_path};
use super::reports::{Contents, Found, Origin, Report};
use diffsoft::output::base64;

/// Counts the page states in its summary line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Counts {
    pub verdicts: usize,
    pub failing: usize,
    pub expected_failing: usize,
}

const STYLE: &str = "
:root { color-scheme: light; }
body { font: 14px/1.45 system-ui, -apple-system, 'Segoe UI', Roboto, sans-serif; color: #1d2430;
  margin: 0 auto; max-width: 1320px; padding: 18px 24px 40px; }
h1 { font-size: 22px; margin: 4px 0 10px; }
h2 { font-size: 18px; margin: 28px 0 10px; border-bottom: 1px solid #d0d5dd; padding-bottom: 4px; }
a { color: #175cd3; }
code { font: 12.5px ui-monospace, SFMono-Regular, Menlo, Consolas, monospace; }
.summary { font-size: 16px; margin: 0 0 8px; padding: 10px 14px; border-radius: 6px;
  background: #f2f4f7; border-left: 5px solid #1a7f37; }
.summary.failing { border-left-color: #b42318; }
.summary .n-fail { color: #b42318; font-weight: 600; }
.summary .n-hold { color: #1a7f37; font-weight: 600; }
.meta { color: #475467; margin: 4px 0; }
nav a { margin-right: 14px; }
table { border-collapse: collapse; width: 100%; }
th, td { border-bottom: 1px solid #e4e7ec; padding: 5px 8px; vertical-align: top; text-align: left; }
thead th { position: sticky; top: 0; background: #eaecf0; font-weight: 600; z-index: 1; }
table.verdicts { table-layout: fixed; }
col.c-status { width: 118px; } col.c-num { width: 92px; } col.c-cmp { width: 250px; }
col.c-report { width: 150px; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.cmp { color: #475467; font-size: 12px; overflow-wrap: anywhere; }
td.claim { overflow-wrap: anywhere; }
.place { display: block; color: #667085; font-size: 12px; }
td.status { font-weight: 600; white-space: nowrap; }
tr.fail td { background: #fde8e7; }
tr.fail td.status { color: #b42318; }
tr.expected td { background: #fff3dc; }
tr.expected td.status { color: #93590b; }
tr.holds td.status { color: #1a7f37; }
td.report { font-size: 12.5px; overflow-wrap: anywhere; }
table.files td { font-size: 13px; }
.plots { display: grid; grid-template-columns: repeat(auto-fill, minmax(600px, 1fr)); gap: 18px; }
figure { margin: 0; }
figure img { width: 100%; height: auto; border: 1px solid #e4e7ec; background: #fff; }
figcaption { font-size: 12.5px; color: #475467; }
";

/// Failing verdicts first (unexpected failures, then known ones), then those that hold; in
/// report order, and in each report in the order found.
pub(crate) fn ordered(contents: &Contents) -> Vec<(&Report, &Found)> {
    let mut rows: Vec<(&Report, &Found)> = contents
        .reports
        .iter()
        .flat_map(|r| r.verdicts.iter().map(move |v| (r, v)))
        .collect();
    let rank = |v: &Found| match (v.holds, v.expected_to_fail) {
        (false, false) => 0,
        (false, true) => 1,
        (true, _) => 2,
    };
    // A stable sort keeps report and document order within a rank.
    rows.sort_by_key(|(_, v)| rank(v));
    rows
}

/// The HTML document and its counts.
pub(crate) fn render(contents: &Contents) -> (String, Counts) {
    let rows = ordered(contents);
    let counts = Counts {
        verdicts: rows.len(),
        failing: rows.iter().filter(|(_, v)| !v.holds).count(),
        expected_failing: rows.iter().filter(|(_, v)| !v.holds && v.expected_to_fail).count(),
    };
    let mut h = String::new();
    h.push_str("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n");
    h.push_str("<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n");
    h.push_str("<title>diffsoft: verification reports</title>\n<style>");
    h.push_str(STYLE);
    h.push_str("</style>\n</head>\n<body>\n<header>\n<h1>diffsoft: verification reports</h1>\n");
    summary(&mut h, contents, counts);
    h.push_str(
        "<nav><a href=\"#verdicts\">Verdicts</a><a href=\"#reports\">Reports and provenance</a><a href=\"#plots\">Plots</a></nav>\n</header>\n",
    );
    verdicts(&mut h, &rows);
    files(&mut h, contents);
    plots(&mut h, contents);
    h.push_str("</body>\n</html>\n");
    (h, counts)
}

fn summary(h: &mut String, contents: &Contents, c: Counts) {
    let holding = c.verdicts - c.failing;
    let _ = write!(
        h,
        "<p class=\"summary{}\" id=\"summary\"><strong>{} verdicts</strong> in {} reports: <span class=\"n-fail\">{} fail</span>",
        if c.failing > 0 { " failing" } else { "" },
        c.verdicts,
        contents.reports.len(),
        c.failing
    );
    if c.expected_failing > 0 {
        let _ = write!(h, " ({} of them expected to fail)", c.expected_failing);
    }
    let _ = writeln!(
        h,
        ", <span class=\"n-hold\">{holding} hold</span>. Failing verdicts come first.</p>"
    );
    // Which reports the failures are in.
    let failing: Vec<String> = contents
        .reports
        .iter()
        .filter_map(|r| {
            let n = r.verdicts.iter().filter(|v| !v.holds).count();
            (n > 0).then(|| {
                format!(
                    "<a href=\"{}\">{}</a> {n} of {}",
                    escape(&url_path(&r.file)),
                    escape(&r.file),
                    r.verdicts.len()
                )
            })
        })
        .collect();
    if !failing.is_empty() {
        let _ = writeln!(h, "<p class=\"meta\">Failing: {}.</p>", failing.join(", "));
    }
    // Where the reports come from: commits (most reports first) and the span of dates.
    let origins: Vec<&Origin> = contents.reports.iter().filter_map(|r| r.provenance.as_ref()).collect();
    let mut commits: BTreeMap<&str, usize> = BTreeMap::new();
    for o in &origins {
        *commits.entry(o.git_commit.as_deref().unwrap_or("unknown")).or_default() += 1;
    }
    let mut commits: Vec<(&str, usize)> = commits.into_iter().collect();
    commits.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(b.0)));
    let dates: Vec<&str> = origins.iter().filter_map(|o| o.date_utc.as_deref()).collect();
    let _ = write!(
        h,
        "<p class=\"meta\">Provenance recorded by {} of the {} reports",
        origins.len(),
        contents.reports.len()
    );
    if !commits.is_empty() {
        let list: Vec<String> = commits
            .iter()
            .map(|(c, n)| {
                format!(
                    "<code title=\"{}\">{}</code> ({n})",
                    escape(c),
                    escape(&short_commit(c))
                )
            })
            .collect();
        let _ = write!(h, "; git commit {}", list.join(", "));
    }
    if let (Some(first), Some(last)) = (dates.iter().min(), dates.iter().max()) {
        let _ = write!(h, "; written {} to {} (UTC)", escape(first), escape(last));
    }
    let _ = writeln!(
        h,
        ". {} plots. Every JSON file is linked below.</p>",
        contents.plots.len()
    );
}

fn short_commit(c: &str) -> String {
    let (hash, dirty) = match c.strip_suffix("-dirty") {
        Some(h) => (h, "-dirty"),
        None => (c, ""),
    };
    let hash: String = hash.chars().take(12).collect();
    format!("{hash}{dirty}")
}

fn number_cell(h: &mut String, class: &str, x: Option<f64>) {
    match x {
        Some(x) => {
            let _ = write!(
                h,
                "<td class=\"num {class}\" data-value=\"{x:e}\" title=\"{x:e}\">{}</td>",
                short_number(x)
            );
        }
        None => {
            let _ = write!(h, "<td class=\"num {class}\">&#8212;</td>");
        }
    }
}

fn verdicts(h: &mut String, rows: &[(&Report, &Found)]) {
    h.push_str("<section id=\"verdicts\">\n<h2>Verdicts</h2>\n<table class=\"verdicts\">\n");
    h.push_str("<colgroup><col class=\"c-status\"><col><col class=\"c-num\"><col class=\"c-num\"><col class=\"c-cmp\"><col class=\"c-report\"></colgroup>\n");
    h.push_str("<thead><tr><th>holds</th><th>claim</th><th>measured</th><th>threshold</th><th>comparison</th><th>report</th></tr></thead>\n<tbody>\n");
    for (r, v) in rows {
        let (class, status) = match (v.holds, v.expected_to_fail) {
            (true, _) => ("holds", "holds"),
            (false, false) => ("fail", "FAILS"),
            (false, true) => ("fail expected", "FAILS (expected)"),
        };
        let _ = write!(
            h,
            "<tr class=\"verdict {class}\" data-report=\"{}\" data-holds=\"{}\"><td class=\"status\">{status}</td><td class=\"claim\"><span class=\"claim-text\">{}</span>",
            escape(&r.file),
            v.holds,
            escape(&v.claim)
        );
        if !v.place.is_empty() {
            let _ = write!(h, "<span class=\"place\">{}</span>", escape(&v.place));
        }
        h.push_str("</td>");
        number_cell(h, "measured", v.measured);
        number_cell(h, "threshold", v.threshold);
        let _ = writeln!(
            h,
            "<td class=\"cmp\">{}</td><td class=\"report\"><a href=\"{}\">{}</a></td></tr>",
            escape(&v.comparison),
            escape(&url_path(&r.file)),
            escape(&r.file)
        );
    }
    h.push_str("</tbody>\n</table>\n</section>\n");
}

fn files(h: &mut String, contents: &Contents) {
    h.push_str("<section id=\"reports\">\n<h2>Reports and provenance</h2>\n<table class=\"files\">\n");
    h.push_str("<thead><tr><th>report</th><th>schema</th><th>verdicts</th><th>failing</th><th>git commit</th><th>written (UTC)</th><th>machine</th><th>compiler</th></tr></thead>\n<tbody>\n");
    for r in &contents.reports {
        let failing = r.verdicts.iter().filter(|v| !v.holds).count();
        let _ = write!(
            h,
            "<tr class=\"file\"><td><a href=\"{}\">{}</a></td><td><code>{}</code>{}</td><td class=\"num\">{}</td><td class=\"num\">{failing}</td>",
            escape(&url_path(&r.file)),
            escape(&r.file),
            escape(r.schema.as_deref().unwrap_or("")),
            r.crate_version
                .as_deref()
                .map(|v| format!(" <span class=\"meta\">crate {}</span>", escape(v)))
                .unwrap_or_default(),
            r.verdicts.len()
        );
        match &r.provenance {
            Some(o) => {
                let commit = o.git_commit.as_deref().unwrap_or("unknown");
                let mut machine = o.cpu_model.clone().unwrap_or_else(|| "unknown CPU".into());
                if let Some(n) = o.cpus {
                    let _ = write!(machine, ", {n} CPUs");
                }
                if let Some(t) = o.threads {
                    let _ = write!(machine, ", {t} threads");
                }
                if let Some(os) = &o.os {
                    let _ = write!(machine, ", {os}");
                }
                let _ = writeln!(
                    h,
                    "<td><code title=\"{}\">{}</code></td><td>{}</td><td>{}</td><td>{}</td></tr>",
                    escape(commit),
                    escape(&short_commit(commit)),
                    escape(o.date_utc.as_deref().unwrap_or("")),
                    escape(&machine),
                    escape(o.rustc_version.as_deref().unwrap_or(""))
                );
            }
            None => h.push_str("<td colspan=\"4\" class=\"meta\">no provenance recorded in this report</td></tr>\n"),
        }
    }
    h.push_str("</tbody>\n</table>\n</section>\n");
}

fn plots(h: &mut String, contents: &Contents) {
    h.push_str("<section id=\"plots\">\n<h2>Plots</h2>\n<div class=\"plots\">\n");
    for p in &contents.plots {
        let _ = writeln!(
            h,
            "<figure><img src=\"data:image/svg+xml;base64,{}\" alt=\"{}\"><figcaption><a href=\"{}\">{}</a></figcaption></figure>",
            base64(&p.svg),
            escape(&p.file),
            escape(&url_path(&p.file)),
            escape(&p.file)
        );
    }
    h.push_str("</div>\n</section>\n");
}
