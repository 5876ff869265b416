//! `bounds` against reference values computed independently (numpy/scipy dense generalized
//! eigenproblems, bisection for h*_21) on random Delaunay meshes the crate never generated, one
//! per file format. See `verification/reference/independent.py`.

use crate::common::{rel, root};
use diffsoft::analysis::bounds::{analyze, BoundsParams};
use diffsoft::analysis::spectral::EigenMethod;
use diffsoft::analysis::Attachments;
use diffsoft::mesh;
use serde_json::Value;

fn check(method: EigenMethod, tol: f64) {
    let dir = root().join("verification/reference");
    let values: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("values.json")).unwrap()).unwrap();
    assert_eq!(values["schema"], "diffsoft.reference/1");
    let cases = values["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 4);
    let mut formats = std::collections::BTreeSet::new();
    for c in cases {
        let name = c["name"].as_str().unwrap();
        let loaded = mesh::load(dir.join(c["file"].as_str().unwrap())).unwrap();
        formats.insert(format!("{:?}", loaded.info.format));
        assert_eq!(
            loaded.mesh.num_vertices() as u64,
            c["vertices"].as_u64().unwrap(),
            "{name}"
        );
        assert_eq!(loaded.mesh.num_tets() as u64, c["tets"].as_u64().unwrap(), "{name}");
        assert_eq!(
            loaded.info.dropped_nodes as u64,
            c["unused_nodes"].as_u64().unwrap(),
            "{name}"
        );
        let p = BoundsParams {
            rho: c["rho"].as_f64().unwrap(),
            mu: c["mu"].as_f64().unwrap(),
            dt: c["dt"].as_f64().unwrap(),
            attachments: Attachments::default(),
            method,
            empirical: false,
        };
        let r = analyze(&loaded.mesh, &loaded.info, &p).unwrap();
        let pairs = [
            (
                "jacobi.critical_dt",
                r.jacobi.critical_dt.unwrap(),
                c["jacobi_critical_dt"].as_f64().unwrap(),
            ),
            (
                "jacobi.spectral_radius",
                r.jacobi.spectral_radius,
                c["jacobi_spectral_radius"].as_f64().unwrap(),
            ),
            (
                "split.spectral_radius",
                r.split.spectral_radius,
                c["split_spectral_radius"].as_f64().unwrap(),
            ),
        ];
        for (what, ours, theirs) in pairs {
            assert!(rel(ours, theirs) < tol, "{name} {what}: {ours} vs reference {theirs}");
        }
        match (r.split.critical_dt, c["split_critical_dt"].as_f64()) {
            // The reference bisects to 1e-13 relative in h.
            (Some(ours), Some(theirs)) => {
                assert!(rel(ours, theirs) < tol.max(1e-11), "{name} h*_21: {ours} vs {theirs}")
            }
            (None, None) => {}
            other => panic!("{name}: h*_21 {other:?}"),
        }
    }
    assert_eq!(
        formats.len(),
        4,
        "OBJ, TetGen, Gmsh 2.2 and Gmsh 4.1 are all covered: {formats:?}"
    );
}

#[test]
fn dense_matches_independent_reference() {
    check(EigenMethod::Dense, 1e-9);
}

#[test]
fn krylov_matches_independent_reference() {
    check(EigenMethod::Krylov, 1e-8);
}
