//! Times `diff::rollout` of a scene from Rust: the counterpart of
//! `examples/python/rollout_timing.py`, which times `Scene.simulate` on the same scene, so the
//! cost of the Python layer is the ratio of the two medians (docs/python.md, "Overhead").
//!
//! `cargo run --release -p diffsoft --example rollout_timing -- [SCENE] [STEPS] [REPEATS]`
//! (defaults: verification/scenes/baymax_skeleton.json, 100 steps, 15 repeats).

use std::time::Instant;

use diffsoft::diff::{self, Controls};
use diffsoft::scene::{self, LoadOptions};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().cloned().unwrap_or_else(|| {
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../verification/scenes/baymax_skeleton.json"
        )
        .into()
    });
    let steps: usize = args.get(1).map_or(Ok(100), |s| s.parse())?;
    let repeats: usize = args.get(2).map_or(Ok(15), |s| s.parse())?;
    let scene = scene::load(&path, LoadOptions::default())?;
    let controls = Controls::default();
    // One untimed rollout warms caches and the thread pool, as the Python script does.
    diff::rollout(&scene.model, &scene.settings, steps, &controls)?;
    let mut ms = Vec::with_capacity(repeats);
    for _ in 0..repeats {
        let t = Instant::now();
        let r = diff::rollout(&scene.model, &scene.settings, steps, &controls)?;
        ms.push(t.elapsed().as_secs_f64() * 1e3);
        anyhow::ensure!(r.unconverged_steps() == 0, "{path}: the rollout did not converge");
    }
    ms.sort_by(f64::total_cmp);
    println!(
        "rust   {path}: {steps} steps, median {:.2} ms over {repeats} rollouts (min {:.2}, max {:.2})",
        ms[repeats / 2],
        ms[0],
        ms[repeats - 1]
    );
    Ok(())
}
