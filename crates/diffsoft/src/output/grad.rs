//! The JSON output of `diffsoft grad --json` (`diffsoft.grad/1`): the loss of a simulation and
//! its derivatives with respect to scalar parameters.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::diff::{DiffStats, Mode};
use crate::output::report::Header;

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
    /// Value of each differentiated parameter, by name (its unit: Pa for `youngs_modulus`,
    /// kg/m^3 for `density`, m/s for `initial_velocity.*`, m/s^2 for `gravity.*`, 1 for
    /// `poisson_ratio`); parameters without a single value are left out.
    pub parameters: BTreeMap<String, f64>,
    /// `d loss / d parameter` for each parameter, by name (loss unit per parameter unit).
    pub gradient: BTreeMap<String, f64>,
    /// Cost and accuracy of the forward and backward passes.
    pub stats: DiffStats,
}
