//! `diffsoft tradeoff`: its options and the sweep it runs (from a scene, a cantilever or a
//! spec file; one shard's partial report, or the whole study with its plots).

use super::choice::choice;
use super::files::{check_plot_paths, preflight, save};
use super::prelude::*;

/// Options of `diffsoft tradeoff`.
#[derive(clap::Args)]
pub(crate) struct TradeoffArgs {
    /// Scene file (diffsoft or paper format); or --cantilever, or --spec.
    scene: Option<PathBuf>,
    /// Instead of a scene: a generated cantilever with these cells along x,y,z (6 tets per
    /// cell; 1 m x 0.25 m x 0.25 m, E 1e6, nu 0.3, rho 1000, h = 0.01 s), e.g. 52,13,13.
    #[arg(long, value_delimiter = ',')]
    cantilever: Option<Vec<usize>>,
    /// Instead of the options below: a sweep as JSON (a `tradeoff.scenes` entry of the suite;
    /// scene paths relative to that file); the grid's options are refused beside it.
    #[arg(long)]
    spec: Option<PathBuf>,
    /// Name in the report (default: the scene's file stem).
    #[arg(long, conflicts_with = "spec")]
    name: Option<String>,
    /// Simulated duration, in steps of the scene's time step h.
    #[arg(long, conflicts_with = "spec", default_value_t = 50, value_parser = super::numbers::at_least_one)]
    steps: usize,
    /// Grid time steps h/d.
    #[arg(long, conflicts_with = "spec", value_delimiter = ',', default_values_t = [1, 2, 4, 8])]
    dt_divisors: Vec<usize>,
    /// The reference runs at h/R.
    #[arg(long, conflicts_with = "spec", default_value_t = 16)]
    reference_divisor: usize,
    /// Tolerance of the reference runs.
    #[arg(long, conflicts_with = "spec", default_value_t = 1e-12, value_parser = super::numbers::positive)]
    reference_tolerance: f64,
    /// Anderson memory of the reference trajectories (0: plain iteration).
    #[arg(long, conflicts_with = "spec", default_value_t = 0)]
    reference_anderson: usize,
    /// Solver families.
    #[arg(long, conflicts_with = "spec", value_parser = choice::<diffsoft_harness::tradeoff::Family>(), value_delimiter = ',', default_values = ["direct", "split", "chebyshev", "certified"])]
    families: Vec<diffsoft_harness::tradeoff::Family>,
    /// Time integrators of the grid (bdf2 rows are named `bdf2/...`).
    #[arg(long, conflicts_with = "spec", value_parser = choice::<diffsoft::solver::Integrator>(), value_delimiter = ',', default_values = ["implicit_euler"])]
    integrators: Vec<diffsoft::solver::Integrator>,
    /// Families run with the integrators after the first (default: every one of --families).
    #[arg(long, conflicts_with = "spec", value_parser = choice::<diffsoft_harness::tradeoff::Family>(), value_delimiter = ',')]
    integrator_families: Vec<diffsoft_harness::tradeoff::Family>,
    /// Material models to compare on the scene (every body switched to each, Newton at every
    /// grid step, against neo_hookean at h/R); default none.
    #[arg(long, conflicts_with = "spec", value_parser = choice::<diffsoft::base::MaterialModel>(), value_delimiter = ',')]
    models: Vec<diffsoft::base::MaterialModel>,
    /// Newton tolerance of the model comparison.
    #[arg(long, conflicts_with = "spec", default_value_t = 1e-8, value_parser = super::numbers::positive)]
    model_tolerance: f64,
    /// Iteration caps of the newton family (default, or `''`: --caps).
    #[arg(long, conflicts_with = "spec", default_value = "")]
    newton_caps: List<usize>,
    /// Integrator of the h/R reference run (the total error of every setting).
    #[arg(long, conflicts_with = "spec", value_parser = choice::<diffsoft::solver::Integrator>(), default_value = "implicit_euler")]
    reference_integrator: diffsoft::solver::Integrator,
    /// Iteration caps (tolerance 0), comma-separated; `--caps ''` for none.
    #[arg(long, conflicts_with = "spec", default_value = "1,3,10,30,100")]
    caps: List<usize>,
    /// Tolerances, comma-separated; `--tolerances ''` for none.
    #[arg(long, conflicts_with = "spec", default_value = "1e-2,1e-4,1e-6,1e-8,1e-10")]
    tolerances: List<f64>,
    /// Time-step divisors whose settings also get a gradient (default: none).
    #[arg(long, conflicts_with = "spec", value_delimiter = ',')]
    gradient_dt_divisors: Vec<usize>,
    /// Loss of the gradients: final_com.x|y|z or mean_com.x|y|z.
    #[arg(long, conflicts_with = "spec", default_value = "final_com.y")]
    loss: String,
    /// Target relative errors to recommend a setting for.
    #[arg(long, conflicts_with = "spec", value_delimiter = ',', default_values_t = [1e-2, 1e-4, 1e-6], value_parser = super::numbers::positive)]
    targets: Vec<f64>,
    /// Cost axis of the Pareto fronts: cpu (thread CPU time) or iterations (deterministic).
    #[arg(long, conflicts_with = "spec", value_parser = choice::<diffsoft_harness::tradeoff::TimeAxis>(), default_value = "cpu")]
    time_axis: diffsoft_harness::tradeoff::TimeAxis,
    /// Repeat each forward run until this many CPU seconds are measured (at most 1000 runs; each row's `timing.runs` says how many ran).
    #[arg(long, conflicts_with = "spec", default_value_t = diffsoft_harness::tradeoff::DEFAULT_MIN_TIMING_S, value_parser = super::numbers::non_negative)]
    min_timing_s: f64,
    /// Run only shard K of N (0 <= K < N): writes a partial report for `diffsoft merge`.
    #[arg(long, value_name = "K/N")]
    shard: Option<diffsoft_harness::shard::Shard>,
    /// Write the JSON report (or the shard's partial report) here (`-`: standard output).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write the SVG plots into this directory (default: the JSON's directory; the working
    /// directory without `--json` or with `--json -`).
    #[arg(long)]
    svg_dir: Option<PathBuf>,
}

/// `diffsoft tradeoff`: the sweep from a scene, a cantilever or a spec file; a shard's partial
/// report, or the whole study with its plots.
pub(crate) fn tradeoff(args: TradeoffArgs) -> Result<()> {
    let TradeoffArgs {
        scene,
        cantilever,
        spec,
        name,
        steps,
        dt_divisors,
        reference_divisor,
        reference_tolerance,
        reference_anderson,
        families,
        integrators,
        integrator_families,
        reference_integrator,
        newton_caps,
        models,
        model_tolerance,
        caps,
        tolerances,
        gradient_dt_divisors,
        loss,
        targets,
        time_axis,
        min_timing_s,
        shard,
        json,
        svg_dir,
    } = args;
    use diffsoft_harness::tradeoff::{self, Cantilever, SceneSource, TradeoffSpec};
    let input_paths: Vec<PathBuf> = spec.iter().chain(scene.iter()).cloned().collect();
    let inputs: Vec<&Path> = input_paths.iter().map(PathBuf::as_path).collect();
    preflight(json.as_deref(), &inputs)?;
    if let Some(dir) = &svg_dir {
        // Before the sweep, not after it: a file or device given as the plots' directory.
        diffsoft::output::output_dir(dir, "--svg-dir")?;
    }
    let spec_given = spec.is_some();
    let (spec, base) = match (spec, scene, cantilever) {
        (Some(path), None, None) => {
            let text = std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
            let spec: TradeoffSpec =
                serde_json::from_str(&text).with_context(|| format!("{}: not a trade-off sweep", path.display()))?;
            (spec, path.parent().unwrap_or(Path::new(".")).to_path_buf())
        }
        (None, scene, cantilever) => {
            let (source, default_name) = match (scene, cantilever) {
                (Some(p), None) => {
                    let stem = p
                        .file_stem()
                        .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
                    (SceneSource::Scene(p), stem)
                }
                (None, Some(c)) if c.len() == 3 => {
                    let mut b = Cantilever::small();
                    b.cells = [c[0], c[1], c[2]];
                    let tets = 6 * c.iter().product::<usize>();
                    (SceneSource::Cantilever(b), format!("cantilever_{tets}"))
                }
                (None, Some(c)) => bail!("--cantilever takes three cell counts, e.g. 52,13,13 (got {c:?})"),
                _ => bail!("give a scene file, --cantilever NX,NY,NZ or --spec FILE (one of them)"),
            };
            let mut s = TradeoffSpec::new(&name.unwrap_or(default_name), source, steps);
            s.dt_divisors = dt_divisors;
            s.reference_divisor = reference_divisor;
            s.reference_tolerance = reference_tolerance;
            s.reference_anderson = reference_anderson;
            s.families = families;
            s.integrators = integrators;
            s.integrator_families = integrator_families;
            s.reference_integrator = reference_integrator;
            s.newton_caps = newton_caps.0;
            s.models = models;
            s.model_tolerance = model_tolerance;
            s.caps = caps.0;
            s.tolerances = tolerances.0;
            s.gradient_dt_divisors = gradient_dt_divisors;
            s.loss = loss;
            s.targets = targets;
            s.time_axis = time_axis;
            s.min_timing_s = min_timing_s;
            (s, PathBuf::from("."))
        }
        _ => bail!("--spec replaces the scene and the grid options: give one of a scene file, --cantilever, --spec"),
    };
    // The reference runs take `steps x reference_divisor` steps and keep their states (the
    // sweep's own numbers: a spec file's, not the command line's defaults).
    let (steps, reference_divisor) = (spec.steps, spec.reference_divisor);
    // Named as the user gave them: the spec file's fields, or the flags.
    let (steps_name, divisor_name) = match inputs.first().filter(|_| input_paths.len() == 1 && spec_given) {
        Some(file) => (format!("{}: steps", file.display()), "reference_divisor"),
        None => ("--steps".to_string(), "--reference-divisor"),
    };
    let reference_steps = steps
        .checked_mul(reference_divisor)
        .with_context(|| format!("{steps_name} {steps} x {divisor_name} {reference_divisor} overflows"))?;
    diffsoft::base::memory::check(
        &format!("{steps_name} {steps} at h/{reference_divisor}"),
        reference_steps,
        1024,
    )?;
    let workers = rayon::current_num_threads();
    let plot_dir = svg_dir
        .clone()
        .or_else(|| json.as_ref().and_then(|j| j.parent().map(Path::to_path_buf)))
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or_else(|| PathBuf::from("."));
    if shard.is_none() {
        check_plot_paths(json.as_deref(), &plot_dir, &tradeoff::plot_names(&spec.name), &inputs)?;
    }
    match shard {
        Some(k) => {
            let Some(path) = json else {
                bail!("--shard needs --json (where the partial report goes)");
            };
            diffsoft_harness::shard::check_items(k, spec.grid().len(), "settings")?;
            let part = tradeoff::run_shard(&spec, &base, k, workers, true)?;
            save(&path, &part, &inputs)?;
            say!(
                "shard {k}: {} of {} settings, {:.1} s; merge all shards with `diffsoft merge`",
                part.rows.len(),
                part.total_rows,
                part.wall_time_s
            );
        }
        None => {
            let mut s = tradeoff::run_scene(&spec, &base, workers, true)?;
            // Data before plots: a plot that fails (nothing to draw) loses no data.
            let plots = tradeoff::write_plots(&mut s, &plot_dir);
            say_raw!("{}", tradeoff::summary(&s));
            let report = tradeoff::TradeoffReport::new(vec![s]);
            if let Some(path) = &json {
                save(path, &report, &inputs)?;
            }
            plots.context(if json.is_some() {
                "the report is written, a plot is not"
            } else {
                "a plot could not be drawn"
            })?;
        }
    }
    Ok(())
}

/// A comma-separated list given as one value, which may be empty (`--caps ''`: none).
#[derive(Clone, Debug)]
pub(crate) struct List<T>(Vec<T>);

impl<T: std::str::FromStr> std::str::FromStr for List<T> {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        s.split(',')
            .map(str::trim)
            .filter(|t| !t.is_empty())
            .map(|t| {
                t.parse().map_err(|_| {
                    let expected = match std::any::type_name::<T>() {
                        "usize" => "a whole number of at least 0",
                        "f64" => "a number",
                        other => other,
                    };
                    format!("'{t}' is not a valid entry of the list '{s}': expected {expected}")
                })
            })
            .collect::<Result<_, _>>()
            .map(List)
    }
}
