//! The static data of a simulation: bodies (tet meshes with material and mass), constraint
//! weights, attachments, Dirichlet vertices, external accelerations and obstacles. Built once by
//! [`ModelBuilder`]; the [`Simulator`](super::Simulator) never changes it.

use std::ops::Range;

use nalgebra::Vector3;
use serde::Serialize;

use super::SolverError;
use crate::actuator::{ActuatorKind, ActuatorSpec, Actuators};
use crate::cloth::{Bends, Cloth, ClothBody, ClothSpec, Incidence};
use crate::constraint::attachment::Attachment;
use crate::contact::pair::{BodyCollision, Colliders};
use crate::contact::Obstacle;
use crate::fem::{Coefficient, FemOperators};
use crate::mesh::TetMesh;
use crate::skeleton::{BoneSpec, Skeleton};

/// Elastic material of a body.
///
/// Weights follow the paper's reference implementation (METHOD.md section 2): per tet, a
/// corotated constraint with weight `E/(1+nu) V` and a volume constraint with weight
/// `nu E/(1+nu) V`, both on the deformation gradient. For small strains this is linear
/// elasticity with shear modulus `mu = E/(2(1+nu))` and an extra volumetric stiffness; with
/// `nu = 0` it is exactly linear elasticity with Young's modulus `E` and `lambda = 0`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Material {
    /// Young's modulus (Pa).
    pub youngs_modulus: f64,
    /// Poisson ratio, in `[0, 0.5)`.
    pub poisson_ratio: f64,
}

impl Material {
    /// Check the parameters are physically meaningful.
    pub fn validate(&self, body: &str) -> Result<(), SolverError> {
        if !(self.youngs_modulus.is_finite() && self.youngs_modulus > 0.0) {
            return Err(SolverError::Input(format!(
                "body '{body}': Young's modulus must be finite and positive, got {}",
                self.youngs_modulus
            )));
        }
        if !(0.0..0.5).contains(&self.poisson_ratio) {
            return Err(SolverError::Input(format!(
                "body '{body}': Poisson ratio must be in [0, 0.5), got {}",
                self.poisson_ratio
            )));
        }
        Ok(())
    }

    /// Corotated weight per unit volume, `E / (1 + nu)`.
    pub fn rotation_stiffness(&self) -> f64 {
        self.youngs_modulus / (1.0 + self.poisson_ratio)
    }

    /// Volume weight per unit volume, `nu E / (1 + nu)`.
    pub fn volume_stiffness(&self) -> f64 {
        self.poisson_ratio * self.youngs_modulus / (1.0 + self.poisson_ratio)
    }
}

/// How a body's mass is given.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MassSpec {
    /// Density (kg/m^3), lumped `rho V / 4` per tet corner.
    Density(f64),
    /// Total mass (kg), lumped by volume (the paper's "Mass").
    Total(f64),
}

/// One body as given to the builder.
#[derive(Debug)]
pub struct BodySpec {
    /// Name (reports, output files).
    pub name: String,
    /// The mesh in simulation coordinates (already scaled / placed).
    pub mesh: TetMesh,
    /// Material.
    pub material: Material,
    /// Mass.
    pub mass: MassSpec,
    /// Whether gravity acts on the body.
    pub gravity: bool,
    /// Initial velocity of every vertex.
    pub initial_velocity: Vector3<f64>,
    /// Vertices held fixed at their rest position (Dirichlet), body numbering.
    pub fixed: Vec<usize>,
    /// Penalty attachments to the rest position: (vertex, weight), body numbering.
    pub attachments: Vec<(usize, f64)>,
    /// Enable the volume constraint (weight `nu E/(1+nu) V`).
    pub volume_constraint: bool,
    /// Bones embedded in the body (vertex indices and parents are body-local).
    pub bones: Vec<BoneSpec>,
    /// Actuator groups (tets are body-local).
    pub actuators: Vec<ActuatorSpec>,
}

impl BodySpec {
    /// A body with gravity, zero initial velocity, no pins and the volume constraint on.
    pub fn new(name: &str, mesh: TetMesh, material: Material, mass: MassSpec) -> Self {
        Self {
            name: name.to_string(),
            mesh,
            material,
            mass,
            gravity: true,
            initial_velocity: Vector3::zeros(),
            fixed: Vec::new(),
            attachments: Vec::new(),
            volume_constraint: true,
            bones: Vec::new(),
            actuators: Vec::new(),
        }
    }
}

/// Where a body lives in the assembled system.
#[derive(Debug, Clone, Serialize)]
pub struct Body {
    /// Name.
    pub name: String,
    /// Its vertices in the global numbering.
    pub vertices: Range<usize>,
    /// Its tets in the global numbering.
    pub tets: Range<usize>,
    /// Material.
    pub material: Material,
    /// Total mass.
    pub mass: f64,
    /// Density (kg/m^3; for a total-mass body, mass / volume).
    pub density: f64,
    /// Whether gravity acts on it.
    pub gravity: bool,
    /// Whether its volume constraint is on.
    pub volume_constraint: bool,
}

/// For each vertex, the tets that contain it and its local index there (CSR).
#[derive(Debug, Clone)]
pub struct VertexTets {
    /// Offsets, length `n + 1`.
    pub offsets: Vec<usize>,
    /// `(tet, local corner)` pairs.
    pub entries: Vec<(u32, u8)>,
}

impl VertexTets {
    fn new(n: usize, tets: &[[usize; 4]]) -> Self {
        let mut count = vec![0usize; n + 1];
        for t in tets {
            for &v in t {
                count[v + 1] += 1;
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut entries = vec![(0u32, 0u8); count[n]];
        for (ti, t) in tets.iter().enumerate() {
            for (a, &v) in t.iter().enumerate() {
                entries[fill[v]] = (ti as u32, a as u8);
                fill[v] += 1;
            }
        }
        Self {
            offsets: count,
            entries,
        }
    }

    /// The `(tet, corner)` pairs of vertex `v`.
    pub fn of(&self, v: usize) -> &[(u32, u8)] {
        &self.entries[self.offsets[v]..self.offsets[v + 1]]
    }
}

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

/// Smallest thickness of a triangle-mesh obstacle, relative to the bodies' length scale: well
/// above the round-off of a contact solve (a cube resting on a plate of thickness 1e-12 m fell
/// through it; 1e-9 m held).
pub const MIN_MESH_THICKNESS: f64 = 1e-6;

/// Builds a [`Model`] from bodies, obstacles and gravity.
#[derive(Debug, Default)]
pub struct ModelBuilder {
    bodies: Vec<BodySpec>,
    cloths: Vec<ClothSpec>,
    obstacles: Vec<Obstacle>,
    gravity: Vector3<f64>,
    collision: Option<BodyCollision>,
}

impl ModelBuilder {
    /// An empty model with no gravity.
    pub fn new() -> Self {
        Self::default()
    }

    /// Gravitational acceleration (m/s^2), applied to bodies with `gravity` enabled.
    pub fn gravity(mut self, g: Vector3<f64>) -> Self {
        self.gravity = g;
        self
    }

    /// Add a body.
    pub fn body(mut self, b: BodySpec) -> Self {
        self.bodies.push(b);
        self
    }

    /// Add a cloth body.
    pub fn cloth(mut self, c: ClothSpec) -> Self {
        self.cloths.push(c);
        self
    }

    /// Let the bodies (soft and cloth) collide with each other, keeping `thickness` apart, with
    /// Coulomb friction `friction`.
    pub fn collisions(mut self, c: BodyCollision) -> Self {
        self.collision = Some(c);
        self
    }

    /// Add an obstacle.
    pub fn obstacle(mut self, o: Obstacle) -> Self {
        self.obstacles.push(o);
        self
    }

    /// Validate and assemble.
    pub fn build(mut self) -> Result<Model, SolverError> {
        if self.bodies.is_empty() && self.cloths.is_empty() {
            return Err(SolverError::Input("the scene has no bodies".into()));
        }
        if !self.gravity.iter().all(|g| g.is_finite()) {
            return Err(SolverError::Input(format!(
                "gravity must be finite, got {:?}",
                self.gravity
            )));
        }
        let mut rest = Vec::new();
        let mut tets = Vec::new();
        let mut w_rot = Vec::new();
        let mut w_vol = Vec::new();
        let mut bodies = Vec::new();
        let mut initial_velocity = Vec::new();
        let mut accel = Vec::new();
        let mut fixed = Vec::new();
        let mut attachments = Vec::new();
        let mut mass = Vec::new();
        let mut bones: Vec<BoneSpec> = Vec::new();
        let mut actuators = Actuators {
            groups: Vec::new(),
            cells: Vec::new(),
        };
        let mut volumes = Vec::new();
        for b in &mut self.bodies {
            b.material.validate(&b.name)?;
            if !b.initial_velocity.iter().all(|v| v.is_finite()) {
                return Err(SolverError::Input(format!(
                    "body '{}': initial velocity must be finite",
                    b.name
                )));
            }
            let v0 = rest.len();
            let t0 = tets.len();
            let nb = b.mesh.num_vertices();
            let fem = FemOperators::new(&b.mesh).map_err(|e| SolverError::Input(format!("body '{}': {e}", b.name)))?;
            let total_volume = fem.total_volume();
            let rho = match b.mass {
                MassSpec::Density(rho) => rho,
                MassSpec::Total(m) => m / total_volume,
            };
            if !(rho.is_finite() && rho > 0.0) {
                return Err(SolverError::Input(format!(
                    "body '{}': density and total mass must be finite and positive (density {rho})",
                    b.name
                )));
            }
            let m = fem.lumped_mass(Coefficient::Uniform(rho)).expect("density validated");
            let body_mass: f64 = m.iter().sum();
            mass.extend(m);
            for g in &fem.geometry {
                volumes.push(g.volume);
                w_rot.push(b.material.rotation_stiffness() * g.volume);
                w_vol.push(if b.volume_constraint {
                    b.material.volume_stiffness() * g.volume
                } else {
                    0.0
                });
            }
            rest.extend(b.mesh.vertices.iter().copied());
            tets.extend(b.mesh.tets.iter().map(|t| t.map(|i| i + v0)));
            initial_velocity.extend(std::iter::repeat_n(b.initial_velocity, nb));
            accel.extend(std::iter::repeat_n(
                if b.gravity { self.gravity } else { Vector3::zeros() },
                nb,
            ));
            let mut is_fixed = vec![false; nb];
            for &v in &b.fixed {
                if v >= nb {
                    return Err(SolverError::Input(format!(
                        "body '{}': fixed vertex {v} out of range ({nb} vertices)",
                        b.name
                    )));
                }
                is_fixed[v] = true;
            }
            fixed.extend(is_fixed);
            for &(v, w) in &b.attachments {
                if v >= nb {
                    return Err(SolverError::Input(format!(
                        "body '{}': attached vertex {v} out of range ({nb} vertices)",
                        b.name
                    )));
                }
                if !(w.is_finite() && w > 0.0) {
                    return Err(SolverError::Input(format!(
                        "body '{}': attachment stiffness must be finite and positive, got {w}",
                        b.name
                    )));
                }
                attachments.push(Attachment {
                    vertex: v + v0,
                    target: b.mesh.vertices[v],
                    weight: w,
                });
            }
            let bone0 = bones.len();
            for mut bone in std::mem::take(&mut b.bones) {
                for v in &mut bone.vertices {
                    if *v >= nb {
                        return Err(SolverError::Input(format!(
                            "body '{}', bone '{}': vertex {v} out of range ({nb} vertices)",
                            b.name, bone.name
                        )));
                    }
                    if b.fixed.contains(v) {
                        return Err(SolverError::Input(format!(
                            "body '{}', bone '{}': vertex {v} is also a fixed (Dirichlet) vertex",
                            b.name, bone.name
                        )));
                    }
                    *v += v0;
                }
                bone.parent = bone.parent.map(|p| p + bone0);
                bones.push(bone);
            }
            actuators.push_body(
                &b.name,
                std::mem::take(&mut b.actuators),
                t0,
                b.mesh.num_tets(),
                &volumes,
            )?;
            bodies.push(Body {
                name: b.name.clone(),
                vertices: v0..v0 + nb,
                tets: t0..t0 + b.mesh.num_tets(),
                material: b.material,
                mass: body_mass,
                density: rho,
                gravity: b.gravity,
                volume_constraint: b.volume_constraint,
            });
        }
        let cloth_parts = self.add_cloth(
            &mut rest,
            &mut initial_velocity,
            &mut accel,
            &mut fixed,
            &mut attachments,
            &mut mass,
        )?;
        if fixed.iter().all(|&f| f) {
            return Err(SolverError::Input("every vertex is fixed: nothing to simulate".into()));
        }
        for o in &self.obstacles {
            o.validate()?;
        }
        let all = TetMesh {
            vertices: rest.clone(),
            tets: tets.clone(),
        };
        let mut fem = FemOperators::new(&all).map_err(|e| SolverError::Input(e.to_string()))?;
        let cloth = cloth_parts.map(|c| c.assemble(&mut fem, &rest));
        let (lo, hi) = all.bounding_box();
        let length_scale = (hi - lo).norm().max(f64::MIN_POSITIVE);
        for o in &self.obstacles {
            // A mesh obstacle is two-sided: a vertex resting on a zero-thickness surface is on
            // neither side, and round-off can put it on the far side, through the surface.
            let min = MIN_MESH_THICKNESS * length_scale;
            if matches!(o.shape, crate::contact::Shape::TriMesh(_)) && o.thickness < min {
                return Err(SolverError::Input(format!(
                    "obstacle '{}': a triangle-mesh obstacle is two-sided, so its thickness must be at least {MIN_MESH_THICKNESS:e} x the bodies' length scale ({min:.3e} m) for vertices resting on it to stay on their side despite round-off; got {} (the paper's scenes use 1e-4 m)",
                    o.name, o.thickness
                )));
            }
        }
        let vertex_tets = VertexTets::new(rest.len(), &tets);
        let collision = match self.collision {
            Some(c) => Some(Colliders::new(c, &bodies, &tets, cloth.as_ref(), &fixed, &rest)?),
            None => None,
        };
        let skeleton = if bones.is_empty() {
            None
        } else {
            Some(Skeleton::new(bones, &rest)?)
        };
        Ok(Model {
            rest,
            initial_velocity,
            tets,
            fem,
            w_rot,
            w_vol,
            mass,
            accel,
            attachments,
            fixed,
            obstacles: self.obstacles,
            bodies,
            vertex_tets,
            skeleton,
            actuators: (!actuators.groups.is_empty()).then_some(actuators),
            cloth,
            collision,
            length_scale,
        })
    }

    /// Append the cloth bodies' vertices to the per-vertex arrays (after the soft bodies).
    fn add_cloth(
        &self,
        rest: &mut Vec<Vector3<f64>>,
        initial_velocity: &mut Vec<Vector3<f64>>,
        accel: &mut Vec<Vector3<f64>>,
        fixed: &mut Vec<bool>,
        attachments: &mut Vec<Attachment>,
        mass: &mut Vec<f64>,
    ) -> Result<Option<ClothParts>, SolverError> {
        if self.cloths.is_empty() {
            return Ok(None);
        }
        let mut parts = ClothParts::default();
        for c in &self.cloths {
            let p = crate::cloth::prepare(c)?;
            let v0 = rest.len();
            let nb = c.surface.vertices.len();
            let t0 = parts.triangles.len();
            let what = format!("cloth '{}'", c.name);
            let mut is_fixed = vec![false; nb];
            for &v in &c.fixed {
                if v >= nb {
                    return Err(SolverError::Input(format!(
                        "{what}: fixed vertex {v} out of range ({nb} vertices)"
                    )));
                }
                is_fixed[v] = true;
            }
            for &(v, w) in &c.attachments {
                if v >= nb {
                    return Err(SolverError::Input(format!(
                        "{what}: attached vertex {v} out of range ({nb} vertices)"
                    )));
                }
                if !(w.is_finite() && w > 0.0) {
                    return Err(SolverError::Input(format!(
                        "{what}: attachment stiffness must be finite and positive, got {w}"
                    )));
                }
                attachments.push(Attachment {
                    vertex: v + v0,
                    target: c.surface.vertices[v],
                    weight: w,
                });
            }
            fixed.extend(is_fixed);
            rest.extend(c.surface.vertices.iter().copied());
            initial_velocity.extend(std::iter::repeat_n(c.initial_velocity, nb));
            accel.extend(std::iter::repeat_n(
                if c.gravity { self.gravity } else { Vector3::zeros() },
                nb,
            ));
            let body_mass: f64 = p.mass.iter().sum();
            mass.extend(p.mass);
            for (tri, g) in c.surface.triangles.iter().zip(&p.geometry) {
                parts.triangles.push(tri.map(|v| v + v0));
                parts.w_stretch.push(c.stretching * g.area);
            }
            parts.geometry.extend(p.geometry);
            let bending_vertices = p.stencils.len();
            for (verts, coefs, area) in p.stencils {
                parts
                    .stencils
                    .push((verts.iter().map(|v| v + v0).collect(), coefs, c.bending * area));
            }
            parts.bodies.push(ClothBody {
                name: c.name.clone(),
                vertices: v0..v0 + nb,
                triangles: t0..parts.triangles.len(),
                stretching: c.stretching,
                bending: c.bending,
                area_density: c.area_density,
                mass: body_mass,
                area: p.area,
                bending_vertices,
            });
        }
        Ok(Some(parts))
    }
}

/// Cloth bodies gathered by the builder, before the pattern is known.
#[derive(Default)]
struct ClothParts {
    bodies: Vec<ClothBody>,
    triangles: Vec<[usize; 3]>,
    geometry: Vec<crate::cloth::TriangleGeometry>,
    w_stretch: Vec<f64>,
    /// (global vertices, coefficients, weight) per bending stencil.
    stencils: Vec<(Vec<usize>, Vec<f64>, f64)>,
}

impl ClothParts {
    /// Rebuild the stiffness pattern with the cloth's elements and assemble the cloth.
    fn assemble(self, fem: &mut FemOperators, rest: &[Vector3<f64>]) -> Cloth {
        let n = rest.len();
        let cliques: Vec<&[usize]> = self
            .triangles
            .iter()
            .map(|t| t.as_slice())
            .chain(self.stencils.iter().map(|s| s.0.as_slice()))
            .collect();
        let (pattern, slots) = crate::fem::StiffnessPattern::with_cliques(n, &fem.tets, &cliques);
        fem.pattern = pattern;
        let nt = self.triangles.len();
        let tri_slots = slots[..nt].iter().map(|s| std::array::from_fn(|k| s[k])).collect();
        let mut bends = Bends {
            offsets: vec![0],
            slot_offsets: vec![0],
            ..Default::default()
        };
        for ((verts, coefs, w), sl) in self.stencils.into_iter().zip(&slots[nt..]) {
            let (len, dir) = crate::cloth::rest_curvature(&verts, &coefs, rest);
            bends.vertices.extend(&verts);
            bends.coefs.extend(&coefs);
            bends.offsets.push(bends.vertices.len());
            bends.weight.push(w);
            bends.rest.push(len);
            bends.rest_dir.push(dir);
            bends.slots.extend(sl);
            bends.slot_offsets.push(bends.slots.len());
        }
        let vertex_triangles = Incidence::new(n, self.triangles.iter().map(|t| t.as_slice()));
        let vertex_bends = Incidence::new(
            n,
            (0..bends.len()).map(|i| &bends.vertices[bends.offsets[i]..bends.offsets[i + 1]]),
        );
        Cloth {
            bodies: self.bodies,
            triangles: self.triangles,
            geometry: self.geometry,
            w_stretch: self.w_stretch,
            bends,
            tri_slots,
            vertex_triangles,
            vertex_bends,
        }
    }
}
