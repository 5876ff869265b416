//! Cost of the backward pass against the forward pass (issue: backward at most 3x forward),
//! Baymax, 100 steps at dt 1/100, on 1 and 2 threads:
//!
//! * `baymax_free_fall`: the paper mesh falling (no obstacles);
//! * `baymax_on_ground`: dropped onto the ground (frictional contact from the first step).
//!
//! For each: the forward alone (`diff::loss_value`), and the forward plus backward of the
//! unrolled and implicit modes (`diff::gradient`). Backward / forward is the ratio of the
//! medians: (gradient - forward) / forward.
//! For scale, the paper's operator-overloading AD needs 2.2 s per step backward for Baymax with
//! its skeleton and 18 s (11 GB) per step for Baymax in ground contact.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use diffsoft::diff::{self, loss, Controls, Mode, Options};
use diffsoft::scene::{self, LoadOptions};
use diffsoft::solver::{Model, Settings, SolverKind};

fn baymax(ground: bool) -> (Model, Settings) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("verification/scenes/baymax_ground.json");
    let mut sc = scene::load(path, LoadOptions::default()).expect("scene loads");
    if !ground {
        sc.model.obstacles.clear();
    }
    sc.settings.solver = SolverKind::Direct;
    (sc.model, sc.settings)
}

fn bench(c: &mut Criterion) {
    let steps = 100;
    let l = loss::by_name("mean_com.y").expect("loss");
    let mut g = c.benchmark_group("gradient_baymax_100_steps");
    g.sample_size(10);
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        for (name, ground) in [("free_fall", false), ("on_ground", true)] {
            let (model, settings) = baymax(ground);
            g.bench_function(BenchmarkId::new(format!("{name}/forward"), threads), |b| {
                b.iter(|| {
                    pool.install(|| diff::loss_value(&model, &settings, steps, &Controls::default(), l.as_ref()))
                        .expect("forward")
                })
            });
            for mode in [Mode::Unrolled, Mode::Implicit] {
                g.bench_function(
                    BenchmarkId::new(format!("{name}/gradient_{mode:?}").to_lowercase(), threads),
                    |b| {
                        b.iter(|| {
                            pool.install(|| {
                                diff::gradient(
                                    &model,
                                    &settings,
                                    steps,
                                    &Controls::default(),
                                    l.as_ref(),
                                    Options::mode(mode),
                                )
                            })
                            .expect("gradient")
                        })
                    },
                );
            }
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
