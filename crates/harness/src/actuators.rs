//! The actuator study (`reports/actuators.json`, appendix D):
//!
//! * **static checks with closed-form answers**: a free cube made entirely of pneumatic cells
//!   and a free bar made entirely of muscle fibres are solved to static equilibrium. Their exact
//!   solution is a homogeneous deformation that minimises the energy density (so it is
//!   stress-free), which gives the expected volume ratio and fibre stretch without any mesh
//!   error: measured against expected to the solver tolerance;
//! * **a pneumatic beam** (clamped, cells in its top half): expanding cells (`a > 1`) bend it
//!   away from them (the expanded side becomes convex), contracting cells (`a < 1`) bend it
//!   toward them; the curvature is compared with Timoshenko's equal-layer bimorph estimate
//!   `kappa = 3 eps / (2 h)` from the cells' free expansion `eps` (an estimate only: the cells
//!   also add volumetric stiffness to the top layer);
//! * **the paper's scenes from its files**: the drone gripper (`droneman.json`, pneumatic
//!   "Volume Verts" groups) closes its arms when its cells expand, and the octopus
//!   (`octopus.json`, 16 muscles from `octopus.muscle`) moves the tentacle of the one muscle
//!   that is activated; both write VTK frames.

use std::path::Path;

use anyhow::{anyhow, Result};
use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

use crate::report::{Header, ModelSize, Verdict};
use diffsoft::actuator::{fibres_along, ActuatorSpec};
use diffsoft::base::Material;
use diffsoft::base::Schedule;
use diffsoft::kernel::volume::nearest_product;
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::model::{BodySpec, MassSpec, ModelBuilder};
use diffsoft::output::FrameWriter;
use diffsoft::scene::{self, LoadOptions};
use diffsoft::solver::{Settings, Simulator, SolverKind};

/// Schema of `reports/actuators.json`.
pub const SCHEMA: &str = "diffsoft.actuators/2";

/// Material of the static checks.
const MATERIAL: Material = Material {
    youngs_modulus: 1e5,
    poisson_ratio: 0.3,
};

/// One static check against a closed form.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct StaticCheck {
    /// What is measured.
    pub name: String,
    /// Activation (1: the pneumatic target volume ratio, or the muscle contraction).
    pub activation: f64,
    /// Actuator stiffness (Pa).
    pub stiffness: f64,
    /// Measured value (1: a volume ratio or a stretch, as `name` says).
    pub measured: f64,
    /// Closed-form value (1).
    pub expected: f64,
    /// `|measured - expected| / |expected|` (1).
    pub relative_error: f64,
    /// Local-global iterations of the static solve.
    pub iterations: usize,
}

/// One run of the pneumatic beam.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct BeamRun {
    /// Activation of the top-half cells (1: target volume ratio).
    pub activation: f64,
    /// Free linear expansion of the cells' material `s* - 1` (1).
    pub free_strain: f64,
    /// Tip deflection along `+y` (the cells are on the `+y` side), m.
    pub tip_deflection: f64,
    /// Measured curvature `2 w / L^2` (1/m; positive: bends toward the cells).
    pub curvature: f64,
    /// Equal-layer bimorph estimate `-3 eps / (2 h)` (1/m; same sign convention).
    pub bimorph_estimate: f64,
    /// Local-global iterations of the static solve.
    pub iterations: usize,
}

/// An actuator group held at an activation.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct GroupActivation {
    /// The group's name.
    pub group: String,
    /// Its activation (1: pneumatic volume ratio, muscle contraction).
    pub activation: f64,
}

/// The number of actuated tets of a group.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct GroupCells {
    /// The group's name.
    pub group: String,
    /// Its actuated tets.
    pub cells: usize,
}

/// A measure at one time.
#[derive(Debug, Clone, Copy, Serialize, schemars::JsonSchema)]
pub struct TimeValue {
    /// Simulated time (s).
    pub time: f64,
    /// The measure (its unit is in the run's `measure`: m for both scenes of the study).
    pub value: f64,
}

/// A paper scene driven by its actuators.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct SceneRun {
    /// Scene file.
    pub scene: String,
    /// Vertices and tets.
    pub size: ModelSize,
    /// Groups driven and their activation.
    pub driven: Vec<GroupActivation>,
    /// Actuated tets per group.
    pub cells_per_group: Vec<GroupCells>,
    /// Steps.
    pub steps: usize,
    /// The measure, in words.
    pub measure: String,
    /// The measure at the start and after every step.
    pub series: Vec<TimeValue>,
    /// A control measure (what should not move), over time.
    pub control: Vec<TimeValue>,
    /// Median wall time per step (ms).
    pub median_ms_per_step: f64,
    /// Mean local-global iterations per step.
    pub mean_iterations: f64,
    /// Frames written (VTK, `.pvd` index in this folder).
    pub frames: String,
}

/// `reports/actuators.json`.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct ActuatorsReport {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// Static checks.
    pub statics: Vec<StaticCheck>,
    /// Pneumatic beam runs.
    pub beam: Vec<BeamRun>,
    /// Drone gripper.
    pub drone: SceneRun,
    /// Octopus.
    pub octopus: SceneRun,
    /// Claims.
    pub verdicts: Vec<Verdict>,
}

/// Static settings: one implicit step with a huge time step is a static solve (Anderson-accelerated).
fn static_settings() -> Settings {
    Settings {
        dt: 1e3,
        solver: SolverKind::Direct,
        max_iterations: 20_000,
        tolerance: 1e-11,
        anderson: 5,
        ..Settings::default()
    }
}

/// The best-fit homogeneous `F` of a deformed body (least squares over all vertices).
pub fn fitted_gradient(rest: &[Vector3<f64>], q: &[Vector3<f64>]) -> Matrix3<f64> {
    let n = rest.len() as f64;
    let (xc, qc) = (
        rest.iter().sum::<Vector3<f64>>() / n,
        q.iter().sum::<Vector3<f64>>() / n,
    );
    let (mut a, mut b) = (Matrix3::zeros(), Matrix3::zeros());
    for (x, y) in rest.iter().zip(q) {
        let (dx, dy) = (x - xc, y - qc);
        a += dy * dx.transpose();
        b += dx * dx.transpose();
    }
    a * b.try_inverse().unwrap_or_else(Matrix3::identity)
}

/// Free expansion `s*` of material with actuator weight `k` (per volume) at pneumatic
/// activation `a`: the minimiser of `(w_r + w_v)(s - 1)^2 + k (s - a^(1/3))^2`.
pub fn free_expansion(material: &Material, k: f64, a: f64) -> f64 {
    let w = material.rotation_stiffness() + material.volume_stiffness();
    (w + k * a.cbrt()) / (w + k)
}

/// Gradient of the energy density of a homogeneous `F = diag(s1, s2, s2)` of muscle material
/// (fibres along the first axis) with respect to `(s1, s2)`: each term is a squared distance to a
/// set, whose gradient is `w (s - nearest)` (times 2 for the density's `1/2`-free form).
fn muscle_gradient(material: &Material, k: f64, a: f64, s1: f64, s2: f64) -> (f64, f64) {
    let s = Vector3::new(s1, s2, s2);
    let r = s - nearest_product(&s, 1.0).unwrap_or(s);
    let (wr, wv) = (material.rotation_stiffness(), material.volume_stiffness());
    (
        wr * (s1 - 1.0) + wv * r[0] + k * (s1 - (1.0 - a)),
        2.0 * wr * (s2 - 1.0) + wv * (r[1] + r[2]),
    )
}

/// The root of an increasing function on `[lo, hi]` by bisection (to round-off).
fn bisect(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if f(mid) > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The stress-free stretches `(s1, s2)` of muscle material (fibres along axis 1): the zero of
/// the energy density's gradient, by nested bisection (the density is convex in each stretch
/// near the rest state).
pub fn muscle_stretches(material: &Material, k: f64, a: f64) -> (f64, f64) {
    let best_s2 = |s1: f64| bisect(|s2| muscle_gradient(material, k, a, s1, s2).1, 0.3, 3.0);
    // Along the optimal s2(s1), d/ds1 f = the partial derivative (envelope theorem).
    let s1 = bisect(|s1| muscle_gradient(material, k, a, s1, best_s2(s1)).0, 0.05, 1.5);
    (s1, best_s2(s1))
}

fn body(mesh: diffsoft::mesh::TetMesh, actuators: Vec<ActuatorSpec>) -> BodySpec {
    let mut b = BodySpec::new("body", mesh, MATERIAL, MassSpec::Density(1000.0));
    b.gravity = false;
    b.fixed = vec![0];
    b.actuators = actuators;
    b
}

/// A free 0.1 m cube of pneumatic cells at activation `a`: measured and expected volume ratio.
pub fn pneumatic_cube(k: f64, a: f64) -> Result<StaticCheck> {
    let mesh = BoxSpec::new([3, 3, 3], [0.1; 3]).build()?;
    let all: Vec<usize> = (0..mesh.num_tets()).collect();
    let spec = ActuatorSpec::pneumatic("cells", &all, k, Schedule::constant(a));
    let model = ModelBuilder::new().body(body(mesh, vec![spec])).build()?;
    let rest = model.rest().to_vec();
    let mut sim = Simulator::new(model, static_settings())?;
    let st = sim.step()?;
    let f = fitted_gradient(&rest, &sim.state().q);
    let expected = free_expansion(&MATERIAL, k, a).powi(3);
    let measured = f.determinant();
    Ok(StaticCheck {
        name: "pneumatic cube: volume ratio".into(),
        activation: a,
        stiffness: k,
        measured,
        expected,
        relative_error: (measured - expected).abs() / expected,
        iterations: st.iterations,
    })
}

/// A free 0.4 x 0.1 x 0.1 m bar of muscle fibres along `x` at activation `a`: measured and
/// expected fibre stretch and cross-section stretch.
pub fn muscle_bar(k: f64, a: f64) -> Result<[StaticCheck; 2]> {
    let mesh = BoxSpec::new([8, 2, 2], [0.4, 0.1, 0.1]).build()?;
    let all: Vec<usize> = (0..mesh.num_tets()).collect();
    let spec = ActuatorSpec::muscle("fibres", fibres_along(&all, Vector3::x()), k, Schedule::constant(a));
    let model = ModelBuilder::new().body(body(mesh, vec![spec])).build()?;
    let rest = model.rest().to_vec();
    let mut sim = Simulator::new(model, static_settings())?;
    let st = sim.step()?;
    let f = fitted_gradient(&rest, &sim.state().q);
    let (s1, s2) = muscle_stretches(&MATERIAL, k, a);
    let along = (f * Vector3::x()).norm();
    let across = 0.5 * ((f * Vector3::y()).norm() + (f * Vector3::z()).norm());
    let check = |name: &str, measured: f64, expected: f64| StaticCheck {
        name: name.into(),
        activation: a,
        stiffness: k,
        measured,
        expected,
        relative_error: (measured - expected).abs() / expected,
        iterations: st.iterations,
    };
    Ok([
        check("muscle bar: stretch along the fibres", along, s1),
        check("muscle bar: stretch across the fibres", across, s2),
    ])
}

/// A clamped 1 x 0.1 x 0.1 m beam whose top half (`y > 0.05`) is pneumatic at activation `a`.
pub fn pneumatic_beam(k: f64, a: f64) -> Result<BeamRun> {
    let (l, h) = (1.0, 0.1);
    let mesh = BoxSpec::new([20, 4, 2], [l, h, h]).build()?;
    let top: Vec<usize> = (0..mesh.num_tets())
        .filter(|&t| diffsoft::actuator::centroid(&mesh, t).y > 0.5 * h)
        .collect();
    let fixed: Vec<usize> = (0..mesh.num_vertices())
        .filter(|&i| mesh.vertices[i].x < 1e-9)
        .collect();
    let tip: Vec<usize> = (0..mesh.num_vertices())
        .filter(|&i| (mesh.vertices[i].x - l).abs() < 1e-9)
        .collect();
    let mut b = body(
        mesh,
        vec![ActuatorSpec::pneumatic("top", &top, k, Schedule::constant(a))],
    );
    b.fixed = fixed;
    let model = ModelBuilder::new().body(b).build()?;
    let rest = model.rest().to_vec();
    let mut sim = Simulator::new(model, static_settings())?;
    let st = sim.step()?;
    let w = tip.iter().map(|&i| sim.state().q[i].y - rest[i].y).sum::<f64>() / tip.len() as f64;
    let eps = free_expansion(&MATERIAL, k, a) - 1.0;
    Ok(BeamRun {
        activation: a,
        free_strain: eps,
        tip_deflection: w,
        curvature: 2.0 * w / (l * l),
        bimorph_estimate: -1.5 * eps / h,
        iterations: st.iterations,
    })
}

/// A measure and a control measure of a state.
type Measure = dyn Fn(&[Vector3<f64>]) -> (f64, f64);

/// Run a paper scene with some groups held at activations, measuring `measure` (and a control)
/// every `every` steps; frames go to `frames`.
#[allow(clippy::too_many_arguments)]
fn drive(
    path: &Path,
    driven: &[(String, f64)],
    steps: usize,
    every: usize,
    frames: &Path,
    measure_name: &str,
    measure: &Measure,
) -> Result<SceneRun> {
    let sc = scene::load(path, LoadOptions::default())?;
    let size = ModelSize::of(&sc.model);
    let cells_per_group = sc
        .model
        .actuators()
        .map(|a| {
            a.groups
                .iter()
                .map(|g| GroupCells {
                    group: g.name.clone(),
                    cells: g.cells.len(),
                })
                .collect()
        })
        .unwrap_or_default();
    let mut sim = Simulator::new(sc.model, sc.settings)?;
    for (name, a) in driven {
        sim.set_activation(name, *a)?;
    }
    if frames.exists() {
        std::fs::remove_dir_all(frames)?;
    }
    let mut writer = FrameWriter::new(frames, sim.model())?;
    writer.write(0.0, &sim.state().q, &sim.state().v)?;
    let (m0, c0) = measure(&sim.state().q);
    let at = |time, value| TimeValue { time, value };
    let (mut series, mut control) = (vec![at(0.0, m0)], vec![at(0.0, c0)]);
    let mut stats = Vec::new();
    for k in 1..=steps {
        stats.push(sim.step()?);
        let t = sim.state().time;
        let (m, c) = measure(&sim.state().q);
        series.push(at(t, m));
        control.push(at(t, c));
        if k % every == 0 || k == steps {
            writer.write(t, &sim.state().q, &sim.state().v)?;
        }
    }
    let summary = diffsoft::output::RunSummary::of(&stats);
    Ok(SceneRun {
        scene: path.display().to_string(),
        size,
        driven: driven
            .iter()
            .map(|(group, activation)| GroupActivation {
                group: group.clone(),
                activation: *activation,
            })
            .collect(),
        cells_per_group,
        steps,
        measure: measure_name.into(),
        series,
        control,
        median_ms_per_step: summary.median_ms_per_step,
        mean_iterations: summary.mean_iterations,
        frames: frames.display().to_string(),
    })
}

/// The drone gripper: every pneumatic group at `a`; measure = mean distance of the arm tips
/// (the top 5% of the drone's vertices) from the vertical axis, control = mean height of the
/// hub (the bottom 5%).
pub fn drone(path: &Path, a: f64, steps: usize, frames: &Path) -> Result<SceneRun> {
    let sc = scene::load(path, LoadOptions::default())?;
    let body = sc
        .model
        .bodies()
        .first()
        .ok_or_else(|| anyhow!("the drone scene has no body"))?;
    let range = body.vertices.clone();
    let groups: Vec<(String, f64)> = sc
        .model
        .actuators()
        .ok_or_else(|| anyhow!("the drone scene has no actuators"))?
        .groups
        .iter()
        .map(|g| (g.name.clone(), a))
        .collect();
    let mut ys: Vec<f64> = range.clone().map(|i| sc.model.rest()[i].y).collect();
    ys.sort_by(f64::total_cmp);
    let (lo, hi) = (ys[ys.len() / 20], ys[ys.len() - 1 - ys.len() / 20]);
    let tips: Vec<usize> = range.clone().filter(|&i| sc.model.rest()[i].y >= hi).collect();
    let hub: Vec<usize> = range.filter(|&i| sc.model.rest()[i].y <= lo).collect();
    drop(sc);
    let measure = move |q: &[Vector3<f64>]| {
        let r = tips
            .iter()
            .map(|&i| (q[i].x.powi(2) + q[i].z.powi(2)).sqrt())
            .sum::<f64>()
            / tips.len() as f64;
        let y = hub.iter().map(|&i| q[i].y).sum::<f64>() / hub.len() as f64;
        (r, y)
    };
    drive(
        path,
        &groups,
        steps,
        (steps / 5).max(1),
        frames,
        "mean distance of the arm tips from the vertical axis (m); control: mean height of the hub (m)",
        &measure,
    )
}

/// The octopus: `muscle` at `a`; measure = displacement of that muscle's tentacle tip (the
/// vertex of its cells farthest from the body's centre), control = the largest displacement of
/// the tips of the muscles in other tentacles (the whole body also turns and drifts in reaction
/// to the arm, which moves the other tips too).
pub fn octopus(path: &Path, muscle: &str, a: f64, steps: usize, frames: &Path) -> Result<SceneRun> {
    let sc = scene::load(path, LoadOptions::default())?;
    let act = sc
        .model
        .actuators()
        .ok_or_else(|| anyhow!("the octopus scene has no actuators"))?;
    let centre = sc.model.rest().iter().sum::<Vector3<f64>>() / sc.model.n() as f64;
    // Tip of each group: the vertex (of its tets) farthest from the centre.
    let tips: Vec<(String, usize)> = act
        .groups
        .iter()
        .map(|g| {
            let v = act.cells[g.cells.clone()]
                .iter()
                .flat_map(|c| sc.model.tets()[c.tet])
                .max_by(|&i, &j| {
                    (sc.model.rest()[i] - centre)
                        .norm()
                        .total_cmp(&(sc.model.rest()[j] - centre).norm())
                })
                .unwrap_or(0);
            (g.name.clone(), v)
        })
        .collect();
    let driven_tip = tips
        .iter()
        .find(|(n, _)| n == muscle)
        .map(|t| t.1)
        .ok_or_else(|| anyhow!("no muscle named {muscle}"))?;
    // Other tentacles: tips farther than a quarter of the body's radius from the driven one
    // (each tentacle carries two muscles).
    let radius = sc.model.rest().iter().map(|x| (x - centre).norm()).fold(0.0, f64::max);
    let others: Vec<usize> = tips
        .iter()
        .filter(|(_, v)| (sc.model.rest()[*v] - sc.model.rest()[driven_tip]).norm() > 0.25 * radius)
        .map(|t| t.1)
        .collect();
    let rest = sc.model.rest().to_vec();
    drop(sc);
    let measure = move |q: &[Vector3<f64>]| {
        let d = (q[driven_tip] - rest[driven_tip]).norm();
        let c = others.iter().map(|&i| (q[i] - rest[i]).norm()).fold(0.0, f64::max);
        (d, c)
    };
    drive(
        path,
        &[(muscle.to_string(), a)],
        steps,
        (steps / 5).max(1),
        frames,
        "displacement of the driven muscle's tentacle tip (m); control: largest displacement of a tip in another tentacle (m)",
        &measure,
    )
}

/// Settings of the study (from the suite).
#[derive(Debug, Clone)]
pub struct StudyInputs<'a> {
    /// Drone scene.
    pub drone: &'a Path,
    /// Drone activation.
    pub drone_activation: f64,
    /// Drone steps.
    pub drone_steps: usize,
    /// Octopus scene.
    pub octopus: &'a Path,
    /// Driven muscle.
    pub octopus_muscle: &'a str,
    /// Its activation.
    pub octopus_activation: f64,
    /// Octopus steps.
    pub octopus_steps: usize,
}

/// Run the whole study; frames go under `out/frames/`.
pub fn study(inputs: &StudyInputs<'_>, out: &Path) -> Result<ActuatorsReport> {
    let k = 1e5;
    let mut statics = Vec::new();
    for a in [0.5, 2.0] {
        statics.push(pneumatic_cube(k, a)?);
    }
    for a in [0.1, 0.3] {
        statics.extend(muscle_bar(5e5, a)?);
    }
    let beam = vec![pneumatic_beam(k, 1.5)?, pneumatic_beam(k, 0.7)?];
    let drone = drone(
        inputs.drone,
        inputs.drone_activation,
        inputs.drone_steps,
        &out.join("frames/droneman"),
    )?;
    let octopus = octopus(
        inputs.octopus,
        inputs.octopus_muscle,
        inputs.octopus_activation,
        inputs.octopus_steps,
        &out.join("frames/octopus"),
    )?;
    let worst = statics.iter().map(|s| s.relative_error).fold(0.0, f64::max);
    let bends = beam
        .iter()
        .all(|b| b.curvature.signum() == (1.0 - b.activation).signum());
    let ratio = beam
        .iter()
        .map(|b| b.curvature / b.bimorph_estimate)
        .fold(f64::NAN, |m: f64, r| if m.is_nan() { r } else { m.min(r) });
    let tip = octopus.series.iter().map(|c| c.value).fold(0.0, f64::max);
    let others = octopus.control.iter().map(|c| c.value).fold(0.0, f64::max);
    let mean = |s: &[TimeValue]| s.iter().map(|p| p.value).sum::<f64>() / s.len().max(1) as f64;
    let closed = (drone.series[0].value - mean(&drone.series)) / drone.series[0].value;
    let verdicts = vec![
        Verdict::at_most(
            "Static pneumatic cube and muscle bar reach the closed-form homogeneous deformation (volume ratio; fibre and cross-section stretch)",
            worst,
            1e-9,
        ),
        Verdict::new(
            "A pneumatic beam bends away from expanding cells (a > 1: that side becomes convex) and toward contracting ones (a < 1)",
            bends,
            None,
            None,
            "sign of the tip deflection against 1 - a",
        ),
        Verdict::new(
            "Its curvature is within a factor 2 of the equal-layer bimorph estimate 3 eps / (2 h)",
            beam.iter().all(|b| {
                let r = b.curvature / b.bimorph_estimate;
                (0.5..=2.0).contains(&r)
            }),
            Some(ratio),
            Some(0.5),
            "0.5 <= measured / estimate <= 2 for every run (measured = smallest ratio)",
        ),
        Verdict::new(
            "The paper's drone gripper closes its arms when its pneumatic cells expand: averaged over the run (the undamped arms swing about their new equilibrium), the arm tips are at least 5% closer to the axis than at rest",
            closed >= 0.05,
            Some(closed),
            Some(0.05),
            "1 - mean over the run / rest value of the tips' distance from the axis >= threshold",
        ),
        Verdict::new(
            "The paper's octopus moves the tentacle of the activated muscle: over the run its tip moves at least 3 times farther than the tip of any other tentacle (which move only as the body reacts)",
            tip > 3.0 * others && tip > 0.0,
            Some(tip / others.max(f64::MIN_POSITIVE)),
            Some(3.0),
            "largest driven tip displacement / largest displacement of another tentacle's tip >= threshold",
        ),
    ];
    Ok(ActuatorsReport {
        header: Header::new(SCHEMA),
        statics,
        beam,
        drone,
        octopus,
        verdicts,
    })
}

/// The lines `diffsoft verify` prints for the actuator study.
pub fn table(r: &ActuatorsReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "  {:<42} {:>6} {:>14} {:>14} {:>10} {:>6}",
        "static check", "a", "measured", "expected", "rel err", "its"
    );
    for c in &r.statics {
        let _ = writeln!(
            s,
            "  {:<42} {:>6} {:>14.10} {:>14.10} {:>10.2e} {:>6}",
            c.name, c.activation, c.measured, c.expected, c.relative_error, c.iterations
        );
    }
    for b in &r.beam {
        let _ = writeln!(
            s,
            "  pneumatic beam a = {:<4}: tip {:+.4} m, curvature {:+.3} 1/m (bimorph estimate {:+.3})",
            b.activation, b.tip_deflection, b.curvature, b.bimorph_estimate
        );
    }
    for run in [&r.drone, &r.octopus] {
        let first = run.series.first().map_or(f64::NAN, |p| p.value);
        let mean = run.series.iter().map(|p| p.value).sum::<f64>() / run.series.len().max(1) as f64;
        let max = run.series.iter().map(|p| p.value).fold(f64::NAN, f64::max);
        let control = run.control.iter().map(|p| p.value).fold(f64::NAN, f64::max);
        let _ = writeln!(
            s,
            "  {}: {} steps, {:.3} ms/step, {:.2} it/step; measure start {:.4}, mean {:.4}, max {:.4}; control max {:.4}",
            run.scene, run.steps, run.median_ms_per_step, run.mean_iterations, first, mean, max, control
        );
    }
    for v in &r.verdicts {
        let _ = writeln!(s, "  [{}] {}", if v.holds { "holds" } else { "FAILS" }, v.claim);
    }
    s
}
