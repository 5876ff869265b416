//! Simulation output: VTK XML frames that ParaView reads (written here, no VTK library) with a
//! `.pvd` time collection, the JSON run log, the JSON output of `diffsoft grad`, the run's output
//! directory, and atomic file writes (never a half-written file).

mod file;
mod grad;
mod run_dir;
mod runlog;
mod vtk;

pub use crate::report::{write_atomic, write_json, Header, ModelSize, Provenance, Verdict};
pub use file::{check_writable, distinct_outputs, input_family, output_dir, own_file, refuse_input};
pub use grad::{GradReport, GRAD_SCHEMA};
pub use run_dir::{RunDir, RunStatus, COLLECTION, RUN_LOG};

pub use runlog::{
    body_notes, folded, solver_energy_gain, BodyLog, EnergyGain, MaterialLog, RunLog, RunSummary, FOLDED_SHARE,
    RUN_SCHEMA, WEIGHT_STRAIN,
};
pub use vtk::FrameWriter;

/// Standard base64 (RFC 4648, with padding) of `bytes`: the encoding of the VTK frames' binary
/// arrays, also used by the harness's report page for its inline plots.
///
/// ```
/// assert_eq!(diffsoft::output::base64(b"foobar"), "Zm9vYmFy");
/// assert_eq!(diffsoft::output::base64(b"fo"), "Zm8=");
/// ```
pub fn base64(bytes: &[u8]) -> String {
    let mut out = Vec::with_capacity(bytes.len().div_ceil(3) * 4);
    vtk::base64_encode(bytes, &mut out);
    // The alphabet and the padding are ASCII.
    String::from_utf8(out).unwrap_or_default()
}
