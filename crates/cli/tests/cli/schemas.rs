//! `diffsoft schemas` writes the schemas the harness generates.

use std::process::Command;

use crate::common::tmp_dir;

#[test]
fn the_cli_writes_the_same_schemas() {
    let dir = tmp_dir("schemas-cli");
    let out = Command::new(env!("CARGO_BIN_EXE_diffsoft"))
        .args(["schemas", "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let generated = diffsoft_harness::schemas::schemas();
    assert_eq!(crate::common::json_files(&dir).len(), generated.len());
    for (file, schema) in &generated {
        assert_eq!(
            std::fs::read_to_string(dir.join(file)).unwrap(),
            crate::common::pretty_json(schema),
            "{file}"
        );
    }
}
