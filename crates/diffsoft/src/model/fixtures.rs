//! Small models shared by tests inside this crate and by the test scenes of `testing`
//! (feature `testing`): they depend only on the model's own inputs, so that tests of the
//! solver can build them without reaching up to `testing`, which depends on the solver.

use nalgebra::Vector3;

use super::{BodySpec, MassSpec, Model, ModelBuilder};
use crate::actuator::{centroid, ActuatorSpec};
use crate::base::{InputError, Material, Schedule};
use crate::contact::Obstacle;
use crate::mesh::generate::BoxSpec;

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
    let mesh = BoxSpec::new([6, 2, 2], [0.6, 0.1, 0.1])
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

/// The ground-contact case's model: a jittered soft box (60 tets) thrown at (0.5, -1, 0.2) m/s
/// onto ground with friction `mu`.
pub fn ground_box(mu: f64) -> Result<Model, InputError> {
    let mesh = BoxSpec::new([3, 2, 2], [0.3, 0.2, 0.2])
        .jitter(0.1, 5)
        .origin([0.0, 0.02, 0.0])
        .build()
        .map_err(|e| InputError::new(format!("ground box: {e}")))?;
    let mut body = BodySpec::new(
        "box",
        mesh,
        Material {
            youngs_modulus: 2e4,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(1000.0),
    );
    body.initial_velocity = Vector3::new(0.5, -1.0, 0.2);
    ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .obstacle(Obstacle::plane("ground", Vector3::zeros(), Vector3::y(), mu))
        .build()
}

/// A free box of `cells` cells spanning `size` metres (E = 1e5, nu = 0.3, 1000 kg/m^3), no
/// gravity, nothing fixed: the plainest model, for tests of operators on a mesh.
#[cfg(test)]
pub(crate) fn free_box(cells: [usize; 3], size: [f64; 3]) -> Result<Model, InputError> {
    let mesh = BoxSpec::new(cells, size)
        .build()
        .map_err(|e| InputError::new(format!("free box: {e}")))?;
    let m = Material {
        youngs_modulus: 1e5,
        poisson_ratio: 0.3,
    };
    ModelBuilder::new()
        .body(BodySpec::new("box", mesh, m, MassSpec::Density(1000.0)))
        .build()
}
