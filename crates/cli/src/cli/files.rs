//! Output files of the subcommands: reports printed and saved (atomically, never over an
//! input), data files found, meshes written.

use super::prelude::*;
use diffsoft::mesh;
use diffsoft::report::write_json;

/// Print a report's summary and write its JSON if asked (never over one of `inputs`).
pub(crate) fn emit<T: serde::Serialize>(
    summary: &str,
    report: &T,
    json: Option<&Path>,
    inputs: &[&Path],
) -> Result<()> {
    say_raw!("{summary}");
    if let Some(path) = json {
        save(path, report, inputs)?;
    }
    Ok(())
}

/// The project's data (`verification/...`) from any working directory: `path` as given if it
/// exists, else under the working directory's ancestors, else under the source tree this binary
/// was built from. The error lists every place looked in.
pub(crate) fn find_data(path: &Path) -> Result<PathBuf> {
    if path.exists() || path.is_absolute() {
        return Ok(path.to_path_buf());
    }
    let mut looked = vec![path.to_path_buf()];
    if let Ok(cwd) = std::env::current_dir() {
        looked.extend(cwd.ancestors().skip(1).map(|a| a.join(path)));
    }
    // The repository this binary was built from (crates/cli -> the root).
    looked.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(path));
    if let Some(found) = looked.iter().find(|p| p.exists()) {
        return Ok(found.clone());
    }
    let shown: Vec<String> = looked.iter().map(|p| p.display().to_string()).collect();
    bail!("cannot find {} (looked in {})", path.display(), shown.join(", "))
}

/// Before the work: an output file (not `-`) must be writable and not one of `inputs`.
pub(crate) fn preflight(path: Option<&Path>, inputs: &[&Path]) -> Result<()> {
    if let Some(p) = path.filter(|p| *p != Path::new("-")) {
        diffsoft::output::refuse_input(p, inputs)?;
        diffsoft::output::check_writable(p)?;
    }
    Ok(())
}

/// Refuse a trade-off run whose plots (`names`, written into `dir`) would land on its JSON
/// report `json` or on one of its `inputs`: the plots are written first, so either would be lost
/// (or replace what the command read).
pub(crate) fn check_plot_paths(json: Option<&Path>, dir: &Path, names: &[String], inputs: &[&Path]) -> Result<()> {
    let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => std::path::absolute(a).ok() == std::path::absolute(b).ok(),
    };
    for name in names {
        let plot = dir.join(name);
        if let Some(j) = json.filter(|j| *j != Path::new("-") && same(j, &plot)) {
            bail!(
                "--json {} is where the plot {name} goes: choose another name for the report (or --svg-dir for the plots)",
                j.display()
            );
        }
        diffsoft::output::refuse_input(&plot, inputs)?;
    }
    Ok(())
}

/// Write a report as JSON to `path` (atomically, never over one of `inputs`, then say so), or
/// to standard output for `-`.
pub(crate) fn save<T: serde::Serialize>(path: &Path, report: &T, inputs: &[&Path]) -> Result<()> {
    if path == Path::new("-") {
        let mut text = serde_json::to_string_pretty(report)?;
        text.push('\n');
        std::io::Write::write_all(&mut std::io::stdout().lock(), text.as_bytes()).context("standard output")?;
        return Ok(());
    }
    diffsoft::output::refuse_input(path, inputs)?;
    write_json(path, report)?;
    say!("wrote {}", path.display());
    Ok(())
}

/// Write a mesh in the format its extension names (TetGen: the `.node` and `.ele` pair), each
/// file atomically ([`diffsoft::report::write_atomic`]: never seen half-written; a link is
/// written through, a device in place), after checking that every file of the set can be
/// written, so that a pair is not left half-replaced.
pub(crate) fn write_mesh(m: &mesh::TetMesh, out: &Path, gmsh_version: Option<&str>) -> Result<()> {
    let ext = out.extension().and_then(|e| e.to_str()).unwrap_or("");
    if let (Some(v), false) = (gmsh_version, ext == "msh") {
        bail!(
            "--gmsh-version {v}: applies to .msh output only, and --out {} is not one",
            out.display()
        );
    }
    let files: Vec<(PathBuf, String)> = match ext {
        "obj" => vec![(out.to_path_buf(), mesh::write::obj(m))],
        "node" | "ele" => {
            let (node, ele) = mesh::write::tetgen(m, 0);
            vec![(out.with_extension("node"), node), (out.with_extension("ele"), ele)]
        }
        "msh" => match gmsh_version.unwrap_or("4.1") {
            "2.2" => vec![(out.to_path_buf(), mesh::write::gmsh22(m))],
            "4.1" => vec![(out.to_path_buf(), mesh::write::gmsh41(m))],
            v => bail!("--gmsh-version must be 2.2 or 4.1, got {v}"),
        },
        _ => bail!("--out must end in .obj, .node, .ele or .msh: {}", out.display()),
    };
    for (p, _) in &files {
        diffsoft::output::check_writable(p).with_context(|| format!("--out {}", out.display()))?;
    }
    for (p, text) in &files {
        diffsoft::report::write_atomic(p, text.as_bytes()).with_context(|| format!("cannot write {}", p.display()))?;
    }
    Ok(())
}
