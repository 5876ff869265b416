//! Jacobian checks of the skeleton and the actuators (`diffsoft jacobians`,
//! `reports/jacobians.json`, schema `diffsoft.jacobians/2`):
//!
//! * every joint type's `dA/dz_k` against forward-mode dual numbers (num-dual) and against
//!   central differences with a step sweep, at random configurations including angles at
//!   `+-pi` and large prismatic extensions;
//! * every column of `B = dq/dz` (Eqs. 12-16) for mixed chains at least four joints deep;
//! * the rotational update across `+-pi` (Eq. 35) and the root update's projection onto the
//!   rotations (Eq. 10);
//! * the actuators (docs/method.md section 5, Eqs. 39-40; [`diffsoft::kernel::actuator`]): for the
//!   pneumatic cell `dR/dF`, `dR/da`, the nearest product's log-log Jacobian
//!   `d ln x / d ln(s, a)` and `dPsi/dF`; for the muscle fibre `dp/dF`, `dp/da` and `dPsi/dF`;
//!   each against dual numbers (an independent one-sided Jacobi SVD and Newton in dual
//!   arithmetic) and a step sweep, at random, inverted (`det F < 0`) and wide (singular values
//!   `1e4 .. 1e-4`) `F`, pneumatic `a in {1e-6, 0.5, 1, 2}`, muscle `a in {1e-6, 0.5, 1 - 1e-6}`
//!   and fibres of length `1e-4 .. 1e4`; plus the constraint residuals
//!   `max |prod x - a| / a` and `max ||p| - (1 - a)|` over random `F`.
//!
//! The skeleton checks use the fixed tolerances [`DUAL_TOL`] and [`FD_TOL`]. The actuator checks
//! span eight decades of conditioning, so their tolerances are derived per configuration
//! ([`check_pneumatic`], [`check_muscle`]): `ACTUATOR_SAFETY = 100` times the predicted
//! round-off of the two computations (against dual numbers) or the predicted best error of
//! central differences, [`fd_floor`] (against differences), from the scale `M` of the values,
//! the conditioning `max|J|`, and the distance `L` to the nearest pole of the Jacobian
//! ([`pneumatic_scales`]). Each check records the condition number `M / L` it used
//! (`condition`); at `M / L ~ 1` the tolerances are about `1e-14` and `1e-8` relative to
//! `max|J|`.

mod actuators;
mod joints;

use nalgebra::{Rotation3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::fd::{Comparison, StepSweep};
use crate::report::{Header, Verdict};
use diffsoft::skeleton::free::Free;
use diffsoft::skeleton::prismatic::Prismatic;
use diffsoft::skeleton::rotational::Rotational;
use diffsoft::skeleton::Joint;
pub use diffsoft::testing::random_chain;
use diffsoft::testing::unit;

pub use actuators::{
    actuator_checks, check_muscle, check_pneumatic, fd_floor, pneumatic_scales, sweep_scale, with_singular_values,
    ACTUATOR_SAFETY, MUSCLE_ACTIVATIONS, PNEUMATIC_ACTIVATIONS,
};
pub use joints::{check_jacobian, check_joint};

/// Schema of the report.
pub const SCHEMA: &str = "diffsoft.jacobians/3";
/// Tolerances against dual numbers (both exact up to round-off).
pub const DUAL_TOL: Tolerance = Tolerance {
    atol: 1e-12,
    rtol: 1e-10,
};
/// Tolerances against central differences at the best step.
pub const FD_TOL: Tolerance = Tolerance { atol: 1e-7, rtol: 1e-6 };

/// A comparison passes where `|analytic - reference| <= atol + rtol |reference|` entrywise.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, schemars::JsonSchema)]
pub struct Tolerance {
    /// Absolute tolerance (the unit of the compared derivative's entries).
    pub atol: f64,
    /// Relative tolerance (1).
    pub rtol: f64,
}

/// The fixed tolerances of the skeleton checks.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, schemars::JsonSchema)]
pub struct Tolerances {
    /// Against dual numbers ([`DUAL_TOL`]).
    pub versus_dual: Tolerance,
    /// Against central differences at the best step ([`FD_TOL`]).
    pub versus_fd: Tolerance,
}

/// One derivative check.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct JacobianCheck {
    /// What is checked.
    pub name: String,
    /// The configuration, in words.
    pub configuration: String,
    /// Entries compared.
    pub entries: usize,
    /// Against dual numbers.
    pub versus_dual: Comparison,
    /// Against central differences at the best step.
    pub versus_fd: Comparison,
    /// The step sweep.
    pub sweep: StepSweep,
    /// Actuator checks: the condition number the tolerances are derived from (1; `M / L`, see the
    /// module doc); absent for the skeleton checks.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub condition: Option<f64>,
}

impl JacobianCheck {
    /// Both comparisons pass.
    pub fn pass(&self) -> bool {
        self.versus_dual.pass && self.versus_fd.pass
    }
}

/// The rotational update across the branch cut.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct AngleWrapCheck {
    /// Start angle (rad).
    pub from: f64,
    /// Increment (1: the update adds `atan(increment)` to the angle).
    pub increment: f64,
    /// Angle after the update (rad, in `(-pi, pi]`).
    pub to: f64,
    /// `|A(to) - A(from + atan(increment))|_max` (1): the transform is continuous across the cut.
    pub transform_jump: f64,
    /// In range and continuous.
    pub pass: bool,
}

/// The root update stays a rotation.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct RootUpdateCheck {
    /// Updates applied (random rotations up to 1 rad, translations up to 1e3).
    pub updates: usize,
    /// Largest `|R^T R - I|_max` after an update (1).
    pub max_orthogonality_error: f64,
    /// Largest `|det R - 1|` (1).
    pub max_det_error: f64,
    /// Both below 1e-12.
    pub pass: bool,
}

/// The actuator constraints are met: `prod sigma(R) = a` and `|p| = 1 - a`.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct ActuatorConstraintCheck {
    /// Pneumatic projections evaluated (random `F`, half inverted, singular values log-uniform
    /// in `[1e-4, 1e4]`, `a in {1e-6, 0.5, 1, 2}`).
    pub pneumatic_cases: usize,
    /// `max |x_1 x_2 x_3 - a| / a` over them (1; `x` the singular values `R` is composed from).
    pub max_product_rel_error: f64,
    /// Muscle targets evaluated (the same `F`, random unit `m`, `a in {0, 1e-6, 0.5, 1}`).
    pub muscle_cases: usize,
    /// `max ||p| - (1 - a)|` over them (1: `p` is a stretch).
    pub max_fibre_length_error: f64,
    /// Both below 1e-12 and no projection failed.
    pub pass: bool,
}

/// `reports/jacobians.json`.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct JacobiansReport {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// Seed of the random configurations.
    pub seed: u64,
    /// Tolerances of the skeleton checks against dual numbers and against finite differences.
    pub tolerances: Tolerances,
    /// Derivative checks.
    pub checks: Vec<JacobianCheck>,
    /// Angle updates across `+-pi`.
    pub angle_wrap: Vec<AngleWrapCheck>,
    /// Root updates.
    pub root_update: RootUpdateCheck,
    /// Residuals of the actuator constraints.
    pub actuator_constraints: ActuatorConstraintCheck,
    /// Claims.
    pub verdicts: Vec<Verdict>,
}

/// Run every check with configurations drawn from `seed`.
pub fn run(seed: u64) -> JacobiansReport {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut checks = Vec::new();
    // Rotational joints at random, at +-pi and at 0.
    for (label, angle) in [
        ("random angle", rng.random_range(-3.0..3.0)),
        ("angle pi - 1e-9", std::f64::consts::PI - 1e-9),
        ("angle -pi + 1e-9", -std::f64::consts::PI + 1e-9),
        ("angle 0", 0.0),
    ] {
        let mut r = Rotational::new(
            Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 0.5),
            unit(&mut rng),
        );
        r.angle = angle;
        checks.extend(check_joint(&r, "rotational", label, 1.0));
    }
    for (label, ext) in [("extension 0.3", 0.3), ("extension 1e4", 1e4), ("extension -1e6", -1e6)] {
        let mut p = Prismatic::new(unit(&mut rng));
        p.extension = ext;
        checks.extend(check_joint(&p, "prismatic", label, 1.0));
    }
    let root = Free {
        rotation: *Rotation3::from_scaled_axis(unit(&mut rng) * 2.5).matrix(),
        translation: Vector3::new(1e3, -2e2, 3.0),
    };
    checks.extend(check_joint(
        &root,
        "free root",
        "rotation 2.5 rad, translation ~1e3",
        1.0,
    ));
    // Chains at least four joints deep, mixed types.
    for (label, depth, near_pi, long) in [
        ("chain of 4, random", 4, false, false),
        ("chain of 5, angles at +-pi", 5, true, false),
        ("chain of 6, extensions ~1e3", 6, false, true),
    ] {
        let sk = random_chain(depth, &mut rng, near_pi, long);
        checks.extend(check_jacobian(&sk, "B", label));
    }
    // Angle update across the cut.
    let mut angle_wrap = Vec::new();
    for (from, inc) in [
        (std::f64::consts::PI - 1e-3, 2e-3),
        (-std::f64::consts::PI + 1e-3, -2e-3),
        (3.0, 0.5),
        (-3.0, -0.5),
    ] {
        let mut r = Rotational::new(Vector3::zeros(), Vector3::new(0.3, -0.4, 0.87));
        r.angle = from;
        let expected = r.transform_at(from + f64::atan(inc));
        r.update(&[inc]);
        let jump = (r.transform() - expected).amax();
        angle_wrap.push(AngleWrapCheck {
            from,
            increment: inc,
            to: r.angle,
            transform_jump: jump,
            pass: r.angle > -std::f64::consts::PI && r.angle <= std::f64::consts::PI && jump < 1e-12,
        });
    }
    // Root updates.
    let mut root = Free::default();
    let (mut orth, mut det) = (0.0f64, 0.0f64);
    let updates = 1000;
    for _ in 0..updates {
        let w = unit(&mut rng) * rng.random_range(0.0..1.0);
        let l = unit(&mut rng) * rng.random_range(0.0..1e3);
        root.update(&[w.x, w.y, w.z, l.x, l.y, l.z]);
        orth = orth.max((root.rotation.transpose() * root.rotation - nalgebra::Matrix3::identity()).amax());
        det = det.max((root.rotation.determinant() - 1.0).abs());
    }
    let root_update = RootUpdateCheck {
        updates,
        max_orthogonality_error: orth,
        max_det_error: det,
        pass: orth < 1e-12 && det < 1e-12,
    };
    let (actuator, actuator_constraints) = actuator_checks(&mut rng);
    let joint_checks: Vec<&JacobianCheck> = checks.iter().filter(|c| !c.name.starts_with("B")).collect();
    let chain_checks: Vec<&JacobianCheck> = checks.iter().filter(|c| c.name.starts_with("B")).collect();
    let pneumatic: Vec<&JacobianCheck> = actuator.iter().filter(|c| c.name.starts_with("pneumatic")).collect();
    let muscle: Vec<&JacobianCheck> = actuator.iter().filter(|c| c.name.starts_with("muscle")).collect();
    // Normwise relative error against differences, the largest over the checks.
    let rel_fd = |cs: &[&JacobianCheck]| {
        cs.iter()
            .map(|c| c.versus_fd.max_abs_error / c.sweep.max_abs_difference.max(f64::MIN_POSITIVE))
            .fold(0.0, f64::max)
    };
    let verdicts = vec![
        Verdict::new(
            "dA/dz of rotational, prismatic and free joints matches dual numbers and central differences",
            joint_checks.iter().all(|c| c.pass()),
            Some(joint_checks.iter().map(|c| c.versus_fd.max_rel_error.min(c.versus_fd.max_abs_error)).fold(0.0, f64::max)),
            Some(FD_TOL.rtol),
            "per check: |a - r| <= atol + rtol |r| against both references",
        ),
        Verdict::new(
            "Every column of B (Eqs. 12-16) of mixed chains 4-6 joints deep matches dual numbers and central differences",
            chain_checks.iter().all(|c| c.pass()),
            None,
            None,
            "per check: |a - r| <= atol + rtol |r| against both references",
        ),
        Verdict::new(
            "The rotational update (Eq. 35) keeps the angle in (-pi, pi] and the transform continuous across the cut",
            angle_wrap.iter().all(|a| a.pass),
            Some(angle_wrap.iter().map(|a| a.transform_jump).fold(0.0, f64::max)),
            Some(1e-12),
            "measured = largest transform jump",
        ),
        Verdict::at_most("The root update (Eq. 10) yields a rotation to 1e-12", orth.max(det), 1e-12),
        Verdict::new(
            "Pneumatic cell Jacobians (dR/dF, dR/da, the nearest product's log-log Jacobian, dPsi/dF; Eqs. 39-40) match dual numbers and central differences, including inverted F, a in {1e-6, 0.5, 1, 2} and singular values 1e-4..1e4",
            pneumatic.len() == 4 * 16 && pneumatic.iter().all(|c| c.pass()),
            Some(rel_fd(&pneumatic)),
            None,
            "per check: |a - r| <= atol with atol from the conditioning (module doc); measured = largest max|a - r_FD| / max|r_FD|",
        ),
        Verdict::new(
            "Muscle fibre Jacobians (dp/dF, dp/da, dPsi/dF) match dual numbers and central differences, including inverted F, fibres of length 1e-4..1e4 and a in {1e-6, 0.5, 1 - 1e-6}",
            muscle.len() == 3 * 3 * 6 && muscle.iter().all(|c| c.pass()),
            Some(rel_fd(&muscle)),
            None,
            "per check: |a - r| <= atol with atol from the conditioning (module doc); measured = largest max|a - r_FD| / max|r_FD|",
        ),
        Verdict::new(
            "The actuator constraints are met to 1e-12 (prod sigma(R) = a relative, |p| = 1 - a absolute) and no projection fails",
            actuator_constraints.pass,
            Some(actuator_constraints.max_product_rel_error.max(actuator_constraints.max_fibre_length_error)),
            Some(1e-12),
            "measured <= threshold",
        ),
    ];
    checks.extend(actuator);
    JacobiansReport {
        header: Header::new(SCHEMA),
        seed,
        tolerances: Tolerances {
            versus_dual: DUAL_TOL,
            versus_fd: FD_TOL,
        },
        checks,
        angle_wrap,
        root_update,
        actuator_constraints,
        verdicts,
    }
}
