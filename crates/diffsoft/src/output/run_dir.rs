//! The output directory of a simulation run. Checked before the run (created, writable, no
//! earlier run's files left beside the new ones, no input written over), then holding a run log
//! that is kept current while the run goes on and finalised however it ends.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::runlog::RunLog;
use crate::report::write_atomic;

/// Files a run writes into its directory.
pub const RUN_LOG: &str = "run.json";
/// The ParaView time collection.
pub const COLLECTION: &str = "frames.pvd";

/// Whether `name` is a file an earlier run wrote (`run.json`, `frames.pvd`, `frame_NNNNN.vtu`, or
/// a temporary file an interrupted write left).
fn is_run_output(name: &str) -> bool {
    name == RUN_LOG
        || name == COLLECTION
        || (name.starts_with("frame_") && name.ends_with(".vtu"))
        || (name.starts_with('.') && name.contains(".tmp."))
}

/// The directory of one run.
#[derive(Debug)]
pub struct RunDir {
    dir: PathBuf,
    last_log: Option<Instant>,
    interval: Duration,
}

impl RunDir {
    /// Prepare `dir`: create it, refuse (or with `overwrite`, remove) the files of an earlier run,
    /// refuse to write over any of `inputs`, and check it is writable by writing a first run log
    /// (`status: "starting"`). Errors name the directory and the file.
    ///
    /// ```
    /// use diffsoft::output::{RunDir, RUN_LOG};
    ///
    /// let dir = std::env::temp_dir().join(format!("diffsoft-doc-run-{}", std::process::id()));
    /// let run = RunDir::prepare(&dir, &[], false)?;
    /// assert_eq!(run.log_path(), dir.join(RUN_LOG));
    /// assert!(std::fs::read_to_string(run.log_path())?.contains("starting"));
    /// // An earlier run's files are not overwritten unless asked.
    /// assert!(RunDir::prepare(&dir, &[], false).is_err());
    /// RunDir::prepare(&dir, &[], true)?;
    /// std::fs::remove_dir_all(&dir)?;
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn prepare(dir: &Path, inputs: &[&Path], overwrite: bool) -> std::io::Result<Self> {
        let named = |e: std::io::Error, p: &Path| std::io::Error::new(e.kind(), format!("{}: {e}", p.display()));
        std::fs::create_dir_all(dir).map_err(|e| named(e, dir))?;
        let canonical_dir = dir.canonicalize().map_err(|e| named(e, dir))?;
        for input in inputs {
            if let (Ok(p), Some(name)) = (input.canonicalize(), input.file_name()) {
                if p.parent() == Some(canonical_dir.as_path()) && is_run_output(&name.to_string_lossy()) {
                    return Err(std::io::Error::new(
                        std::io::ErrorKind::AlreadyExists,
                        format!(
                            "{}: the run would write over its input {}; choose another --out",
                            dir.display(),
                            input.display()
                        ),
                    ));
                }
            }
        }
        let mut earlier = Vec::new();
        for entry in std::fs::read_dir(dir).map_err(|e| named(e, dir))? {
            let entry = entry.map_err(|e| named(e, dir))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            if is_run_output(&name) && entry.file_type().is_ok_and(|t| t.is_file()) {
                earlier.push(entry.path());
            }
        }
        if !earlier.is_empty() {
            if !overwrite {
                let frames = earlier
                    .iter()
                    .filter(|p| p.extension().is_some_and(|e| e == "vtu"))
                    .count();
                return Err(std::io::Error::new(
                    std::io::ErrorKind::AlreadyExists,
                    format!(
                        "{} holds the output of an earlier run ({} files, {frames} frames): pass --overwrite to replace it, or choose another --out",
                        dir.display(),
                        earlier.len()
                    ),
                ));
            }
            for p in &earlier {
                std::fs::remove_file(p).map_err(|e| named(e, p))?;
            }
        }
        let first = serde_json::json!({ "schema": super::RUN_SCHEMA, "status": RunStatus::Starting });
        let path = dir.join(RUN_LOG);
        write_atomic(&path, format!("{first:#}\n").as_bytes())?;
        Ok(Self {
            dir: dir.to_path_buf(),
            last_log: None,
            interval: Duration::from_secs(2),
        })
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    /// The run log's path.
    pub fn log_path(&self) -> PathBuf {
        self.dir.join(RUN_LOG)
    }

    /// Whether the run log is due for a refresh (every 2 s of wall time while running, so a
    /// long run can be watched and an abrupt end loses at most that much of the log).
    pub fn log_due(&self) -> bool {
        self.last_log.is_none_or(|t| t.elapsed() >= self.interval)
    }

    /// Record a failure before the first full log: `run.json` becomes `{schema, status:
    /// "failed", error}` instead of staying `"starting"`. A no-op once a full log was written
    /// (its own `status` and `error` then say how the run ended).
    pub fn write_setup_failure(&mut self, error: &str) -> std::io::Result<()> {
        if self.last_log.is_some() {
            return Ok(());
        }
        let v = serde_json::json!({ "schema": super::RUN_SCHEMA, "status": RunStatus::Failed, "error": error });
        write_atomic(&self.log_path(), format!("{v:#}\n").as_bytes())
    }

    /// Write the run log (atomically).
    pub fn write_log(&mut self, log: &RunLog) -> std::io::Result<()> {
        let mut text = serde_json::to_string_pretty(log).map_err(std::io::Error::other)?;
        text.push('\n');
        write_atomic(&self.log_path(), text.as_bytes())?;
        self.last_log = Some(Instant::now());
        Ok(())
    }
}

/// How a run stands (or ended), as recorded in its log.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum RunStatus {
    /// Set up, no step taken yet.
    Starting,
    /// Steps are being taken; the log is refreshed every few seconds.
    Running,
    /// Every requested step was taken.
    Completed,
    /// Stopped by SIGINT or SIGTERM; the log holds the steps taken.
    Interrupted,
    /// Stopped by an error (divergence, a solver failure), named in `error`.
    Failed,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("diffsoft-rundir-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn refuses_an_earlier_run_unless_overwrite_and_then_removes_only_its_files() {
        let d = tmp("stale");
        std::fs::create_dir_all(&d).unwrap();
        for f in [
            "run.json",
            "frames.pvd",
            "frame_00000.vtu",
            "frame_00007.vtu",
            "notes.txt",
        ] {
            std::fs::write(d.join(f), "x").unwrap();
        }
        let e = RunDir::prepare(&d, &[], false).unwrap_err();
        assert!(
            e.to_string().contains("--overwrite") && e.to_string().contains("2 frames"),
            "{e}"
        );
        RunDir::prepare(&d, &[], true).unwrap();
        let mut left: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        left.sort();
        assert_eq!(left, ["notes.txt", "run.json"]);
        let log: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("run.json")).unwrap()).unwrap();
        assert_eq!(log["status"], "starting");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn never_writes_over_an_input() {
        let d = tmp("input");
        std::fs::create_dir_all(&d).unwrap();
        let input = d.join("run.json");
        std::fs::write(&input, "{}").unwrap();
        let e = RunDir::prepare(&d, &[&input], true).unwrap_err();
        assert!(e.to_string().contains("write over its input"), "{e}");
        assert_eq!(std::fs::read_to_string(&input).unwrap(), "{}");
        std::fs::remove_dir_all(&d).unwrap();
    }
}
