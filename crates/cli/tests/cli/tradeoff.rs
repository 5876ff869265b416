//! `diffsoft tradeoff --shard` and `diffsoft merge`.

use serde_json::Value;

use crate::common::tmp_dir;
use crate::run::diffsoft;

#[test]
fn cli_shards_and_merge() {
    let dir = tmp_dir("tradeoff-cli");
    let p = |f: &str| dir.join(f).to_str().unwrap().to_string();
    let common = [
        "tradeoff",
        "--cantilever",
        "4,1,1",
        "--steps",
        "3",
        "--dt-divisors",
        "1,2",
        "--reference-divisor",
        "4",
        "--families",
        "direct,chebyshev",
        "--caps",
        "1,2",
        "--tolerances",
        "1e-6",
        "--time-axis",
        "iterations",
        "--min-timing-s",
        "0",
    ];
    let run = |extra: &[&str]| {
        let mut a: Vec<&str> = common.to_vec();
        a.extend_from_slice(extra);
        let out = diffsoft(&a);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let whole = run(&["--json", &p("whole.json")]);
    assert!(whole.contains("Pareto front"), "{whole}");
    run(&["--shard", "0/2", "--json", &p("a.json")]);
    run(&["--shard", "1/2", "--json", &p("b.json")]);
    let out = diffsoft(&["merge", &p("a.json"), &p("b.json"), "-o", &p("merged.json")]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let read = |f: &str| -> Value { serde_json::from_str(&std::fs::read_to_string(dir.join(f)).unwrap()).unwrap() };
    let (mut w, mut m) = (read("whole.json"), read("merged.json"));
    assert_eq!(w["schema"], "diffsoft.tradeoff/1");
    assert_eq!(read("a.json")["schema"], "diffsoft.tradeoff_partial/1");
    // Where each shard ran reaches the merged report (the whole run: one shard); the report
    // itself says where it was written, as every report does.
    let shard_provenance = |v: &Value| {
        v["scenes"][0]["method"]["shard_provenance"]
            .as_array()
            .cloned()
            .unwrap()
    };
    assert_eq!(shard_provenance(&w).len(), 1);
    let merged_shards = shard_provenance(&m);
    assert_eq!(merged_shards.len(), 2);
    for (k, part) in ["a.json", "b.json"].iter().enumerate() {
        assert!(
            read(part)["provenance"]["date_utc"].is_string(),
            "{part} has no provenance"
        );
        assert_eq!(merged_shards[k], read(part)["provenance"], "shard {k}");
    }
    assert!(m["provenance"]["date_utc"].is_string() && w["provenance"]["cpus"].as_u64() >= Some(1));
    assert!(dir.join("tradeoff_cantilever_24.svg").exists());
    crate::common::strip_keys(&mut w, crate::common::RUN_DEPENDENT_KEYS);
    crate::common::strip_keys(&mut m, crate::common::RUN_DEPENDENT_KEYS);
    assert_eq!(crate::common::json_difference(&w, &m, ""), None);
    // Merging one shard alone names the missing one; a bad --shard is refused.
    let out = diffsoft(&["merge", &p("a.json"), "-o", &p("x.json")]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing 1 of 2 shards: 1/2"));
    let out = diffsoft(&[
        "tradeoff",
        "--cantilever",
        "2,1,1",
        "--shard",
        "2/2",
        "--json",
        &p("y.json"),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("0 <= K < N"));
    // A report named as one of its plots is refused before anything runs (the plot, written
    // first, would be replaced by the report), by the sweep and by merge alike; the plot that
    // is there stays.
    let plot = std::fs::read(dir.join("tradeoff_cantilever_24.svg")).unwrap();
    let mut a: Vec<&str> = common.to_vec();
    let target = p("tradeoff_cantilever_24.svg");
    a.extend_from_slice(&["--json", &target]);
    let out = diffsoft(&a);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("is where the plot tradeoff_cantilever_24.svg goes"), "{e}");
    let out = diffsoft(&[
        "merge",
        &p("a.json"),
        &p("b.json"),
        "-o",
        &p("tradeoff_cantilever_24_gradient.svg"),
    ]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("is where the plot tradeoff_cantilever_24_gradient.svg goes"),
        "{e}"
    );
    assert_eq!(std::fs::read(dir.join("tradeoff_cantilever_24.svg")).unwrap(), plot);
}
