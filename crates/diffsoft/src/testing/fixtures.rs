//! Test bodies shared by more than one study, built in one place so that every study that
//! names one means the same body.

use nalgebra::Vector3;

use crate::actuator::{centroid, ActuatorSpec};
use crate::base::{InputError, Material, Schedule};
use crate::model::{BodySpec, MassSpec, Model, ModelBuilder};

/// A beam (6 x 2 x 2 cells, 0.6 x 0.1 x 0.1 m, 72 tets, E = 1e4, nu = 0.3, 500 kg/m^3) held by
/// springs (stiffness 1e4) at x = 0 under gravity 1 m/s^2, with a pneumatic group `inflate` on
/// its top layer (active at 1) and a muscle group `contract` along x on its bottom layer (at 0),
/// both of stiffness 2e4.
pub struct ActuatedBeam {
    /// The model.
    pub model: Model,
    /// The vertex at the free tip (largest x).
    pub tip: usize,
}

/// Build the [`ActuatedBeam`].
pub fn actuated_beam() -> Result<ActuatedBeam, InputError> {
    let mesh = crate::mesh::generate::BoxSpec::new([6, 2, 2], [0.6, 0.1, 0.1])
        .build()
        .map_err(|e| InputError::new(format!("actuated beam: {e}")))?;
    let top: Vec<usize> = (0..mesh.num_tets()).filter(|&t| centroid(&mesh, t).y > 0.05).collect();
    let bottom: Vec<usize> = (0..mesh.num_tets()).filter(|&t| centroid(&mesh, t).y <= 0.05).collect();
    let attached: Vec<(usize, f64)> = (0..mesh.num_vertices())
        .filter(|&i| mesh.vertices[i].x < 1e-9)
        .map(|i| (i, 1e4))
        .collect();
    let tip = (0..mesh.num_vertices())
        .max_by(|&a, &b| mesh.vertices[a].x.total_cmp(&mesh.vertices[b].x))
        .unwrap_or(0);
    let mut body = BodySpec::new(
        "beam",
        mesh,
        Material {
            youngs_modulus: 1e4,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(500.0),
    );
    body.attachments = attached;
    body.actuators = vec![
        ActuatorSpec::pneumatic("inflate", &top, 2e4, Schedule::constant(1.0)),
        ActuatorSpec::muscle(
            "contract",
            bottom.iter().map(|&t| (t, Vector3::x())).collect(),
            2e4,
            Schedule::constant(0.0),
        ),
    ];
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -1.0, 0.0))
        .body(body)
        .build()?;
    Ok(ActuatedBeam { model, tip })
}

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
