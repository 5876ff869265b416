//! Human-readable summaries of reports (what the CLI prints).

use std::fmt::Write as _;

use super::{PhysicsReport, QualityReport, SuiteBoundsReport, SweepReport};
use diffsoft::analysis::bounds::BoundsReport;

fn opt(v: Option<f64>) -> String {
    v.map_or("none (every dt)".to_string(), |h| format!("{h:.6e} s"))
}

fn yes(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "NO"
    }
}

/// Summary of a bounds report.
pub fn bounds_summary(r: &BoundsReport) -> String {
    let mut s = String::new();
    let m = &r.mesh;
    let q = &m.quality;
    let _ = writeln!(
        s,
        "mesh        {} ({} vertices, {} tets, {:?})",
        r.inputs.mesh_file, m.vertices, m.tets, m.source.format
    );
    if m.source.dropped_nodes > 0 || m.source.reoriented_tets > 0 {
        let _ = writeln!(
            s,
            "            dropped {} unused nodes, re-oriented {} inverted tets",
            m.source.dropped_nodes, m.source.reoriented_tets
        );
    }
    let _ = writeln!(
        s,
        "quality     dihedral {:.2}..{:.2} deg, {} tets with an obtuse angle, {} positive off-diagonal entries of L",
        q.min_dihedral_deg, q.max_dihedral_deg, q.tets_with_obtuse_dihedral, m.l_sign.positive_offdiagonal_entries
    );
    let _ = writeln!(
        s,
        "inputs      rho {:e}  mu {:e}  dt {:e}  ({:?} eigensolver{})",
        r.inputs.rho,
        r.inputs.mu,
        r.inputs.dt,
        r.inputs.eigen_method,
        if r.inputs.attached_vertices > 0 {
            format!(", {} attached vertices", r.inputs.attached_vertices)
        } else {
            String::new()
        }
    );
    let _ = writeln!(
        s,
        "Eq. 19      rho(G19) = {:.6e}  h*_19 = {}  converges at dt: {}",
        r.jacobi.spectral_radius,
        opt(r.jacobi.critical_dt),
        yes(r.jacobi.converges)
    );
    let _ = writeln!(
        s,
        "Eq. 21      rho(G21) = {:.6e}  h*_21 = {}  converges at dt: {}  (rho -> {:.6} as h -> inf)",
        r.split.spectral_radius,
        opt(r.split.critical_dt),
        yes(r.split.converges),
        r.split.spectral_radius_limit_h_inf.unwrap_or(f64::NAN)
    );
    let a = &r.appendix_a;
    let _ = writeln!(
        s,
        "Appendix A  bound on h               value          / h*_19      safe"
    );
    for (name, b) in [
        ("Eq. 28 (min over tets)", &a.eq28_min_over_tets),
        ("Eq. 29 (as printed)", &a.eq29),
        ("Eq. 24 Gershgorin", &a.gershgorin),
        ("re-derived sigma_min", &a.rederived_sigma_min),
        ("re-derived altitude", &a.rederived_altitude),
    ] {
        let _ = writeln!(
            s,
            "            {name:<24} {:>12.4e} {:<6} {:>10.3e}  {}",
            b.dt,
            b.units,
            b.ratio_to_exact,
            yes(b.safe)
        );
    }
    let b = &r.appendix_b;
    let _ = writeln!(
        s,
        "Appendix B  (21) converges for every h: {}  (lambda_max(D^-1 L) = {:.6}, threshold 2)",
        yes(b.holds),
        b.lambda_max_dinv_l
    );
    let _ = writeln!(s, "            {}", b.explanation);
    for e in &r.empirical {
        let _ = writeln!(
            s,
            "empirical   {:?}: observed rate {:.6} vs predicted {:.6} (rel. diff {:.1e}, {} iterations, {:?})",
            e.scheme, e.observed_rate, e.predicted_spectral_radius, e.relative_difference, e.iterations, e.outcome
        );
    }
    let _ = writeln!(
        s,
        "time        assembly {:.1} ms, eigenvalues {:.1} ms, total {:.1} ms",
        r.timing.assembly_ms, r.timing.eigen_ms, r.timing.total_ms
    );
    s
}

/// Summary of a sweep.
pub fn sweep_summary(r: &SweepReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "mesh {}: h*_19 = {:.6e} s, h*_21 = {}",
        r.inputs.mesh_file,
        r.critical_dt_plain,
        opt(r.critical_dt_split)
    );
    let _ = writeln!(s, "{:>14} {:>14} {:>14}", "dt", "rho(G19)", "rho(G21)");
    for p in &r.points {
        let _ = writeln!(s, "{:>14.6e} {:>14.6e} {:>14.6e}", p.dt, p.rho_plain, p.rho_split);
    }
    s
}

/// Summary of a quality report.
pub fn quality_summary(r: &QualityReport) -> String {
    let q = &r.quality;
    let mut s = String::new();
    let _ = writeln!(s, "mesh        {} ({:?})", r.source.path, r.source.format);
    let _ = writeln!(
        s,
        "counts      {} vertices, {} tets (dropped {} unused nodes, re-oriented {} tets, skipped {} non-tet elements)",
        q.vertices, q.tets, r.source.dropped_nodes, r.source.reoriented_tets, r.source.skipped_elements
    );
    let _ = writeln!(
        s,
        "volume      total {:.6e}, min {:.3e}, max {:.3e}, min normalised {:.3e}",
        q.total_volume, q.min_volume, q.max_volume, q.min_normalized_volume
    );
    let _ = writeln!(
        s,
        "edges       min {:.3e}, mean {:.3e}, max {:.3e}; min altitude {:.3e}",
        q.min_edge, q.mean_edge, q.max_edge, q.min_altitude
    );
    let _ = writeln!(
        s,
        "dihedral    min {:.3} deg, max {:.3} deg, {} tets with an obtuse angle",
        q.min_dihedral_deg, q.max_dihedral_deg, q.tets_with_obtuse_dihedral
    );
    let l = &r.l_sign;
    let _ = writeln!(
        s,
        "L           {} positive off-diagonal entries ({} edges), {} rows not diagonally dominant, M-matrix: {}",
        l.positive_offdiagonal_entries,
        l.positive_offdiagonal_edges,
        l.rows_not_diagonally_dominant,
        yes(l.is_m_matrix)
    );
    s
}

/// The table printed by `diffsoft verify`.
pub fn table(r: &SuiteBoundsReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\n{:<18} {:>5} {:>6} {:>8} | {:>10} {:>9} {:>4} | {:>10} {:>9} {:>4} | {:>10} {:>5} | {:>6}",
        "mesh", "verts", "tets", "dt", "h*_19", "rho19", "conv", "h*_21", "rho21", "conv", "Eq.29", "safe", "App.B"
    );
    let _ = writeln!(s, "{}", "-".repeat(128));
    for t in &r.table {
        let _ = writeln!(
            s,
            "{:<18} {:>5} {:>6} {:>8.2e} | {:>10.3e} {:>9.2e} {:>4} | {:>10} {:>9.3e} {:>4} | {:>10.3e} {:>5} | {:>6}",
            t.mesh,
            t.vertices,
            t.tets,
            t.dt,
            t.critical_dt_plain,
            t.rho_plain,
            yes(t.plain_converges),
            t.critical_dt_split.map_or("none".to_string(), |h| format!("{h:.3e}")),
            t.rho_split,
            yes(t.split_converges),
            t.eq29,
            yes(t.eq29_safe),
            if t.appendix_b_holds { "holds" } else { "FAILS" }
        );
    }
    let p = &r.paper_arithmetic;
    let _ = writeln!(
        s,
        "\nAppendix A arithmetic (T={}, mu={:e}, edge={:e}, rho={}): Eq. 29 gives h < 1/{:.1} (printed 1/1934: reproduced {}); \
         exact h*_19 is {:.3e} s for a regular tet and {:.3e} s for a {}-tet box of that edge: the printed step is {:.0}x too large.",
        p.tets, p.mu, p.edge, p.rho, p.eq29_inverse_dt, yes(p.reproduced), p.exact_dt_regular_tet, p.exact_dt_box, p.box_tets, p.printed_over_exact
    );
    let ts = &r.t_scaling;
    let _ = writeln!(
        s,
        "Eq. 29's T dependence: at fixed cell size {:e}, h*_19 scales like T^{:.3} (Eq. 29 like T^{:.3}); claim T^-0.5 holds: {}",
        ts.cell_size,
        ts.exact_exponent,
        ts.eq29_exponent,
        yes(ts.verdicts.first().is_some_and(|v| v.holds))
    );
    s
}

/// The physics summary printed by `diffsoft verify`.
pub fn physics_table(r: &PhysicsReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\ncantilever  {:>6} {:>12} {:>12} {:>9} {:>7}",
        "tets", "w (m)", "w_EB (m)", "error", "its"
    );
    for c in &r.cantilever {
        let _ = writeln!(
            s,
            "            {:>6} {:>12.5e} {:>12.5e} {:>8.2}% {:>7}",
            c.tets,
            c.tip_deflection,
            c.euler_bernoulli,
            100.0 * c.relative_error,
            c.iterations
        );
    }
    for v in &r.verdicts {
        let _ = writeln!(s, "  [{}] {}", if v.holds { "holds" } else { "FAILS" }, v.claim);
    }
    s
}

/// The table printed by `diffsoft jacobians`: per check the largest error against dual numbers
/// and against central differences, each with its tolerance at the worst entry
/// (`atol + rtol |r|`), the best step and the truncation slope ("linear": no truncation error
/// at any step; "-": an actuator check whose sweep shows no truncation side above round-off).
pub fn jacobians_table(r: &super::jacobians::JacobiansReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<26} {:<40} {:>9} {:>9} {:>9} {:>9} {:>8} {:>6} {:>4}",
        "check", "configuration", "vs dual", "tol", "vs FD", "tol", "best h", "slope", "pass"
    );
    let bound = |c: &super::fd::Comparison| c.atol + c.rtol * c.reference_at_worst.abs();
    for c in &r.checks {
        let _ = writeln!(
            s,
            "{:<26} {:<40} {:>9.2e} {:>9.2e} {:>9.2e} {:>9.2e} {:>8.1e} {:>6} {:>4}",
            c.name,
            c.configuration,
            c.versus_dual.max_abs_error,
            bound(&c.versus_dual),
            c.versus_fd.max_abs_error,
            bound(&c.versus_fd),
            c.sweep.best_step,
            if c.sweep.truncation_slope.is_finite() {
                format!("{:.2}", c.sweep.truncation_slope)
            } else if c.condition.is_some() {
                "-".to_string()
            } else {
                // No truncation side: the map is linear in this coordinate (exact at every step).
                "linear".to_string()
            },
            yes(c.pass())
        );
    }
    let a = &r.actuator_constraints;
    let _ = writeln!(
        s,
        "actuator constraints: max |prod x - a|/a = {:.1e} over {} pneumatic cases, max ||p| - (1 - a)| = {:.1e} over {} muscle cases",
        a.max_product_rel_error, a.pneumatic_cases, a.max_fibre_length_error, a.muscle_cases
    );
    for v in &r.verdicts {
        let _ = writeln!(s, "  [{}] {}", if v.holds { "holds" } else { "FAILS" }, v.claim);
    }
    s
}

/// The lines `diffsoft verify` prints for the skeleton study.
pub fn skeleton_table(r: &super::skeleton::SkeletonReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "  {:<12} {:>10} {:>8} {:>10} {:>22} {:>22} {:>7}",
        "run", "ms/step", "it/step", "bone err", "arm elevation (deg)", "arm length ratio", "height"
    );
    for run in [&r.with_bones, &r.without_bones] {
        let last = run.samples.last();
        let fmt = |v: Option<&Vec<f64>>, p: usize| {
            v.map_or(String::new(), |v| {
                v.iter().map(|x| format!("{x:.*}", p)).collect::<Vec<_>>().join(" / ")
            })
        };
        let _ = writeln!(
            s,
            "  {:<12} {:>10.3} {:>8.2} {:>10.1e} {:>22} {:>22} {:>7.3}",
            if run.with_bones { "with bones" } else { "no bones" },
            run.median_ms_per_step,
            run.mean_iterations,
            run.max_bone_length_error,
            fmt(last.map(|l| &l.arm_elevation_deg), 1),
            fmt(last.map(|l| &l.arm_length_ratio), 3),
            last.map_or(f64::NAN, |l| l.height_ratio)
        );
    }
    let _ = writeln!(
        s,
        "  cost per iteration ({} it/step, {} threads): {:.3} ms with bones / {:.3} ms without = {:.2}x",
        r.cost.iterations, r.cost.threads, r.cost.with_bones_ms, r.cost.without_bones_ms, r.cost.ratio
    );
    for v in &r.verdicts {
        let _ = writeln!(s, "  [{}] {}", if v.holds { "holds" } else { "FAILS" }, v.claim);
    }
    s
}
