//! Writers for the formats the readers accept, so generated meshes can be exchanged with other
//! tools (and so every reader is tested on the same mesh written three ways).

use std::fmt::Write as _;

use super::TetMesh;

/// OBJ with `v` and 0-based `t` lines.
pub fn obj(mesh: &TetMesh) -> String {
    let mut s = String::new();
    writeln!(
        s,
        "# diffsoft tet mesh: {} vertices, {} tets",
        mesh.num_vertices(),
        mesh.num_tets()
    )
    .unwrap();
    for v in &mesh.vertices {
        writeln!(s, "v {:?} {:?} {:?}", v.x, v.y, v.z).unwrap();
    }
    for t in &mesh.tets {
        writeln!(s, "t {} {} {} {}", t[0], t[1], t[2], t[3]).unwrap();
    }
    s
}

/// TetGen `.node` and `.ele` texts with numbering starting at `base` (0 or 1).
pub fn tetgen(mesh: &TetMesh, base: usize) -> (String, String) {
    let mut node = String::new();
    writeln!(node, "# diffsoft tet mesh").unwrap();
    writeln!(node, "{} 3 0 0", mesh.num_vertices()).unwrap();
    for (i, v) in mesh.vertices.iter().enumerate() {
        writeln!(node, "{} {:?} {:?} {:?}", i + base, v.x, v.y, v.z).unwrap();
    }
    let mut ele = String::new();
    writeln!(ele, "{} 4 0", mesh.num_tets()).unwrap();
    for (i, t) in mesh.tets.iter().enumerate() {
        writeln!(
            ele,
            "{} {} {} {} {}",
            i + base,
            t[0] + base,
            t[1] + base,
            t[2] + base,
            t[3] + base
        )
        .unwrap();
    }
    (node, ele)
}

/// Gmsh ASCII 2.2 (1-based node tags, linear tets, two tags per element).
pub fn gmsh22(mesh: &TetMesh) -> String {
    let mut s = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
    writeln!(s, "{}", mesh.num_vertices()).unwrap();
    for (i, v) in mesh.vertices.iter().enumerate() {
        writeln!(s, "{} {:?} {:?} {:?}", i + 1, v.x, v.y, v.z).unwrap();
    }
    writeln!(s, "$EndNodes\n$Elements\n{}", mesh.num_tets()).unwrap();
    for (i, t) in mesh.tets.iter().enumerate() {
        writeln!(
            s,
            "{} 4 2 1 1 {} {} {} {}",
            i + 1,
            t[0] + 1,
            t[1] + 1,
            t[2] + 1,
            t[3] + 1
        )
        .unwrap();
    }
    s.push_str("$EndElements\n");
    s
}

/// Gmsh ASCII 4.1 (one volume entity, 1-based node tags, linear tets).
pub fn gmsh41(mesh: &TetMesh) -> String {
    let n = mesh.num_vertices();
    let m = mesh.num_tets();
    let mut s = String::from("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n");
    writeln!(s, "1 {n} 1 {n}\n3 1 0 {n}").unwrap();
    for i in 0..n {
        writeln!(s, "{}", i + 1).unwrap();
    }
    for v in &mesh.vertices {
        writeln!(s, "{:?} {:?} {:?}", v.x, v.y, v.z).unwrap();
    }
    writeln!(s, "$EndNodes\n$Elements\n1 {m} 1 {m}\n3 1 4 {m}").unwrap();
    for (i, t) in mesh.tets.iter().enumerate() {
        writeln!(s, "{} {} {} {} {}", i + 1, t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1).unwrap();
    }
    s.push_str("$EndElements\n");
    s
}
