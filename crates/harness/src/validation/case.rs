//! One validation case as the report writes it: its setup, the closed form with its formula
//! and source, the measurement, the error, the tolerance and why, the verdict, and where
//! discretisation error matters, the refinement series with its observed order.

use serde::Serialize;

use crate::report::Verdict;
use diffsoft::base::MaterialModel;

/// Whether a case holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Measured within tolerance of the closed form.
    Holds,
    /// Measured outside the tolerance (see `reason`).
    DoesNotHold,
    /// Not run (see `reason`).
    NotRun,
}

/// One level of a refinement series.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Level {
    /// Cells across the section (or the refinement parameter of the case).
    pub cells: usize,
    /// Characteristic element size (m).
    pub h: f64,
    /// Tets.
    pub tets: usize,
    /// The measured quantity at this level (unit of the case).
    pub measured: f64,
    /// Relative error against the case's reference (1).
    pub error: f64,
    /// Observed order against the reference between the previous level and this one,
    /// `log(e_prev / e) / log(h_prev / h)` (`null` at the first level).
    pub order: Option<f64>,
    /// Newton iterations of the solve.
    pub iterations: usize,
    /// Whether the solve converged.
    pub converged: bool,
    /// Wall time of the solve (s).
    pub seconds: f64,
}

/// One validation case.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Case {
    /// Unique identifier, `<study>.<variant>.<model>[.<moduli>]`.
    pub id: String,
    /// The study it belongs to (`patch_test`, `hanging_bar`, `cantilever`, `elastica`,
    /// `vibration`, `hertz`, `capstan`).
    pub study: String,
    /// The material model (`projective`, `corotated`, `neo_hookean`; `cloth` for the capstan).
    pub model: String,
    /// Which moduli the closed form is evaluated with: `E, nu` (the parameters given) or
    /// `E_eff, nu_eff` (the projective model's small-strain response).
    pub moduli: String,
    /// The setup in words: geometry, mesh, material, load, solver.
    pub setup: String,
    /// The quantity compared, with its unit.
    pub quantity: String,
    /// The closed form.
    pub formula: String,
    /// Where the closed form comes from.
    pub source: String,
    /// The closed form's value (unit of `quantity`; `null` when not run).
    pub reference: Option<f64>,
    /// The measured value (unit of `quantity`; `null` when not run).
    pub measured: Option<f64>,
    /// The error the verdict rests on (relative unless `comparison` says otherwise; 1).
    pub error: Option<f64>,
    /// The tolerance on `error` (1).
    pub tolerance: f64,
    /// Why this tolerance (discretisation order, locking, integrator damping, ...).
    pub tolerance_basis: String,
    /// Whether the closed form is expected to hold for this model and these moduli (the
    /// projective model against `E, nu` at `nu > 0` is expected not to).
    pub expected_to_hold: bool,
    /// The outcome.
    pub status: Status,
    /// Why it does not hold or was not run (`null` when it holds).
    pub reason: Option<String>,
    /// The verdict.
    pub verdict: Verdict,
    /// The refinement series (empty where discretisation is not studied).
    pub series: Vec<Level>,
    /// Observed order of convergence of the finest levels (`null` without a series).
    pub observed_order: Option<f64>,
    /// Further measured values, by name (units in their names).
    pub extra: Vec<Figure>,
    /// Wall time of the case (s; shared runs count once, in the first case that uses them).
    pub seconds: f64,
}

/// A named number.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Figure {
    /// Name (with the unit).
    pub name: String,
    /// Value.
    pub value: f64,
}

/// What every case of a check shares before it is measured.
#[derive(Debug, Clone)]
pub struct Spec {
    /// See [`Case::id`].
    pub id: String,
    /// See [`Case::study`].
    pub study: &'static str,
    /// See [`Case::model`].
    pub model: String,
    /// See [`Case::moduli`].
    pub moduli: String,
    /// See [`Case::setup`].
    pub setup: String,
    /// See [`Case::quantity`].
    pub quantity: String,
    /// See [`Case::formula`].
    pub formula: String,
    /// See [`Case::source`].
    pub source: String,
    /// See [`Case::tolerance`].
    pub tolerance: f64,
    /// See [`Case::tolerance_basis`].
    pub tolerance_basis: String,
    /// See [`Case::expected_to_hold`].
    pub expected_to_hold: bool,
}

/// The moduli label of a model: `E_eff, nu_eff` for the projective model when `effective`.
pub fn moduli(model: MaterialModel, effective: bool) -> String {
    if effective && model == MaterialModel::Projective {
        "E_eff, nu_eff".into()
    } else {
        "E, nu".into()
    }
}

impl Spec {
    /// A case of `study` named `variant` for `model`.
    pub fn new(study: &'static str, variant: &str, model: &str, moduli: &str) -> Self {
        let suffix = match moduli {
            "E_eff, nu_eff" => ".eff",
            _ => "",
        };
        Self {
            id: format!("{study}.{variant}.{model}{suffix}"),
            study,
            model: model.into(),
            moduli: moduli.into(),
            setup: String::new(),
            quantity: String::new(),
            formula: String::new(),
            source: String::new(),
            tolerance: 0.0,
            tolerance_basis: String::new(),
            expected_to_hold: true,
        }
    }

    fn claim(&self) -> String {
        format!(
            "{}: {} matches {} ({}) within the tolerance",
            self.id, self.quantity, self.formula, self.moduli
        )
    }

    /// The case measured: `measured` against `reference`, judged on `error <= tolerance`;
    /// `reason` says why when it does not hold.
    pub fn measured(self, reference: f64, measured: f64, error: f64, reason: impl FnOnce(&Spec) -> String) -> Case {
        let verdict = Verdict::at_most(self.claim(), error, self.tolerance);
        let holds = verdict.holds;
        let why = (!holds).then(|| reason(&self));
        let status = if holds { Status::Holds } else { Status::DoesNotHold };
        self.into_case(verdict, status, why, Some((reference, measured, error)))
    }

    /// The case not run, with the reason.
    pub fn not_run(self, reason: &str) -> Case {
        let verdict = Verdict::new(
            self.claim(),
            false,
            None,
            Some(self.tolerance),
            format!("not run: {reason}"),
        );
        self.into_case(verdict, Status::NotRun, Some(format!("not run: {reason}")), None)
    }

    /// The case with its verdict, status, reason and, when measured, `(reference, measured,
    /// error)`.
    fn into_case(
        self,
        verdict: Verdict,
        status: Status,
        reason: Option<String>,
        values: Option<(f64, f64, f64)>,
    ) -> Case {
        Case {
            id: self.id,
            study: self.study.into(),
            model: self.model,
            moduli: self.moduli,
            setup: self.setup,
            quantity: self.quantity,
            formula: self.formula,
            source: self.source,
            reference: values.map(|v| v.0),
            measured: values.map(|v| v.1),
            error: values.map(|v| v.2),
            tolerance: self.tolerance,
            tolerance_basis: self.tolerance_basis,
            expected_to_hold: self.expected_to_hold,
            status,
            reason,
            verdict,
            series: Vec::new(),
            observed_order: None,
            extra: Vec::new(),
            seconds: 0.0,
        }
    }
}

impl Case {
    /// With further named figures.
    pub fn with(mut self, figures: &[(&str, f64)]) -> Self {
        self.extra.extend(figures.iter().map(|(n, v)| Figure {
            name: (*n).into(),
            value: *v,
        }));
        self
    }

    /// With its wall time.
    pub fn timed(mut self, seconds: f64) -> Self {
        self.seconds = seconds;
        self
    }

    /// Whether the outcome is the expected one (holds when expected to, does not hold when
    /// expected not to); a case not run is not.
    pub fn as_expected(&self) -> bool {
        match self.status {
            Status::Holds => self.expected_to_hold,
            Status::DoesNotHold => !self.expected_to_hold,
            Status::NotRun => false,
        }
    }
}
