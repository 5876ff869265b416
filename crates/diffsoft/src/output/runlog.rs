//! The JSON run log of `diffsoft simulate` (`diffsoft.run/2`): scene, notes, settings,
//! certificate, per-step statistics and a summary.

use serde::Serialize;

use crate::base::{Body, MaterialModel};
use crate::cloth::ClothBody;
use crate::model::Model;
use crate::report::{Header, ModelSize};
use crate::solver::{Certificate, Settings, StepStats};

/// Schema of the run log.
pub const RUN_SCHEMA: &str = "diffsoft.run/2";

/// Summary over all steps.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct RunSummary {
    /// Steps taken.
    pub steps: usize,
    /// Simulated time (s).
    pub simulated_time: f64,
    /// Wall time of the steps (s).
    pub wall_time_s: f64,
    /// Median wall time per step (ms).
    pub median_ms_per_step: f64,
    /// Mean local-global iterations per step.
    pub mean_iterations: f64,
    /// Steps that met the tolerance before the iteration cap.
    pub converged_steps: usize,
    /// Steps with a global or contact solve that stopped unconverged (cap or stall).
    pub steps_with_capped_solves: usize,
    /// Steps that ended with the surfaces of two bodies crossing (`pair_crossings` in the step
    /// log): contacts the run missed.
    pub steps_with_pair_crossings: usize,
    /// Steps that kept two bodies apart with contacts found by sweeping their motion
    /// (`swept_pairs` in the step log): gradients refuse them.
    pub steps_with_swept_pairs: usize,
    /// Steps that ended with inverted tets (`inverted_tets` in the step log): a body folded
    /// through itself.
    pub steps_with_inverted_tets: usize,
    /// Most inverted tets at the end of a step.
    pub max_inverted_tets: usize,
    /// Deepest penetration over the run (m).
    pub max_penetration: f64,
    /// Largest number of contacts in a step.
    pub max_contacts: usize,
    /// Largest number of contacts between bodies in a step.
    pub max_pair_contacts: usize,
    /// Total energy after the first step (J; 0 without steps).
    pub energy_first_step: f64,
    /// Total energy after the last step (J; 0 without steps).
    pub energy_last_step: f64,
}

/// A body's material as the run log reports it: the model, the moduli given, and for the
/// projective model the moduli it responds with at small strain (docs/method.md Eq. H5).
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct MaterialLog {
    /// The constitutive model.
    pub model: MaterialModel,
    /// Young's modulus given (Pa).
    pub youngs_modulus: f64,
    /// Poisson ratio given (1).
    pub poisson_ratio: f64,
    /// Projective model: the Young's modulus it responds with at small strain,
    /// `E / (1 + 2 nu / 3)` (Pa); `null` for the true models, which respond with the one given.
    pub effective_youngs_modulus: Option<f64>,
    /// Projective model: the Poisson ratio it responds with at small strain, `nu / (3 + 2 nu)`.
    pub effective_poisson_ratio: Option<f64>,
}

/// One soft body in the run log.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct BodyLog {
    /// Name.
    pub name: String,
    /// Its vertices in the global numbering.
    pub vertices: std::ops::Range<usize>,
    /// Its tets in the global numbering.
    pub tets: std::ops::Range<usize>,
    /// Material.
    pub material: MaterialLog,
    /// Total mass (kg).
    pub mass: f64,
    /// Density (kg/m^3).
    pub density: f64,
    /// Whether gravity acts on it.
    pub gravity: bool,
    /// Whether its volume constraint is on (projective model).
    pub volume_constraint: bool,
}

impl BodyLog {
    /// The log entry of `b`.
    pub fn of(b: &Body) -> Self {
        let eff = (b.model == MaterialModel::Projective).then(|| b.material.projective_response());
        Self {
            name: b.name.clone(),
            vertices: b.vertices.clone(),
            tets: b.tets.clone(),
            material: MaterialLog {
                model: b.model,
                youngs_modulus: b.material.youngs_modulus,
                poisson_ratio: b.material.poisson_ratio,
                effective_youngs_modulus: eff.map(|m| m.youngs_modulus),
                effective_poisson_ratio: eff.map(|m| m.poisson_ratio),
            },
            mass: b.mass,
            density: b.density,
            gravity: b.gravity,
            volume_constraint: b.volume_constraint,
        }
    }

    /// The one-line note for a projective body with `nu > 0`, whose response differs from the
    /// moduli given (`None` otherwise).
    pub fn material_note(b: &Body) -> Option<String> {
        if b.model != MaterialModel::Projective || b.material.poisson_ratio == 0.0 {
            return None;
        }
        let r = b.material.projective_response();
        Some(format!(
            "body '{}': the projective material with E = {:e} Pa, nu = {} responds as E_eff = {:.6e} Pa, nu_eff = {:.4}; use model corotated or neo_hookean for the stated moduli",
            b.name, b.material.youngs_modulus, b.material.poisson_ratio, r.youngs_modulus, r.poisson_ratio
        ))
    }

    /// The one-line note for a body of `model` too soft to hold its shape under its own
    /// weight (`None` otherwise): the strain `rho g H / E` at the foot of a column of the body's
    /// height `H` along gravity (the stress there is `rho g H`), with the modulus the body
    /// responds with (`E_eff` for the projective model), at or above [`WEIGHT_STRAIN`]. Such a
    /// body folds through itself once it rests on something (`inverted_tets` in the step log).
    ///
    /// ```
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::output::BodyLog;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
    /// use nalgebra::Vector3;
    ///
    /// let cube = |e: f64| -> Result<_, Box<dyn std::error::Error>> {
    ///     let mesh = BoxSpec::new([2, 2, 2], [0.5, 0.5, 0.5]).build()?;
    ///     let m = Material { youngs_modulus: e, poisson_ratio: 0.0 };
    ///     let body = BodySpec::new("cube", mesh, m, MassSpec::Density(1000.0));
    ///     Ok(ModelBuilder::new().gravity(Vector3::new(0.0, -9.81, 0.0)).body(body).build()?)
    /// };
    /// // A cube 0.5 m high: 1000 kg/m^3 x 9.81 m/s^2 x 0.5 m over E: 4.9 at E = 1000 Pa
    /// // (nu = 0: the projective response is E itself), 4.9e-3 at 1 MPa.
    /// let soft = cube(1e3)?;
    /// let note = BodyLog::weight_note(&soft, &soft.bodies()[0]).ok_or("no note")?;
    /// assert!(note.contains("4.91e0") && note.contains("(0.500 m)"), "{note}");
    /// let stiff = cube(1e6)?;
    /// assert!(BodyLog::weight_note(&stiff, &stiff.bodies()[0]).is_none());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn weight_note(model: &Model, b: &Body) -> Option<String> {
        let g = *model.accel.get(b.vertices.start)?;
        let gn = g.norm();
        if !b.gravity || gn == 0.0 {
            return None;
        }
        let down = g / gn;
        let heights = model.rest[b.vertices.clone()].iter().map(|x| x.dot(&down));
        let (lo, hi) = heights.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), h| (lo.min(h), hi.max(h)));
        let e = b.model.small_strain_response(b.material).youngs_modulus;
        let strain = b.density * gn * (hi - lo) / e;
        (strain >= WEIGHT_STRAIN).then(|| {
            format!(
                "body '{}': too soft to carry its own weight: a column of its height ({:.3} m) would be strained by rho g H / E = {:.2e} at its foot (E = {:e} Pa{}); expect it to fold through itself once it rests on something (inverted_tets in the step log)",
                b.name,
                hi - lo,
                strain,
                e,
                if b.model == MaterialModel::Projective { ", the projective response" } else { "" }
            )
        })
    }
}

/// Every body's notes about its material, in body order: the projective response differing
/// from the moduli given ([`BodyLog::material_note`]) and a body too soft to carry its own
/// weight ([`BodyLog::weight_note`]). What `simulate` and `grad` print before a run and what
/// the Python package's `Scene.notes` adds to the importer's notes; computed from the model as
/// it is, so a changed modulus changes them.
///
/// ```
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::output::body_notes;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
/// use nalgebra::Vector3;
///
/// let mesh = BoxSpec::new([2, 2, 2], [0.5, 0.5, 0.5]).build()?;
/// let m = Material { youngs_modulus: 1e3, poisson_ratio: 0.3 };
/// let body = BodySpec::new("cube", mesh, m, MassSpec::Density(1000.0));
/// let model = ModelBuilder::new().gravity(Vector3::new(0.0, -9.81, 0.0)).body(body).build()?;
/// let notes = body_notes(&model);
/// assert_eq!(notes.len(), 2, "{notes:?}");
/// assert!(notes[0].contains("E_eff") && notes[1].contains("too soft to carry its own weight"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn body_notes(model: &Model) -> Vec<String> {
    model
        .bodies()
        .iter()
        .flat_map(|b| [BodyLog::material_note(b), BodyLog::weight_note(model, b)])
        .flatten()
        .collect()
}

/// Share of a model's tets inverted at the end of some step from which a run is said to have
/// folded a body through itself ([`folded`]): a few inverted tets (the paper's bridgesus: up to
/// 4 of 668 while it sags) are counted in the step log but not warned about.
pub const FOLDED_SHARE: f64 = 0.1;

/// Whether a run whose worst step ended with `max_inverted` of the model's `tets` tets inverted
/// folded a body through itself ([`FOLDED_SHARE`]): what `simulate` and the Python package warn
/// about.
///
/// ```
/// use diffsoft::output::folded;
/// assert!(folded(58, 80)); // the paper's cloth_ball
/// assert!(!folded(4, 668)); // the paper's bridgesus while it sags
/// assert!(!folded(0, 0));
/// ```
pub fn folded(max_inverted: usize, tets: usize) -> bool {
    max_inverted > 0 && max_inverted as f64 >= FOLDED_SHARE * tets as f64
}

/// A step that stopped short of its tolerance and raised the total energy of a scene that has
/// no energy source ([`solver_energy_gain`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnergyGain {
    /// The step (1-based).
    pub step: usize,
    /// Total energy after the step before it (J).
    pub before: f64,
    /// Total energy after it (J).
    pub after: f64,
}

/// The unconverged step of `steps` (a run of `model`) that raised the total energy the most,
/// where it raised it by more than half of what the bodies held before it (their kinetic and
/// elastic energy, or the total's magnitude) and `model` has no energy source (actuators, joint
/// torques): without one, a step of implicit Euler or BDF2 with frictional contact keeps or
/// loses energy to the integrator's accuracy, so such a gain is the solver's error, not the
/// physics'. Converged steps are not considered, nor the first (no energy before it is logged).
///
/// ```
/// use diffsoft::output::solver_energy_gain;
/// use diffsoft::{Settings, Simulator};
///
/// // A box dropped on frictional ground, converged steps: no energy is the solver's.
/// let mut sim = Simulator::new(diffsoft::testing::ground_box(0.5)?, Settings::default())?;
/// let steps = (0..10).map(|_| sim.step()).collect::<Result<Vec<_>, _>>()?;
/// assert!(solver_energy_gain(sim.model(), &steps).is_none());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn solver_energy_gain(model: &Model, steps: &[StepStats]) -> Option<EnergyGain> {
    let driven = model.actuators().is_some()
        || model
            .skeleton()
            .is_some_and(|k| k.bones.iter().any(|b| b.torque.is_some()));
    if driven {
        return None;
    }
    steps
        .windows(2)
        .filter(|w| !w[1].converged)
        .filter_map(|w| {
            let (before, after) = (w[0].total_energy(), w[1].total_energy());
            let held = (w[0].kinetic_energy + w[0].elastic_energy).max(before.abs());
            (after.is_finite() && after - before > 0.5 * held).then_some(EnergyGain {
                step: w[1].step,
                before,
                after,
            })
        })
        .max_by(|a, b| (a.after - a.before).total_cmp(&(b.after - b.before)))
}

/// Strain under the body's own weight ([`BodyLog::weight_note`]) from which a body is noted
/// as too soft to carry itself: linear elasticity has long stopped describing it there.
pub const WEIGHT_STRAIN: f64 = 1.0;

/// The run log.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct RunLog {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// Scene file.
    pub scene: String,
    /// What the importer did.
    pub notes: Vec<String>,
    /// Bodies.
    pub bodies: Vec<BodyLog>,
    /// Cloth bodies.
    pub cloth: Vec<ClothBody>,
    /// Vertices and tets in total.
    pub size: ModelSize,
    /// Solver settings (`damping` is the velocity factor per step).
    pub settings: Settings,
    /// The velocity damping over one second, `damping^(1/dt)`: what a time-step override keeps.
    pub damping_per_second: f64,
    /// Actuator groups held at one activation for the whole run (`--activation NAME=A`), by
    /// group name (empty: none held).
    pub activations: std::collections::BTreeMap<String, f64>,
    /// Certification outcome.
    pub certificate: Certificate,
    /// Summary.
    pub summary: RunSummary,
    /// Per-step statistics.
    pub steps: Vec<StepStats>,
    /// Frames written (relative to the output directory).
    pub frames: Vec<String>,
    /// How the run stands or ended (`running` while it goes on; the log is refreshed every
    /// few seconds).
    pub status: super::RunStatus,
    /// Error that ended the run early, if any.
    pub error: Option<String>,
}

impl RunSummary {
    /// Summarise step statistics.
    ///
    /// ```
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::output::RunSummary;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Settings, Simulator};
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
    /// let model = ModelBuilder::new().body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0))).build()?;
    /// let mut sim = Simulator::new(model, Settings::default())?;
    /// let steps = vec![sim.step()?, sim.step()?];
    /// let summary = RunSummary::of(&steps);
    /// assert_eq!((summary.steps, summary.converged_steps), (2, 2));
    /// assert!((summary.simulated_time - 0.02).abs() < 1e-12);
    /// let none = RunSummary::of(&[]);
    /// assert_eq!(none.steps, 0);
    /// // Zero, not -0 (printed "-0.000" for a run that failed before its first step).
    /// assert!(none.wall_time_s.is_sign_positive() && none.mean_iterations.is_sign_positive());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn of(steps: &[StepStats]) -> Self {
        let mut ms: Vec<f64> = steps.iter().map(|s| s.wall_ms).collect();
        ms.sort_by(f64::total_cmp);
        let median = if ms.is_empty() { 0.0 } else { ms[ms.len() / 2] };
        Self {
            steps: steps.len(),
            simulated_time: steps.last().map_or(0.0, |s| s.time),
            // Folds from +0 (an empty f64 sum is -0, printed "-0.000" for a run of no steps).
            wall_time_s: ms.iter().fold(0.0, |a, b| a + b) / 1e3,
            median_ms_per_step: median,
            mean_iterations: steps.iter().fold(0.0, |a, s| a + s.iterations as f64) / steps.len().max(1) as f64,
            converged_steps: steps.iter().filter(|s| s.converged).count(),
            steps_with_capped_solves: steps.iter().filter(|s| s.capped_solves > 0).count(),
            steps_with_pair_crossings: steps.iter().filter(|s| s.pair_crossings > 0).count(),
            steps_with_swept_pairs: steps.iter().filter(|s| s.swept_pairs > 0).count(),
            steps_with_inverted_tets: steps.iter().filter(|s| s.inverted_tets > 0).count(),
            max_inverted_tets: steps.iter().map(|s| s.inverted_tets).max().unwrap_or(0),
            max_penetration: steps.iter().map(|s| s.max_penetration).fold(0.0, f64::max),
            max_contacts: steps.iter().map(|s| s.contacts).max().unwrap_or(0),
            max_pair_contacts: steps.iter().map(|s| s.pair_contacts).max().unwrap_or(0),
            energy_first_step: steps.first().map_or(0.0, |s| s.total_energy()),
            energy_last_step: steps.last().map_or(0.0, |s| s.total_energy()),
        }
    }
}

#[cfg(test)]
mod energy_gain_tests {
    use super::*;

    /// An unconverged step that multiplies the energy is the solver's; a converged one, a small
    /// gain, or a scene with actuators is not reported.
    #[test]
    fn a_large_gain_in_an_unconverged_step_of_a_passive_scene_is_reported() {
        let model = crate::model::fixtures::ground_box(0.5).unwrap();
        let step = |k: usize, kinetic: f64, converged: bool| StepStats {
            kinetic_energy: kinetic,
            converged,
            ..StepStats::new(k, 0.01 * k as f64)
        };
        let gain = solver_energy_gain(
            &model,
            &[step(1, 7.8, true), step(2, 4839.6, false), step(3, 4000.0, false)],
        );
        assert_eq!(
            gain,
            Some(EnergyGain {
                step: 2,
                before: 7.8,
                after: 4839.6
            })
        );
        assert_eq!(
            solver_energy_gain(&model, &[step(1, 7.8, true), step(2, 4839.6, true)]),
            None
        );
        assert_eq!(
            solver_energy_gain(&model, &[step(1, 7.8, true), step(2, 8.0, false)]),
            None
        );
        assert_eq!(solver_energy_gain(&model, &[step(2, 4839.6, false)]), None);
    }
}
