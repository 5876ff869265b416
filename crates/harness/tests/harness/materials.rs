//! Gradient checks of the hyperelastic material models (corotated, neo_hookean): implicit-mode
//! gradients through Newton's method against the harness's central differences (its step sweep
//! and tolerances, rtol 1e-6) on a free body, a body in frictional ground contact, an actuated
//! body and Baymax with its skeleton and joint torques, every parameter group of each case
//! (Young's modulus and Poisson ratio through the Lame parameters, density, gravity, initial
//! state, activations, torques).

use diffsoft::base::{Choice, MaterialModel};
use diffsoft::testing::{self, Case};
use diffsoft_harness::gradients;

fn with_model(mut case: Case, model: MaterialModel) -> Case {
    let bodies: Vec<String> = case.model.bodies().iter().map(|b| b.name.clone()).collect();
    for b in bodies {
        case.model.set_material_model(&b, model).unwrap();
    }
    case.name = format!("{}_{}", case.name, model.name());
    testing::with_newton(case)
}

fn check(case: Case) {
    let c = gradients::check_case(&case, 11);
    eprint!("{}", gradients::checks_table(std::slice::from_ref(&c)));
    assert!(c.error.is_none(), "{}: {:?}", case.name, c.error);
    assert!(c.passes, "{}: a group fails", case.name);
}

#[test]
fn hyperelastic_gradients_of_a_free_body_match_finite_differences() {
    for m in [MaterialModel::Corotated, MaterialModel::NeoHookean] {
        check(with_model(testing::free_body(4).unwrap(), m));
    }
}

/// With contacts Newton's friction states settle through a fixed point weighted by the
/// diagonal of `A`, whose hyperelastic share is stiffer than the shear response (see
/// `model::HyperTets::weight`): up to a few hundred iterations on some steps, hence the cap.
/// Ten steps (landing and sliding): by step 15 a contact of the neo-Hookean box sits at the
/// stick/slip threshold, where central differences straddle the kink (7.9e-6 off there).
#[test]
fn hyperelastic_gradients_with_ground_contact_match_finite_differences() {
    for m in [MaterialModel::Corotated, MaterialModel::NeoHookean] {
        let mut case = with_model(testing::ground_contact(10).unwrap(), m);
        case.settings.max_iterations = 1000;
        check(case);
    }
}

#[test]
fn hyperelastic_gradients_of_an_actuated_body_match_finite_differences() {
    for m in [MaterialModel::Corotated, MaterialModel::NeoHookean] {
        check(with_model(testing::actuated(3).unwrap(), m));
    }
}

#[test]
fn hyperelastic_gradients_of_baymax_with_torques_match_finite_differences() {
    let path = diffsoft::testing::root().join("verification/scenes/baymax_skeleton.json");
    for m in [MaterialModel::Corotated, MaterialModel::NeoHookean] {
        check(with_model(testing::baymax_torques(&path, 3).unwrap(), m));
    }
}
