//! Time per step of the forward solver on the scenes the paper's C++ implementation was timed on
//! (single-threaded and with 2 threads), plus a ~50k-tet mesh:
//!
//! * bridge (821 v / 2911 t, dt 1/200, Dirichlet pins, no contact): paper 12.5 ms/step;
//! * Baymax falling freely (775 v / 3078 t, dt 1/100, one iteration): paper 7.2 ms/step;
//! * Baymax resting on the ground (contacts): paper 253 ms/step;
//! * a 50k-tet beam with pinned end under gravity;
//! * the trade-off study's 52 728-tet clamped cantilever at exactly 10 iterations per step
//!   (`beam_52k_10_iterations`, the 2-thread scaling target);
//! * Baymax with its skeleton (root + 4 rotational joints, shoulder torques) dropped on the
//!   ground: paper 14.5 ms/step (5 bones, 3-6 local-global iterations per step);
//! * the skeleton's overhead: the same scene with and without bones, both held to exactly 5
//!   local-global iterations per step (so the ratio is the cost per iteration).
//!
//! Two environment variables serve runs on other machines (a many-core one, say):
//! `DIFFSOFT_BENCH_THREADS=1,4,16` replaces the thread counts `1,2`, and
//! `DIFFSOFT_BENCH_ONLY=beam_52k_10_iterations,bridge` builds only the named cases (criterion's
//! own filter only skips the timing, not the building). Scenes are read from the repository's
//! `verification/`, or from `./verification` when the build's checkout is not there.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion};
use diffsoft::mesh::generate::box_with_about;
use diffsoft::scene::{self, LoadOptions};
use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Settings, Simulator};
use nalgebra::Vector3;

fn root() -> PathBuf {
    let built = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join("verification");
    if built.is_dir() {
        built
    } else {
        PathBuf::from("verification")
    }
}

/// The thread counts to time: `DIFFSOFT_BENCH_THREADS` (comma-separated) or 1 and 2.
fn thread_counts() -> Vec<usize> {
    match std::env::var("DIFFSOFT_BENCH_THREADS") {
        Ok(list) => list
            .split(',')
            .map(|t| {
                t.trim()
                    .parse()
                    .expect("DIFFSOFT_BENCH_THREADS: comma-separated thread counts")
            })
            .collect(),
        Err(_) => vec![1, 2],
    }
}

/// Whether the case `name` is built and timed: all, or those `DIFFSOFT_BENCH_ONLY` names.
fn wanted(name: &str) -> bool {
    match std::env::var("DIFFSOFT_BENCH_ONLY") {
        Ok(list) => list.split(',').any(|n| n.trim() == name),
        Err(_) => true,
    }
}

fn scene_sim(path: &str, warmup: usize, strip_obstacles: bool) -> Simulator {
    scene_sim_with(path, warmup, |sc| {
        if strip_obstacles {
            sc.model.remove_obstacles();
        }
    })
}

fn scene_sim_with(path: &str, warmup: usize, edit: impl Fn(&mut scene::Scene)) -> Simulator {
    let mut sc = scene::load(root().join(path), LoadOptions::default()).expect("scene loads");
    edit(&mut sc);
    let mut sim = Simulator::new(sc.model, sc.settings).expect("simulator");
    for _ in 0..warmup {
        sim.step().expect("warm-up step");
    }
    sim
}

/// The clamped cantilever of the trade-off study (52 x 13 x 13 cells, 52 728 tets, its `x = 0`
/// face fixed) at exactly 10 local-global iterations per step: the many-core case.
fn beam_52k_10_iterations() -> Simulator {
    let mut sim = diffsoft::testing::clamped_cantilever_52k_fixed(10).expect("simulator");
    sim.step().expect("warm-up");
    sim
}

fn beam_50k() -> Simulator {
    let mesh = box_with_about(50_000, 4.0).build().expect("box");
    let pinned: Vec<usize> = (0..mesh.num_vertices())
        .filter(|&i| mesh.vertices[i].z < 1e-9)
        .collect();
    let mut body = BodySpec::new(
        "beam",
        mesh,
        Material {
            youngs_modulus: 1e6,
            poisson_ratio: 0.4,
        },
        MassSpec::Density(1000.0),
    );
    body.fixed = pinned;
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .build()
        .expect("model");
    let mut sim = Simulator::new(
        model,
        Settings {
            dt: 0.01,
            ..Settings::default()
        },
    )
    .expect("simulator");
    sim.step().expect("warm-up");
    sim
}

/// Exactly 5 local-global iterations per step, no acceleration.
fn fixed_iterations(sc: &mut scene::Scene) {
    sc.settings.max_iterations = 5;
    sc.settings.tolerance = 0.0;
    sc.settings.anderson = 0;
}

/// A worker pool of `threads` threads.
fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool")
}

/// Builds the simulator of one benchmark case.
type Make = Box<dyn Fn() -> Simulator + Send + Sync>;

fn steps(c: &mut Criterion) {
    let mut g = c.benchmark_group("step");
    g.sample_size(30);
    let cases: Vec<(&str, Make)> = vec![
        ("bridge", Box::new(|| scene_sim("paper/bridge/bridge.json", 5, false))),
        (
            "baymax_free_fall",
            Box::new(|| scene_sim("scenes/baymax_ground.json", 0, true)),
        ),
        (
            "baymax_on_ground",
            Box::new(|| scene_sim("scenes/baymax_ground.json", 150, false)),
        ),
        ("beam_50k", Box::new(beam_50k)),
        ("beam_52k_10_iterations", Box::new(beam_52k_10_iterations)),
        (
            "baymax_skeleton",
            Box::new(|| scene_sim("scenes/baymax_skeleton.json", 30, false)),
        ),
        (
            "baymax_5_iterations_with_bones",
            Box::new(|| scene_sim_with("scenes/baymax_skeleton.json", 30, fixed_iterations)),
        ),
        (
            "baymax_5_iterations_without_bones",
            Box::new(|| {
                scene_sim_with("scenes/baymax_skeleton.json", 30, |sc| {
                    sc.model.remove_skeleton();
                    fixed_iterations(sc);
                })
            }),
        ),
    ];
    for (name, make) in cases.into_iter().filter(|(name, _)| wanted(name)) {
        for threads in thread_counts() {
            let pool = pool(threads);
            let mut sim = pool.install(&make);
            g.bench_function(BenchmarkId::new(name, format!("{threads}_threads")), |b| {
                b.iter(|| pool.install(|| sim.step().expect("step")))
            });
        }
    }
    g.finish();
}

/// Whole episodes from the scene's initial state, timed per step: the skeleton scene's first
/// second (drop, impact, arms lifting), which is what the paper's per-step time averages over.
fn episodes(c: &mut Criterion) {
    let mut g = c.benchmark_group("episode_100_steps");
    g.sample_size(10);
    for threads in thread_counts()
        .into_iter()
        .filter(|_| wanted("episode_baymax_skeleton"))
    {
        let pool = pool(threads);
        g.bench_function(BenchmarkId::new("baymax_skeleton", format!("{threads}_threads")), |b| {
            b.iter_batched(
                || pool.install(|| scene_sim("scenes/baymax_skeleton.json", 0, false)),
                |mut sim| {
                    pool.install(|| {
                        for _ in 0..100 {
                            sim.step().expect("step");
                        }
                    })
                },
                BatchSize::PerIteration,
            )
        });
    }
    g.finish();
}

/// Steps in contact between bodies, each timed from the same saved state (the contact solve's
/// warm starts aside): the paper's cloth_ball with the cloth draped over the ball (after 150
/// steps), and a ball dropped onto a pinned cloth at 1, 100 and 1000 m/s (the first steps of
/// the impact).
fn contacts(c: &mut Criterion) {
    let mut g = c.benchmark_group("contact_steps");
    g.sample_size(10);
    let impact = |speed: f64| {
        move || {
            let mut sim = scene_sim("scenes/ball_on_cloth.json", 0, false);
            let (q, v) = (sim.state().q.clone(), sim.state().v.clone());
            // The scene drops the ball at 1 m/s: scale its velocity.
            let v: Vec<_> = v.iter().map(|x| x * speed).collect();
            sim.set_state(q, v).expect("state");
            sim
        }
    };
    let cases: Vec<(&str, usize, Make)> = vec![
        (
            "cloth_ball_draped",
            5,
            Box::new(|| scene_sim("paper/cloth_ball/cloth_ball.json", 150, false)),
        ),
        ("impact_1_m_s", 5, Box::new(impact(1.0))),
        ("impact_100_m_s", 3, Box::new(impact(100.0))),
        ("impact_1000_m_s", 3, Box::new(impact(1000.0))),
    ];
    for (name, steps, make) in cases.into_iter().filter(|(name, _, _)| wanted(name)) {
        for threads in thread_counts() {
            let pool = pool(threads);
            let mut sim = pool.install(&make);
            let (q, v) = (sim.state().q.clone(), sim.state().v.clone());
            let (t, k) = (sim.state().time, sim.state().step);
            g.bench_function(
                BenchmarkId::new(name, format!("{threads}_threads_{steps}_steps")),
                |b| {
                    b.iter(|| {
                        pool.install(|| {
                            sim.set_state_from(&q, &v).expect("state");
                            sim.set_clock(t, k);
                            for _ in 0..steps {
                                sim.step().expect("step");
                            }
                        })
                    })
                },
            );
        }
    }
    g.finish();
}

criterion_group!(benches, steps, episodes, contacts);
criterion_main!(benches);
