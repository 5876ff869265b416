//! A readable summary of a scene's study (printed by `diffsoft tradeoff`, `merge` and
//! `verify`).

use diffsoft::base::Choice;
use std::collections::BTreeMap;
use std::fmt::Write as _;

use super::report::{Pick, Row, SceneTradeoff, Status};

/// A readable summary of one scene's study.
pub fn summary(s: &SceneTradeoff) -> String {
    let mut o = String::new();
    let sc = &s.scene;
    let ran = s.rows.iter().filter(|r| r.status == Status::Ran).count();
    let resolved = s.rows.iter().filter(|r| r.status == Status::Resolved).count();
    let failed: Vec<&Row> = s
        .rows
        .iter()
        .filter(|r| matches!(r.status, Status::Diverged | Status::Rejected | Status::Panicked))
        .collect();
    let _ = writeln!(
        o,
        "  {}: {} vertices, {} tets{}, h = {:e} s, {} steps of h; reference {} at h/{}; {} settings: {ran} ran, {resolved} resolved to another row, {} stopped with an error ({:.1} s on {:?} workers)",
        s.name,
        sc.vertices,
        sc.tets,
        if sc.bones > 0 { format!(", {} bones", sc.bones) } else { String::new() },
        sc.dt,
        s.inputs.steps,
        s.inputs.reference_integrator.name(),
        s.inputs.reference_divisor,
        s.rows.len(),
        failed.len(),
        s.wall_time_s,
        s.method.workers
    );
    let mut kinds: BTreeMap<String, usize> = BTreeMap::new();
    for r in &failed {
        *kinds.entry(format!("{:?}", r.status).to_lowercase()).or_default() += 1;
    }
    if let Some(r) = failed.first() {
        let _ = writeln!(
            o,
            "    stopped: {kinds:?}; e.g. {}: {}",
            r.id,
            r.message.as_deref().unwrap_or("")
        );
    }
    let _ = writeln!(
        o,
        "    Pareto front ({}; error = max vertex error / largest displacement):",
        s.pareto.time_meaning
    );
    for p in &s.pareto.trajectory {
        let _ = writeln!(o, "      {:<28} {:>10.4e} {:>10.3e}", p.id, p.time, p.error);
    }
    if !s.observed_orders.is_empty() {
        let _ = writeln!(o, "    observed order in the time step (direct, tightest tolerance):");
        for ord in &s.observed_orders {
            let _ = writeln!(
                o,
                "      {:<14} {} -> {}: {} ({:.3e} -> {:.3e})",
                ord.integrator.name(),
                ord.coarse,
                ord.fine,
                ord.order.map_or("-".into(), |p| format!("{p:.2}")),
                ord.coarse_error,
                ord.fine_error
            );
        }
    }
    for r in &s.recommendations {
        let show = |p: &Option<Pick>, note: &str| match p {
            Some(p) => format!("{} ({:.3e}, error {:.2e})", p.id, p.time, p.error),
            None => format!("none: {note}"),
        };
        let _ = writeln!(o, "    target {:e}:", r.target);
        let _ = writeln!(o, "      trajectory:      {}", show(&r.trajectory, &r.trajectory_note));
        let _ = writeln!(
            o,
            "      keeping h:       {}",
            show(&r.at_scene_dt, &r.at_scene_dt_note)
        );
        let _ = writeln!(o, "      gradient:        {}", show(&r.gradient, &r.gradient_note));
        let _ = writeln!(
            o,
            "      gradient at h:   {}",
            show(&r.gradient_at_scene_dt, &r.gradient_at_scene_dt_note)
        );
    }
    if let Some(m) = &s.models {
        let _ = writeln!(
            o,
            "    material models against {} at h/{} (Newton, tolerance {:e}; relative to {:.3e} m):",
            m.reference_model.name(),
            m.reference_divisor,
            m.reference_tolerance,
            m.displacement_scale
        );
        for r in &m.rows {
            let _ = match (r.max_relative, r.cpu_s_per_sim_s) {
                (Some(e), c) => writeln!(
                    o,
                    "      {:<22} max error {e:.3e}, rms {:.3e}, {} CPU s per simulated s, {:.1} Newton iterations per step",
                    r.id,
                    r.rms_relative.unwrap_or(f64::NAN),
                    c.map_or("-".into(), |c| format!("{c:.3e}")),
                    r.iterations_per_step.unwrap_or(f64::NAN)
                ),
                (None, _) => writeln!(o, "      {:<22} {}", r.id, r.status),
            };
        }
    }
    for v in &s.verdicts {
        let _ = writeln!(
            o,
            "    [{}] {} (measured {}, threshold {})",
            if v.holds { "holds" } else { "FAILS" },
            v.claim,
            v.measured.map_or("-".into(), |m| format!("{m:.3e}")),
            v.threshold.map_or("-".into(), |m| format!("{m:.3e}"))
        );
    }
    o
}
