//! Assembling a [`Model`] from bodies, cloth, obstacles and gravity, with validation.

use nalgebra::Vector3;
use serde::Serialize;

use super::Attachment;
use super::{HyperTets, Model, VertexTets};
use crate::actuator::{ActuatorSpec, Actuators};
use crate::base::{Body, InputError, Material, MaterialModel};
use crate::cloth::ClothSpec;
use crate::contact::pair::{BodyCollision, Colliders};
use crate::contact::Obstacle;
use crate::fem::{Coefficient, FemOperators};
use crate::mesh::TetMesh;
use crate::skeleton::{BoneSpec, Skeleton};

/// How a body's mass is given.
///
/// ```
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
///
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let total = |mass: MassSpec| -> Result<f64, Box<dyn std::error::Error>> {
///     let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
///     let model = ModelBuilder::new().body(BodySpec::new("box", mesh, material, mass)).build()?;
///     Ok(model.mass().iter().sum())
/// };
/// assert!((total(MassSpec::Density(1000.0))? - 1.0).abs() < 1e-12); // 1000 kg/m^3 x 1e-3 m^3
/// assert!((total(MassSpec::Total(2.5))? - 2.5).abs() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
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
    /// The constitutive model of the material (default projective).
    pub model: MaterialModel,
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
    ///
    /// ```
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
    /// let mut spec = BodySpec::new("box", mesh, material, MassSpec::Density(1000.0));
    /// assert!(spec.gravity && spec.volume_constraint && spec.fixed.is_empty());
    /// spec.fixed = vec![0, 1]; // body numbering
    /// let model = ModelBuilder::new().body(spec).build()?;
    /// assert_eq!(model.fixed().iter().filter(|&&f| f).count(), 2);
    /// assert_eq!(model.bodies()[0].name, "box");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(name: &str, mesh: TetMesh, material: Material, mass: MassSpec) -> Self {
        Self {
            name: name.to_string(),
            mesh,
            material,
            model: MaterialModel::Projective,
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

/// Smallest thickness of a triangle-mesh obstacle, relative to the bodies' length scale: well
/// above the round-off of a contact solve (a cube resting on a plate of thickness 1e-12 m fell
/// through it; 1e-9 m held).
pub const MIN_MESH_THICKNESS: f64 = 1e-6;

/// Builds a [`Model`] from bodies, obstacles and gravity.
#[derive(Debug, Default)]
pub struct ModelBuilder {
    pub(super) bodies: Vec<BodySpec>,
    pub(super) cloths: Vec<ClothSpec>,
    pub(super) obstacles: Vec<Obstacle>,
    pub(super) gravity: Vector3<f64>,
    pub(super) collision: Option<BodyCollision>,
}

impl ModelBuilder {
    /// An empty model with no gravity.
    ///
    /// ```
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
    /// use nalgebra::Vector3;
    ///
    /// // Nothing to simulate yet.
    /// assert!(ModelBuilder::new().build().is_err());
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
    /// let model = ModelBuilder::new()
    ///     .gravity(Vector3::new(0.0, -9.81, 0.0))
    ///     .body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0)))
    ///     .build()?;
    /// assert_eq!(model.accel()[0], Vector3::new(0.0, -9.81, 0.0));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
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
    ///
    /// ```
    /// use diffsoft::contact::Obstacle;
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
    /// use nalgebra::Vector3;
    ///
    /// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
    /// let a = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let b = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1]).origin([0.0, 0.5, 0.0]).build()?;
    /// let model = ModelBuilder::new()
    ///     .body(BodySpec::new("a", a, material, MassSpec::Density(1000.0)))
    ///     .body(BodySpec::new("b", b, material, MassSpec::Total(1.0)))
    ///     .obstacle(Obstacle::plane("ground", Vector3::zeros(), Vector3::y(), 0.5))
    ///     .build()?;
    /// // One global numbering: body b's vertices follow body a's.
    /// assert_eq!(model.n(), 8 + 12);
    /// assert_eq!(model.bodies()[1].vertices, 8..20);
    /// assert_eq!(model.tets().len(), 6 + 12);
    /// assert_eq!(model.obstacles().len(), 1);
    ///
    /// // Invalid input is refused with a message that names the body.
    /// let bad = Material { youngs_modulus: -1.0, poisson_ratio: 0.3 };
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let soft = BodySpec::new("soft", mesh, bad, MassSpec::Density(1000.0));
    /// let err = ModelBuilder::new().body(soft).build().unwrap_err();
    /// assert!(err.message().contains("soft"));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn build(mut self) -> Result<Model, InputError> {
        if self.bodies.is_empty() && self.cloths.is_empty() {
            return Err(InputError::new("the scene has no bodies"));
        }
        if !self.gravity.iter().all(|g| g.is_finite()) {
            return Err(InputError::new(format!(
                "gravity must be finite, got {:?}",
                self.gravity
            )));
        }
        // Names address bodies in parameters, logs and outputs: each names one body.
        let mut names = std::collections::HashSet::new();
        for name in self
            .bodies
            .iter()
            .map(|b| &b.name)
            .chain(self.cloths.iter().map(|c| &c.name))
        {
            crate::base::check_name("body", name)?;
            if !names.insert(name.as_str()) {
                return Err(InputError::new(format!("body name '{name}' is used twice")));
            }
        }
        let mut obstacle_names = std::collections::HashSet::new();
        for o in &self.obstacles {
            crate::base::check_name("obstacle", &o.name)?;
            if !obstacle_names.insert(o.name.as_str()) {
                return Err(InputError::new(format!("obstacle name '{}' is used twice", o.name)));
            }
        }
        let mut rest = Vec::new();
        let mut tets = Vec::new();
        let mut w_rot = Vec::new();
        let mut w_vol = Vec::new();
        let mut hyper = HyperTets {
            tets: Vec::new(),
            energy: Vec::new(),
            lame: Vec::new(),
            weight: Vec::new(),
        };
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
                return Err(InputError::new(format!(
                    "body '{}': initial velocity must be finite",
                    b.name
                )));
            }
            let v0 = rest.len();
            let t0 = tets.len();
            let nb = b.mesh.num_vertices();
            let fem = FemOperators::new(&b.mesh).map_err(|e| InputError::new(format!("body '{}': {e}", b.name)))?;
            let total_volume = fem.total_volume();
            let rho = match b.mass {
                MassSpec::Density(rho) => rho,
                MassSpec::Total(m) => m / total_volume,
            };
            if !(rho.is_finite() && rho > 0.0) {
                let given = match b.mass {
                    MassSpec::Density(rho) => format!("density {}", crate::base::number(rho)),
                    MassSpec::Total(m) => format!(
                        "total mass {}, over a volume of {} (density {})",
                        crate::base::number(m),
                        crate::base::number(total_volume),
                        crate::base::number(rho)
                    ),
                };
                return Err(InputError::new(format!(
                    "body '{}': density and total mass must be finite and positive ({given})",
                    b.name
                )));
            }
            let m = fem.lumped_mass(Coefficient::Uniform(rho)).expect("density validated");
            let body_mass: f64 = m.iter().sum();
            mass.extend(m);
            let energy = HyperTets::energy_of(b.model);
            for (k, g) in fem.geometry.iter().enumerate() {
                volumes.push(g.volume);
                if let Some(e) = energy {
                    // A hyperelastic tet: no projective constraint (Eq. H6).
                    hyper.push(t0 + k, e, b.material, g.volume);
                    w_rot.push(0.0);
                    w_vol.push(0.0);
                    continue;
                }
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
                    return Err(InputError::new(format!(
                        "body '{}': fixed vertex {v} out of range ({nb} vertices)",
                        b.name
                    )));
                }
                is_fixed[v] = true;
            }
            fixed.extend(is_fixed);
            let mut is_attached = vec![false; nb];
            for &(v, w) in &b.attachments {
                if v >= nb {
                    return Err(InputError::new(format!(
                        "body '{}': attached vertex {v} out of range ({nb} vertices)",
                        b.name
                    )));
                }
                if std::mem::replace(&mut is_attached[v], true) {
                    return Err(InputError::new(format!(
                        "body '{}': vertex {v} is attached twice (two attachments of one vertex add their stiffnesses; attach it once, with the stiffness wanted)",
                        b.name
                    )));
                }
                if !(w.is_finite() && w > 0.0) {
                    return Err(InputError::new(format!(
                        "body '{}': attachment stiffness must be finite and positive, got {}",
                        b.name,
                        crate::base::number(w)
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
                        return Err(InputError::new(format!(
                            "body '{}', bone '{}': vertex {v} out of range ({nb} vertices)",
                            b.name, bone.name
                        )));
                    }
                    if b.fixed.contains(v) {
                        return Err(InputError::new(format!(
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
                model: b.model,
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
            return Err(InputError::new("every vertex is fixed: nothing to simulate"));
        }
        for o in &self.obstacles {
            o.validate()?;
        }
        let all = TetMesh {
            vertices: rest.clone(),
            tets: tets.clone(),
        };
        let mut fem = FemOperators::new(&all).map_err(|e| InputError::new(e.to_string()))?;
        let cloth = cloth_parts.map(|c| c.assemble(&mut fem, &rest));
        let (lo, hi) = all.bounding_box();
        let length_scale = (hi - lo).norm().max(f64::MIN_POSITIVE);
        for o in &self.obstacles {
            // A mesh obstacle is two-sided: a vertex resting on a zero-thickness surface is on
            // neither side, and round-off can put it on the far side, through the surface.
            let min = MIN_MESH_THICKNESS * length_scale;
            if o.shape.two_sided() && o.thickness < min {
                return Err(InputError::new(format!(
                    "obstacle '{}': a triangle-mesh obstacle is two-sided, so its thickness must be at least {MIN_MESH_THICKNESS:e} x the bodies' length scale ({min:.3e} m) for vertices resting on it to stay on their side despite round-off; got {} (the paper's scenes use 1e-4 m)",
                    o.name, o.thickness
                )));
            }
            if o.thickness >= length_scale {
                return Err(too_thick(&format!("obstacle '{}'", o.name), o.thickness, length_scale));
            }
        }
        if let Some(c) = &self.collision {
            if c.thickness >= length_scale {
                return Err(too_thick("the collisions between bodies", c.thickness, length_scale));
            }
            // Refused here, where the scene's file is named, rather than when a run is set up.
            if let Some(b) = bones.first() {
                return Err(InputError::new(format!(
                    "collisions between bodies are not supported with a skeleton yet (bone '{}'): remove the scene's collisions or the skeleton",
                    b.name
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
            hyper: (!hyper.is_empty()).then_some(hyper),
        })
    }
}

/// The error for a contact thickness of `what` as large as the bodies themselves: every vertex
/// would start inside it, and the first step would push the bodies out by that distance.
fn too_thick(what: &str, thickness: f64, length_scale: f64) -> InputError {
    InputError::new(format!(
        "{what}: thickness {} m is not smaller than the bodies' length scale (the diagonal of their bounding box, {} m): every vertex would start within it; a contact thickness is a small gap (the paper's scenes use 1e-4 to 1.5e-2 m)",
        crate::base::number(thickness),
        crate::base::number(length_scale)
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::pair::BodyCollision;
    use crate::mesh::generate::BoxSpec;

    fn cube(name: &str, y: f64) -> BodySpec {
        let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1])
            .origin([0.0, y, 0.0])
            .build()
            .unwrap();
        let m = Material {
            youngs_modulus: 1e5,
            poisson_ratio: 0.3,
        };
        BodySpec::new(name, mesh, m, MassSpec::Density(1000.0))
    }

    /// A contact thickness as large as the bodies (bounding-box diagonal 0.33 m for two cubes
    /// of 0.1 m, 0.2 m apart) is refused naming what it belongs to; a small one builds.
    #[test]
    fn a_contact_thickness_as_large_as_the_bodies_is_refused() {
        let ground = |t: f64| {
            let mut g = Obstacle::plane("ground", Vector3::zeros(), Vector3::y(), 0.5);
            g.thickness = t;
            g
        };
        let pair = |t: f64| BodyCollision {
            thickness: t,
            friction: 0.3,
        };
        let build = |g: f64, c: f64| {
            ModelBuilder::new()
                .body(cube("a", 0.0))
                .body(cube("b", 0.2))
                .obstacle(ground(g))
                .collisions(pair(c))
                .build()
        };
        build(1e-3, 1e-3).unwrap();
        let e = build(1.0, 1e-3).unwrap_err().to_string();
        assert!(
            e.contains("obstacle 'ground': thickness 1 m is not smaller than the bodies' length scale"),
            "{e}"
        );
        let e = build(1e-3, 1e300).unwrap_err().to_string();
        assert!(e.contains("the collisions between bodies: thickness 1e300 m"), "{e}");
        // With a skeleton, collisions between bodies are refused when the model is built.
        let mut a = cube("a", 0.0);
        a.bones.push(crate::skeleton::BoneSpec {
            name: "root".into(),
            parent: None,
            joint: Box::new(crate::skeleton::free::Free::default()),
            vertices: vec![0],
            torque: None,
        });
        let e = ModelBuilder::new()
            .body(a)
            .body(cube("b", 0.2))
            .collisions(pair(1e-3))
            .build()
            .unwrap_err()
            .to_string();
        assert!(e.contains("not supported with a skeleton yet (bone 'root')"), "{e}");
    }
}
