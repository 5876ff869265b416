//! Collision detection between bodies (vertex-face candidates and the end-of-step violation
//! pass with edge-edge pairs) at three mesh sizes: a cloth of 32^2, 64^2 and 128^2 cells under
//! a box of (n/4)^2 x n/8 cells resting within the contact margin
//! ([`diffsoft::testing::detection_scene`]). Each size has about four times the surface
//! of the previous one; near-linear cost means about four times the time.
//!
//! Also one step of the paper's ball-on-cloth scene in contact.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion};
use diffsoft::contact::pair::{Detector, Query};
use diffsoft::scene::{self, LoadOptions};
use diffsoft::solver::Simulator;
use diffsoft::testing::detection_scene;

fn detection(c: &mut Criterion) {
    let mut g = c.benchmark_group("collision_detection");
    for n in [32, 64, 128] {
        let model = detection_scene(n).expect("scene");
        let col = model.collision().expect("collisions");
        let q0 = model.rest().to_vec();
        let mut q1 = q0.clone();
        for v in model.bodies()[0].vertices.clone() {
            q1[v].y -= 2e-3;
        }
        let size = col.triangles.len() + col.edges.len() + col.vertices.len();
        let mut det = Detector::default();
        let mut out = Vec::new();
        g.bench_with_input(BenchmarkId::from_parameter(size), &n, |b, _| {
            b.iter(|| {
                out.clear();
                det.detect(col, &q0, &q1, Query::Candidates { margin: 1e-3 }, &mut out);
                det.remember(&out, true);
                det.detect(col, &q0, &q1, Query::Violations { tolerance: 1e-6 }, &mut out);
                out.len()
            })
        });
    }
    g.finish();
}

fn ball_on_cloth_step(c: &mut Criterion) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join("verification/paper/cloth_ball/cloth_ball.json");
    let sc = scene::load(path, LoadOptions::default()).expect("scene");
    let mut sim = Simulator::new(sc.model, sc.settings).expect("simulator");
    for _ in 0..90 {
        sim.step().expect("warm-up");
    }
    let state = sim.state().clone();
    c.bench_function("ball_on_cloth_step_in_contact", |b| {
        b.iter_batched(
            || (state.q.clone(), state.v.clone()),
            |(q, v)| {
                sim.set_state(q, v).expect("state");
                sim.step().expect("step").pair_contacts
            },
            BatchSize::SmallInput,
        )
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = detection, ball_on_cloth_step
}
criterion_main!(benches);
