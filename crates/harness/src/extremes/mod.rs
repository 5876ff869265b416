//! The extremes suite (`diffsoft extremes`, `reports/extremes.json`): the simulator and its
//! gradients at the edges of their input ranges (stiffness 1 Pa to 1e12 Pa, density 1e-3 to
//! 1e5, time steps 1e-7 s to 1 s, near-degenerate and inverted tets, 1 to 1e5 tets, rotations of
//! 1e3 rad, translations of 1e6 m, activations 0 and 1, joint angles near +-pi, contact at high
//! speed, large friction).
//!
//! Each case ends in one of three explained outcomes: `stable` (every step ran, every value
//! finite), `detected_divergence` (the solver stopped with a message: divergence, non-finite
//! values, a failed factorisation) or `rejected_input` (the input was refused with a message).
//! Anything else is `failed`: a panic (caught here with `catch_unwind`, reported, and a bug to fix
//! at its root), or non-finite values that no check caught (a silent NaN). Each case also
//! checks the conserved quantities that apply (momentum, energy drift, invariance under rigid
//! motions) and whether its gradient stays finite, and states the outcomes it expects; a case
//! passes when its outcome is expected, its checks hold and its gradient is not silently
//! non-finite.

mod cases;
mod probe;
mod scenarios;

use std::fmt::Write as _;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::pool;
use crate::report::{Provenance, Verdict, CRATE_VERSION};
use crate::shard::{check_partials, check_same, Partial, Shard, ShardError};

pub use cases::{all, Case};
pub use probe::{Check, Comparison, GradientCheck, GradientStatus, Trial};

/// Schema of a shard's partial report.
pub const PARTIAL_SCHEMA: &str = "diffsoft.extremes_partial/1";
/// Schema of `reports/extremes.json`.
pub const SCHEMA: &str = "diffsoft.extremes/1";

/// How a case ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Every step ran and every value is finite.
    Stable,
    /// The solver stopped with a clear message (divergence, non-finite values, failed
    /// factorisation).
    DetectedDivergence,
    /// The input was refused with a clear message.
    RejectedInput,
    /// A panic or a silent NaN: a bug.
    Failed,
}

/// Which cases to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Subset {
    /// The cases that take well under a second each (the test suite's subset).
    Fast,
    /// Every case (the main job).
    Full,
}

/// The result of one case.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct CaseResult {
    /// Position in the full case list.
    pub index: usize,
    /// Name.
    pub name: String,
    /// Which extreme it probes.
    pub category: String,
    /// What it does.
    pub description: String,
    /// Outcomes that are correct for it.
    pub expected: Vec<Outcome>,
    /// What happened.
    pub outcome: Outcome,
    /// The solver's or validator's message (or the panic's).
    pub message: Option<String>,
    /// Steps asked for.
    pub steps: usize,
    /// Steps that ran.
    pub steps_run: usize,
    /// Conserved quantities and other checks.
    pub checks: Vec<Check>,
    /// Whether the gradient stays finite.
    pub gradient: GradientCheck,
    /// Expected outcome, checks hold, gradient not silently non-finite.
    pub passes: bool,
    /// Why it passes or fails, in words.
    pub explanation: String,
    /// Wall time (s).
    pub wall_s: f64,
}

/// A shard's part of the suite (`diffsoft extremes --shard K/N`).
#[derive(Debug, Clone, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ExtremesPartial {
    /// [`PARTIAL_SCHEMA`].
    pub schema: String,
    /// Version of the crate that wrote it.
    pub crate_version: String,
    /// Where and how this shard ran (`null` in a partial written before partials carried it).
    #[serde(default)]
    pub provenance: Option<Provenance>,
    /// Which shard.
    pub shard: Shard,
    /// Which cases.
    pub subset: Subset,
    /// Cases in the subset.
    pub total_cases: usize,
    /// This shard's cases.
    pub cases: Vec<CaseResult>,
    /// Wall time (s).
    pub wall_time_s: f64,
}

impl Partial for ExtremesPartial {
    fn shard(&self) -> Shard {
        self.shard
    }
    fn schema(&self) -> &str {
        &self.schema
    }
    fn crate_version(&self) -> &str {
        &self.crate_version
    }
}

/// Counts of outcomes.
#[derive(Debug, Clone, Copy, Default, Serialize, schemars::JsonSchema)]
pub struct Counts {
    /// Stable.
    pub stable: usize,
    /// Detected divergence.
    pub detected_divergence: usize,
    /// Rejected input.
    pub rejected_input: usize,
    /// Failed.
    pub failed: usize,
    /// Cases that pass.
    pub passing: usize,
    /// Cases whose gradient is finite.
    pub gradient_finite: usize,
    /// Cases whose gradient is refused with a message.
    pub gradient_error: usize,
}

/// `reports/extremes.json`.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct ExtremesReport {
    /// [`SCHEMA`].
    pub schema: String,
    /// Crate version.
    pub crate_version: String,
    /// Where and how this report was written.
    pub provenance: Provenance,
    /// Which cases.
    pub subset: Subset,
    /// Shards merged.
    pub shards: usize,
    /// Where and how each shard ran, in shard order (`null` for a partial written before
    /// partials carried it).
    pub shard_provenance: Vec<Option<Provenance>>,
    /// Outcome counts.
    pub counts: Counts,
    /// The cases, in list order.
    pub cases: Vec<CaseResult>,
    /// Claims.
    pub verdicts: Vec<Verdict>,
    /// Wall time summed over shards (s).
    pub wall_time_s: f64,
}

/// Run one case, catching panics.
pub fn run_case(index: usize, case: &Case) -> CaseResult {
    let t0 = Instant::now();
    let trial = catch_unwind(AssertUnwindSafe(|| (case.run)())).unwrap_or_else(|p| {
        Trial::failed(
            format!("panicked: {}", crate::pool::panic_message(p.as_ref())),
            case.steps,
        )
    });
    let expected_ok = case.expected.contains(&trial.outcome) && trial.outcome != Outcome::Failed;
    let failing_checks: Vec<&Check> = trial.checks.iter().filter(|c| !c.holds).collect();
    let gradient_ok = trial.gradient.status != GradientStatus::NonFinite;
    let checks_ok = check_set(trial.outcome, &trial.checks, &case.checks);
    let passes = expected_ok && failing_checks.is_empty() && gradient_ok && checks_ok.is_ok();
    let mut explanation = String::new();
    if let Err(e) = &checks_ok {
        let _ = write!(explanation, "its run {e}; ");
    }
    if !expected_ok {
        let _ = write!(
            explanation,
            "outcome {:?} is not one of the expected {:?}; ",
            trial.outcome, case.expected
        );
    }
    for c in &failing_checks {
        let _ = write!(explanation, "check '{}' fails ({}); ", c.quantity, c.note);
    }
    if !gradient_ok {
        let _ = write!(explanation, "the gradient is non-finite without an error; ");
    }
    if passes {
        explanation = format!(
            "{:?} as expected{}",
            trial.outcome,
            if trial.checks.is_empty() {
                String::new()
            } else {
                format!("; {} check(s) hold", trial.checks.len())
            }
        )
        .to_lowercase();
    }
    CaseResult {
        index,
        name: case.name.to_string(),
        category: case.category.to_string(),
        description: case.description.clone(),
        expected: case.expected.clone(),
        outcome: trial.outcome,
        message: trial.message,
        steps: case.steps,
        steps_run: trial.steps_run,
        checks: trial.checks,
        gradient: trial.gradient,
        passes,
        explanation: explanation.trim_end_matches("; ").to_string(),
        wall_s: t0.elapsed().as_secs_f64(),
    }
}

/// The cases of `subset`, with their indices in the full list.
pub fn select(subset: Subset) -> Vec<(usize, Case)> {
    all()
        .into_iter()
        .enumerate()
        .filter(|(_, c)| subset == Subset::Full || c.fast)
        .collect()
}

/// Run shard `shard` of `subset`: each case single-threaded on its own one-thread pool (so its
/// result does not depend on the worker count), as many at once as the current rayon pool has
/// threads, with a progress bar when `show_progress` and stderr is a terminal.
pub fn run_shard(subset: Subset, shard: Shard, show_progress: bool) -> ExtremesPartial {
    let t0 = Instant::now();
    let cases = select(subset);
    let total = cases.len();
    let mine: Vec<(usize, Case)> = cases
        .into_iter()
        .enumerate()
        .filter(|(k, _)| shard.owns(*k))
        .map(|(_, c)| c)
        .collect();
    let bar = indicatif::ProgressBar::new(mine.len() as u64);
    if !show_progress || !std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    bar.set_style(
        indicatif::ProgressStyle::with_template("extremes {bar:40} {pos}/{len} cases {elapsed_precise}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    // The largest cases first, so the last ones to finish are short.
    let mut order: Vec<usize> = (0..mine.len()).collect();
    order.sort_by_key(|&k| (mine[k].1.fast, k));
    let tasks: Vec<pool::Task<'_, CaseResult>> = order
        .iter()
        .map(|&k| -> pool::Task<'_, CaseResult> {
            let (index, case) = (&mine[k].0, &mine[k].1);
            Box::new(move || run_case(*index, case))
        })
        .collect();
    let results = pool::run(tasks, rayon::current_num_threads(), &bar);
    bar.finish_and_clear();
    let mut out: Vec<CaseResult> = results
        .into_iter()
        .zip(&order)
        .map(|(r, &k)| {
            r.unwrap_or_else(|panic| {
                let (index, case) = (mine[k].0, &mine[k].1);
                let mut c = run_case_failed(index, case, panic);
                c.wall_s = 0.0;
                c
            })
        })
        .collect();
    out.sort_by_key(|c| c.index);
    ExtremesPartial {
        schema: PARTIAL_SCHEMA.into(),
        crate_version: CRATE_VERSION.into(),
        provenance: Some(Provenance::now()),
        shard,
        subset,
        total_cases: total,
        cases: out,
        wall_time_s: t0.elapsed().as_secs_f64(),
    }
}

/// The result of a case whose run panicked outside [`run_case`]'s own guard.
fn run_case_failed(index: usize, case: &Case, panic: String) -> CaseResult {
    CaseResult {
        index,
        name: case.name.to_string(),
        category: case.category.to_string(),
        description: case.description.clone(),
        expected: case.expected.clone(),
        outcome: Outcome::Failed,
        message: Some(format!("panicked: {panic}")),
        steps: case.steps,
        steps_run: 0,
        checks: Vec::new(),
        gradient: GradientCheck::not_computed("the case failed"),
        passes: false,
        explanation: "the case panicked".into(),
        wall_s: 0.0,
    }
}

/// A shard's case checked against the case list: the same case (name, expected outcomes,
/// steps), no more steps run than asked, a wall time that is a time, and a verdict (`passes`)
/// that follows from its own outcome, checks and gradient as [`run_case`] decides it.
fn check_case(c: &CaseResult, case: &Case) -> Result<(), String> {
    if c.name != case.name || c.expected != case.expected || c.steps != case.steps {
        return Err(format!(
            "is not the case the list has at that place ('{}', expecting {:?} in {} steps)",
            case.name, case.expected, case.steps
        ));
    }
    if c.steps_run > c.steps {
        return Err(format!("ran {} steps of {}", c.steps_run, c.steps));
    }
    if !(c.wall_s.is_finite() && c.wall_s >= 0.0) {
        return Err(format!(
            "wall_s must be finite and not negative, got {}",
            diffsoft::base::number(c.wall_s)
        ));
    }
    if c.outcome == Outcome::Stable && c.steps_run != c.steps {
        return Err(format!(
            "is stable (every step ran), but ran {} steps of {}",
            c.steps_run, c.steps
        ));
    }
    for k in &c.checks {
        if let Some(m) = k.measured.filter(|m| !m.is_finite()) {
            return Err(format!(
                "check '{}' measured {}, not a finite number",
                k.quantity,
                diffsoft::base::number(m)
            ));
        }
        if k.threshold.is_some_and(|t| !t.is_finite()) {
            return Err(format!("check '{}' has a threshold that is not finite", k.quantity));
        }
        let holds = Check::verdict(k.comparison, k.measured, k.threshold);
        if k.holds != holds {
            return Err(format!(
                "check '{}' says holds = {}, but its measurement {} against its threshold {} ({:?}) gives {holds}",
                k.quantity,
                k.holds,
                k.measured.map_or("null".into(), diffsoft::base::number),
                k.threshold.map_or("null".into(), diffsoft::base::number),
                k.comparison
            ));
        }
    }
    check_gradient(&c.gradient)?;
    check_set(c.outcome, &c.checks, &case.checks)?;
    let passes = c.expected.contains(&c.outcome)
        && c.outcome != Outcome::Failed
        && c.checks.iter().all(|k| k.holds)
        && c.gradient.status != GradientStatus::NonFinite;
    if c.passes != passes {
        return Err(format!(
            "says passes = {}, but its outcome, checks and gradient give {passes}",
            c.passes
        ));
    }
    Ok(())
}

/// Whether `checks` are the checks a run of a case that declares `declared`
/// ([`Case::checks`]) records on ending in `outcome`: all of them, in order, when it ends
/// stable; some of them, in order, otherwise (a run that stops early records what it reached).
/// The error says what was recorded and what was declared.
pub(crate) fn check_set(outcome: Outcome, checks: &[Check], declared: &[String]) -> Result<(), String> {
    let recorded: Vec<&str> = checks.iter().map(|k| k.quantity.as_str()).collect();
    let fits = if outcome == Outcome::Stable {
        recorded.len() == declared.len() && recorded.iter().zip(declared).all(|(r, d)| *r == d.as_str())
    } else {
        let mut rest = declared.iter();
        recorded.iter().all(|r| rest.any(|d| d.as_str() == *r))
    };
    if fits {
        return Ok(());
    }
    Err(format!(
        "records the checks {recorded:?}, where {} {declared:?}",
        if outcome == Outcome::Stable {
            "a stable run of this case records"
        } else {
            "a run of this case records some of"
        }
    ))
}

/// A case's gradient as [`probe::Probe::gradient`] writes it: finite values, one per parameter,
/// with status `finite`; no values otherwise, and a message saying why.
fn check_gradient(g: &GradientCheck) -> Result<(), String> {
    match (g.status, &g.values) {
        (GradientStatus::Finite, Some(v)) => {
            if v.len() != g.parameters.len() {
                return Err(format!(
                    "its gradient has {} values for {} parameters",
                    v.len(),
                    g.parameters.len()
                ));
            }
            if let Some(x) = v.iter().find(|x| !x.is_finite()) {
                return Err(format!(
                    "its gradient is 'finite' but holds {}",
                    diffsoft::base::number(*x)
                ));
            }
            Ok(())
        }
        (GradientStatus::Finite, None) => Err("its gradient is 'finite' but holds no values".into()),
        (status, Some(_)) => Err(format!("its gradient is {status:?} but holds values")),
        (status, None) if g.message.as_deref().is_none_or(str::is_empty) => {
            Err(format!("its gradient is {status:?} without a message saying why"))
        }
        _ => Ok(()),
    }
}

/// Merge the partial reports of one run into the report of the unsharded run.
pub fn merge(parts: Vec<ExtremesPartial>, paths: &[String]) -> Result<ExtremesReport, ShardError> {
    check_partials(&parts, paths, PARTIAL_SCHEMA)?;
    let subsets: Vec<Subset> = parts.iter().map(|p| p.subset).collect();
    check_same("subsets", &subsets, paths)?;
    if let Some((p, path)) = parts
        .iter()
        .zip(paths)
        .find(|(p, _)| !(p.wall_time_s.is_finite() && p.wall_time_s >= 0.0))
    {
        return Err(ShardError::Mismatch(format!(
            "{path}: wall_time_s must be finite and not negative, got {}",
            diffsoft::base::number(p.wall_time_s)
        )));
    }
    let mut cases: Vec<CaseResult> = parts.iter().flat_map(|p| p.cases.iter().cloned()).collect();
    cases.sort_by_key(|c| c.index);
    let total = parts[0].total_cases;
    let listed = select(subsets[0]);
    let expected: Vec<usize> = listed.iter().map(|(i, _)| *i).collect();
    let got: Vec<usize> = cases.iter().map(|c| c.index).collect();
    if cases.len() != total || got != expected {
        return Err(ShardError::Mismatch(format!(
            "the shards hold cases {got:?}, the {:?} subset has {expected:?}",
            subsets[0]
        )));
    }
    let owner = |index: usize| {
        parts
            .iter()
            .zip(paths)
            .find(|(p, _)| p.cases.iter().any(|c| c.index == index))
            .map_or("", |(_, path)| path.as_str())
    };
    for (c, (_, case)) in cases.iter().zip(&listed) {
        check_case(c, case)
            .map_err(|e| ShardError::Mismatch(format!("{}: case {} ('{}'): {e}", owner(c.index), c.index, c.name)))?;
    }
    let mut order: Vec<&ExtremesPartial> = parts.iter().collect();
    order.sort_by_key(|p| p.shard.index);
    Ok(report(
        subsets[0],
        order.iter().map(|p| p.provenance.clone()).collect(),
        cases,
        parts.iter().map(|p| p.wall_time_s).sum(),
    ))
}

fn report(
    subset: Subset,
    shard_provenance: Vec<Option<Provenance>>,
    cases: Vec<CaseResult>,
    wall_time_s: f64,
) -> ExtremesReport {
    let mut counts = Counts::default();
    for c in &cases {
        match c.outcome {
            Outcome::Stable => counts.stable += 1,
            Outcome::DetectedDivergence => counts.detected_divergence += 1,
            Outcome::RejectedInput => counts.rejected_input += 1,
            Outcome::Failed => counts.failed += 1,
        }
        counts.passing += usize::from(c.passes);
        match c.gradient.status {
            GradientStatus::Finite => counts.gradient_finite += 1,
            GradientStatus::Error => counts.gradient_error += 1,
            _ => {}
        }
    }
    let non_finite = cases
        .iter()
        .filter(|c| c.gradient.status == GradientStatus::NonFinite)
        .count();
    let verdicts = vec![
        Verdict::at_most(
            "No case ends in a panic or a silent NaN (outcome failed)",
            counts.failed as f64,
            0.0,
        ),
        Verdict::at_most(
            "Every case ends in an outcome it expects, with its checks holding (cases that do not)",
            (cases.len() - counts.passing) as f64,
            0.0,
        ),
        Verdict::at_most(
            "No gradient is non-finite without an error (cases)",
            non_finite as f64,
            0.0,
        ),
    ];
    ExtremesReport {
        schema: SCHEMA.into(),
        crate_version: CRATE_VERSION.into(),
        provenance: Provenance::now(),
        subset,
        shards: shard_provenance.len(),
        shard_provenance,
        counts,
        cases,
        verdicts,
        wall_time_s,
    }
}

/// Run `subset` unsharded.
pub fn run(subset: Subset, show_progress: bool) -> ExtremesReport {
    let p = run_shard(subset, Shard::ALL, show_progress);
    report(subset, vec![p.provenance], p.cases, p.wall_time_s)
}

/// A table of the cases.
pub fn table(r: &ExtremesReport) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "  {:<30} {:<20} {:<6} {:<11} message / failing checks",
        "case", "outcome", "pass", "gradient"
    );
    for c in &r.cases {
        let msg = if c.passes {
            c.message.clone().unwrap_or_default()
        } else {
            c.explanation.clone()
        };
        let short: String = msg.chars().take(110).collect();
        let _ = writeln!(
            o,
            "  {:<30} {:<20} {:<6} {:<11} {}",
            c.name,
            format!("{:?}", c.outcome),
            if c.passes { "yes" } else { "NO" },
            format!("{:?}", c.gradient.status),
            short
        );
    }
    let k = &r.counts;
    let _ = writeln!(
        o,
        "  {} cases: {} stable, {} detected divergence, {} rejected input, {} failed; {} pass; gradients finite in {}, refused with a message in {}",
        r.cases.len(),
        k.stable,
        k.detected_divergence,
        k.rejected_input,
        k.failed,
        k.passing,
        k.gradient_finite,
        k.gradient_error
    );
    o
}

diffsoft::choice!(Subset {
    Fast => "fast",
    Full => "full",
});

#[cfg(test)]
mod tests {
    use super::*;

    fn recorded(names: &[&str]) -> Vec<Check> {
        names.iter().map(|n| Check::at_most(n, 0.0, 1.0, "a bound")).collect()
    }

    #[test]
    fn a_stable_run_records_every_declared_check_and_a_stopped_one_some_in_order() {
        let declared: Vec<String> = ["a", "b", "c"].iter().map(|s| s.to_string()).collect();
        assert!(check_set(Outcome::Stable, &recorded(&["a", "b", "c"]), &declared).is_ok());
        for wrong in [
            &["a", "b"][..],
            &[],
            &["a", "c", "b"],
            &["a", "b", "c", "c"],
            &["a", "b", "d"],
        ] {
            let e = check_set(Outcome::Stable, &recorded(wrong), &declared).unwrap_err();
            assert!(e.contains("a stable run of this case records"), "{wrong:?}: {e}");
        }
        let stopped = Outcome::DetectedDivergence;
        for fine in [&["a", "c"][..], &[], &["c"], &["a", "b", "c"]] {
            assert!(check_set(stopped, &recorded(fine), &declared).is_ok(), "{fine:?}");
        }
        for wrong in [&["c", "a"][..], &["d"], &["a", "a"]] {
            let e = check_set(stopped, &recorded(wrong), &declared).unwrap_err();
            assert!(e.contains("records some of"), "{wrong:?}: {e}");
        }
        assert!(check_set(Outcome::Stable, &[], &[]).is_ok());
    }
}
