//! The validation suite's fast subset: the engine against closed forms of continuum mechanics
//! (docs/validation.md), run as `cargo test` runs it.

use std::sync::OnceLock;

use diffsoft_harness::validation::{self, Case, Status, Subset, ValidationReport};

fn report() -> &'static ValidationReport {
    static R: OnceLock<ValidationReport> = OnceLock::new();
    R.get_or_init(|| validation::run(Subset::Fast, &[]))
}

fn case(id: &str) -> &'static Case {
    report()
        .cases
        .iter()
        .find(|c| c.id == id)
        .unwrap_or_else(|| panic!("case {id} is in the fast subset"))
}

#[test]
fn every_fast_case_comes_out_as_expected() {
    let r = report();
    let off: Vec<String> = r
        .cases
        .iter()
        .filter(|c| !c.as_expected())
        .map(|c| format!("{}: {:?} {}", c.id, c.status, c.reason.clone().unwrap_or_default()))
        .collect();
    assert!(off.is_empty(), "{}", off.join("\n"));
    assert_eq!(r.summary.not_run, 0);
    assert_eq!(r.summary.fails_unexpectedly, 0);
    assert!(r.summary.holds >= 24, "{} cases hold", r.summary.holds);
}

#[test]
fn the_patch_test_passes_for_every_model() {
    for model in ["projective", "corotated", "neo_hookean"] {
        let c = case(&format!("patch_test.affine.{model}"));
        assert_eq!(c.status, Status::Holds, "{model}");
        // Interior vertices on the affine field to Newton's tolerance, far below any
        // discretisation error (linear tets represent an affine field exactly).
        assert!(c.error.unwrap() < 1e-9, "{model}: {:?}", c.error);
    }
}

/// The claim: at nu = 0.3 the true models match `rho g L^2 / (2E)` and the axial
/// frequency `sqrt(E / rho) / (4L)` (after the integrator's exact frequency factor) to 1% at small
/// strain; the projective model misses both by the factor `E / E_eff = 1 + 2 nu / 3` (resp. its
/// square root) and matches `E_eff`.
#[test]
fn true_models_mean_their_moduli_and_the_projective_model_means_e_eff() {
    for model in ["corotated", "neo_hookean"] {
        for id in [
            format!("hanging_bar.small_nu03.{model}"),
            format!("vibration.axial_implicit_euler_wh0.1.frequency.{model}"),
            format!("vibration.axial_bdf2_wh0.5.frequency.{model}"),
        ] {
            let c = case(&id);
            assert_eq!(c.moduli, "E, nu", "{id}");
            assert!(c.error.unwrap() < 0.01, "{id}: relative error {:?}", c.error);
        }
    }
    let bar = case("hanging_bar.small_nu03.projective");
    assert_eq!(bar.status, Status::DoesNotHold);
    assert!(!bar.expected_to_hold);
    // Stretches E / E_eff = 1.2 times the closed form with E (to the clamp's 2%).
    let ratio = bar.measured.unwrap() / bar.reference.unwrap();
    assert!((ratio - 1.2).abs() < 0.024, "projective bar stretches {ratio}x");
    for id in [
        "hanging_bar.small_nu03.projective.eff",
        "vibration.axial_implicit_euler_wh0.1.frequency.projective.eff",
        "vibration.axial_bdf2_wh0.5.frequency.projective.eff",
    ] {
        let c = case(id);
        assert_eq!(c.moduli, "E_eff, nu_eff", "{id}");
        assert_eq!(c.status, Status::Holds, "{id}");
        assert!(c.error.unwrap() < 0.01, "{id}: {:?}", c.error);
    }
}

#[test]
fn integrator_factors_and_elastica_agree_with_the_quoted_tables() {
    let r = report();
    assert!(r.derivations.len() >= 20);
    for d in &r.derivations {
        assert!(d.agrees, "{}: quoted {} derived {}", d.name, d.quoted, d.derived);
    }
}

#[test]
fn the_mapping_states_the_projective_moduli() {
    let r = report();
    let p = r
        .mapping
        .iter()
        .find(|m| diffsoft::base::Choice::name(m.model) == "projective")
        .unwrap();
    assert!((p.youngs_modulus_factor - 1.0 / 1.2).abs() < 1e-12);
    assert!((p.effective_poisson_ratio - 0.3 / 3.6).abs() < 1e-12);
    for m in r
        .mapping
        .iter()
        .filter(|m| diffsoft::base::Choice::name(m.model) != "projective")
    {
        assert_eq!(m.youngs_modulus_factor, 1.0);
        assert_eq!(m.effective_poisson_ratio, 0.3);
    }
}

/// Coulomb friction against the capstan equation with the belt's weight: 5% below the threshold
/// the strip holds (its light end rises by round-off and elastic settling only), 5% above it
/// slides by centimetres.
#[test]
fn the_capstan_sticks_below_its_threshold_and_slides_above() {
    let stick = case("capstan.sticks_near.cloth");
    let slide = case("capstan.slides_near.cloth");
    assert_eq!(stick.status, Status::Holds, "{:?}", stick.reason);
    assert_eq!(slide.status, Status::Holds, "{:?}", slide.reason);
    assert!(stick.measured.unwrap() < 1e-5, "{:?}", stick.measured);
    assert!(slide.measured.unwrap() > 1e-2, "{:?}", slide.measured);
}
