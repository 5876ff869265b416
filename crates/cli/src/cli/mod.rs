//! The command-line tool's larger subcommands, one module each (the binary's own code; the
//! library is `diffsoft`). `main.rs` parses the command line and dispatches.

pub(crate) mod choice;
pub(crate) mod files;
pub(crate) mod grad;
pub(crate) mod overrides;
pub(crate) mod simulate;
pub(crate) mod tradeoff;

/// What every subcommand module uses.
mod prelude {
    pub(crate) use std::path::{Path, PathBuf};

    pub(crate) use anyhow::{bail, Context, Result};
}
