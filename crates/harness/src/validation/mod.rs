//! The validation suite: the engine against closed forms of continuum mechanics that nobody
//! here wrote (`diffsoft validate`, `reports/validation.json`, docs/validation.md).
//!
//! Each case states its setup, the closed form with its formula and source, the measured value,
//! the error and a verdict with its tolerance ([`case::Case`]); where discretisation error
//! matters, a refinement series with the observed order. A case that does not hold is reported
//! as not holding, with the reason; a case that cannot run is reported as not run, with the
//! reason. The cases are independent and run in parallel.
//!
//! * [`statics`]: the patch test, the bar hanging under its own weight, the cantilever;
//! * [`elastica`]: large deflection of the cantilever under self-weight;
//! * [`vibration`]: axial, bending and torsional frequencies after the integrators' exact
//!   amplitude and frequency factors;
//! * [`hertz`]: the contact radius of a ball resting on the ground;
//! * [`capstan`]: Coulomb friction of a cloth strip over a cylinder (Euler-Eytelwein);
//! * [`closed`]: the closed forms, computed independently of the engine.

pub mod capstan;
pub mod case;
pub mod closed;
pub mod common;
pub mod elastica;
pub mod hertz;
pub mod statics;
pub mod vibration;

use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::report::{Header, Verdict};
pub use case::{Case, Status};
use closed::{Scheme, ELASTICA_TABLE, FACTOR_TABLE};
use diffsoft::base::MaterialModel;

/// Schema of `reports/validation.json`.
pub const SCHEMA: &str = "diffsoft.validation/1";

/// The studies of the suite, in report order.
pub const STUDIES: [&str; 7] = [
    "patch_test",
    "hanging_bar",
    "cantilever",
    "elastica",
    "vibration",
    "hertz",
    "capstan",
];

/// How much of the suite to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Subset {
    /// Every case (the main job).
    Full,
    /// The cases the tests run (a few seconds).
    Fast,
}

diffsoft::choice!(Subset {
    Full => "full",
    Fast => "fast",
});

/// The material mapping of one model: the parameters given and the small-strain moduli the model
/// responds with.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Mapping {
    /// The model.
    pub model: MaterialModel,
    /// Poisson ratio given (1).
    pub poisson_ratio: f64,
    /// Small-strain Young's modulus over the given `E` (1).
    pub youngs_modulus_factor: f64,
    /// Small-strain Poisson ratio (1).
    pub effective_poisson_ratio: f64,
}

/// A reference value of the notes against its derivation here.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Derivation {
    /// What it is (`implicit_euler amplitude at omega h = 0.1`, ...).
    pub name: String,
    /// The value in the reference notes.
    pub quoted: f64,
    /// The value derived here.
    pub derived: f64,
    /// Whether they agree to the quoted digits (within half a unit of the last).
    pub agrees: bool,
}

/// `reports/validation.json`: the engine against closed forms.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct ValidationReport {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// Which subset ran.
    pub subset: Subset,
    /// The studies that ran.
    pub studies: Vec<String>,
    /// Wall time of the suite (s).
    pub wall_time_s: f64,
    /// The small-strain moduli of each model with `(E, nu)`.
    pub mapping: Vec<Mapping>,
    /// The closed forms computed here against the values of the reference notes (integrator
    /// factors, elastica).
    pub derivations: Vec<Derivation>,
    /// The cases.
    pub cases: Vec<Case>,
    /// Counts: cases holding, not holding as expected, not holding unexpectedly, not run.
    pub summary: Summary,
    /// The suite's claims.
    pub verdicts: Vec<Verdict>,
}

/// How the cases came out.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Summary {
    /// Cases.
    pub cases: usize,
    /// Cases that hold.
    pub holds: usize,
    /// Cases that do not hold, as expected (the projective model against `E, nu`).
    pub fails_as_expected: usize,
    /// Cases that do not hold although expected to.
    pub fails_unexpectedly: usize,
    /// Cases not run.
    pub not_run: usize,
}

/// Whether `derived` rounds to `quoted` at the quoted number's last decimal.
fn agrees(quoted: f64, decimals: i32, derived: f64) -> bool {
    (derived - quoted).abs() <= 0.5 * 10f64.powi(-decimals) * (1.0 + 1e-9)
}

impl Derivation {
    /// `derived` against the value `quoted` to `decimals` decimals.
    fn new(name: String, quoted: f64, decimals: i32, derived: f64) -> Self {
        Self {
            name,
            quoted,
            derived,
            agrees: agrees(quoted, decimals, derived),
        }
    }
}

fn derivations() -> Vec<Derivation> {
    let mut out = Vec::new();
    for (wh, ie_a, ie_f, bdf_a, bdf_f) in FACTOR_TABLE {
        let ie = Scheme::ImplicitEuler.factors(wh);
        let bdf = Scheme::Bdf2.factors(wh);
        for (name, quoted, decimals, derived) in [
            ("implicit_euler amplitude per period", ie_a, 4, ie.amplitude_per_period),
            ("implicit_euler frequency ratio", ie_f, 5, ie.frequency_ratio),
            ("bdf2 amplitude per period", bdf_a, 4, bdf.amplitude_per_period),
            ("bdf2 frequency ratio", bdf_f, 5, bdf.frequency_ratio),
        ] {
            out.push(Derivation::new(
                format!("{name} at omega h = {wh}"),
                quoted,
                decimals,
                derived,
            ));
        }
    }
    for (alpha, v, u, th) in ELASTICA_TABLE {
        let e = closed::elastica(alpha);
        for (name, quoted, decimals, derived) in [
            ("elastica v/L", v, 5, e.tip_deflection),
            ("elastica (L-x)/L", u, 5, e.tip_shortening),
            ("elastica tip rotation (rad)", th, 4, e.tip_rotation),
        ] {
            out.push(Derivation::new(
                format!("{name} at alpha = {alpha}"),
                quoted,
                decimals,
                derived,
            ));
        }
    }
    out
}

type Job = Box<dyn Fn() -> Vec<Case> + Send + Sync>;

/// The jobs of `study` in `subset`. The fast subset (the tests') runs the patch test, the
/// hanging bar and two axial vibrations per model: the cases that hold on coarse meshes. The
/// cantilever needs the full refinement series to leave locking behind.
fn jobs(study: &str, subset: Subset) -> Vec<Job> {
    let fast = subset == Subset::Fast;
    let mut out: Vec<Job> = Vec::new();
    for model in common::models() {
        match study {
            "patch_test" => out.push(Box::new(move || vec![statics::patch_test(model)])),
            "hanging_bar" => out.push(Box::new(move || statics::hanging_bar(model))),
            "cantilever" if !fast => out.push(Box::new(move || {
                statics::cantilever(model, &statics::CANTILEVER_LEVELS)
            })),
            "elastica" if !fast => out.push(Box::new(move || elastica::cases(model))),
            "vibration" => out.push(Box::new(move || vibration::cases(model, fast))),
            "hertz" if !fast => out.push(Box::new(move || hertz::cases(model))),
            _ => {}
        }
    }
    if study == "capstan" {
        for (variant, ratio) in capstan::variants(fast) {
            out.push(Box::new(move || vec![capstan::case(variant, ratio)]));
        }
    }
    out
}

/// The studies of `studies` that have no case in `subset` (the long ones run only in the full
/// subset): a selection naming one runs nothing for it, which the command line refuses.
///
/// ```
/// use diffsoft_harness::validation::{empty_studies, Subset};
///
/// assert_eq!(empty_studies(Subset::Fast, &["hertz".into(), "patch_test".into()]), ["hertz"]);
/// assert!(empty_studies(Subset::Full, &["hertz".into()]).is_empty());
/// ```
pub fn empty_studies(subset: Subset, studies: &[String]) -> Vec<String> {
    studies.iter().filter(|s| jobs(s, subset).is_empty()).cloned().collect()
}

/// Run `studies` (all when empty) of `subset`, in parallel.
pub fn run(subset: Subset, studies: &[String]) -> ValidationReport {
    let t0 = Instant::now();
    let chosen: Vec<String> = if studies.is_empty() {
        STUDIES.iter().map(|s| s.to_string()).collect()
    } else {
        studies.to_vec()
    };
    let all: Vec<Job> = chosen.iter().flat_map(|s| jobs(s, subset)).collect();
    let token = diffsoft::base::cancel::Cancel::current();
    let mut cases: Vec<Case> = all
        .par_iter()
        .flat_map_iter(|job| diffsoft::base::cancel::within(token.as_ref(), job))
        .collect();
    // Report order: by study, then as the jobs listed them.
    let rank = |c: &Case| STUDIES.iter().position(|s| *s == c.study).unwrap_or(usize::MAX);
    cases.sort_by_key(rank);
    let summary = Summary {
        cases: cases.len(),
        holds: cases.iter().filter(|c| c.status == Status::Holds).count(),
        fails_as_expected: cases
            .iter()
            .filter(|c| c.status == Status::DoesNotHold && !c.expected_to_hold)
            .count(),
        fails_unexpectedly: cases
            .iter()
            .filter(|c| c.status == Status::DoesNotHold && c.expected_to_hold)
            .count(),
        not_run: cases.iter().filter(|c| c.status == Status::NotRun).count(),
    };
    let derivations = derivations();
    let verdicts = vec![
        Verdict::new(
            "Every case comes out as expected: the closed form holds for every model with its own small-strain \
             moduli, and the projective model does not match the closed form with E, nu at nu > 0",
            cases.iter().all(Case::as_expected),
            Some(cases.iter().filter(|c| !c.as_expected()).count() as f64),
            Some(0.0),
            "cases not as expected (not run included) == 0",
        ),
        Verdict::new(
            "The integrator factors and the elastica derived here agree with the reference notes to their quoted \
             digits",
            derivations.iter().all(|d| d.agrees),
            Some(derivations.iter().filter(|d| !d.agrees).count() as f64),
            Some(0.0),
            "disagreements == 0",
        ),
    ];
    let material = diffsoft::base::Material {
        youngs_modulus: 1.0,
        poisson_ratio: 0.3,
    };
    ValidationReport {
        header: Header::new(SCHEMA),
        subset,
        studies: chosen,
        wall_time_s: t0.elapsed().as_secs_f64(),
        mapping: common::models()
            .map(|m| {
                let r = m.small_strain_response(material);
                Mapping {
                    model: m,
                    poisson_ratio: material.poisson_ratio,
                    youngs_modulus_factor: r.youngs_modulus,
                    effective_poisson_ratio: r.poisson_ratio,
                }
            })
            .collect(),
        derivations,
        cases,
        summary,
        verdicts,
    }
}

fn short(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.4e}"))
}

/// The report as a table: one line per case.
pub fn table(r: &ValidationReport) -> String {
    let mut s = format!(
        "{:<44} {:<13} {:>11} {:>11} {:>9} {:>8}  {}\n",
        "case", "moduli", "reference", "measured", "error", "tol", "verdict"
    );
    for c in &r.cases {
        let verdict = match c.status {
            Status::Holds => "holds".to_string(),
            Status::DoesNotHold if !c.expected_to_hold => "does not hold (expected)".to_string(),
            Status::DoesNotHold => "DOES NOT HOLD".to_string(),
            Status::NotRun => "not run".to_string(),
        };
        s.push_str(&format!(
            "{:<44} {:<13} {:>11} {:>11} {:>9} {:>8.1e}  {}\n",
            c.id,
            c.moduli,
            short(c.reference),
            short(c.measured),
            c.error.map_or("-".into(), |e| format!("{e:.2e}")),
            c.tolerance,
            verdict
        ));
        if let Some(p) = c.observed_order {
            let levels: Vec<String> = c
                .series
                .iter()
                .map(|l| format!("k={} {:.2}%", l.cells, l.error * 100.0))
                .collect();
            s.push_str(&format!("    series {} | observed order {p:.2}\n", levels.join(", ")));
        }
        if c.status != Status::Holds {
            if let Some(reason) = &c.reason {
                s.push_str(&format!("    {reason}\n"));
            }
        }
    }
    let m = &r.summary;
    s.push_str(&format!(
        "{} cases: {} hold, {} do not hold as expected, {} do not hold unexpectedly, {} not run ({:.1} s)\n",
        m.cases, m.holds, m.fails_as_expected, m.fails_unexpectedly, m.not_run, r.wall_time_s
    ));
    s
}
