//! `diffsoft` command-line interface: parses arguments, calls the library, prints summaries.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand, ValueEnum};
use diffsoft::base::number;

use diffsoft::analysis::bounds::{self, BoundsParams};
use diffsoft::analysis::spectral::EigenMethod;
use diffsoft::analysis::sweep::{self, log_space};
use diffsoft::analysis::{Attachments, IterationSystem, Spectrum};
use diffsoft::mesh::generate::{BoxSpec, CellSplit};
use diffsoft::mesh::{self, LoadOptions};
use diffsoft::output::write_json;

/// Set when a report goes to standard output (`--json -`): the human-readable text then goes
/// to standard error, so the JSON on standard output is parseable as it stands.
static JSON_ON_STDOUT: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// `println!`, or `eprintln!` when a report goes to standard output. Never panics: a closed
/// pipe or a full disk loses the text, not the run (its files are written and checked on
/// their own).
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = if crate::JSON_ON_STDOUT.load(std::sync::atomic::Ordering::Relaxed) {
            writeln!(std::io::stderr(), $($t)*)
        } else {
            writeln!(std::io::stdout(), $($t)*)
        };
    }};
}

/// `print!`, or `eprint!` when a report goes to standard output; never panics (see `say!`).
macro_rules! say_raw {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = if crate::JSON_ON_STDOUT.load(std::sync::atomic::Ordering::Relaxed) {
            write!(std::io::stderr(), $($t)*)
        } else {
            write!(std::io::stdout(), $($t)*)
        };
    }};
}

/// `eprintln!` that never panics (a closed or full standard error loses the text only).
macro_rules! warn {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($t)*);
    }};
}

mod cli;

use cli::choice::choice;
use cli::files::{check_plot_paths, emit, find_data, preflight, save, write_mesh};
use cli::grad::{grad, GradArgs};
use cli::numbers::{at_least_one, non_negative, positive};
use cli::overrides::SolverOverrides;
use cli::simulate::{simulate, RunOutput};
use cli::tradeoff::{tradeoff, TradeoffArgs};

#[derive(Parser)]
#[command(
    name = "diffsoft",
    version,
    about = "Differentiable soft multi-body simulation and its verification harness"
)]
struct Cli {
    /// Worker threads (default, or 0: all cores).
    #[arg(long, global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Spectral radii and critical time steps of iterations (19) and (21), Appendix A/B verdicts.
    #[command(allow_negative_numbers = true)]
    Bounds {
        #[command(flatten)]
        input: MeshArgs,
        /// Time step (s).
        #[arg(long, value_parser = positive)]
        dt: f64,
        /// Also run both iterations and compare observed and predicted contraction.
        #[arg(long)]
        empirical: bool,
        /// Write the JSON report here (`-`: standard output).
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// rho(G19) and rho(G21) over a log range of time steps, as JSON and an SVG plot.
    #[command(allow_negative_numbers = true)]
    Sweep {
        #[command(flatten)]
        input: MeshArgs,
        /// Smallest time step (default: h*_19 / 100).
        #[arg(long, value_parser = positive)]
        dt_min: Option<f64>,
        /// Largest time step (default: 100 x the larger critical step).
        #[arg(long, value_parser = positive)]
        dt_max: Option<f64>,
        /// Number of time steps.
        #[arg(long, default_value_t = 41)]
        points: usize,
        /// Mark this time step on the plot (e.g. the scene's).
        #[arg(long, value_parser = positive)]
        mark_dt: Option<f64>,
        /// Write the JSON here (`-`: standard output).
        #[arg(long)]
        json: Option<PathBuf>,
        /// Write the SVG plot here.
        #[arg(long)]
        svg: Option<PathBuf>,
    },
    /// Mesh quality: counts, volumes, dihedral angles, sign pattern of L.
    Quality {
        /// Mesh file (.obj with t lines, .node/.ele, .msh).
        #[arg(long)]
        mesh: PathBuf,
        /// Write the JSON report here (`-`: standard output).
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Write a structured box mesh (for tests and studies).
    #[command(allow_negative_numbers = true)]
    Generate {
        /// Cells per axis, e.g. 4,4,8.
        #[arg(long, value_delimiter = ',', required = true)]
        cells: Vec<usize>,
        /// Box size per axis, e.g. 1,1,2.
        #[arg(long, value_delimiter = ',', default_values_t = [1.0, 1.0, 1.0], value_parser = positive)]
        size: Vec<f64>,
        /// Cell split.
        #[arg(long, value_enum, default_value_t = Split::Kuhn)]
        split: Split,
        /// Random vertex displacement as a fraction of the cell size.
        #[arg(long, default_value_t = 0.0, value_parser = non_negative)]
        jitter: f64,
        /// Seed for the jitter.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Output file: .obj, .node (writes .node + .ele) or .msh.
        #[arg(long)]
        out: PathBuf,
        /// Gmsh version for .msh output: 2.2 or 4.1 (the default).
        #[arg(long)]
        gmsh_version: Option<String>,
    },
    /// Simulate a scene (diffsoft or paper format), writing VTK frames and a JSON run log.
    #[command(allow_negative_numbers = true)]
    Simulate {
        /// Scene file (.json, diffsoft.scene/1 or a paper scene).
        scene: PathBuf,
        /// Steps to take.
        #[arg(long, default_value_t = 100, value_parser = at_least_one)]
        steps: usize,
        /// Output directory for frames and the run log.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Write a frame every this many steps (0: no frames; the run log is still written).
        #[arg(long, default_value_t = 1)]
        every: usize,
        /// Replace the files of an earlier run in --out (run.json, frames) instead of refusing.
        #[arg(long)]
        overwrite: bool,
        #[command(flatten)]
        overrides: SolverOverrides,
        /// Paper scenes: drop features this version cannot simulate, with a note, instead of
        /// failing (every feature of the paper's own files is simulated now).
        #[arg(long)]
        passive: bool,
        /// Hold an actuator group at an activation for the whole run, `NAME=VALUE` (repeatable;
        /// e.g. `pneumatic0=1.5`, `muscle3=0.4`).
        #[arg(long, value_name = "NAME=VALUE")]
        activation: Vec<String>,
    },
    /// Loss and gradient of a simulation with respect to a scalar parameter (reverse mode).
    #[command(allow_negative_numbers = true)]
    Grad(GradArgs),
    /// Gradient checks (reverse mode vs finite differences and dual numbers) on the built-in
    /// cases, writing gradients.json.
    Gradcheck {
        /// Steps per case.
        #[arg(long, default_value_t = 20, value_parser = at_least_one)]
        steps: usize,
        /// Time integrator of every case (default: each case's own, implicit Euler).
        #[arg(long, value_parser = choice::<diffsoft::solver::Integrator>())]
        integrator: Option<diffsoft::solver::Integrator>,
        /// Write the JSON report here (`-`: standard output).
        #[arg(long, default_value = "reports/gradcheck.json")]
        json: PathBuf,
    },
    /// Jacobian checks of the joints and of B = dq/dz against dual numbers and finite differences.
    Jacobians {
        /// Seed of the random configurations.
        #[arg(long, default_value_t = 2021)]
        seed: u64,
        /// Write the JSON report here (`-`: standard output).
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Accuracy against cost of solver settings on one scene: errors against tight references,
    /// Pareto front, recommended setting per target error (reports/tradeoff.json format).
    #[command(allow_negative_numbers = true)]
    Tradeoff(Box<TradeoffArgs>),
    /// The extremes suite: the simulator and its gradients at the edges of their input ranges
    /// (reports/extremes.json format); exits 1 if a case fails.
    Extremes {
        /// Which cases: fast (the test suite's subset) or full.
        #[arg(long, value_parser = choice::<diffsoft_harness::extremes::Subset>(), default_value = "full")]
        subset: diffsoft_harness::extremes::Subset,
        /// Run only shard K of N (0 <= K < N): writes a partial report for `diffsoft merge`.
        #[arg(long, value_name = "K/N")]
        shard: Option<diffsoft_harness::shard::Shard>,
        /// Write the JSON report (or the shard's partial report) here (`-`: standard output).
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// The cloth study: a scene with cloth and collisions between bodies (default: the paper's
    /// ball on cloth), probed every step, and the cost of collision detection against mesh size
    /// (reports/cloth.json format); exits 1 if a claim fails.
    Cloth {
        /// Scenes with cloth and collisions between bodies.
        #[arg(long, default_value = "verification/paper/cloth_ball/cloth_ball.json")]
        scene: Vec<PathBuf>,
        /// Steps to run.
        #[arg(long, default_value_t = 100, value_parser = at_least_one)]
        steps: usize,
        /// Cloth cells per side of the detection-cost meshes.
        #[arg(long, value_delimiter = ',', default_value = "16,32,64,128")]
        sizes: Vec<usize>,
        /// Directory for the plots and VTK frames.
        #[arg(long, default_value = "out/cloth")]
        out: PathBuf,
        /// Write the JSON report here (`-`: standard output).
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// The validation suite: the engine against closed forms of continuum mechanics (patch
    /// test, hanging bar, cantilever, elastica, vibrating bar, Hertz, capstan), per material
    /// model (reports/validation.json format); exits 1 if a case is not as expected.
    Validate {
        /// Which cases: full (the main job's) or fast (the test suite's subset).
        #[arg(long, value_parser = choice::<diffsoft_harness::validation::Subset>(), default_value = "full")]
        subset: diffsoft_harness::validation::Subset,
        /// Run only these studies (repeatable; default: all).
        #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(diffsoft_harness::validation::STUDIES))]
        study: Vec<String>,
        /// Write the JSON report here (`-`: standard output).
        #[arg(long, default_value = "reports/validation.json")]
        json: PathBuf,
    },
    /// Merge the partial reports of a sharded `tradeoff` or `extremes` run into one report.
    Merge {
        /// Partial reports (every shard 0/N .. N-1/N once).
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Write the merged report here (a file, as `--json` everywhere; `-o`/`--out` are
        /// accepted too).
        #[arg(long = "json", short = 'o', alias = "out")]
        out: PathBuf,
        /// Trade-off plots go into this directory (default: the output's directory; the working
        /// directory with `--json -`).
        #[arg(long)]
        svg_dir: Option<PathBuf>,
    },
    /// Write the JSON Schemas of every report, the run log, the scene format and the suite file.
    Schemas {
        /// Output directory (one `<name>.schema.json` per schema).
        #[arg(long, default_value = "schemas")]
        out: PathBuf,
    },
    /// Rewrite the report page (DIR/index.html) from the JSON reports and SVG plots in DIR:
    /// every verdict, failing first, with provenance, links and the plots.
    ReportPage {
        /// Reports directory.
        #[arg(long, default_value = "reports")]
        reports: PathBuf,
    },
    /// The main job: run the verification suite and write reports/ (and reports/index.html).
    Verify {
        /// Suite definition.
        #[arg(long, default_value = "verification/suite.json")]
        suite: PathBuf,
        /// Output directory.
        #[arg(long, default_value = "reports")]
        out: PathBuf,
    },
}

#[derive(Clone, Copy, ValueEnum)]
enum Split {
    Kuhn,
    Five,
}

#[derive(clap::Args)]
struct MeshArgs {
    /// Mesh file (.obj with t lines, TetGen .node/.ele, Gmsh .msh).
    #[arg(long)]
    mesh: PathBuf,
    /// Density rho (kg/m^3).
    #[arg(long, value_parser = positive)]
    rho: f64,
    /// Stiffness coefficient mu of L = sum mu V A^T A (Pa).
    #[arg(long, value_parser = positive)]
    mu: f64,
    /// Multiply vertex positions by this factor first (the paper's "Scale").
    #[arg(long, default_value_t = 1.0, value_parser = positive)]
    scale: f64,
    /// Eigensolver: dense (exact), krylov (Lanczos), auto (dense up to 1500 vertices).
    #[arg(long, value_parser = choice::<EigenMethod>(), default_value = "auto")]
    method: EigenMethod,
    /// Reject tets whose normalised volume 6 sqrt(2) V / l_rms^3 is below this.
    #[arg(long, default_value_t = 1e-9, value_parser = non_negative)]
    min_tet_quality: f64,
}

impl MeshArgs {
    fn load(&self) -> Result<(mesh::TetMesh, mesh::MeshInfo)> {
        if !(self.scale.is_finite() && self.scale > 0.0) {
            bail!("--scale must be finite and positive, got {}", self.scale);
        }
        let loaded = mesh::load_with(
            &self.mesh,
            LoadOptions {
                min_quality: self.min_tet_quality,
            },
        )?
        .scaled(self.scale);
        let mesh = loaded.mesh;
        // Volumes go like the cube of the coordinates: they must neither overflow nor vanish.
        let reach = mesh.vertices.iter().map(|v| v.amax()).fold(0.0, f64::max);
        let cube = reach.powi(3);
        if !(cube.is_finite() && cube > f64::MIN_POSITIVE) {
            bail!(
                "--scale {:e}: coordinates up to {reach:e} make tet volumes {} f64's range",
                self.scale,
                if cube.is_finite() { "fall below" } else { "overflow" }
            );
        }
        Ok((mesh, loaded.info))
    }
}

#[global_allocator]
static ALLOC: diffsoft::alloc::Counting = diffsoft::alloc::Counting;

fn main() {
    // A value a flag cannot take (checked by its parser, `cli::numbers`) is bad input like any
    // other: exit status 1. A malformed command line (unknown flag, missing value) stays 2.
    let cli = Cli::try_parse().unwrap_or_else(|e| {
        if e.kind() == clap::error::ErrorKind::ValueValidation {
            let _ = e.print();
            std::process::exit(1);
        }
        e.exit()
    });
    let args: Vec<String> = std::env::args().collect();
    let stdout_json = args.windows(2).any(|w| w[0] == "--json" && w[1] == "-") || args.iter().any(|a| a == "--json=-");
    JSON_ON_STDOUT.store(stdout_json, std::sync::atomic::Ordering::Relaxed);
    // The whole command runs on a worker of the pool, so parallel sections fork from a worker
    // (cheap) instead of being injected from an outside thread that then sleeps.
    // A thread count far beyond the machine only costs memory and start-up time.
    const MAX_THREADS: usize = 4096;
    if cli.threads.is_some_and(|t| t > MAX_THREADS) {
        warn!(
            "error: --threads {}: at most {MAX_THREADS} (this machine has {})",
            cli.threads.unwrap_or(0),
            std::thread::available_parallelism().map_or(1, |n| n.get())
        );
        std::process::exit(2);
    }
    // Without --threads, rayon reads RAYON_NUM_THREADS: the same bound, naming the variable
    // (50 000 threads took minutes to start; a value rayon cannot read it ignores).
    if cli.threads.is_none() {
        if let Some(t) = std::env::var("RAYON_NUM_THREADS")
            .ok()
            .and_then(|v| v.trim().parse::<usize>().ok())
            .filter(|&t| t > MAX_THREADS)
        {
            warn!(
                "error: RAYON_NUM_THREADS={t}: at most {MAX_THREADS} (this machine has {}); --threads N overrides it",
                std::thread::available_parallelism().map_or(1, |n| n.get())
            );
            std::process::exit(2);
        }
    }
    let pool = match rayon::ThreadPoolBuilder::new()
        .num_threads(cli.threads.unwrap_or(0))
        .build()
    {
        Ok(pool) => pool,
        Err(e) => {
            warn!("error: cannot set thread count: {e}");
            std::process::exit(2);
        }
    };
    if let Err(e) = pool.install(|| run(cli.command)) {
        warn!("error: {}", cli::message(&e));
        std::process::exit(1);
    }
}

fn run(command: Command) -> Result<()> {
    match command {
        Command::Bounds {
            input,
            dt,
            empirical,
            json,
        } => {
            preflight(json.as_deref(), &[&input.mesh])?;
            let (mesh, info) = input.load()?;
            let params = BoundsParams {
                rho: input.rho,
                mu: input.mu,
                dt,
                attachments: Attachments::default(),
                method: input.method,
                empirical,
            };
            let report = bounds::analyze(&mesh, &info, &params).with_context(|| {
                format!(
                    "{} with --rho {}, --mu {}, --dt {}",
                    input.mesh.display(),
                    number(input.rho),
                    number(input.mu),
                    number(dt)
                )
            })?;
            emit(
                &diffsoft_harness::bounds_summary(&report),
                &report,
                json.as_deref(),
                &[&input.mesh],
            )?;
        }
        Command::Sweep {
            input,
            dt_min,
            dt_max,
            points,
            mark_dt,
            json,
            svg,
        } => {
            preflight(json.as_deref(), &[&input.mesh])?;
            preflight(svg.as_deref(), &[&input.mesh])?;
            if let (Some(j), Some(s)) = (json.as_deref(), svg.as_deref()) {
                diffsoft::output::distinct_outputs(&[("--json", j), ("--svg", s)])?;
            }
            // Each point holds its spectral radii, critical steps and verdicts.
            diffsoft::base::memory::check(&format!("--points {points}"), points, 1024)?;
            let (mesh, info) = input.load()?;
            let inputs = || {
                format!(
                    "{} with --rho {}, --mu {}",
                    input.mesh.display(),
                    number(input.rho),
                    number(input.mu)
                )
            };
            let sys = IterationSystem::new(&mesh, input.rho, input.mu, &Attachments::default()).with_context(inputs)?;
            let spectrum = Spectrum::compute(&sys, input.method).with_context(inputs)?;
            let (lo, hi) = sweep::default_range(&spectrum);
            let (lo, hi) = (dt_min.unwrap_or(lo), dt_max.unwrap_or(hi));
            if !(lo > 0.0 && hi > lo && points >= 2) {
                bail!("need 0 < --dt-min < --dt-max and --points >= 2 (got {lo}, {hi}, {points})");
            }
            let pts = sweep::sweep(&sys, &spectrum, &log_space(lo, hi, points), spectrum.method)
                .with_context(|| format!("{}, time steps {} to {}", inputs(), number(lo), number(hi)))?;
            let report = diffsoft_harness::SweepReport::new(&info, input.rho, input.mu, mark_dt, &spectrum, pts);
            emit(
                &diffsoft_harness::sweep_summary(&report),
                &report,
                json.as_deref(),
                &[&input.mesh],
            )?;
            if let Some(path) = svg {
                diffsoft_harness::plot::write_svg(
                    &path,
                    &report.chart(&format!("{}: spectral radius vs time step", info.path)),
                )?;
                say!("wrote {}", path.display());
            }
        }
        Command::Quality { mesh: path, json } => {
            preflight(json.as_deref(), &[&path])?;
            let loaded = mesh::load(&path)?;
            let report = diffsoft_harness::QualityReport::new(&loaded)?;
            emit(
                &diffsoft_harness::quality_summary(&report),
                &report,
                json.as_deref(),
                &[&path],
            )?;
        }
        Command::Generate {
            cells,
            size,
            split,
            jitter,
            seed,
            out,
            gmsh_version,
        } => {
            if cells.len() != 3 || size.len() != 3 {
                bail!("--cells and --size take three comma-separated values, e.g. --cells 4,4,8 --size 1,1,2");
            }
            if cells.contains(&0) || !size.iter().all(|s| s.is_finite() && *s > 0.0) {
                bail!("--cells must be positive and --size finite and positive (got {cells:?}, {size:?})");
            }
            if !(0.0..0.5).contains(&jitter) {
                bail!(
                    "--jitter must be in [0, 0.5) (fraction of the cell size), got {}",
                    diffsoft::base::number(jitter)
                );
            }
            let spec = BoxSpec::new([cells[0], cells[1], cells[2]], [size[0], size[1], size[2]])
                .split(match split {
                    Split::Kuhn => CellSplit::Kuhn6,
                    Split::Five => CellSplit::Five,
                })
                .jitter(jitter, seed);
            let m = spec.build().map_err(|e| {
                anyhow::anyhow!(
                    "--cells {} --size {}: {e}",
                    cells.iter().map(|c| c.to_string()).collect::<Vec<_>>().join(","),
                    size.iter()
                        .map(|&s| diffsoft::base::number(s))
                        .collect::<Vec<_>>()
                        .join(",")
                )
            })?;
            write_mesh(&m, &out, gmsh_version.as_deref())?;
            say!(
                "wrote {} ({} vertices, {} tets)",
                out.display(),
                m.num_vertices(),
                m.num_tets()
            );
        }
        Command::Simulate {
            scene,
            steps,
            out,
            every,
            overrides,
            passive,
            activation,
            overwrite,
        } => {
            cli::simulate::catch_signals();
            let mut sc = diffsoft::scene::load(&scene, diffsoft::scene::LoadOptions { passive })?;
            if passive && sc.format != diffsoft::scene::SceneFormat::Paper {
                bail!(
                    "--passive applies to the paper's scene files only; {} is a diffsoft scene",
                    scene.display()
                );
            }
            overrides.apply(&mut sc.settings)?;
            let mut held = Vec::new();
            for a in &activation {
                // The value is a number, so the last '=' ends the name (a group's name may hold one).
                let (name, value) = a
                    .rsplit_once('=')
                    .ok_or_else(|| anyhow::anyhow!("--activation {a}: expected NAME=VALUE"))?;
                let value: f64 = value
                    .parse()
                    .map_err(|_| anyhow::anyhow!("--activation {a}: '{value}' is not a number"))?;
                if held.iter().any(|(n, _)| n == name) {
                    bail!("--activation {name}: given twice; give each group once");
                }
                held.push((name.to_string(), value));
            }
            let output = RunOutput {
                dir: out.as_deref(),
                every,
                overwrite,
            };
            simulate(sc, steps, output, &held)?;
        }
        Command::Jacobians { seed, json } => {
            preflight(json.as_deref(), &[])?;
            let report = diffsoft_harness::jacobians::run(seed);
            emit(
                &diffsoft_harness::jacobians_table(&report),
                &report,
                json.as_deref(),
                &[],
            )?;
            if report.verdicts.iter().any(|v| !v.holds) {
                bail!("some Jacobian checks failed");
            }
        }
        Command::Grad(a) => grad(a)?,
        Command::Schemas { out } => {
            let all = diffsoft_harness::schemas();
            diffsoft::output::output_dir(&out, "--out")?;
            // Every name checked before the first is written: a link or FIFO among them
            // leaves the directory as it was.
            let paths = all
                .iter()
                .map(|(file, _)| diffsoft::output::own_file(&out, file))
                .collect::<std::io::Result<Vec<_>>>()?;
            for (path, (_, schema)) in paths.iter().zip(&all) {
                write_json(path, schema)?;
            }
            say!("wrote {} schemas in {}", all.len(), out.display());
        }
        Command::Gradcheck {
            steps,
            integrator,
            json,
        } => {
            use diffsoft_harness::gradients;
            preflight(Some(&json), &[])?;
            // The largest case keeps about 1000 vertices' positions and velocities per step.
            diffsoft::base::memory::check(&format!("--steps {steps}"), steps, 64 * 1024)?;
            let data = find_data(Path::new("verification"))?;
            let mut cases = diffsoft::testing::builtin_cases(&diffsoft::testing::CaseScenes::under(&data), steps)?;
            if let Some(i) = integrator {
                for c in &mut cases {
                    c.settings.integrator = i;
                }
            }
            let checks = gradients::check_all(&cases, 2021);
            say_raw!("{}", gradients::checks_table(&checks));
            let (failed, total) = (checks.iter().filter(|c| !c.passes).count(), checks.len());
            save(&json, &gradients::GradcheckReport::new(checks), &[])?;
            say!(
                "{} of {total} cases pass (unrolled mode; implicit mode for Newton's method)",
                total - failed
            );
            if failed > 0 {
                bail!("{failed} gradient check case(s) failed");
            }
        }
        Command::Tradeoff(args) => tradeoff(*args)?,
        Command::Cloth {
            scene,
            steps,
            sizes,
            out,
            json,
        } => {
            use diffsoft_harness::cloth;
            let scenes: Vec<(PathBuf, usize)> = scene
                .iter()
                .map(|p| Ok((find_data(p)?, steps)))
                .collect::<Result<_>>()?;
            let inputs: Vec<&Path> = scenes.iter().map(|(p, _)| p.as_path()).collect();
            preflight(json.as_deref(), &inputs)?;
            // The study keeps a probe of every step (penetration, distances, stretch).
            diffsoft::base::memory::check(&format!("--steps {steps}"), steps, 4096)?;
            let r = cloth::study(&scenes, &sizes, &out)?;
            say_raw!("{}", cloth::table(&r));
            if let Some(path) = json {
                save(&path, &r, &inputs)?;
            }
            if !r.plot_errors.is_empty() {
                bail!(
                    "the report is complete, but plots were not drawn: {}",
                    r.plot_errors.join("; ")
                );
            }
            if r.verdicts.iter().any(|v| !v.holds) {
                bail!("some cloth claims failed");
            }
        }
        Command::Extremes { subset, shard, json } => {
            use diffsoft_harness::extremes;
            preflight(json.as_deref(), &[])?;
            match shard {
                Some(k) => {
                    let Some(path) = json else {
                        bail!("--shard needs --json (where the partial report goes)");
                    };
                    diffsoft_harness::shard::check_items(k, extremes::select(subset).len(), "cases")?;
                    let part = extremes::run_shard(subset, k, true);
                    save(&path, &part, &[])?;
                    say!(
                        "shard {k}: {} of {} cases; merge all shards with `diffsoft merge`",
                        part.cases.len(),
                        part.total_cases
                    );
                }
                None => {
                    let r = extremes::run(subset, true);
                    say_raw!("{}", extremes::table(&r));
                    if let Some(path) = json {
                        save(&path, &r, &[])?;
                    }
                    let failing = r.cases.iter().filter(|c| !c.passes).count();
                    if failing > 0 {
                        bail!("{failing} extreme case(s) fail");
                    }
                }
            }
        }
        Command::Validate { subset, study, json } => {
            use diffsoft_harness::validation;
            let empty = validation::empty_studies(subset, &study);
            if !empty.is_empty() {
                bail!(
                    "--study {}: no case in --subset {} (these studies run only in the full subset); pass --subset full",
                    empty.join(","),
                    diffsoft::base::Choice::name(subset)
                );
            }
            preflight(Some(&json), &[])?;
            let r = validation::run(subset, &study);
            say_raw!("{}", validation::table(&r));
            save(&json, &r, &[])?;
            let off = r.cases.iter().filter(|c| !c.as_expected()).count();
            if off > 0 {
                bail!("{off} validation case(s) not as expected (see the reasons above)");
            }
        }
        Command::Merge { inputs, out, svg_dir } => {
            use diffsoft_harness::merge::{merge_files, Merged};
            let sources: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
            preflight(Some(&out), &sources)?;
            match merge_files(&inputs)? {
                Merged::Tradeoff(mut r) => {
                    let dir = svg_dir
                        .or_else(|| out.parent().map(Path::to_path_buf))
                        .filter(|d| !d.as_os_str().is_empty())
                        .unwrap_or_else(|| PathBuf::from("."));
                    for s in &r.scenes {
                        let names = diffsoft_harness::tradeoff::plot_names(&s.name);
                        check_plot_paths(Some(&out), &dir, &names, &sources)?;
                    }
                    // Data before plots: a plot that fails (nothing to draw) loses no data.
                    let mut plots = Ok(());
                    for s in r.scenes.iter_mut() {
                        if plots.is_ok() {
                            plots = diffsoft_harness::tradeoff::write_plots(s, &dir);
                        }
                        say_raw!("{}", diffsoft_harness::tradeoff::summary(s));
                    }
                    save(&out, &r, &sources)?;
                    plots.context("the merged report is written, a plot is not")?;
                }
                Merged::Extremes(r) => {
                    say_raw!("{}", diffsoft_harness::extremes::table(&r));
                    save(&out, &r, &sources)?;
                }
            }
            say!("merged {} partial reports", inputs.len());
        }
        Command::ReportPage { reports } => {
            let (page, path) = diffsoft_harness::page::write(&reports)?;
            say!(
                "wrote {} ({} verdicts in {} reports, {} fail, {} plots)",
                path.display(),
                page.verdicts,
                page.reports,
                page.failing,
                page.plots
            );
        }
        Command::Verify { suite, out } => {
            diffsoft_harness::run_suite(&find_data(&suite)?, &out)?;
        }
    }
    Ok(())
}
