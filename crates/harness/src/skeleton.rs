//! The skeleton study (`reports/skeleton.json`, paper Fig. 5b/5e): a soft body with an embedded
//! skeleton dropped onto the ground while torques drive two joints, against the same body
//! without bones; plus the cost of the skeleton's reduced step per local-global iteration.
//!
//! Arm proxies are measured on the deformed mesh, so they mean the same with and without bones:
//! for each arm bone named in the suite, the *shoulder point* is the centroid of that bone's
//! vertices and the *tip* is the rest vertex farthest from the body's vertical axis on that
//! side. The arm's elevation is the angle of `tip - shoulder` above the horizontal plane
//! (gravity is `-y`), its length ratio is `|tip - shoulder|` over its rest value; the body's
//! height ratio is its current vertical extent over the rest one (legs collapsing lower it).

use std::path::Path;

use anyhow::{anyhow, Result};
use nalgebra::Vector3;
use serde::Serialize;

use crate::plot::{self, LinearChart, Panel, Series, Snapshots};
use crate::report::{Header, ModelSize, Verdict};
use diffsoft::scene::{self, LoadOptions, Scene};
use diffsoft::solver::{Simulator, StepStats};

/// Schema of `reports/skeleton.json`.
pub const SCHEMA: &str = "diffsoft.skeleton/2";

/// One arm's reference points (vertex indices, global numbering).
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Arm {
    /// The arm bone's name.
    pub bone: String,
    /// The bone's vertices (their centroid is the shoulder point).
    pub shoulder_vertices: Vec<usize>,
    /// The tip vertex.
    pub tip: usize,
    /// Elevation at rest (degrees).
    pub rest_elevation_deg: f64,
    /// Shoulder-to-tip distance at rest (m).
    pub rest_length: f64,
}

/// The coordinate of a one-DoF joint.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct JointCoordinate {
    /// The bone whose joint it is.
    pub bone: String,
    /// Angle of a rotational joint (rad) or extension of a prismatic one (m).
    pub value: f64,
}

/// A bone and the kind of its joint.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct BoneJoint {
    /// The bone's name.
    pub bone: String,
    /// Its joint's kind (`free`, `fixed`, `rotational`, `prismatic`).
    pub joint: String,
}

/// The state of the body at one sampled step.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Sample {
    /// Simulated time (s).
    pub time: f64,
    /// One-DoF joint coordinates; empty without bones.
    pub joints: Vec<JointCoordinate>,
    /// Elevation of each arm (degrees, suite order).
    pub arm_elevation_deg: Vec<f64>,
    /// Length ratio of each arm (1).
    pub arm_length_ratio: Vec<f64>,
    /// Vertical extent over the rest one (1).
    pub height_ratio: f64,
    /// Horizontal extent along the arms (tip to tip) over the rest one (1).
    pub span_ratio: f64,
    /// Local-global iterations of the step.
    pub iterations: usize,
    /// Wall time of the step (ms).
    pub wall_ms: f64,
    /// Largest change of a distance within a bone after the step (m).
    pub bone_length_error: f64,
    /// Contacts of the step.
    pub contacts: usize,
}

/// One run of the scene.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Run {
    /// With the scene's bones (and torques) or with the bones removed.
    pub with_bones: bool,
    /// Steps.
    pub steps: usize,
    /// Median wall time per step (ms).
    pub median_ms_per_step: f64,
    /// Mean local-global iterations per step.
    pub mean_iterations: f64,
    /// Steps that met the tolerance.
    pub converged_steps: usize,
    /// Largest bone-length error over the run (m; the paper reports 0).
    pub max_bone_length_error: f64,
    /// Deepest penetration (m).
    pub max_penetration: f64,
    /// Every step.
    pub samples: Vec<Sample>,
}

/// Cost per local-global iteration with and without the skeleton (exactly `iterations` per step).
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Cost {
    /// Iterations per step (tolerance 0, no acceleration).
    pub iterations: usize,
    /// Steps timed.
    pub steps: usize,
    /// Worker threads.
    pub threads: usize,
    /// Median wall time per step with bones (ms).
    pub with_bones_ms: f64,
    /// Median wall time per step without bones (ms).
    pub without_bones_ms: f64,
    /// `with / without` (1).
    pub ratio: f64,
}

/// `reports/skeleton.json`.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct SkeletonReport {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// Scene file.
    pub scene: String,
    /// Vertices and tets.
    pub size: ModelSize,
    /// Bones and the kinds of their joints.
    pub bones: Vec<BoneJoint>,
    /// Arm reference points.
    pub arms: Vec<Arm>,
    /// The run with bones.
    pub with_bones: Run,
    /// The run without bones.
    pub without_bones: Run,
    /// Per-iteration cost of the skeleton.
    pub cost: Cost,
    /// Claims.
    pub verdicts: Vec<Verdict>,
}

fn elevation_deg(d: &Vector3<f64>) -> f64 {
    d.y.atan2((d.x * d.x + d.z * d.z).sqrt()).to_degrees()
}

fn centroid(q: &[Vector3<f64>], vs: &[usize]) -> Vector3<f64> {
    vs.iter().map(|&v| q[v]).sum::<Vector3<f64>>() / vs.len().max(1) as f64
}

fn height(q: &[Vector3<f64>]) -> f64 {
    let (lo, hi) = q
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| (l.min(p.y), h.max(p.y)));
    hi - lo
}

fn arms(sc: &Scene, names: &[String]) -> Result<Vec<Arm>> {
    let sk = sc
        .model
        .skeleton()
        .ok_or_else(|| anyhow!("{}: the scene has no bones", sc.path.display()))?;
    let rest = sc.model.rest();
    let axis = centroid(rest, &(0..rest.len()).collect::<Vec<_>>());
    names
        .iter()
        .map(|name| {
            let bone = sk
                .bones
                .iter()
                .find(|b| &b.name == name)
                .ok_or_else(|| anyhow!("{}: no bone named '{name}'", sc.path.display()))?;
            let shoulder = centroid(rest, &bone.vertices);
            // Horizontal direction from the body's axis to the shoulder.
            let mut side = shoulder - axis;
            side.y = 0.0;
            let side = side
                .try_normalize(1e-12)
                .ok_or_else(|| anyhow!("bone '{name}' sits on the body's axis"))?;
            let tip = (0..rest.len())
                .max_by(|&a, &b| rest[a].dot(&side).total_cmp(&rest[b].dot(&side)))
                .unwrap_or(0);
            let d = rest[tip] - shoulder;
            Ok(Arm {
                bone: name.clone(),
                shoulder_vertices: bone.vertices.clone(),
                tip,
                rest_elevation_deg: elevation_deg(&d),
                rest_length: d.norm(),
            })
        })
        .collect()
}

fn span(q: &[Vector3<f64>], arms: &[Arm]) -> f64 {
    match arms {
        [a, b, ..] => {
            let d = q[a.tip] - q[b.tip];
            (d.x * d.x + d.z * d.z).sqrt()
        }
        _ => f64::NAN,
    }
}

fn sample(sim: &Simulator, s: &StepStats, arms: &[Arm], rest_height: f64, rest_span: f64) -> Sample {
    let q = &sim.state().q;
    let joints = sim.skeleton().map_or(Vec::new(), |sk| {
        sk.bones
            .iter()
            .filter_map(|b| {
                b.joint.scalar().map(|value| JointCoordinate {
                    bone: b.name.clone(),
                    value,
                })
            })
            .collect()
    });
    let mut elev = Vec::new();
    let mut len = Vec::new();
    for a in arms {
        let d = q[a.tip] - centroid(q, &a.shoulder_vertices);
        elev.push(elevation_deg(&d));
        len.push(d.norm() / a.rest_length);
    }
    Sample {
        time: s.time,
        joints,
        arm_elevation_deg: elev,
        arm_length_ratio: len,
        height_ratio: height(q) / rest_height,
        span_ratio: span(q, arms) / rest_span,
        iterations: s.iterations,
        wall_ms: s.wall_ms,
        bone_length_error: s.bone_length_error,
        contacts: s.contacts,
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Front views (`x`, `y`) taken during a run.
type Views = Vec<Panel>;

fn run(sc: &Scene, with_bones: bool, steps: usize, arms: &[Arm]) -> Result<(Run, Views)> {
    let mut model = sc.model.clone();
    if !with_bones {
        model.remove_skeleton();
    }
    let rest_height = height(model.rest());
    let rest_span = span(model.rest(), arms);
    let mut sim = Simulator::new(model, sc.settings.clone())?;
    let mut samples = Vec::with_capacity(steps);
    let mut max_pen = 0.0f64;
    let mut converged = 0;
    let mut views = Vec::new();
    let every = (steps / 5).max(1);
    for k in 0..steps {
        let s = sim.step()?;
        max_pen = max_pen.max(s.max_penetration);
        converged += usize::from(s.converged);
        samples.push(sample(&sim, &s, arms, rest_height, rest_span));
        if (k + 1) % every == 0 {
            views.push(Panel {
                title: format!("{} t = {:.2} s", if with_bones { "bones" } else { "no bones" }, s.time),
                points: sim.state().q.iter().map(|p| (p.x, p.y)).collect(),
            });
        }
    }
    let run = Run {
        with_bones,
        steps,
        median_ms_per_step: median(samples.iter().map(|s| s.wall_ms).collect()),
        mean_iterations: samples.iter().map(|s| s.iterations as f64).sum::<f64>() / steps.max(1) as f64,
        converged_steps: converged,
        max_bone_length_error: samples.iter().map(|s| s.bone_length_error).fold(0.0, f64::max),
        max_penetration: max_pen,
        samples,
    };
    Ok((run, views))
}

fn cost(sc: &Scene, iterations: usize, steps: usize) -> Result<Cost> {
    let time = |with_bones: bool| -> Result<f64> {
        let mut model = sc.model.clone();
        if !with_bones {
            model.remove_skeleton();
        }
        let mut settings = sc.settings.clone();
        settings.max_iterations = iterations;
        settings.tolerance = 0.0;
        settings.anderson = 0;
        let mut sim = Simulator::new(model, settings)?;
        let mut ms = Vec::with_capacity(steps);
        for _ in 0..steps {
            ms.push(sim.step()?.wall_ms);
        }
        Ok(median(ms))
    };
    let (with_bones_ms, without_bones_ms) = (time(true)?, time(false)?);
    Ok(Cost {
        iterations,
        steps,
        threads: rayon::current_num_threads(),
        with_bones_ms,
        without_bones_ms,
        ratio: with_bones_ms / without_bones_ms,
    })
}

/// Run the study on `scene` for `steps` steps; `arm_bones` names the driven arm bones.
pub fn study(scene_path: &Path, steps: usize, arm_bones: &[String], out: &Path) -> Result<SkeletonReport> {
    let sc = scene::load(scene_path, LoadOptions::default()).map_err(|e| anyhow!("{e}"))?;
    let arms = arms(&sc, arm_bones)?;
    let sk = sc.model.skeleton().expect("checked by arms()");
    let bones = sk
        .bones
        .iter()
        .map(|b| BoneJoint {
            bone: b.name.clone(),
            joint: b.joint.kind().to_string(),
        })
        .collect();
    let (with, views_with) = run(&sc, true, steps, &arms)?;
    let (without, views_without) = run(&sc, false, steps, &arms)?;
    let cost = cost(&sc, 5, 100)?;
    let last = |r: &Run| r.samples.last().cloned().expect("at least one step");
    let (lw, lo) = (last(&with), last(&without));
    let lift: Vec<f64> = arms
        .iter()
        .enumerate()
        .map(|(k, a)| lw.arm_elevation_deg[k] - a.rest_elevation_deg)
        .collect();
    let droop: Vec<f64> = (0..arms.len())
        .map(|k| lw.arm_elevation_deg[k] - lo.arm_elevation_deg[k])
        .collect();
    let verdicts = vec![
        Verdict::at_most(
            "Bone vertices keep their rest distances during the run with bones (the paper reports 0; m)",
            with.max_bone_length_error,
            1e-12,
        ),
        Verdict::new(
            "With bones and shoulder torques the arms lift (Fig. 5b): every driven arm ends at least 20 degrees above its rest elevation",
            lift.iter().all(|&d| d >= 20.0),
            Some(lift.iter().copied().fold(f64::INFINITY, f64::min)),
            Some(20.0),
            "measured = smallest elevation gain (degrees) at the end of the run",
        ),
        Verdict::new(
            "Without bones the body does not hold its shape (Fig. 5e, legs collapse): its final height is at most 3/4 of the height with bones",
            lo.height_ratio <= 0.75 * lw.height_ratio,
            Some(lo.height_ratio),
            Some(0.75 * lw.height_ratio),
            "measured = final height ratio without bones; threshold = 3/4 of that with bones",
        ),
        Verdict::new(
            "Without bones the arms are not held up (Fig. 5e): every arm ends at least 20 degrees lower than with bones",
            droop.iter().all(|&d| d >= 20.0),
            Some(droop.iter().copied().fold(f64::INFINITY, f64::min)),
            Some(20.0),
            "measured = smallest elevation difference with - without bones (degrees) at the end",
        ),
        Verdict::at_most(
            "The skeleton's reduced step costs at most 1.5x the plain step per local-global iteration (same scene, 5 iterations per step)",
            cost.ratio,
            1.5,
        ),
        Verdict::new(
            "Every step of both runs met the tolerance",
            with.converged_steps == steps && without.converged_steps == steps,
            None,
            None,
            "informational",
        ),
    ];
    let (lo_x, hi_x, lo_y, hi_y) = sc.model.rest().iter().fold(
        (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY),
        |(a, b, c, d), p| (a.min(p.x), b.max(p.x), c.min(p.y), d.max(p.y)),
    );
    let (w, h) = (hi_x - lo_x, hi_y - lo_y);
    plot::write_snapshots_svg(
        &diffsoft::output::own_file(out, "skeleton_frames.svg")?,
        &Snapshots {
            title: "Front views: with bones and shoulder torques (top, Fig. 5b) and without bones (bottom, Fig. 5e)"
                .into(),
            rows: vec![views_with, views_without],
            x_range: (lo_x - 0.2 * w, hi_x + 0.2 * w),
            y_range: (lo_y - 0.3 * h, hi_y + 0.4 * h),
        },
    )?;
    let series = |r: &Run, k: usize, label: &str| Series {
        label: label.to_string(),
        points: r.samples.iter().map(|s| (s.time, s.arm_elevation_deg[k])).collect(),
    };
    let mut chart = LinearChart {
        title: "Arm elevation: embedded skeleton with shoulder torques vs no bones (paper Fig. 5b/5e)".into(),
        x_label: "time (s)".into(),
        y_label: "arm elevation above horizontal (degrees)".into(),
        series: Vec::new(),
    };
    for (k, a) in arms.iter().enumerate() {
        chart
            .series
            .push(series(&with, k, &format!("{} arm, with bones", a.bone)));
        chart
            .series
            .push(series(&without, k, &format!("{} arm, no bones", a.bone)));
    }
    plot::write_linear_svg(&diffsoft::output::own_file(out, "skeleton_arms.svg")?, &chart)?;
    let joints = LinearChart {
        title: "Joint angles with shoulder torques (paper Fig. 5b)".into(),
        x_label: "time (s)".into(),
        y_label: "joint angle (rad)".into(),
        series: with.samples[0]
            .joints
            .iter()
            .enumerate()
            .map(|(j, joint)| Series {
                label: joint.bone.clone(),
                points: with.samples.iter().map(|s| (s.time, s.joints[j].value)).collect(),
            })
            .collect(),
    };
    plot::write_linear_svg(&diffsoft::output::own_file(out, "skeleton_joints.svg")?, &joints)?;
    Ok(SkeletonReport {
        header: Header::new(SCHEMA),
        scene: scene_path.display().to_string(),
        size: ModelSize::of(&sc.model),
        bones,
        arms,
        with_bones: with,
        without_bones: without,
        cost,
        verdicts,
    })
}
