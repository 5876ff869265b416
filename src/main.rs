//! `diffsoft` command-line interface: parses arguments, calls the library, prints summaries.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand, ValueEnum};

use diffsoft::analysis::bounds::{self, BoundsParams};
use diffsoft::analysis::spectral::EigenMethod;
use diffsoft::analysis::sweep::{self, log_space};
use diffsoft::analysis::{Attachments, IterationSystem, Spectrum};
use diffsoft::mesh::generate::{BoxSpec, CellSplit};
use diffsoft::mesh::{self, LoadOptions};
use diffsoft::report::write_json;
use diffsoft::verify;

/// Set when a report goes to standard output (`--json -`): the human-readable text then goes
/// to standard error, so the JSON on standard output is parseable as it stands.
static JSON_ON_STDOUT: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// `println!`, or `eprintln!` when a report goes to standard output.
macro_rules! say {
    ($($t:tt)*) => {
        if JSON_ON_STDOUT.load(std::sync::atomic::Ordering::Relaxed) {
            eprintln!($($t)*)
        } else {
            println!($($t)*)
        }
    };
}

/// `print!`, or `eprint!` when a report goes to standard output.
macro_rules! say_raw {
    ($($t:tt)*) => {
        if JSON_ON_STDOUT.load(std::sync::atomic::Ordering::Relaxed) {
            eprint!($($t)*)
        } else {
            print!($($t)*)
        }
    };
}

#[derive(Parser)]
#[command(
    name = "diffsoft",
    version,
    about = "Differentiable soft multi-body simulation and its verification harness"
)]
struct Cli {
    /// Worker threads (default: all cores).
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
        #[arg(long)]
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
        #[arg(long)]
        dt_min: Option<f64>,
        /// Largest time step (default: 100 x the larger critical step).
        #[arg(long)]
        dt_max: Option<f64>,
        /// Number of time steps.
        #[arg(long, default_value_t = 41)]
        points: usize,
        /// Mark this time step on the plot (e.g. the scene's).
        #[arg(long)]
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
        #[arg(long, value_delimiter = ',', default_values_t = [1.0, 1.0, 1.0])]
        size: Vec<f64>,
        /// Cell split.
        #[arg(long, value_enum, default_value_t = Split::Kuhn)]
        split: Split,
        /// Random vertex displacement as a fraction of the cell size.
        #[arg(long, default_value_t = 0.0)]
        jitter: f64,
        /// Seed for the jitter.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Output file: .obj, .node (writes .node + .ele) or .msh.
        #[arg(long)]
        out: PathBuf,
        /// Gmsh version for .msh output.
        #[arg(long, default_value = "4.1")]
        gmsh_version: String,
    },
    /// Simulate a scene (diffsoft or paper format), writing VTK frames and a JSON run log.
    #[command(allow_negative_numbers = true)]
    Simulate {
        /// Scene file (.json, diffsoft.scene/1 or a paper scene).
        scene: PathBuf,
        /// Steps to take.
        #[arg(long, default_value_t = 100)]
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
        /// Override the global solver.
        #[arg(long, value_enum)]
        solver: Option<diffsoft::solver::SolverKind>,
        /// Override the time integrator (bdf2: second order; its first step is implicit Euler).
        #[arg(long, value_enum)]
        integrator: Option<diffsoft::solver::Integrator>,
        /// Override the certification policy.
        #[arg(long, value_enum)]
        certify: Option<diffsoft::solver::CertifyPolicy>,
        /// Override the time step (s).
        #[arg(long)]
        dt: Option<f64>,
        /// Override the local-global iteration cap.
        #[arg(long)]
        max_iterations: Option<usize>,
        /// Override the local-global tolerance (0: always run the cap), as on `grad`.
        #[arg(long)]
        tolerance: Option<f64>,
        /// Override the Anderson memory of the local-global iteration (0: off), as on `grad`.
        #[arg(long)]
        anderson: Option<usize>,
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
        #[arg(long, default_value_t = 20)]
        steps: usize,
        /// Time integrator of every case (default: each case's own, implicit Euler).
        #[arg(long, value_enum)]
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
        #[arg(long, value_enum, default_value = "full")]
        subset: diffsoft::verify::extremes::Subset,
        /// Run only shard K of N (0 <= K < N): writes a partial report for `diffsoft merge`.
        #[arg(long, value_name = "K/N")]
        shard: Option<diffsoft::verify::shard::Shard>,
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
        #[arg(long, default_value_t = 100)]
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
    /// Merge the partial reports of a sharded `tradeoff` or `extremes` run into one report.
    Merge {
        /// Partial reports (every shard 0/N .. N-1/N once).
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Write the merged report here (a file, as `--json` everywhere; `-o`/`--out` are
        /// accepted too).
        #[arg(long = "json", short = 'o', alias = "out")]
        out: PathBuf,
        /// Trade-off plots go into this directory (default: the output's directory).
        #[arg(long)]
        svg_dir: Option<PathBuf>,
    },
    /// Write the JSON Schemas of every report, the run log, the scene format and the suite file.
    Schemas {
        /// Output directory (one `<name>.schema.json` per schema).
        #[arg(long, default_value = "schemas")]
        out: PathBuf,
    },
    /// The main job: run the verification suite and write reports/.
    Verify {
        /// Suite definition.
        #[arg(long, default_value = "verification/suite.json")]
        suite: PathBuf,
        /// Output directory.
        #[arg(long, default_value = "reports")]
        out: PathBuf,
    },
}

/// Options of `diffsoft tradeoff`.
#[derive(clap::Args)]
struct TradeoffArgs {
    /// Scene file (diffsoft or paper format); or --cantilever, or --spec.
    scene: Option<PathBuf>,
    /// Instead of a scene: a generated cantilever with these cells along x,y,z (6 tets per
    /// cell; 1 m x 0.25 m x 0.25 m, E 1e6, nu 0.3, rho 1000, h = 0.01 s), e.g. 52,13,13.
    #[arg(long, value_delimiter = ',')]
    cantilever: Option<Vec<usize>>,
    /// Instead of the options below: a sweep as JSON (a `tradeoff.scenes` entry of the suite;
    /// scene paths relative to that file).
    #[arg(long)]
    spec: Option<PathBuf>,
    /// Name in the report (default: the scene's file stem).
    #[arg(long)]
    name: Option<String>,
    /// Simulated duration, in steps of the scene's time step h.
    #[arg(long, default_value_t = 50)]
    steps: usize,
    /// Grid time steps h/d.
    #[arg(long, value_delimiter = ',', default_values_t = [1, 2, 4, 8])]
    dt_divisors: Vec<usize>,
    /// The reference runs at h/R.
    #[arg(long, default_value_t = 16)]
    reference_divisor: usize,
    /// Tolerance of the reference runs.
    #[arg(long, default_value_t = 1e-12)]
    reference_tolerance: f64,
    /// Anderson memory of the reference trajectories (0: plain iteration).
    #[arg(long, default_value_t = 0)]
    reference_anderson: usize,
    /// Solver families.
    #[arg(long, value_enum, value_delimiter = ',', default_values = ["direct", "split", "chebyshev", "certified"])]
    families: Vec<diffsoft::verify::tradeoff::Family>,
    /// Time integrators of the grid (bdf2 rows are named `bdf2/...`).
    #[arg(long, value_enum, value_delimiter = ',', default_values = ["implicit-euler"])]
    integrators: Vec<diffsoft::solver::Integrator>,
    /// Families run with the integrators after the first (default: every one of --families).
    #[arg(long, value_enum, value_delimiter = ',')]
    integrator_families: Vec<diffsoft::verify::tradeoff::Family>,
    /// Iteration caps of the newton family (default: --caps).
    #[arg(long, value_delimiter = ',')]
    newton_caps: Vec<usize>,
    /// Integrator of the h/R reference run (the total error of every setting).
    #[arg(long, value_enum, default_value = "implicit-euler")]
    reference_integrator: diffsoft::solver::Integrator,
    /// Iteration caps (tolerance 0), comma-separated; `--caps ''` for none.
    #[arg(long, default_value = "1,3,10,30,100")]
    caps: List<usize>,
    /// Tolerances, comma-separated; `--tolerances ''` for none.
    #[arg(long, default_value = "1e-2,1e-4,1e-6,1e-8,1e-10")]
    tolerances: List<f64>,
    /// Time-step divisors whose settings also get a gradient (default: none).
    #[arg(long, value_delimiter = ',')]
    gradient_dt_divisors: Vec<usize>,
    /// Loss of the gradients: final_com.x|y|z or mean_com.x|y|z.
    #[arg(long, default_value = "final_com.y")]
    loss: String,
    /// Target relative errors to recommend a setting for.
    #[arg(long, value_delimiter = ',', default_values_t = [1e-2, 1e-4, 1e-6])]
    targets: Vec<f64>,
    /// Cost axis of the Pareto fronts: cpu (thread CPU time) or iterations (deterministic).
    #[arg(long, value_enum, default_value = "cpu")]
    time_axis: diffsoft::verify::tradeoff::TimeAxis,
    /// Repeat each forward run until this many CPU seconds are measured.
    #[arg(long, default_value_t = 0.2)]
    min_timing_s: f64,
    /// Run only shard K of N (0 <= K < N): writes a partial report for `diffsoft merge`.
    #[arg(long, value_name = "K/N")]
    shard: Option<diffsoft::verify::shard::Shard>,
    /// Write the JSON report (or the shard's partial report) here (`-`: standard output).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write the SVG plots into this directory (default: the JSON's directory).
    #[arg(long)]
    svg_dir: Option<PathBuf>,
}

/// A comma-separated list given as one value, which may be empty (`--caps ''`: none).
#[derive(Clone, Debug)]
struct List<T>(Vec<T>);

impl<T: std::str::FromStr> std::str::FromStr for List<T> {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        s.split(',')
            .map(str::trim)
            .filter(|t| !t.is_empty())
            .map(|t| {
                t.parse()
                    .map_err(|_| format!("'{t}' is not a valid entry of the list '{s}'"))
            })
            .collect::<Result<_, _>>()
            .map(List)
    }
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
    #[arg(long)]
    rho: f64,
    /// Stiffness coefficient mu of L = sum mu V A^T A (Pa).
    #[arg(long)]
    mu: f64,
    /// Multiply vertex positions by this factor first (the paper's "Scale").
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
    /// Eigensolver: dense (exact), krylov (Lanczos), auto (dense up to 1500 vertices).
    #[arg(long, value_enum, default_value_t = EigenMethod::Auto)]
    method: EigenMethod,
    /// Reject tets whose normalised volume 6 sqrt(2) V / l_rms^3 is below this.
    #[arg(long, default_value_t = 1e-9)]
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
        )?;
        let mesh = loaded.mesh.scaled(self.scale);
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
    let cli = Cli::parse();
    let args: Vec<String> = std::env::args().collect();
    let stdout_json = args.windows(2).any(|w| w[0] == "--json" && w[1] == "-") || args.iter().any(|a| a == "--json=-");
    JSON_ON_STDOUT.store(stdout_json, std::sync::atomic::Ordering::Relaxed);
    // The whole command runs on a worker of the pool, so parallel sections fork from a worker
    // (cheap) instead of being injected from an outside thread that then sleeps.
    // A thread count far beyond the machine only costs memory and start-up time.
    const MAX_THREADS: usize = 4096;
    if cli.threads.is_some_and(|t| t > MAX_THREADS) {
        eprintln!(
            "error: --threads {}: at most {MAX_THREADS} (this machine has {})",
            cli.threads.unwrap_or(0),
            std::thread::available_parallelism().map_or(1, |n| n.get())
        );
        std::process::exit(2);
    }
    let pool = match rayon::ThreadPoolBuilder::new()
        .num_threads(cli.threads.unwrap_or(0))
        .build()
    {
        Ok(pool) => pool,
        Err(e) => {
            eprintln!("error: cannot set thread count: {e}");
            std::process::exit(2);
        }
    };
    if let Err(e) = pool.install(|| run(cli.command)) {
        eprintln!("error: {e:#}");
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
            let report = bounds::analyze(&mesh, &info, &params)?;
            emit(
                &verify::bounds_summary(&report),
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
            // Each point holds its spectral radii, critical steps and verdicts.
            diffsoft::base::memory::check(&format!("--points {points}"), points, 1024)?;
            let (mesh, info) = input.load()?;
            let sys = IterationSystem::new(&mesh, input.rho, input.mu, &Attachments::default())?;
            let spectrum = Spectrum::compute(&sys, input.method)?;
            let (lo, hi) = sweep::default_range(&spectrum);
            let (lo, hi) = (dt_min.unwrap_or(lo), dt_max.unwrap_or(hi));
            if !(lo > 0.0 && hi > lo && points >= 2) {
                bail!("need 0 < --dt-min < --dt-max and --points >= 2 (got {lo}, {hi}, {points})");
            }
            let pts = sweep::sweep(&sys, &spectrum, &log_space(lo, hi, points), spectrum.method)?;
            let report = verify::SweepReport::new(&info.path, input.rho, input.mu, mark_dt, &spectrum, pts);
            emit(
                &verify::sweep_summary(&report),
                &report,
                json.as_deref(),
                &[&input.mesh],
            )?;
            if let Some(path) = svg {
                diffsoft::plot::write_svg(
                    &path,
                    &report.chart(&format!("{}: spectral radius vs time step", info.path)),
                )?;
                say!("wrote {}", path.display());
            }
        }
        Command::Quality { mesh: path, json } => {
            preflight(json.as_deref(), &[&path])?;
            let loaded = mesh::load(&path)?;
            let report = verify::QualityReport::new(&loaded)?;
            emit(&verify::quality_summary(&report), &report, json.as_deref(), &[&path])?;
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
                bail!("--jitter must be in [0, 0.5) (fraction of the cell size), got {jitter}");
            }
            let spec = BoxSpec::new([cells[0], cells[1], cells[2]], [size[0], size[1], size[2]])
                .split(match split {
                    Split::Kuhn => CellSplit::Kuhn6,
                    Split::Five => CellSplit::Five,
                })
                .jitter(jitter, seed);
            let m = spec.build()?;
            write_mesh(&m, &out, &gmsh_version)?;
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
            solver,
            integrator,
            certify,
            dt,
            max_iterations,
            tolerance,
            anderson,
            passive,
            activation,
            overwrite,
        } => {
            let mut sc = diffsoft::scene::load(&scene, diffsoft::scene::LoadOptions { passive })?;
            if let Some(s) = solver {
                sc.settings.solver = s;
            }
            if let Some(i) = integrator {
                sc.settings.integrator = i;
            }
            if let Some(c) = certify {
                sc.settings.certify = c;
            }
            if let Some(h) = dt {
                sc.settings.dt = h;
            }
            if let Some(m) = max_iterations {
                sc.settings.max_iterations = m;
            }
            if let Some(t) = tolerance {
                sc.settings.tolerance = t;
            }
            if let Some(m) = anderson {
                sc.settings.anderson = m;
            }
            let mut held = Vec::new();
            for a in &activation {
                let (name, value) = a
                    .split_once('=')
                    .ok_or_else(|| anyhow::anyhow!("--activation {a}: expected NAME=VALUE"))?;
                let value: f64 = value
                    .parse()
                    .map_err(|_| anyhow::anyhow!("--activation {a}: {value} is not a number"))?;
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
            let report = verify::jacobians::run(seed);
            emit(&verify::jacobians_table(&report), &report, json.as_deref(), &[])?;
            if report.verdicts.iter().any(|v| !v.holds) {
                bail!("some Jacobian checks failed");
            }
        }
        Command::Grad(a) => grad(a)?,
        Command::Schemas { out } => {
            let all = verify::schemas();
            for (file, schema) in &all {
                write_json(out.join(file), schema)?;
            }
            say!("wrote {} schemas in {}", all.len(), out.display());
        }
        Command::Gradcheck {
            steps,
            integrator,
            json,
        } => {
            use verify::gradients;
            preflight(Some(&json), &[])?;
            // The largest case keeps about 1000 vertices' positions and velocities per step.
            diffsoft::base::memory::check(&format!("--steps {steps}"), steps, 64 * 1024)?;
            let data = find_data(Path::new("verification"))?;
            let mut cases = gradients::builtin_cases(&gradients::CaseScenes::under(&data), steps)?;
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
            use diffsoft::verify::cloth;
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
            use diffsoft::verify::extremes;
            preflight(json.as_deref(), &[])?;
            match shard {
                Some(k) => {
                    let Some(path) = json else {
                        bail!("--shard needs --json (where the partial report goes)");
                    };
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
        Command::Merge { inputs, out, svg_dir } => {
            use diffsoft::verify::merge::{merge_files, Merged};
            let sources: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
            preflight(Some(&out), &sources)?;
            match merge_files(&inputs)? {
                Merged::Tradeoff(mut r) => {
                    let dir = svg_dir
                        .or_else(|| out.parent().map(Path::to_path_buf))
                        .filter(|d| !d.as_os_str().is_empty())
                        .unwrap_or_else(|| PathBuf::from("."));
                    // Data before plots: a plot that fails (nothing to draw) loses no data.
                    let mut plots = Ok(());
                    for s in r.scenes.iter_mut() {
                        if plots.is_ok() {
                            plots = diffsoft::verify::tradeoff::write_plots(s, &dir);
                        }
                        say_raw!("{}", diffsoft::verify::tradeoff::summary(s));
                    }
                    save(&out, &r, &sources)?;
                    plots.context("the merged report is written, a plot is not")?;
                }
                Merged::Extremes(r) => {
                    say_raw!("{}", diffsoft::verify::extremes::table(&r));
                    save(&out, &r, &sources)?;
                }
            }
            say!("merged {} partial reports", inputs.len());
        }
        Command::Verify { suite, out } => {
            verify::run_suite(&find_data(&suite)?, &out)?;
        }
    }
    Ok(())
}

/// `diffsoft tradeoff`: the sweep from a scene, a cantilever or a spec file; a shard's partial
/// report, or the whole study with its plots.
fn tradeoff(args: TradeoffArgs) -> Result<()> {
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
    use diffsoft::verify::tradeoff::{self, Cantilever, SceneSource, TradeoffSpec};
    let input_paths: Vec<PathBuf> = spec.iter().chain(scene.iter()).cloned().collect();
    let inputs: Vec<&Path> = input_paths.iter().map(PathBuf::as_path).collect();
    preflight(json.as_deref(), &inputs)?;
    // The reference runs take `steps x reference_divisor` steps and keep their states.
    let reference_steps = steps
        .checked_mul(reference_divisor)
        .with_context(|| format!("--steps {steps} x --reference-divisor {reference_divisor} overflows"))?;
    diffsoft::base::memory::check(
        &format!("--steps {steps} at h/{reference_divisor}"),
        reference_steps,
        1024,
    )?;
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
            s.newton_caps = newton_caps;
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
    let workers = rayon::current_num_threads();
    match shard {
        Some(k) => {
            let Some(path) = json else {
                bail!("--shard needs --json (where the partial report goes)");
            };
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
            let dir = svg_dir
                .or_else(|| json.as_ref().and_then(|j| j.parent().map(Path::to_path_buf)))
                .filter(|d| !d.as_os_str().is_empty())
                .unwrap_or_else(|| PathBuf::from("."));
            // Data before plots: a plot that fails (nothing to draw) loses no data.
            let plots = tradeoff::write_plots(&mut s, &dir);
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

#[derive(clap::Args)]
struct GradArgs {
    /// Scene file (.json, diffsoft.scene/1 or a paper scene), positional as in `simulate`.
    #[arg(required_unless_present = "scene_flag", conflicts_with = "scene_flag")]
    scene: Option<PathBuf>,
    /// The scene as a flag (the older spelling; same as the positional SCENE).
    #[arg(long = "scene", value_name = "SCENE", hide = true)]
    scene_flag: Option<PathBuf>,
    /// Steps to simulate.
    #[arg(long, default_value_t = 100)]
    steps: usize,
    /// Loss: final_com.x|y|z, mean_com.x|y|z, joint_angle.BONE or mean_joint_angle.BONE.
    #[arg(long, default_value = "final_com.y")]
    loss: String,
    /// Parameters to differentiate (repeatable): youngs_modulus, poisson_ratio, density,
    /// initial_velocity.x|y|z, gravity.x|y|z.
    #[arg(long, required = true)]
    param: Vec<String>,
    /// Override a parameter first, `NAME=VALUE` (repeatable; same names as --param).
    #[arg(long, value_name = "NAME=VALUE")]
    set: Vec<String>,
    /// Differentiation mode.
    #[arg(long, value_enum, default_value = "unrolled")]
    mode: diffsoft::diff::Mode,
    /// Override the global solver.
    #[arg(long, value_enum)]
    solver: Option<diffsoft::solver::SolverKind>,
    /// Override the time integrator (bdf2: second order; its first step is implicit Euler).
    #[arg(long, value_enum)]
    integrator: Option<diffsoft::solver::Integrator>,
    /// Override the local-global iteration cap.
    #[arg(long)]
    max_iterations: Option<usize>,
    /// Override the local-global tolerance (0: always run the cap, a smooth forward).
    #[arg(long)]
    tolerance: Option<f64>,
    /// Override the Anderson memory (unrolled mode differentiates plain iterations: 0).
    #[arg(long)]
    anderson: Option<usize>,
    /// Write `{loss, gradient}` as JSON here (`-`: standard output).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Unrolled mode: keep whole steps' recordings from the forward pass up to this many MB
    /// instead of replaying them from checkpoints (0: pure checkpointing).
    #[arg(long, default_value_t = 0.0)]
    store_mb: f64,
    /// Return the loss and gradient even if forward steps miss the tolerance or a replay
    /// deviates from the forward pass (otherwise an error; the counts are printed).
    #[arg(long)]
    allow_unconverged: bool,
    /// Implicit mode: relative residual at which the adjoint solve of each step stops
    #[arg(long, default_value_t = diffsoft::diff::Options::default().implicit_tolerance)]
    implicit_tolerance: f64,
}

/// A memory budget in MB as bytes.
fn store_bytes(mb: f64) -> Result<usize> {
    if !(mb.is_finite() && mb >= 0.0) {
        anyhow::bail!("--store-mb must be finite and >= 0, got {mb}");
    }
    Ok((mb * 1e6) as usize)
}

/// `diffsoft grad`: overrides, one forward and one backward pass, the loss and the derivatives.
fn grad(a: GradArgs) -> Result<()> {
    use diffsoft::diff::{self, Controls, Options, Param};
    let Some(scene) = a.scene.clone().or_else(|| a.scene_flag.clone()) else {
        bail!("give the scene file: diffsoft grad SCENE --param P");
    };
    preflight(a.json.as_deref(), &[&scene])?;
    if !(a.implicit_tolerance.is_finite() && a.implicit_tolerance >= 0.0) {
        bail!(
            "--implicit-tolerance must be finite and >= 0, got {}",
            a.implicit_tolerance
        );
    }
    let mut sc = diffsoft::scene::load(&scene, diffsoft::scene::LoadOptions::default())?;
    if let Some(s) = a.solver {
        sc.settings.solver = s;
    }
    if let Some(i) = a.integrator {
        sc.settings.integrator = i;
    }
    if let Some(m) = a.max_iterations {
        sc.settings.max_iterations = m;
    }
    if let Some(t) = a.tolerance {
        sc.settings.tolerance = t;
    }
    if let Some(m) = a.anderson {
        sc.settings.anderson = m;
    }
    for s in &a.set {
        let (name, value) = s
            .split_once('=')
            .ok_or_else(|| anyhow::anyhow!("--set {s}: expected NAME=VALUE"))?;
        let p: Param = name.parse()?;
        let v: f64 = value
            .trim()
            .parse()
            .map_err(|_| anyhow::anyhow!("--set {s}: '{value}' is not a number"))?;
        p.set(&mut sc.model, v)?;
    }
    let params: Vec<Param> = a.param.iter().map(|p| p.parse()).collect::<Result<_, _>>()?;
    let loss = diff::loss::by_name(&a.loss)?;
    let g = diff::gradient(
        &sc.model,
        &sc.settings,
        a.steps,
        &Controls::default(),
        loss.as_ref(),
        Options {
            store_bytes: store_bytes(a.store_mb)?,
            allow_unconverged: a.allow_unconverged,
            implicit_tolerance: a.implicit_tolerance,
            ..Options::mode(a.mode)
        },
    )
    .map_err(|e| match e {
        diff::DiffError::Unconverged { .. } | diff::DiffError::NotReplayable { .. } => {
            anyhow::anyhow!("{e} (--allow-unconverged)")
        }
        e => e.into(),
    })?;
    let mut gradient = std::collections::BTreeMap::new();
    let mut values = std::collections::BTreeMap::new();
    say!("loss {} = {:.17e}", a.loss, g.loss);
    for p in &params {
        let d = p.derivative(&sc.model, &g);
        say!(
            "d loss / d {p} = {d:.17e}   (at {p} = {})",
            p.get(&sc.model).map_or("-".into(), |v| v.to_string())
        );
        gradient.insert(p.to_string(), d);
        if let Ok(v) = p.get(&sc.model) {
            values.insert(p.to_string(), v);
        }
    }
    say!(
        "forward {:.1} ms, backward {:.1} ms ({:?} mode), {} forward iterations, {} backward iterations",
        g.stats.forward_ms,
        g.stats.backward_ms,
        a.mode,
        g.stats.forward_iterations,
        g.stats.backward_iterations
    );
    let missed = sc.settings.tolerance > 0.0 && g.stats.unconverged_steps > 0;
    if missed || g.stats.replay_deviation > 1e-6 * sc.model.length_scale() {
        say!(
            "warning: {} of {} forward steps did not converge, replay deviation {:.3e} m (allowed by --allow-unconverged)",
            g.stats.unconverged_steps, a.steps, g.stats.replay_deviation
        );
    }
    if a.mode == diff::Mode::Unrolled && g.stats.one_iteration_steps > 0 {
        say!(
            "warning: {} of {} forward steps met the tolerance in their first iteration; unrolled mode differentiates that one iteration, not the converged step (use --mode implicit, or --tolerance 0 with a fixed --max-iterations)",
            g.stats.one_iteration_steps, a.steps
        );
    }
    if let Some(path) = &a.json {
        let out = diffsoft::output::GradReport {
            header: diffsoft::report::Header::new(diffsoft::output::GRAD_SCHEMA),
            scene: scene.display().to_string(),
            steps: a.steps,
            mode: a.mode,
            loss_name: a.loss.clone(),
            loss: g.loss,
            parameters: values,
            gradient,
            stats: g.stats,
        };
        save(path, &out, &[&scene])?;
    }
    Ok(())
}

/// Set by SIGINT/SIGTERM: the run stops after its current step and finalises its log.
static INTERRUPTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Where `simulate` writes, and whether it may replace an earlier run's files.
struct RunOutput<'a> {
    dir: Option<&'a Path>,
    every: usize,
    overwrite: bool,
}

/// Run a scene, printing a summary and writing frames and the run log. The output directory is
/// checked before the first step; the log is kept current during the run and finalised however
/// it ends (completed, failed, or interrupted by SIGINT/SIGTERM, exit status 130).
fn simulate(sc: diffsoft::scene::Scene, steps: usize, out: RunOutput<'_>, activations: &[(String, f64)]) -> Result<()> {
    use diffsoft::output::{FrameWriter, RunDir, RunLog, RunStatus, RunSummary, RUN_SCHEMA};
    use diffsoft::report::Header;
    use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
    use std::sync::atomic::Ordering;
    // The run log holds every step's figures: a step count it cannot hold is refused up front.
    diffsoft::base::memory::check(
        &format!("--steps {steps}"),
        steps,
        std::mem::size_of::<diffsoft::StepStats>(),
    )?;
    let mut run_dir = match out.dir {
        Some(dir) => Some(RunDir::prepare(dir, &[sc.path.as_path()], out.overwrite)?),
        None => None,
    };
    let model_size = diffsoft::report::ModelSize::of(&sc.model);
    let bodies = sc.model.bodies().to_vec();
    let cloth = sc.model.cloth().map_or(Vec::new(), |c| c.bodies.clone());
    say!(
        "scene       {} ({:?}): {} vertices, {} tets, {} bodies{}",
        sc.path.display(),
        sc.format,
        model_size.vertices,
        model_size.tets,
        bodies.len(),
        if cloth.is_empty() {
            String::new()
        } else {
            format!(", {} cloth ({} triangles)", cloth.len(), sc.model.num_cloth_triangles())
        }
    );
    for n in &sc.notes {
        say!("note        {n}");
    }
    let mut sim = diffsoft::solver::Simulator::new(sc.model, sc.settings.clone())?;
    say!("solver      {}", sim.certificate().message);
    if sc.settings.integrator == diffsoft::solver::Integrator::Bdf2 {
        say!(
            "integrator  bdf2 (docs/method.md Eq. T1): the matrix above is M/h_e^2 + L with h_e = 2h/3; the first step is implicit Euler on M/h^2 + L, factored when it is taken"
        );
    }
    for (name, a) in activations {
        sim.set_activation(name, *a)?;
        say!("activation  {name} held at {a}");
    }
    let mut frames = match (&run_dir, out.every) {
        (Some(d), every) if every > 0 => Some(FrameWriter::new(d.path(), sim.model())?),
        _ => None,
    };
    let mut log = RunLog {
        header: Header::new(RUN_SCHEMA),
        scene: sc.path.display().to_string(),
        notes: sc.notes.clone(),
        bodies,
        cloth,
        size: model_size,
        settings: sim.settings().clone(),
        certificate: sim.certificate().clone(),
        summary: RunSummary::of(&[]),
        steps: Vec::new(),
        frames: Vec::new(),
        status: RunStatus::Running,
        error: None,
    };
    let frame_name = |p: PathBuf| p.file_name().unwrap_or_default().to_string_lossy().into_owned();
    if let Some(f) = frames.as_mut() {
        log.frames.push(frame_name(f.write_state(&sim)?));
    }
    if let Some(d) = run_dir.as_mut() {
        d.write_log(&log)?;
    }
    if let Err(e) = ctrlc::set_handler(|| {
        // A second signal ends the process at once; the log of the last refresh stays.
        if INTERRUPTED.swap(true, Ordering::SeqCst) {
            std::process::exit(130);
        }
    }) {
        eprintln!("warning: cannot catch SIGINT/SIGTERM ({e}); an interrupted run keeps its last log refresh");
    }
    let bar = ProgressBar::new(steps as u64);
    if steps < 50 || !std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} steps {elapsed_precise} eta {eta} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    for k in 0..steps {
        if INTERRUPTED.load(Ordering::SeqCst) {
            log.status = RunStatus::Interrupted;
            break;
        }
        match sim.step() {
            Ok(s) => {
                bar.set_message(format!("{} it", s.iterations));
                log.steps.push(s);
            }
            Err(e) => {
                log.status = RunStatus::Failed;
                log.error = Some(format!("step {}: {e}", k + 1));
                break;
            }
        }
        bar.inc(1);
        if let Some(f) = frames.as_mut() {
            if (k + 1) % out.every == 0 {
                log.frames.push(frame_name(f.write_state(&sim)?));
            }
        }
        if let Some(d) = run_dir.as_mut().filter(|d| d.log_due()) {
            log.summary = RunSummary::of(&log.steps);
            d.write_log(&log)?;
        }
    }
    if log.status == RunStatus::Running {
        log.status = if INTERRUPTED.load(Ordering::SeqCst) && log.steps.len() < steps {
            RunStatus::Interrupted
        } else {
            RunStatus::Completed
        };
    }
    bar.finish_and_clear();
    log.summary = RunSummary::of(&log.steps);
    let summary = &log.summary;
    say!(
        "ran         {} steps ({:.4} s simulated) in {:.3} s: median {:.3} ms/step, {:.2} iterations/step, {} of {} converged, max penetration {:.3e} m, max contacts {} (between bodies {})",
        summary.steps,
        summary.simulated_time,
        summary.wall_time_s,
        summary.median_ms_per_step,
        summary.mean_iterations,
        summary.converged_steps,
        summary.steps,
        summary.max_penetration,
        summary.max_contacts,
        summary.max_pair_contacts
    );
    if summary.steps_with_capped_solves > 0 {
        say!(
            "warning     {} of {} steps had a global or contact solve stop unconverged, at its iteration cap (the scene's solver.inner_max_iterations) or stalled (an infeasible contact set); capped_solves in the step log",
            summary.steps_with_capped_solves,
            summary.steps
        );
    }
    if let Some(d) = run_dir.as_mut() {
        d.write_log(&log)?;
        say!(
            "wrote       {} ({:?}) and {} frames{}",
            d.log_path().display(),
            log.status,
            log.frames.len(),
            if log.frames.is_empty() { "" } else { " (frames.pvd)" }
        );
    }
    match (log.status, log.error) {
        (RunStatus::Interrupted, _) => {
            eprintln!("interrupted after {} of {steps} steps", log.steps.len());
            std::process::exit(130);
        }
        (_, Some(e)) => bail!(e),
        _ => Ok(()),
    }
}

/// Print a report's summary and write its JSON if asked (never over one of `inputs`).
fn emit<T: serde::Serialize>(summary: &str, report: &T, json: Option<&Path>, inputs: &[&Path]) -> Result<()> {
    say_raw!("{summary}");
    if let Some(path) = json {
        save(path, report, inputs)?;
    }
    Ok(())
}

/// The project's data (`verification/...`) from any working directory: `path` as given if it
/// exists, else under the working directory's ancestors, else under the source tree this binary
/// was built from. The error lists every place looked in.
fn find_data(path: &Path) -> Result<PathBuf> {
    if path.exists() || path.is_absolute() {
        return Ok(path.to_path_buf());
    }
    let mut looked = vec![path.to_path_buf()];
    if let Ok(cwd) = std::env::current_dir() {
        looked.extend(cwd.ancestors().skip(1).map(|a| a.join(path)));
    }
    looked.push(Path::new(env!("CARGO_MANIFEST_DIR")).join(path));
    if let Some(found) = looked.iter().find(|p| p.exists()) {
        return Ok(found.clone());
    }
    let shown: Vec<String> = looked.iter().map(|p| p.display().to_string()).collect();
    bail!("cannot find {} (looked in {})", path.display(), shown.join(", "))
}

/// Before the work: an output file (not `-`) must be writable and not one of `inputs`.
fn preflight(path: Option<&Path>, inputs: &[&Path]) -> Result<()> {
    if let Some(p) = path.filter(|p| *p != Path::new("-")) {
        diffsoft::output::refuse_input(p, inputs)?;
        diffsoft::output::check_writable(p)?;
    }
    Ok(())
}

/// Write a report as JSON to `path` (atomically, never over one of `inputs`, then say so), or
/// to standard output for `-`.
fn save<T: serde::Serialize>(path: &Path, report: &T, inputs: &[&Path]) -> Result<()> {
    if path == Path::new("-") {
        let mut text = serde_json::to_string_pretty(report)?;
        text.push('\n');
        std::io::Write::write_all(&mut std::io::stdout().lock(), text.as_bytes()).context("standard output")?;
        return Ok(());
    }
    diffsoft::output::refuse_input(path, inputs)?;
    write_json(path, report)?;
    say!("wrote {}", path.display());
    Ok(())
}

fn write_mesh(m: &mesh::TetMesh, out: &Path, gmsh_version: &str) -> Result<()> {
    let ext = out.extension().and_then(|e| e.to_str()).unwrap_or("");
    let write = |p: &Path, s: String| std::fs::write(p, s).with_context(|| format!("cannot write {}", p.display()));
    match ext {
        "obj" => write(out, mesh::write::obj(m)),
        "node" | "ele" => {
            let (node, ele) = mesh::write::tetgen(m, 0);
            write(&out.with_extension("node"), node)?;
            write(&out.with_extension("ele"), ele)
        }
        "msh" => match gmsh_version {
            "2.2" => write(out, mesh::write::gmsh22(m)),
            "4.1" => write(out, mesh::write::gmsh41(m)),
            v => bail!("--gmsh-version must be 2.2 or 4.1, got {v}"),
        },
        _ => bail!("output must end in .obj, .node or .msh: {}", out.display()),
    }
}
