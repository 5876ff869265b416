//! Simulation output: VTK XML frames that ParaView reads (written here, no VTK library) with a
//! `.pvd` time collection, the JSON run log, the JSON output of `diffsoft grad`, the run's output
//! directory, and atomic file writes (never a half-written file).

mod file;
mod grad;
mod run_dir;
mod runlog;
mod vtk;

pub use crate::report::{write_atomic, write_json, Header, ModelSize, Provenance, Verdict};
pub use file::{check_writable, distinct_outputs, input_family, refuse_input};
pub use grad::{GradReport, GRAD_SCHEMA};
pub use run_dir::{RunDir, RunStatus, COLLECTION, RUN_LOG};

pub use runlog::{BodyLog, MaterialLog, RunLog, RunSummary, RUN_SCHEMA};
pub use vtk::FrameWriter;
