//! What one step did: iterations, convergence, contacts, energies, timings.

use serde::Serialize;

/// What one step did.
#[derive(Debug, Clone, Copy, Serialize, schemars::JsonSchema)]
pub struct StepStats {
    /// Step number (1-based).
    pub step: usize,
    /// Time after the step (s).
    pub time: f64,
    /// Local-global iterations.
    pub iterations: usize,
    /// Whether the tolerance was met before the cap.
    pub converged: bool,
    /// Last RMS position change relative to the length scale (1).
    pub relative_change: f64,
    /// The change of the iteration before the last one of the final contact round, relative to
    /// the length scale (1; NaN when that round took one iteration): with `relative_change`,
    /// the rate at which the step's iterations were contracting when they stopped
    /// ([`StepStats::distance_to_converged`]).
    pub previous_change: f64,
    /// Inner iterations of the global solver, summed over the step.
    pub global_iterations: usize,
    /// Contacts in the final round.
    pub contacts: usize,
    /// Contact rounds.
    pub contact_rounds: usize,
    /// Contact iterations (sweeps and active-set solves), summed over the step.
    pub contact_iterations: usize,
    /// Global or contact solves of the step that stopped unconverged: at their iteration cap,
    /// or a contact solve that stalled (no progress over a long batch of sweeps: an infeasible
    /// contact set, such as surfaces already crossed, or one too badly conditioned to reach the
    /// tolerance). Their result is used as it is; the step's own convergence test still applies.
    pub capped_solves: usize,
    /// Deepest penetration after the step (m; 0 without obstacles).
    pub max_penetration: f64,
    /// Kinetic energy after the step (J).
    pub kinetic_energy: f64,
    /// Constraint energy at the last local step (J).
    pub elastic_energy: f64,
    /// Potential energy of the external accelerations, `-sum m a . q` (J).
    pub potential_energy: f64,
    /// Wall time (ms).
    pub wall_ms: f64,
    /// Of which in local steps (projections and gather, ms).
    pub local_ms: f64,
    /// Of which in global solves (ms).
    pub global_ms: f64,
    /// Accelerated iterates rejected by the energy safeguard.
    pub anderson_rejections: usize,
    /// Largest change of a distance within a bone after the step (m; 0 without a skeleton).
    pub bone_length_error: f64,
    /// Contacts between bodies (vertex-face and edge-edge pairs) in the final round.
    pub pair_contacts: usize,
    /// Surface edges of one body that cross a face of another at the end of the step (0
    /// without collisions between bodies): the bodies passed through each other, a contact the
    /// step missed (a body too fast for the time step, or a contact set the solve could not
    /// satisfy). Gradients refuse such a step (the differentiation's `Interpenetration` error).
    pub pair_crossings: usize,
    /// Contacts between bodies whose primitives passed through each other during a round of
    /// the step and were linearised where they met (docs/method.md Eq. C6): the step kept the
    /// bodies apart, but those contacts' geometry depends on more than the step's start, so
    /// gradients refuse the step (the differentiation's `SweptContacts` error).
    pub swept_pairs: usize,
    /// Tets with a zero or negative volume at the end of the step (0 without tets): a body
    /// folded through itself, under a load its material is too soft for or in a step too long
    /// for it. The projective and corotated models pull such a tet back only weakly, and
    /// contacts with a surface that has turned inside out cannot keep the bodies apart (the
    /// paper's cloth_ball, docs/performance.md).
    pub inverted_tets: usize,
    /// Obstacle contacts on bone vertices in the final round (0 without a skeleton; they are
    /// included in `contacts`).
    pub bone_contacts: usize,
}

/// The largest contraction rate [`StepStats::distance_to_converged`] extrapolates with: a rate
/// at or above it (iterations that were not contracting when they stopped) counts as this.
pub const MAX_EXTRAPOLATED_RATE: f64 = 0.99;

impl StepStats {
    /// Record an iteration's change (relative to the length scale), keeping the one before.
    pub(crate) fn record_change(&mut self, relative: f64) {
        self.previous_change = self.relative_change;
        self.relative_change = relative;
    }

    /// Start a contact round's iterations: the rate is measured within one round.
    pub(crate) fn begin_round(&mut self) {
        self.relative_change = f64::NAN;
        self.previous_change = f64::NAN;
    }

    /// Estimated distance of the step's last iterate from the step's converged solution,
    /// relative to the length scale: for iterations contracting at the rate
    /// `rho = relative_change / previous_change`, the remaining changes sum to
    /// `relative_change rho / (1 - rho)` (rho capped at `MAX_EXTRAPOLATED_RATE`); the last
    /// change itself when the round took one iteration (no rate). 0 before any iteration.
    ///
    /// ```
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Settings, Simulator};
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
    /// let body = BodySpec::new("box", mesh, material, MassSpec::Density(1000.0));
    /// let mut s = Simulator::new(ModelBuilder::new().body(body).build()?, Settings::default())?.step()?;
    /// (s.previous_change, s.relative_change) = (1e-4, 5e-5);
    /// assert!((s.distance_to_converged() - 5e-5).abs() < 1e-18); // rho = 1/2
    /// (s.previous_change, s.relative_change) = (1e-4, 2e-4);
    /// assert!((s.distance_to_converged() - 2e-4 * 99.0).abs() < 1e-15); // not contracting
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn distance_to_converged(&self) -> f64 {
        let last = self.relative_change;
        if !last.is_finite() {
            return if last.is_nan() { 0.0 } else { f64::INFINITY };
        }
        let prev = self.previous_change;
        if !(prev.is_finite() && prev > 0.0) {
            return last;
        }
        let rho = (last / prev).min(MAX_EXTRAPOLATED_RATE);
        last * rho / (1.0 - rho)
    }

    /// The figures of step `step` (1-based) ending at `time`, before it runs.
    pub(crate) fn new(step: usize, time: f64) -> Self {
        Self {
            step,
            time,
            iterations: 0,
            converged: false,
            relative_change: f64::NAN,
            previous_change: f64::NAN,
            global_iterations: 0,
            contacts: 0,
            contact_rounds: 0,
            contact_iterations: 0,
            capped_solves: 0,
            max_penetration: 0.0,
            kinetic_energy: 0.0,
            elastic_energy: 0.0,
            potential_energy: 0.0,
            wall_ms: 0.0,
            local_ms: 0.0,
            global_ms: 0.0,
            anderson_rejections: 0,
            bone_length_error: 0.0,
            pair_contacts: 0,
            pair_crossings: 0,
            swept_pairs: 0,
            inverted_tets: 0,
            bone_contacts: 0,
        }
    }

    /// Kinetic + elastic + potential energy.
    pub fn total_energy(&self) -> f64 {
        self.kinetic_energy + self.elastic_energy + self.potential_energy
    }
}
