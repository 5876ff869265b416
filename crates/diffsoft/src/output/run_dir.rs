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

/// The lock a run holds on its directory (its process id inside).
pub const LOCK: &str = ".diffsoft-run.lock";

/// Whether `name` is a file an earlier run wrote (`run.json`, `frames.pvd`, `frame_NNNNN.vtu`, or
/// the temporary file of one of those that an interrupted write left, `.run.json.tmp.PID.K`).
fn is_run_output(name: &str) -> bool {
    let written = |n: &str| n == RUN_LOG || n == COLLECTION || (n.starts_with("frame_") && n.ends_with(".vtu"));
    written(name)
        || name
            .strip_prefix('.')
            .and_then(|n| n.split_once(".tmp."))
            .is_some_and(|(base, pid)| written(base) && pid.chars().all(|c| c.is_ascii_digit() || c == '.'))
}

/// Take the run lock of `dir`: created exclusively with this process's id; a lock whose process
/// is gone (a run killed outright) is taken over, a live one refused with its id.
fn lock(dir: &Path) -> std::io::Result<PathBuf> {
    let path = dir.join(LOCK);
    for _ in 0..2 {
        match std::fs::OpenOptions::new().write(true).create_new(true).open(&path) {
            Ok(mut f) => {
                use std::io::Write as _;
                write!(f, "{}", std::process::id())?;
                return Ok(path);
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                let holder = std::fs::read_to_string(&path).unwrap_or_default();
                let alive = holder
                    .trim()
                    .parse::<u32>()
                    .is_ok_and(|pid| pid != std::process::id() && Path::new(&format!("/proc/{pid}")).exists());
                if alive {
                    return Err(std::io::Error::new(
                        std::io::ErrorKind::WouldBlock,
                        format!(
                            "{}: another run (process {}) is writing into this directory; wait for it or choose another --out",
                            dir.display(),
                            holder.trim()
                        ),
                    ));
                }
                // Stale: its process is gone.
                std::fs::remove_file(&path)?;
            }
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other(format!(
        "{}: cannot take the run lock",
        path.display()
    )))
}

/// The directory of one run.
#[derive(Debug)]
pub struct RunDir {
    dir: PathBuf,
    last_log: Option<Instant>,
    interval: Duration,
    /// The run lock, removed when the run's directory is dropped.
    lock: PathBuf,
}

impl Drop for RunDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.lock);
    }
}

impl RunDir {
    /// Prepare `dir`: create it, take its run lock (a second run into the same directory is
    /// refused while the first goes on), refuse (or with `overwrite`, remove) the files of an
    /// earlier run, refuse to write over any of `inputs` or the files they bring
    /// ([`super::input_family`]), and check it is writable by writing a first run log (`status:
    /// "starting"`). Errors name the directory and the file.
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
        // An existing path that is not a directory (a file, a device, a FIFO) is named as such,
        // not reported as the bare "File exists" of the failed creation.
        super::output_dir(dir, "--out")?;
        let canonical_dir = dir.canonicalize().map_err(|e| named(e, dir))?;
        let family: Vec<PathBuf> = inputs.iter().flat_map(|p| super::input_family(p)).collect();
        for input in &family {
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
        let lock = lock(dir)?;
        let rest = Self::clear_and_start(dir, overwrite);
        match rest {
            Ok(()) => Ok(Self {
                dir: dir.to_path_buf(),
                last_log: None,
                interval: Duration::from_secs(2),
                lock,
            }),
            Err(e) => {
                let _ = std::fs::remove_file(&lock);
                Err(e)
            }
        }
    }

    /// The part of [`RunDir::prepare`] under the lock: an earlier run's files refused or removed,
    /// the first run log written.
    fn clear_and_start(dir: &Path, overwrite: bool) -> std::io::Result<()> {
        let named = |e: std::io::Error, p: &Path| std::io::Error::new(e.kind(), format!("{}: {e}", p.display()));
        let mut earlier = Vec::new();
        for entry in std::fs::read_dir(dir).map_err(|e| named(e, dir))? {
            let entry = entry.map_err(|e| named(e, dir))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            if !is_run_output(&name) {
                continue;
            }
            // Not following links: a run writes only regular files of its own, so a link, a
            // FIFO, a device or a directory under one of its names is never written through
            // (it could be an input, or block the run forever), with or without --overwrite.
            super::own_file(dir, &name)?;
            earlier.push(entry.path());
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
        write_atomic(&path, format!("{first:#}\n").as_bytes())
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
        let text = format!("{v:#}\n");
        write_atomic(&self.log_path(), text.as_bytes()).or_else(|_| self.rewrite_in_place(&text))
    }

    /// Finalise the log of a run that failed after its steps began (a frame or the log itself
    /// could not be written: a full disk, a vanished directory): status `failed` with `error`.
    /// When the full log cannot be written either, the existing `run.json` is rewritten in
    /// place with a short record (status, error, steps taken): truncating it first frees its
    /// blocks, so a full disk still takes it, and the log never says `running` for a run that
    /// ended.
    pub fn write_failure(&mut self, log: &mut RunLog, error: &str) -> std::io::Result<()> {
        log.status = RunStatus::Failed;
        log.error = Some(error.to_string());
        if self.write_log(log).is_ok() {
            return Ok(());
        }
        let v = serde_json::json!({
            "schema": super::RUN_SCHEMA,
            "scene": log.scene,
            "status": RunStatus::Failed,
            "error": error,
            "steps_taken": log.steps.len(),
            "frames": log.frames,
        });
        self.rewrite_in_place(&format!("{v:#}\n"))
    }

    /// Overwrite the existing run log in place (not atomically: the fallback when no new file
    /// can be made).
    fn rewrite_in_place(&self, text: &str) -> std::io::Result<()> {
        use std::io::Write;
        let path = self.log_path();
        let mut f = std::fs::OpenOptions::new().write(true).truncate(true).open(&path)?;
        f.write_all(text.as_bytes())?;
        f.sync_all()
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

    /// A run lock held by a live process (here init, pid 1) refuses a second run into the
    /// directory; one left by a process that is gone is taken over; a finished run releases it.
    #[test]
    fn a_second_run_into_a_busy_directory_is_refused() {
        let dir = std::env::temp_dir().join(format!("diffsoft-lock-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(LOCK), "1").unwrap();
        let e = RunDir::prepare(&dir, &[], false).unwrap_err();
        assert!(e.to_string().contains("another run (process 1)"), "{e}");
        assert!(!dir.join(RUN_LOG).exists(), "nothing written");
        std::fs::write(dir.join(LOCK), "999999999").unwrap();
        let run = RunDir::prepare(&dir, &[], false).unwrap();
        assert_eq!(
            std::fs::read_to_string(dir.join(LOCK)).unwrap(),
            std::process::id().to_string()
        );
        drop(run);
        assert!(!dir.join(LOCK).exists());
        // A file named like a temporary but not one of a run's is nobody's output.
        std::fs::write(dir.join(".mesh.obj.tmp.1"), "an input").unwrap();
        RunDir::prepare(&dir, &[], true).unwrap();
        assert!(dir.join(".mesh.obj.tmp.1").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// When no new file can be made in the run's directory (here: made read-only; a full disk
    /// in the field), the failure is still recorded, by rewriting run.json in place.
    #[test]
    fn a_failure_is_recorded_even_when_no_new_file_can_be_made() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tmp("no-room");
        let mut run = RunDir::prepare(&dir, &[], false).unwrap();
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o555)).unwrap();
        // As root a read-only directory still takes new files: then the atomic write is used.
        let atomic_blocked = std::fs::write(dir.join("probe"), "").is_err();
        run.write_setup_failure("step 3: frame_00003.vtu: No space left on device")
            .unwrap();
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o755)).unwrap();
        let log: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join(RUN_LOG)).unwrap()).unwrap();
        assert_eq!(
            log["status"], "failed",
            "{log} (atomic write blocked: {atomic_blocked})"
        );
        assert!(log["error"].as_str().unwrap().contains("No space left"), "{log}");
        drop(run);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A link, a FIFO or a directory under a run's file name is never written through or
    /// removed, with or without `overwrite`: the error names it (a link to the scene would
    /// otherwise be replaced by the run log; a FIFO would block the run forever).
    #[test]
    fn never_writes_through_a_link_or_into_a_special_file() {
        let d = tmp("special");
        std::fs::create_dir_all(&d).unwrap();
        let scene = d.join("in.json");
        std::fs::write(&scene, "{}").unwrap();
        std::os::unix::fs::symlink("in.json", d.join(RUN_LOG)).unwrap();
        for overwrite in [false, true] {
            let e = RunDir::prepare(&d, &[], overwrite).unwrap_err();
            assert!(e.to_string().contains("symbolic link to in.json"), "{e}");
        }
        assert_eq!(std::fs::read_to_string(&scene).unwrap(), "{}");
        assert!(!d.join(LOCK).exists(), "lock released");
        std::fs::remove_file(d.join(RUN_LOG)).unwrap();
        let fifo = d.join("frame_00001.vtu");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status().unwrap();
        assert!(made.success());
        let e = RunDir::prepare(&d, &[], true).unwrap_err();
        assert!(e.to_string().contains("named pipe"), "{e}");
        std::fs::remove_file(&fifo).unwrap();
        std::fs::create_dir(d.join(COLLECTION)).unwrap();
        let e = RunDir::prepare(&d, &[], true).unwrap_err();
        assert!(e.to_string().contains("a directory"), "{e}");
        // --out naming a file is named as such.
        let e = RunDir::prepare(&scene, &[], true).unwrap_err();
        assert!(
            e.to_string()
                .contains("must name a directory, and this is a regular file"),
            "{e}"
        );
        std::fs::remove_dir_all(&d).unwrap();
    }

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
