//! # diffsoft
//!
//! Differentiable simulation of soft multi-body systems (Qiao et al., NeurIPS 2021), built
//! around a verification and convergence-analysis harness. Equation numbers refer to the
//! method document `docs/method.md` in the repository (paper Eqs. 1-21, appendix Eqs. 22-40,
//! and the labels C, G, S of what this implementation adds).
//!
//! ## The pipeline
//!
//! Data flows one way, each layer using only the ones before it:
//!
//! ```text
//! base ─► mesh ─► fem ─► kernel ─► skeleton, actuator, cloth, contact ─► model ─► constraint
//!      ─► solver ─► diff ─► analysis / scene / output ─► verify (reports, plots)
//! ```
//!
//! * [`base`]: the input-validation error, [`Material`], [`Body`], [`Schedule`]; imports nothing
//!   of the crate.
//! * [`mesh`]: tetrahedral meshes (OBJ with `t` lines, TetGen, Gmsh 2.2/4.1) with errors that
//!   name file and line, generators, quality measures, surfaces.
//! * [`fem`]: per-tet operators, lumped mass and the per-axis stiffness `L` (Eqs. 22-23).
//! * [`kernel`]: math on one element: the signed 3 x 3 SVD, the corotated, volume, pneumatic and
//!   muscle projections and their derivatives, the 3 x 2 polar decomposition of cloth.
//! * [`skeleton`], [`actuator`], [`cloth`], [`contact`]: the parts of a model: bones and joints
//!   (Eqs. 6-18), actuator groups (Eqs. 39-40), cloth bodies, obstacles and collisions between
//!   bodies (Eqs. C1-C5).
//! * [`model`]: [`ModelBuilder`] assembles bodies, cloth, obstacles and gravity into a validated
//!   [`Model`] in the global numbering.
//! * `constraint` (internal): one constraint set per kind (elasticity, pneumatic, muscle, cloth
//!   stretching and bending, attachments) with its share of `L`, projection and adjoint.
//! * [`solver`]: the [`Simulator`]: projective dynamics with implicit Euler (Eqs. 2-5) as named
//!   phases, global solvers behind one trait (sparse Cholesky, the paper's Eqs. 19 and 21,
//!   Chebyshev), certified by the spectral analysis before stepping.
//! * [`diff`]: reverse-mode gradients of whole simulations, unrolled or implicit ([`gradient`]).
//! * [`analysis`]: spectral radii of the paper's iterations, critical time steps, the appendix's
//!   claims checked on real meshes.
//! * [`scene`]: the JSON scene format and the importer of the paper's scene files.
//! * [`output`]: VTK frames and the JSON run log of a simulation.
//! * [`report`], [`plot`], [`verify`]: versioned JSON reports, SVG plots and the harness the main
//!   job (`diffsoft verify`) runs; [`verify::schemas()`] generates the JSON Schemas of every report,
//!   the run log, the scene format and the suite file (`schemas/`, `diffsoft schemas`).
//! * [`alloc`]: a counting allocator, to measure peak heap and allocations.
//!
//! ## The seams
//!
//! * `ConstraintSet` (internal): one kind of projective constraint (Eq. 3) with its share of
//!   `L`, its gather and its adjoint; the local step is one loop over the sets.
//! * `GlobalSolver` (internal): the global step (Eq. 5) on the free vertices.
//! * [`skeleton::Joint`]: a joint's transform, derivative and update rule.
//! * [`contact::Shape`]: an obstacle's geometry query.
//! * `StepObserver` (internal): watches the phases of a step (the backward pass records
//!   through it).
//! * [`diff::loss::Loss`]: a loss of a trajectory with its gradient.
//!
//! ## A first simulation
//!
//! ```no_run
//! use diffsoft::{scene, Simulator};
//!
//! let sc = scene::load("verification/paper/bridgesus/bridgesus.json", Default::default())?;
//! let mut sim = Simulator::new(sc.model, sc.settings)?;
//! for _ in 0..10 {
//!     let stats = sim.step()?;
//!     println!("step {}: {} iterations", stats.step, stats.iterations);
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

pub mod actuator;
pub mod alloc;
pub mod analysis;
pub mod base;
pub mod cloth;
pub(crate) mod constraint;
pub mod contact;
pub mod diff;
pub mod fem;
pub mod kernel;
pub mod mesh;
pub mod model;
pub mod output;
pub mod report;
pub mod scene;
pub mod skeleton;
pub mod solver;
#[cfg(feature = "testing")]
pub mod testing;

pub use base::{Body, InputError, Material, Schedule};
pub use constraint::stiffness_values;
pub use diff::loss::Loss;
pub use diff::{
    gradient, gradient_with, loss_value, rollout, vjp, Controls, Cotangent, DiffError, Gradient, Mode, Options, Param,
    Progress, Rollout,
};
pub use mesh::{MeshError, TetMesh};
pub use model::{BodySpec, MassSpec, Model, ModelBuilder};
pub use scene::{Scene, SceneError};
pub use solver::{Settings, Simulator, SolverError, SolverKind, State, StepStats};
