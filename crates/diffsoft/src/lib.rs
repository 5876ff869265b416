//! # diffsoft
//!
//! Differentiable simulation of soft multi-body systems (Qiao et al., NeurIPS 2021), built
//! around a verification and convergence-analysis harness. Equation numbers refer to the
//! method document `docs/method.md` in the repository (paper Eqs. 1-21, appendix Eqs. 22-40,
//! and the labels C, G, S of what this implementation adds).
//!
//! ## The pipeline
//!
//! Data flows one way, each layer using only the ones before it (no module imports another
//! that imports it back, at any level):
//!
//! ```text
//! base ─► mesh ─► fem ─► kernel ─► skeleton, actuator, cloth, contact ─► model ─► report
//!      ─► constraint ─► analysis ─► solver ─► diff ─► scene / output
//! ```
//!
//! * [`base`]: the input-validation error, [`Material`], [`Body`], [`Schedule`], the
//!   [`Choice`](base::Choice) of named settings; imports nothing of the crate.
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
//! * [`report`]: versioned JSON (schema headers, provenance, verdicts), written atomically.
//! * `constraint` (internal): one constraint set per kind (elasticity, pneumatic, muscle, cloth
//!   stretching and bending, attachments) with its share of `L`, projection, adjoint and the
//!   term it adds to Newton's Hessian.
//! * [`analysis`]: spectral radii of the paper's iterations, critical time steps, the appendix's
//!   claims checked on real meshes.
//! * [`solver`]: the [`Simulator`]. A model's global system at a step size (`System`: the
//!   assembled `M/h^2 + L`, its factor and its certificates, shared through
//!   [`Systems`](solver::Systems)); the step's problem (energy, gradient, Hessian, Eq. S3); the
//!   iteration that solves it (local-global with any global solver, Eqs. 3-5, or Newton's
//!   method, Eqs. S3-S9), certified by the spectral analysis before stepping; contacts
//!   (Eqs. C1-C5); implicit Euler or BDF2.
//! * [`diff`]: reverse-mode gradients of whole simulations, unrolled or implicit ([`gradient`]),
//!   on the forward's systems; the registry of named parameters ([`diff::params`]).
//! * [`scene`]: the JSON scene format and the importer of the paper's scene files.
//! * [`output`]: VTK frames and the JSON run log of a simulation.
//! * [`alloc`]: a counting allocator, to measure peak heap and allocations.
//! * `testing` (feature `testing`): shared test scenes and helpers.
//!
//! The harness (studies, reports, plots, JSON Schemas) is the crate `diffsoft-harness`, the
//! command-line tool `diffsoft-cli`; neither is needed to use the engine.
//!
//! ## The seams
//!
//! * `ConstraintSet` (internal): one kind of projective constraint (Eq. 3) with its share of
//!   `L`, its gather, its adjoint and its Hessian term (declared, no default); the local step is
//!   one loop over the sets.
//! * `StepIteration` (internal): the method that solves a step's contact round (local-global,
//!   Newton, Newton in the skeleton's coordinates), chosen by value and handed the run's state.
//! * `GlobalSolver` (internal): the global step (Eq. 5) on the free vertices.
//! * [`skeleton::Joint`]: a joint's transform, derivative and update rule.
//! * [`contact::Shape`]: an obstacle's geometry query, and whether it is piecewise planar.
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
