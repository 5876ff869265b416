//! Properties of the FEM operators (Eqs. 22-23) on random meshes.
#![allow(clippy::needless_range_loop)] // matrix entries are clearest as (i, j) loops

use diffsoft::fem::{Coefficient, FemOperators, SymCsc};
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::mesh::TetMesh;
use nalgebra::{Rotation3, Vector3};
use proptest::prelude::*;
use proptest::test_runner::FileFailurePersistence;

/// Random jittered boxes, either split.
fn meshes() -> impl Strategy<Value = TetMesh> {
    crate::common::jittered_boxes(0.1..10.0, 0.0..0.25)
}

fn dense(l: &SymCsc) -> Vec<Vec<f64>> {
    let mut a = vec![vec![0.0; l.n]; l.n];
    for j in 0..l.n {
        for (i, v) in l.column(j) {
            a[i][j] = v;
        }
    }
    a
}

fn max_abs(a: &[Vec<f64>]) -> f64 {
    a.iter().flatten().fold(0.0, |m, v| m.max(v.abs()))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, failure_persistence: Some(Box::new(FileFailurePersistence::Direct("tests/regressions/fem_props.txt"))), ..ProptestConfig::default() })]

    /// Each row of A sums to zero (sum_i a_i = 0), so L 1 = 0: a rigid translation costs nothing.
    #[test]
    fn gradients_sum_to_zero_and_l_annihilates_constants(mesh in meshes(), mu in 1e-3f64..1e9) {
        let fem = FemOperators::new(&mesh).unwrap();
        for g in &fem.geometry {
            let s: Vector3<f64> = g.grads.iter().sum();
            let scale = g.grads.iter().map(|a| a.norm()).fold(0.0, f64::max);
            prop_assert!(s.norm() <= 1e-12 * scale);
        }
        let l = fem.laplacian_csc(Coefficient::Uniform(mu)).unwrap();
        let ones = vec![1.0; l.n];
        let mut y = vec![0.0; l.n];
        l.matvec(&ones, &mut y);
        let diag_max = l.diagonal().iter().fold(0.0f64, |m, v| m.max(*v));
        for v in y {
            prop_assert!(v.abs() <= 1e-12 * diag_max);
        }
    }

    /// L is symmetric positive semidefinite.
    #[test]
    fn l_is_symmetric_psd(mesh in meshes(), x in proptest::collection::vec(-1.0f64..1.0, 64)) {
        let fem = FemOperators::new(&mesh).unwrap();
        let l = fem.laplacian_csc(Coefficient::Uniform(1.0)).unwrap();
        let a = dense(&l);
        for i in 0..l.n {
            for j in 0..l.n {
                prop_assert!((a[i][j] - a[j][i]).abs() <= 1e-14 * max_abs(&a));
            }
        }
        let v: Vec<f64> = (0..l.n).map(|i| x[i % x.len()]).collect();
        let mut lv = vec![0.0; l.n];
        l.matvec(&v, &mut lv);
        let q: f64 = v.iter().zip(&lv).map(|(a, b)| a * b).sum();
        prop_assert!(q >= -1e-12 * max_abs(&a) * l.n as f64);
    }

    /// L is invariant under rigid motions of the rest mesh.
    #[test]
    fn l_invariant_under_rigid_motion(mesh in meshes(), axis in prop::array::uniform3(-1.0f64..1.0), angle in -7.0f64..7.0, t in prop::array::uniform3(-1e3f64..1e3)) {
        let axis = Vector3::from(axis);
        prop_assume!(axis.norm() > 1e-3);
        let r = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle);
        let moved = mesh.map_vertices(|v| r * v + Vector3::from(t));
        let l0 = FemOperators::new(&mesh).unwrap().laplacian_csc(Coefficient::Uniform(3.0)).unwrap();
        let l1 = FemOperators::new(&moved).unwrap().laplacian_csc(Coefficient::Uniform(3.0)).unwrap();
        prop_assert_eq!(&l0.row_idx, &l1.row_idx);
        let scale = l0.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        // Translations of 1e3 on unit-size meshes cost ~1e3 eps of relative accuracy.
        for (a, b) in l0.values.iter().zip(&l1.values) {
            prop_assert!((a - b).abs() <= 1e-9 * scale, "{} vs {}", a, b);
        }
    }

    /// Entries scale like mu V / len^2: scaling lengths by c scales L by c and M by c^3.
    #[test]
    fn l_and_mass_scale_with_length_and_coefficients(mesh in meshes(), c in 1e-3f64..1e3, mu in 1e-3f64..1e9, rho in 1e-3f64..1e5) {
        let f0 = FemOperators::new(&mesh).unwrap();
        let f1 = FemOperators::new(&mesh.scaled(c)).unwrap();
        let l0 = f0.laplacian_csc(Coefficient::Uniform(1.0)).unwrap();
        let l1 = f1.laplacian_csc(Coefficient::Uniform(mu)).unwrap();
        for (a, b) in l0.values.iter().zip(&l1.values) {
            prop_assert!((b - mu * c * a).abs() <= 1e-11 * (mu * c * a).abs().max(1e-300) + 1e-12 * mu * c * l0.values.iter().fold(0.0f64, |m, v| m.max(v.abs())));
        }
        let m0 = f0.lumped_mass(Coefficient::Uniform(1.0)).unwrap();
        let m1 = f1.lumped_mass(Coefficient::Uniform(rho)).unwrap();
        for (a, b) in m0.iter().zip(&m1) {
            prop_assert!(crate::common::rel(*b, rho * c * c * c * a) < 1e-11);
        }
        let total: f64 = m1.iter().sum();
        prop_assert!(crate::common::rel(total, rho * f1.total_volume()) < 1e-12);
    }

    /// Per-tet coefficients: a uniform per-tet vector equals the uniform coefficient, and L is
    /// linear in the coefficients.
    #[test]
    fn per_tet_coefficients_are_linear(mesh in meshes(), a in 0.1f64..10.0, b in 0.1f64..10.0) {
        let fem = FemOperators::new(&mesh).unwrap();
        let t = mesh.num_tets();
        let ka: Vec<f64> = (0..t).map(|i| if i % 2 == 0 { a } else { b }).collect();
        let sum: Vec<f64> = ka.iter().map(|k| k + 1.0).collect();
        let la = fem.laplacian_values(Coefficient::PerTet(&ka)).unwrap();
        let l1 = fem.laplacian_values(Coefficient::Uniform(1.0)).unwrap();
        let ls = fem.laplacian_values(Coefficient::PerTet(&sum)).unwrap();
        for k in 0..la.len() {
            prop_assert!((ls[k] - la[k] - l1[k]).abs() <= 1e-12 * (ls[k].abs() + 1.0));
        }
    }
}

#[test]
fn single_tet_operators_match_closed_form() {
    // Unit right tet: P = I, V = 1/6, A = [-s, I] (Eq. 23).
    let mesh = TetMesh::new(
        vec![Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::z()],
        vec![[0, 1, 2, 3]],
    )
    .unwrap();
    let fem = FemOperators::new(&mesh).unwrap();
    let g = &fem.geometry[0];
    assert!((g.volume - 1.0 / 6.0).abs() < 1e-15);
    assert_eq!(g.grads[0], Vector3::new(-1.0, -1.0, -1.0));
    assert_eq!(g.grads[1], Vector3::x());
    let l = fem.laplacian_csc(Coefficient::Uniform(6.0)).unwrap();
    let a = dense(&l);
    // mu V A^T A with mu V = 1: [[3, -1, -1, -1], [-1, 1, 0, 0], ...]
    let expect = [
        [3.0, -1.0, -1.0, -1.0],
        [-1.0, 1.0, 0.0, 0.0],
        [-1.0, 0.0, 1.0, 0.0],
        [-1.0, 0.0, 0.0, 1.0],
    ];
    for i in 0..4 {
        for j in 0..4 {
            assert!((a[i][j] - expect[i][j]).abs() < 1e-14);
        }
    }
    let m = fem.lumped_mass(Coefficient::Uniform(24.0)).unwrap();
    assert!(m.iter().all(|&x| (x - 1.0).abs() < 1e-15));
}

#[test]
fn bad_coefficients_are_rejected() {
    let mesh = BoxSpec::new([1, 1, 1], [1.0; 3]).build().unwrap();
    let fem = FemOperators::new(&mesh).unwrap();
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(fem.laplacian_values(Coefficient::Uniform(bad)).is_err());
        assert!(fem.lumped_mass(Coefficient::Uniform(bad)).is_err());
    }
    let short = [1.0; 3];
    let e = fem.laplacian_values(Coefficient::PerTet(&short)).unwrap_err();
    assert!(e.to_string().contains("expected 6 per-tet values, got 3"), "{e}");
}

#[test]
fn assembly_matches_faer_triplet_assembly() {
    // The pattern-scatter assembly equals faer's own triplet assembly (duplicates summed).
    let mesh = BoxSpec::new([3, 2, 2], [1.0, 0.7, 0.5]).jitter(0.2, 7).build().unwrap();
    let fem = FemOperators::new(&mesh).unwrap();
    let mut trip = Vec::new();
    for (t, g) in fem.geometry.iter().enumerate() {
        let k = g.local_laplacian();
        for a in 0..4 {
            for b in 0..4 {
                trip.push(faer::sparse::Triplet::new(
                    mesh.tets[t][a],
                    mesh.tets[t][b],
                    2.5 * k[a][b],
                ));
            }
        }
    }
    let n = mesh.num_vertices();
    let reference = faer::sparse::SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &trip).unwrap();
    let ours = fem.laplacian(Coefficient::Uniform(2.5)).unwrap();
    let (a, b) = (reference.to_dense(), ours.to_dense());
    for i in 0..n {
        for j in 0..n {
            assert!((a[(i, j)] - b[(i, j)]).abs() < 1e-13, "({i},{j})");
        }
    }
}
