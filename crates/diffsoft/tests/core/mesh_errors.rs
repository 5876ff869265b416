//! Every class of bad mesh input gets a clear error that names the file and the line (or the
//! element), in every format; inverted tets are re-oriented, not rejected.

use crate::common::{tmp_dir, write};
use diffsoft::mesh::{self, MeshError, MeshErrorKind};

const TET_V: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n";

fn obj_err(name: &str, text: &str) -> MeshError {
    let dir = tmp_dir(name);
    let path = write(&dir, &format!("{name}.obj"), text);
    let e = mesh::load(&path).expect_err("must be rejected");
    assert!(
        e.location.path.ends_with(&format!("{name}.obj")),
        "error names the file: {e}"
    );
    e
}

fn assert_line(e: &MeshError, line: usize) {
    assert_eq!(e.location.line, Some(line), "wrong line in: {e}");
    assert!(
        e.to_string().contains(&format!(":{line}: ")),
        "message shows file:line: {e}"
    );
}

#[test]
fn obj_bad_number_names_line_and_token() {
    let e = obj_err("badnum", "v 0 0 0\nv 1 0 0\nv 0 1.5x 0\nv 0 0 1\nt 0 1 2 3\n");
    assert_line(&e, 3);
    assert!(matches!(&e.kind, MeshErrorKind::BadNumber { found, .. } if found == "1.5x"));
}

#[test]
fn obj_nan_and_inf_are_rejected() {
    for (i, tok) in ["nan", "NaN", "inf", "-inf", "1e400"].iter().enumerate() {
        let e = obj_err(
            &format!("nonfinite{i}"),
            &format!("v 0 0 0\nv 1 0 0\nv 0 {tok} 0\nv 0 0 1\nt 0 1 2 3\n"),
        );
        assert_line(&e, 3);
        assert!(matches!(&e.kind, MeshErrorKind::NonFinite(t) if t == tok), "{e}");
    }
}

#[test]
fn obj_index_out_of_range_names_tet_line() {
    let e = obj_err("oor", &format!("{TET_V}t 0 1 2 3\nt 0 1 2 4\n"));
    assert_line(&e, 6);
    assert!(matches!(
        e.kind,
        MeshErrorKind::IndexOutOfRange { tet: 1, index: 4, .. }
    ));
    let e = obj_err("neg", &format!("{TET_V}t 0 1 -2 3\n"));
    assert!(matches!(e.kind, MeshErrorKind::IndexOutOfRange { index: -2, .. }));
}

#[test]
fn obj_one_based_file_gets_a_hint() {
    let e = obj_err("onebased", &format!("{TET_V}t 1 2 3 4\n"));
    assert!(e.to_string().contains("1-based"), "{e}");
}

#[test]
fn obj_repeated_vertex() {
    let e = obj_err("rep", &format!("{TET_V}t 0 1 1 3\n"));
    assert_line(&e, 5);
    assert!(matches!(e.kind, MeshErrorKind::RepeatedVertex { tet: 0, vertex: 1 }));
}

#[test]
fn obj_zero_and_near_zero_volume() {
    let e = obj_err("flat", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nt 0 1 2 3\n");
    assert_line(&e, 5);
    assert!(matches!(e.kind, MeshErrorKind::DegenerateTet { tet: 0, .. }));
    let e = obj_err("sliver", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0.3 0.3 1e-12\nt 0 1 2 3\n");
    assert!(matches!(e.kind, MeshErrorKind::DegenerateTet { .. }), "{e}");
    assert!(e.to_string().contains("degenerate"));
    // A thin but valid tet passes.
    let dir = tmp_dir("thin");
    let p = write(
        &dir,
        "thin.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0.3 0.3 1e-3\nt 0 1 2 3\n",
    );
    assert!(mesh::load(&p).is_ok());
}

#[test]
fn obj_truncated_lines_and_missing_tets() {
    let e = obj_err("shortv", "v 0 0 0\nv 1 0\n");
    assert_line(&e, 2);
    assert!(matches!(e.kind, MeshErrorKind::Syntax(_)));
    let e = obj_err("shortt", &format!("{TET_V}t 0 1 2\n"));
    assert_line(&e, 5);
    let e = obj_err("notets", TET_V);
    assert_eq!(e.kind, MeshErrorKind::NoTets);
    let e = obj_err("junk", &format!("{TET_V}tet 0 1 2 3\n"));
    assert_line(&e, 5);
    assert!(e.to_string().contains("unknown OBJ statement 'tet'"));
}

#[test]
fn inverted_tets_are_reoriented_and_counted() {
    let dir = tmp_dir("inverted");
    let p = write(&dir, "inv.obj", &format!("{TET_V}v 1 1 1\nt 0 2 1 3\nt 1 2 3 4\n"));
    let loaded = mesh::load(&p).unwrap();
    assert_eq!(loaded.info.reoriented_tets, 1);
    assert_eq!(loaded.info.first_reoriented, vec![0]);
    for t in 0..loaded.mesh.num_tets() {
        assert!(loaded.mesh.signed_volume(t) > 0.0);
    }
}

#[test]
fn unused_vertices_are_dropped_and_counted_with_file_ids() {
    let dir = tmp_dir("unused");
    let p = write(
        &dir,
        "u.obj",
        "v 9 9 9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 1 2 3 4\n",
    );
    let loaded = mesh::load(&p).unwrap();
    assert_eq!(loaded.info.dropped_nodes, 1);
    assert_eq!(loaded.mesh.num_vertices(), 4);
    assert_eq!(loaded.info.file_ids, vec![1, 2, 3, 4]);
}

#[test]
fn missing_file_and_unknown_extension() {
    let e = mesh::load("/nonexistent/dir/mesh.obj").unwrap_err();
    assert!(matches!(e.kind, MeshErrorKind::Io(_)));
    assert!(e.to_string().starts_with("/nonexistent/dir/mesh.obj"));
    let dir = tmp_dir("ext");
    let p = write(&dir, "mesh.stl", "solid");
    let e = mesh::load(&p).unwrap_err();
    assert!(matches!(e.kind, MeshErrorKind::UnsupportedFormat(_)), "{e}");
}

// ---------------------------------------------------------------- TetGen

const NODE: &str = "# a tet and a half\n5 3 0 0\n1 0 0 0\n2 1 0 0 # comment\n3 0 1 0\n4 0 0 1\n\n5 1 1 1\n";
const ELE: &str = "2 4 0\n1 1 2 3 4\n2 2 3 4 5\n";

fn tetgen_err(name: &str, node: &str, ele: &str) -> MeshError {
    let dir = tmp_dir(name);
    write(&dir, "m.node", node);
    let p = write(&dir, "m.ele", ele);
    mesh::load(&p).expect_err("must be rejected")
}

#[test]
fn tetgen_one_based_with_comments_loads() {
    let dir = tmp_dir("tg1");
    write(&dir, "m.node", NODE);
    let p = write(&dir, "m.ele", ELE);
    let m = mesh::load(&p).unwrap();
    assert_eq!((m.mesh.num_vertices(), m.mesh.num_tets()), (5, 2));
    assert_eq!(m.info.file_ids, vec![1, 2, 3, 4, 5]);
    // Either file name of the pair works.
    assert_eq!(mesh::load(dir.join("m.node")).unwrap().mesh, m.mesh);
}

#[test]
fn tetgen_truncated_node_file() {
    let e = tetgen_err(
        "tgtrunc",
        "5 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n",
        "1 4 0\n0 0 1 2 3\n",
    );
    assert!(e.location.path.ends_with("m.node"), "{e}");
    assert!(matches!(e.kind, MeshErrorKind::Truncated(_)), "{e}");
    assert!(e.to_string().contains("5 nodes"), "{e}");
}

#[test]
fn tetgen_truncated_ele_file() {
    let e = tetgen_err("tgtrunce", NODE, "3 4 0\n1 1 2 3 4\n2 2 3 4 5\n");
    assert!(e.location.path.ends_with("m.ele"));
    assert!(matches!(e.kind, MeshErrorKind::Truncated(_)));
    assert_line(&e, 3);
}

/// A header that announces fewer entries than the file holds is refused where the first extra
/// entry is (TetGen would read only the announced ones, dropping the rest without a word).
#[test]
fn tetgen_files_longer_than_their_headers_are_refused() {
    let e = tetgen_err("tgmoree", NODE, "1 4 0\n1 1 2 3 4\n2 2 3 4 5\n");
    assert!(e.location.path.ends_with("m.ele"), "{e}");
    assert_line(&e, 3);
    assert!(e.to_string().contains("more lines than the header's 1 tets"), "{e}");
    let e = tetgen_err("tgmoren", &NODE.replacen("5 3 0 0", "4 3 0 0", 1), "1 4 0\n1 1 2 3 4\n");
    assert!(e.location.path.ends_with("m.node"), "{e}");
    assert!(e.to_string().contains("more lines than the header's 4 nodes"), "{e}");
}

#[test]
fn tetgen_index_out_of_range_and_bad_numbers() {
    let e = tetgen_err("tgoor", NODE, "1 4 0\n1 1 2 3 6\n");
    assert_line(&e, 2);
    assert!(matches!(e.kind, MeshErrorKind::IndexOutOfRange { index: 6, .. }));
    assert!(e.to_string().contains("1..=5"), "{e}");
    let e = tetgen_err(
        "tgbad",
        "4 3 0 0\n0 0 0 0\n1 1 0 zero\n2 0 1 0\n3 0 0 1\n",
        "1 4 0\n0 0 1 2 3\n",
    );
    assert!(e.location.path.ends_with("m.node"));
    assert_line(&e, 3);
    let e = tetgen_err(
        "tginf",
        "4 3 0 0\n0 0 0 0\n1 1 0 inf\n2 0 1 0\n3 0 0 1\n",
        "1 4 0\n0 0 1 2 3\n",
    );
    assert!(matches!(e.kind, MeshErrorKind::NonFinite(_)));
    let e = tetgen_err(
        "tgseq",
        "4 3 0 0\n0 0 0 0\n2 1 0 0\n2 0 1 0\n3 0 0 1\n",
        "1 4 0\n0 0 1 2 3\n",
    );
    assert_line(&e, 3);
    assert!(e.to_string().contains("out of sequence"));
}

#[test]
fn tetgen_repeated_vertex_and_degenerate() {
    let e = tetgen_err("tgrep", NODE, "1 4 0\n1 1 2 2 4\n");
    assert!(matches!(e.kind, MeshErrorKind::RepeatedVertex { vertex: 2, .. }));
    assert_line(&e, 2);
    let e = tetgen_err(
        "tgflat",
        "4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 1 1 0\n",
        "1 4 0\n0 0 1 2 3\n",
    );
    assert!(matches!(e.kind, MeshErrorKind::DegenerateTet { .. }));
    assert_line(&e, 2);
}

#[test]
fn tetgen_missing_ele_file_names_it() {
    let dir = tmp_dir("tgmissing");
    let p = write(&dir, "only.node", NODE);
    let e = mesh::load(&p).unwrap_err();
    assert!(e.location.path.ends_with("only.ele"), "{e}");
    assert!(matches!(e.kind, MeshErrorKind::Io(_)));
}

#[test]
fn tetgen_quadratic_tets_keep_corners() {
    let node =
        "10 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n4 .5 0 0\n5 0 .5 0\n6 0 0 .5\n7 .5 .5 0\n8 0 .5 .5\n9 .5 0 .5\n";
    let dir = tmp_dir("tgquad");
    write(&dir, "q.node", node);
    let p = write(&dir, "q.ele", "1 10 0\n0 0 1 2 3 4 5 6 7 8 9\n");
    let m = mesh::load(&p).unwrap();
    assert_eq!((m.mesh.num_vertices(), m.info.dropped_nodes), (4, 6));
}

// ---------------------------------------------------------------- Gmsh

const MSH22: &str = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n6\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n6 7 7 7\n$EndNodes\n$Elements\n3\n1 2 2 0 1 1 2 3\n2 4 2 0 1 1 2 3 4\n3 4 2 0 1 2 3 4 5\n$EndElements\n";

fn msh_err(name: &str, text: &str) -> MeshError {
    let dir = tmp_dir(name);
    let p = write(&dir, &format!("{name}.msh"), text);
    let e = mesh::load(&p).expect_err("must be rejected");
    assert!(e.location.path.ends_with(".msh"));
    e
}

#[test]
fn gmsh22_loads_tets_only_and_drops_unused_nodes() {
    let dir = tmp_dir("g22");
    let p = write(&dir, "m.msh", MSH22);
    let m = mesh::load(&p).unwrap();
    assert_eq!((m.mesh.num_vertices(), m.mesh.num_tets()), (5, 2));
    assert_eq!(m.info.dropped_nodes, 1, "node 6 is used by no tet");
    assert_eq!(m.info.skipped_elements, 1, "the triangle is skipped");
    assert_eq!(m.info.format, mesh::MeshFormat::Gmsh22);
}

#[test]
fn gmsh22_truncated_and_overfull_sections() {
    let e = msh_err("g22trunc", &MSH22[..MSH22.find("3 4 2").unwrap()]);
    assert!(matches!(e.kind, MeshErrorKind::Truncated(_)), "{e}");
    assert!(e.to_string().contains("3 elements"), "{e}");
    let e = msh_err("g22noend", MSH22.trim_end_matches("$EndElements\n"));
    assert!(matches!(e.kind, MeshErrorKind::Truncated(_)), "{e}");
    let overfull = MSH22.replace("$Elements\n3\n", "$Elements\n2\n");
    let e = msh_err("g22over", &overfull);
    assert!(e.to_string().contains("expected $EndElements"), "{e}");
}

#[test]
fn gmsh22_bad_number_undefined_node_nan() {
    let e = msh_err("g22bad", &MSH22.replace("3 0 1 0", "3 0 1x 0"));
    assert_line(&e, 8);
    let e = msh_err("g22undef", &MSH22.replace("2 4 2 0 1 1 2 3 4", "2 4 2 0 1 1 2 3 44"));
    assert_line(&e, 16);
    assert!(
        matches!(e.kind, MeshErrorKind::IndexOutOfRange { index: 44, .. }),
        "{e}"
    );
    let e = msh_err("g22nan", &MSH22.replace("5 1 1 1", "5 1 nan 1"));
    assert!(matches!(e.kind, MeshErrorKind::NonFinite(_)));
    assert_line(&e, 10);
}

#[test]
fn gmsh_binary_and_unsupported_versions() {
    let e = msh_err("gbin", &MSH22.replace("2.2 0 8", "2.2 1 8"));
    assert!(e.to_string().contains("binary"), "{e}");
    assert_line(&e, 2);
    let e = msh_err("g40", &MSH22.replace("2.2 0 8", "4.0 0 8"));
    assert!(e.to_string().contains("4.0"), "{e}");
    let e = msh_err("gnone", "$Nodes\n0\n$EndNodes\n");
    assert!(matches!(e.kind, MeshErrorKind::Syntax(_)), "{e}");
}

const MSH41: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 0 1\n1 0 0 0 1 1 1 0 0\n$EndEntities\n$Nodes\n2 6 1 6\n3 1 0 5\n1\n2\n3\n4\n5\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 1 1\n0 2 1 1\n6\n7 7 7 0.5\n$EndNodes\n$Elements\n2 3 1 3\n3 1 4 2\n1 1 2 3 4\n2 2 3 4 5\n2 1 2 1\n3 1 2 3\n$EndElements\n";

#[test]
fn gmsh41_loads_with_entities_and_parametric_nodes() {
    let dir = tmp_dir("g41");
    let p = write(&dir, "m.msh", MSH41);
    let m = mesh::load(&p).unwrap();
    assert_eq!((m.mesh.num_vertices(), m.mesh.num_tets()), (5, 2));
    assert_eq!((m.info.dropped_nodes, m.info.skipped_elements), (1, 1));
    assert_eq!(m.info.format, mesh::MeshFormat::Gmsh41);
}

#[test]
fn gmsh41_truncated_and_inconsistent_headers() {
    let e = msh_err("g41trunc", &MSH41[..MSH41.find("0 0 1\n1 1 1").unwrap()]);
    assert!(matches!(e.kind, MeshErrorKind::Truncated(_)), "{e}");
    let e = msh_err("g41count", &MSH41.replace("2 6 1 6", "2 7 1 7"));
    assert!(e.to_string().contains("announces 7 nodes"), "{e}");
    assert_line(&e, 9);
    let e = msh_err("g41rep", &MSH41.replace("2 2 3 4 5", "2 2 3 3 5"));
    assert!(matches!(e.kind, MeshErrorKind::RepeatedVertex { vertex: 3, .. }));
    assert_line(&e, 29);
}

/// Counts a header declares are never trusted for allocation or arithmetic: a block that claims
/// 2^64-1 or 1e12 entries, or an element with 2^64-1 tags, is an error naming the file and line
/// (the reader stops at the end of what the file holds), never a panic or an abort.
#[test]
fn gmsh_astronomical_declared_counts_are_errors() {
    let max = u64::MAX.to_string();
    for (name, text) in [
        ("g41nmax", MSH41.replace("3 1 0 5", &format!("3 1 0 {max}"))),
        ("g41n1e12", MSH41.replace("3 1 0 5", "3 1 0 1000000000000")),
        ("g41blocks", MSH41.replace("2 6 1 6", &format!("{max} 6 1 6"))),
        ("g41emax", MSH41.replace("3 1 4 2", &format!("3 1 4 {max}"))),
        ("g22nmax", MSH22.replace("$Nodes\n6\n", &format!("$Nodes\n{max}\n"))),
        ("g22emax", MSH22.replace("$Elements\n3\n", "$Elements\n1000000000000\n")),
        (
            "g22tags",
            MSH22.replace("2 4 2 0 1 1 2 3 4", &format!("2 4 {max} 0 1 1 2 3 4")),
        ),
        (
            "g22tags2",
            MSH22.replace("2 4 2 0 1 1 2 3 4", &format!("2 4 {} 0 1 1 2 3 4", u64::MAX - 5)),
        ),
    ] {
        assert_ne!(
            text,
            if name.starts_with("g41") { MSH41 } else { MSH22 },
            "{name}: pattern not found"
        );
        let e = msh_err(name, &text);
        assert!(e.location.line.is_some(), "{name}: names a line: {e}");
        assert!(
            matches!(
                e.kind,
                MeshErrorKind::Truncated(_) | MeshErrorKind::Syntax(_) | MeshErrorKind::BadNumber { .. }
            ),
            "{name}: {e}"
        );
    }
}

/// A tet whose corners sit at the same four positions as another's, through repeated vertices,
/// is refused like a tet that repeats another's vertices (the solid would count twice), naming
/// both tets, the file's vertices and the line; tets that share only a face's positions (a
/// crack in the mesh) load.
#[test]
fn a_tet_lying_on_another_through_repeated_vertices_is_refused() {
    let e = obj_err("coincident", &format!("{TET_V}v 0 0 0\nt 0 1 2 3\nt 4 1 3 2\n"));
    assert_line(&e, 7);
    assert!(
        matches!(&e.kind, MeshErrorKind::CoincidentTet { tet: 1, first: 0, vertices } if *vertices == [4, 1, 3, 2]),
        "{e}"
    );
    assert!(e.to_string().contains("merge the repeated vertices"), "{e}");
    // -0 and 0 are one place.
    let e = obj_err("coincident_zero", &format!("{TET_V}v -0 0 -0\nt 0 1 2 3\nt 4 1 3 2\n"));
    assert!(matches!(&e.kind, MeshErrorKind::CoincidentTet { .. }), "{e}");
    let dir = tmp_dir("crack");
    let path = write(
        &dir,
        "crack.obj",
        &format!("{TET_V}v 0 0 0\nv 1 1 1\nt 0 1 2 3\nt 4 1 2 5\n"),
    );
    assert_eq!(mesh::load(&path).unwrap().mesh.num_tets(), 2);
}
