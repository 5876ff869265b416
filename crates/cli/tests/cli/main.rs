//! The command-line tool's tests: the `diffsoft` binary run as a user runs it (one test binary).

mod common {
    pub use diffsoft::testing::*;
}
mod cli;
mod grad;
mod hardening;
mod run;
mod schemas;
mod simulate;
mod tradeoff;
