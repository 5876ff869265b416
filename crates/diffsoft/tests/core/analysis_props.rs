//! Properties of the convergence analysis (docs/method.md section 6) on random and real meshes.

use crate::common::rel;
use diffsoft::analysis::appendix::{self, gershgorin_dt};
use diffsoft::analysis::bounds::{analyze, BoundsParams};
use diffsoft::analysis::empirical::{contraction, Outcome, Scheme};
use diffsoft::analysis::spectral::{spectral_radius, EigenMethod};
use diffsoft::analysis::{rho_split, Attachments, IterationSystem, Spectrum};
use diffsoft::fem::{sign_pattern, Coefficient, FemOperators};
use diffsoft::mesh::generate::{BoxSpec, CellSplit};
use diffsoft::mesh::{self, TetMesh};
use proptest::prelude::*;
use proptest::test_runner::FileFailurePersistence;

fn jittered() -> impl Strategy<Value = TetMesh> {
    crate::common::jittered_boxes(0.2..5.0, 0.05..0.25)
}

/// Kuhn boxes of any aspect ratio: every tet is an orthoscheme, so L is an M-matrix.
fn kuhn_boxes() -> impl Strategy<Value = TetMesh> {
    (
        1usize..5,
        1usize..5,
        1usize..5,
        0.01f64..100.0,
        0.01f64..100.0,
        0.01f64..100.0,
    )
        .prop_map(|(a, b, c, x, y, z)| BoxSpec::new([a, b, c], [x, y, z]).build().unwrap())
}

fn system(mesh: &TetMesh, rho: f64, mu: f64) -> IterationSystem {
    IterationSystem::new(mesh, rho, mu, &Attachments::default()).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, failure_persistence: Some(Box::new(FileFailurePersistence::Direct("tests/regressions/analysis_props.txt"))), ..ProptestConfig::default() })]

    /// rho(G19), computed as the spectral radius of the (similar, symmetric) iteration matrix
    /// itself, equals (dt / h*_19)^2.
    #[test]
    fn rho_g19_is_dt_over_critical_squared(mesh in jittered(), rho in 1e-3f64..1e4, mu in 1e-2f64..1e9, f in 1e-3f64..1e3) {
        let sys = system(&mesh, rho, mu);
        let s = Spectrum::compute(&sys, EigenMethod::Dense).unwrap();
        let dt = f * s.critical_dt_plain();
        let direct = spectral_radius(&sys.op_g19(dt), EigenMethod::Dense).unwrap();
        prop_assert!(rel(direct, (dt / s.critical_dt_plain()).powi(2)) < 1e-10);
        prop_assert!(rel(s.rho_plain(dt), direct) < 1e-10);
    }

    /// On M-matrix meshes (21) converges for every time step (Appendix B's claim holds there).
    #[test]
    fn m_matrix_meshes_make_split_converge_for_every_dt(mesh in kuhn_boxes(), rho in 1e-3f64..1e4, mu in 1e-2f64..1e9, logs in prop::collection::vec(-6.0f64..6.0, 4)) {
        let fem = FemOperators::new(&mesh).unwrap();
        prop_assert!(sign_pattern(&fem.laplacian_csc(Coefficient::Uniform(1.0)).unwrap()).is_m_matrix);
        let sys = system(&mesh, rho, mu);
        let s = Spectrum::compute(&sys, EigenMethod::Dense).unwrap();
        prop_assert!(s.critical_dt_split().is_none(), "h*_21 = {:?}", s.critical_dt_split());
        prop_assert!(s.lambda_max_dinv_l <= 2.0 + 1e-12);
        for l in logs {
            let dt = s.critical_dt_plain() * 10f64.powf(l);
            let r = rho_split(&sys, dt, EigenMethod::Dense).unwrap();
            prop_assert!(r < 1.0, "rho(G21) = {} at dt = {}", r, dt);
        }
    }

    /// The critical steps are exactly where the spectral radius crosses 1.
    #[test]
    fn critical_steps_are_where_rho_crosses_one(mesh in jittered(), rho in 1e-2f64..1e3, mu in 1e2f64..1e7) {
        let sys = system(&mesh, rho, mu);
        let s = Spectrum::compute(&sys, EigenMethod::Dense).unwrap();
        let h19 = s.critical_dt_plain();
        prop_assert!(spectral_radius(&sys.op_g19(h19 * (1.0 - 1e-6)), EigenMethod::Dense).unwrap() < 1.0);
        prop_assert!(spectral_radius(&sys.op_g19(h19 * (1.0 + 1e-6)), EigenMethod::Dense).unwrap() > 1.0);
        match s.critical_dt_split() {
            Some(h21) => {
                prop_assert!(h21 > h19, "the split iteration tolerates larger steps");
                prop_assert!(rho_split(&sys, h21 * (1.0 - 1e-6), EigenMethod::Dense).unwrap() < 1.0);
                prop_assert!(rho_split(&sys, h21 * (1.0 + 1e-6), EigenMethod::Dense).unwrap() > 1.0);
                prop_assert!(s.lambda_max_dinv_l > 2.0);
            }
            None => {
                prop_assert!(s.lambda_max_dinv_l <= 2.0 + 1e-9);
                prop_assert!(rho_split(&sys, 1e6 * h19, EigenMethod::Dense).unwrap() < 1.0);
            }
        }
    }

    /// As h -> inf, rho(G21) -> max(1, lambda_max(D^-1 L) - 1).
    #[test]
    fn split_radius_limit(mesh in jittered()) {
        let sys = system(&mesh, 1.0, 1.0);
        let s = Spectrum::compute(&sys, EigenMethod::Dense).unwrap();
        let r = rho_split(&sys, 1e5 * s.critical_dt_plain(), EigenMethod::Dense).unwrap();
        prop_assert!(rel(r, s.rho_split_limit()) < 1e-6, "{} vs {}", r, s.rho_split_limit());
    }

    /// Bounds that claim sufficiency are sufficient; the printed Eq. 29 has the wrong length
    /// scaling; the exact critical step scales linearly with length.
    #[test]
    fn sufficient_bounds_are_sufficient(mesh in jittered(), rho in 1e-2f64..1e4, mu in 1e-1f64..1e9, c in 0.01f64..100.0) {
        let scaled = mesh.scaled(c);
        let p = BoundsParams { rho, mu, dt: 1e-3, attachments: Attachments::default(), method: EigenMethod::Dense, empirical: false };
        let info = mesh::LoadedMesh { mesh: scaled.clone(), info: dummy_info() }.info;
        let r = analyze(&scaled, &info, &p).unwrap();
        let a = &r.appendix_a;
        prop_assert!(a.gershgorin.safe && a.rederived_sigma_min.safe && a.rederived_altitude.safe);
        prop_assert!(a.rederived_altitude.dt <= a.gershgorin.dt * (1.0 + 1e-12));
        for b in [&a.gershgorin, &a.rederived_sigma_min, &a.rederived_altitude] {
            prop_assert!((b.length_scaling_exponent - 1.0).abs() < 1e-9);
        }
        prop_assert!((a.eq29.length_scaling_exponent + 1.0).abs() < 1e-9);
        prop_assert!((a.eq28_min_over_tets.length_scaling_exponent + 1.0).abs() < 1e-9);
        let base = Spectrum::compute(&system(&mesh, rho, mu), EigenMethod::Dense).unwrap().critical_dt_plain();
        prop_assert!(rel(a.exact_critical_dt, c * base) < 1e-9, "h*_19 scales like length");
        // Diagonal dominance of M + h^2 L is sufficient for (21) (rows may lose it while (21)
        // still converges for every h, so compare only when both steps exist).
        if let (Some(dd), Some(h21)) = (r.appendix_b.diagonal_dominance_dt, r.split.critical_dt) {
            prop_assert!(dd <= h21 * (1.0 + 1e-12));
        }
    }
}

fn dummy_info() -> diffsoft::mesh::MeshInfo {
    mesh::TetMesh::new_with(
        vec![
            nalgebra::Vector3::zeros(),
            nalgebra::Vector3::x(),
            nalgebra::Vector3::y(),
            nalgebra::Vector3::z(),
        ],
        vec![[0, 1, 2, 3]],
        Default::default(),
    )
    .unwrap()
    .info
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, failure_persistence: Some(Box::new(FileFailurePersistence::Direct("tests/regressions/analysis_props.txt"))), ..ProptestConfig::default() })]

    /// Running the iterations themselves: the observed contraction rate matches the predicted
    /// spectral radius, on both sides of 1.
    #[test]
    fn observed_contraction_matches_predicted(mesh in jittered(), target in prop::sample::select(vec![0.5, 0.8, 0.95, 1.05, 1.5]), seed in any::<u64>()) {
        let sys = system(&mesh, 1.0, 1.0);
        let s = Spectrum::compute(&sys, EigenMethod::Dense).unwrap();
        let dt = s.critical_dt_plain() * f64::sqrt(target);
        let e = contraction(&sys, dt, Scheme::Plain, s.rho_plain(dt), 20_000, seed);
        prop_assert!(e.relative_difference < 1e-3, "plain: {:?}", e);
        prop_assert!(e.observed_rate <= e.predicted_spectral_radius * (1.0 + 1e-9), "the rate approaches rho from below");
        prop_assert_eq!(e.outcome, if target < 1.0 { Outcome::Converged } else { Outcome::Diverged }, "{:?}", e);
        if target < 1.0 {
            prop_assert!(e.final_relative_residual < 1e-10, "fixed point solves (M + h^2 L) v = f: {:?}", e);
        }
        // The split scheme on both sides of its own critical step (or at dt when (21) converges
        // for every step), away from rho = 1 where any finite run stalls.
        let dts = match s.critical_dt_split() {
            Some(h21) => vec![0.7 * h21, 1.3 * h21, dt],
            None => vec![dt],
        };
        for dt in dts {
            let r21 = rho_split(&sys, dt, EigenMethod::Dense).unwrap();
            if r21 < 1e-3 || (r21 - 1.0).abs() < 0.01 {
                continue;
            }
            let e = contraction(&sys, dt, Scheme::Split, r21, 20_000, seed);
            prop_assert!(e.relative_difference < 1e-3, "split: {:?}", e);
            prop_assert!(e.observed_rate <= e.predicted_spectral_radius * (1.0 + 1e-9));
            prop_assert_eq!(e.outcome, if r21 < 1.0 { Outcome::Converged } else { Outcome::Diverged });
        }
    }
}

/// Dense and Krylov eigenvalues agree to 1e-8 relative on mid-size meshes (jittered boxes and a
/// real paper mesh), for every quantity behind the critical steps and spectral radii.
#[test]
fn krylov_matches_dense_on_mid_size_meshes() {
    let mut meshes: Vec<(String, TetMesh)> = vec![
        (
            "jittered kuhn 7x7x7".into(),
            BoxSpec::new([7, 7, 7], [1.0, 1.2, 0.8]).jitter(0.2, 1).build().unwrap(),
        ),
        (
            "five-split 8x6x5".into(),
            BoxSpec::new([8, 6, 5], [2.0, 1.0, 1.0])
                .split(CellSplit::Five)
                .jitter(0.15, 2)
                .build()
                .unwrap(),
        ),
        (
            "regular kuhn 9x6x6".into(),
            BoxSpec::new([9, 6, 6], [3.0, 1.0, 1.0]).build().unwrap(),
        ),
    ];
    let baymax = mesh::load(crate::common::root().join("verification/paper/baymax/baymax500_tet.obj")).unwrap();
    meshes.push(("baymax".into(), baymax.mesh));
    for (name, m) in &meshes {
        let sys = system(m, 3.0, 1e4);
        assert!(sys.n() >= 256, "{name}: mid-size means Krylov applies");
        let d = Spectrum::compute(&sys, EigenMethod::Dense).unwrap();
        let k = Spectrum::compute(&sys, EigenMethod::Krylov).unwrap();
        assert_eq!(k.method, EigenMethod::Krylov);
        assert!(
            rel(k.lambda_max_minv_l, d.lambda_max_minv_l) < 1e-8,
            "{name}: {} vs {}",
            k.lambda_max_minv_l,
            d.lambda_max_minv_l
        );
        assert!(rel(k.lambda_max_dinv_l, d.lambda_max_dinv_l) < 1e-8, "{name}");
        match (k.critical_dt_split(), d.critical_dt_split()) {
            (Some(a), Some(b)) => assert!(rel(a, b) < 1e-8, "{name}: h*_21 {a} vs {b}"),
            (None, None) => {}
            other => panic!("{name}: h*_21 disagree: {other:?}"),
        }
        for f in [0.5, 2.0, 20.0] {
            let dt = f * d.critical_dt_plain();
            let rd = rho_split(&sys, dt, EigenMethod::Dense).unwrap();
            let rk = rho_split(&sys, dt, EigenMethod::Krylov).unwrap();
            assert!(rel(rk, rd) < 1e-8, "{name}: rho21({dt}) {rk} vs {rd}");
        }
    }
}

/// Attachments of 1e20 (the paper's) are handled in their Dirichlet limit for h*_21; the value
/// agrees with the directly computed one for attachments that are stiff but resolvable.
#[test]
fn stiff_attachments_reach_their_dirichlet_limit() {
    let m = BoxSpec::new([4, 3, 3], [2.0, 1.0, 1.0]).jitter(0.2, 5).build().unwrap();
    let pinned: Vec<usize> = (0..m.num_vertices()).filter(|&i| m.vertices[i].x < 0.3).collect();
    assert!(!pinned.is_empty());
    let base = system(&m, 1.0, 1.0);
    let dmax = base.diag.iter().fold(0.0f64, |a, b| a.max(*b));
    let h = |w: f64| {
        let sys = IterationSystem::new(
            &m,
            1.0,
            1.0,
            &Attachments {
                vertices: pinned.clone(),
                stiffness: w,
            },
        )
        .unwrap();
        let s = Spectrum::compute(&sys, EigenMethod::Dense).unwrap();
        (
            s.critical_dt_split(),
            s.split_critical_eliminated_rows,
            s.lambda_max_dinv_l,
        )
    };
    let (h_moderate, elim_moderate, _) = h(1e6 * dmax);
    let (h_stiff, elim_stiff, lam) = h(1e20);
    assert_eq!(elim_moderate, 0);
    assert_eq!(elim_stiff, pinned.len());
    match (h_moderate, h_stiff) {
        (Some(a), Some(b)) => assert!(rel(a, b) < 1e-4, "{a} vs {b}"),
        (None, None) => assert!(lam <= 2.0),
        other => panic!("{other:?}"),
    }
}

#[test]
fn appendix_arithmetic_is_reproduced() {
    let p = appendix::paper_arithmetic().unwrap();
    assert!(p.reproduced);
    assert!((p.eq29_inverse_dt - 1934.2).abs() < 0.1, "{}", p.eq29_inverse_dt);
    // Closed form for one regular tet: edge * sqrt(rho / (8 mu)).
    assert!(rel(p.exact_dt_regular_tet, 1e-2 * (1.0f64 / 2.4e6).sqrt()) < 1e-10);
    assert!(p.printed_over_exact > 10.0, "Eq. 29 is unsafe by a wide margin");
}

#[test]
fn appendix_b_fails_on_a_real_mesh_and_the_verdict_matches_the_radius() {
    let m = mesh::load(crate::common::root().join("verification/paper/bridgesus/bridgesus200_tet_cen.obj")).unwrap();
    let mesh = m.mesh.scaled(0.05);
    let sys = system(&mesh, 10.0, 2e5);
    let s = Spectrum::compute(&sys, EigenMethod::Dense).unwrap();
    let h21 = s
        .critical_dt_split()
        .expect("bridgesus has obtuse tets with lambda_max(D^-1 L) > 2");
    assert!(s.lambda_max_dinv_l > 2.0);
    assert!(rho_split(&sys, 2.0 * h21, EigenMethod::Dense).unwrap() > 1.0);
    assert!(gershgorin_dt(&sys) <= s.critical_dt_plain());
}

#[test]
fn step_31_fails_exactly_for_tets_with_obtuse_dihedral_angles() {
    use diffsoft::mesh::quality::quality;
    let fem_ok = |verts: Vec<nalgebra::Vector3<f64>>| {
        let m = TetMesh::new(verts, vec![[0, 1, 2, 3]]).unwrap();
        let fem = FemOperators::new(&m).unwrap();
        let sys = IterationSystem::from_fem(
            &fem,
            Coefficient::Uniform(1.0),
            Coefficient::Uniform(1.0),
            &Attachments::default(),
        )
        .unwrap();
        let s = Spectrum::compute(&sys, EigenMethod::Dense).unwrap();
        let sign = sign_pattern(&fem.laplacian_csc(Coefficient::Uniform(1.0)).unwrap());
        let q = quality(&m);
        let b = appendix::appendix_b(
            &fem,
            &sys,
            &s,
            sign.positive_offdiagonal_entries,
            q.tets_with_obtuse_dihedral,
            sign.rows_not_diagonally_dominant,
        );
        (
            b.tets_violating_step_31,
            q.tets_with_obtuse_dihedral,
            sign.positive_offdiagonal_entries,
        )
    };
    use nalgebra::Vector3 as V;
    // Right-corner tet: three right angles, no obtuse one.
    assert_eq!(fem_ok(vec![V::zeros(), V::x(), V::y(), V::z()]), (0, 0, 0));
    // A flattened tet (apex close to the base centroid) has obtuse dihedral angles.
    let (viol, obtuse, pos) = fem_ok(vec![
        V::new(0.0, 0.0, 0.0),
        V::new(1.0, 0.0, 0.0),
        V::new(0.5, 0.9, 0.0),
        V::new(0.5, 0.3, 0.05),
    ]);
    assert_eq!((viol, obtuse), (1, 1));
    assert!(pos > 0);
}
