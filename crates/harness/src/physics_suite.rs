//! The physics part of the suite: `reports/physics.json` (the forward solver against closed
//! forms) and the run that writes it with the cantilever plot.

use std::path::Path;

use anyhow::{anyhow, Result};
use serde::Serialize;

use crate::plot::{self, LogLogChart, RefLine, Series};
use crate::report::{Header, Verdict};
use crate::{physics, suite};
use diffsoft::mesh;

/// `reports/physics.json`: the forward solver against closed forms.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct PhysicsReport {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// Free fall: largest relative position error after 50 steps, per solver.
    pub free_fall: Vec<physics::FreeFallResult>,
    /// Blocks on inclines.
    pub incline: Vec<physics::InclineResult>,
    /// Ball drop, per solver.
    pub ball_drop: Vec<physics::BallDropResult>,
    /// Cantilever refinement study.
    pub cantilever: Vec<physics::CantileverRow>,
    /// Solvers against the direct one.
    pub solver_agreement: Vec<physics::AgreementRow>,
    /// Scene runs.
    pub scenes: Vec<physics::SceneRun>,
    /// Claims.
    pub verdicts: Vec<Verdict>,
}

/// Schema of `reports/physics.json`.
pub const PHYSICS_SCHEMA: &str = "diffsoft.physics/2";

pub(crate) fn run_physics(base: &Path, out: &Path, suite: &suite::PhysicsSuite) -> Result<PhysicsReport> {
    use diffsoft::solver::SolverKind;
    let mut free_fall = Vec::new();
    for s in [SolverKind::Direct, SolverKind::Split, SolverKind::Chebyshev] {
        free_fall.push(physics::FreeFallResult {
            solver: s,
            max_relative_error: physics::free_fall(s, 50)?,
        });
    }
    let mut incline = Vec::new();
    for (angle, mu) in [
        (10.0, 0.2),
        (20.0, 0.5),
        (30.0, 0.7),
        (30.0, 0.0),
        (35.0, 0.5),
        (40.0, 0.2),
    ] {
        incline.push(physics::incline(angle, mu)?);
    }
    let ball = mesh::load(base.join("paper/droneman/ball_tet.obj"))?.mesh;
    let mut ball_drop = Vec::new();
    for s in [SolverKind::Direct, SolverKind::Chebyshev] {
        let (max_penetration, lowest_height, max_contacts) = physics::ball_drop(ball.clone(), s)?;
        ball_drop.push(physics::BallDropResult {
            solver: s,
            max_penetration,
            lowest_height,
            max_contacts,
        });
    }
    crate::say!("  cantilever levels {:?} ...", suite.cantilever_levels);
    let cantilever = physics::cantilever(&suite.cantilever_levels)?;
    let solver_agreement = physics::solver_agreement()?;
    let mut scenes = Vec::new();
    for sc in &suite.scenes {
        let r = physics::run_scene(&base.join(&sc.scene), sc.steps).map_err(|e| anyhow!("{e}"))?;
        crate::say!(
            "  {:<45} {:>8.3} ms/step {:>6.2} it/step",
            sc.scene.display(),
            r.median_ms_per_step,
            r.mean_iterations
        );
        scenes.push(r);
    }
    let mut verdicts = vec![
        Verdict::at_most(
            "Free fall matches implicit Euler's exact trajectory (every solver)",
            free_fall.iter().map(|f| f.max_relative_error).fold(0.0, f64::max),
            1e-10,
        ),
        Verdict::new(
            "A block on an incline sticks iff tan(angle) < mu_f: contact vertices at rest when it should stick, sliding at Coulomb's acceleration (within 2%) when it should not",
            incline.iter().all(|r| {
                if r.should_stick {
                    r.contact_speed < 1e-6
                } else {
                    (r.centroid_displacement / r.predicted_displacement - 1.0).abs() < 0.02
                }
            }),
            None,
            None,
            "per case in `incline`",
        ),
        Verdict::at_most(
            "No penetration: deepest over the ball drops and inclines (m)",
            ball_drop
                .iter()
                .map(|b| b.max_penetration)
                .chain(incline.iter().map(|r| r.max_penetration))
                .fold(0.0, f64::max),
            1e-9,
        ),
        Verdict::at_most(
            "Direct, plain, split, Chebyshev and certified solvers reach the same state (largest difference, m)",
            solver_agreement.iter().map(|r| r.max_difference).fold(0.0, f64::max),
            1e-8,
        ),
    ];
    verdicts.extend(physics::cantilever_verdicts(&cantilever));
    let chart = LogLogChart {
        title: "Cantilever under gravity: tip deflection error vs Euler-Bernoulli".into(),
        x_label: "tets".into(),
        y_label: "relative error |w - qL^4/8EI| / (qL^4/8EI)".into(),
        series: vec![Series {
            label: "linear tets, corotated PD (nu = 0)".into(),
            points: cantilever.iter().map(|r| (r.tets as f64, r.relative_error)).collect(),
        }],
        vlines: Vec::new(),
        hlines: vec![RefLine {
            label: "shear deformation neglected by Euler-Bernoulli (~0.8%)".into(),
            at: 0.008,
        }],
    };
    plot::write_svg(&diffsoft::output::own_file(out, "cantilever.svg")?, &chart)?;
    Ok(PhysicsReport {
        header: Header::new(PHYSICS_SCHEMA),
        free_fall,
        incline,
        ball_drop,
        cantilever,
        solver_agreement,
        scenes,
        verdicts,
    })
}
