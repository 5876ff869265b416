//! The solver settings `simulate` and `grad` both let the command line override. Each flag is a
//! field of [`Settings`], spelled as in scene files and Python's `Scene.configure`, documented
//! by that field's doc comment and written through [`Settings::set`], which checks it.

use super::choice::choice;
use diffsoft::solver::{CertifyPolicy, Integrator, SolverKind};
use diffsoft::Settings;

/// The help of the flag that overrides setting `name`: the setting's documentation.
fn help(name: &str) -> String {
    let doc = Settings::describe(name).unwrap_or_default();
    format!("Override the scene's solver setting `{name}`: {doc}")
}

/// Overrides of a scene's solver settings (each left as the scene has it when absent).
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct SolverOverrides {
    #[arg(long, value_parser = choice::<SolverKind>(), help = help("solver"))]
    pub(crate) solver: Option<SolverKind>,
    #[arg(long, value_parser = choice::<Integrator>(), help = help("integrator"))]
    pub(crate) integrator: Option<Integrator>,
    #[arg(long, value_parser = choice::<CertifyPolicy>(), help = help("certify"))]
    pub(crate) certify: Option<CertifyPolicy>,
    #[arg(long, help = help("dt"))]
    pub(crate) dt: Option<f64>,
    #[arg(long, help = help("max_iterations"))]
    pub(crate) max_iterations: Option<usize>,
    #[arg(long, help = help("tolerance"))]
    pub(crate) tolerance: Option<f64>,
    #[arg(long, help = help("anderson"))]
    pub(crate) anderson: Option<usize>,
}

impl SolverOverrides {
    /// Write the given overrides into `settings` (an error names a setting that is not
    /// meaningful).
    pub(crate) fn apply(&self, settings: &mut Settings) -> anyhow::Result<()> {
        let given = [
            ("solver", self.solver.map(|v| serde_json::json!(v))),
            ("integrator", self.integrator.map(|v| serde_json::json!(v))),
            ("certify", self.certify.map(|v| serde_json::json!(v))),
            ("dt", self.dt.map(|v| serde_json::json!(v))),
            ("max_iterations", self.max_iterations.map(|v| serde_json::json!(v))),
            ("tolerance", self.tolerance.map(|v| serde_json::json!(v))),
            ("anderson", self.anderson.map(|v| serde_json::json!(v))),
        ];
        // JSON has no NaN or infinity: such a value is refused here, naming the flag (the
        // settings' own checks, through `Settings::set`, judge every finite one).
        for (name, v) in [("dt", self.dt), ("tolerance", self.tolerance)] {
            if let Some(v) = v.filter(|v| !v.is_finite()) {
                anyhow::bail!("--{name} {v}: must be a finite number");
            }
        }
        for (name, value) in given {
            if let Some(v) = value {
                // The error names the flag as the user typed it.
                settings
                    .set(name, v.clone())
                    .map_err(|e| anyhow::anyhow!("--{} {v}: {e}", name.replace('_', "-")))?;
            }
        }
        Ok(())
    }
}
