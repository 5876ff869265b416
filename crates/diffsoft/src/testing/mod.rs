//! Shared test scenes (feature `testing`): the bodies and gradient cases that this crate's
//! tests, the harness's studies and the benchmarks all use, built in one place so that every
//! caller that names one means the same scene.
//!
//! * [`Case`]: a scene, its settings, a loss, controls and the parameter groups to check,
//!   with its finite-difference perturbations ([`Case::perturbed`]-style helpers) and
//!   [`Case::gradient`];
//! * scene builders: [`clamped_cantilever_52k`] (and [`clamped_cantilever_52k_fixed`]), [`free_body`], [`ground_box`], [`ground_contact`], [`actuated`],
//!   [`ball_on_cloth`], the paper's scenes ([`bridgesus`], [`baymax_torques`],
//!   [`baymax_ground`], [`paper_ball_on_cloth`]), [`actuated_beam`], the collision-detection
//!   scene [`detection_scene`] and random joint chains ([`random_chain`]).
//!
//! * helpers of the integration tests ([`tmp_dir`], [`root`], [`cube_scene`], ...).
//!
//! Not part of the engine's API: enable it with `features = ["testing"]` (the dev-dependency
//! of this crate's own tests does).

mod cases;
mod fixtures;
mod scenes;
mod skeletons;
mod support;

pub use cases::*;
pub use fixtures::*;
pub use scenes::*;
pub use skeletons::*;
pub use support::*;
