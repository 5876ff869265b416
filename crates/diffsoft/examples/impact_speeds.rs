//! Where contacts between bodies hold: the ball on the pinned cloth
//! (`verification/scenes/ball_on_cloth.json`) thrown at the cloth at each given speed, with the
//! scene's step divided by a factor, for a number of steps (docs/cloth.md, docs/performance.md).
//! Prints, per speed, the steps with contacts between the bodies, those that ended crossed
//! (`pair_crossings`), those that needed swept pairs (`swept_pairs`, docs/method.md Eq. C6), the
//! most inverted tets and the median wall time of a contact step.
//!
//! ```text
//! cargo run --release -p diffsoft --example impact_speeds -- 1,20,40,45 [divide] [steps]
//! ```

use diffsoft::scene::{load, LoadOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: impact_speeds SPEEDS(m/s, comma-separated) [DIVIDE (1)] [STEPS (60)]";
    let speeds: Vec<f64> = args
        .get(1)
        .ok_or(usage)?
        .split(',')
        .map(|s| s.trim().parse::<f64>().map_err(|e| format!("speed '{s}': {e}")))
        .collect::<Result<_, _>>()?;
    let divide: u32 = args
        .get(2)
        .map_or(Ok(1), |s| s.parse())
        .map_err(|e| format!("divide: {e}"))?;
    let steps: usize = args
        .get(3)
        .map_or(Ok(60), |s| s.parse())
        .map_err(|e| format!("steps: {e}"))?;
    if divide == 0 || steps == 0 {
        return Err(usage.into());
    }
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../verification/scenes/ball_on_cloth.json");
    let sc = load(&path, LoadOptions::default())?;
    let settings = sc.settings.with_dt(sc.settings.dt / divide as f64);
    for speed in speeds {
        let mut sim = diffsoft::Simulator::new(sc.model.clone(), settings.clone())?;
        // The scene's velocity (1 m/s down) scaled.
        let q = sim.state().q.clone();
        let v = sim.state().v.iter().map(|x| x * speed).collect();
        sim.set_state(q, v)?;
        let (mut contact, mut crossed, mut swept, mut inverted) = (0, 0, 0, 0);
        let mut ms = Vec::new();
        for _ in 0..steps {
            let t = std::time::Instant::now();
            let st = sim.step()?;
            if st.pair_contacts > 0 {
                contact += 1;
                ms.push(t.elapsed().as_secs_f64() * 1e3);
            }
            crossed += usize::from(st.pair_crossings > 0);
            swept += usize::from(st.swept_pairs > 0);
            inverted = inverted.max(st.inverted_tets);
        }
        ms.sort_by(f64::total_cmp);
        let median = ms.get(ms.len() / 2).copied().unwrap_or(0.0);
        println!(
            "{speed} m/s, dt/{divide}, {steps} steps: {contact} with contacts between the bodies, {crossed} crossed, {swept} with swept pairs, at most {inverted} inverted tets, median contact step {median:.2} ms"
        );
    }
    Ok(())
}
