//! # diffsoft
//!
//! Differentiable simulation of soft multi-body systems (Qiao et al., NeurIPS 2021), built
//! around a verification and convergence-analysis harness.
//!
//! Data flows one way:
//!
//! ```text
//! scene file ─► scene ─► mesh ─► fem ─► solver (model, constraint, contact) ─► output (VTK, run log)
//!                                 │
//!                                 └───► analysis ─► report / verify (JSON + SVG)
//! ```
//!
//! * [`mesh`]: tetrahedral meshes (OBJ with `t` lines, TetGen, Gmsh 2.2/4.1), validation with
//!   errors that name file and line, structured generators, quality measures, OBJ surfaces.
//! * [`fem`]: per-tet operators `P`, `P^-1`, `V`, `A` (seed Eq. 23), lumped mass and the
//!   per-axis stiffness `L = sum mu V A^T A` (seed Eq. 22).
//! * [`constraint`]: the signed 3x3 SVD and the projective constraints (corotated, volume,
//!   attachment, pneumatic cell and muscle fibre).
//! * [`skeleton`]: embedded skeletons (paper Eqs. 6-18): joints behind one trait (free root,
//!   rotational, prismatic, fixed), the bone tree and `B = dq/dz` (Eqs. 12-16).
//! * [`actuator`]: groups of pneumatic cells and muscle fibres with their activation schedules
//!   (seed Appendix D).
//! * [`cloth`]: triangle-mesh bodies (2D as-rigid-as-possible stretching, cotangent-Laplacian
//!   bending, area density) in the same projective-dynamics system as the soft bodies.
//! * [`contact`]: static obstacles, collisions between bodies (vertex-face and edge-edge pairs,
//!   spatial hash) and the Coulomb cone projection.
//! * [`solver`]: projective dynamics with implicit Euler (paper Eqs. 2-5): parallel local step,
//!   global solvers (sparse Cholesky, plain Eq. 19, split Eq. 21, Chebyshev) behind one trait,
//!   certified by the spectral analysis before stepping.
//! * [`scene`]: the JSON scene format and the importer for the paper's scene files.
//! * [`output`]: VTK frames and the JSON run log of a simulation.
//! * [`analysis`]: spectral radii of the plain (Eq. 19) and split (Eq. 21) iterations, their
//!   critical time steps, the Appendix A/B claims checked on real meshes, empirical contraction
//!   rates and `rho(dt)` sweeps.
//! * [`report`], [`plot`], [`verify`]: versioned JSON reports, SVG plots and the suite that the
//!   main job (`diffsoft verify`) runs over `verification/`, including the physics checks of
//!   the forward solver, the accuracy/cost trade-off of its settings, the extremes suite, and
//!   sharded sweeps.
//!
//! Equation numbers refer to the paper and its supplementary appendix as summarised in the
//! project's METHOD notes (paper Eqs. 1-21, seed Eqs. 22-40).
#![warn(missing_docs)]

pub mod actuator;
pub mod alloc;
pub mod analysis;
pub mod base;
pub mod cloth;
pub mod constraint;
pub mod contact;
pub mod diff;
pub mod fem;
pub mod kernel;
pub mod mesh;
pub mod model;
pub mod output;
pub mod plot;
pub mod report;
pub mod scene;
pub mod skeleton;
pub mod solver;
pub mod verify;
