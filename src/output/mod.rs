//! Simulation output: VTK frames that ParaView reads (vtkio) with a `.pvd` time collection, and
//! the JSON run log.

mod runlog;
mod vtk;

pub use runlog::{RunLog, RunSummary, RUN_SCHEMA};
pub use vtk::FrameWriter;
