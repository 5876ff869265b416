//! The same mesh read from every format gives the same mesh and the same analysis; the paper's
//! meshes load with their published counts.

use crate::common::{root, tmp_dir, write};
use diffsoft::analysis::spectral::EigenMethod;
use diffsoft::analysis::{Attachments, IterationSystem, Spectrum};
use diffsoft::mesh::generate::{BoxSpec, CellSplit};
use diffsoft::mesh::{self, write as mw, MeshFormat};

#[test]
fn all_formats_round_trip_to_the_same_mesh_and_spectrum() {
    let m = BoxSpec::new([3, 2, 4], [1.0, 0.5, 2.0])
        .split(CellSplit::Five)
        .jitter(0.2, 9)
        .build()
        .unwrap();
    let dir = tmp_dir("roundtrip");
    let (node0, ele0) = mw::tetgen(&m, 0);
    let (node1, ele1) = mw::tetgen(&m, 1);
    write(&dir, "zero.node", &node0);
    write(&dir, "zero.ele", &ele0);
    write(&dir, "one.node", &node1);
    write(&dir, "one.ele", &ele1);
    let files = [
        (write(&dir, "m.obj", &mw::obj(&m)), MeshFormat::Obj),
        (dir.join("zero.ele"), MeshFormat::Tetgen),
        (dir.join("one.node"), MeshFormat::Tetgen),
        (write(&dir, "m22.msh", &mw::gmsh22(&m)), MeshFormat::Gmsh22),
        (write(&dir, "m41.msh", &mw::gmsh41(&m)), MeshFormat::Gmsh41),
    ];
    let reference = Spectrum::compute(
        &IterationSystem::new(&m, 2.0, 3e4, &Attachments::default()).unwrap(),
        EigenMethod::Dense,
    )
    .unwrap();
    for (path, format) in files {
        let loaded = mesh::load(&path).unwrap();
        assert_eq!(loaded.info.format, format);
        assert_eq!(loaded.mesh, m, "{}", path.display());
        let s = Spectrum::compute(
            &IterationSystem::new(&loaded.mesh, 2.0, 3e4, &Attachments::default()).unwrap(),
            EigenMethod::Dense,
        )
        .unwrap();
        assert_eq!(s.lambda_max_minv_l, reference.lambda_max_minv_l);
        assert_eq!(s.critical_dt_split(), reference.critical_dt_split());
    }
}

#[test]
fn paper_meshes_load_with_their_published_counts() {
    let cases = [
        ("baymax/baymax500_tet.obj", 775, 3078, 0),
        ("bridge/bridge700_tet_cen.obj", 821, 2911, 0),
        ("bridgesus/bridgesus200_tet_cen.obj", 212, 668, 0),
        ("fish/fish400_tet.obj", 759, 3268, 0),
        ("droneman/droneman600_tet.obj", 856, 3008, 0),
        ("droneman/ball_tet.obj", 43, 80, 0),
        // Every tet of the octopus is stored with negative orientation.
        ("octopus/octopus.obj", 977, 2160, 2160),
    ];
    for (file, v, t, inverted) in cases {
        let loaded = mesh::load(root().join("verification/paper").join(file)).unwrap();
        assert_eq!((loaded.mesh.num_vertices(), loaded.mesh.num_tets()), (v, t), "{file}");
        assert_eq!(loaded.info.reoriented_tets, inverted, "{file}");
        assert_eq!(loaded.info.dropped_nodes, 0);
        assert!((0..t).all(|k| loaded.mesh.signed_volume(k) > 0.0));
    }
    // The cloth and obstacle files have no tets: a clear error, not a crash.
    let e = mesh::load(root().join("verification/paper/cloth_ball/flag2.obj")).unwrap_err();
    assert!(e.to_string().contains("no tetrahedra"), "{e}");
}

#[test]
fn generators_cover_kuhn_and_five_splits_and_jitter_is_seeded() {
    let a = BoxSpec::new([2, 2, 2], [1.0; 3]).jitter(0.2, 4).build().unwrap();
    let b = BoxSpec::new([2, 2, 2], [1.0; 3]).jitter(0.2, 4).build().unwrap();
    let c = BoxSpec::new([2, 2, 2], [1.0; 3]).jitter(0.2, 5).build().unwrap();
    assert_eq!(a, b);
    assert_ne!(a, c);
    let beam = mesh::generate::beam(4.0, 0.5, 0.5, 16, 2).build().unwrap();
    assert_eq!(beam.num_tets(), 6 * 16 * 4);
    let big = mesh::generate::box_with_about(10_000, 1.0);
    assert!((big.num_tets() as f64 / 10_000.0 - 1.0).abs() < 0.2);
}
