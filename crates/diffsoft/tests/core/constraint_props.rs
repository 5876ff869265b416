//! Properties of the constraint kernels: the signed SVD (single, warm-started and batched)
//! against nalgebra, and the volume projection's optimality.

use diffsoft::kernel::svd::{svd3, svd3_nalgebra, svd3_warm, svd3_warm_batch, Svd3, LANES};
use diffsoft::kernel::volume::{nearest_product, nearest_product_batch, nearest_product_batch_warm};
use nalgebra::{Matrix3, Rotation3, Vector3};
use proptest::prelude::*;
use proptest::test_runner::FileFailurePersistence;

/// F = R1 diag(s) R2 with log10 singular values in [-4, 4] and an optional reflection.
fn matrices() -> impl Strategy<Value = Matrix3<f64>> {
    (
        prop::array::uniform3(-4.0f64..4.0),
        prop::array::uniform3(-3.2f64..3.2),
        prop::array::uniform3(-3.2f64..3.2),
        any::<bool>(),
    )
        .prop_map(|(ls, a, b, flip)| {
            let mut s = Vector3::new(10f64.powf(ls[0]), 10f64.powf(ls[1]), 10f64.powf(ls[2]));
            if flip {
                s[2] = -s[2];
            }
            Rotation3::from_scaled_axis(Vector3::from(a)).matrix()
                * Matrix3::from_diagonal(&s)
                * Rotation3::from_scaled_axis(Vector3::from(b)).matrix()
        })
}

/// Singular values (descending) from faer's dense SVD.
fn reference_singular_values(f: &Matrix3<f64>) -> [f64; 3] {
    let m = faer::Mat::<f64>::from_fn(3, 3, |i, j| f[(i, j)]);
    let sv = m.singular_values().expect("faer svd");
    [sv[0], sv[1], sv[2]]
}

fn check_svd(f: &Matrix3<f64>, s: &Svd3) -> Result<(), TestCaseError> {
    let scale = f.norm();
    prop_assert!(
        (s.compose(&s.sigma) - f).norm() <= 1e-12 * scale,
        "reconstruction error {}",
        (s.compose(&s.sigma) - f).norm() / scale
    );
    prop_assert!((s.u.determinant() - 1.0).abs() < 1e-12 && (s.v.determinant() - 1.0).abs() < 1e-12);
    prop_assert!((s.u.transpose() * s.u - Matrix3::identity()).norm() < 1e-12);
    prop_assert!((s.v.transpose() * s.v - Matrix3::identity()).norm() < 1e-12);
    prop_assert!(s.sigma[0] >= s.sigma[1] * (1.0 - 1e-12) && s.sigma[1] >= s.sigma[2].abs() * (1.0 - 1e-12));
    prop_assert_eq!(s.sigma[2] < 0.0, f.determinant() < 0.0);
    // Singular values against faer's dense (backward-stable) SVD, to 1e-12 of the largest.
    // (nalgebra's 3x3 SVD is not a reference: it loses small singular values, see below.)
    let reference = reference_singular_values(f);
    for i in 0..3 {
        prop_assert!(
            (s.sigma[i].abs() - reference[i]).abs() <= 1e-12 * reference[0],
            "{} vs {:?}",
            s.sigma,
            reference
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, failure_persistence: Some(Box::new(FileFailurePersistence::Direct("tests/regressions/constraint_props.txt"))), ..ProptestConfig::default() })]

    #[test]
    fn svd_is_a_signed_rotation_decomposition(f in matrices(), w in prop::array::uniform3(-3.2f64..3.2)) {
        check_svd(&f, &svd3(&f))?;
        let warm = *Rotation3::from_scaled_axis(Vector3::from(w)).matrix();
        check_svd(&f, &svd3_warm(&f, &warm))?;
    }

    #[test]
    fn batched_svd_matches_the_single_one(fs in prop::collection::vec(matrices(), LANES), w in prop::array::uniform3(-3.2f64..3.2)) {
        let fs: [Matrix3<f64>; LANES] = fs.try_into().unwrap();
        let warm = *Rotation3::from_scaled_axis(Vector3::from(w)).matrix();
        let v0 = [warm; LANES];
        let b = svd3_warm_batch(&fs, &v0);
        for k in 0..LANES {
            let s = svd3_warm(&fs[k], &warm);
            check_svd(&fs[k], &b[k])?;
            prop_assert!((b[k].sigma - s.sigma).amax() <= 1e-14 * s.sigma[0].abs());
            // The rotation (polar factor) is unique and stable when sigma_2 + sigma_3 is not
            // small: its condition number is about sigma_1 / (sigma_2 + sigma_3).
            let cond = s.sigma[0] / (s.sigma[1] + s.sigma[2]);
            prop_assert!((b[k].rotation() - s.rotation()).amax() <= 1e-14 * cond.max(1.0), "cond {}", cond);
        }
    }

    /// The volume projection meets its target to 1e-12 and is a local minimum of the distance
    /// on the constraint surface (no nearby feasible point is closer).
    #[test]
    fn volume_projection_is_the_nearest_point(
        ls in prop::array::uniform3(-4.0f64..4.0),
        flip in any::<bool>(),
        a in prop::sample::select(vec![1e-6, 0.5, 1.0, 2.0]),
        moves in prop::collection::vec((0usize..3, 0usize..3, -1e-3f64..1e-3), 12),
    ) {
        let mut s = Vector3::new(10f64.powf(ls[0]), 10f64.powf(ls[1]), 10f64.powf(ls[2]));
        if flip {
            s[2] = -s[2];
        }
        let x = nearest_product(&s, a).unwrap();
        prop_assert!(x.iter().all(|&v| v > 0.0));
        prop_assert!((x.product() / a - 1.0).abs() < 1e-12, "product {} vs {}", x.product(), a);
        let d0 = (x - s).norm();
        for (i, j, e) in moves {
            if i == j {
                continue;
            }
            let mut y = x;
            y[i] *= 1.0 + e;
            y[j] /= 1.0 + e;
            prop_assert!((y - s).norm() >= d0 - 1e-10 * (1.0 + d0), "{} is closer than {}", y, x);
        }
    }

    #[test]
    fn batched_volume_projection_matches(
        ls in prop::collection::vec(prop::array::uniform3(-1.0f64..1.0), LANES),
        a in prop::sample::select(vec![1e-6, 0.5, 1.0, 2.0]),
        warm in prop::collection::vec(-1.0f64..1.0, LANES),
    ) {
        let s: [Vector3<f64>; LANES] = std::array::from_fn(|k| Vector3::new(10f64.powf(ls[k][0]), 10f64.powf(ls[k][1]), 10f64.powf(ls[k][2])));
        let b = nearest_product_batch(&s, a).unwrap();
        // Any warm start (including ones outside the fast path's domain) gives the same answer.
        let mut t: [f64; LANES] = warm.try_into().unwrap();
        let bw = nearest_product_batch_warm(&s, a, &mut t).unwrap();
        for k in 0..LANES {
            let x = nearest_product(&s[k], a).unwrap();
            prop_assert!((b[k] - x).amax() <= 1e-12 * x.amax(), "{} vs {}", b[k], x);
            prop_assert!((bw[k] - x).amax() <= 1e-12 * x.amax(), "warm {} vs {}", bw[k], x);
            // The returned multiplier satisfies x_i (x_i - s_i) = t for every component.
            for i in 0..3 {
                prop_assert!((x[i] * (x[i] - s[k][i]) - t[k]).abs() <= 1e-9 * (1.0 + t[k].abs()) * x.amax() * x.amax());
            }
        }
    }
}

#[test]
fn more_accurate_than_nalgebra_on_a_graded_matrix() {
    // Found by the property test: a 3x3 matrix with singular values 2961, 1.7e-4, 1.1e-4.
    let f = Matrix3::from_columns(&[
        Vector3::new(-6.912152199219246e-5, 0.0, 0.00010279629854903656),
        Vector3::new(0.0, 2961.6452121472084, 0.0),
        Vector3::new(-0.00015730170177997852, -0.0, -4.517075486450712e-5),
    ]);
    let ours = svd3(&f);
    let theirs = svd3_nalgebra(&f);
    let reference = reference_singular_values(&f);
    let err = |s: &Svd3| (s.compose(&s.sigma) - f).norm() / f.norm();
    assert!(err(&ours) < 1e-15, "ours {}", err(&ours));
    assert!(err(&theirs) > 1e-10, "nalgebra got better? {}", err(&theirs));
    assert!((ours.sigma[1] - reference[1]).abs() < 1e-15 * reference[0]);
}

#[test]
fn degenerate_and_non_finite_matrices() {
    check_svd_plain(&Matrix3::zeros());
    check_svd_plain(&Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0));
    check_svd_plain(&Matrix3::new(1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 1.0, 1.0, 1.0));
    let nan = Matrix3::from_element(f64::NAN);
    assert!(
        svd3(&nan).sigma.iter().any(|v| v.is_nan()),
        "non-finite input does not pretend to succeed"
    );
    assert!(nearest_product(&Vector3::new(1.0, f64::NAN, 1.0), 1.0).is_err());
    let mut s = [Vector3::repeat(1.0); LANES];
    s[1] = Vector3::new(1.0, f64::INFINITY, 1.0);
    assert!(nearest_product_batch(&s, 1.0).is_err());
}

fn check_svd_plain(f: &Matrix3<f64>) {
    let s = svd3(f);
    let scale = f.norm().max(1e-300);
    assert!((s.compose(&s.sigma) - f).norm() <= 1e-13 * scale);
    assert!((s.u.determinant() - 1.0).abs() < 1e-12 && (s.v.determinant() - 1.0).abs() < 1e-12);
}
