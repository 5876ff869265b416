//! The static data of a simulation: bodies (tet meshes with material and mass), cloth,
//! attachments, Dirichlet vertices, external accelerations, obstacles, skeleton and actuators.
//! Built once by [`ModelBuilder`] (validated, in the global numbering); a
//! [`Simulator`](crate::solver::Simulator) never changes it. Its fields are read through
//! accessors.

mod attachment;
mod builder;
mod cloth;
mod vertex_tets;

pub use attachment::Attachment;
pub use builder::{BodySpec, MassSpec, ModelBuilder, MIN_MESH_THICKNESS};
pub use vertex_tets::VertexTets;

use nalgebra::{Matrix3, Vector3};

use crate::actuator::Actuators;
use crate::base::Body;
use crate::cloth::Cloth;
use crate::contact::pair::Colliders;
use crate::contact::Obstacle;
use crate::fem::FemOperators;
use crate::skeleton::Skeleton;

/// Everything a simulation needs that does not change while it runs.
#[derive(Debug, Clone)]
pub struct Model {
    /// Rest positions of all vertices.
    pub rest: Vec<Vector3<f64>>,
    /// Initial velocities.
    pub initial_velocity: Vec<Vector3<f64>>,
    /// All tets (global vertex numbering).
    pub tets: Vec<[usize; 4]>,
    /// Per-tet geometry and the pattern of `L`.
    pub fem: FemOperators,
    /// Corotated weight per tet (`E/(1+nu) V`).
    pub w_rot: Vec<f64>,
    /// Volume weight per tet (`nu E/(1+nu) V`, 0 when disabled).
    pub w_vol: Vec<f64>,
    /// Lumped mass per vertex.
    pub mass: Vec<f64>,
    /// External acceleration per vertex (gravity where enabled).
    pub accel: Vec<Vector3<f64>>,
    /// Penalty attachments.
    pub attachments: Vec<Attachment>,
    /// Dirichlet vertices (held at their rest position).
    pub fixed: Vec<bool>,
    /// Obstacles (empty: no collision code runs).
    pub obstacles: Vec<Obstacle>,
    /// Bodies.
    pub bodies: Vec<Body>,
    /// Vertex-to-tet adjacency for the right-hand-side gather.
    pub vertex_tets: VertexTets,
    /// Embedded skeleton (`None`: no skeleton code runs).
    pub skeleton: Option<Skeleton>,
    /// Pneumatic cells and muscle fibres (`None`: no actuator code runs).
    pub actuators: Option<Actuators>,
    /// Cloth bodies (`None`: no cloth code runs).
    pub cloth: Option<Cloth>,
    /// Collisions between bodies (soft-soft, soft-cloth; `None`: bodies pass through each
    /// other and no collision code runs).
    pub collision: Option<Colliders>,
    /// Characteristic length: the diagonal of the rest bounding box.
    pub length_scale: f64,
}

impl Model {
    /// Number of vertices.
    pub fn n(&self) -> usize {
        self.rest.len()
    }

    /// `F_t(x) = sum_a x_a a_{t,a}^T`: the deformation gradient of tet `t` at positions `x`
    /// (all vertices), or the adjoint of its projection when `x` is an adjoint.
    #[inline]
    pub fn tet_deformation(&self, t: usize, x: &[Vector3<f64>]) -> Matrix3<f64> {
        let [i0, i1, i2, i3] = self.tets[t];
        let x0 = x[i0];
        Matrix3::from_columns(&[x[i1] - x0, x[i2] - x0, x[i3] - x0]) * self.fem.geometry[t].p_inv
    }

    /// Number of cloth triangles (0 without cloth).
    pub fn num_cloth_triangles(&self) -> usize {
        self.cloth.as_ref().map_or(0, |c| c.num_triangles())
    }
}
