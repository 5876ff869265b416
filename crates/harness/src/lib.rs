//! # diffsoft-harness
//!
//! The verification and convergence-analysis harness of `diffsoft`: the studies the main job
//! (`diffsoft verify`) runs, their versioned JSON reports and JSON Schemas, readable summaries
//! and SVG plots. It reads `verification/suite.json` and writes `reports/`.
//!
//! The engine it measures is the `diffsoft` crate; this crate adds no physics.
#![deny(missing_docs)]

pub mod actuators;
pub mod cloth;
pub mod extremes;
pub mod fd;
pub mod gradients;
pub mod jacobians;
pub mod merge;
pub mod physics;
pub mod plot;
pub mod pool;
pub mod report;
pub mod schemas;
pub mod shard;
pub mod skeleton;
pub mod suite;
mod summary;
pub mod tradeoff;

pub use schemas::schemas;
pub use summary::{
    bounds_summary, jacobians_table, physics_table, quality_summary, skeleton_table, sweep_summary, table,
};

use std::collections::HashMap;

use std::path::Path;
use std::time::Instant;

use anyhow::{anyhow, Context, Result};
use serde::Serialize;

use crate::plot::{LogLogChart, RefLine, Series};
use crate::report::{write_json, Header, Verdict};
use diffsoft::analysis::appendix::{self, PaperArithmetic};
use diffsoft::analysis::bounds::{self, BoundsParams, BoundsReport};
use diffsoft::analysis::spectral::{EigenMethod, KRYLOV_MIN_N};
use diffsoft::analysis::sweep::{self, log_space, SweepPoint};
use diffsoft::analysis::{rho_split, Attachments, IterationSystem, Spectrum};
use diffsoft::fem::{sign_pattern, Coefficient, FemOperators, SignPattern};
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::mesh::quality::{quality, MeshQuality};
use diffsoft::mesh::{self, LoadedMesh, MeshInfo};
use suite::{Suite, SuiteMesh};

/// Schema of `diffsoft sweep` output.
pub const SWEEP_SCHEMA: &str = "diffsoft.sweep/1";
/// Schema of `diffsoft quality` output.
pub const QUALITY_SCHEMA: &str = "diffsoft.quality/1";
/// Schema of `reports/bounds.json`.
pub const SUITE_BOUNDS_SCHEMA: &str = "diffsoft.bounds_suite/1";

/// `rho(dt)` curves of both schemes for one mesh.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct SweepReport {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// Inputs.
    pub inputs: SweepInputs,
    /// `h*_19` (s).
    pub critical_dt_plain: f64,
    /// `h*_21` (s; null: converges for every dt).
    pub critical_dt_split: Option<f64>,
    /// `lim_{h -> inf} rho(G21)` (1).
    pub rho_split_limit_h_inf: f64,
    /// Eigensolver used.
    pub method: EigenMethod,
    /// The curve.
    pub points: Vec<SweepPoint>,
}

/// Inputs of a sweep.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct SweepInputs {
    /// Mesh file.
    pub mesh_file: String,
    /// Density (kg/m^3).
    pub rho: f64,
    /// Stiffness coefficient of `L` (Pa).
    pub mu: f64,
    /// Time step marked on the plot (s; the scene's).
    pub mark_dt: Option<f64>,
}

impl SweepReport {
    /// Assemble a sweep report.
    pub fn new(
        mesh_file: &str,
        rho: f64,
        mu: f64,
        mark_dt: Option<f64>,
        spectrum: &Spectrum,
        points: Vec<SweepPoint>,
    ) -> Self {
        Self {
            header: Header::new(SWEEP_SCHEMA),
            inputs: SweepInputs {
                mesh_file: mesh_file.to_string(),
                rho,
                mu,
                mark_dt,
            },
            critical_dt_plain: spectrum.critical_dt_plain(),
            critical_dt_split: spectrum.critical_dt_split(),
            rho_split_limit_h_inf: spectrum.rho_split_limit(),
            method: spectrum.method,
            points,
        }
    }

    /// The plot of this sweep.
    pub fn chart(&self, title: &str) -> LogLogChart {
        let mut vlines = vec![RefLine {
            label: format!("h*_19 = {:.3e} s", self.critical_dt_plain),
            at: self.critical_dt_plain,
        }];
        if let Some(h) = self.critical_dt_split {
            vlines.push(RefLine {
                label: format!("h*_21 = {h:.3e} s"),
                at: h,
            });
        }
        if let Some(h) = self.inputs.mark_dt {
            vlines.push(RefLine {
                label: format!("scene dt = {h:.3e} s"),
                at: h,
            });
        }
        LogLogChart {
            title: title.to_string(),
            x_label: "time step h (s)".into(),
            y_label: "spectral radius".into(),
            series: vec![
                Series {
                    label: "rho(G19), plain Eq. 19".into(),
                    points: self.points.iter().map(|p| (p.dt, p.rho_plain)).collect(),
                },
                Series {
                    label: "rho(G21), split Eq. 21".into(),
                    points: self.points.iter().map(|p| (p.dt, p.rho_split)).collect(),
                },
            ],
            vlines,
            hlines: vec![RefLine {
                label: "rho = 1 (convergence limit)".into(),
                at: 1.0,
            }],
        }
    }
}

/// `diffsoft quality` output.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct QualityReport {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// Loading details.
    pub source: MeshInfo,
    /// Geometry.
    pub quality: MeshQuality,
    /// Sign structure of `L` (independent of the material coefficient).
    pub l_sign: SignPattern,
}

impl QualityReport {
    /// Compute the quality report of a loaded mesh.
    pub fn new(loaded: &LoadedMesh) -> Result<Self> {
        let fem = FemOperators::new(&loaded.mesh)?;
        Ok(Self {
            header: Header::new(QUALITY_SCHEMA),
            source: loaded.info.clone(),
            quality: quality(&loaded.mesh),
            l_sign: sign_pattern(&fem.laplacian_csc(Coefficient::Uniform(1.0))?),
        })
    }
}

/// The paper material of a suite mesh and how `rho`, `mu` follow from it.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct SuiteMaterial {
    /// Paper scene file.
    pub source_scene: Option<String>,
    /// Vertex scale applied (1).
    pub scale: f64,
    /// Total mass (kg).
    pub total_mass: f64,
    /// Young's modulus (Pa).
    pub youngs_modulus: f64,
    /// Poisson ratio (1).
    pub poisson_ratio: f64,
    /// Volume after scaling (m^3).
    pub volume: f64,
    /// `rho = total_mass / volume` (kg/m^3).
    pub rho: f64,
    /// `mu` used in `L` (Pa).
    pub mu: f64,
    /// Why.
    pub derivation: &'static str,
}

/// Krylov vs dense agreement on one mesh (relative differences).
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct CrossCheck {
    /// Relative difference of `h*_19` (1).
    pub rel_diff_critical_dt_plain: f64,
    /// Relative difference of `h*_21` (1; null when neither solver finds one; 1 when only one
    /// does).
    pub rel_diff_critical_dt_split: Option<f64>,
    /// Relative difference of `rho(G21)` at the scene's dt (1).
    pub rel_diff_rho_split_at_dt: f64,
    /// Relative difference of `lambda_max(D^-1 L)` (1).
    pub rel_diff_lambda_dinv_l: f64,
    /// Dense time (ms).
    pub dense_ms: f64,
    /// Krylov time (ms).
    pub krylov_ms: f64,
}

/// Results for one suite mesh.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct SuiteMeshResult {
    /// Name.
    pub name: String,
    /// Material.
    pub material: SuiteMaterial,
    /// The full bounds report.
    pub bounds: BoundsReport,
    /// Krylov vs dense (meshes large enough for Krylov).
    pub krylov_cross_check: Option<CrossCheck>,
    /// Sweep JSON, relative to the reports directory.
    pub sweep_json: String,
    /// Sweep plot, relative to the reports directory.
    pub sweep_svg: String,
}

/// One row of the summary table.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct TableRow {
    /// Mesh name.
    pub mesh: String,
    /// Vertices.
    pub vertices: usize,
    /// Tets.
    pub tets: usize,
    /// Scene time step (s).
    pub dt: f64,
    /// `h*_19` (s).
    pub critical_dt_plain: f64,
    /// `rho(G19)` at dt (1).
    pub rho_plain: f64,
    /// `h*_21` (s; null: every dt).
    pub critical_dt_split: Option<f64>,
    /// `rho(G21)` at dt (1).
    pub rho_split: f64,
    /// Eq. 29 bound (s/m^2: the formula as printed is not dimensionally consistent).
    pub eq29: f64,
    /// (19) converges at dt.
    pub plain_converges: bool,
    /// (21) converges at dt.
    pub split_converges: bool,
    /// Eq. 29 is below `h*_19` (sufficient).
    pub eq29_safe: bool,
    /// Appendix B holds (21 converges for every dt).
    pub appendix_b_holds: bool,
}

/// Appendix A's `T` dependence measured on boxes of fixed cell size.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct TScaling {
    /// Cell edge (m).
    pub cell_size: f64,
    /// Density (kg/m^3).
    pub rho: f64,
    /// Stiffness coefficient of `L` (Pa).
    pub mu: f64,
    /// One row per box.
    pub rows: Vec<TScalingRow>,
    /// Fitted exponent of `h*_19` against `T` (1; log-log slope over the largest boxes).
    pub exact_exponent: f64,
    /// Fitted exponent of Eq. 29 against `T` (1).
    pub eq29_exponent: f64,
    /// Claims.
    pub verdicts: Vec<Verdict>,
}

/// One box of the `T` study.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct TScalingRow {
    /// Cells per axis.
    pub cells_per_axis: usize,
    /// Tets `T`.
    pub tets: usize,
    /// Exact `h*_19` (s).
    pub exact_dt: f64,
    /// Eq. 29 (s/m^2: the formula as printed is not dimensionally consistent).
    pub eq29_dt: f64,
    /// Eq. 24, Gershgorin (s).
    pub gershgorin_dt: f64,
}

/// `reports/bounds.json`.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct SuiteBoundsReport {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// Suite file.
    pub suite: String,
    /// Summary table.
    pub table: Vec<TableRow>,
    /// Per mesh.
    pub meshes: Vec<SuiteMeshResult>,
    /// The appendix's own arithmetic.
    pub paper_arithmetic: PaperArithmetic,
    /// Eq. 29's `T` dependence.
    pub t_scaling: TScaling,
    /// Wall time of the whole suite (s).
    pub wall_time_s: f64,
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

fn map_attach(name: &str, info: &MeshInfo, vertices: &[usize]) -> Result<Vec<usize>> {
    let index: HashMap<i64, usize> = info.file_ids.iter().enumerate().map(|(i, &id)| (id, i)).collect();
    vertices
        .iter()
        .map(|&v| {
            index.get(&(v as i64)).copied().ok_or_else(|| {
                anyhow!(
                    "suite mesh '{name}': attached vertex {v} is not a vertex of any tet of {}",
                    info.path
                )
            })
        })
        .collect()
}

fn run_mesh(
    base: &Path,
    out: &Path,
    entry: &SuiteMesh,
    empirical: bool,
    sweep_points: usize,
) -> Result<SuiteMeshResult> {
    let path = base.join(&entry.mesh);
    let loaded = mesh::load(&path)?;
    let scaled = loaded.mesh.scaled(entry.scale);
    let fem = FemOperators::new(&scaled)?;
    let volume = fem.total_volume();
    let rho = entry.total_mass / volume;
    // Reference implementation: corotated weight E/(1+nu) V and volume weight nu E/(1+nu) V, both
    // on the deformation-gradient operator A, so the assembled L is E V A^T A.
    let mu = entry.youngs_modulus / (1.0 + entry.poisson_ratio) * (1.0 + entry.poisson_ratio);
    let attachments = match &entry.attach {
        Some(a) => Attachments {
            vertices: map_attach(&entry.name, &loaded.info, &a.vertices)?,
            stiffness: a.stiffness,
        },
        None => Attachments::default(),
    };
    let params = BoundsParams {
        rho,
        mu,
        dt: entry.dt,
        attachments: attachments.clone(),
        method: EigenMethod::Auto,
        empirical,
    };
    let report =
        bounds::analyze(&scaled, &loaded.info, &params).with_context(|| format!("suite mesh '{}'", entry.name))?;

    let sys = IterationSystem::from_fem(&fem, Coefficient::Uniform(rho), Coefficient::Uniform(mu), &attachments)?;
    let t = Instant::now();
    let dense = Spectrum::compute(&sys, EigenMethod::Dense)?;
    let dense_ms = t.elapsed().as_secs_f64() * 1e3;
    let krylov_cross_check = if sys.n() >= KRYLOV_MIN_N {
        let t = Instant::now();
        let kry = Spectrum::compute(&sys, EigenMethod::Krylov)?;
        let krylov_ms = t.elapsed().as_secs_f64() * 1e3;
        let rho_k = rho_split(&sys, entry.dt, EigenMethod::Krylov)?;
        let rho_d = rho_split(&sys, entry.dt, EigenMethod::Dense)?;
        Some(CrossCheck {
            rel_diff_critical_dt_plain: rel(kry.critical_dt_plain(), dense.critical_dt_plain()),
            rel_diff_critical_dt_split: match (kry.critical_dt_split(), dense.critical_dt_split()) {
                (Some(a), Some(b)) => Some(rel(a, b)),
                (None, None) => None,
                _ => Some(1.0),
            },
            rel_diff_rho_split_at_dt: rel(rho_k, rho_d),
            rel_diff_lambda_dinv_l: rel(kry.lambda_max_dinv_l, dense.lambda_max_dinv_l),
            dense_ms,
            krylov_ms,
        })
    } else {
        None
    };

    let (lo, hi) = sweep::default_range(&dense);
    let lo = lo.min(entry.dt / 10.0);
    let hi = hi.max(entry.dt * 10.0);
    let pts = sweep::sweep(&sys, &dense, &log_space(lo, hi, sweep_points), EigenMethod::Dense)?;
    let sweep_report = SweepReport::new(&loaded.info.path, rho, mu, Some(entry.dt), &dense, pts);
    let slug: String = entry
        .name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    let sweep_json = format!("sweeps/{slug}.json");
    let sweep_svg = format!("sweeps/{slug}.svg");
    write_json(out.join(&sweep_json), &sweep_report)?;
    plot::write_svg(
        &out.join(&sweep_svg),
        &sweep_report.chart(&format!(
            "{}: spectral radius of (19) and (21) vs time step",
            entry.name
        )),
    )?;
    Ok(SuiteMeshResult {
        name: entry.name.clone(),
        material: SuiteMaterial {
            source_scene: entry.source_scene.as_ref().map(|p| p.display().to_string()),
            scale: entry.scale,
            total_mass: entry.total_mass,
            youngs_modulus: entry.youngs_modulus,
            poisson_ratio: entry.poisson_ratio,
            volume,
            rho,
            mu,
            derivation: "reference implementation: rho = Mass / volume (mass lumped by volume); L gets the corotated \
                         weight E/(1+nu) V plus the volume weight nu E/(1+nu) V on the same operator A, so mu = E",
        },
        bounds: report,
        krylov_cross_check,
        sweep_json,
        sweep_svg,
    })
}

fn slope(xs: &[f64], ys: &[f64]) -> f64 {
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let sxy: f64 = xs.iter().zip(ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

/// Measure how `h*_19` and Eq. 29 depend on the number of tets at fixed element size.
pub fn t_scaling(cell_size: f64, rho: f64, mu: f64, cells: &[usize]) -> Result<TScaling> {
    let mut rows = Vec::new();
    for &k in cells {
        let side = cell_size * k as f64;
        let mesh = BoxSpec::new([k, k, k], [side; 3]).build()?;
        let fem = FemOperators::new(&mesh)?;
        let sys = IterationSystem::from_fem(
            &fem,
            Coefficient::Uniform(rho),
            Coefficient::Uniform(mu),
            &Attachments::default(),
        )?;
        let spectrum = Spectrum::compute(&sys, EigenMethod::Auto)?;
        let total: f64 = fem.geometry.iter().map(|g| g.p.norm_squared()).sum();
        rows.push(TScalingRow {
            cells_per_axis: k,
            tets: mesh.num_tets(),
            exact_dt: spectrum.critical_dt_plain(),
            eq29_dt: (rho / (24.0 * 3f64.sqrt() * mu * total)).sqrt(),
            gershgorin_dt: appendix::gershgorin_dt(&sys),
        });
    }
    let tail = &rows[rows.len().saturating_sub(3)..];
    let lt: Vec<f64> = tail.iter().map(|r| (r.tets as f64).ln()).collect();
    let exact_exponent = slope(&lt, &tail.iter().map(|r| r.exact_dt.ln()).collect::<Vec<_>>());
    let eq29_exponent = slope(&lt, &tail.iter().map(|r| r.eq29_dt.ln()).collect::<Vec<_>>());
    let verdicts = vec![
        Verdict::new(
            "Appendix A, Eq. 29: at fixed element size the admissible step shrinks like T^-1/2 as tets are added",
            (exact_exponent + 0.5).abs() < 0.1,
            Some(exact_exponent),
            Some(-0.5),
            "measured = log-log slope of the exact h*_19 against T over the three largest boxes; holds iff within 0.1 of threshold",
        ),
        Verdict::new(
            "The exact critical step of (19) is a local property: independent of T at fixed element size",
            exact_exponent.abs() < 0.05,
            Some(exact_exponent),
            Some(0.0),
            "measured = log-log slope of h*_19 against T; holds iff |slope| < 0.05",
        ),
    ];
    Ok(TScaling {
        cell_size,
        rho,
        mu,
        rows,
        exact_exponent,
        eq29_exponent,
        verdicts,
    })
}

/// Eq. 29 and the exact critical step against the number of tets at fixed element size.
pub fn t_scaling_chart(ts: &TScaling) -> LogLogChart {
    let series = |label: &str, f: fn(&TScalingRow) -> f64| Series {
        label: label.to_string(),
        points: ts.rows.iter().map(|r| (r.tets as f64, f(r))).collect(),
    };
    LogLogChart {
        title: format!(
            "Appendix A: critical step vs number of tets T (cell size {:.2e} m)",
            ts.cell_size
        ),
        x_label: "tets T".into(),
        y_label: "time step bound (s, or s/m^2 for Eq. 29)".into(),
        series: vec![
            series("exact h*_19", |r| r.exact_dt),
            series("Eq. 29 as printed (claims T^-1/2)", |r| r.eq29_dt),
            series("Eq. 24 Gershgorin (sufficient)", |r| r.gershgorin_dt),
        ],
        vlines: Vec::new(),
        hlines: Vec::new(),
    }
}

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

fn run_physics(base: &Path, out: &Path, suite: &suite::PhysicsSuite) -> Result<PhysicsReport> {
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
    println!("  cantilever levels {:?} ...", suite.cantilever_levels);
    let cantilever = physics::cantilever(&suite.cantilever_levels)?;
    let solver_agreement = physics::solver_agreement()?;
    let mut scenes = Vec::new();
    for sc in &suite.scenes {
        let r = physics::run_scene(&base.join(&sc.scene), sc.steps).map_err(|e| anyhow!("{e}"))?;
        println!(
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
    plot::write_svg(&out.join("cantilever.svg"), &chart)?;
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

/// Run the suite at `suite_path` and write reports into `out`.
pub fn run_suite(suite_path: &Path, out: &Path) -> Result<SuiteBoundsReport> {
    let t0 = Instant::now();
    let suite = Suite::load(suite_path)?;
    let base = suite_path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut meshes = Vec::new();
    for entry in &suite.bounds.meshes {
        let t = Instant::now();
        let r = run_mesh(base, out, entry, suite.bounds.empirical, suite.bounds.sweep_points)?;
        println!(
            "  {:<22} {:>6} v {:>7} t  analysed in {:.2} s",
            entry.name,
            r.bounds.mesh.vertices,
            r.bounds.mesh.tets,
            t.elapsed().as_secs_f64()
        );
        meshes.push(r);
    }
    let mut sections = vec![("bounds and sweeps", t0.elapsed().as_secs_f64())];
    let mut lap = Instant::now();
    let mut section = |name: &'static str, lap: &mut Instant| {
        sections.push((name, lap.elapsed().as_secs_f64()));
        *lap = Instant::now();
    };
    let paper_arithmetic = appendix::paper_arithmetic()?;
    let ts = &suite.t_scaling;
    let t_scaling = t_scaling(ts.cell_size, ts.rho, ts.mu, &ts.cells_per_axis)?;
    let table = meshes
        .iter()
        .map(|m| {
            let b = &m.bounds;
            TableRow {
                mesh: m.name.clone(),
                vertices: b.mesh.vertices,
                tets: b.mesh.tets,
                dt: b.inputs.dt,
                critical_dt_plain: b.jacobi.critical_dt.unwrap_or(f64::NAN),
                rho_plain: b.jacobi.spectral_radius,
                critical_dt_split: b.split.critical_dt,
                rho_split: b.split.spectral_radius,
                eq29: b.appendix_a.eq29.dt,
                plain_converges: b.jacobi.converges,
                split_converges: b.split.converges,
                eq29_safe: b.appendix_a.eq29.safe,
                appendix_b_holds: b.appendix_b.holds,
            }
        })
        .collect();
    let report = SuiteBoundsReport {
        header: Header::new(SUITE_BOUNDS_SCHEMA),
        suite: suite_path.display().to_string(),
        table,
        meshes,
        paper_arithmetic,
        t_scaling,
        wall_time_s: t0.elapsed().as_secs_f64(),
    };
    let path = out.join("bounds.json");
    write_json(&path, &report)?;
    plot::write_svg(&out.join("t_scaling.svg"), &t_scaling_chart(&report.t_scaling))?;
    let table = summary::table(&report);
    // The table as printed, for the documentation that quotes it (tests/doc_numbers.rs).
    diffsoft::output::write_atomic(&out.join("bounds_table.txt"), table.as_bytes())?;
    print!("{table}");
    section("t-scaling and paper arithmetic", &mut lap);
    println!("\nJacobian checks of the skeleton:");
    let jac = jacobians::run(2021);
    write_json(out.join("jacobians.json"), &jac)?;
    for v in &jac.verdicts {
        println!("  [{}] {}", if v.holds { "holds" } else { "FAILS" }, v.claim);
    }
    section("Jacobian checks", &mut lap);
    println!("\nphysics checks of the forward solver:");
    let phys = run_physics(base, out, &suite.physics)?;
    write_json(out.join("physics.json"), &phys)?;
    print!("{}", summary::physics_table(&phys));
    section("physics checks", &mut lap);
    println!("\nskeleton study ({}):", suite.skeleton.scene.display());
    let sk = skeleton::study(
        &base.join(&suite.skeleton.scene),
        suite.skeleton.steps,
        &suite.skeleton.arm_bones,
        out,
    )?;
    write_json(out.join("skeleton.json"), &sk)?;
    print!("{}", summary::skeleton_table(&sk));
    section("skeleton study", &mut lap);
    println!("\nactuator study:");
    let ac = &suite.actuators;
    let act = actuators::study(
        &actuators::StudyInputs {
            drone: &base.join(&ac.drone),
            drone_activation: ac.drone_activation,
            drone_steps: ac.drone_steps,
            octopus: &base.join(&ac.octopus),
            octopus_muscle: &ac.octopus_muscle,
            octopus_activation: ac.octopus_activation,
            octopus_steps: ac.octopus_steps,
        },
        out,
    )?;
    write_json(out.join("actuators.json"), &act)?;
    print!("{}", actuators::table(&act));
    section("actuator study", &mut lap);
    println!(
        "\ngradient checks (unrolled reverse mode, implicit mode for Newton cases, vs central differences, rtol {:e}):",
        gradients::RTOL
    );
    let gs = &suite.gradients;
    let grad = gradients::study(
        &gradients::Inputs {
            bridgesus: &base.join(&gs.bridgesus),
            baymax_skeleton: &base.join(&gs.baymax_skeleton),
            ball_on_cloth: &base.join(&gs.ball_on_cloth),
            memory_scene: &base.join(&gs.memory_scene),
            memory_steps: &gs.memory_steps,
            steps: gs.steps,
            sysid_steps: gs.sysid_steps,
        },
        out,
    )?;
    write_json(out.join("gradients.json"), &grad)?;
    for v in &grad.verdicts {
        println!("  [{}] {}", if v.holds { "holds" } else { "FAILS" }, v.claim);
    }
    section("gradient study", &mut lap);
    if let Some(t) = &suite.tradeoff {
        println!("\ntrade-off of solver settings (accuracy against cost):");
        tradeoff::suite_section(base, out, &t.scenes)?;
    }
    section("trade-off study", &mut lap);
    if let Some(x) = &suite.extremes {
        println!("\nextremes ({:?} subset):", x.subset);
        let ex = extremes::run(x.subset, true);
        write_json(out.join("extremes.json"), &ex)?;
        print!("{}", extremes::table(&ex));
    }
    section("extremes", &mut lap);
    if let Some(c) = &suite.cloth {
        println!("\ncloth study:");
        let scenes: Vec<(std::path::PathBuf, usize)> =
            c.scenes.iter().map(|s| (base.join(&s.scene), s.steps)).collect();
        let cl = cloth::study(&scenes, &c.detection_sizes, out)?;
        write_json(out.join("cloth.json"), &cl)?;
        print!("{}", cloth::table(&cl));
        for e in &cl.plot_errors {
            eprintln!("warning: cloth plot not drawn: {e}");
        }
    }
    section("cloth study", &mut lap);
    println!("\nwall time per section:");
    for (name, s) in &sections {
        println!("  {name:<32} {s:>7.1} s");
    }
    println!(
        "wrote {}, {}, {}, {}, {}, gradients.json, tradeoff.json, extremes.json, cloth.json, t_scaling.svg, cantilever.svg, skeleton_*.svg, gradient_cost.svg, tradeoff_*.svg, cloth_*.svg, actuator and cloth frames and {} sweep plots in {:.1} s",
        path.display(),
        out.join("jacobians.json").display(),
        out.join("physics.json").display(),
        out.join("skeleton.json").display(),
        out.join("actuators.json").display(),
        report.meshes.len(),
        t0.elapsed().as_secs_f64()
    );
    Ok(report)
}
