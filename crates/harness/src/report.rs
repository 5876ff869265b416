//! Versioned JSON reports: every report starts with a [`Header`] (schema name with version,
//! crate version, provenance) and states its claims as [`Verdict`]s; both live in the core crate
//! (`diffsoft::output::report`), whose analysis reports use them too.

pub use diffsoft::report::{write_atomic, write_json, Header, ModelSize, Provenance, Verdict, CRATE_VERSION};
