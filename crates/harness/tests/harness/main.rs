//! The harness crate's integration tests (the studies, their reports and schemas), one module per subject (one test binary).

mod common {
    pub use diffsoft::testing::*;
}
mod actuator_props;
mod actuators;
mod bdf2;
mod cloth;
mod doc_numbers;
mod extremes;
mod gradients;
mod materials;
mod newton_contact;
mod newton_skeleton;
mod page;
mod physics;
mod schemas;
mod skeleton;
mod solvers;
mod tradeoff;
mod validation;
