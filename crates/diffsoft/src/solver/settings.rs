//! The settings of a simulation: time step and integrator, global solver and its certification, iteration caps
//! and tolerances, damping, contact handling, Anderson acceleration.

use serde::Serialize;

use super::certificate::CertifyPolicy;
use super::global::SolverKind;
use super::integrator::Integrator;
use super::SolverError;
use crate::analysis::spectral::EigenMethod;
use crate::model::Model;

/// Solver settings, documented once here: the scene file's `solver` section reads them (every
/// key optional, unknown keys refused; the scene format's `SceneFile` also takes the time
/// step), `diffsoft simulate` and `grad` override them (`--dt`, `--solver`, `--tolerance`, ...)
/// and Python's `Scene.configure(**settings)` sets them, all by these names and through
/// [`Settings::set`]; the run log (`run.json`) writes them back.
#[derive(Debug, Clone, Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct Settings {
    /// Time step (s). A scene file may give it as its top-level `time_step` instead, the older
    /// spelling.
    pub dt: f64,
    /// Time integrator: implicit Euler (the paper's, first order) or `bdf2` (second order,
    /// docs/method.md Eqs. T1-T3; its first step is implicit Euler).
    pub integrator: Integrator,
    /// Global solver (default `auto`: the cheapest for the mesh and time step).
    pub solver: SolverKind,
    /// Certification policy for iterative global solvers.
    pub certify: CertifyPolicy,
    /// Local-global iteration cap per step.
    pub max_iterations: usize,
    /// Local-global tolerance: a step stops when the RMS change of the positions is below
    /// `tolerance x length scale` (1, below 1; 0: always run the cap, a smooth forward).
    pub tolerance: f64,
    /// Inner iterations stop when no coordinate moves more than this `x length scale` (1, below
    /// 1).
    pub inner_tolerance: f64,
    /// Inner iteration cap (iterative global solvers, contact sweeps).
    pub inner_max_iterations: usize,
    /// Velocity damping factor per step (1; 1 = none; the paper uses 0.9999).
    pub damping: f64,
    /// Contact detection margin, as a fraction of the length scale (1, at most 1).
    pub contact_margin: f64,
    /// Largest number of detect-and-resolve rounds per step (at least 1).
    pub contact_rounds: usize,
    /// Largest number of rounds of a step that would otherwise end with the surfaces of two
    /// bodies crossing: past `contact_rounds`, the rounds go on while the round's end
    /// positions cross and detection finds contacts to add (docs/method.md, "Crossed surfaces
    /// after a step"). At or below `contact_rounds`: no extra rounds.
    pub crossing_rounds: usize,
    /// Eigensolver for certification.
    pub eigen_method: EigenMethod,
    /// Anderson acceleration memory of the local-global iteration (0: off, the paper's plain
    /// iteration; unrolled mode differentiates plain iterations only).
    pub anderson: usize,
}

/// The defaults: `dt` 0.01 s, implicit Euler, the `auto` solver certified with fallback, 30
/// local-global iterations to a tolerance of 1e-6 of the length scale, no damping.
///
/// ```
/// use diffsoft::{Settings, SolverKind};
///
/// let s = Settings::default();
/// assert_eq!((s.dt, s.solver, s.max_iterations), (0.01, SolverKind::Auto, 30));
/// ```
/// The largest Anderson memory accepted ([`Settings::anderson`]): the accelerator keeps two
/// position-sized vectors per slot and solves a least-squares problem of this size every
/// iteration, so a memory beyond a few dozen costs memory and time and gains nothing.
pub const MAX_ANDERSON: usize = 64;

impl Default for Settings {
    fn default() -> Self {
        Self {
            dt: 0.01,
            integrator: Integrator::ImplicitEuler,
            solver: SolverKind::Auto,
            certify: CertifyPolicy::Fallback,
            max_iterations: 30,
            tolerance: 1e-6,
            inner_tolerance: 1e-10,
            inner_max_iterations: 2000,
            damping: 1.0,
            contact_margin: 1e-3,
            contact_rounds: 4,
            crossing_rounds: 64,
            eigen_method: EigenMethod::Auto,
            anderson: 0,
        }
    }
}

impl Settings {
    /// Check the settings are meaningful.
    pub fn validate(&self) -> Result<(), SolverError> {
        let bad = |m: String| Err(SolverError::input(m));
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return bad(format!(
                "time step must be finite and positive, got {}",
                crate::base::number(self.dt)
            ));
        }
        for (name, cap) in [
            ("max_iterations", self.max_iterations),
            ("inner_max_iterations", self.inner_max_iterations),
            // Every step detects and resolves its contacts at least once.
            ("contact_rounds", self.contact_rounds),
        ] {
            if cap == 0 {
                return bad(format!("{name} (an iteration cap) must be at least 1, got 0"));
            }
        }
        for (name, v) in [
            ("tolerance", self.tolerance),
            ("inner_tolerance", self.inner_tolerance),
            ("contact_margin", self.contact_margin),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!(
                    "{name} must be finite and >= 0, got {}",
                    crate::base::number(v)
                ));
            }
        }
        // All three are fractions of the model's length scale: a change of the whole length
        // scale per iteration "converged" would stop every step at its first iteration, and a
        // margin of more than the length scale would put every surface in contact.
        for (name, v, what) in [
            (
                "tolerance",
                self.tolerance,
                "every step would stop at its first iteration",
            ),
            (
                "inner_tolerance",
                self.inner_tolerance,
                "every inner solve would stop at its first iteration",
            ),
        ] {
            if v >= 1.0 {
                return bad(format!(
                    "{name} must be below 1 (a fraction of the model's length scale; at {} {what})",
                    crate::base::number(v)
                ));
            }
        }
        if self.contact_margin > 1.0 {
            return bad(format!(
                "contact_margin must be at most 1 (a fraction of the model's length scale; at {} surfaces farther apart than the bodies are large would be in contact)",
                crate::base::number(self.contact_margin)
            ));
        }
        if !(self.damping.is_finite() && self.damping > 0.0 && self.damping <= 1.0) {
            return bad(format!(
                "damping must be in (0, 1], got {}",
                crate::base::number(self.damping)
            ));
        }
        if self.anderson > MAX_ANDERSON {
            return bad(format!(
                "anderson memory must be at most {MAX_ANDERSON}, got {} (it keeps 2 x memory copies of the positions; memories above about 10 rarely converge faster)",
                self.anderson
            ));
        }
        Ok(())
    }

    /// Set one setting by name to a JSON value (`"split"`, `1e-8`, `200`), as a scene file's
    /// `solver` section would, and check the result ([`Settings::validate`]); on an error the
    /// settings are unchanged. The command line's overrides and Python's `Scene.configure`
    /// come through here. A number setting given `null` (how serde writes NaN and infinity)
    /// is refused.
    ///
    /// ```
    /// use diffsoft::{Settings, SolverKind};
    ///
    /// let mut s = Settings::default();
    /// s.set("solver", "split".into())?;
    /// s.set("tolerance", 1e-8.into())?;
    /// assert_eq!((s.solver, s.tolerance), (SolverKind::Split, 1e-8));
    /// assert!(s.set("tolerance", (-1.0).into()).is_err());
    /// assert!(s.set("tolerance", 1e300.into()).is_err()); // a fraction of the length scale
    /// assert_eq!(s.tolerance, 1e-8); // unchanged by the refused call
    /// assert!(s.set("no_such_setting", 1.into()).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// Setting `dt` keeps the damping per second: the per-step factor becomes
    /// `damping^(dt' / dt)` ([`Settings::with_dt`]), so refining the time step changes no physics.
    pub fn set(&mut self, name: &str, value: serde_json::Value) -> Result<(), SolverError> {
        if name == "dt" {
            let dt = value
                .as_f64()
                .ok_or_else(|| SolverError::input(format!("dt must be a finite number, got {value}")))?;
            let next = self.with_dt(dt);
            next.validate()?;
            *self = next;
            return Ok(());
        }
        let mut fields = match serde_json::to_value(&*self) {
            Ok(serde_json::Value::Object(fields)) => fields,
            _ => return Err(SolverError::input("settings: cannot be written as JSON")),
        };
        if !fields.contains_key(name) {
            return Err(SolverError::input(format!(
                "unknown setting '{name}' (settings: {})",
                Self::names().join(", ")
            )));
        }
        if value.is_null() && fields[name].is_number() {
            // JSON has no NaN or infinity: serde writes them as null.
            return Err(SolverError::input(format!("{name} must be a finite number")));
        }
        fields.insert(name.to_string(), value);
        let next: Settings = serde_json::from_value(serde_json::Value::Object(fields))
            .map_err(|e| SolverError::input(format!("settings: {name}: {e}")))?;
        next.validate()?;
        *self = next;
        Ok(())
    }

    /// These settings with time step `dt`, the velocity damping rescaled to the same damping
    /// per second (`damping^(dt/self.dt)`; docs/method.md Eq. 4): how the command line's `--dt`,
    /// Python's `configure(dt=)` and the trade-off study's step refinements change the step.
    ///
    /// ```
    /// use diffsoft::Settings;
    ///
    /// let s = Settings { dt: 0.01, damping: 0.9999, ..Settings::default() };
    /// let fine = s.with_dt(0.005);
    /// assert!((fine.damping * fine.damping - 0.9999).abs() < 1e-15);
    /// assert!((fine.damping_per_second() - s.damping_per_second()).abs() < 1e-12);
    /// ```
    pub fn with_dt(&self, dt: f64) -> Settings {
        let mut s = self.clone();
        if dt.is_finite() && dt > 0.0 && self.dt > 0.0 && self.damping != 1.0 {
            s.damping = self.damping.powf(dt / self.dt);
        }
        s.dt = dt;
        s
    }

    /// The velocity damping over one second, `damping^(1/dt)` (1: none).
    pub fn damping_per_second(&self) -> f64 {
        self.damping.powf(1.0 / self.dt)
    }

    /// The names of the settings, in declaration order.
    pub fn names() -> Vec<String> {
        schema()
            .get("required")
            .and_then(|r| r.as_array())
            .map(|r| r.iter().filter_map(|n| n.as_str().map(str::to_string)).collect())
            .unwrap_or_default()
    }

    /// The documentation of setting `name` on one line (its doc comment above, which is also
    /// its description in the JSON Schemas), for help texts.
    pub fn describe(name: &str) -> Option<String> {
        let schema = schema();
        let text = schema.pointer(&format!("/properties/{name}/description"))?.as_str()?;
        Some(text.split_whitespace().collect::<Vec<_>>().join(" "))
    }

    /// The local-global tolerance in metres: `tolerance` is relative to the model's length
    /// scale.
    pub fn absolute_tolerance(&self, model: &Model) -> f64 {
        self.tolerance * model.length_scale()
    }

    /// The inner iterations' tolerance in metres: `inner_tolerance` is relative to the model's
    /// length scale.
    pub fn inner_absolute_tolerance(&self, model: &Model) -> f64 {
        self.inner_tolerance * model.length_scale()
    }

    /// The contact detection margin in metres: `contact_margin` is relative to the model's
    /// length scale.
    pub fn absolute_contact_margin(&self, model: &Model) -> f64 {
        self.contact_margin * model.length_scale()
    }
}

/// The JSON Schema of the settings as written (every field listed as required, in declaration
/// order).
fn schema() -> schemars::Schema {
    let mut settings = schemars::generate::SchemaSettings::default();
    settings.contract = schemars::generate::Contract::Serialize;
    settings.into_generator().into_root_schema_for::<Settings>()
}
