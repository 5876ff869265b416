//! Output paths checked before the work: writable, and never one of the command's inputs.
//! (Files themselves are written atomically by [`crate::report::write_atomic`].)

use std::path::{Path, PathBuf};

use crate::report::{create_temporary, output_target, Target};

/// Check, before a long computation, that `path` can be written: its directory is created if
/// needed and a probe file is written into it and removed. Errors name the path.
pub fn check_writable(path: &Path) -> std::io::Result<()> {
    let named =
        |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: cannot write here: {e}", path.display()));
    if path.is_dir() {
        return Err(named(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "is a directory, expected a file",
        )));
    }
    // Where the bytes will go (links followed, as the writer follows them).
    let target = match output_target(path).map_err(named)? {
        Target::File(t) => t,
        Target::InPlace => {
            // A device or socket is written in place: it must open for writing. A FIFO is not
            // opened here (that would wait for its reader, as the real write will).
            #[cfg(unix)]
            {
                let meta = std::fs::metadata(path).map_err(named)?;
                if std::os::unix::fs::FileTypeExt::is_fifo(&meta.file_type()) {
                    return Ok(());
                }
            }
            return std::fs::OpenOptions::new()
                .write(true)
                .open(path)
                .map(drop)
                .map_err(named);
        }
    };
    let dir = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&dir).map_err(named)?;
    let (probe, f) = create_temporary(&target).map_err(named)?;
    drop(f);
    std::fs::remove_file(&probe).map_err(named)
}

pub(crate) use crate::base::input_file::kind_of;

/// Make `dir` a directory for outputs the command names itself (a run's frames, the schemas):
/// created if missing; an existing path that is not a directory (a file, a device, a FIFO) is
/// refused as such, naming `flag`.
///
/// ```
/// let dir = std::env::temp_dir().join(format!("diffsoft-doc-outdir-{}", std::process::id()));
/// diffsoft::output::output_dir(&dir, "--out")?;
/// assert!(dir.is_dir());
/// std::fs::write(dir.join("f"), "x")?;
/// let e = diffsoft::output::output_dir(&dir.join("f"), "--out").unwrap_err();
/// assert!(e.to_string().contains("--out must name a directory, and this is a regular file"));
/// std::fs::remove_dir_all(&dir)?;
/// # Ok::<(), std::io::Error>(())
/// ```
pub fn output_dir(dir: &Path, flag: &str) -> std::io::Result<()> {
    if let Ok(meta) = std::fs::metadata(dir) {
        if !meta.is_dir() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                format!(
                    "{}: {flag} must name a directory, and this is {}",
                    dir.display(),
                    kind_of(&meta.file_type())
                ),
            ));
        }
    }
    std::fs::create_dir_all(dir).map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", dir.display())))
}

/// The path of a file the command names itself inside an output directory (`dir/name`),
/// checked not to be a link, FIFO, device or directory: such an entry is never written
/// through (a link could point at an input; a FIFO would block), and the error names it.
///
/// ```
/// let dir = std::env::temp_dir().join(format!("diffsoft-doc-own-{}", std::process::id()));
/// std::fs::create_dir_all(&dir)?;
/// assert_eq!(diffsoft::output::own_file(&dir, "a.json")?, dir.join("a.json"));
/// std::os::unix::fs::symlink("/etc/hostname", dir.join("b.json"))?;
/// let e = diffsoft::output::own_file(&dir, "b.json").unwrap_err();
/// assert!(e.to_string().contains("is a symbolic link to /etc/hostname"));
/// std::fs::remove_dir_all(&dir)?;
/// # Ok::<(), std::io::Error>(())
/// ```
pub fn own_file(dir: &Path, name: &str) -> std::io::Result<PathBuf> {
    let path = dir.join(name);
    match std::fs::symlink_metadata(&path) {
        Ok(meta) if !meta.file_type().is_file() => {
            let what = match std::fs::read_link(&path) {
                Ok(to) => format!("a symbolic link to {}", to.display()),
                Err(_) => kind_of(&meta.file_type()).to_string(),
            };
            Err(std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                format!(
                    "{}: is {what}, where the command writes its own {name}; only a regular file is replaced: remove it or choose another directory",
                    path.display()
                ),
            ))
        }
        _ => Ok(path),
    }
}

/// Refuse to write `out` when it is one of `inputs` or a file they bring with them (the same
/// file, however named): an output never replaces what the command read. The error names both.
///
/// An input brings its family ([`input_family`]): a TetGen `.node` its `.ele` and `.face`, and
/// the other way round; a JSON file (a scene) every file its strings name relative to its
/// directory (meshes, activations), so `grad scene.json --json box.obj` cannot replace the
/// scene's mesh either.
pub fn refuse_input(out: &Path, inputs: &[&Path]) -> std::io::Result<()> {
    let Ok(target) = out.canonicalize() else {
        return Ok(()); // does not exist yet: cannot be an input
    };
    for input in inputs {
        for member in input_family(input) {
            if member.canonicalize().is_ok_and(|p| p == target) {
                let via = if member.as_path() == *input {
                    String::new()
                } else {
                    format!(" ({} reads it)", input.display())
                };
                return Err(std::io::Error::new(
                    std::io::ErrorKind::AlreadyExists,
                    format!(
                        "{}: refusing to write the output over the input {}{via}; choose another output path",
                        out.display(),
                        member.display()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// `input` and the files that come with it: the TetGen siblings of a `.node`, `.ele` or
/// `.face` file, and, for a JSON file, every existing file that one of its strings names
/// relative to its directory (one level: a scene's meshes and data files).
pub fn input_family(input: &Path) -> Vec<PathBuf> {
    let mut out = vec![input.to_path_buf()];
    let ext = input.extension().and_then(|e| e.to_str()).unwrap_or("");
    match ext.to_ascii_lowercase().as_str() {
        "node" | "ele" | "face" | "edge" => {
            // Siblings as the reader looks for them (lower case), and in the input's own case.
            for e in ["node", "ele", "face", "edge"] {
                for e in [e.to_string(), e.to_ascii_uppercase()] {
                    if e != ext {
                        out.push(input.with_extension(e));
                    }
                }
            }
        }
        // Mesh and output formats name no other file.
        "obj" | "msh" | "vtu" | "vtk" | "pvd" | "svg" | "html" | "csv" => {}
        // Anything else may be a scene (a scene need not be named `.json`): the strings of
        // whatever parses as JSON are looked up.
        _ => {
            let dir = input.parent().unwrap_or(Path::new("."));
            // A scene is small; anything that does not parse brings nothing.
            if let Some(v) = std::fs::read_to_string(input)
                .ok()
                .filter(|t| t.len() < 64 << 20)
                .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            {
                let mut names = Vec::new();
                strings(&v, &mut names);
                for n in names {
                    let p = dir.join(n);
                    if p.is_file() {
                        // One level: a JSON file named here is an input, not read further.
                        if p.extension().is_some_and(|e| e == "json") {
                            out.push(p);
                        } else {
                            out.extend(input_family(&p));
                        }
                    }
                }
            }
        }
    }
    out
}

/// Every string in `v` that could be a relative or absolute path.
fn strings<'a>(v: &'a serde_json::Value, out: &mut Vec<&'a str>) {
    match v {
        serde_json::Value::String(s) if !s.is_empty() && s.len() < 4096 => out.push(s),
        serde_json::Value::Array(a) => a.iter().for_each(|x| strings(x, out)),
        serde_json::Value::Object(o) => o.values().for_each(|x| strings(x, out)),
        _ => {}
    }
}

/// Refuse two outputs of one command that are the same file (`--json X --svg X`): the second
/// would replace the first. Paths that do not exist yet are compared as given, made absolute.
pub fn distinct_outputs(outputs: &[(&str, &Path)]) -> std::io::Result<()> {
    for (i, (a, pa)) in outputs.iter().enumerate() {
        for (b, pb) in &outputs[..i] {
            if *pa != Path::new("-") && resolved(pa) == resolved(pb) {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::AlreadyExists,
                    format!(
                        "{b} and {a} name the same file {}: give each output its own path",
                        pa.display()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// The file `p` names once written: its canonical path when it exists; else, following a
/// dangling link to its target, the canonical directory joined with the file name; else the
/// absolute path with `.` and `..` resolved lexically.
fn resolved(p: &Path) -> PathBuf {
    if let Ok(c) = p.canonicalize() {
        return c;
    }
    // The writer's own link resolution: a dangling link names its target.
    let p = crate::report::resolve_links(p).unwrap_or_else(|_| p.to_path_buf());
    if let Ok(c) = p.canonicalize() {
        return c;
    }
    if let (Some(dir), Some(name)) = (p.parent(), p.file_name()) {
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        if let Ok(d) = dir.canonicalize() {
            return d.join(name);
        }
    }
    let absolute = std::env::current_dir().map(|d| d.join(&p)).unwrap_or(p);
    let mut out = PathBuf::new();
    for c in absolute.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unwritable_outputs_are_found_before_the_work() {
        let e = check_writable(Path::new("/proc/diffsoft/report.json")).unwrap_err();
        assert!(e.to_string().contains("/proc/diffsoft/report.json"), "{e}");
        let e = check_writable(&std::env::temp_dir()).unwrap_err();
        assert!(e.to_string().contains("directory"), "{e}");
    }

    #[test]
    fn an_output_never_replaces_an_input() {
        let dir = std::env::temp_dir().join(format!("diffsoft-refuse-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        let input = dir.join("mesh.obj");
        std::fs::write(&input, "v 0 0 0").unwrap();
        let e = refuse_input(&dir.join("sub/../mesh.obj"), &[&input]).unwrap_err();
        assert!(e.to_string().contains("mesh.obj"), "{e}");
        refuse_input(&dir.join("other.json"), &[&input]).unwrap();
        refuse_input(&input, &[&dir.join("x.obj")]).unwrap();
        // A scene not named .json still brings its mesh.
        for name in ["scene.txt", "scene.JSON", "scene"] {
            let scene = dir.join(name);
            std::fs::write(&scene, r#"{"bodies": [{"mesh": "mesh.obj"}]}"#).unwrap();
            let e = refuse_input(&input, &[&scene]).unwrap_err();
            assert!(e.to_string().contains(name), "{e}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Two outputs are the same file however they are spelled: through `..`, or a link (even
    /// one whose target does not exist yet).
    #[test]
    fn outputs_spelled_differently_are_still_one_file() {
        let dir = std::env::temp_dir().join(format!("diffsoft-distinct-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("d")).unwrap();
        let (a, b) = (dir.join("d/../same.out"), dir.join("same.out"));
        assert!(distinct_outputs(&[("--json", &a), ("--svg", &b)]).is_err());
        std::os::unix::fs::symlink("same2.out", dir.join("link.svg")).unwrap();
        let (a, b) = (dir.join("same2.out"), dir.join("link.svg"));
        assert!(distinct_outputs(&[("--json", &a), ("--svg", &b)]).is_err());
        distinct_outputs(&[("--json", &dir.join("x.json")), ("--svg", &dir.join("x.svg"))]).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
