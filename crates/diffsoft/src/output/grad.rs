//! The JSON output of `diffsoft grad --json` (`diffsoft.grad/1`): the loss of a simulation and
//! its derivatives with respect to scalar parameters.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::diff::{DiffStats, Mode};
use crate::report::Header;
use crate::solver::Settings;

/// Schema of `diffsoft grad --json`.
pub const GRAD_SCHEMA: &str = "diffsoft.grad/1";

/// `diffsoft grad --json`.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct GradReport {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// Scene file.
    pub scene: String,
    /// Steps simulated.
    pub steps: usize,
    /// Differentiation mode.
    pub mode: Mode,
    /// The loss, by name (e.g. `final_com.y`).
    pub loss_name: String,
    /// Loss value (the loss's unit: m for centre-of-mass losses, rad for joint angles).
    pub loss: f64,
    /// Value of each differentiated parameter, by name, in its unit; parameters without a
    /// single value are left out. The names and units are the registry's
    /// ([`crate::diff::params::PARAMETERS`]), which the schema lists.
    #[schemars(
        schema_with = "crate::diff::params::values_schema",
        description = crate::diff::params::values_description()
    )]
    pub parameters: BTreeMap<String, f64>,
    /// `d loss / d parameter` for each parameter, by name (loss unit per parameter unit).
    #[schemars(schema_with = "crate::diff::params::values_schema")]
    pub gradient: BTreeMap<String, f64>,
    /// Parameters set before the run (`--set NAME=VALUE`), by name, in the registry's units.
    #[schemars(schema_with = "crate::diff::params::values_schema")]
    pub overrides: BTreeMap<String, f64>,
    /// The solver settings of the run, the command line's overrides applied (`damping` is the
    /// velocity factor per step).
    pub settings: Settings,
    /// Cost and accuracy of the forward and backward passes.
    pub stats: DiffStats,
}
