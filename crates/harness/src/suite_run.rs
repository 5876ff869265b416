//! The main job: [`run_suite`] runs every section of the suite in turn (bounds and sweeps,
//! `T` scaling and the paper's arithmetic, Jacobian checks, physics checks, the skeleton,
//! actuator and gradient studies, the trade-off study, extremes, cloth and the validation
//! against closed forms), writes their reports
//! and plots and prints their summaries and the wall and CPU time per section (the CPU time
//! of every thread of the process, so `CPU / wall` says how many cores a section kept busy),
//! and last writes the report page (`index.html`, [`crate::page`]) of everything in the
//! output directory.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};

use crate::bounds::{run_mesh, t_scaling, t_scaling_chart, SuiteBoundsReport, TableRow, SUITE_BOUNDS_SCHEMA};
use crate::physics_suite::run_physics;
use crate::report::{write_json, Header};
use crate::suite::Suite;
use crate::{actuators, cloth, extremes, gradients, jacobians, plot, skeleton, summary, tradeoff, validation};
use diffsoft::analysis::appendix;

/// Run the suite at `suite_path` and write reports into `out`.
pub fn run_suite(suite_path: &Path, out: &Path) -> Result<SuiteBoundsReport> {
    let t0 = Instant::now();
    let cpu0 = process_cpu_s();
    let suite = Suite::load(suite_path)?;
    let base = suite_path.parent().unwrap_or(Path::new("."));
    diffsoft::output::output_dir(out, "--out")?;
    let mut meshes = Vec::new();
    for entry in &suite.bounds.meshes {
        let t = Instant::now();
        let r = run_mesh(base, out, entry, suite.bounds.empirical, suite.bounds.sweep_points)?;
        crate::say!(
            "  {:<22} {:>6} v {:>7} t  analysed in {:.2} s",
            entry.name,
            r.bounds.mesh.vertices,
            r.bounds.mesh.tets,
            t.elapsed().as_secs_f64()
        );
        meshes.push(r);
    }
    let mut sections = vec![("bounds and sweeps", t0.elapsed().as_secs_f64(), cpu_since(cpu0))];
    let mut lap = (Instant::now(), process_cpu_s());
    let mut section = |name: &'static str, lap: &mut (Instant, Option<f64>)| {
        sections.push((name, lap.0.elapsed().as_secs_f64(), cpu_since(lap.1)));
        *lap = (Instant::now(), process_cpu_s());
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
    let path = diffsoft::output::own_file(out, "bounds.json")?;
    write_json(&path, &report)?;
    plot::write_svg(
        &diffsoft::output::own_file(out, "t_scaling.svg")?,
        &t_scaling_chart(&report.t_scaling),
    )?;
    let table = summary::table(&report);
    // The table as printed, for the documentation that quotes it (crates/harness/tests/harness/doc_numbers.rs).
    diffsoft::output::write_atomic(&diffsoft::output::own_file(out, "bounds_table.txt")?, table.as_bytes())?;
    crate::say_raw!("{table}");
    section("t-scaling and paper arithmetic", &mut lap);
    crate::say!("\nJacobian checks of the skeleton:");
    let jac = jacobians::run(2021);
    write_json(diffsoft::output::own_file(out, "jacobians.json")?, &jac)?;
    for v in &jac.verdicts {
        crate::say!("  [{}] {}", if v.holds { "holds" } else { "FAILS" }, v.claim);
    }
    section("Jacobian checks", &mut lap);
    crate::say!("\nphysics checks of the forward solver:");
    let phys = run_physics(base, out, &suite.physics)?;
    write_json(diffsoft::output::own_file(out, "physics.json")?, &phys)?;
    crate::say_raw!("{}", summary::physics_table(&phys));
    section("physics checks", &mut lap);
    crate::say!("\nskeleton study ({}):", suite.skeleton.scene.display());
    let sk = skeleton::study(
        &base.join(&suite.skeleton.scene),
        suite.skeleton.steps,
        &suite.skeleton.arm_bones,
        out,
    )?;
    write_json(diffsoft::output::own_file(out, "skeleton.json")?, &sk)?;
    crate::say_raw!("{}", summary::skeleton_table(&sk));
    section("skeleton study", &mut lap);
    crate::say!("\nactuator study:");
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
    write_json(diffsoft::output::own_file(out, "actuators.json")?, &act)?;
    crate::say_raw!("{}", actuators::table(&act));
    section("actuator study", &mut lap);
    crate::say!(
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
    write_json(diffsoft::output::own_file(out, "gradients.json")?, &grad)?;
    for v in &grad.verdicts {
        crate::say!("  [{}] {}", if v.holds { "holds" } else { "FAILS" }, v.claim);
    }
    section("gradient study", &mut lap);
    if let Some(t) = &suite.tradeoff {
        crate::say!("\ntrade-off of solver settings (accuracy against cost):");
        tradeoff::suite_section(base, out, &t.scenes)?;
    }
    section("trade-off study", &mut lap);
    if let Some(x) = &suite.extremes {
        crate::say!("\nextremes ({:?} subset):", x.subset);
        let ex = extremes::run(x.subset, true);
        write_json(diffsoft::output::own_file(out, "extremes.json")?, &ex)?;
        crate::say_raw!("{}", extremes::table(&ex));
    }
    section("extremes", &mut lap);
    if let Some(c) = &suite.cloth {
        crate::say!("\ncloth study:");
        let scenes: Vec<(std::path::PathBuf, usize)> =
            c.scenes.iter().map(|s| (base.join(&s.scene), s.steps)).collect();
        let cl = cloth::study(&scenes, &c.detection_sizes, out)?;
        write_json(diffsoft::output::own_file(out, "cloth.json")?, &cl)?;
        crate::say_raw!("{}", cloth::table(&cl));
        for e in &cl.plot_errors {
            crate::warn!("warning: cloth plot not drawn: {e}");
        }
    }
    section("cloth study", &mut lap);
    if let Some(v) = &suite.validation {
        crate::say!("\nvalidation against closed forms ({:?} subset):", v.subset);
        let val = validation::run(v.subset, &[]);
        write_json(diffsoft::output::own_file(out, "validation.json")?, &val)?;
        crate::say_raw!("{}", validation::table(&val));
    }
    section("validation", &mut lap);
    crate::say!("\nwall and CPU time per section:");
    for (name, wall, cpu) in &sections {
        match cpu {
            Some(c) if *wall > 0.0 => crate::say!("  {name:<32} {wall:>7.1} s {c:>8.1} CPU-s ({:.2} cores)", c / wall),
            _ => crate::say!("  {name:<32} {wall:>7.1} s"),
        }
    }
    if let Some(c) = cpu_since(cpu0) {
        let wall = t0.elapsed().as_secs_f64();
        crate::say!(
            "  {:<32} {wall:>7.1} s {c:>8.1} CPU-s ({:.2} cores)",
            "all sections",
            c / wall
        );
    }
    crate::say!(
        "wrote {}, {}, {}, {}, {}, gradients.json, tradeoff.json, extremes.json, cloth.json, validation.json, t_scaling.svg, cantilever.svg, skeleton_*.svg, gradient_cost.svg, tradeoff_*.svg, cloth_*.svg, actuator and cloth frames and {} sweep plots in {:.1} s",
        path.display(),
        out.join("jacobians.json").display(),
        out.join("physics.json").display(),
        out.join("skeleton.json").display(),
        out.join("actuators.json").display(),
        report.meshes.len(),
        t0.elapsed().as_secs_f64()
    );
    // Last: the page shows every report and plot written above (and any other in `out`).
    let (page, page_path) = crate::page::write(out).context("the reports are written, the report page is not")?;
    crate::say!(
        "wrote {} ({} verdicts, {} fail, {} plots)",
        page_path.display(),
        page.verdicts,
        page.failing,
        page.plots
    );
    Ok(report)
}

/// CPU time of the whole process so far (s: user plus system, every thread, those that have
/// ended included), from `/proc/self/stat` in its clock ticks of 1/100 s (Linux's fixed
/// `USER_HZ`); `None` where that file is not there (not Linux) or not as expected.
fn process_cpu_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    parse_stat_cpu_s(&stat)
}

/// Process CPU seconds since a reading `start` of [`process_cpu_s`] (`None` if either is).
fn cpu_since(start: Option<f64>) -> Option<f64> {
    start.zip(process_cpu_s()).map(|(a, b)| b - a)
}

/// `utime + stime` of a `/proc/PID/stat` line, in seconds. The command name (field 2) is in
/// parentheses and may hold spaces or parentheses itself, so fields are counted after the last
/// `)`: the state is the first, `utime` and `stime` (fields 14 and 15) the twelfth and
/// thirteenth.
fn parse_stat_cpu_s(stat: &str) -> Option<f64> {
    let rest = &stat[stat.rfind(')')? + 1..];
    let mut fields = rest.split_whitespace().skip(11);
    let utime: u64 = fields.next()?.parse().ok()?;
    let stime: u64 = fields.next()?.parse().ok()?;
    Some((utime + stime) as f64 / 100.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_time_is_read_after_the_command_name_whatever_it_holds() {
        let line = "4242 (a (weird) name) R 1 4242 4242 0 -1 4194304 500 0 0 0 1234 56 0 0 20 0 3 0 100 0 0";
        assert_eq!(parse_stat_cpu_s(line), Some(12.90));
        assert_eq!(parse_stat_cpu_s("4242 (cut short) R 1 2"), None);
        assert_eq!(parse_stat_cpu_s("no parenthesis at all"), None);
    }

    #[test]
    fn the_process_cpu_clock_advances_with_work() {
        let Some(a) = process_cpu_s() else {
            return; // not Linux
        };
        // Busy until the clock has moved by a few ticks (or a generous bound on a loaded
        // machine): a clock that never advances fails.
        let t = Instant::now();
        let mut x = 0.0f64;
        let mut b = a;
        while b - a < 0.05 && t.elapsed().as_secs_f64() < 30.0 {
            for _ in 0..100_000 {
                x = std::hint::black_box(x + 1.0);
            }
            b = process_cpu_s().expect("read once already");
        }
        assert!(b - a >= 0.05, "{a} -> {b} after {:.1} s", t.elapsed().as_secs_f64());
    }
}
