//! Time per step of the forward solver on the scenes the paper's C++ implementation was timed on
//! (single-threaded and with 2 threads), plus a ~50k-tet mesh:
//!
//! * bridge (821 v / 2911 t, dt 1/200, Dirichlet pins, no contact): paper 12.5 ms/step;
//! * Baymax falling freely (775 v / 3078 t, dt 1/100, one iteration): paper 7.2 ms/step;
//! * Baymax resting on the ground (contacts): paper 253 ms/step;
//! * a 50k-tet beam with pinned end under gravity.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use diffsoft::mesh::generate::box_with_about;
use diffsoft::scene::{self, LoadOptions};
use diffsoft::solver::{BodySpec, MassSpec, Material, ModelBuilder, Settings, Simulator};
use nalgebra::Vector3;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("verification")
}

fn scene_sim(path: &str, warmup: usize, strip_obstacles: bool) -> Simulator {
    let mut sc = scene::load(root().join(path), LoadOptions::default()).expect("scene loads");
    if strip_obstacles {
        sc.model.obstacles.clear();
    }
    let mut sim = Simulator::new(sc.model, sc.settings).expect("simulator");
    for _ in 0..warmup {
        sim.step().expect("warm-up step");
    }
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
    ];
    for (name, make) in cases {
        for threads in [1usize, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            let mut sim = pool.install(&make);
            g.bench_function(BenchmarkId::new(name, format!("{threads}_threads")), |b| {
                b.iter(|| pool.install(|| sim.step().expect("step")))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, steps);
criterion_main!(benches);
