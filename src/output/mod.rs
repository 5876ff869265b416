//! Simulation output: VTK frames that ParaView reads (vtkio) with a `.pvd` time collection, the
//! JSON run log, and atomic file writes (never a half-written file).

mod file;
mod run_dir;
mod runlog;
mod vtk;

pub use file::{check_writable, refuse_input, write_atomic};
pub use run_dir::{RunDir, RunStatus, COLLECTION, RUN_LOG};

pub use runlog::{RunLog, RunSummary, RUN_SCHEMA};
pub use vtk::FrameWriter;
