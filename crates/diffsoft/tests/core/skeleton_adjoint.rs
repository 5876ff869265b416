//! The skeleton's pieces of the backward pass against central differences: the update rules'
//! Jacobians in the joint charts (Eqs. 10, 35, 38) and the contraction of `dB/dz` with an
//! adjoint of `B` (Eqs. 12-16), on random chains (free root, rotational, prismatic).

use diffsoft::skeleton::free::Free;
use diffsoft::skeleton::Skeleton;
use diffsoft::testing::random_chain;
use nalgebra::{DMatrix, Matrix4, Rotation3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The skeleton moved by `e` along chart direction `l` (the increment of `Joint::transform_dual`).
fn moved(sk: &Skeleton, l: usize, e: f64) -> Skeleton {
    let mut out = sk.clone();
    for b in &mut out.bones {
        let n = b.joint.dofs();
        if l < b.dof_offset || l >= b.dof_offset + n {
            continue;
        }
        let mut s = vec![0.0; b.joint.state_len()];
        b.joint.write_state(&mut s);
        if b.joint.kind() == "free" {
            let t = b.joint.transform();
            let mut z = [0.0; 6];
            z[l - b.dof_offset] = e;
            let m = Free::increment(&t, &Vector3::new(z[0], z[1], z[2]), &Vector3::new(z[3], z[4], z[5]));
            s[..9].copy_from_slice(m.fixed_view::<3, 3>(0, 0).into_owned().as_slice());
            s[9..12].copy_from_slice(m.fixed_view::<3, 1>(0, 3).into_owned().as_slice());
        } else {
            s[0] += e;
        }
        b.joint.read_state(&s);
    }
    out
}

#[test]
fn jacobian_derivative_contraction_matches_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for depth in [1, 3, 5] {
        let sk = random_chain(depth, &mut rng, false, false);
        let rows = 3 * sk.rigid.len();
        let b_bar = DMatrix::from_fn(rows, sk.dofs, |_, _| rng.random_range(-1.0..1.0));
        let mut an = vec![0.0; sk.dofs];
        sk.contract_jacobian_derivative(&b_bar, &mut an);
        let contract = |s: &Skeleton| {
            let mut b = DMatrix::zeros(rows, s.dofs);
            s.jacobian(&mut b);
            b.dot(&b_bar)
        };
        for (l, a) in an.iter().enumerate() {
            let e = 1e-6;
            let fd = (contract(&moved(&sk, l, e)) - contract(&moved(&sk, l, -e))) / (2.0 * e);
            assert!(
                (a - fd).abs() <= 1e-7 * (1.0 + fd.abs()),
                "depth {depth}, coordinate {l}: analytic {a}, fd {fd}"
            );
        }
    }
}

/// `Skeleton::jacobian_derivative_matrix` (the bones' curvature of Newton's reduced Hessian):
/// entry `(l, k)` is the derivative along chart direction `l` of `g . B e_k`.
#[test]
fn jacobian_derivative_matrix_matches_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(19);
    for depth in [1, 3, 5] {
        let sk = random_chain(depth, &mut rng, false, false);
        let nr = sk.rigid.len();
        let g: Vec<Vector3<f64>> = (0..nr)
            .map(|_| {
                Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                )
            })
            .collect();
        let mut an = DMatrix::zeros(sk.dofs, sk.dofs);
        sk.jacobian_derivative_matrix(&g, &mut an);
        let gb = |s: &Skeleton, k: usize| {
            let mut b = DMatrix::zeros(3 * nr, s.dofs);
            s.jacobian(&mut b);
            (0..nr)
                .map(|r| (0..3).map(|a| g[r][a] * b[(3 * r + a, k)]).sum::<f64>())
                .sum::<f64>()
        };
        for l in 0..sk.dofs {
            let e = 1e-6;
            let (p, m) = (moved(&sk, l, e), moved(&sk, l, -e));
            for k in 0..sk.dofs {
                let fd = (gb(&p, k) - gb(&m, k)) / (2.0 * e);
                assert!(
                    (an[(l, k)] - fd).abs() <= 1e-7 * (1.0 + fd.abs()),
                    "depth {depth}, ({l}, {k}): analytic {}, fd {fd}",
                    an[(l, k)]
                );
            }
        }
    }
}

/// `sum_r J[r, j] dA/dz_r` at the state after the update, for comparison with a difference of
/// the transforms.
fn chart_to_transform(j: &Skeleton, bone: usize, col: &[f64]) -> Matrix4<f64> {
    let b = &j.bones[bone];
    (0..b.joint.dofs()).map(|r| b.joint.derivative(r) * col[r]).sum()
}

#[test]
fn update_jacobians_match_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for trial in 0..6 {
        let mut sk = random_chain(3, &mut rng, false, false);
        // A sizeable increment (the update is nonlinear: projection and atan).
        let dz: Vec<f64> = (0..sk.dofs).map(|_| rng.random_range(-0.4..0.4)).collect();
        if trial == 0 {
            if let Some(b) = sk.bones.iter_mut().find(|b| b.joint.kind() == "free") {
                let mut s = vec![0.0; 12];
                b.joint.write_state(&mut s);
                let r = Rotation3::from_scaled_axis(Vector3::new(0.3, -2.5, 0.7));
                s[..9].copy_from_slice(r.matrix().as_slice());
                b.joint.read_state(&s);
            }
        }
        let after = {
            let mut s = sk.clone();
            s.update(&dz);
            s
        };
        // Column by column: unit adjoints give the rows of the Jacobians; compare their action
        // on perturbations with differences of the updated transforms.
        let n = sk.dofs;
        let mut jz = DMatrix::zeros(n, n);
        let mut jdz = DMatrix::zeros(n, n);
        for r in 0..n {
            let mut unit = vec![0.0; n];
            unit[r] = 1.0;
            let (mut before, mut dzb) = (vec![0.0; n], vec![0.0; n]);
            sk.update_adjoint(&dz, &unit, &mut before, &mut dzb);
            for c in 0..n {
                jz[(r, c)] = before[c];
                jdz[(r, c)] = dzb[c];
            }
        }
        let e = 1e-6;
        for (bi, b) in sk.bones.iter().enumerate() {
            let (o, m) = (b.dof_offset, b.joint.dofs());
            if m == 0 {
                continue;
            }
            for c in o..o + m {
                // State direction c.
                let up = |s: f64| {
                    let mut k = moved(&sk, c, s);
                    k.update(&dz);
                    k.bones[bi].joint.transform()
                };
                let fd = (up(e) - up(-e)) / (2.0 * e);
                let col: Vec<f64> = (o..o + m).map(|r| jz[(r, c)]).collect();
                let an = chart_to_transform(&after, bi, &col);
                assert!(
                    (an - fd).amax() <= 1e-6 * (1.0 + fd.amax()),
                    "trial {trial}, bone {bi}, state direction {c}: {an} vs {fd}"
                );
                // Increment direction c.
                let up = |s: f64| {
                    let mut k = sk.clone();
                    let mut d = dz.clone();
                    d[c] += s;
                    k.update(&d);
                    k.bones[bi].joint.transform()
                };
                let fd = (up(e) - up(-e)) / (2.0 * e);
                let col: Vec<f64> = (o..o + m).map(|r| jdz[(r, c)]).collect();
                let an = chart_to_transform(&after, bi, &col);
                assert!(
                    (an - fd).amax() <= 1e-6 * (1.0 + fd.amax()),
                    "trial {trial}, bone {bi}, increment direction {c}: {an} vs {fd}"
                );
            }
        }
    }
}

#[test]
fn state_round_trips_exactly() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let sk = random_chain(4, &mut rng, true, true);
    let mut s = Vec::new();
    sk.save_state(&mut s);
    assert_eq!(s.len(), sk.state_len());
    // Same skeleton, moved: loading gives back the same transforms bit for bit.
    let mut other = sk.clone();
    other.update(&vec![0.3; sk.dofs]);
    assert_ne!(other.bones[0].joint.transform(), sk.bones[0].joint.transform());
    other.load_state(&s).unwrap();
    for (a, b) in sk.bones.iter().zip(&other.bones) {
        assert_eq!(a.joint.transform(), b.joint.transform());
    }
    assert!(other.load_state(&s[1..]).is_err());
    let mut bad = s.clone();
    bad[0] = f64::NAN;
    assert!(other.load_state(&bad).is_err());
}
