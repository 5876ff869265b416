//! Test bodies shared by more than one study, built in one place so that every study that
//! names one means the same body.

use nalgebra::Vector3;

use crate::base::{InputError, Material};
pub use crate::model::fixtures::{actuated_beam, ActuatedBeam};
use crate::model::{BodySpec, MassSpec, Model, ModelBuilder};

/// The trade-off study's clamped cantilever: 52 x 13 x 13 cells (1 x 0.25 x 0.25 m, 52 728
/// tets, 10 388 vertices), E = 1e6, nu = 0.3, 1000 kg/m^3, its `x = 0` face fixed, gravity
/// 9.81 m/s^2 along -y: the many-core case of the step benchmark and `examples/thread_scaling.rs`.
pub fn clamped_cantilever_52k() -> Result<Model, InputError> {
    let mesh = crate::mesh::generate::BoxSpec::new([52, 13, 13], [1.0, 0.25, 0.25])
        .build()
        .map_err(|e| InputError::new(format!("clamped cantilever: {e}")))?;
    let fixed: Vec<usize> = (0..mesh.num_vertices())
        .filter(|&i| mesh.vertices[i].x < 1e-9)
        .collect();
    let mut body = BodySpec::new(
        "cantilever",
        mesh,
        Material {
            youngs_modulus: 1e6,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(1000.0),
    );
    body.fixed = fixed;
    ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .build()
}

/// [`clamped_cantilever_52k`] on the direct solver at exactly `iterations` local-global
/// iterations per step (tolerance 0, no Anderson acceleration), `dt = 0.01` s.
pub fn clamped_cantilever_52k_fixed(iterations: usize) -> anyhow::Result<crate::solver::Simulator> {
    Ok(crate::solver::Simulator::new(
        clamped_cantilever_52k()?,
        crate::solver::Settings {
            dt: 0.01,
            solver: crate::solver::SolverKind::Direct,
            tolerance: 0.0,
            max_iterations: iterations,
            anderson: 0,
            ..crate::solver::Settings::default()
        },
    )?)
}
