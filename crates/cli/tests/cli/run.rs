//! Running the `diffsoft` binary as a user does, and reading what it wrote.

use std::path::Path;
use std::process::{Command, Output};

/// The binary run with `args`.
pub fn diffsoft(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_diffsoft"))
        .args(args)
        .output()
        .unwrap()
}

/// `diffsoft generate` of a box of `cells` ("nx,ny,nz") and `size` ("x,y,z", m) into `out`.
pub fn generate_box(cells: &str, size: &str, out: &Path) -> Output {
    diffsoft(&[
        "generate",
        "--cells",
        cells,
        "--size",
        size,
        "--out",
        out.to_str().unwrap(),
    ])
}

/// A run's standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A run's standard output as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A JSON file's value.
pub fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}
