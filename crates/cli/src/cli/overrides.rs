//! The solver settings `simulate` and `grad` both let the command line override.

use super::choice::choice;
use diffsoft::solver::{Integrator, SolverKind};
use diffsoft::Settings;

/// Overrides of a scene's solver settings (each left as the scene has it when absent).
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct SolverOverrides {
    /// Override the global solver.
    #[arg(long, value_parser = choice::<SolverKind>())]
    pub(crate) solver: Option<SolverKind>,
    /// Override the time integrator (bdf2: second order; its first step is implicit Euler).
    #[arg(long, value_parser = choice::<Integrator>())]
    pub(crate) integrator: Option<Integrator>,
    /// Override the local-global iteration cap.
    #[arg(long)]
    pub(crate) max_iterations: Option<usize>,
    /// Override the local-global tolerance (0: always run the cap, a smooth forward).
    #[arg(long)]
    pub(crate) tolerance: Option<f64>,
    /// Override the Anderson memory of the local-global iteration (0: off; unrolled mode
    /// differentiates plain iterations with 0).
    #[arg(long)]
    pub(crate) anderson: Option<usize>,
}

impl SolverOverrides {
    /// Write the given overrides into `settings`.
    pub(crate) fn apply(&self, settings: &mut Settings) {
        if let Some(s) = self.solver {
            settings.solver = s;
        }
        if let Some(i) = self.integrator {
            settings.integrator = i;
        }
        if let Some(m) = self.max_iterations {
            settings.max_iterations = m;
        }
        if let Some(t) = self.tolerance {
            settings.tolerance = t;
        }
        if let Some(m) = self.anderson {
            settings.anderson = m;
        }
    }
}
