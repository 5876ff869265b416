//! Where a step's time goes as threads are added: the 52 728-tet clamped cantilever of the
//! trade-off study at exactly 10 local-global iterations per step (`benches/step.rs`'s
//! `beam_52k_10_iterations`), timed per step with the step's own clocks (wall, local steps,
//! global solves; the rest is assembly of right-hand sides, convergence tests and the update).
//!
//! `cargo run --release --example thread_scaling -- [THREADS,...] [STEPS]`
//! (defaults: 1,2 and 20 steps). Medians over the steps after one untimed warm-up step.

use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let threads: Vec<usize> = args
        .first()
        .map_or("1,2", String::as_str)
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    let steps: usize = args.get(1).map_or(Ok(20), |s| s.parse())?;
    println!("threads   wall ms   local ms   global ms   rest ms   (medians of {steps} steps)");
    let mut first = None;
    for t in threads {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build()?;
        let rows = pool.install(|| -> anyhow::Result<_> {
            let mut sim = diffsoft::testing::clamped_cantilever_52k_fixed(10)?;
            sim.step()?;
            let mut rows = Vec::with_capacity(steps);
            for _ in 0..steps {
                let t0 = Instant::now();
                let s = sim.step()?;
                rows.push((t0.elapsed().as_secs_f64() * 1e3, s.local_ms, s.global_ms));
            }
            Ok(rows)
        })?;
        let wall = median(rows.iter().map(|r| r.0).collect());
        let local = median(rows.iter().map(|r| r.1).collect());
        let global = median(rows.iter().map(|r| r.2).collect());
        let base = *first.get_or_insert(wall);
        println!(
            "{t:>7} {wall:>9.1} {local:>10.1} {global:>11.1} {:>9.1}   speed-up {:.2}x",
            wall - local - global,
            base / wall
        );
    }
    Ok(())
}
