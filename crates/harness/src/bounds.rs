//! The bounds part of the suite and the `diffsoft sweep` / `diffsoft quality` reports: the
//! `rho(dt)` sweep of one mesh and its plot, a mesh's quality report, the per-mesh results and
//! summary table of `reports/bounds.json` (with the analysis of one suite mesh), and Appendix A's
//! `T` dependence with its plot.

use std::collections::HashMap;

use std::path::Path;
use std::time::Instant;

use anyhow::{anyhow, Context, Result};
use serde::Serialize;

use crate::plot::{self, LogLogChart, RefLine, Series};
use crate::report::{write_json, Header, Verdict};
use crate::suite::SuiteMesh;
use diffsoft::analysis::appendix::{self, PaperArithmetic};
use diffsoft::analysis::bounds::{self, BoundsParams, BoundsReport};
use diffsoft::analysis::spectral::{EigenMethod, KRYLOV_MIN_N};
use diffsoft::analysis::sweep::{self, log_space, SweepPoint};
use diffsoft::analysis::{rho_split, Attachments, IterationSystem, Spectrum};
use diffsoft::fem::{sign_pattern, Coefficient, FemOperators, SignPattern};
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::mesh::quality::{quality, MeshQuality};
use diffsoft::mesh::{self, LoadedMesh, MeshInfo};

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
    /// The factor the file's coordinates were multiplied by (`--scale`).
    pub mesh_scale: f64,
    /// The quality threshold every tet passed (`--min-tet-quality`).
    pub min_tet_quality: f64,
    /// Density (kg/m^3).
    pub rho: f64,
    /// Stiffness coefficient of `L` (Pa).
    pub mu: f64,
    /// Time step marked on the plot (s; the scene's).
    pub mark_dt: Option<f64>,
}

impl SweepReport {
    /// Assemble a sweep report of the mesh `mesh` read (its file, scale and quality threshold).
    pub fn new(
        mesh: &MeshInfo,
        rho: f64,
        mu: f64,
        mark_dt: Option<f64>,
        spectrum: &Spectrum,
        points: Vec<SweepPoint>,
    ) -> Self {
        Self {
            header: Header::new(SWEEP_SCHEMA),
            inputs: SweepInputs {
                mesh_file: mesh.path.clone(),
                mesh_scale: mesh.scale,
                min_tet_quality: mesh.min_quality,
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

pub(crate) fn run_mesh(
    base: &Path,
    out: &Path,
    entry: &SuiteMesh,
    empirical: bool,
    sweep_points: usize,
) -> Result<SuiteMeshResult> {
    let path = base.join(&entry.mesh);
    let loaded = mesh::load(&path)?.scaled(entry.scale);
    let scaled = &loaded.mesh;
    let fem = FemOperators::new(scaled)?;
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
        bounds::analyze(scaled, &loaded.info, &params).with_context(|| format!("suite mesh '{}'", entry.name))?;

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
    let sweep_report = SweepReport::new(&loaded.info, rho, mu, Some(entry.dt), &dense, pts);
    let slug: String = entry
        .name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    let sweep_json = format!("sweeps/{slug}.json");
    let sweep_svg = format!("sweeps/{slug}.svg");
    write_json(diffsoft::output::own_file(out, &sweep_json)?, &sweep_report)?;
    plot::write_svg(
        &diffsoft::output::own_file(out, &sweep_svg)?,
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
