//! Cost of the backward pass against the forward pass, 100 steps on 1 and 2 threads:
//!
//! * `free_fall`: the paper's Baymax mesh falling (no obstacles; dt 1/100);
//! * `on_ground`: the same dropped onto the ground (frictional contact from the first step);
//! * `skeleton`: the paper's skeleton scene (free torso, 4 rotational joints, shoulder
//!   torques; no ground), through the reduced step;
//! * `bridge`: the paper's bridge (pinned ends, dt 1/200), the other scene of the implicit
//!   backward's target;
//! * `beam_5k`: a clamped beam of about 5 000 tets under gravity (E = 1 MPa, nu = 0.4,
//!   dt 1/100, tolerance 1e-6), the third.
//!
//! For each: the forward alone (`diff::loss_value`), and the forward plus backward of the
//! unrolled mode with pure checkpointing (`unrolled`), with the forward's recordings kept within
//! 64 MB (`unrolled_store`), and the implicit mode (not with a skeleton). Backward / forward is
//! the ratio of the medians: (gradient - forward) / forward.
//! For scale, the paper's operator-overloading AD needs 2.2 s per step backward for Baymax with
//! its skeleton and 18 s (11 GB) per step for Baymax in ground contact.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use diffsoft::diff::{self, loss, Controls, Mode, Options};
use diffsoft::mesh::generate::box_with_about;
use diffsoft::scene::{self, LoadOptions};
use diffsoft::{BodySpec, MassSpec, Material, Model, ModelBuilder, Settings, SolverKind};
use nalgebra::Vector3;

fn load(file: &str, ground: bool) -> (Model, Settings) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join("verification")
        .join(file);
    let mut sc = scene::load(path, LoadOptions::default()).expect("scene loads");
    if !ground {
        sc.model.remove_obstacles();
    }
    sc.settings.solver = SolverKind::Direct;
    sc.settings.anderson = 0;
    (sc.model, sc.settings)
}

/// The clamped beam: about 5 000 tets, its `z = 0` face fixed.
fn beam_5k() -> (Model, Settings) {
    let mesh = box_with_about(5_000, 4.0).build().expect("box");
    let fixed: Vec<usize> = (0..mesh.num_vertices())
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
    body.fixed = fixed;
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .build()
        .expect("model");
    let settings = Settings {
        dt: 0.01,
        solver: SolverKind::Direct,
        anderson: 0,
        ..Settings::default()
    };
    (model, settings)
}

fn bench(c: &mut Criterion) {
    let steps = 100;
    let l = loss::by_name("mean_com.y").expect("loss");
    let mut g = c.benchmark_group("gradient_100_steps");
    g.sample_size(10);
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        for (name, file, ground) in [
            ("free_fall", "scenes/baymax_ground.json", false),
            ("on_ground", "scenes/baymax_ground.json", true),
            ("skeleton", "scenes/baymax_skeleton.json", false),
            ("bridge", "paper/bridge/bridge.json", true),
            ("beam_5k", "", false),
        ] {
            let (model, settings) = if file.is_empty() { beam_5k() } else { load(file, ground) };
            g.bench_function(BenchmarkId::new(format!("{name}/forward"), threads), |b| {
                b.iter(|| {
                    pool.install(|| diff::loss_value(&model, &settings, steps, &Controls::default(), l.as_ref()))
                        .expect("forward")
                })
            });
            let skeleton = model.skeleton().is_some();
            for (label, mode, store_bytes) in [
                ("unrolled", Mode::Unrolled, 0),
                ("unrolled_store", Mode::Unrolled, 64_000_000),
                ("implicit", Mode::Implicit, 0),
            ] {
                if skeleton && mode == Mode::Implicit {
                    continue;
                }
                g.bench_function(BenchmarkId::new(format!("{name}/gradient_{label}"), threads), |b| {
                    b.iter(|| {
                        pool.install(|| {
                            diff::gradient(
                                &model,
                                &settings,
                                steps,
                                &Controls::default(),
                                l.as_ref(),
                                Options {
                                    store_bytes,
                                    ..Options::mode(mode)
                                },
                            )
                        })
                        .expect("gradient")
                    })
                });
            }
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
