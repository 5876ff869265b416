//! A plain forward run with controls that keeps the whole trajectory (positions and velocities
//! before the first step and after each) and every step's figures: what a caller that writes
//! its own loss (the Python package) needs to evaluate it.

use nalgebra::Vector3;

use super::forward::set_controls;
use super::{Controls, DiffError};
use crate::base::InputError;
use crate::model::Model;
use crate::solver::{Certificate, Settings, Simulator, StepStats};

/// A trajectory of `steps` steps: states `0..=steps` of `n` vertices each, stored step-major
/// (`positions[k * n + i]` is vertex `i` after step `k`; step 0 is the initial state).
#[derive(Debug, Clone)]
pub struct Rollout {
    /// Vertices per state.
    pub n: usize,
    /// Positions, `(steps + 1) * n`, step-major.
    pub positions: Vec<Vector3<f64>>,
    /// Velocities, `(steps + 1) * n`, step-major.
    pub velocities: Vec<Vector3<f64>>,
    /// Time of each state.
    pub times: Vec<f64>,
    /// What each step did.
    pub stats: Vec<StepStats>,
    /// The solver certification of the run.
    pub certificate: Certificate,
}

impl Rollout {
    /// Steps taken.
    pub fn steps(&self) -> usize {
        self.stats.len()
    }

    /// Steps that stopped at the iteration cap.
    pub fn unconverged_steps(&self) -> usize {
        self.stats.iter().filter(|s| !s.converged).count()
    }

    /// Steps that ended with the surfaces of two bodies crossing (contacts the run missed; see
    /// [`StepStats::pair_crossings`]).
    pub fn interpenetrating_steps(&self) -> usize {
        self.stats.iter().filter(|s| s.pair_crossings > 0).count()
    }

    /// Most tets a step ended with inverted ([`StepStats::inverted_tets`]; 0: none).
    pub fn max_inverted_tets(&self) -> usize {
        self.stats.iter().map(|s| s.inverted_tets).max().unwrap_or(0)
    }
}

/// Run `steps` steps of `model` with `controls` (initial state, activations and torques per
/// step, as for [`gradient`](super::gradient)), keeping every state.
///
/// ```
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
/// use diffsoft::{rollout, Controls, Settings};
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let model = ModelBuilder::new()
///     .gravity(nalgebra::Vector3::new(0.0, -9.81, 0.0))
///     .body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0)))
///     .build()?;
/// let run = rollout(&model, &Settings::default(), 3, &Controls::default())?;
/// assert_eq!((run.steps(), run.n), (3, 8));
/// assert_eq!(run.positions.len(), 4 * 8);
/// assert_eq!(run.unconverged_steps(), 0);
/// assert!((run.times[3] - 0.03).abs() < 1e-12);
/// // State 0 is the rest state; the box falls from there.
/// assert_eq!(&run.positions[..8], model.rest());
/// assert!(run.positions[3 * 8].y < model.rest()[0].y);
/// assert!(rollout(&model, &Settings::default(), 0, &Controls::default()).is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn rollout(model: &Model, settings: &Settings, steps: usize, controls: &Controls) -> Result<Rollout, DiffError> {
    if steps == 0 {
        return Err(DiffError::Input("steps must be at least 1".into()));
    }
    let n = model.n();
    let states = steps
        .checked_add(1)
        .and_then(|s| s.checked_mul(n))
        .ok_or_else(|| InputError::out_of_memory(format!("{steps} steps of {n} vertices do not fit in memory")))?;
    let row_bytes = 2 * n * std::mem::size_of::<Vector3<f64>>() + std::mem::size_of::<StepStats>() + 8;
    crate::base::memory::check(&format!("{steps} steps of {n} vertices"), steps + 1, row_bytes)?;
    let mut sim = Simulator::new(model.clone(), settings.clone())?;
    if let Some((q, v)) = &controls.initial {
        sim.start_from(q, v)?;
    }
    let mut out = Rollout {
        n,
        positions: Vec::new(),
        velocities: Vec::new(),
        times: Vec::new(),
        stats: Vec::new(),
        certificate: sim.certificate().clone(),
    };
    // Reserve the whole trajectory up front, and say so if it does not fit (never abort).
    let no_room = |_| {
        DiffError::from(InputError::out_of_memory(format!(
            "{steps} steps of {n} vertices do not fit in memory"
        )))
    };
    out.positions.try_reserve_exact(states).map_err(no_room)?;
    out.velocities.try_reserve_exact(states).map_err(no_room)?;
    out.times.try_reserve_exact(steps + 1).map_err(no_room)?;
    out.stats.try_reserve_exact(steps).map_err(no_room)?;
    let keep = |sim: &Simulator, out: &mut Rollout| {
        let s = sim.state();
        out.positions.extend_from_slice(&s.q);
        out.velocities.extend_from_slice(&s.v);
        out.times.push(s.time);
    };
    keep(&sim, &mut out);
    for k in 0..steps {
        set_controls(&mut sim, model, controls, k)?;
        let st = sim.step()?;
        out.stats.push(st);
        keep(&sim, &mut out);
    }
    Ok(out)
}
