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

use nalgebra::Vector3;

use crate::actuator::{ActuatorKind, Actuators};
use crate::base::Body;
use crate::cloth::Cloth;
use crate::contact::pair::Colliders;
use crate::contact::Obstacle;
use crate::fem::{Coefficient, FemOperators};
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

    /// `L = sum_t (w_rot + w_vol + w_pneumatic) A_t^T A_t + sum_fibres w (A_t m)(A_t m)^T +
    /// attachments` (per axis), values in the pattern.
    pub fn stiffness_values(&self) -> Vec<f64> {
        let mut k: Vec<f64> = (0..self.tets.len())
            .map(|t| (self.w_rot[t] + self.w_vol[t]) / self.fem.geometry[t].volume)
            .collect();
        let mut fibres = Vec::new();
        if let Some(act) = &self.actuators {
            for c in &act.cells {
                match act.groups[c.group].kind {
                    ActuatorKind::Pneumatic => k[c.tet] += c.weight / self.fem.geometry[c.tet].volume,
                    ActuatorKind::Muscle => fibres.push(c),
                }
            }
        }
        let mut values = self
            .fem
            .laplacian_values(Coefficient::PerTet(&k))
            .expect("weights validated");
        // A fibre's constraint is on F m = sum_a x_a (a_a . m): a rank-one block.
        for c in fibres {
            let g = &self.fem.geometry[c.tet];
            let gm: [f64; 4] = std::array::from_fn(|a| g.grads[a].dot(&c.direction));
            let slots = &self.fem.pattern.tet_slots[c.tet];
            for a in 0..4 {
                for b in 0..4 {
                    values[slots[4 * a + b] as usize] += c.weight * gm[a] * gm[b];
                }
            }
        }
        if let Some(cl) = &self.cloth {
            for ((g, slots), w) in cl.geometry.iter().zip(&cl.tri_slots).zip(&cl.w_stretch) {
                let k = g.local_laplacian();
                for a in 0..3 {
                    for b in 0..3 {
                        values[slots[3 * a + b] as usize] += w * k[a][b];
                    }
                }
            }
            let bends = &cl.bends;
            for i in 0..bends.len() {
                let (_, c) = bends.stencil(i);
                let slots = &bends.slots[bends.slot_offsets[i]..bends.slot_offsets[i + 1]];
                let k = c.len();
                for a in 0..k {
                    for b in 0..k {
                        values[slots[k * a + b] as usize] += bends.weight[i] * c[a] * c[b];
                    }
                }
            }
        }
        for a in &self.attachments {
            values[self.fem.pattern.diag_slot[a.vertex]] += a.weight;
        }
        values
    }

    /// Number of cloth triangles (0 without cloth).
    pub fn num_cloth_triangles(&self) -> usize {
        self.cloth.as_ref().map_or(0, |c| c.num_triangles())
    }
}
