//! The static data of a simulation: bodies (tet meshes with material and mass), cloth,
//! attachments, Dirichlet vertices, external accelerations, obstacles, skeleton and actuators.
//! Built once by [`ModelBuilder`] (validated, in the global numbering); a
//! [`Simulator`](crate::solver::Simulator) never changes it. Its fields are read through
//! accessors.

mod attachment;
mod builder;
mod cloth;
#[cfg(feature = "testing")]
pub(crate) mod fixtures;
mod hyper;
mod vertex_tets;

pub use attachment::Attachment;
pub use builder::{BodySpec, MassSpec, ModelBuilder, MIN_MESH_THICKNESS};
pub(crate) use hyper::weight as hyper_weight;
pub use hyper::HyperTets;
pub use vertex_tets::VertexTets;

use nalgebra::{Matrix3, Vector3};

use crate::actuator::Actuators;
use crate::base::{Body, InputError};
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
    /// Tets of hyperelastic bodies (`None`: every body is projective and no hyperelastic code
    /// runs). Their projective weights `w_rot`, `w_vol` are zero.
    pub(crate) hyper: Option<HyperTets>,
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

    /// Tets of hyperelastic bodies (`None` when every body is projective).
    pub fn hyper(&self) -> Option<&HyperTets> {
        self.hyper.as_ref()
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

    /// Give body `body` the material model `model` (its Young's modulus per tet and Poisson
    /// ratio kept), rebuilding the tets' projective weights or hyperelastic parameters.
    ///
    /// ```
    /// use diffsoft::base::MaterialModel;
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let m = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
    /// let mut model = ModelBuilder::new().body(BodySpec::new("box", mesh, m, MassSpec::Density(1e3))).build()?;
    /// model.set_material_model("box", MaterialModel::NeoHookean)?;
    /// assert_eq!(model.hyper().map(|h| h.len()), Some(model.tets().len()));
    /// model.set_material_model("box", MaterialModel::Projective)?;
    /// assert!(model.hyper().is_none() && model.w_rot().iter().all(|&w| w > 0.0));
    /// assert!(model.set_material_model("ball", MaterialModel::Corotated).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn set_material_model(&mut self, body: &str, model: crate::base::MaterialModel) -> Result<(), InputError> {
        let k = self
            .bodies
            .iter()
            .position(|b| b.name == body)
            .ok_or_else(|| InputError::new(format!("no body named '{body}'")))?;
        // Every tet's Young's modulus as it stands (per-tet values included).
        let e: Vec<f64> = (0..self.tets.len())
            .map(
                |t| match self.hyper.as_ref().and_then(|h| h.position(t).map(|i| h.lame[i])) {
                    Some(l) => l.mu * (3.0 * l.lambda + 2.0 * l.mu) / (l.lambda + l.mu),
                    None => {
                        let nu = self
                            .bodies
                            .iter()
                            .find(|b| b.tets.contains(&t))
                            .map_or(0.0, |b| b.material.poisson_ratio);
                        self.w_rot[t] * (1.0 + nu) / self.fem.geometry[t].volume
                    }
                },
            )
            .collect();
        self.bodies[k].model = model;
        let mut hyper = HyperTets {
            tets: Vec::new(),
            energy: Vec::new(),
            lame: Vec::new(),
            weight: Vec::new(),
        };
        for b in &self.bodies {
            let energy = HyperTets::energy_of(b.model);
            for t in b.tets.clone() {
                let vol = self.fem.geometry[t].volume;
                let m = crate::base::Material {
                    youngs_modulus: e[t],
                    poisson_ratio: b.material.poisson_ratio,
                };
                match energy {
                    Some(en) => {
                        hyper.push(t, en, m, vol);
                        self.w_rot[t] = 0.0;
                        self.w_vol[t] = 0.0;
                    }
                    None => {
                        self.w_rot[t] = m.rotation_stiffness() * vol;
                        self.w_vol[t] = if b.volume_constraint {
                            m.volume_stiffness() * vol
                        } else {
                            0.0
                        };
                    }
                }
            }
        }
        self.hyper = (!hyper.is_empty()).then_some(hyper);
        Ok(())
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
    #[inline(always)]
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
