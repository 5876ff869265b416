//! The gradient-check cases: a scene, a loss, the parameter groups to check and the
//! settings, with the built-in fixtures (free body, bridgesus, ground contact, actuated beam,
//! Baymax with torques, Baymax on the ground, ball on cloth) and the list `diffsoft gradcheck` runs.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::fixtures::{actuated_beam, ActuatedBeam};
use crate::actuator::ActuatorKind;
use crate::base::Material;
use crate::diff::loss::{CenterOfMass, JointAngle, Loss, Sum, VertexPositions};
use crate::diff::{self, Controls, DiffError, Gradient, Param};
use crate::mesh::generate::BoxSpec;
pub use crate::model::fixtures::ground_box;
use crate::model::{BodySpec, MassSpec, Model, ModelBuilder};
use crate::scene::{self, LoadOptions};
use crate::solver::{Settings, SolverKind};

/// A parameter group to check.
#[derive(Debug, Clone, PartialEq)]
pub enum Group {
    /// A named scalar.
    Scalar(Param),
    /// Every initial position (random direction).
    InitialPositions,
    /// Every initial velocity (random direction).
    InitialVelocities,
    /// Young's modulus per tet (random direction).
    YoungsPerTet,
    /// Every activation at every step (random direction).
    Activations,
    /// Every attachment target (random direction).
    AttachmentTargets,
    /// Every joint torque of a one-DoF joint at every step (random direction).
    Torques,
    /// One component of the initial velocity of one body's vertices (a uniform shift).
    BodyVelocity {
        /// Body name (reports).
        body: String,
        /// Its vertices (global numbering).
        vertices: std::ops::Range<usize>,
        /// Component (0, 1, 2).
        axis: usize,
    },
}

impl Group {
    /// Name in reports.
    pub fn name(&self) -> String {
        match self {
            Group::Scalar(p) => p.to_string(),
            Group::InitialPositions => "initial_positions (random direction)".into(),
            Group::InitialVelocities => "initial_velocities (random direction)".into(),
            Group::YoungsPerTet => "youngs_modulus per tet (random direction)".into(),
            Group::Activations => "activations per step and group (random direction)".into(),
            Group::AttachmentTargets => "attachment targets (random direction)".into(),
            Group::Torques => "joint torques per step and joint (random direction)".into(),
            Group::BodyVelocity { body, axis, .. } => {
                format!("initial_velocity.{} of {body}", ["x", "y", "z"][*axis])
            }
        }
    }
}

/// One scene of the gradient check.
pub struct Case {
    /// Name.
    pub name: String,
    /// What it covers.
    pub description: String,
    /// Model.
    pub model: Model,
    /// Settings (tolerance 0: a fixed number of iterations, so the forward is smooth).
    pub settings: Settings,
    /// Steps.
    pub steps: usize,
    /// Loss.
    pub loss: Box<dyn Loss>,
    /// Controls (initial state, activations).
    pub controls: Controls,
    /// Groups to check.
    pub groups: Vec<Group>,
}

/// A perturbation direction of a vector group: `x + e * scale * u`.
#[derive(Debug, Clone)]
pub struct Direction {
    /// The direction `u`, one entry per scalar of the group.
    pub u: Vec<f64>,
    /// The group's natural scale (its value, or the model's length scale).
    pub scale: f64,
}

fn initial_state(case: &Case) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
    case.controls
        .initial
        .clone()
        .unwrap_or_else(|| (case.model.rest.clone(), case.model.initial_velocity.clone()))
}

fn activations(case: &Case) -> Vec<Vec<f64>> {
    case.controls.activations.clone().unwrap_or_default()
}

/// The joint torques per step and coordinate: the case's controls, or the bones' schedules.
fn torques(case: &Case) -> Vec<Vec<f64>> {
    if let Some(t) = &case.controls.torques {
        return t.clone();
    }
    let Some(sk) = case.model.skeleton.as_ref() else {
        return Vec::new();
    };
    (0..case.steps)
        .map(|n| {
            let mut row = vec![0.0; sk.dofs];
            sk.torques((n + 1) as f64 * case.settings.dt, &mut row);
            row
        })
        .collect()
}

/// Whether coordinate `k` belongs to a one-DoF joint (the ones torques act on).
fn torque_coordinate(model: &Model, k: usize) -> bool {
    model
        .skeleton
        .as_ref()
        .is_some_and(|sk| sk.bones.iter().any(|b| b.joint.dofs() == 1 && b.dof_offset == k))
}

fn random_direction(len: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..len).map(|_| rng.random_range(-1.0..1.0)).collect()
}

impl Case {
    /// The case's loss and gradient over its steps, controls and loss, under `settings` (its
    /// own or a variant) and `opts`.
    pub fn gradient(&self, settings: &Settings, opts: diff::Options) -> Result<Gradient, DiffError> {
        diff::gradient(
            &self.model,
            settings,
            self.steps,
            &self.controls,
            self.loss.as_ref(),
            opts,
        )
    }

    /// A perturbation direction of `group`: the unit for a scalar, a random direction (from
    /// `seed`) for a vector group, with the group's scale.
    pub fn direction(&self, group: &Group, seed: u64) -> Direction {
        let m = &self.model;
        match group {
            Group::Scalar(p) => Direction {
                u: vec![1.0],
                scale: p.get(m).map_or(1.0, |v| if v == 0.0 { 1.0 } else { v.abs() }),
            },
            Group::InitialPositions => Direction {
                u: random_direction(3 * m.n(), seed),
                scale: m.length_scale,
            },
            Group::InitialVelocities => Direction {
                u: random_direction(3 * m.n(), seed),
                scale: initial_state(self).1.iter().map(|v| v.norm()).fold(1.0, f64::max),
            },
            Group::YoungsPerTet => Direction {
                u: random_direction(m.tets.len(), seed),
                scale: m.bodies.iter().map(|b| b.material.youngs_modulus).fold(0.0, f64::max),
            },
            Group::Activations => {
                // A muscle held at an end of its range [0, 1] is perturbed inwards only, so that
                // one side of every step stays valid (the check then differences on that side).
                let acts = activations(self);
                let mut u = random_direction(acts.iter().map(|r| r.len()).sum(), seed);
                let groups = m.actuators.as_ref().map(|a| a.groups.as_slice()).unwrap_or_default();
                for (x, (j, a)) in u.iter_mut().zip(acts.iter().flat_map(|r| r.iter().enumerate())) {
                    if groups.get(j).is_some_and(|g| g.kind == ActuatorKind::Muscle) {
                        if *a <= 0.0 {
                            *x = x.abs();
                        } else if *a >= 1.0 {
                            *x = -x.abs();
                        }
                    }
                }
                Direction { u, scale: 1.0 }
            }
            Group::AttachmentTargets => Direction {
                u: random_direction(3 * m.attachments.len(), seed),
                scale: m.length_scale,
            },
            Group::BodyVelocity { .. } => Direction {
                u: vec![1.0],
                scale: 1.0,
            },
            Group::Torques => {
                let t = torques(self);
                let dofs = t.first().map_or(0, |r| r.len());
                let mut u = random_direction(t.len() * dofs, seed);
                for (i, x) in u.iter_mut().enumerate() {
                    if !torque_coordinate(m, i % dofs.max(1)) {
                        *x = 0.0;
                    }
                }
                Direction {
                    u,
                    scale: t.iter().flatten().fold(1.0f64, |a, b| a.max(b.abs())),
                }
            }
        }
    }

    /// `g . (scale u)`.
    pub fn analytic(&self, group: &Group, g: &Gradient, d: &Direction) -> f64 {
        let m = &self.model;
        let dot3 = |v: &[Vector3<f64>]| -> f64 {
            v.iter()
                .flat_map(|x| x.iter().copied())
                .zip(&d.u)
                .map(|(a, b)| a * b)
                .sum::<f64>()
        };
        d.scale
            * match group {
                Group::Scalar(p) => p.derivative(m, g),
                Group::InitialPositions => dot3(&g.q0),
                Group::InitialVelocities => dot3(&g.v0),
                Group::YoungsPerTet => g.youngs_modulus(m).iter().zip(&d.u).map(|(a, b)| a * b).sum(),
                Group::Activations => g.activations.iter().flatten().zip(&d.u).map(|(a, b)| a * b).sum(),
                Group::AttachmentTargets => dot3(&g.attachment_targets),
                Group::Torques => g.torques.iter().flatten().zip(&d.u).map(|(a, b)| a * b).sum(),
                Group::BodyVelocity { vertices, axis, .. } => g.v0[vertices.clone()].iter().map(|v| v[*axis]).sum(),
            }
    }

    /// The loss at `x + e scale u`.
    pub fn loss_at(&self, group: &Group, d: &Direction, e: f64) -> Result<f64, DiffError> {
        let mut model = self.model.clone();
        let mut controls = self.controls.clone();
        let step = e * d.scale;
        let shift3 = |v: &mut [Vector3<f64>]| {
            for (k, x) in v.iter_mut().enumerate() {
                for a in 0..3 {
                    x[a] += step * d.u[3 * k + a];
                }
            }
        };
        match group {
            Group::Scalar(p) => {
                let x = p.get(&model)?;
                p.set(&mut model, x + step)?;
            }
            Group::InitialPositions | Group::InitialVelocities => {
                let (mut q, mut v) = initial_state(self);
                if *group == Group::InitialPositions {
                    shift3(&mut q);
                } else {
                    shift3(&mut v);
                }
                controls.initial = Some((q, v));
            }
            Group::YoungsPerTet => {
                let mut e = crate::diff::params::youngs_modulus_per_tet(&model);
                for (x, u) in e.iter_mut().zip(&d.u) {
                    *x += step * u;
                }
                crate::diff::params::set_youngs_modulus_per_tet(&mut model, &e)?;
            }
            Group::Activations => {
                let mut a = activations(self);
                for (x, u) in a.iter_mut().flatten().zip(&d.u) {
                    *x += step * u;
                }
                controls.activations = Some(a);
            }
            Group::BodyVelocity { vertices, axis, .. } => {
                let (q, mut v) = initial_state(self);
                for x in &mut v[vertices.clone()] {
                    x[*axis] += step;
                }
                controls.initial = Some((q, v));
            }
            Group::Torques => {
                let mut t = torques(self);
                for (x, u) in t.iter_mut().flatten().zip(&d.u) {
                    *x += step * u;
                }
                controls.torques = Some(t);
            }
            Group::AttachmentTargets => {
                let mut t: Vec<Vector3<f64>> = model.attachments.iter().map(|a| a.target).collect();
                shift3(&mut t);
                for (a, x) in model.attachments.iter_mut().zip(t) {
                    a.target = x;
                }
            }
        }
        diff::loss_value(&model, &self.settings, self.steps, &controls, self.loss.as_ref())
    }
}

/// The settings of a gradient check at time step `dt`: the direct solver with a fixed number of
/// local-global iterations (tolerance 0), so the forward pass is a smooth function of its inputs.
pub fn gradcheck_settings(dt: f64, iterations: usize) -> Settings {
    Settings {
        dt,
        solver: SolverKind::Direct,
        tolerance: 0.0,
        max_iterations: iterations,
        inner_tolerance: 1e-15,
        inner_max_iterations: 100_000,
        ..Settings::default()
    }
}

/// A free soft body: a jittered box spinning and stretching in flight (no pins, no contact).
pub fn free_body(steps: usize) -> Result<Case> {
    let mesh = BoxSpec::new([3, 2, 2], [0.3, 0.2, 0.2]).jitter(0.1, 3).build()?;
    let body = BodySpec::new(
        "box",
        mesh,
        Material {
            youngs_modulus: 2e4,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(1000.0),
    );
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .build()?;
    // Spin about z and stretch along x: the body deforms, so the material matters.
    let c = Vector3::new(0.15, 0.1, 0.1);
    let v: Vec<Vector3<f64>> = model
        .rest
        .iter()
        .map(|x| {
            let r = x - c;
            Vector3::new(0.5, 0.2, 0.0) + Vector3::new(-r.y, r.x, 0.0) * 6.0 + Vector3::new(r.x, 0.0, 0.0) * 4.0
        })
        .collect();
    let corner = (0..model.n())
        .max_by(|&a, &b| model.rest[a].sum().total_cmp(&model.rest[b].sum()))
        .unwrap_or(0);
    Ok(Case {
        name: "free_body".into(),
        description: "free soft box (3x2x2 cells, 60 tets) spinning and stretching under gravity; loss: final position of its far corner".into(),
        controls: Controls {
            initial: Some((model.rest.clone(), v)),
            ..Controls::default()
        },
        loss: Box::new(VertexPositions {
            terms: vec![(corner, Vector3::new(1.0, 0.5, 0.25))],
        }),
        model,
        settings: gradcheck_settings(0.01, 10),
        steps,
        groups: vec![
            Group::Scalar(Param::YOUNGS_MODULUS),
            Group::Scalar(Param::POISSON_RATIO),
            Group::Scalar(Param::DENSITY),
            Group::InitialPositions,
            Group::InitialVelocities,
            Group::YoungsPerTet,
        ],
    })
}

/// The paper's bridgesus scene (Dirichlet-pinned ends, gravity -100): material parameters for
/// system identification; loss: final height of the barycentre.
pub fn bridgesus(scene_path: &Path, steps: usize) -> Result<Case> {
    let sc = scene::load(scene_path, LoadOptions::default()).with_context(|| scene_path.display().to_string())?;
    let settings = gradcheck_settings(sc.settings.dt, sc.settings.max_iterations.min(30));
    Ok(Case {
        name: "bridgesus".into(),
        description: format!(
            "the paper's bridgesus ({} vertices, {} tets, pinned ends, gravity -100); loss: final barycentre height",
            sc.model.n(),
            sc.model.tets.len()
        ),
        model: sc.model,
        settings,
        steps,
        loss: Box::new(CenterOfMass {
            direction: Vector3::y(),
            time_average: false,
            vertices: None,
        }),
        controls: Controls::default(),
        groups: vec![
            Group::Scalar(Param::YOUNGS_MODULUS),
            Group::Scalar(Param::POISSON_RATIO),
            Group::Scalar(Param::DENSITY),
            Group::Scalar(Param::GRAVITY_Y),
            Group::YoungsPerTet,
        ],
    })
}

/// A soft box thrown onto frictional ground (mu 0.5): it lands, slides and sticks.
pub fn ground_contact(steps: usize) -> Result<Case> {
    let model = ground_box(0.5)?;
    Ok(Case {
        name: "ground_contact".into(),
        description:
            "soft box (60 tets) thrown onto ground with friction 0.5: lands, slides, sticks; loss: final barycentre x"
                .into(),
        model,
        settings: gradcheck_settings(0.01, 10),
        steps,
        loss: Box::new(CenterOfMass {
            direction: Vector3::x(),
            time_average: false,
            vertices: None,
        }),
        controls: Controls::default(),
        groups: vec![
            Group::Scalar(Param::YOUNGS_MODULUS),
            Group::Scalar(Param::DENSITY),
            Group::Scalar(Param::INITIAL_VELOCITY_X),
            Group::Scalar(Param::INITIAL_VELOCITY_Y),
            Group::Scalar(Param::GRAVITY_Y),
            Group::InitialPositions,
        ],
    })
}

/// A soft box dropped onto a cloth held at its corners by attachment springs: both deform, and
/// the box's vertices and the cloth's collide (vertex-face pairs in both directions, friction).
/// The loss is a weighted sum of the box's final barycentre coordinates.
pub fn ball_on_cloth(steps: usize) -> Result<Case> {
    let n = 6;
    let id = |i: usize, j: usize| j * (n + 1) + i;
    let corners = [id(0, 0), id(n, 0), id(0, n), id(n, n)];
    let mut cloth = crate::cloth::ClothSpec::new("cloth", crate::cloth::grid(n, 0.6), 200.0, 5e-4, 3.0);
    cloth.attachments = corners.iter().map(|&v| (v, 1e4)).collect();
    // Jitter moves vertices up to a tenth of a cell (8 mm): the box starts that much higher, so
    // that none of it starts through the cloth (it did by 2 mm before the initial-state check).
    let mesh = BoxSpec::new([2, 1, 2], [0.16, 0.08, 0.16])
        .jitter(0.1, 11)
        .origin([-0.07, 0.012, -0.09])
        .build()?;
    let mut body = BodySpec::new(
        "ball",
        mesh,
        Material {
            youngs_modulus: 5e3,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(300.0),
    );
    body.initial_velocity = Vector3::new(0.3, -1.0, 0.2);
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .cloth(cloth)
        .collisions(crate::contact::pair::BodyCollision {
            thickness: 1e-3,
            friction: 0.3,
        })
        .build()?;
    let ball = model.bodies[0].vertices.clone();
    Ok(Case {
        name: "ball_on_cloth".into(),
        description: "soft box (16 tets) thrown onto a cloth (72 triangles, corners on springs): both deform, vertex-face contacts both ways with friction 0.3; loss: 0.3 x + y + 0.2 z of the box's final barycentre".into(),
        settings: gradcheck_settings(0.005, 8),
        steps,
        loss: Box::new(CenterOfMass {
            direction: Vector3::new(0.3, 1.0, 0.2),
            time_average: false,
            vertices: Some(ball.clone().collect()),
        }),
        controls: Controls::default(),
        groups: (0..3)
            .map(|axis| Group::BodyVelocity {
                body: "ball".into(),
                vertices: ball.clone(),
                axis,
            })
            .chain([Group::InitialPositions])
            .collect(),
        model,
    })
}

/// The paper's ball (43 vertices, 80 tets) thrown onto the paper's flag cloth pinned along its
/// edges (`verification/scenes/ball_on_cloth.json`), starting 2 mm above it so that contact
/// acts within a few steps; loss: a weighted sum of the ball's final barycentre coordinates.
pub fn paper_ball_on_cloth(scene_path: &Path, steps: usize) -> Result<Case> {
    let sc =
        scene::load(scene_path, LoadOptions::default()).with_context(|| format!("loading {}", scene_path.display()))?;
    let model = sc.model;
    let ball = model.bodies[0].vertices.clone();
    let cloth_top = model
        .cloth
        .as_ref()
        .context("the scene has no cloth")?
        .bodies
        .iter()
        .flat_map(|b| b.vertices.clone())
        .map(|v| model.rest[v].y)
        .fold(f64::NEG_INFINITY, f64::max);
    let bottom = ball.clone().map(|v| model.rest[v].y).fold(f64::INFINITY, f64::min);
    let mut q = model.rest.clone();
    let mut v = model.initial_velocity.clone();
    for i in ball.clone() {
        q[i].y += cloth_top + 2e-3 - bottom;
        v[i] = Vector3::new(0.2, -1.0, 0.1);
    }
    Ok(Case {
        name: "paper_ball_on_cloth".into(),
        description: "the paper's ball (80 tets, 5 kPa) thrown at 1 m/s onto the paper's flag cloth (128 triangles) pinned along its edges, from 2 mm above: contacts between the bodies both ways with friction 0.3; loss: 0.3 x + y + 0.2 z of the ball's final barycentre".into(),
        settings: gradcheck_settings(sc.settings.dt, 8),
        steps,
        loss: Box::new(CenterOfMass {
            direction: Vector3::new(0.3, 1.0, 0.2),
            time_average: false,
            vertices: Some(ball.clone().collect()),
        }),
        controls: Controls {
            initial: Some((q, v)),
            ..Controls::default()
        },
        groups: (0..3)
            .map(|axis| Group::BodyVelocity {
                body: "ball".into(),
                vertices: ball.clone(),
                axis,
            })
            .collect(),
        model,
    })
}

/// A beam held by attachment springs at one end, bent by a pneumatic group (top layer) and a
/// muscle group (bottom layer) with time-varying activations.
pub fn actuated(steps: usize) -> Result<Case> {
    let ActuatedBeam { model, tip } = actuated_beam()?;
    let acts: Vec<Vec<f64>> = (0..steps)
        .map(|n| {
            let t = (n + 1) as f64 / steps as f64;
            vec![1.0 + 0.3 * t, 0.2 + 0.2 * t]
        })
        .collect();
    Ok(Case {
        name: "actuated".into(),
        description: "beam (72 tets) on attachment springs, bent by a pneumatic layer (a 1 -> 1.3) and a muscle layer (a 0.2 -> 0.4); loss: final tip position".into(),
        model,
        settings: gradcheck_settings(0.01, 10),
        steps,
        loss: Box::new(VertexPositions {
            terms: vec![(tip, Vector3::new(0.3, 1.0, 0.1))],
        }),
        controls: Controls {
            activations: Some(acts),
            ..Controls::default()
        },
        groups: vec![
            Group::Scalar(Param::YOUNGS_MODULUS),
            Group::Activations,
            Group::AttachmentTargets,
            Group::InitialVelocities,
        ],
    })
}

/// Baymax with its skeleton and joint torques (the paper's skeleton scene, which has no
/// ground: the built-in scene's ground plane is removed, as in the reference implementation's
/// `baymax_skeleton.json`); loss: final barycentre height plus both shoulder angles.
pub fn baymax_torques(scene_path: &Path, steps: usize) -> Result<Case> {
    let sc = scene::load(scene_path, LoadOptions::default()).with_context(|| scene_path.display().to_string())?;
    let mut model = sc.model;
    model.obstacles.clear();
    let settings = gradcheck_settings(sc.settings.dt, 10);
    let mut case = Case {
        name: "baymax_torques".into(),
        description: format!(
            "the paper's Baymax ({} vertices, {} tets) with its skeleton (free torso, 4 rotational joints) in free fall, shoulder torques ramping up; loss: final barycentre height + shoulder angles",
            model.n(),
            model.tets.len()
        ),
        model,
        settings,
        steps,
        loss: Box::new(
            Sum::default()
                .add(
                    1.0,
                    CenterOfMass {
                        direction: Vector3::y(),
                        time_average: false,
                        vertices: None,
                    },
                )
                .add(
                    0.3,
                    JointAngle {
                        bone: "left_shoulder".into(),
                        target: None,
                        time_average: false,
                    },
                )
                .add(
                    0.2,
                    JointAngle {
                        bone: "right_shoulder".into(),
                        target: Some(0.5),
                        time_average: true,
                    },
                ),
        ),
        controls: Controls::default(),
        groups: vec![
            Group::Torques,
            Group::InitialVelocities,
            Group::InitialPositions,
            Group::Scalar(Param::YOUNGS_MODULUS),
            Group::Scalar(Param::POISSON_RATIO),
            Group::Scalar(Param::DENSITY),
            Group::Scalar(Param::GRAVITY_Y),
        ],
    };
    case.controls.torques = Some(torques(&case));
    Ok(case)
}

/// Baymax with its skeleton dropped onto frictional ground (the built-in scene of paper
/// Fig. 5b): contacts on the free vertices inside the reduced step.
pub fn baymax_ground(scene_path: &Path, steps: usize) -> Result<Case> {
    let mut case = baymax_torques(scene_path, steps)?;
    let sc = scene::load(scene_path, LoadOptions::default()).with_context(|| scene_path.display().to_string())?;
    case.model = sc.model;
    case.name = "baymax_skeleton_ground".into();
    case.description = format!(
        "the paper's Baymax ({} vertices, {} tets) with its skeleton thrown onto ground with friction {} (v0 = (0.5, -6, 0.2) m/s), shoulder torques ramping up; loss: final barycentre height + shoulder angles",
        case.model.n(),
        case.model.tets.len(),
        case.model.obstacles.first().map_or(0.0, |o| o.friction)
    );
    // Thrown down and sideways so it lands within a few steps (it starts 0.26 m above ground).
    let v0 = vec![Vector3::new(0.5, -6.0, 0.2); case.model.n()];
    case.controls.initial = Some((case.model.rest.clone(), v0));
    // Density is checked without ground (baymax_torques): here its derivative is 1e-5 of the
    // loss and the differences plateau at a relative scatter of 1e-5 (contact sweeps stop at
    // round-off), below which no step resolves it.
    case.groups = vec![
        Group::Torques,
        Group::InitialVelocities,
        Group::Scalar(Param::YOUNGS_MODULUS),
        Group::Scalar(Param::GRAVITY_Y),
    ];
    Ok(case)
}

/// The scene files the built-in cases read.
#[derive(Debug, Clone)]
pub struct CaseScenes {
    /// The paper's bridgesus scene.
    pub bridgesus: PathBuf,
    /// Baymax with its skeleton (diffsoft scene).
    pub baymax_skeleton: PathBuf,
    /// The paper's ball on its flag cloth (diffsoft scene).
    pub ball_on_cloth: PathBuf,
}

impl CaseScenes {
    /// The scenes as they lie in the repository's `verification/` folder, under `root`.
    pub fn under(root: &Path) -> Self {
        Self {
            bridgesus: root.join("paper/bridgesus/bridgesus.json"),
            baymax_skeleton: root.join("scenes/baymax_skeleton.json"),
            ball_on_cloth: root.join("scenes/ball_on_cloth.json"),
        }
    }
}

/// The built-in cases, in report order: free body, bridgesus, ground contact, actuated beam,
/// Baymax with torques, Baymax on the ground, ball on cloth (built-in and the paper's), then the
/// free body, bridgesus, ground contact and Baymax with torques again with BDF2 (docs/method.md
/// Eqs. T1-T3; names ending in `_bdf2`), then the free body, bridgesus, ground contact and
/// Baymax with torques through Newton's method (section 6.5; names ending in `_newton`,
/// implicit mode).
pub fn builtin_cases(scenes: &CaseScenes, steps: usize) -> Result<Vec<Case>> {
    let mut cases = vec![
        free_body(steps)?,
        bridgesus(&scenes.bridgesus, steps)?,
        ground_contact(steps)?,
        actuated(steps)?,
        baymax_torques(&scenes.baymax_skeleton, steps)?,
        baymax_ground(&scenes.baymax_skeleton, steps)?,
        ball_on_cloth(steps)?,
        paper_ball_on_cloth(&scenes.ball_on_cloth, steps)?,
    ];
    for case in [
        free_body(steps)?,
        bridgesus(&scenes.bridgesus, steps)?,
        ground_contact(steps)?,
        baymax_torques(&scenes.baymax_skeleton, steps)?,
    ] {
        cases.push(with_bdf2(case));
    }
    for case in [
        free_body(steps)?,
        bridgesus(&scenes.bridgesus, steps)?,
        ground_contact(steps)?,
        baymax_torques(&scenes.baymax_skeleton, steps)?,
    ] {
        cases.push(with_newton(case));
    }
    Ok(cases)
}

/// `case` through Newton's method (docs/method.md section 6.5) converged to tolerance `1e-12`:
/// its gradients are implicit-mode ones, exact at convergence, so the forward converges
/// instead of running a fixed iteration count (names ending in `_newton`).
pub fn with_newton(mut case: Case) -> Case {
    case.settings.solver = SolverKind::Newton;
    case.settings.tolerance = 1e-12;
    case.settings.max_iterations = 200;
    case.name.push_str("_newton");
    case.description = format!(
        "{} Solved by Newton's method to tolerance 1e-12 (implicit-mode gradients).",
        case.description
    );
    case
}

/// `case` integrated with BDF2 instead of implicit Euler.
pub fn with_bdf2(mut case: Case) -> Case {
    case.settings.integrator = crate::solver::Integrator::Bdf2;
    case.name.push_str("_bdf2");
    case.description = format!(
        "{} Integrated with BDF2 (its first step implicit Euler).",
        case.description
    );
    case
}
