//! The skeleton checks: every joint's `dA/dz_k` and every column of `B = dq/dz`, against dual
//! numbers and central differences with the fixed tolerances [`DUAL_TOL`] and [`FD_TOL`].

use nalgebra::Matrix4;

use super::{JacobianCheck, DUAL_TOL, FD_TOL};
use crate::fd::{compare, sweep};
use diffsoft::skeleton::{Joint, Skeleton};

fn flat(m: &Matrix4<f64>) -> Vec<f64> {
    m.iter().copied().collect()
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
                versus_dual: compare(&analytic, &dual, DUAL_TOL.atol, DUAL_TOL.rtol),
                versus_fd: compare(&analytic, &s.best_difference, FD_TOL.atol, FD_TOL.rtol),
                sweep: s,
                condition: None,
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
                versus_dual: compare(&analytic, &dual, DUAL_TOL.atol, DUAL_TOL.rtol),
                versus_fd: compare(&analytic, &s.best_difference, FD_TOL.atol, FD_TOL.rtol),
                sweep: s,
                condition: None,
            }
        })
        .collect()
}
