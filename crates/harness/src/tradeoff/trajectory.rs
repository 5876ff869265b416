//! Sampled simulation runs and their errors against a reference: the stepping loop with its
//! work counters and timers, the centre of mass, the energy bookkeeping, and the error
//! accumulator (max and RMS vertex error, centre-of-mass error).

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use diffsoft::model::Model;
use diffsoft::solver::{Simulator, SolverError};

/// CPU time of the calling thread in seconds (`CLOCK_THREAD_CPUTIME_ID`, read to the
/// nanosecond: the kernel adds the running slice when it is read, unlike
/// `/proc/thread-self/schedstat`, which advances only at scheduler ticks of a few ms). `None`
/// where it is unavailable.
pub fn thread_cpu_s() -> Option<f64> {
    #[cfg(unix)]
    {
        use nix::time::{clock_gettime, ClockId};
        let t = clock_gettime(ClockId::CLOCK_THREAD_CPUTIME_ID).ok()?;
        Some(t.tv_sec() as f64 + t.tv_nsec() as f64 * 1e-9)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// Work done by a run (deterministic).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Work {
    /// Steps taken.
    pub steps: usize,
    /// Local-global iterations, summed over the steps.
    pub iterations: usize,
    /// Inner iterations of iterative global solvers, summed.
    pub global_iterations: usize,
    /// Steps that stopped at the iteration cap before meeting a positive tolerance.
    pub unconverged_steps: usize,
}

/// A completed run.
#[derive(Debug, Clone, Copy)]
pub struct RunOutcome {
    /// Work.
    pub work: Work,
    /// Kinetic + elastic + potential energy after the last step (J).
    pub final_energy: f64,
    /// Wall time of the stepping (s).
    pub wall_s: f64,
    /// Thread CPU time of the stepping (s).
    pub cpu_s: Option<f64>,
}

/// A run that stopped with an error.
#[derive(Debug, Clone)]
pub struct RunFailure {
    /// The 1-based step that failed.
    pub step: usize,
    /// The error.
    pub error: SolverError,
}

impl std::fmt::Display for RunFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "step {}: {}", self.step, self.error)
    }
}

/// Take `steps` steps, calling `sample(k, q)` after every `every`-th step (`k` counts samples
/// from 0).
pub fn advance(
    sim: &mut Simulator,
    steps: usize,
    every: usize,
    mut sample: impl FnMut(usize, &[Vector3<f64>]),
) -> Result<RunOutcome, RunFailure> {
    let tolerance = sim.settings().tolerance;
    let cpu0 = thread_cpu_s();
    let t0 = std::time::Instant::now();
    let mut work = Work::default();
    let mut energy = 0.0;
    for s in 1..=steps {
        let st = sim.step().map_err(|error| RunFailure { step: s, error })?;
        work.steps += 1;
        work.iterations += st.iterations;
        work.global_iterations += st.global_iterations;
        if tolerance > 0.0 && !st.converged {
            work.unconverged_steps += 1;
        }
        energy = st.total_energy();
        if s % every == 0 {
            sample(s / every - 1, &sim.state().q);
        }
    }
    let wall_s = t0.elapsed().as_secs_f64();
    let cpu_s = match (cpu0, thread_cpu_s()) {
        (Some(a), Some(b)) => Some(b - a),
        _ => None,
    };
    Ok(RunOutcome {
        work,
        final_energy: energy,
        wall_s,
        cpu_s,
    })
}

/// Mass-weighted centre of `q`.
pub fn com(model: &Model, q: &[Vector3<f64>]) -> Vector3<f64> {
    let total: f64 = model.mass().iter().sum();
    q.iter().zip(model.mass()).map(|(x, m)| x * *m).sum::<Vector3<f64>>() / total
}

/// Energy of the initial state (rest positions, so no elastic energy; initial velocities):
/// kinetic plus the potential `-sum m a . q` of the external accelerations.
pub fn initial_energy(model: &Model) -> f64 {
    model
        .rest()
        .iter()
        .zip(model.initial_velocity())
        .zip(model.mass().iter().zip(model.accel()))
        .map(|((q, v), (m, a))| 0.5 * m * v.norm_squared() - m * a.dot(q))
        .sum()
}

/// The energy scale that drifts are divided by: `M (|a|_max L + |v0|_max^2)` (the scale the
/// solver's divergence check uses), or 1 J for a scene at rest without loads.
pub fn energy_scale(model: &Model) -> f64 {
    let total: f64 = model.mass().iter().sum();
    let g = model.accel().iter().map(|a| a.norm()).fold(0.0, f64::max);
    let v0 = model.initial_velocity().iter().map(|v| v.norm()).fold(0.0, f64::max);
    let e = total * (g * model.length_scale() + v0 * v0);
    if e > 0.0 {
        e
    } else {
        1.0
    }
}

/// The largest displacement of any vertex from the rest positions over the samples (m).
pub fn displacement_scale(model: &Model, samples: &[Vec<Vector3<f64>>]) -> f64 {
    samples
        .iter()
        .flat_map(|q| q.iter().zip(model.rest()).map(|(a, b)| (a - b).norm()))
        .fold(0.0, f64::max)
}

/// A 64-bit FNV-1a hash of the bits of sampled states, to check that shards used the same
/// reference.
pub fn fingerprint(samples: &[Vec<Vector3<f64>>]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for x in samples.iter().flatten().flat_map(|v| v.iter()) {
        for b in x.to_bits().to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    format!("{h:016x}")
}

/// Running errors of sampled states against reference states.
#[derive(Debug, Clone, Copy, Default)]
pub struct ErrorAcc {
    max: f64,
    sum_sq: f64,
    count: usize,
    com_max: f64,
}

impl ErrorAcc {
    /// Add one sample.
    pub fn add(&mut self, model: &Model, q: &[Vector3<f64>], q_ref: &[Vector3<f64>]) {
        for (a, b) in q.iter().zip(q_ref) {
            let d2 = (a - b).norm_squared();
            self.max = self.max.max(d2.sqrt());
            self.sum_sq += d2;
        }
        self.count += q.len();
        self.com_max = self.com_max.max((com(model, q) - com(model, q_ref)).norm());
    }

    /// Largest vertex distance (m).
    pub fn max(&self) -> f64 {
        self.max
    }

    /// Root mean square vertex distance over vertices and samples (m).
    pub fn rms(&self) -> f64 {
        (self.sum_sq / self.count.max(1) as f64).sqrt()
    }

    /// Largest centre-of-mass distance (m).
    pub fn com_max(&self) -> f64 {
        self.com_max
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thread_cpu_time_grows_with_work() {
        let Some(a) = thread_cpu_s() else {
            return;
        };
        let mut x = 0.0f64;
        let t = std::time::Instant::now();
        while t.elapsed().as_secs_f64() < 0.05 {
            x += x.sin() + 1.0;
        }
        let b = thread_cpu_s().unwrap();
        assert!(x > 0.0 && b > a, "cpu {a} -> {b}");
    }

    /// The clock resolves a fraction of a millisecond of work: a tick-granular clock (a few ms)
    /// would read the same value before and after most such pieces.
    #[test]
    fn thread_cpu_time_resolves_a_fraction_of_a_millisecond() {
        if thread_cpu_s().is_none() {
            return;
        }
        let mut x = 0.0f64;
        let advanced = (0..20)
            .filter(|_| {
                let a = thread_cpu_s().unwrap();
                let t = std::time::Instant::now();
                while t.elapsed().as_secs_f64() < 2e-4 {
                    x += x.sin() + 1.0;
                }
                thread_cpu_s().unwrap() > a
            })
            .count();
        assert!(
            x > 0.0 && advanced >= 18,
            "the clock advanced over {advanced} of 20 pieces of 0.2 ms"
        );
    }

    #[test]
    fn fingerprint_sees_one_bit() {
        let s = vec![vec![Vector3::new(1.0, 2.0, 3.0)]];
        let mut t = s.clone();
        t[0][0].y = f64::from_bits(2.0f64.to_bits() + 1);
        assert_ne!(fingerprint(&s), fingerprint(&t));
        assert_eq!(fingerprint(&s), fingerprint(&s.clone()));
    }
}
