//! The suite definition read from `verification/suite.json` (unknown keys are rejected).

use std::path::{Path, PathBuf};

use serde::Deserialize;

/// Schema name the suite file must declare.
pub const SUITE_SCHEMA: &str = "diffsoft.suite/1";

/// The whole suite.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Suite {
    /// Must be [`SUITE_SCHEMA`].
    pub schema: String,
    /// Convergence analysis of real meshes.
    pub bounds: BoundsSuite,
    /// Appendix A's `T` dependence on structured boxes of fixed cell size.
    pub t_scaling: TScalingSuite,
    /// Physics checks of the forward solver.
    pub physics: PhysicsSuite,
    /// The embedded-skeleton study (paper Fig. 5).
    pub skeleton: SkeletonSuite,
    /// The actuator study (appendix D).
    pub actuators: ActuatorSuite,
    /// Gradient checks, system identification, accuracy against cost, memory (docs/method.md 7).
    pub gradients: GradientSuite,
    /// Accuracy against cost of the solver settings (absent: skipped).
    #[serde(default)]
    pub tradeoff: Option<TradeoffSuite>,
    /// The extremes suite (absent: skipped).
    #[serde(default)]
    pub extremes: Option<ExtremesSuite>,
    /// The cloth study: the paper's ball-on-cloth scene and collision-detection cost (absent:
    /// skipped).
    #[serde(default)]
    pub cloth: Option<ClothSuite>,
    /// The validation suite against closed forms (absent: skipped).
    #[serde(default)]
    pub validation: Option<ValidationSuite>,
}

/// The validation suite.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ValidationSuite {
    /// Which cases.
    pub subset: super::validation::Subset,
}

/// The cloth study.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ClothSuite {
    /// The scenes (relative to the suite file) and their steps; the first is the paper's.
    pub scenes: Vec<SuiteScene>,
    /// Cloth cells per side of the detection-cost meshes.
    pub detection_sizes: Vec<usize>,
}

/// The trade-off study: one sweep per scene.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TradeoffSuite {
    /// The sweeps (scene files relative to the suite file).
    pub scenes: Vec<super::tradeoff::TradeoffSpec>,
}

/// The extremes suite.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ExtremesSuite {
    /// Which cases.
    pub subset: super::extremes::Subset,
}

/// The gradient study.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GradientSuite {
    /// The bridgesus scene (paper format), relative to the suite file.
    pub bridgesus: PathBuf,
    /// The Baymax skeleton scene.
    pub baymax_skeleton: PathBuf,
    /// The ball-on-cloth scene (diffsoft format).
    pub ball_on_cloth: PathBuf,
    /// Scene of the memory study.
    pub memory_scene: PathBuf,
    /// Horizons of the memory study.
    pub memory_steps: Vec<usize>,
    /// Steps of each check.
    pub steps: usize,
    /// Steps of the system identification.
    pub sysid_steps: usize,
}

/// The actuator study: static checks plus the paper's drone and octopus scenes.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ActuatorSuite {
    /// The drone scene (paper format), relative to the suite file.
    pub drone: PathBuf,
    /// Activation of every pneumatic group of the drone (1: target volume ratio).
    pub drone_activation: f64,
    /// Steps of the drone run.
    pub drone_steps: usize,
    /// The octopus scene (paper format).
    pub octopus: PathBuf,
    /// The muscle group driven.
    pub octopus_muscle: String,
    /// Its activation (1: muscle contraction).
    pub octopus_activation: f64,
    /// Steps of the octopus run.
    pub octopus_steps: usize,
}

/// The embedded-skeleton study.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SkeletonSuite {
    /// Scene with bones and joint torques, relative to the suite file.
    pub scene: PathBuf,
    /// Steps of each run.
    pub steps: usize,
    /// Bones whose arms are measured (elevation, length).
    pub arm_bones: Vec<String>,
}

/// Physics checks of the forward solver.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PhysicsSuite {
    /// Refinement levels of the cantilever study (cells across the section).
    pub cantilever_levels: Vec<usize>,
    /// Scenes to run, relative to the suite file.
    pub scenes: Vec<SuiteScene>,
}

/// A scene run by the suite.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SuiteScene {
    /// Scene file, relative to the suite file.
    pub scene: PathBuf,
    /// Steps.
    pub steps: usize,
}

/// Bounds analysis settings and meshes.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BoundsSuite {
    /// Run the empirical contraction check.
    pub empirical: bool,
    /// Time steps per sweep curve.
    pub sweep_points: usize,
    /// Meshes to analyse.
    pub meshes: Vec<SuiteMesh>,
}

/// One mesh of the suite, with the paper scene's material and time step.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SuiteMesh {
    /// Short name (file names of the sweep outputs).
    pub name: String,
    /// Mesh file, relative to the suite file.
    pub mesh: PathBuf,
    /// The paper scene file these parameters come from (relative to the suite file).
    pub source_scene: Option<PathBuf>,
    /// Vertex scale (1; "Scale"; the reference implementation's default is 0.05).
    pub scale: f64,
    /// Total mass (kg; "Mass", default 10): lumped by volume, i.e. density = mass / volume.
    pub total_mass: f64,
    /// Young's modulus (Pa).
    pub youngs_modulus: f64,
    /// Poisson ratio (1).
    pub poisson_ratio: f64,
    /// Time step (s; 1 / "Simulation HZ").
    pub dt: f64,
    /// Penalty attachments ("Attach Verts", "Attach Stiffness").
    #[serde(default)]
    pub attach: Option<SuiteAttach>,
}

/// Attachments of a suite mesh.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SuiteAttach {
    /// Attached vertices (0-based file indices).
    pub vertices: Vec<usize>,
    /// Spring weight (N/m).
    pub stiffness: f64,
}

/// Structured boxes with a fixed cell size and a growing number of cells.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TScalingSuite {
    /// Cell edge length (m).
    pub cell_size: f64,
    /// Density (kg/m^3).
    pub rho: f64,
    /// Stiffness coefficient of `L` (Pa).
    pub mu: f64,
    /// Cells per axis of each cubic box.
    pub cells_per_axis: Vec<usize>,
}

/// Errors reading a suite.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SuiteError {
    /// Cannot read the file.
    #[error("{path}: {source}")]
    Io {
        /// Suite path.
        path: String,
        /// Cause.
        source: std::io::Error,
    },
    /// Invalid JSON or unknown/missing keys (serde names key, line and column).
    #[error("{path}: {source}")]
    Json {
        /// Suite path.
        path: String,
        /// Cause.
        source: serde_json::Error,
    },
    /// A value is meaningless.
    #[error("{path}: {message}")]
    Invalid {
        /// Suite path.
        path: String,
        /// What is wrong.
        message: String,
    },
}

impl Suite {
    /// Read and check a suite file.
    pub fn load(path: &Path) -> Result<Suite, SuiteError> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| SuiteError::Io {
            path: shown.clone(),
            source,
        })?;
        let suite: Suite = serde_json::from_str(&text).map_err(|source| SuiteError::Json {
            path: shown.clone(),
            source,
        })?;
        let invalid = |message: String| SuiteError::Invalid {
            path: shown.clone(),
            message,
        };
        if suite.schema != SUITE_SCHEMA {
            return Err(invalid(format!(
                "schema is '{}', expected '{SUITE_SCHEMA}'",
                suite.schema
            )));
        }
        for m in &suite.bounds.meshes {
            for (what, v) in [
                ("scale", m.scale),
                ("total_mass", m.total_mass),
                ("youngs_modulus", m.youngs_modulus),
                ("dt", m.dt),
            ] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(invalid(format!(
                        "mesh '{}': {what} must be finite and positive, got {v}",
                        m.name
                    )));
                }
            }
            if !(m.poisson_ratio > -1.0 && m.poisson_ratio < 0.5) {
                return Err(invalid(format!(
                    "mesh '{}': poisson_ratio must be in (-1, 0.5), got {}",
                    m.name, m.poisson_ratio
                )));
            }
        }
        if suite.bounds.sweep_points < 2 {
            return Err(invalid("bounds.sweep_points must be at least 2".into()));
        }
        Ok(suite)
    }
}
