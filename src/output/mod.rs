//! Simulation output: VTK frames that ParaView reads (vtkio) with a `.pvd` time collection, the
//! JSON run log, and atomic file writes (never a half-written file).

mod file;
mod runlog;
mod vtk;

pub use file::write_atomic;

pub use runlog::{RunLog, RunSummary, RUN_SCHEMA};
pub use vtk::FrameWriter;
