//! The cloth study (`reports/cloth.json`): the paper's ball-on-cloth scene (appendix E,
//! Fig. 6) run from its own file, and the cost of collision detection against mesh size.
//!
//! Each step's end state is probed: the smallest distance between the ball's surface and the
//! cloth (vertex-face and edge-edge), surface edges of one body crossing a face of the other
//! (interpenetration), the cloth's principal stretches (singular values of each triangle's
//! in-plane deformation gradient) and the ball's (of each tet's deformation gradient), the
//! contacts between the bodies and the wall time of the step.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

use crate::plot::{self, LinearChart, LogLogChart, Panel, Series, Snapshots};
use crate::report::{Header, Verdict};
use diffsoft::contact::pair::{Detector, Query};
use diffsoft::kernel::svd::svd3;
use diffsoft::model::Model;
use diffsoft::output::FrameWriter;
use diffsoft::scene::{self, LoadOptions};
use diffsoft::solver::Simulator;
pub use diffsoft::testing::{check_cloth_size, detection_scene};

/// Schema of `cloth.json`.
pub const CLOTH_SCHEMA: &str = "diffsoft.cloth/2";

/// One step's probe.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct ClothStep {
    /// Step (1-based).
    pub step: usize,
    /// Time (s).
    pub time: f64,
    /// Smallest distance between the bodies' surfaces (m; `null` when farther than 10
    /// thicknesses).
    pub min_distance: Option<f64>,
    /// Surface edges crossing a face of the other body.
    pub intersections: usize,
    /// Deepest crossing (m; 0 without crossings, see [`diffsoft::contact::pair::Probe`]).
    pub penetration: f64,
    /// Contacts between the bodies in the step's last round.
    pub pair_contacts: usize,
    /// Largest principal stretch of a cloth triangle (1).
    pub cloth_max_stretch: f64,
    /// Smallest principal stretch of a cloth triangle (1).
    pub cloth_min_stretch: f64,
    /// Largest `|sigma - 1|` of a tet of the soft bodies (1).
    pub body_max_strain: f64,
    /// Lowest cloth vertex (m).
    pub cloth_lowest: f64,
    /// Local-global iterations.
    pub iterations: usize,
    /// Contact rounds.
    pub contact_rounds: usize,
    /// Projected Gauss-Seidel sweeps.
    pub contact_sweeps: usize,
    /// Wall time (ms).
    pub wall_ms: f64,
}

/// Size of a model with cloth.
#[derive(Debug, Clone, Copy, Serialize, schemars::JsonSchema)]
pub struct ClothSize {
    /// Vertices (every body and cloth).
    pub vertices: usize,
    /// Tets (every soft body).
    pub tets: usize,
    /// Cloth triangles.
    pub cloth_triangles: usize,
}

/// The range of the cloth's principal stretches over a run.
#[derive(Debug, Clone, Copy, Serialize, schemars::JsonSchema)]
pub struct StretchRange {
    /// Largest principal stretch of a cloth triangle (1).
    pub largest: f64,
    /// Smallest principal stretch of a cloth triangle (1).
    pub smallest: f64,
}

/// Wall time per step over a set of steps.
#[derive(Debug, Clone, Copy, Serialize, schemars::JsonSchema)]
pub struct StepTimes {
    /// Median wall time per step (ms).
    pub median_ms: f64,
    /// Mean wall time per step (ms).
    pub mean_ms: f64,
}

impl StepTimes {
    fn of(ms: &[f64]) -> Self {
        Self {
            median_ms: median(ms.to_vec()),
            mean_ms: mean(ms),
        }
    }
}

/// The run of one scene.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct ClothRun {
    /// Scene file.
    pub scene: String,
    /// Importer notes.
    pub notes: Vec<String>,
    /// Vertices, tets and cloth triangles.
    pub size: ClothSize,
    /// Collision thickness (m).
    pub thickness: f64,
    /// Time step (s).
    pub dt: f64,
    /// Steps run.
    pub steps: usize,
    /// First step with contacts between the bodies.
    pub first_contact_step: Option<usize>,
    /// Deepest penetration of one body's surface through the other's over the run (m): 0 when
    /// no surface edge ever crossed a face of the other body.
    pub max_penetration: f64,
    /// Smallest distance between the surfaces over the run (m).
    pub min_separation: Option<f64>,
    /// How far the surfaces came into the collision thickness, `max(0, thickness -
    /// min_separation)` (m).
    pub thickness_intrusion: f64,
    /// Interpenetrating edge-face pairs summed over all step ends (0: the surfaces never
    /// crossed).
    pub intersections: usize,
    /// Largest and smallest principal stretch of the cloth over the run.
    pub cloth_stretch_range: StretchRange,
    /// Largest `|sigma - 1|` of the soft body over the run (1).
    pub body_max_strain: f64,
    /// Median and mean wall time per step.
    pub ms_per_step: StepTimes,
    /// Median and mean wall time per step while the bodies touch.
    pub ms_per_contact_step: StepTimes,
    /// Largest number of contacts between the bodies.
    pub max_pair_contacts: usize,
    /// Per step.
    pub series: Vec<ClothStep>,
    /// Error that ended the run, if any.
    pub error: Option<String>,
    /// Positions at six evenly spaced steps (for the side-view plot).
    #[serde(skip)]
    pub snapshots: Vec<(f64, Vec<Vector3<f64>>)>,
}

/// Collision-detection cost at one mesh size.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct DetectionCost {
    /// Cloth grid cells per side.
    pub cloth_cells: usize,
    /// Surface triangles (both bodies).
    pub triangles: usize,
    /// Surface edges.
    pub edges: usize,
    /// Surface vertices.
    pub vertices: usize,
    /// Median time of a candidate pass (vertex-face) plus a violation pass (vertex-face and
    /// edge-edge) (ms).
    pub median_ms: f64,
    /// Pairs tested exactly in the two passes.
    pub tested: usize,
    /// Candidate contacts found.
    pub candidates: usize,
}

/// `cloth.json`.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct ClothReport {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// The scenes: the paper's from its file first.
    pub runs: Vec<ClothRun>,
    /// Collision-detection cost against size.
    pub detection: Vec<DetectionCost>,
    /// Fitted exponent of detection time against surface size (1).
    pub detection_exponent: f64,
    /// Claims.
    pub verdicts: Vec<Verdict>,
    /// Wall time of the study (s).
    pub wall_time_s: f64,
    /// Plots that could not be drawn (e.g. nothing to draw); the data above is complete.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub plot_errors: Vec<String>,
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The mean; 0 for none (a fold from +0: an empty `sum` of f64 is -0, printed "-0.00").
fn mean(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |a, b| a + b) / v.len().max(1) as f64
}

/// Largest `|sigma_i - 1|` over the tets at positions `q`.
fn body_strain(model: &Model, q: &[Vector3<f64>]) -> f64 {
    let mut worst: f64 = 0.0;
    for (t, tet) in model.tets().iter().enumerate() {
        let x0 = q[tet[0]];
        let f =
            Matrix3::from_columns(&[q[tet[1]] - x0, q[tet[2]] - x0, q[tet[3]] - x0]) * model.fem().geometry[t].p_inv;
        let s = svd3(&f).sigma;
        worst = worst.max(s.iter().map(|x| (x - 1.0).abs()).fold(0.0, f64::max));
    }
    worst
}

/// Run a scene with cloth and collisions between bodies for `steps` steps, probing every step
/// (frames every `every` steps into `frames`, when given).
pub fn run(scene_path: &Path, steps: usize, frames: Option<(&Path, usize)>) -> Result<ClothRun> {
    let sc =
        scene::load(scene_path, LoadOptions::default()).with_context(|| format!("loading {}", scene_path.display()))?;
    let model = sc.model.clone();
    let cloth = model
        .cloth()
        .with_context(|| format!("{}: the scene has no cloth", scene_path.display()))?;
    let col = model
        .collision()
        .with_context(|| format!("{}: the scene has no collisions between bodies", scene_path.display()))?;
    let thickness = col.settings.thickness;
    let mut sim = Simulator::new(sc.model, sc.settings.clone())?;
    let mut writer = match frames {
        Some((dir, _)) => Some(FrameWriter::new(dir, &model)?),
        None => None,
    };
    if let Some(w) = writer.as_mut() {
        w.write(0.0, &sim.state().q, &sim.state().v)?;
    }
    let mut det = Detector::default();
    let mut series = Vec::with_capacity(steps);
    let mut error = None;
    let picks: Vec<usize> = (0..6).map(|k| k * steps / 5).collect();
    let mut snapshots = vec![(0.0, sim.state().q.clone())];
    for _ in 0..steps {
        let st = match sim.step() {
            Ok(s) => s,
            Err(e) => {
                error = Some(e.to_string());
                break;
            }
        };
        let q = &sim.state().q;
        let probe = det.probe(col, q, 10.0 * thickness);
        let (hi, lo) = cloth.stretch_range(q);
        let lowest = cloth
            .bodies
            .iter()
            .flat_map(|b| b.vertices.clone())
            .map(|v| q[v].y)
            .fold(f64::INFINITY, f64::min);
        series.push(ClothStep {
            step: st.step,
            time: st.time,
            min_distance: probe.min_distance,
            intersections: probe.intersections,
            penetration: probe.penetration,
            pair_contacts: st.pair_contacts,
            cloth_max_stretch: hi,
            cloth_min_stretch: lo,
            body_max_strain: body_strain(&model, q),
            cloth_lowest: lowest,
            iterations: st.iterations,
            contact_rounds: st.contact_rounds,
            contact_sweeps: st.contact_iterations,
            wall_ms: st.wall_ms,
        });
        if picks[1..].contains(&st.step) {
            snapshots.push((st.time, sim.state().q.clone()));
        }
        if let (Some(w), Some((_, every))) = (writer.as_mut(), frames) {
            if st.step % every.max(1) == 0 {
                w.write(st.time, &sim.state().q, &sim.state().v)?;
            }
        }
    }
    let first_contact_step = series.iter().find(|s| s.pair_contacts > 0).map(|s| s.step);
    let max_penetration = series.iter().map(|s| s.penetration).fold(0.0, f64::max);
    let min_separation = series
        .iter()
        .filter_map(|s| s.min_distance)
        .fold(None, |a: Option<f64>, d| Some(a.map_or(d, |a| a.min(d))));
    let thickness_intrusion = min_separation.map_or(0.0, |d| (thickness - d).max(0.0));
    let contact_ms: Vec<f64> = series
        .iter()
        .filter(|s| s.pair_contacts > 0)
        .map(|s| s.wall_ms)
        .collect();
    let all_ms: Vec<f64> = series.iter().map(|s| s.wall_ms).collect();
    Ok(ClothRun {
        scene: scene_path.display().to_string(),
        notes: sc.notes,
        size: ClothSize {
            vertices: model.n(),
            tets: model.tets().len(),
            cloth_triangles: cloth.num_triangles(),
        },
        thickness,
        dt: sc.settings.dt,
        steps: series.len(),
        first_contact_step,
        max_penetration,
        min_separation,
        thickness_intrusion,
        intersections: series.iter().map(|s| s.intersections).sum(),
        cloth_stretch_range: StretchRange {
            largest: series.iter().map(|s| s.cloth_max_stretch).fold(0.0, f64::max),
            smallest: series.iter().map(|s| s.cloth_min_stretch).fold(f64::INFINITY, f64::min),
        },
        body_max_strain: series.iter().map(|s| s.body_max_strain).fold(0.0, f64::max),
        ms_per_step: StepTimes::of(&all_ms),
        ms_per_contact_step: StepTimes::of(&contact_ms),
        max_pair_contacts: series.iter().map(|s| s.pair_contacts).max().unwrap_or(0),
        series,
        error,
        snapshots,
    })
}

/// Time the detection passes of one step on [`detection_scene`]`(n)`: the body moves 2 mm down
/// into the cloth's thickness.
pub fn detection_cost(n: usize, repeats: usize) -> Result<DetectionCost> {
    let model = detection_scene(n)?;
    let col = model.collision().context("collisions")?;
    let q0 = model.rest().to_vec();
    let mut q1 = q0.clone();
    for v in model.bodies()[0].vertices.clone() {
        q1[v].y -= 2e-3;
    }
    let mut det = Detector::default();
    let mut out = Vec::new();
    let mut times = Vec::with_capacity(repeats);
    let (mut tested, mut found) = (0, 0);
    for _ in 0..repeats.max(1) {
        out.clear();
        let t = Instant::now();
        det.detect(col, &q0, &q1, Query::Candidates { margin: 1e-3 }, &mut out);
        tested = det.tested;
        found = out.len();
        det.remember(&out, true);
        det.detect(col, &q0, &q1, Query::Violations { tolerance: 1e-6 }, &mut out);
        tested += det.tested;
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    Ok(DetectionCost {
        cloth_cells: n,
        triangles: col.triangles.len(),
        edges: col.edges.len(),
        vertices: col.vertices.len(),
        median_ms: median(times),
        tested,
        candidates: found,
    })
}

/// Least-squares slope of `log y` against `log x`.
fn loglog_slope(xs: &[f64], ys: &[f64]) -> f64 {
    let lx: Vec<f64> = xs.iter().map(|x| x.ln()).collect();
    let ly: Vec<f64> = ys.iter().map(|y| y.ln()).collect();
    let (mx, my) = (mean(&lx), mean(&ly));
    let num: f64 = lx.iter().zip(&ly).map(|(x, y)| (x - mx) * (y - my)).sum();
    let den: f64 = lx.iter().map(|x| (x - mx) * (x - mx)).sum();
    num / den
}

/// The study: each scene for its steps (frames and plots into `out`, named after the scene's
/// file) and the detection cost at `sizes` cloth cells per side.
pub fn study(scenes: &[(std::path::PathBuf, usize)], sizes: &[usize], out: &Path) -> Result<ClothReport> {
    let t0 = Instant::now();
    // Sizes first: an impossible one is refused before the scenes run.
    for &n in sizes {
        check_cloth_size(n)?;
    }
    // The detection cost's exponent is a fit over sizes: it needs two different ones.
    let mut distinct = sizes.to_vec();
    distinct.sort_unstable();
    distinct.dedup();
    anyhow::ensure!(
        distinct.len() == sizes.len() && sizes.len() >= 2,
        "--sizes {sizes:?}: the detection cost's growth is fitted over the sizes, so it needs at least two, each once"
    );
    let mut runs = Vec::new();
    let mut verdicts = Vec::new();
    // Plot failures are collected, not raised: the data is returned whatever a plot does.
    let mut plot_errors = Vec::new();
    for (path, steps) in scenes {
        let name = path.file_stem().and_then(|s| s.to_str()).unwrap_or("scene").to_string();
        let r = run(path, *steps, Some((&out.join("frames").join(&name), 5)))?;
        verdicts.extend(run_verdicts(&name, &r, *steps));
        if let Err(e) = write_plots(&name, &r, out) {
            plot_errors.push(format!("{e:#}"));
        }
        runs.push(r);
    }
    let detection: Vec<DetectionCost> = sizes.iter().map(|&n| detection_cost(n, 7)).collect::<Result<_>>()?;
    let size_of = |d: &DetectionCost| (d.triangles + d.edges + d.vertices) as f64;
    let exponent = loglog_slope(
        &detection.iter().map(size_of).collect::<Vec<_>>(),
        &detection.iter().map(|d| d.median_ms).collect::<Vec<_>>(),
    );
    verdicts.push(Verdict::at_most(
        "Collision detection cost grows near-linearly with mesh size (fitted exponent of time against surface primitives)",
        exponent,
        1.25,
    ));
    if !detection.is_empty() {
        let drawn = plot::write_svg(
            &diffsoft::output::own_file(out, "cloth_detection.svg")?,
            &LogLogChart {
                title: "Collision detection cost against surface size".into(),
                x_label: "surface primitives (triangles + edges + vertices)".into(),
                y_label: "ms per step (candidate + violation passes)".into(),
                series: vec![Series {
                    label: "measured (median of 7)".into(),
                    points: detection.iter().map(|d| (size_of(d), d.median_ms)).collect(),
                }],
                ..Default::default()
            },
        );
        if let Err(e) = drawn {
            plot_errors.push(e.to_string());
        }
    }
    Ok(ClothReport {
        header: Header::new(CLOTH_SCHEMA),
        runs,
        detection,
        detection_exponent: exponent,
        verdicts,
        wall_time_s: t0.elapsed().as_secs_f64(),
        plot_errors,
    })
}

/// The claims on one run.
pub fn run_verdicts(name: &str, r: &ClothRun, steps: usize) -> Vec<Verdict> {
    let stretch = &r.cloth_stretch_range;
    vec![
        Verdict::new(
            format!("{name}: the run completes without a solver error"),
            r.error.is_none() && r.steps == steps,
            Some(r.steps as f64),
            Some(steps as f64),
            "steps run == steps asked",
        ),
        Verdict::new(
            format!("{name}: the ball reaches the cloth (contacts between the bodies occur)"),
            r.first_contact_step.is_some(),
            r.first_contact_step.map(|s| s as f64),
            None,
            "first step with contacts between the bodies",
        ),
        Verdict::at_most(
            format!("{name}: no penetration: no surface edge of one body crosses a face of the other at any step's end (max penetration, m)"),
            r.max_penetration,
            0.0,
        ),
        Verdict::below(
            format!("{name}: contact stays within the collision thickness: the surfaces never touch (thickness - smallest distance < thickness)"),
            r.thickness_intrusion,
            r.thickness,
        ),
        Verdict::new(
            format!("{name}: both bodies deform: the cloth's principal stretches and the ball's leave [0.99, 1.01]"),
            r.body_max_strain > 0.01 && (stretch.largest > 1.01 || stretch.smallest < 0.99),
            Some(r.body_max_strain.min((stretch.largest - 1.0).max(1.0 - stretch.smallest))),
            Some(0.01),
            "min(ball's largest |sigma - 1|, cloth's largest |stretch - 1|) > threshold",
        ),
    ]
}

fn write_plots(name: &str, run: &ClothRun, out: &Path) -> Result<()> {
    let times: Vec<f64> = run.series.iter().map(|s| s.time).collect();
    let series = |label: &str, f: &dyn Fn(&ClothStep) -> f64| Series {
        label: label.into(),
        points: times.iter().zip(&run.series).map(|(&t, s)| (t, f(s))).collect(),
    };
    plot::write_linear_svg(
        &diffsoft::output::own_file(out, &format!("cloth_{name}_stretch.svg"))?,
        &LinearChart {
            title: format!("{name}: principal stretches"),
            x_label: "time (s)".into(),
            y_label: "stretch".into(),
            series: vec![
                series("cloth, largest", &|s| s.cloth_max_stretch),
                series("cloth, smallest", &|s| s.cloth_min_stretch),
                series("ball, largest |sigma - 1| + 1", &|s| 1.0 + s.body_max_strain),
            ],
        },
    )?;
    if run.series.iter().any(|s| s.min_distance.is_some()) {
        plot::write_linear_svg(
            &diffsoft::output::own_file(out, &format!("cloth_{name}_distance.svg"))?,
            &LinearChart {
                title: format!(
                    "{name}: smallest distance between the surfaces (thickness {:.0e} m)",
                    run.thickness
                ),
                x_label: "time (s)".into(),
                y_label: "m".into(),
                series: vec![
                    series("smallest distance", &|s| s.min_distance.unwrap_or(f64::NAN)),
                    series("thickness", &|_| run.thickness),
                ],
            },
        )?;
    }
    // Side view (x, y) of the ball and the cloth at six times.
    let panels: Vec<Panel> = run
        .snapshots
        .iter()
        .map(|(t, q)| Panel {
            title: format!("t = {t:.3} s"),
            points: q.iter().map(|v| (v.x, v.y)).collect(),
        })
        .collect();
    let (mut lo, mut hi) = ((f64::INFINITY, f64::INFINITY), (f64::NEG_INFINITY, f64::NEG_INFINITY));
    for p in panels.iter().flat_map(|p| p.points.iter()) {
        lo = (lo.0.min(p.0), lo.1.min(p.1));
        hi = (hi.0.max(p.0), hi.1.max(p.1));
    }
    plot::write_snapshots_svg(
        &diffsoft::output::own_file(out, &format!("cloth_{name}_frames.svg"))?,
        &Snapshots {
            title: format!("{name}: side view (x, y) of all vertices"),
            rows: vec![panels],
            x_range: (lo.0, hi.0),
            y_range: (lo.1, hi.1),
        },
    )?;
    Ok(())
}

/// The console summary of the study.
pub fn table(r: &ClothReport) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    for p in &r.runs {
        let _ = writeln!(
            s,
            "  {}: {} vertices, {} tets, {} cloth triangles, {} steps of {} s; first contact at step {}",
            p.scene,
            p.size.vertices,
            p.size.tets,
            p.size.cloth_triangles,
            p.steps,
            p.dt,
            p.first_contact_step.map_or("-".into(), |k| k.to_string())
        );
        let _ = writeln!(
            s,
            "    max penetration {:.3e} m ({} crossing edge-face pairs); smallest distance {} (thickness {:.0e} m); cloth stretch {:.3}..{:.3}, ball strain {:.3}",
            p.max_penetration,
            p.intersections,
            p.min_separation
                .map_or("none measured (the surfaces never came within reach)".into(), |d| format!("{d:.3e} m")),
            p.thickness,
            p.cloth_stretch_range.smallest,
            p.cloth_stretch_range.largest,
            p.body_max_strain
        );
        let _ = writeln!(
            s,
            "    {:.2} ms per step median ({:.2} mean); in contact {:.2} median ({:.2} mean), up to {} contacts between the bodies",
            p.ms_per_step.median_ms,
            p.ms_per_step.mean_ms,
            p.ms_per_contact_step.median_ms,
            p.ms_per_contact_step.mean_ms,
            p.max_pair_contacts
        );
    }
    for d in &r.detection {
        let _ = writeln!(
            s,
            "  detection: cloth {:>3}^2 cells, {:>6} triangles {:>6} edges {:>6} vertices: {:.3} ms ({} pairs tested, {} candidates)",
            d.cloth_cells, d.triangles, d.edges, d.vertices, d.median_ms, d.tested, d.candidates
        );
    }
    for v in &r.verdicts {
        let _ = writeln!(s, "  [{}] {}", if v.holds { "holds" } else { "FAILS" }, v.claim);
    }
    s
}
