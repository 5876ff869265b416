//! The extreme cases, in report order: name, category, what each does and the outcomes that
//! are correct for it; the runs are in [`super::scenarios`].

use std::f64::consts::PI;

use nalgebra::{Rotation3, Unit, Vector3};

use super::probe::Trial;
use super::scenarios::{
    actuated, free_flight_checks, hinge_at, hinge_checks, impact, impact_checks, invariance, invariance_checks,
    inverted_in_file, inverted_in_file_checks, inverted_start, inverted_start_checks, jelly, jelly_from, sliver,
    sticking, sticking_checks, unvalidated_tet, EDGE,
};
use super::Outcome;
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::mesh::TetMesh;

/// One case.
pub struct Case {
    /// Name.
    pub name: &'static str,
    /// Which extreme.
    pub category: &'static str,
    /// What it does.
    pub description: String,
    /// Outcomes that are correct.
    pub expected: Vec<Outcome>,
    /// Steps it takes.
    pub steps: usize,
    /// Part of the fast subset.
    pub fast: bool,
    /// The quantities of the checks its run records when it ends stable, in order (a run that
    /// ends otherwise records some of them, in the same order, or none): what a report's case
    /// is held to ([`super::check_set`]), so a result that lost or renamed a check is not taken.
    pub checks: Vec<String>,
    /// Run it.
    pub run: Box<dyn Fn() -> Trial + Send + Sync>,
}

fn material_case(name: &'static str, category: &'static str, e: f64, rho: f64, dt: f64, steps: usize) -> Case {
    Case {
        name,
        category,
        description: format!(
            "jittered 48-tet cube, E {e:e} Pa, density {rho:e} kg/m^3, spinning at 6 rad/s and stretching, free flight under gravity, {steps} steps of {dt:e} s (certified split solver, cap 30, tolerance 1e-6)"
        ),
        expected: vec![Outcome::Stable],
        steps,
        fast: true,
        checks: free_flight_checks(),
        run: Box::new(move || jelly(e, rho, dt, steps, 6.0)),
    }
}

fn rejected_case(name: &'static str, category: &'static str, what: &str, e: f64, rho: f64, dt: f64) -> Case {
    Case {
        name,
        category,
        description: format!("{what}: must be refused with a message"),
        expected: vec![Outcome::RejectedInput],
        steps: 1,
        fast: true,
        checks: free_flight_checks(),
        run: Box::new(move || jelly(e, rho, dt, 1, 6.0)),
    }
}

fn stable(
    name: &'static str,
    category: &'static str,
    description: &str,
    steps: usize,
    fast: bool,
    checks: Vec<String>,
    run: impl Fn() -> Trial + Send + Sync + 'static,
) -> Case {
    Case {
        name,
        category,
        description: description.to_string(),
        expected: vec![Outcome::Stable],
        steps,
        fast,
        checks,
        run: Box::new(run),
    }
}

/// The quantity of the rotation-invariance checks.
const ROTATION: &str = "rotation invariance: max |R^T q_rotated - q| / L";
/// The quantity of the translation-invariance checks.
const TRANSLATION: &str = "translation invariance: max |q_translated - offset - q| / L";

/// Every case, in report order.
pub fn all() -> Vec<Case> {
    let r = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(1.0, 2.0, 3.0)), 1e3);
    let offset = Vector3::new(1e6, 1e6, 1e6);
    vec![
        material_case("stiffness_1_pa", "stiffness", 1.0, 1000.0, 0.01, 100),
        material_case("stiffness_1e12_pa", "stiffness", 1e12, 1000.0, 0.01, 100),
        rejected_case("stiffness_0_pa", "stiffness", "Young's modulus 0", 0.0, 1000.0, 0.01),
        material_case("density_1e-3", "density", 1e5, 1e-3, 0.01, 100),
        material_case("density_1e5", "density", 1e5, 1e5, 0.01, 100),
        rejected_case("density_nan", "density", "density NaN", 1e5, f64::NAN, 0.01),
        material_case("dt_1e-7_s", "time step", 1e5, 1000.0, 1e-7, 100),
        material_case("dt_1_s", "time step", 1e5, 1000.0, 1.0, 20),
        rejected_case("dt_0_s", "time step", "time step 0", 1e5, 1000.0, 0.0),
        stable(
            "sliver_tet_quality_1e-7",
            "degenerate tets",
            "two tets, the second a sliver with normalised volume about 1e-7 (above the reader's 1e-9 floor), spinning in free flight",
            50,
            true,
            free_flight_checks(),
            || sliver(1e-7, 50),
        ),
        Case {
            name: "sliver_tet_quality_1e-11",
            category: "degenerate tets",
            description: "the same sliver with normalised volume about 1e-11: the reader must refuse it, naming file, line and tet".into(),
            expected: vec![Outcome::RejectedInput],
            steps: 1,
            fast: true,
            checks: free_flight_checks(),
            run: Box::new(|| sliver(1e-11, 1)),
        },
        Case {
            name: "zero_volume_tet_api",
            category: "degenerate tets",
            description: "a mesh built in code (bypassing the readers) with four coplanar vertices: the model builder must refuse it".into(),
            expected: vec![Outcome::RejectedInput],
            steps: 1,
            fast: true,
            checks: Vec::new(),
            run: Box::new(|| unvalidated_tet(Vector3::new(0.3, 0.3, 0.0))),
        },
        Case {
            name: "inverted_tet_api",
            category: "inverted tets",
            description: "a mesh built in code with a negatively oriented tet: the model builder must refuse it (the readers re-orient instead)".into(),
            expected: vec![Outcome::RejectedInput],
            steps: 1,
            fast: true,
            checks: Vec::new(),
            run: Box::new(|| unvalidated_tet(Vector3::new(0.0, 0.0, -1.0))),
        },
        stable(
            "inverted_tet_in_file",
            "inverted tets",
            "an OBJ whose second tet is listed with negative orientation: re-oriented by the reader, then simulated",
            50,
            true,
            inverted_in_file_checks(),
            inverted_in_file,
        ),
        stable(
            "inverted_initial_state",
            "inverted tets",
            "the 48-tet cube with a corner pushed through its tets (inverted at the start), no gravity, 100 steps",
            100,
            true,
            inverted_start_checks(),
            inverted_start,
        ),
        stable(
            "one_tet",
            "mesh size",
            "a single tet spinning in free flight",
            100,
            true,
            free_flight_checks(),
            || {
                let m = TetMesh::new(
                    vec![Vector3::zeros(), Vector3::x() * EDGE, Vector3::y() * EDGE, Vector3::z() * EDGE],
                    vec![[0, 1, 2, 3]],
                )
                .expect("a valid tet");
                jelly_from(m, 100)
            },
        ),
        stable(
            "tets_1e5",
            "mesh size",
            "a 26^3-cell cube (105 456 tets, 19 683 vertices) spinning in free flight, 2 steps (certification by Lanczos)",
            2,
            false,
            free_flight_checks(),
            || {
                let m = BoxSpec::new([26; 3], [EDGE; 3]).build().expect("valid box");
                jelly_from(m, 2)
            },
        ),
        stable(
            "rotation_1e3_rad",
            "rigid motion",
            "the spinning cube and its gravity rotated by 1000 rad about (1,2,3): the trajectory must be the rotated one",
            50,
            true,
            invariance_checks(ROTATION),
            move || {
                invariance(
                    ROTATION,
                    |x| r * x,
                    |x| r * x,
                    |x| r.inverse() * x,
                    "the corotated projection and L (x) I3 commute with rotations",
                )
            },
        ),
        stable(
            "translation_1e6_m",
            "rigid motion",
            "the spinning cube translated by (1e6, 1e6, 1e6) m: the trajectory must be the translated one to the precision of coordinates near 1e6 m",
            50,
            true,
            invariance_checks(TRANSLATION),
            move || {
                invariance(
                    TRANSLATION,
                    |x| x + offset,
                    |x| *x,
                    |x| x - offset,
                    "PD is translation invariant; coordinates near 1e6 m resolve about 1e-10 m",
                )
            },
        ),
        stable(
            "spin_1e3_rad_per_s",
            "rigid motion",
            "the cube spinning at 1000 rad/s (10 rad per step) in free flight, 50 steps",
            50,
            true,
            free_flight_checks(),
            || jelly(1e5, 1000.0, 0.01, 50, 1e3),
        ),
        stable(
            "muscle_activation_0",
            "activation",
            "beam with a muscle layer held at activation 0 (fibres at rest length)",
            50,
            true,
            Vec::new(),
            || actuated("contract", 0.0),
        ),
        stable(
            "muscle_activation_1",
            "activation",
            "beam with a muscle layer held at activation 1 (fibres pulled to zero length)",
            50,
            true,
            Vec::new(),
            || actuated("contract", 1.0),
        ),
        stable(
            "pneumatic_activation_1",
            "activation",
            "beam with a pneumatic layer held at activation 1 (rest volume)",
            50,
            true,
            Vec::new(),
            || actuated("inflate", 1.0),
        ),
        Case {
            name: "pneumatic_activation_0",
            category: "activation",
            description: "pneumatic layer at activation 0 (zero target volume): must be refused with a message (pneumatic activations are > 0)".into(),
            expected: vec![Outcome::RejectedInput],
            steps: 50,
            fast: true,
            checks: Vec::new(),
            run: Box::new(|| actuated("inflate", 0.0)),
        },
        stable(
            "pneumatic_activation_1e-6",
            "activation",
            "pneumatic layer at activation 1e-6 (cells pulled towards zero volume)",
            50,
            true,
            Vec::new(),
            || actuated("inflate", 1e-6),
        ),
        stable(
            "joint_angle_near_pi",
            "joint angle",
            "block on a hinge released upside down at pi - 1e-6 with a nudge: falls through +-pi",
            100,
            true,
            hinge_checks(),
            || hinge_at(PI - 1e-6),
        ),
        stable(
            "joint_angle_near_minus_pi",
            "joint angle",
            "block on a hinge released at -pi + 1e-6",
            100,
            true,
            hinge_checks(),
            || hinge_at(-PI + 1e-6),
        ),
        stable(
            "joint_angle_pi",
            "joint angle",
            "block on a hinge released at exactly pi",
            100,
            true,
            hinge_checks(),
            || hinge_at(PI),
        ),
        stable(
            "contact_1e3_m_per_s_plane",
            "contact speed",
            "cube thrown at 1000 m/s (10 m per step) at a ground plane, 20 steps",
            20,
            true,
            impact_checks(),
            || impact(1e3, None),
        ),
        stable(
            "contact_1e5_m_per_s_plane",
            "contact speed",
            "cube thrown at 1e5 m/s (1 km per step) at a ground plane, 20 steps",
            20,
            true,
            impact_checks(),
            || impact(1e5, None),
        ),
        stable(
            "tunnelling_1e3_m_per_s_plate",
            "contact speed",
            "cube thrown at 1000 m/s at a two-sided two-triangle plate of thickness 1e-4 m (the paper's), 20 steps",
            20,
            true,
            impact_checks(),
            || impact(1e3, Some(1e-4)),
        ),
        stable(
            "tunnelling_1e5_m_per_s_plate",
            "contact speed",
            "the same at 1e5 m/s",
            20,
            true,
            impact_checks(),
            || impact(1e5, Some(1e-4)),
        ),
        Case {
            name: "plate_zero_thickness",
            category: "contact speed",
            description: "a two-sided plate of zero thickness: a vertex resting on it is on neither side, and round-off let the cube fall through it; must be refused with a message".into(),
            expected: vec![Outcome::RejectedInput],
            steps: 20,
            fast: true,
            checks: impact_checks(),
            run: Box::new(|| impact(1e3, Some(0.0))),
        },
        stable(
            "friction_1e3",
            "friction",
            "cube resting on the ground (its jittered bottom layer flattened onto it) with friction 1e3 under gravity tilted by 30 degrees (must stick; a cube tips over beyond 45)",
            60,
            true,
            sticking_checks(),
            || sticking(1e3),
        ),
        stable(
            "friction_1e12",
            "friction",
            "the same with friction 1e12",
            60,
            true,
            sticking_checks(),
            || sticking(1e12),
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique() {
        let c = all();
        for (i, a) in c.iter().enumerate() {
            assert!(c[..i].iter().all(|b| b.name != a.name), "{}", a.name);
        }
    }

    #[test]
    fn sliver_quality_brackets_the_reader_floor() {
        // Normalised volume 6 sqrt(2) V / l_rms^3 of the second tet.
        let q = |h: f64| {
            let m = diffsoft::mesh::parse_str("s.obj", &super::super::scenarios::sliver_text(h));
            m.map(|_| ()).map_err(|e| e.to_string())
        };
        assert!(q(1e-7).is_ok());
        let e = q(1e-11).unwrap_err();
        assert!(
            e.contains("s.obj") && e.contains("tet 1") && e.contains("degenerate"),
            "{e}"
        );
    }

    #[test]
    fn solver_errors_are_classified() {
        use diffsoft::solver::SolverError;
        let c = super::super::probe::classify;
        assert_eq!(c(&SolverError::Diverged("x".into())), Outcome::DetectedDivergence);
        assert_eq!(c(&SolverError::Input("x".into())), Outcome::RejectedInput);
    }
}
