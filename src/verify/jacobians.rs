//! Jacobian checks of the skeleton (`diffsoft jacobians`, `reports/jacobians.json`):
//!
//! * every joint type's `dA/dz_k` against forward-mode dual numbers (num-dual) and against
//!   central differences with a step sweep, at random configurations including angles at
//!   `+-pi` and large prismatic extensions;
//! * every column of `B = dq/dz` (Eqs. 12-16) for mixed chains at least four joints deep;
//! * the rotational update across `+-pi` (Eq. 35) and the root update's projection onto the
//!   rotations (Eq. 10).

use nalgebra::{Matrix4, Rotation3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::fd::{compare, sweep, Comparison};
use crate::report::{Header, Verdict};
use crate::skeleton::free::Free;
use crate::skeleton::prismatic::Prismatic;
use crate::skeleton::rotational::Rotational;
use crate::skeleton::{BoneSpec, Joint, Skeleton};

/// Schema of the report.
pub const SCHEMA: &str = "diffsoft.jacobians/1";
/// Tolerances against dual numbers (both exact up to round-off).
pub const DUAL_TOL: (f64, f64) = (1e-12, 1e-10);
/// Tolerances against central differences at the best step.
pub const FD_TOL: (f64, f64) = (1e-7, 1e-6);

/// Summary of a step sweep (without the difference vector).
#[derive(Debug, Clone, Serialize)]
pub struct SweepSummary {
    /// Steps.
    pub steps: Vec<f64>,
    /// Largest absolute error at each step.
    pub errors: Vec<f64>,
    /// Best step and its error.
    pub best_step: f64,
    /// Best error.
    pub best_error: f64,
    /// Truncation-side log-log slope (about 2; `null` when the map is linear in the coordinate,
    /// so every step is exact to round-off).
    pub truncation_slope: f64,
    /// Richardson-extrapolated error at the best step.
    pub richardson_error: f64,
}

/// One derivative check.
#[derive(Debug, Clone, Serialize)]
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
    pub sweep: SweepSummary,
}

impl JacobianCheck {
    /// Both comparisons pass.
    pub fn pass(&self) -> bool {
        self.versus_dual.pass && self.versus_fd.pass
    }
}

/// The rotational update across the branch cut.
#[derive(Debug, Clone, Serialize)]
pub struct AngleWrapCheck {
    /// Start angle.
    pub from: f64,
    /// Increment.
    pub increment: f64,
    /// Angle after the update (in `(-pi, pi]`).
    pub to: f64,
    /// `|A(to) - A(from + atan(increment))|_max`: the transform is continuous across the cut.
    pub transform_jump: f64,
    /// In range and continuous.
    pub pass: bool,
}

/// The root update stays a rotation.
#[derive(Debug, Clone, Serialize)]
pub struct RootUpdateCheck {
    /// Updates applied (random rotations up to 1 rad, translations up to 1e3).
    pub updates: usize,
    /// Largest `|R^T R - I|_max` after an update.
    pub max_orthogonality_error: f64,
    /// Largest `|det R - 1|`.
    pub max_det_error: f64,
    /// Both below 1e-12.
    pub pass: bool,
}

/// `reports/jacobians.json`.
#[derive(Debug, Clone, Serialize)]
pub struct JacobiansReport {
    /// Schema and crate version.
    #[serde(flatten)]
    pub header: Header,
    /// Seed of the random configurations.
    pub seed: u64,
    /// Tolerances `(atol, rtol)` against dual numbers and against finite differences.
    pub tolerances: ((f64, f64), (f64, f64)),
    /// Derivative checks.
    pub checks: Vec<JacobianCheck>,
    /// Angle updates across `+-pi`.
    pub angle_wrap: Vec<AngleWrapCheck>,
    /// Root updates.
    pub root_update: RootUpdateCheck,
    /// Claims.
    pub verdicts: Vec<Verdict>,
}

fn flat(m: &Matrix4<f64>) -> Vec<f64> {
    m.iter().copied().collect()
}

fn summary(s: &super::fd::StepSweep) -> SweepSummary {
    SweepSummary {
        steps: s.steps.clone(),
        errors: s.errors.clone(),
        best_step: s.best_step,
        best_error: s.best_error,
        truncation_slope: s.truncation_slope,
        richardson_error: s.richardson_error,
    }
}

/// Check `dA/dz_k` of one joint for every coordinate.
pub fn check_joint(joint: &dyn Joint, name: &str, configuration: &str, scale: f64) -> Vec<JacobianCheck> {
    (0..joint.dofs())
        .map(|k| {
            let analytic = flat(&joint.derivative(k));
            let mut z = vec![num_dual::Dual64::from(0.0); joint.dofs()];
            z[k] = num_dual::Dual64::from(0.0).derivative();
            let dual: Vec<f64> = joint.transform_dual(&z).iter().map(|d| d.eps).collect();
            let f = |h: f64| {
                let mut zz = vec![0.0; joint.dofs()];
                zz[k] = h;
                flat(&joint.transform_after(&zz))
            };
            let s = sweep(&f, &analytic, scale, 10);
            JacobianCheck {
                name: format!("{name}: dA/dz_{k}"),
                configuration: configuration.to_string(),
                entries: analytic.len(),
                versus_dual: compare(&analytic, &dual, DUAL_TOL.0, DUAL_TOL.1),
                versus_fd: compare(&analytic, &s.best_difference, FD_TOL.0, FD_TOL.1),
                sweep: summary(&s),
            }
        })
        .collect()
}

/// Check every column of `B` of a skeleton.
pub fn check_jacobian(sk: &Skeleton, name: &str, configuration: &str) -> Vec<JacobianCheck> {
    let nr = sk.rigid.len();
    let mut b = nalgebra::DMatrix::zeros(3 * nr, sk.dofs);
    sk.jacobian(&mut b);
    (0..sk.dofs)
        .map(|c| {
            let analytic: Vec<f64> = b.column(c).iter().copied().collect();
            let dual: Vec<f64> = sk
                .jacobian_column_dual(c)
                .iter()
                .flat_map(|v| [v.x, v.y, v.z])
                .collect();
            let f = |h: f64| {
                sk.positions_after(c, h)
                    .iter()
                    .flat_map(|v| [v.x, v.y, v.z])
                    .collect::<Vec<f64>>()
            };
            let s = sweep(&f, &analytic, 1.0, 10);
            JacobianCheck {
                name: format!("{name}: column {c} of B"),
                configuration: configuration.to_string(),
                entries: analytic.len(),
                versus_dual: compare(&analytic, &dual, DUAL_TOL.0, DUAL_TOL.1),
                versus_fd: compare(&analytic, &s.best_difference, FD_TOL.0, FD_TOL.1),
                sweep: summary(&s),
            }
        })
        .collect()
}

fn unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if v.norm() > 0.1 {
            return v.normalize();
        }
    }
}

/// A random mixed chain: free root, then alternating rotational and prismatic joints, `depth`
/// joints below the root, each bone owning three random vertices; angles may sit near `+-pi`
/// and extensions may be large.
pub fn random_chain(depth: usize, rng: &mut ChaCha8Rng, near_pi: bool, long: bool) -> Skeleton {
    let mut rest = Vec::new();
    let mut specs = Vec::new();
    let mut next_vertices = |rng: &mut ChaCha8Rng| -> Vec<usize> {
        (0..3)
            .map(|_| {
                rest.push(Vector3::new(
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                ));
                rest.len() - 1
            })
            .collect()
    };
    let root = Free {
        rotation: *Rotation3::from_scaled_axis(unit(rng) * rng.random_range(0.0..3.0)).matrix(),
        translation: Vector3::new(
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
        ),
    };
    specs.push(BoneSpec {
        name: "root".into(),
        parent: None,
        joint: Box::new(root),
        vertices: next_vertices(rng),
        torque: None,
    });
    for d in 0..depth {
        let joint: Box<dyn Joint> = if d % 2 == 0 {
            let mut r = Rotational::new(
                Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ),
                unit(rng),
            );
            r.angle = if near_pi && d % 4 == 0 {
                std::f64::consts::PI - 1e-7
            } else if near_pi {
                -std::f64::consts::PI + 1e-7
            } else {
                rng.random_range(-3.0..3.0)
            };
            Box::new(r)
        } else {
            let mut p = Prismatic::new(unit(rng));
            p.extension = if long {
                rng.random_range(-1e3..1e3)
            } else {
                rng.random_range(-1.0..1.0)
            };
            Box::new(p)
        };
        specs.push(BoneSpec {
            name: format!("bone{}", d + 1),
            parent: Some(d),
            joint,
            vertices: next_vertices(rng),
            torque: None,
        });
    }
    Skeleton::new(specs, &rest).expect("a valid chain")
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
    let joint_checks: Vec<&JacobianCheck> = checks.iter().filter(|c| !c.name.starts_with("B")).collect();
    let chain_checks: Vec<&JacobianCheck> = checks.iter().filter(|c| c.name.starts_with("B")).collect();
    let verdicts = vec![
        Verdict::new(
            "dA/dz of rotational, prismatic and free joints matches dual numbers and central differences",
            joint_checks.iter().all(|c| c.pass()),
            Some(joint_checks.iter().map(|c| c.versus_fd.max_rel_error.min(c.versus_fd.max_abs_error)).fold(0.0, f64::max)),
            Some(FD_TOL.1),
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
    ];
    JacobiansReport {
        header: Header::new(SCHEMA),
        seed,
        tolerances: (DUAL_TOL, FD_TOL),
        checks,
        angle_wrap,
        root_update,
        verdicts,
    }
}
