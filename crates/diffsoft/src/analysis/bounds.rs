//! The `bounds` analysis of one mesh: spectral radii and critical steps of (19) and (21),
//! Appendix A and B verdicts, and optionally the empirical contraction check, as one report.

use std::time::Instant;

use serde::Serialize;

use super::appendix::{self, AppendixA, AppendixB, Discretized};
use super::empirical::{self, EmpiricalCheck, Scheme};
use super::spectral::EigenMethod;
use super::{positive, rho_split, AnalysisError, Attachments, IterationSystem, Spectrum};
use crate::fem::{sign_pattern, Coefficient, FemOperators, SignPattern};
use crate::mesh::quality::{quality, MeshQuality};
use crate::mesh::{MeshInfo, TetMesh};
use crate::report::Header;

/// Schema name of the bounds report.
pub const SCHEMA: &str = "diffsoft.bounds/1";

/// What to analyse.
#[derive(Debug, Clone, Serialize)]
pub struct BoundsParams {
    /// Density (kg/m^3); lumped mass `rho V / 4` per corner.
    pub rho: f64,
    /// Stiffness coefficient of `L = sum mu V A^T A` (Pa).
    pub mu: f64,
    /// Time step (s).
    pub dt: f64,
    /// Penalty attachments added to the diagonal of `L` (none by default).
    pub attachments: Attachments,
    /// Eigensolver.
    pub method: EigenMethod,
    /// Also run the iterations and compare observed and predicted rates.
    pub empirical: bool,
}

/// Mesh section of the report.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct MeshSection {
    /// Vertices.
    pub vertices: usize,
    /// Tets.
    pub tets: usize,
    /// Loading details (format, dropped nodes, re-oriented tets).
    pub source: MeshInfo,
    /// Geometric quality.
    pub quality: MeshQuality,
    /// Sign structure of `L`.
    pub l_sign: SignPattern,
}

/// One iteration scheme at the analysed time step.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct SchemeSection {
    /// The iteration, with its equation number.
    pub iteration: &'static str,
    /// Its iteration matrix.
    pub iteration_matrix: &'static str,
    /// Spectral radius at `dt` (1).
    pub spectral_radius: f64,
    /// Critical time step (s; null if it converges for every dt).
    pub critical_dt: Option<f64>,
    /// `spectral_radius < 1`.
    pub converges: bool,
    /// How the critical step was computed.
    pub critical_dt_formula: &'static str,
    /// The eigenvalue behind the critical step (1/s^2).
    pub critical_eigenvalue: f64,
    /// `lim_{h -> inf}` of the spectral radius (1; only for (21)).
    pub spectral_radius_limit_h_inf: Option<f64>,
    /// Rows with stiff attachments taken in their Dirichlet limit for the critical step (the
    /// neglected term is relatively `O(L_ii / w)`; see `Spectrum::compute`).
    pub critical_dt_dirichlet_limit_rows: usize,
}

/// Wall-clock times of the analysis stages.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Timing {
    /// FEM operators, mass and `L` (ms).
    pub assembly_ms: f64,
    /// Eigenvalue computations (ms).
    pub eigen_ms: f64,
    /// Everything (ms).
    pub total_ms: f64,
}

/// The `bounds` report for one mesh.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct BoundsReport {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// Inputs.
    pub inputs: BoundsInputs,
    /// Mesh facts.
    pub mesh: MeshSection,
    /// Plain iteration (19).
    pub jacobi: SchemeSection,
    /// Split iteration (21).
    pub split: SchemeSection,
    /// Appendix A.
    pub appendix_a: AppendixA,
    /// Appendix B.
    pub appendix_b: AppendixB,
    /// Observed contraction rates (if requested).
    pub empirical: Vec<EmpiricalCheck>,
    /// Timings.
    pub timing: Timing,
}

/// Inputs as recorded in the report.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct BoundsInputs {
    /// Mesh file.
    pub mesh_file: String,
    /// Density (kg/m^3).
    pub rho: f64,
    /// Stiffness coefficient of `L = sum mu V A^T A` (Pa).
    pub mu: f64,
    /// Time step (s).
    pub dt: f64,
    /// Number of attached vertices.
    pub attached_vertices: usize,
    /// Attachment stiffness (N/m; null without attachments).
    pub attachment_stiffness: Option<f64>,
    /// Eigensolver actually used.
    pub eigen_method: EigenMethod,
    /// What `L` and `M` are.
    pub convention: &'static str,
}

/// Analyse `mesh` (already scaled to simulation units).
///
/// ```
/// use diffsoft::analysis::bounds::{analyze, BoundsParams};
/// use diffsoft::analysis::spectral::EigenMethod;
/// use diffsoft::mesh::{self, LoadOptions};
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::TetMesh;
///
/// let generated = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1]).build()?;
/// let loaded = TetMesh::new_with(generated.vertices, generated.tets, LoadOptions::default())?;
/// let params = BoundsParams {
///     rho: 1000.0,
///     mu: 1e5,
///     dt: 1e-4,
///     attachments: Default::default(),
///     method: EigenMethod::Dense,
///     empirical: false,
/// };
/// let report = analyze(&loaded.mesh, &loaded.info, &params)?;
/// assert_eq!(report.mesh.tets, 12);
/// assert!(report.jacobi.converges && report.split.converges);
/// assert!(report.appendix_b.holds);
/// assert!(report.empirical.is_empty());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn analyze(mesh: &TetMesh, info: &MeshInfo, params: &BoundsParams) -> Result<BoundsReport, AnalysisError> {
    let t0 = Instant::now();
    let rho = positive("density rho", params.rho)?;
    let mu = positive("stiffness mu", params.mu)?;
    let dt = positive("time step dt", params.dt)?;
    let assemble = |m: &TetMesh| -> Result<(FemOperators, IterationSystem), AnalysisError> {
        let fem = FemOperators::new(m)?;
        let sys = IterationSystem::from_fem(
            &fem,
            Coefficient::Uniform(rho),
            Coefficient::Uniform(mu),
            &params.attachments,
        )?;
        Ok((fem, sys))
    };
    let (fem, sys) = assemble(mesh)?;
    // The same mesh scaled by 2 measures how each Appendix A bound scales with length.
    let (fem2, sys2) = assemble(&mesh.scaled(2.0))?;
    let sign = sign_pattern(&fem.laplacian_csc(Coefficient::Uniform(mu))?);
    let q = quality(mesh);
    let assembly_ms = t0.elapsed().as_secs_f64() * 1e3;

    let t1 = Instant::now();
    let spectrum = Spectrum::compute(&sys, params.method)?;
    let rho21 = rho_split(&sys, dt, spectrum.method)?;
    let eigen_ms = t1.elapsed().as_secs_f64() * 1e3;

    let rho19 = spectrum.rho_plain(dt);
    let jacobi = SchemeSection {
        iteration: "Eq. 19 (plain): M v^{i+1} = f - h^2 L v^i + xi^i",
        iteration_matrix: "G19 = -h^2 M^-1 L",
        spectral_radius: rho19,
        critical_dt: Some(spectrum.critical_dt_plain()),
        converges: rho19 < 1.0,
        critical_dt_formula: "h*_19 = 1 / sqrt(lambda_max(M^-1 L))",
        critical_eigenvalue: spectrum.lambda_max_minv_l,
        spectral_radius_limit_h_inf: None,
        critical_dt_dirichlet_limit_rows: 0,
    };
    let split = SchemeSection {
        iteration: "Eq. 21 (split): (M + h^2 D) v^{i+1} = f - h^2 (L - D) v^i + xi^i, D = diag(L)",
        iteration_matrix: "G21 = -(M + h^2 D)^-1 h^2 (L - D)",
        spectral_radius: rho21,
        critical_dt: spectrum.critical_dt_split(),
        converges: rho21 < 1.0,
        critical_dt_formula: "h*_21 = 1 / sqrt(lambda_max(M^-1 (L - 2D))) if that eigenvalue is positive, else none",
        critical_eigenvalue: spectrum.lambda_max_minv_l_minus_2d,
        spectral_radius_limit_h_inf: Some(spectrum.rho_split_limit()),
        critical_dt_dirichlet_limit_rows: spectrum.split_critical_eliminated_rows,
    };
    let has_att = !params.attachments.vertices.is_empty();
    let appendix_a = appendix::appendix_a(
        Discretized { fem: &fem, sys: &sys },
        Discretized { fem: &fem2, sys: &sys2 },
        rho,
        mu,
        &spectrum,
        dt,
    );
    let appendix_b = appendix::appendix_b(
        &fem,
        &sys,
        &spectrum,
        sign.positive_offdiagonal_entries,
        q.tets_with_obtuse_dihedral,
        sign.rows_not_diagonally_dominant,
    );
    let empirical = if params.empirical {
        vec![
            empirical::contraction(&sys, dt, Scheme::Plain, rho19, 20_000, 1),
            empirical::contraction(&sys, dt, Scheme::Split, rho21, 20_000, 1),
        ]
    } else {
        Vec::new()
    };
    Ok(BoundsReport {
        header: Header::new(SCHEMA),
        inputs: BoundsInputs {
            mesh_file: info.path.clone(),
            rho,
            mu,
            dt,
            attached_vertices: params.attachments.vertices.len(),
            attachment_stiffness: has_att.then_some(params.attachments.stiffness),
            eigen_method: spectrum.method,
            convention: "per-axis system: M = lumped rho V/4 per tet corner, L = sum_t mu V_t A_t^T A_t (Eqs. 22-23) \
                         plus attachment stiffness on the diagonal; D = diag(L)",
        },
        mesh: MeshSection {
            vertices: mesh.num_vertices(),
            tets: mesh.num_tets(),
            source: info.clone(),
            quality: q,
            l_sign: sign,
        },
        jacobi,
        split,
        appendix_a,
        appendix_b,
        empirical,
        timing: Timing {
            assembly_ms,
            eigen_ms,
            total_ms: t0.elapsed().as_secs_f64() * 1e3,
        },
    })
}
