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
    pub(crate) rest: Vec<Vector3<f64>>,
    /// Initial velocities.
    pub(crate) initial_velocity: Vec<Vector3<f64>>,
    /// All tets (global vertex numbering).
    pub(crate) tets: Vec<[usize; 4]>,
    /// Per-tet geometry and the pattern of `L`.
    pub(crate) fem: FemOperators,
    /// Corotated weight per tet (`E/(1+nu) V`).
    pub(crate) w_rot: Vec<f64>,
    /// Volume weight per tet (`nu E/(1+nu) V`, 0 when disabled).
    pub(crate) w_vol: Vec<f64>,
    /// Lumped mass per vertex.
    pub(crate) mass: Vec<f64>,
    /// External acceleration per vertex (gravity where enabled).
    pub(crate) accel: Vec<Vector3<f64>>,
    /// Penalty attachments.
    pub(crate) attachments: Vec<Attachment>,
    /// Dirichlet vertices (held at their rest position).
    pub(crate) fixed: Vec<bool>,
    /// Obstacles (empty: no collision code runs).
    pub(crate) obstacles: Vec<Obstacle>,
    /// Bodies.
    pub(crate) bodies: Vec<Body>,
    /// Vertex-to-tet adjacency for the right-hand-side gather.
    pub(crate) vertex_tets: VertexTets,
    /// Embedded skeleton (`None`: no skeleton code runs).
    pub(crate) skeleton: Option<Skeleton>,
    /// Pneumatic cells and muscle fibres (`None`: no actuator code runs).
    pub(crate) actuators: Option<Actuators>,
    /// Cloth bodies (`None`: no cloth code runs).
    pub(crate) cloth: Option<Cloth>,
    /// Collisions between bodies (soft-soft, soft-cloth; `None`: bodies pass through each
    /// other and no collision code runs).
    pub(crate) collision: Option<Colliders>,
    /// Characteristic length: the diagonal of the rest bounding box.
    pub(crate) length_scale: f64,
}

impl Model {
    /// Rest positions of all vertices.
    pub fn rest(&self) -> &[Vector3<f64>] {
        &self.rest
    }

    /// Initial velocities.
    pub fn initial_velocity(&self) -> &[Vector3<f64>] {
        &self.initial_velocity
    }

    /// All tets (global vertex numbering).
    pub fn tets(&self) -> &[[usize; 4]] {
        &self.tets
    }

    /// Per-tet geometry and the pattern of `L`.
    pub fn fem(&self) -> &FemOperators {
        &self.fem
    }

    /// Corotated weight per tet (`E/(1+nu) V`).
    pub fn w_rot(&self) -> &[f64] {
        &self.w_rot
    }

    /// Volume weight per tet (`nu E/(1+nu) V`, 0 when disabled).
    pub fn w_vol(&self) -> &[f64] {
        &self.w_vol
    }

    /// Lumped mass per vertex.
    pub fn mass(&self) -> &[f64] {
        &self.mass
    }

    /// External acceleration per vertex (gravity where enabled).
    pub fn accel(&self) -> &[Vector3<f64>] {
        &self.accel
    }

    /// Penalty attachments.
    pub fn attachments(&self) -> &[Attachment] {
        &self.attachments
    }

    /// Dirichlet vertices (held at their rest position).
    pub fn fixed(&self) -> &[bool] {
        &self.fixed
    }

    /// Obstacles (empty: no collision code runs).
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Bodies.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// Vertex-to-tet adjacency for the right-hand-side gather.
    pub fn vertex_tets(&self) -> &VertexTets {
        &self.vertex_tets
    }

    /// Embedded skeleton (`None`: no skeleton code runs).
    pub fn skeleton(&self) -> Option<&Skeleton> {
        self.skeleton.as_ref()
    }

    /// Pneumatic cells and muscle fibres (`None`: no actuator code runs).
    pub fn actuators(&self) -> Option<&Actuators> {
        self.actuators.as_ref()
    }

    /// Cloth bodies (`None`: no cloth code runs).
    pub fn cloth(&self) -> Option<&Cloth> {
        self.cloth.as_ref()
    }

    /// Collisions between bodies (soft-soft, soft-cloth; `None`: bodies pass through each other and no collision code runs).
    pub fn collision(&self) -> Option<&Colliders> {
        self.collision.as_ref()
    }

    /// Characteristic length: the diagonal of the rest bounding box.
    pub fn length_scale(&self) -> f64 {
        self.length_scale
    }

    /// Remove every obstacle (the same bodies falling freely).
    pub fn remove_obstacles(&mut self) {
        self.obstacles.clear();
    }

    /// Remove the skeleton (its bone vertices become free vertices of the soft body).
    pub fn remove_skeleton(&mut self) {
        self.skeleton = None;
    }

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
