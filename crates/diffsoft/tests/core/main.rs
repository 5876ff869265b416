//! The core crate's integration tests, one module per subject (one test binary).

mod analysis_props;
mod common;
mod constraint_props;
mod contact_props;
mod fem_props;
mod materials;
mod mesh_errors;
mod mesh_formats;
mod newton;
mod paper_carried;
mod reference_values;
mod registry;
mod scenes;
mod shapes;
mod skeleton_adjoint;
mod trajectory;
mod vtk_frames;
