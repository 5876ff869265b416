//! Actuator constraints (docs/method.md section 5, Eqs. 39-40): the analytic Jacobians of the
//! pneumatic target `R(F, a)` and the muscle target `p(F, a)` and the energy gradients against
//! dual numbers and central-difference step sweeps, the constraints themselves, the degenerate
//! limits, and every failure mode as an explicit error.
//!
//! Tolerances come from `diffsoft_harness::jacobians::{check_pneumatic, check_muscle}`: absolute and
//! normwise, `100 x` a predicted error level. Relative to `max |J|` they are
//! `100 eps M / min(L, gap)` against dual numbers and `100 (eps M / (|J| L))^(2/3)` (the optimal
//! central-difference error) against differences, where `M` is the largest singular value and
//! `L` the distance to the nearest pole of the Jacobian (`s_i + s_j`, `c_i + c_j`): so at
//! `M / L = 1` they are `2e-14` and `3e-9`, and they grow only with the conditioning of the
//! configuration. Cases that are genuinely ill-conditioned for one of the references (equal
//! singular values for the Jacobi-based dual SVD; `s_2 + s_3 -> 0` where the Jacobian has a
//! pole) are tested separately below.

use diffsoft::kernel::actuator::{
    muscle_energy, muscle_energy_gradient, muscle_jacobian, muscle_jacobian_dual, muscle_target, nearest_product_dual,
    nearest_product_jacobian, pair_coefficients, pneumatic_energy, pneumatic_energy_gradient,
    pneumatic_energy_gradient_dual, pneumatic_jacobian, pneumatic_jacobian_dual, pneumatic_target, pneumatic_target_of,
    ActuatorError,
};
use diffsoft::kernel::svd::svd3;
use diffsoft::kernel::volume::nearest_product;
use diffsoft::kernel::ProjectionError;
use diffsoft_harness::fd::sweep;
use diffsoft_harness::jacobians::{check_muscle, check_pneumatic, JacobianCheck, PNEUMATIC_ACTIVATIONS};
use nalgebra::{Matrix3, Rotation3, Vector3};
use num_dual::Dual64;
use proptest::prelude::*;
use proptest::test_runner::FileFailurePersistence;

fn rotation(v: [f64; 3]) -> Matrix3<f64> {
    *Rotation3::from_scaled_axis(Vector3::from(v)).matrix()
}

fn with_sigma(u: [f64; 3], s: [f64; 3], v: [f64; 3]) -> Matrix3<f64> {
    rotation(u) * Matrix3::from_diagonal(&Vector3::from(s)) * rotation(v).transpose()
}

fn unit(v: [f64; 3]) -> Vector3<f64> {
    let v = Vector3::from(v);
    if v.norm() < 1e-3 {
        Vector3::z()
    } else {
        v.normalize()
    }
}

fn assert_pass(checks: &[JacobianCheck]) -> Result<(), TestCaseError> {
    for c in checks {
        prop_assert!(
            c.pass(),
            "{} at {}: vs dual {:e} (atol {:e}, worst {} = {} vs {}), vs FD {:e} (atol {:e}, worst {} = {} vs {})",
            c.name,
            c.configuration,
            c.versus_dual.max_abs_error,
            c.versus_dual.atol,
            c.versus_dual.worst_index,
            c.versus_dual.analytic_at_worst,
            c.versus_dual.reference_at_worst,
            c.versus_fd.max_abs_error,
            c.versus_fd.atol,
            c.versus_fd.worst_index,
            c.versus_fd.analytic_at_worst,
            c.versus_fd.reference_at_worst
        );
    }
    Ok(())
}

/// Sorted singular values `10^e`, the last negated when `inverted`.
fn spectrum(e: [f64; 3], inverted: bool) -> [f64; 3] {
    let mut s = e.map(|x| 10f64.powf(x));
    s.sort_by(|x, y| y.total_cmp(x));
    if inverted {
        s[2] = -s[2];
    }
    s
}

fn angles() -> impl Strategy<Value = [f64; 3]> {
    [-2.0..2.0f64, -2.0..2.0f64, -2.0..2.0f64]
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 48,
        failure_persistence: Some(Box::new(FileFailurePersistence::Direct("tests/regressions/actuator_props.txt"))),
        ..ProptestConfig::default()
    })]

    /// Singular values log-uniform in [1e-4, 1e4], half of the F inverted, a in {1e-6, 0.5, 1, 2}.
    #[test]
    fn pneumatic_jacobians_match_duals_and_differences(
        u in angles(), v in angles(), e in [-4.0..4.0f64, -4.0..4.0f64, -4.0..4.0f64],
        inverted in any::<bool>(), ai in 0usize..4,
    ) {
        let s = spectrum(e, inverted);
        let a = PNEUMATIC_ACTIVATIONS[ai];
        let f = with_sigma(u, s, v);
        let checks = check_pneumatic(&f, a, 3.0, &format!("{s:?}, a={a}")).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(checks.len(), 4);
        assert_pass(&checks)?;
    }

    /// Moderate spectra (the common case) get the well-conditioned tolerances.
    #[test]
    fn pneumatic_jacobians_of_moderate_f_are_accurate(
        u in angles(), v in angles(), e in [-0.3..0.3f64, -0.3..0.3f64, -0.3..0.3f64],
        inverted in any::<bool>(), ai in 0usize..4,
    ) {
        let s = spectrum(e, inverted);
        let a = PNEUMATIC_ACTIVATIONS[ai];
        let f = with_sigma(u, s, v);
        let j = pneumatic_jacobian(&f, a).unwrap();
        let (df, da) = pneumatic_jacobian_dual(&f, a).unwrap();
        let gap = (0..3).flat_map(|i| (i + 1..3).map(move |k| (i, k)))
            .map(|(i, k)| (s[i].abs() - s[k].abs()).abs()).fold(f64::INFINITY, f64::min);
        if gap > 1e-2 && s[1] + s[2] > 1e-2 {
            let rel = (j.wrt_f - df).amax() / df.amax();
            prop_assert!(rel < 1e-11, "dR/dF vs dual: {rel:e} at {s:?}, a={a}");
            let rel = (j.wrt_a - da).amax() / da.amax();
            prop_assert!(rel < 1e-11, "dR/da vs dual: {rel:e} at {s:?}, a={a}");
        }
    }

    #[test]
    fn muscle_jacobians_match_duals_and_differences(
        u in angles(), v in angles(), e in [-4.0..4.0f64, -4.0..4.0f64, -4.0..4.0f64],
        inverted in any::<bool>(), m in [-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64],
        a in prop_oneof![Just(1e-6), Just(0.5), Just(1.0 - 1e-6), 1e-3..0.999f64],
    ) {
        let f = with_sigma(u, spectrum(e, inverted), v);
        let m = unit(m);
        let checks = check_muscle(&f, &m, a, 2.0, &format!("a={a}")).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(checks.len(), 3);
        assert_pass(&checks)?;
    }

    /// prod sigma(R) = a to 1e-12 relative and |p| = 1 - a to 1e-12, at any F.
    #[test]
    fn the_constraints_are_met(
        u in angles(), v in angles(), e in [-4.0..4.0f64, -4.0..4.0f64, -4.0..4.0f64],
        inverted in any::<bool>(), m in [-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64],
        a in prop_oneof![Just(1e-6), Just(0.5), Just(1.0), Just(2.0), 1e-8..1e3f64],
        am in prop_oneof![Just(0.0), Just(1e-6), Just(0.5), Just(1.0), 0.0..1.0f64],
    ) {
        let f = with_sigma(u, spectrum(e, inverted), v);
        let svd = svd3(&f);
        let x = nearest_product(&svd.sigma, a).unwrap();
        prop_assert!(x.iter().all(|&v| v > 0.0));
        prop_assert!((x.product() - a).abs() <= 1e-12 * a, "prod {} vs {a}", x.product());
        // The composed target's singular values are x.
        let r = pneumatic_target(&svd, a).unwrap();
        prop_assert!((r - svd.compose(&x)).amax() <= 1e-15 * x.amax());
        let j = pneumatic_jacobian(&f, a);
        if let Ok(j) = j {
            prop_assert!((j.x.product() - a).abs() <= 1e-12 * a);
        }
        let p = muscle_target(&(f * unit(m)), am).unwrap();
        prop_assert!((p.norm() - (1.0 - am)).abs() <= 1e-12, "|p| = {} vs {}", p.norm(), 1.0 - am);
    }

    /// Bad activations, non-finite input, negative stiffness and collapsed fibres are explicit
    /// errors from every entry point, never a NaN or a panic.
    #[test]
    fn failures_are_explicit_errors(
        u in angles(), v in angles(), e in [-2.0..2.0f64, -2.0..2.0f64, -2.0..2.0f64],
        bad_a in prop_oneof![Just(0.0), Just(-1.0), Just(-0.0), Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY), -1e3..0.0f64],
        bad_am in prop_oneof![Just(-1e-12), Just(1.0 + 1e-12), Just(f64::NAN), Just(f64::INFINITY), 1.0001..10.0f64, -10.0..-1e-9f64],
        bad_x in prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY)],
        entry in 0usize..9,
    ) {
        let f = with_sigma(u, spectrum(e, false), v);
        let m = Vector3::new(0.6, 0.0, 0.8);
        let bad_act = |r: Result<(), ActuatorError>| matches!(r, Err(ActuatorError::BadActivation(_)));
        prop_assert!(bad_act(pneumatic_target(&svd3(&f), bad_a).map(|_| ())));
        prop_assert!(bad_act(pneumatic_target_of(&f, bad_a).map(|_| ())));
        prop_assert!(bad_act(pneumatic_energy(&f, bad_a, 1.0).map(|_| ())));
        prop_assert!(bad_act(pneumatic_energy_gradient(&f, bad_a, 1.0).map(|_| ())));
        prop_assert!(bad_act(pneumatic_jacobian(&f, bad_a).map(|_| ())));
        prop_assert!(bad_act(pneumatic_jacobian_dual(&f, bad_a).map(|_| ())));
        prop_assert!(bad_act(muscle_target(&(f * m), bad_am).map(|_| ())));
        prop_assert!(bad_act(muscle_energy(&f, &m, bad_am, 1.0).map(|_| ())));
        prop_assert!(bad_act(muscle_energy_gradient(&f, &m, bad_am, 1.0).map(|_| ())));
        prop_assert!(bad_act(muscle_jacobian(&f, &m, bad_am).map(|_| ())));
        prop_assert!(bad_act(muscle_jacobian_dual(&f, &m, bad_am).map(|_| ())));
        // Non-finite F (any entry) or fibre direction.
        let mut g = f;
        g[(entry % 3, entry / 3)] = bad_x;
        let non_finite = |r: Result<(), ActuatorError>| {
            matches!(r, Err(ActuatorError::NonFinite) | Err(ActuatorError::Projection(ProjectionError::NonFinite)))
        };
        prop_assert!(non_finite(pneumatic_target_of(&g, 0.5).map(|_| ())));
        prop_assert!(non_finite(pneumatic_energy(&g, 0.5, 1.0).map(|_| ())));
        prop_assert!(non_finite(pneumatic_energy_gradient(&g, 0.5, 1.0).map(|_| ())));
        prop_assert!(non_finite(pneumatic_jacobian(&g, 0.5).map(|_| ())));
        prop_assert!(non_finite(pneumatic_jacobian_dual(&g, 0.5).map(|_| ())));
        prop_assert!(non_finite(pneumatic_target(&svd3(&g), 0.5).map(|_| ())));
        prop_assert!(non_finite(muscle_energy(&g, &m, 0.5, 1.0).map(|_| ())));
        prop_assert!(non_finite(muscle_energy_gradient(&g, &m, 0.5, 1.0).map(|_| ())));
        prop_assert!(non_finite(muscle_jacobian(&g, &m, 0.5).map(|_| ())));
        prop_assert!(non_finite(muscle_jacobian_dual(&g, &m, 0.5).map(|_| ())));
        let mut mm = m;
        mm[entry % 3] = bad_x;
        prop_assert!(non_finite(muscle_energy(&f, &mm, 0.5, 1.0).map(|_| ())));
        prop_assert!(non_finite(muscle_jacobian(&f, &mm, 0.5).map(|_| ())));
        // Stiffness.
        for k in [-1.0, f64::NAN, f64::INFINITY] {
            prop_assert!(matches!(pneumatic_energy(&f, 0.5, k), Err(ActuatorError::BadStiffness(_))));
            prop_assert!(matches!(pneumatic_energy_gradient(&f, 0.5, k), Err(ActuatorError::BadStiffness(_))));
            prop_assert!(matches!(pneumatic_energy_gradient_dual(&f, 0.5, k), Err(ActuatorError::BadStiffness(_))));
            prop_assert!(matches!(muscle_energy(&f, &m, 0.5, k), Err(ActuatorError::BadStiffness(_))));
            prop_assert!(matches!(muscle_energy_gradient(&f, &m, 0.5, k), Err(ActuatorError::BadStiffness(_))));
        }
        // Collapsed fibre: m in the null space of a rank-deficient F, or m = 0.
        let s = spectrum(e, false);
        let flat = with_sigma(u, [s[0], s[1], 0.0], v);
        let null = rotation(v).column(2).into_owned();
        let collapsed = |r: Result<(), ActuatorError>| matches!(r, Err(ActuatorError::CollapsedFibre));
        let fm = flat * null;
        // Round-off may leave |F m| ~ eps |F|: take the exact zero fibre for the target itself.
        prop_assert!(collapsed(muscle_target(&Vector3::zeros(), 0.5).map(|_| ())));
        if fm == Vector3::zeros() {
            prop_assert!(collapsed(muscle_jacobian(&flat, &null, 0.5).map(|_| ())));
        }
        let zero = Vector3::zeros();
        prop_assert!(collapsed(muscle_energy(&f, &zero, 0.5, 1.0).map(|_| ())));
        prop_assert!(collapsed(muscle_energy_gradient(&f, &zero, 0.5, 1.0).map(|_| ())));
        prop_assert!(collapsed(muscle_jacobian(&f, &zero, 0.5).map(|_| ())));
        prop_assert!(collapsed(muscle_jacobian_dual(&f, &zero, 0.5).map(|_| ())));
        prop_assert!(collapsed(muscle_jacobian(&Matrix3::zeros(), &m, 0.5).map(|_| ())));
    }

    /// The nearest product is the nearest point: no point of the constraint surface found by a
    /// grid search (refined by pattern search) is closer. Nearly isotropic `s` (within 3% or
    /// 30%) compressed to 1-60% of its volume is where "shrink uniformly" and "collapse the smallest direction" are
    /// both local minima (the case `nearest_product` used to get wrong).
    #[test]
    fn the_nearest_product_is_the_global_minimum(
        b in 0.5..2.0f64, d in [-0.3..0.3f64, -0.3..0.3f64, -0.3..0.3f64],
        spread in prop_oneof![Just(0.1), Just(1.0)], ratio in 0.01..0.6f64,
    ) {
        let s = Vector3::new(b * (1.0 + spread * d[0]), b * (1.0 + spread * d[1]), b * (1.0 + spread * d[2]));
        let a = ratio * s.product();
        let x = nearest_product(&s, a).unwrap();
        let best = brute_force_distance(&s, a);
        prop_assert!((x - s).norm_squared() <= best * (1.0 + 1e-9) + 1e-14, "{s} a={a}: {x} at {} > {best}", (x - s).norm_squared());
    }
}

/// Smallest `|x - s|^2` over `x = (e^u, e^v, a e^(-u-v))` by a grid and pattern search.
fn brute_force_distance(s: &Vector3<f64>, a: f64) -> f64 {
    let dist = |u: f64, v: f64| (Vector3::new(u.exp(), v.exp(), a * (-u - v).exp()) - s).norm_squared();
    let (lo, hi, n) = (-8.0, 1.5, 120);
    let mut starts: Vec<(f64, f64, f64)> = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (u, v) = (
                lo + (hi - lo) * i as f64 / (n - 1) as f64,
                lo + (hi - lo) * j as f64 / (n - 1) as f64,
            );
            starts.push((dist(u, v), u, v));
        }
    }
    starts.sort_by(|p, q| p.0.total_cmp(&q.0));
    let mut best = f64::INFINITY;
    for &(mut bd, mut bu, mut bv) in starts.iter().take(8) {
        let mut h = 0.1;
        while h > 1e-13 {
            let mut moved = false;
            for (du, dv) in [
                (h, 0.0),
                (-h, 0.0),
                (0.0, h),
                (0.0, -h),
                (h, -h),
                (-h, h),
                (h, h),
                (-h, -h),
            ] {
                let d = dist(bu + du, bv + dv);
                if d < bd {
                    (bd, bu, bv) = (d, bu + du, bv + dv);
                    moved = true;
                }
            }
            if !moved {
                h *= 0.5;
            }
        }
        best = best.min(bd);
    }
    best
}

#[test]
fn a_known_wrong_local_minimum_is_no_longer_returned() {
    // Found by brute force: the old solver returned the uniform-shrink point
    // (0.698, 0.742, 0.679) at |x - s|^2 = 1.3278, while collapsing the smallest direction,
    // (1.057, 1.063, 0.313), is at 1.3112.
    let s = Vector3::new(1.3699326657700475, 1.3740836954652762, 1.3697269889809522);
    let a = 0.3518 * 1.0;
    let x = nearest_product(&s, a).unwrap();
    let best = brute_force_distance(&s, a);
    assert!(
        (x - s).norm_squared() <= best * (1.0 + 1e-9),
        "{x}: {} vs {best}",
        (x - s).norm_squared()
    );
    assert!(x.min() < 0.4, "{x}");
    // And F = I compressed to 13% of its volume collapses one direction (1/8 < a < 4/27: the
    // uniform shrink by 0.507 is a local minimum at 0.729, the collapse to (0.205, 0.795, 0.795)
    // is nearer at 0.716).
    let one = Vector3::repeat(1.0);
    let x = nearest_product(&one, 0.13).unwrap();
    let best = brute_force_distance(&one, 0.13);
    assert!(
        (x - one).norm_squared() <= best * (1.0 + 1e-9) && best < 0.72 && x.min() < 0.21,
        "{x}"
    );
}

#[test]
fn the_analytic_limit_at_equal_singular_values_is_right() {
    // s_1 = s_2 exactly: the Jacobi-based dual SVD has no derivative there (its rotation angle
    // is 0/0), so the limit formula (x_i + x_j)/(c_i + c_j) is checked against central
    // differences, which are well conditioned, and against the analytic Jacobian approached
    // from s_2 = s_1 (1 - d).
    for (s, a) in [
        ([1.5, 1.5, 0.7], 0.5),
        ([1.2, 0.8, 0.8], 2.0),
        ([1.0, 1.0, -0.6], 1.0),
        ([1.0, 1.0, 1.0], 0.5),
    ] {
        let f = with_sigma([0.3, -0.7, 1.1], s, [-0.4, 0.2, 0.9]);
        let j = pneumatic_jacobian(&f, a).unwrap();
        let fun = |h: f64| -> Vec<f64> {
            (0..9)
                .flat_map(|q| {
                    let mut g = f;
                    g[(q % 3, q / 3)] += h;
                    pneumatic_target_of(&g, a).unwrap().iter().copied().collect::<Vec<_>>()
                })
                .collect()
        };
        let analytic: Vec<f64> = j.wrt_f.iter().copied().collect();
        let sw = sweep(&fun, &analytic, 0.1, 10);
        assert!(
            sw.best_error < 1e-8 * j.wrt_f.amax(),
            "{s:?} a={a}: FD {:e}",
            sw.best_error
        );
        assert!((sw.truncation_slope - 2.0).abs() < 0.3, "slope {}", sw.truncation_slope);
        let mut prev = f64::INFINITY;
        for d in [1e-2, 1e-4, 1e-6, 1e-8] {
            let mut s2 = s;
            if s[0] == s[1] {
                s2[1] = s[0] * (1.0 - d);
            } else {
                s2[2] = s[1] * (1.0 - d);
            }
            let near = pneumatic_jacobian(&with_sigma([0.3, -0.7, 1.1], s2, [-0.4, 0.2, 0.9]), a).unwrap();
            let diff = (near.wrt_f - j.wrt_f).amax();
            // The approach is continuous and linear in d (no 0/0 left in the formula).
            assert!(diff < 10.0 * d * j.wrt_f.amax() + 1e-14, "{s:?} d={d}: {diff:e}");
            assert!(diff <= prev);
            prev = diff;
        }
    }
    // The coefficient itself: (x_i - x_j)/(s_i - s_j) -> (x_i + x_j)/(c_i + c_j).
    let (sym, _) = pair_coefficients(0.9, 0.9, 1.2, 1.2).unwrap();
    assert!((sym - 1.8 / 1.2).abs() < 1e-15);
}

#[test]
fn opposite_singular_values_are_a_pole_of_the_jacobian() {
    // Inverted F with s_2 + s_3 = g -> 0: the nearest point becomes non-unique (either direction
    // can be flipped), and the Jacobian grows like 1/g. Away from g = 0 it still matches both
    // references with the conditioning-based tolerances; at g = 0 it is an explicit error.
    let mut scaled = Vec::new();
    for g in [1e-1, 1e-3, 1e-5] {
        let f = with_sigma([0.3, -0.7, 1.1], [2.0, 1.0, -(1.0 - g)], [-0.4, 0.2, 0.9]);
        for a in [0.5, 2.0] {
            let checks = check_pneumatic(&f, a, 1.0, &format!("g={g}")).unwrap();
            for c in &checks {
                assert!(
                    c.pass(),
                    "{} g={g} a={a}: {:?} {:?}",
                    c.name,
                    c.versus_dual,
                    c.versus_fd
                );
            }
            scaled.push(pneumatic_jacobian(&f, a).unwrap().wrt_f.amax() * g);
        }
    }
    // g max|J| approaches a constant.
    let (lo, hi) = scaled
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
    assert!(hi / lo < 10.0 && lo > 0.1, "{scaled:?}");
    let f = Matrix3::from_diagonal(&Vector3::new(2.0, 1.0, -1.0));
    assert_eq!(pneumatic_jacobian(&f, 1.0), Err(ActuatorError::NotDifferentiable));
    assert!(
        pneumatic_target_of(&f, 1.0).is_ok(),
        "the target itself exists (one of the nearest points)"
    );
    // Rank-1 F: s_2 + s_3 = 0 with both zero.
    let f = Matrix3::from_diagonal(&Vector3::new(2.0, 0.0, 0.0));
    assert_eq!(pneumatic_jacobian(&f, 1.0), Err(ActuatorError::NotDifferentiable));
}

#[test]
fn a_collapse_with_a_tie_is_not_differentiable() {
    // F = I with a tiny target: one direction collapses, which one is arbitrary.
    assert_eq!(
        pneumatic_jacobian(&Matrix3::identity(), 1e-6),
        Err(ActuatorError::NotDifferentiable)
    );
    // Just off the tie it is differentiable and matches both references.
    let f = with_sigma([0.3, -0.7, 1.1], [1.0, 0.9, 0.8], [-0.4, 0.2, 0.9]);
    for c in check_pneumatic(&f, 1e-6, 1.0, "collapse").unwrap() {
        assert!(c.pass(), "{}: {:?} {:?}", c.name, c.versus_dual, c.versus_fd);
    }
}

#[test]
fn the_singular_value_jacobian_is_a_symmetric_projection_at_the_constraint() {
    // At s with prod s = a, x = s and J = I - n n^T / |n|^2 with n_i = prod_(j != i) s_j.
    let s = Vector3::new(1e4, 1.0, 1e-4);
    let (j, da) = nearest_product_jacobian(&s, &s, 1.0).unwrap();
    let n = Vector3::new(s[1] * s[2], s[0] * s[2], s[0] * s[1]);
    // Diagonal as (|n|^2 - n_i^2)/|n|^2 summed without cancellation.
    let p = Matrix3::from_fn(|r, c| {
        if r == c {
            (0..3).filter(|&q| q != r).map(|q| n[q] * n[q]).sum::<f64>() / n.norm_squared()
        } else {
            -n[r] * n[c] / n.norm_squared()
        }
    });
    for r in 0..3 {
        for c in 0..3 {
            // Entry-wise relative accuracy, including J_33 = 1e-8 (no cancellation).
            assert!((j[(r, c)] - p[(r, c)]).abs() <= 1e-14 * p[(r, c)].abs().max(1e-300) + 1e-300);
        }
    }
    assert!((j - j.transpose()).amax() <= 1e-15 * j.amax());
    // dx/da = n / |n|^2 (the normal direction, scaled so that d prod x / da = 1).
    let expected = n / n.norm_squared();
    assert!((da - expected).amax() <= 1e-14 * expected.amax());
    // The same from dual numbers.
    let sd = s.map(Dual64::from);
    let xd = nearest_product_dual(&sd, Dual64::from(1.0).derivative()).unwrap();
    assert!((xd.map(|z| z.eps) - da).amax() <= 1e-14 * da.amax());
}

#[test]
fn energy_gradients_match_central_differences() {
    // Directly on the energies, at an inverted, an extreme and a moderate F.
    for (s, a) in [
        ([1.3, 0.8, -0.4], 0.5),
        ([1e2, 1.0, 1e-2], 2.0),
        ([1.1, 1.0, 0.9], 1e-6),
    ] {
        let f = with_sigma([0.5, 0.1, -0.9], s, [1.0, -0.3, 0.2]);
        let g = pneumatic_energy_gradient(&f, a, 7.0).unwrap();
        let gd = pneumatic_energy_gradient_dual(&f, a, 7.0).unwrap();
        let fun = |h: f64| -> Vec<f64> {
            (0..9)
                .map(|q| {
                    let mut ff = f;
                    ff[(q % 3, q / 3)] += h;
                    pneumatic_energy(&ff, a, 7.0).unwrap()
                })
                .collect()
        };
        let analytic: Vec<f64> = g.iter().copied().collect();
        let sw = sweep(&fun, &analytic, 1e-2, 10);
        assert!(
            sw.best_error <= 1e-7 * g.amax(),
            "{s:?}: {:e} vs {:e}",
            sw.best_error,
            g.amax()
        );
        // Both carry the round-off of F - R: eps k |F| (the gradient is a small difference here).
        assert!(
            (g - gd).amax() <= 100.0 * f64::EPSILON * 7.0 * f.amax(),
            "{s:?}: {:e}",
            (g - gd).amax()
        );
        let m = Vector3::new(0.2, -0.5, 0.7).normalize();
        let g = muscle_energy_gradient(&f, &m, 0.3, 7.0).unwrap();
        let fun = |h: f64| -> Vec<f64> {
            (0..9)
                .map(|q| {
                    let mut ff = f;
                    ff[(q % 3, q / 3)] += h;
                    muscle_energy(&ff, &m, 0.3, 7.0).unwrap()
                })
                .collect()
        };
        let analytic: Vec<f64> = g.iter().copied().collect();
        let sw = sweep(&fun, &analytic, 1e-2, 10);
        assert!(sw.best_error <= 1e-7 * g.amax(), "muscle {s:?}: {:e}", sw.best_error);
    }
}
