//! Files that are never seen half-written: the content goes to a temporary file beside the
//! target, which is then renamed over it (atomic on POSIX file systems), so a reader or an
//! interrupted run finds either the old file or the new one, never a truncated one.

use std::io::Write as _;
use std::path::{Path, PathBuf};

/// Write `bytes` to `path` atomically (temporary file in the same directory, then rename).
/// Errors name the path.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let named = |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: {e}", path.display()));
    let tmp = temporary_name(path);
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.flush()?;
        drop(f);
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(named)
}

/// `dir/.name.tmp.PID`: hidden, in the target's directory (so the rename stays on one file
/// system), unique per process.
fn temporary_name(path: &Path) -> PathBuf {
    let name = path.file_name().map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}.tmp.{}", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_the_file_and_leaves_no_temporary() {
        let dir = std::env::temp_dir().join(format!("diffsoft-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("a.json");
        write_atomic(&p, b"old").unwrap();
        write_atomic(&p, b"new").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"new");
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, vec![std::ffi::OsString::from("a.json")]);
        let e = write_atomic(&dir.join("missing/b.json"), b"x").unwrap_err();
        assert!(e.to_string().contains("missing/b.json"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
