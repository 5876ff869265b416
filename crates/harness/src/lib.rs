//! # diffsoft-harness
//!
//! The verification and convergence-analysis harness of `diffsoft`: the studies the main job
//! (`diffsoft verify`) runs, their versioned JSON reports and JSON Schemas, readable summaries
//! and SVG plots. It reads `verification/suite.json` and writes `reports/`.
//!
//! The engine it measures is the `diffsoft` crate; this crate adds no physics.
#![deny(missing_docs)]

/// `println!` that never panics: a closed pipe or a full disk on standard output loses the
/// text, not the run (the reports are files, written and checked on their own).
#[macro_export]
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}

/// `print!` that never panics (see [`say!`]).
#[macro_export]
macro_rules! say_raw {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout(), $($t)*);
    }};
}

/// `eprintln!` that never panics (see [`say!`]).
#[macro_export]
macro_rules! warn {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($t)*);
    }};
}

pub mod actuators;
mod bounds;
pub mod cloth;
pub mod extremes;
pub mod fd;
pub mod gradients;
pub mod jacobians;
pub mod merge;
pub mod page;
pub mod physics;
mod physics_suite;
pub mod plot;
pub mod pool;
pub mod report;
pub mod schemas;
pub mod shard;
pub mod skeleton;
pub mod suite;
mod suite_run;
mod summary;
pub mod tradeoff;
pub mod validation;

pub use bounds::{
    t_scaling, t_scaling_chart, CrossCheck, QualityReport, SuiteBoundsReport, SuiteMaterial, SuiteMeshResult,
    SweepInputs, SweepReport, TScaling, TScalingRow, TableRow, QUALITY_SCHEMA, SUITE_BOUNDS_SCHEMA, SWEEP_SCHEMA,
};
pub use physics_suite::{PhysicsReport, PHYSICS_SCHEMA};
pub use schemas::schemas;
pub use suite_run::run_suite;
pub use summary::{
    bounds_summary, jacobians_table, physics_table, quality_summary, skeleton_table, sweep_summary, table,
};
