//! The report page (`reports/index.html`): on a small synthetic reports directory it escapes
//! every text, puts failing verdicts first and shows every verdict; bad input is an error that
//! names the file and key; and the committed page is the one the committed reports give.

use crate::common::{root, tmp_dir};
use diffsoft_harness::page;

/// A verdict as a report writes it.
fn verdict(claim: &str, holds: bool, measured: f64, threshold: f64) -> String {
    serde_json::json!({"claim": claim, "holds": holds, "measured": measured, "threshold": threshold,
        "comparison": "measured <= threshold"})
    .to_string()
}

/// The rows of the verdict table in page order: (class, text of the row).
fn rows(html: &str) -> Vec<(String, String)> {
    html.split("<tr class=\"verdict ")
        .skip(1)
        .map(|r| {
            let (class, rest) = r.split_once('"').unwrap();
            (class.to_string(), rest[..rest.find("</tr>").unwrap()].to_string())
        })
        .collect()
}

fn synthetic(name: &str) -> std::path::PathBuf {
    let dir = tmp_dir(name);
    std::fs::create_dir_all(dir.join("sweeps")).unwrap();
    let a = format!(
        r#"{{"schema": "diffsoft.a/1", "crate_version": "0.1.0",
            "provenance": {{"git_commit": "0123456789abcdef0123-dirty", "date_utc": "2026-11-27T10:00:00Z",
              "threads": 2, "cpu_model": "Test <CPU> & co", "cpus": 2, "rustc_version": "rustc 1.0", "os": "linux x86_64"}},
            "verdicts": [{}, {}, {}]}}"#,
        verdict("a1 holds: x < 1 & y > 2", true, 0.5, 1.0),
        verdict("a2 fails: <script>alert('x')</script>", false, 3.0, 2.0),
        verdict("a3 holds \"quoted\"", true, 1e-12, 1e-9),
    );
    std::fs::write(dir.join("a.json"), a).unwrap();
    // Nested verdicts, a case known to fail, no provenance.
    let b = format!(
        r#"{{"schema": "diffsoft.b/1",
            "cases": [{{"id": "known", "expected_to_hold": false, "verdict": {}}},
                      {{"id": "fine", "expected_to_hold": true, "verdict": {}}}],
            "meshes": [{{"name": "bridge", "bounds": {{"verdicts": [{}]}}}}],
            "summary": {{"holds": 1}}}}"#,
        verdict("b1 fails as expected", false, 2.0, 1.0),
        verdict("b2 holds", true, 0.0, 1.0),
        verdict("b3 fails", false, 5.0, 4.0),
    );
    std::fs::write(dir.join("sweeps/b w#.json"), b).unwrap();
    std::fs::write(
        dir.join("plot.svg"),
        r#"<svg width="10" height="10" xmlns="http://www.w3.org/2000/svg"><rect width="5" height="5"/></svg>"#,
    )
    .unwrap();
    // Neither a temporary file of an atomic write nor other files are read.
    std::fs::write(dir.join(".a.json.tmp.1.0"), "{not json").unwrap();
    std::fs::write(dir.join("notes.txt"), "{not json").unwrap();
    dir
}

#[test]
fn escapes_orders_failing_first_and_shows_every_verdict() {
    let dir = synthetic("page-synthetic");
    let p = page::render(&dir).unwrap();
    assert_eq!(
        (p.verdicts, p.failing, p.expected_failing, p.reports, p.plots),
        (6, 3, 1, 2, 1)
    );
    let rows = rows(&p.html);
    assert_eq!(rows.len(), 6);
    // Failing first (unexpected ones, then the one expected to fail), each group in report order.
    let claims: Vec<&str> = rows
        .iter()
        .map(|(_, r)| {
            let start = r.find("claim-text\">").unwrap() + "claim-text\">".len();
            &r[start..start + 2]
        })
        .collect();
    assert_eq!(claims, ["a2", "b3", "b1", "a1", "a3", "b2"]);
    let classes: Vec<&str> = rows.iter().map(|(c, _)| c.as_str()).collect();
    assert_eq!(classes, ["fail", "fail", "fail expected", "holds", "holds", "holds"]);
    // Every text escaped: no markup from a report reaches the page.
    assert!(!p.html.contains("<script"), "a claim's markup reached the page");
    assert!(p
        .html
        .contains("a2 fails: &lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt;"));
    assert!(p.html.contains("a1 holds: x &lt; 1 &amp; y &gt; 2"));
    assert!(p.html.contains("a3 holds &quot;quoted&quot;"));
    assert!(p.html.contains("Test &lt;CPU&gt; &amp; co, 2 CPUs, 2 threads"));
    // Measured and threshold, shown and exact.
    let a2 = &rows[0].1;
    assert!(
        a2.contains("data-value=\"3e0\" title=\"3e0\">3</td>") && a2.contains(">2</td>"),
        "{a2}"
    );
    assert!(
        rows[4].1.contains(">1e-12</td>") && rows[4].1.contains(">1e-9</td>"),
        "{}",
        rows[4].1
    );
    // Where a nested verdict sits, and the link to its report (the name URL-encoded).
    assert!(rows[1].1.contains("meshes[bridge] › bounds"));
    assert!(rows[2].1.contains("cases[known]"));
    assert!(rows[1]
        .1
        .contains("<a href=\"sweeps/b%20w%23.json\">sweeps/b w#.json</a>"));
    // The summary line and the provenance.
    assert!(p.html.contains("<strong>6 verdicts</strong> in 2 reports: <span class=\"n-fail\">3 fail</span> (1 of them expected to fail), <span class=\"n-hold\">3 hold</span>"));
    assert!(p
        .html
        .contains("<code title=\"0123456789abcdef0123-dirty\">0123456789ab-dirty</code>"));
    assert!(p.html.contains("no provenance recorded in this report"));
    // The plot embedded, the page self-contained.
    assert!(p.html.contains(&format!(
        "src=\"data:image/svg+xml;base64,{}",
        "PHN2ZyB3aWR0aD0iMTAiIGhlaWdodD0iMTAi"
    )));
    assert!(!p.html.contains("http"), "the page names a network address");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn writes_index_html_atomically_and_the_same_reports_give_the_same_page() {
    let dir = synthetic("page-write");
    let (p, path) = page::write(&dir).unwrap();
    assert_eq!(path, dir.join("index.html"));
    assert_eq!(std::fs::read_to_string(&path).unwrap(), p.html);
    // Rendering again (the page itself is not an input) gives the same bytes.
    assert_eq!(page::render(&dir).unwrap().html, p.html);
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp.") && n != ".a.json.tmp.1.0")
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_reports_are_errors_naming_the_file_and_key() {
    let message = |e: anyhow::Error| format!("{e:#}");
    let missing = tmp_dir("page-missing").join("nothing");
    assert!(message(page::render(&missing).unwrap_err()).contains("nothing"));
    let empty = tmp_dir("page-empty");
    assert!(message(page::render(&empty).unwrap_err()).contains("no JSON report"));

    let dir = synthetic("page-bad-holds");
    std::fs::write(
        dir.join("c.json"),
        r#"{"scenes": [{"verdicts": [{"claim": "x", "holds": "yes"}]}]}"#,
    )
    .unwrap();
    let e = message(page::render(&dir).unwrap_err());
    assert!(
        e.contains("c.json") && e.contains("/scenes/0/verdicts/0/holds: expected true or false"),
        "{e}"
    );

    let dir = synthetic("page-bad-json");
    std::fs::write(dir.join("c.json"), "{\"verdicts\": [").unwrap();
    let e = message(page::render(&dir).unwrap_err());
    assert!(e.contains("c.json: not valid JSON") && e.contains("line 1"), "{e}");

    let dir = synthetic("page-bad-svg");
    std::fs::write(dir.join("sweeps/p.svg"), "GIF89a").unwrap();
    let e = message(page::render(&dir).unwrap_err());
    assert!(e.contains("p.svg: not an SVG image"), "{e}");
    for d in [missing.parent().unwrap().to_path_buf(), empty, dir] {
        let _ = std::fs::remove_dir_all(d);
    }
}

/// The committed page is the one the committed reports give, so it never goes stale: a
/// regenerated report fails here until the page is rewritten.
#[test]
fn the_committed_page_is_up_to_date() {
    let reports = root().join("reports");
    let page = page::render(&reports).unwrap();
    let committed = std::fs::read_to_string(reports.join(page::FILE)).unwrap_or_default();
    assert!(
        committed == page.html,
        "reports/index.html is not the page of reports/*.json: rewrite it with `cargo run --release -- report-page`"
    );
    assert!(page.verdicts > 0 && page.reports > 0 && page.plots > 0);
}
