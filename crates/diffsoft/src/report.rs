//! Versioned JSON files: every report and run log starts with a [`Header`] (schema name with
//! version, crate version, provenance); written atomically.

use serde::{Deserialize, Serialize};
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// The crate version written into every report.
pub const CRATE_VERSION: &str = env!("CARGO_PKG_VERSION");

/// First fields of every report.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Header {
    /// Schema name and version, e.g. `diffsoft.bounds/1`.
    pub schema: String,
    /// Version of the crate that wrote the report.
    pub crate_version: &'static str,
    /// Where and how the report was made (its timings depend on it).
    pub provenance: Provenance,
}

impl Header {
    /// A header for the given schema name (e.g. `"diffsoft.bounds/1"`).
    ///
    /// ```
    /// use diffsoft::report::{Header, CRATE_VERSION};
    ///
    /// let header = Header::new("diffsoft.bounds/1");
    /// assert_eq!((header.schema.as_str(), header.crate_version), ("diffsoft.bounds/1", CRATE_VERSION));
    /// // Serialised, its fields come first in every report.
    /// let json = serde_json::to_value(&header)?;
    /// assert_eq!(json["schema"], "diffsoft.bounds/1");
    /// assert!(json["provenance"]["date_utc"].is_string());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(schema: &str) -> Self {
        Self {
            schema: schema.to_string(),
            crate_version: CRATE_VERSION,
            provenance: Provenance::now(),
        }
    }
}

/// Where and how a report was made: the code (crate version, git commit), the compiler, the
/// machine (CPU model, worker threads, OS) and the time, so timings in it can be compared.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Provenance {
    /// `git rev-parse HEAD` of the working directory's repository when the report was written,
    /// with `-dirty` if it had uncommitted changes (`null` outside a git checkout).
    pub git_commit: Option<String>,
    /// UTC date and time the report was written (ISO 8601, seconds).
    pub date_utc: String,
    /// Worker threads of the computation (rayon pool).
    pub threads: usize,
    /// CPU model (`/proc/cpuinfo`; `null` where unknown).
    pub cpu_model: Option<String>,
    /// Logical CPUs of the machine.
    pub cpus: usize,
    /// `rustc --version` of the build.
    pub rustc_version: String,
    /// Operating system and architecture, e.g. `linux x86_64`.
    pub os: String,
}

impl Provenance {
    /// The provenance of a report written now (machine facts are read once per process).
    ///
    /// ```
    /// use diffsoft::report::Provenance;
    ///
    /// let p = Provenance::now();
    /// assert!(p.threads >= 1 && p.cpus >= 1);
    /// assert!(!p.rustc_version.is_empty());
    /// // `YYYY-MM-DDTHH:MM:SSZ`
    /// assert_eq!((p.date_utc.len(), &p.date_utc[10..11], &p.date_utc[19..]), (20, "T", "Z"));
    /// assert!(p.os.contains(std::env::consts::ARCH));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn now() -> Self {
        static FIXED: std::sync::OnceLock<(Option<String>, Option<String>)> = std::sync::OnceLock::new();
        let (git_commit, cpu_model) = FIXED.get_or_init(|| (git_commit(), cpu_model())).clone();
        Self {
            git_commit,
            date_utc: utc_now(),
            threads: rayon::current_num_threads(),
            cpu_model,
            cpus: std::thread::available_parallelism().map_or(1, |n| n.get()),
            rustc_version: env!("DIFFSOFT_RUSTC_VERSION").to_string(),
            os: format!("{} {}", std::env::consts::OS, std::env::consts::ARCH),
        }
    }
}

fn git_commit() -> Option<String> {
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .args(args)
            .stderr(std::process::Stdio::null())
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    let head = git(&["rev-parse", "HEAD"])?;
    let dirty = git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
    Some(if dirty { format!("{head}-dirty") } else { head })
}

fn cpu_model() -> Option<String> {
    let text = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("model name"))?;
    Some(line.split_once(':')?.1.trim().to_string())
}

/// The current UTC time as `YYYY-MM-DDTHH:MM:SSZ` (civil-from-days, proleptic Gregorian).
fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    utc_date(secs)
}

fn utc_date(secs: u64) -> String {
    let (days, rem) = ((secs / 86_400) as i64, secs % 86_400);
    // Howard Hinnant's days-to-civil algorithm.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

/// Size of a simulated model in the global numbering.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, schemars::JsonSchema)]
pub struct ModelSize {
    /// Vertices (every body and cloth).
    pub vertices: usize,
    /// Tets (every soft body).
    pub tets: usize,
}

impl ModelSize {
    /// The size of `model`.
    ///
    /// ```
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::report::ModelSize;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
    /// let model = ModelBuilder::new().body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0))).build()?;
    /// assert_eq!(ModelSize::of(&model), ModelSize { vertices: 8, tets: 6 });
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn of(model: &crate::model::Model) -> Self {
        Self {
            vertices: model.n(),
            tets: model.tets().len(),
        }
    }
}

/// A claim checked against a measurement.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Verdict {
    /// The claim, in words, with its source (paper equation or appendix).
    pub claim: String,
    /// Whether the claim holds on this input.
    pub holds: bool,
    /// The measured value the verdict rests on (its unit is in `claim` or `comparison`; 1 when none
    /// is named).
    pub measured: Option<f64>,
    /// The value it is compared with, in the unit of `measured` (`null` when the claim is not a
    /// comparison).
    pub threshold: Option<f64>,
    /// How the comparison reads, e.g. `measured <= threshold`.
    pub comparison: String,
}

impl Verdict {
    /// `holds` iff `measured <= threshold`.
    ///
    /// ```
    /// use diffsoft::report::Verdict;
    ///
    /// let v = Verdict::at_most("Eq. 24 is a safe step (s)", 1e-3, 1e-3);
    /// assert!(v.holds);
    /// assert_eq!((v.measured, v.threshold), (Some(1e-3), Some(1e-3)));
    /// assert!(!Verdict::at_most("too large", 2.0, 1.0).holds);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn at_most(claim: impl Into<String>, measured: f64, threshold: f64) -> Self {
        Self {
            claim: claim.into(),
            holds: measured <= threshold,
            measured: Some(measured),
            threshold: Some(threshold),
            comparison: "measured <= threshold".into(),
        }
    }

    /// `holds` iff `measured < threshold`.
    ///
    /// ```
    /// use diffsoft::report::Verdict;
    ///
    /// // Equality is not below.
    /// assert!(!Verdict::below("rho(G21) < 1", 1.0, 1.0).holds);
    /// let v = Verdict::below("rho(G21) < 1", 0.9, 1.0);
    /// assert!(v.holds);
    /// assert_eq!(v.comparison, "measured < threshold");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn below(claim: impl Into<String>, measured: f64, threshold: f64) -> Self {
        Self {
            claim: claim.into(),
            holds: measured < threshold,
            measured: Some(measured),
            threshold: Some(threshold),
            comparison: "measured < threshold".into(),
        }
    }

    /// A verdict with an explicit outcome and a description of the comparison.
    ///
    /// ```
    /// use diffsoft::report::Verdict;
    ///
    /// let v = Verdict::new("the mesh is an M-matrix", false, Some(3.0), None, "positive off-diagonal entries == 0");
    /// assert!(!v.holds && v.threshold.is_none());
    /// assert_eq!(serde_json::to_value(&v)?["measured"], 3.0);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(
        claim: impl Into<String>,
        holds: bool,
        measured: Option<f64>,
        threshold: Option<f64>,
        comparison: impl Into<String>,
    ) -> Self {
        Self {
            claim: claim.into(),
            holds,
            measured,
            threshold,
            comparison: comparison.into(),
        }
    }
}

/// Write a report as pretty JSON, creating parent directories; atomically (a temporary file
/// renamed over the target). Errors name the path.
pub fn write_json<T: Serialize>(path: impl AsRef<Path>, report: &T) -> std::io::Result<()> {
    let path = path.as_ref();
    let named = |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: {e}", path.display()));
    if let Some(dir) = path.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).map_err(named)?;
        }
    }
    let mut text = serde_json::to_string_pretty(report).map_err(|e| named(std::io::Error::other(e)))?;
    text.push('\n');
    write_atomic(path, text.as_bytes())
}

/// Write `bytes` to `path` so that it is never seen half-written: the content goes to a
/// temporary file beside the target, which is then renamed over it (atomic on POSIX file
/// systems). Errors name the path.
///
/// What `path` really is decides where the bytes go: a symbolic link is written through (the
/// file it points to is replaced, the link stays); a device, pipe or socket (`/dev/null`,
/// `/dev/stdout`, a FIFO) is written to in place, never replaced by a regular file; a directory
/// is an error. The temporary file is created exclusively under a fresh name, so no existing
/// file, whatever its name, is ever truncated or removed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let named = |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: {e}", path.display()));
    let target = match output_target(path).map_err(named)? {
        Target::InPlace => {
            // A device, FIFO or socket: write to it as it is.
            let mut f = std::fs::OpenOptions::new().write(true).open(path).map_err(named)?;
            return f.write_all(bytes).and_then(|()| f.flush()).map_err(named);
        }
        Target::File(t) => t,
    };
    let (tmp, mut f) = create_temporary(&target).map_err(named)?;
    let result = (|| {
        f.write_all(bytes)?;
        f.flush()?;
        drop(f);
        std::fs::rename(&tmp, &target)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(named)
}

/// Where the bytes of an output path go.
pub(crate) enum Target {
    /// Written in place through the path (a device, FIFO or socket, possibly behind links).
    InPlace,
    /// A regular file, existing or not, at this path (links followed): replaced atomically.
    File(PathBuf),
}

/// What `path` really is, links followed: a directory is an error.
pub(crate) fn output_target(path: &Path) -> std::io::Result<Target> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => Err(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "is a directory, expected a file",
        )),
        Ok(m) if !m.is_file() => Ok(Target::InPlace),
        Ok(_) => Ok(Target::File(path.canonicalize()?)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Target::File(resolve_links(path)?)),
        Err(e) => Err(e),
    }
}

/// `path` with every symbolic link along its final component followed (a dangling link gives
/// the path it points to); at most 40 links, as the kernel allows.
pub(crate) fn resolve_links(path: &Path) -> std::io::Result<PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let to = std::fs::read_link(&p)?;
                p = match p.parent() {
                    Some(dir) if to.is_relative() => dir.join(to),
                    _ => to,
                };
            }
            _ => return Ok(p),
        }
    }
    Err(std::io::Error::other("too many levels of symbolic links"))
}

/// A new, empty file beside `path` named `.name.tmp.PID.K`, created exclusively (`K` counts up
/// past names already taken), and its handle.
pub(crate) fn create_temporary(path: &Path) -> std::io::Result<(PathBuf, std::fs::File)> {
    let name = path
        .file_name()
        .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    for k in 0..1000 {
        let tmp = path.with_file_name(format!(".{name}.tmp.{}.{k}", std::process::id()));
        match std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => return Ok((tmp, f)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other("no free temporary name beside the output"))
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
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("a.json")]);
        let e = write_atomic(&dir.join("missing/b.json"), b"x").unwrap_err();
        assert!(e.to_string().contains("missing/b.json"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The temporary file never takes over an existing file, whatever its name.
    #[test]
    fn a_file_named_like_the_temporary_survives() {
        let dir = std::env::temp_dir().join(format!("diffsoft-atomic-tmp-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("a.json");
        let squatter = dir.join(format!(".a.json.tmp.{}.0", std::process::id()));
        std::fs::write(&squatter, b"an input").unwrap();
        write_atomic(&p, b"report").unwrap();
        crate::output::check_writable(&p).unwrap();
        assert_eq!(std::fs::read(&squatter).unwrap(), b"an input");
        assert_eq!(std::fs::read(&p).unwrap(), b"report");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn utc_dates() {
        assert_eq!(utc_date(0), "1970-01-01T00:00:00Z");
        assert_eq!(utc_date(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(utc_date(1_795_651_199), "2026-11-25T23:59:59Z");
    }

    #[test]
    fn provenance_names_the_machine_and_the_build() {
        let p = Provenance::now();
        assert!(p.threads >= 1 && p.cpus >= 1);
        assert!(p.rustc_version.starts_with("rustc "), "{}", p.rustc_version);
        assert_eq!(p.date_utc.len(), 20);
    }
}
