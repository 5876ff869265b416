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
            let meta = std::fs::metadata(path).map_err(named)?;
            // A device or socket is written in place: it must open for writing. A FIFO is not
            // opened here (that would wait for its reader, as the real write will).
            #[cfg(unix)]
            if std::os::unix::fs::FileTypeExt::is_fifo(&meta.file_type()) {
                return Ok(());
            }
            drop(meta);
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

/// Refuse to write `out` when it is one of `inputs` (the same file, however named): an output
/// never replaces what the command read. The error names both.
pub fn refuse_input(out: &Path, inputs: &[&Path]) -> std::io::Result<()> {
    let Ok(target) = out.canonicalize() else {
        return Ok(()); // does not exist yet: cannot be an input
    };
    for input in inputs {
        if input.canonicalize().is_ok_and(|p| p == target) {
            return Err(std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                format!(
                    "{}: refusing to write the output over the input {}; choose another output path",
                    out.display(),
                    input.display()
                ),
            ));
        }
    }
    Ok(())
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
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
