//! Running one extreme case: a simulation whose errors are classified into the explained
//! outcomes, the checks it records, and its gradient.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::Outcome;
use diffsoft::diff::{self, loss::Loss, Controls, Mode, Options, Param};
use diffsoft::model::Model;
use diffsoft::solver::{CertifyPolicy, Settings, Simulator, SolverError, SolverKind, StepStats};

/// How a check's measurement is compared with its threshold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Comparison {
    /// Holds iff the measurement is finite and at most the threshold.
    AtMost,
    /// Holds iff the measurement is finite and at least the threshold.
    AtLeast,
    /// Recorded, not bounded: no threshold, always holds.
    Recorded,
}

/// A measured quantity and whether it is within its bound.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Check {
    /// What is measured.
    pub quantity: String,
    /// The measurement, in the unit `quantity` names (`null` when it does not exist, e.g. after a
    /// failed run, or is not finite).
    pub measured: Option<f64>,
    /// The bound, in the unit of `measured` (`null` for a recorded check).
    pub threshold: Option<f64>,
    /// How `measured` is compared with `threshold`.
    pub comparison: Comparison,
    /// Whether it holds (what `comparison` gives for `measured` and `threshold`).
    pub holds: bool,
    /// How to read it.
    pub note: String,
}

impl Check {
    /// `measured <= threshold` (a non-finite measurement fails).
    pub fn at_most(quantity: &str, measured: f64, threshold: f64, note: &str) -> Self {
        Self::bounded(quantity, measured, threshold, Comparison::AtMost, note)
    }

    /// `measured >= threshold` (a non-finite measurement fails).
    pub fn at_least(quantity: &str, measured: f64, threshold: f64, note: &str) -> Self {
        Self::bounded(quantity, measured, threshold, Comparison::AtLeast, note)
    }

    /// A measurement recorded without a bound (it always holds).
    pub fn recorded(quantity: String, measured: f64, note: &str) -> Self {
        Self {
            quantity,
            measured: measured.is_finite().then_some(measured),
            threshold: None,
            comparison: Comparison::Recorded,
            holds: true,
            note: note.into(),
        }
    }

    fn bounded(quantity: &str, measured: f64, threshold: f64, comparison: Comparison, note: &str) -> Self {
        let measured = measured.is_finite().then_some(measured);
        Self {
            quantity: quantity.into(),
            measured,
            threshold: Some(threshold),
            comparison,
            holds: Self::verdict(comparison, measured, Some(threshold)),
            note: note.into(),
        }
    }

    /// Whether a check with these figures holds (false when they do not fit the comparison: a
    /// bounded check without a threshold, a recorded one with one).
    pub fn verdict(comparison: Comparison, measured: Option<f64>, threshold: Option<f64>) -> bool {
        match (comparison, threshold) {
            (Comparison::AtMost, Some(t)) => measured.is_some_and(|m| m <= t),
            (Comparison::AtLeast, Some(t)) => measured.is_some_and(|m| m >= t),
            (Comparison::Recorded, None) => true,
            _ => false,
        }
    }
}

/// What happened to a case's gradient.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum GradientStatus {
    /// Every derivative is finite.
    Finite,
    /// The backward pass refused with a message (unsupported scene, failed forward).
    Error,
    /// Non-finite derivatives without an error: a bug.
    NonFinite,
    /// Not computed (the forward was rejected, or the case has no parameters to vary).
    NotComputed,
}

/// A case's gradient.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct GradientCheck {
    /// Outcome.
    pub status: GradientStatus,
    /// The error, or why it was not computed.
    pub message: Option<String>,
    /// Parameters.
    pub parameters: Vec<String>,
    /// `dL/dp` (loss unit per parameter unit; finite values only).
    pub values: Option<Vec<f64>>,
}

impl GradientCheck {
    /// Not computed, because `why`.
    pub fn not_computed(why: &str) -> Self {
        Self {
            status: GradientStatus::NotComputed,
            message: Some(why.into()),
            parameters: Vec::new(),
            values: None,
        }
    }
}

/// What a case measured.
#[derive(Debug, Clone)]
pub struct Trial {
    /// Outcome.
    pub outcome: Outcome,
    /// Message of a detected or rejected outcome.
    pub message: Option<String>,
    /// Steps that ran.
    pub steps_run: usize,
    /// Checks.
    pub checks: Vec<Check>,
    /// Gradient.
    pub gradient: GradientCheck,
}

impl Trial {
    /// A failure (panic) with its message.
    pub fn failed(message: String, _steps: usize) -> Self {
        Self {
            outcome: Outcome::Failed,
            message: Some(message),
            steps_run: 0,
            checks: Vec::new(),
            gradient: GradientCheck::not_computed("the case failed"),
        }
    }

    /// Input refused before simulating.
    pub fn rejected(message: String) -> Self {
        Self {
            outcome: Outcome::RejectedInput,
            message: Some(message),
            steps_run: 0,
            checks: Vec::new(),
            gradient: GradientCheck::not_computed("the input was rejected"),
        }
    }
}

/// The explained outcome of a solver error.
pub fn classify(e: &SolverError) -> Outcome {
    match e {
        SolverError::Input(_) | SolverError::Uncertified(_) => Outcome::RejectedInput,
        _ => Outcome::DetectedDivergence,
    }
}

/// A simulation to probe.
pub struct Probe {
    /// Model.
    pub model: Model,
    /// Settings.
    pub settings: Settings,
    /// Steps.
    pub steps: usize,
    /// Initial positions and velocities (`None`: rest and the model's initial velocities).
    pub initial: Option<diffsoft::diff::InitialState>,
    /// A joint coordinate to set first: (bone, value).
    pub joint: Option<(String, f64)>,
    /// Activations held for the whole run: (group, value).
    pub activations: Vec<(String, f64)>,
}

impl Probe {
    /// A probe of `model` for `steps` steps with `settings`.
    pub fn new(model: Model, settings: Settings, steps: usize) -> Self {
        Self {
            model,
            settings,
            steps,
            initial: None,
            joint: None,
            activations: Vec::new(),
        }
    }

    /// The initial state.
    pub fn initial_state(&self) -> diffsoft::diff::InitialState {
        self.initial
            .clone()
            .unwrap_or_else(|| (self.model.rest().to_vec(), self.model.initial_velocity().to_vec()))
    }

    fn simulator(&self) -> Result<Simulator, SolverError> {
        let mut sim = Simulator::new(self.model.clone(), self.settings.clone())?;
        if let Some((q, v)) = &self.initial {
            sim.set_state(q.clone(), v.clone())?;
        }
        if let Some((bone, c)) = &self.joint {
            sim.set_joint_coordinates(bone, &[*c])?;
        }
        for (g, a) in &self.activations {
            sim.set_activation(g, *a)?;
        }
        Ok(sim)
    }

    /// Run, calling `on_step` after every step; returns the trial (no checks, no gradient yet)
    /// and the simulator after the run (`None` when it could not be set up).
    pub fn run(&self, mut on_step: impl FnMut(&Simulator, &StepStats)) -> (Trial, Option<Simulator>) {
        let mut trial = Trial {
            outcome: Outcome::Stable,
            message: None,
            steps_run: 0,
            checks: Vec::new(),
            gradient: GradientCheck::not_computed("not requested"),
        };
        let mut sim = match self.simulator() {
            Ok(s) => s,
            Err(e) => {
                trial.outcome = classify(&e);
                trial.message = Some(e.to_string());
                return (trial, None);
            }
        };
        trial.message = Some(sim.certificate().message.clone());
        for k in 1..=self.steps {
            match sim.step() {
                Ok(st) => {
                    trial.steps_run = k;
                    on_step(&sim, &st);
                }
                Err(e) => {
                    trial.outcome = classify(&e);
                    trial.message = Some(format!("step {k}: {e}"));
                    return (trial, Some(sim));
                }
            }
        }
        let st = sim.state();
        if !st.q.iter().chain(&st.v).all(|x| x.iter().all(|c| c.is_finite())) {
            trial.outcome = Outcome::Failed;
            trial.message = Some("silent NaN: the run ended without an error but with non-finite states".into());
        }
        (trial, Some(sim))
    }

    /// The gradient of `loss` with respect to `params` (direct solver, the probe's other
    /// settings, held activations as controls).
    pub fn gradient(&self, loss: &dyn Loss, params: &[Param]) -> GradientCheck {
        let mut settings = self.settings.clone();
        settings.solver = SolverKind::Direct;
        settings.certify = CertifyPolicy::Off;
        let mut controls = Controls {
            initial: self.initial.clone(),
            ..Controls::default()
        };
        if let (false, Some(act)) = (self.activations.is_empty(), &self.model.actuators()) {
            let row: Vec<f64> = act
                .groups
                .iter()
                .map(|g| {
                    self.activations
                        .iter()
                        .find(|(n, _)| *n == g.name)
                        .map_or_else(|| g.activation.at(0.0), |(_, a)| *a)
                })
                .collect();
            controls.activations = Some(vec![row; self.steps]);
        }
        let parameters = params.iter().map(|p| p.to_string()).collect();
        match diff::gradient(
            &self.model,
            &settings,
            self.steps,
            &controls,
            loss,
            // The study measures gradients of unconverged settings too (their stats say so).
            Options {
                allow_unconverged: true,
                ..Options::mode(Mode::Unrolled)
            },
        ) {
            Ok(g) => {
                let mut v: Vec<f64> = params.iter().map(|p| p.derivative(&self.model, &g)).collect();
                v.push(g.loss);
                let finite = v.iter().all(|x| x.is_finite());
                v.pop();
                GradientCheck {
                    status: if finite {
                        GradientStatus::Finite
                    } else {
                        GradientStatus::NonFinite
                    },
                    message: (!finite).then(|| format!("non-finite loss or derivatives: {v:?}")),
                    parameters,
                    values: finite.then_some(v),
                }
            }
            Err(e) => GradientCheck {
                status: GradientStatus::Error,
                message: Some(e.to_string()),
                parameters,
                values: None,
            },
        }
    }
}

/// `kappa = 1 + h^2 max_i L_ii / m_i`, the diagonal estimate of the condition number of the
/// global matrix `M/h^2 + L` relative to `M/h^2`: a solve's round-off is about `eps kappa` of
/// the coordinates. NaN (`null` in reports) when the stiffness cannot be assembled (a weight
/// that underflows or overflows: the run itself then stops with that error).
pub fn condition_estimate(model: &Model, dt: f64) -> f64 {
    let Ok(values) = diffsoft::stiffness_values(model) else {
        return f64::NAN;
    };
    let worst = model
        .fem()
        .pattern
        .diag_slot
        .iter()
        .zip(model.mass())
        .map(|(&k, m)| values[k] / m)
        .fold(0.0, f64::max);
    1.0 + dt * dt * worst
}

/// Total linear momentum `sum m v`.
pub fn momentum(model: &Model, v: &[Vector3<f64>]) -> Vector3<f64> {
    v.iter().zip(model.mass()).map(|(v, m)| v * *m).sum()
}

/// The external force `sum m a` (its impulse over `T` is the momentum change without contacts
/// and pins).
pub fn external_force(model: &Model) -> Vector3<f64> {
    model.accel().iter().zip(model.mass()).map(|(a, m)| a * *m).sum()
}
