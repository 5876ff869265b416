//! The Coulomb cone projection in relaxation form as the skeleton's rigid-contact solve uses it
//! (`x_hat = x - lambda / w`, `w = 1 / lambda_max(D)` of the contact's Delassus block `D`):
//! iterated on one contact with an anisotropic, normal-tangential coupled `D` it converges to
//! Coulomb's law at the true position.

use diffsoft::contact::{project, Contact};
use nalgebra::{Matrix3, Rotation3, Vector3};
use proptest::prelude::*;

/// Coulomb's law at `x` for impulse `l` (tolerance `tol` in position units).
fn coulomb(x: &Vector3<f64>, l: &Vector3<f64>, c: &Contact, tol: f64) -> Result<(), String> {
    let n = c.normal;
    let gap = n.dot(&(x - c.point));
    let ln = n.dot(l);
    let lt = l - n * ln;
    let rel = x - c.anchor;
    let rt = rel - n * n.dot(&rel);
    if gap < -tol || ln < 0.0 {
        return Err(format!("gap {gap}, lambda_n {ln}"));
    }
    if ln > 0.0 && gap > tol {
        return Err(format!("impulse {ln} with gap {gap}"));
    }
    if lt.norm() > c.friction * ln * (1.0 + 1e-9) + 1e-15 {
        return Err(format!("outside the cone: {} > {}", lt.norm(), c.friction * ln));
    }
    if lt.norm() < c.friction * ln * (1.0 - 1e-6) {
        if rt.norm() > tol {
            return Err(format!("inside the cone but slipping {}", rt.norm()));
        }
    } else if rt.norm() > tol && rt.normalize().dot(&lt.normalize()) > -1.0 + 1e-6 {
        return Err(format!("slip {rt:?} not opposite to friction {lt:?}"));
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn relaxation_converges_to_coulombs_law(
        log_eigs in prop::array::uniform3(-1.0f64..1.0),
        axis in prop::array::uniform3(-3.0f64..3.0),
        x0 in prop::array::uniform3(-1.0f64..1.0),
        anchor in prop::array::uniform2(-0.5f64..0.5),
        friction in 0.0f64..1.5,
    ) {
        // D = R diag(e) R^T, anisotropy up to 100.
        let r = Rotation3::from_scaled_axis(Vector3::from(axis));
        let d = r.matrix()
            * Matrix3::from_diagonal(&Vector3::from(log_eigs.map(|e| 10f64.powf(e))))
            * r.matrix().transpose();
        let n = Vector3::y();
        let c = Contact {
            vertex: 0,
            obstacle: 0,
            normal: n,
            point: Vector3::zeros(),
            anchor: Vector3::new(anchor[0], 0.0, anchor[1]),
            friction,
        };
        let x_free = Vector3::from(x0);
        let w = 1.0 / d.symmetric_eigenvalues().max();
        let mut l = Vector3::zeros();
        let mut converged = false;
        for _ in 0..20_000 {
            let x = x_free + d * l;
            let (new, _) = project(&(x - l / w), w, &c);
            let change = (d * (new - l)).norm();
            l = new;
            if change < 1e-13 {
                converged = true;
                break;
            }
        }
        prop_assert!(converged, "no convergence");
        let x = x_free + d * l;
        prop_assert!(coulomb(&x, &l, &c, 1e-9).is_ok(), "{:?}", coulomb(&x, &l, &c, 1e-9));
    }
}
