//! Physics checks of the forward solver against closed forms, shared by the tests (which assert
//! on them) and the main job (which writes them to `reports/physics.json`).

use std::path::Path;
use std::time::Instant;

use nalgebra::{Rotation3, Vector3};
use serde::Serialize;

use crate::report::{ModelSize, Verdict};
use diffsoft::base::Material;
use diffsoft::contact::Obstacle;
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::mesh::TetMesh;
use diffsoft::model::{BodySpec, MassSpec, ModelBuilder};
use diffsoft::scene::{self, LoadOptions};
use diffsoft::solver::{CertifyPolicy, Settings, Simulator, SolverError, SolverKind};

fn cube(n: usize, size: f64) -> TetMesh {
    BoxSpec::new([n, n, n], [size; 3])
        .jitter(0.1, 3)
        .build()
        .expect("valid box")
}

fn tight(dt: f64, solver: SolverKind) -> Settings {
    Settings {
        dt,
        solver,
        certify: CertifyPolicy::Fallback,
        tolerance: 1e-12,
        inner_tolerance: 1e-13,
        max_iterations: 50,
        ..Settings::default()
    }
}

/// Free fall of an unconstrained body against the exact implicit-Euler trajectory
/// `x_N = x_0 + N h v_0 + h^2 g N (N+1)/2`; returns the largest relative position error.
pub fn free_fall(solver: SolverKind, steps: usize) -> Result<f64, SolverError> {
    let g = Vector3::new(0.3, -9.81, 0.1);
    let v0 = Vector3::new(1.0, 2.0, -0.5);
    let mut body = BodySpec::new(
        "cube",
        cube(3, 0.5),
        Material {
            youngs_modulus: 1e5,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(1000.0),
    );
    body.initial_velocity = v0;
    let model = ModelBuilder::new().gravity(g).body(body).build()?;
    let rest = model.rest().to_vec();
    let h = 0.01;
    let mut sim = Simulator::new(model, tight(h, solver))?;
    for _ in 0..steps {
        sim.step()?;
    }
    let nf = steps as f64;
    let shift = v0 * (nf * h) + g * (h * h * nf * (nf + 1.0) / 2.0);
    Ok(sim
        .state()
        .q
        .iter()
        .zip(&rest)
        .map(|(q, x0)| (q - (x0 + shift)).norm() / (x0 + shift).norm().max(shift.norm()))
        .fold(0.0, f64::max))
}

/// A block on an inclined plane.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct InclineResult {
    /// Incline angle (degrees).
    pub angle_deg: f64,
    /// Friction coefficient (1).
    pub friction: f64,
    /// Coulomb's verdict: sticks iff `tan(angle) < mu`.
    pub should_stick: bool,
    /// Down-slope displacement of the centroid (m).
    pub centroid_displacement: f64,
    /// Coulomb's prediction for a rigid slide, `a h^2 N(N+1)/2`, `a = g (sin - mu cos)` (m).
    pub predicted_displacement: f64,
    /// Largest tangential displacement of a contact vertex (m).
    pub contact_slip: f64,
    /// Largest tangential speed of a contact vertex at the end (m/s).
    pub contact_speed: f64,
    /// Deepest penetration (m).
    pub max_penetration: f64,
}

/// Release a 0.2 m block at rest on a plane inclined by `angle_deg` with friction `mu`, and let
/// it stick or slide for 0.3 s.
pub fn incline(angle_deg: f64, mu: f64) -> Result<InclineResult, SolverError> {
    let th = angle_deg.to_radians();
    let g = 9.81;
    let normal = Vector3::new(-th.sin(), th.cos(), 0.0);
    let down_slope = Vector3::new(-th.cos(), -th.sin(), 0.0);
    let size = 0.2;
    let mesh = BoxSpec::new([2, 2, 2], [size; 3])
        .origin([-size / 2.0, 0.0, -size / 2.0])
        .build()
        .expect("valid box");
    let rot = Rotation3::from_axis_angle(&Vector3::z_axis(), th);
    let mesh = mesh.map_vertices(|v| rot * v);
    let body = BodySpec::new(
        "block",
        mesh,
        Material {
            youngs_modulus: 1e7,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(1000.0),
    );
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -g, 0.0))
        .body(body)
        .obstacle(Obstacle::plane("incline", Vector3::zeros(), normal, mu))
        .build()?;
    let (h, steps) = (0.002, 150);
    let c0: Vector3<f64> = model.rest().iter().sum::<Vector3<f64>>() / model.n() as f64;
    let bottom: Vec<usize> = (0..model.n())
        .filter(|&i| normal.dot(&model.rest()[i]).abs() < 1e-12)
        .collect();
    let start: Vec<Vector3<f64>> = bottom.iter().map(|&i| model.rest()[i]).collect();
    let mut sim = Simulator::new(model, tight(h, SolverKind::Direct))?;
    let mut pen = 0.0f64;
    for _ in 0..steps {
        pen = pen.max(sim.step()?.max_penetration);
    }
    let q = &sim.state().q;
    let c1: Vector3<f64> = q.iter().sum::<Vector3<f64>>() / q.len() as f64;
    let tangential = |u: Vector3<f64>| (u - normal * normal.dot(&u)).norm();
    let a = g * (th.sin() - mu * th.cos());
    let n = steps as f64;
    Ok(InclineResult {
        angle_deg,
        friction: mu,
        should_stick: th.tan() < mu,
        centroid_displacement: (c1 - c0).dot(&down_slope),
        predicted_displacement: if a > 0.0 { a * h * h * n * (n + 1.0) / 2.0 } else { 0.0 },
        contact_slip: bottom
            .iter()
            .zip(&start)
            .map(|(&i, x0)| tangential(q[i] - x0))
            .fold(0.0, f64::max),
        contact_speed: bottom.iter().map(|&i| tangential(sim.state().v[i])).fold(0.0, f64::max),
        max_penetration: pen,
    })
}

/// Drop the paper's ball (43 vertices) at 3 m/s onto the ground; returns the deepest
/// penetration over 1 s and the lowest vertex height seen.
pub fn ball_drop(ball: TetMesh, solver: SolverKind) -> Result<(f64, f64, usize), SolverError> {
    let mut body = BodySpec::new(
        "ball",
        ball,
        Material {
            youngs_modulus: 2e4,
            poisson_ratio: 0.4,
        },
        MassSpec::Total(1.0),
    );
    body.initial_velocity = Vector3::new(0.5, -3.0, 0.0);
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .obstacle(Obstacle::plane("ground", Vector3::zeros(), Vector3::y(), 0.3))
        .build()?;
    let mut sim = Simulator::new(
        model,
        Settings {
            dt: 0.005,
            solver,
            ..Settings::default()
        },
    )?;
    let (mut pen, mut lowest, mut contacts) = (0.0f64, f64::INFINITY, 0usize);
    for _ in 0..200 {
        let st = sim.step()?;
        pen = pen.max(st.max_penetration);
        contacts = contacts.max(st.contacts);
        lowest = lowest.min(sim.state().q.iter().map(|q| q.y).fold(f64::INFINITY, f64::min));
    }
    Ok((pen, lowest, contacts))
}

/// Free fall with one solver.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct FreeFallResult {
    /// The global solver.
    pub solver: SolverKind,
    /// Largest position error relative to implicit Euler's exact trajectory after 50 steps (1).
    pub max_relative_error: f64,
}

/// The ball drop ([`ball_drop`]) with one solver.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct BallDropResult {
    /// The global solver.
    pub solver: SolverKind,
    /// Deepest penetration into the ground over the run (m).
    pub max_penetration: f64,
    /// Lowest vertex height seen (m; the ground is at 0).
    pub lowest_height: f64,
    /// Most contacts in a step.
    pub max_contacts: usize,
}

/// One refinement level of the cantilever study.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct CantileverRow {
    /// Cells across the section (`10 k` along the beam).
    pub cells_across: usize,
    /// Tets.
    pub tets: usize,
    /// Computed static tip deflection (m, mean over the tip face).
    pub tip_deflection: f64,
    /// Euler-Bernoulli tip deflection `q L^4 / (8 E I)` (m).
    pub euler_bernoulli: f64,
    /// `|w - w_EB| / w_EB` (1).
    pub relative_error: f64,
    /// Local-global iterations of the static solve.
    pub iterations: usize,
    /// Whether the static solve met its tolerance.
    pub converged: bool,
    /// Wall time (s).
    pub seconds: f64,
}

/// A clamped 1 x 0.1 x 0.1 m beam (E = 1e9 Pa, nu = 0: the corotated model linearises to
/// linear elasticity with this E) under its own weight (rho = 1000, g = 9.81), solved to static
/// equilibrium by one implicit step with a huge time step, at `levels` refinements
/// (`10 k x k x k` Kuhn cells).
pub fn cantilever(levels: &[usize]) -> Result<Vec<CantileverRow>, SolverError> {
    let (l, b, e, rho, g): (f64, f64, f64, f64, f64) = (1.0, 0.1, 1e9, 1000.0, 9.81);
    let q = rho * g * b * b;
    let inertia = b.powi(4) / 12.0;
    let eb = q * l.powi(4) / (8.0 * e * inertia);
    let mut rows = Vec::new();
    for &k in levels {
        let t0 = Instant::now();
        let mesh = BoxSpec::new([10 * k, k, k], [l, b, b]).build().expect("valid box");
        let mut body = BodySpec::new(
            "beam",
            mesh.clone(),
            Material {
                youngs_modulus: e,
                poisson_ratio: 0.0,
            },
            MassSpec::Density(rho),
        );
        body.fixed = (0..mesh.num_vertices())
            .filter(|&i| mesh.vertices[i].x < 1e-9)
            .collect();
        body.volume_constraint = false;
        let model = ModelBuilder::new()
            .gravity(Vector3::new(0.0, -g, 0.0))
            .body(body)
            .build()?;
        let tip: Vec<usize> = (0..model.n())
            .filter(|&i| (model.rest()[i].x - l).abs() < 1e-9)
            .collect();
        let s = Settings {
            dt: 1e3,
            solver: SolverKind::Direct,
            max_iterations: 200_000,
            tolerance: 1e-12,
            ..Settings::default()
        };
        let rest = model.rest().to_vec();
        let tets = model.tets().len();
        let mut sim = Simulator::new(model, s)?;
        let st = sim.step()?;
        let w = -tip.iter().map(|&i| sim.state().q[i].y - rest[i].y).sum::<f64>() / tip.len() as f64;
        rows.push(CantileverRow {
            cells_across: k,
            tets,
            tip_deflection: w,
            euler_bernoulli: eb,
            relative_error: (w - eb).abs() / eb,
            iterations: st.iterations,
            converged: st.converged,
            seconds: t0.elapsed().as_secs_f64(),
        });
    }
    Ok(rows)
}

/// One paper scene run.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct SceneRun {
    /// Scene file.
    pub scene: String,
    /// Vertices and tets.
    pub size: ModelSize,
    /// Steps run.
    pub steps: usize,
    /// Solver used and why.
    pub certificate: String,
    /// Median wall time per step (ms).
    pub median_ms_per_step: f64,
    /// Mean local-global iterations per step.
    pub mean_iterations: f64,
    /// Largest contact count.
    pub max_contacts: usize,
    /// Deepest penetration (m).
    pub max_penetration: f64,
    /// Importer notes.
    pub notes: Vec<String>,
}

/// Run a scene file for `steps` steps.
pub fn run_scene(path: &Path, steps: usize) -> Result<SceneRun, Box<dyn std::error::Error>> {
    let sc = scene::load(path, LoadOptions::default())?;
    let size = ModelSize::of(&sc.model);
    let mut sim = Simulator::new(sc.model, sc.settings)?;
    let mut stats = Vec::new();
    for _ in 0..steps {
        stats.push(sim.step()?);
    }
    let summary = diffsoft::output::RunSummary::of(&stats);
    Ok(SceneRun {
        scene: path.display().to_string(),
        size,
        steps,
        certificate: sim.certificate().message.clone(),
        median_ms_per_step: summary.median_ms_per_step,
        mean_iterations: summary.mean_iterations,
        max_contacts: summary.max_contacts,
        max_penetration: summary.max_penetration,
        notes: sc.notes,
    })
}

/// Verdicts for the cantilever study: errors decrease with refinement and the finest is the
/// closest.
pub fn cantilever_verdicts(rows: &[CantileverRow]) -> Vec<Verdict> {
    let decreasing = rows.windows(2).all(|w| w[1].relative_error < w[0].relative_error);
    let last = rows.last().map_or(f64::NAN, |r| r.relative_error);
    vec![
        Verdict::new(
            "Cantilever tip deflection approaches Euler-Bernoulli q L^4 / (8 E I) under refinement (error decreases at every level)",
            decreasing,
            Some(last),
            None,
            "measured = relative error at the finest level; holds iff the error decreases at every refinement",
        ),
        Verdict::new(
            "Every static solve converged to its tolerance",
            rows.iter().all(|r| r.converged),
            None,
            None,
            "informational",
        ),
    ]
}

/// One solver compared with the direct solver.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct AgreementRow {
    /// With a ground the beam's tip touches.
    pub ground: bool,
    /// Solver asked for.
    pub solver: SolverKind,
    /// Certification policy.
    pub policy: CertifyPolicy,
    /// Solver used after certification.
    pub used: SolverKind,
    /// Largest vertex distance to the direct solver's state after 60 steps (m).
    pub max_difference: f64,
    /// Contacts in the last step.
    pub contacts: usize,
}

/// A Kuhn-split (M-matrix) beam clamped at one end under gravity, 5 mm above an optional ground
/// its tip reaches, run for 60 steps of 1 ms with every solver (all certified to converge there:
/// rho(G19) = 0.45) and compared with the direct solver.
pub fn solver_agreement() -> Result<Vec<AgreementRow>, SolverError> {
    let build = |ground: bool| -> Result<diffsoft::model::Model, SolverError> {
        let mesh = BoxSpec::new([8, 2, 2], [1.0, 0.2, 0.2])
            .origin([0.0, 0.0, -0.1])
            .build()
            .expect("valid box");
        let mut body = BodySpec::new(
            "beam",
            mesh.clone(),
            Material {
                youngs_modulus: 2e5,
                poisson_ratio: 0.3,
            },
            MassSpec::Density(500.0),
        );
        body.fixed = (0..mesh.num_vertices())
            .filter(|&i| mesh.vertices[i].x < 1e-9)
            .collect();
        let mut b = ModelBuilder::new().gravity(Vector3::new(0.0, -9.81, 0.0)).body(body);
        if ground {
            b = b.obstacle(Obstacle::plane(
                "ground",
                Vector3::new(0.0, -0.005, 0.0),
                Vector3::y(),
                0.4,
            ));
        }
        Ok(b.build()?)
    };
    let settings = |solver, certify| Settings {
        dt: 1e-3,
        solver,
        certify,
        tolerance: 1e-12,
        inner_tolerance: 1e-14,
        max_iterations: 200,
        inner_max_iterations: 20_000,
        ..Settings::default()
    };
    let run = |ground: bool, s: Settings| -> Result<(Vec<Vector3<f64>>, SolverKind, usize), SolverError> {
        let mut sim = Simulator::new(build(ground)?, s)?;
        let mut contacts = 0;
        for _ in 0..60 {
            contacts = sim.step()?.contacts;
        }
        Ok((sim.state().q.clone(), sim.certificate().used, contacts))
    };
    let mut rows = Vec::new();
    for ground in [false, true] {
        let (reference, _, _) = run(ground, settings(SolverKind::Direct, CertifyPolicy::Off))?;
        for (solver, policy) in [
            (SolverKind::Split, CertifyPolicy::Off),
            (SolverKind::Split, CertifyPolicy::Fallback),
            (SolverKind::Chebyshev, CertifyPolicy::Refuse),
            (SolverKind::Plain, CertifyPolicy::Refuse),
        ] {
            let (q, used, contacts) = run(ground, settings(solver, policy))?;
            let max_difference = q
                .iter()
                .zip(&reference)
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max);
            rows.push(AgreementRow {
                ground,
                solver,
                policy,
                used,
                max_difference,
                contacts,
            });
        }
    }
    Ok(rows)
}
