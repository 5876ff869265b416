//! The scenes of the trade-off study: scene files, or a cantilever beam generated in code (the
//! large mesh, which is not worth committing as a file).

use std::path::Path;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::{SceneSource, TradeoffError};
use diffsoft::base::Material;
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::model::{BodySpec, MassSpec, Model, ModelBuilder};
use diffsoft::scene::{self, LoadOptions};
use diffsoft::solver::Settings;

/// A beam along x, Kuhn-split box cells, its `x = 0` face held fixed (Dirichlet), under gravity
/// `-9.81` along y.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Cantilever {
    /// Cells along x, y, z (6 tets per cell).
    pub cells: [usize; 3],
    /// Edge lengths (m).
    pub size: [f64; 3],
    /// Young's modulus (Pa).
    pub youngs_modulus: f64,
    /// Poisson ratio (1).
    pub poisson_ratio: f64,
    /// Density (kg/m^3).
    pub density: f64,
    /// The scene's time step `h` (s).
    pub dt: f64,
}

impl Cantilever {
    /// A 192-tet beam (8 x 2 x 2 cells, 1 m x 0.25 m x 0.25 m, E 1e6, nu 0.3, rho 1000,
    /// h = 0.01 s) for tests.
    pub fn small() -> Self {
        Self {
            cells: [8, 2, 2],
            size: [1.0, 0.25, 0.25],
            youngs_modulus: 1e6,
            poisson_ratio: 0.3,
            density: 1000.0,
            dt: 0.01,
        }
    }

    /// Build the model and the scene's settings (direct solver, 30 iterations, tolerance 1e-6,
    /// no damping).
    pub fn build(&self) -> Result<(Model, Settings), String> {
        let mesh = BoxSpec::new(self.cells, self.size).build().map_err(|e| e.to_string())?;
        let fixed: Vec<usize> = (0..mesh.num_vertices())
            .filter(|&i| mesh.vertices[i].x <= 1e-12)
            .collect();
        let mut body = BodySpec::new(
            "beam",
            mesh,
            Material {
                youngs_modulus: self.youngs_modulus,
                poisson_ratio: self.poisson_ratio,
            },
            MassSpec::Density(self.density),
        );
        body.fixed = fixed;
        let model = ModelBuilder::new()
            .gravity(Vector3::new(0.0, -9.81, 0.0))
            .body(body)
            .build()
            .map_err(|e| e.to_string())?;
        let settings = Settings {
            dt: self.dt,
            solver: diffsoft::solver::SolverKind::Direct,
            ..Settings::default()
        };
        Ok((model, settings))
    }
}

/// What a scene is, for the report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct SceneSummary {
    /// Vertices.
    pub vertices: usize,
    /// Tets.
    pub tets: usize,
    /// Bones of the embedded skeleton (0: none).
    pub bones: usize,
    /// Obstacles (contact).
    pub obstacles: usize,
    /// Dirichlet vertices.
    pub fixed_vertices: usize,
    /// The scene's time step `h` (s).
    pub dt: f64,
    /// Diagonal of the rest bounding box (m).
    pub length_scale: f64,
    /// Total mass (kg).
    pub mass: f64,
}

impl SceneSummary {
    /// Summarise a model.
    pub fn of(model: &Model, settings: &Settings) -> Self {
        Self {
            vertices: model.n(),
            tets: model.tets().len(),
            bones: model.skeleton().map_or(0, |s| s.bones.len()),
            obstacles: model.obstacles().len(),
            fixed_vertices: model.fixed().iter().filter(|&&f| f).count(),
            dt: settings.dt,
            length_scale: model.length_scale(),
            mass: model.mass().iter().sum(),
        }
    }
}

/// Load a sweep's scene; scene files are resolved against `base`.
pub fn load(name: &str, source: &SceneSource, base: &Path) -> Result<(Model, Settings), TradeoffError> {
    let err = |message: String| TradeoffError::Scene {
        name: name.to_string(),
        message,
    };
    match source {
        SceneSource::Scene(p) => {
            let sc = scene::load(base.join(p), LoadOptions::default()).map_err(|e| err(e.to_string()))?;
            Ok((sc.model, sc.settings))
        }
        SceneSource::Cantilever(c) => {
            if !(c.dt.is_finite() && c.dt > 0.0) {
                return Err(err(format!("cantilever dt must be finite and positive, got {}", c.dt)));
            }
            c.build().map_err(err)
        }
    }
}
