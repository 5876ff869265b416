//! Paper scenes imported from the contents of their files in memory
//! (`scene::paper::import_carried_bytes`): the same scene as from disk, only carried files
//! read, and every error naming the file as shown.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use diffsoft::mesh::{self, generate::BoxSpec};
use diffsoft::scene::paper::{self, CarriedFile};
use diffsoft::scene::{LoadOptions, Scene, SceneError};
use serde_json::{json, Value};

use crate::common::{root, tmp_dir, write};

fn paper_scene(name: &str) -> PathBuf {
    root().join("verification/paper").join(name)
}

fn read_json(path: &Path) -> Value {
    diffsoft::scene::json::parse_lenient(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The names of the files the scene at `path` names (meshes, muscles, cloths, obstacles), each
/// with the other half of a TetGen pair.
fn named_files(value: &Value) -> Vec<String> {
    let mut names = Vec::new();
    for (list, keys) in [
        ("Meshes", &["Obj filename", "Muscle filename"][..]),
        ("Clothes", &["Obj filename"][..]),
        ("Obstacles", &["Obj filename"][..]),
    ] {
        for entry in value.get(list).and_then(Value::as_array).into_iter().flatten() {
            for key in keys {
                if let Some(name) = entry.get(*key).and_then(Value::as_str) {
                    names.push(name.to_string());
                    names.extend(paper::companion_file(name));
                }
            }
        }
    }
    names.dedup();
    names
}

/// Every file the scene at `path` names, read from where the importer finds it and shown by
/// that path.
fn carried_from_disk(path: &Path, value: &Value) -> HashMap<String, CarriedFile> {
    named_files(value)
        .into_iter()
        .map(|name| {
            let found = paper::find_file(path, &name)
                .or_else(|| {
                    // A TetGen half lies beside the other one.
                    let first = paper::companion_file(&name)?;
                    let other = paper::find_file(path, &first)?;
                    Some(other.with_file_name(Path::new(&name).file_name()?))
                })
                .unwrap_or_else(|| panic!("{name} not found beside {}", path.display()));
            let bytes = std::fs::read(&found).unwrap();
            (name, CarriedFile::new(found, bytes))
        })
        .collect()
}

/// The scene at `path` imported from disk and from its files in memory.
fn both(path: &Path) -> (Scene, Scene) {
    let value = read_json(path);
    let carried = carried_from_disk(path, &value);
    let disk = paper::import(path, &value, LoadOptions::default()).unwrap();
    let memory = paper::import_carried_bytes(path, &value, LoadOptions::default(), &carried).unwrap();
    (disk, memory)
}

/// `a` and `b` are the same scene: the same model (every field, as `Debug` writes it: bit for
/// bit), settings, mesh details and notes.
fn assert_same(a: &Scene, b: &Scene) {
    assert_eq!(a.model.n(), b.model.n());
    assert_eq!(a.model.rest(), b.model.rest());
    assert_eq!(a.model.tets(), b.model.tets());
    assert_eq!(a.model.fixed(), b.model.fixed());
    assert_eq!(a.model.mass(), b.model.mass());
    assert_eq!(a.model.obstacles().len(), b.model.obstacles().len());
    assert_eq!(a.meshes, b.meshes);
    assert_eq!(a.notes, b.notes);
    assert_eq!(
        serde_json::to_value(&a.settings).unwrap(),
        serde_json::to_value(&b.settings).unwrap()
    );
    assert_eq!(format!("{:?}", a.model), format!("{:?}", b.model));
}

#[test]
fn paper_scenes_carried_in_memory_import_as_from_disk() {
    let mut imported = HashMap::new();
    for name in [
        "bridgesus/bridgesus.json",   // attachments
        "baymax/baymax.json",         // an obstacle
        "cloth_ball/cloth_ball.json", // a cloth, collisions between bodies
        "octopus/octopus.json",       // a muscle file
        "droneman/droneman.json",     // two meshes, pneumatic actuators
        "fish/fish.json",             // a skeleton
    ] {
        let (disk, memory) = both(&paper_scene(name));
        assert!(disk.model.n() > 0, "{name}");
        assert_same(&disk, &memory);
        imported.insert(name, memory);
    }
    // The features the scenes above are there for did come through.
    let groups = &imported["octopus/octopus.json"]
        .model
        .actuators()
        .expect("muscles")
        .groups;
    assert!(groups.iter().any(|g| g.name.starts_with("muscle")));
    let cloth = imported["cloth_ball/cloth_ball.json"].model.cloth().expect("cloth");
    assert_eq!(cloth.num_triangles(), 128);
    assert_eq!(imported["baymax/baymax.json"].model.obstacles().len(), 1);
    assert_eq!(
        imported["fish/fish.json"].model.skeleton().map(|s| s.bones.len()),
        Some(4)
    );
}

#[test]
fn a_carried_scene_reads_only_its_carried_files() {
    let path = paper_scene("bridgesus/bridgesus.json");
    let value = read_json(&path);
    let name = "bridgesus/bridgesus200_tet_cen.obj";
    // The mesh lies at its name on disk, but is not carried: refused, naming it.
    assert!(paper::find_file(&path, name).is_some());
    let e = paper::import_carried_bytes(&path, &value, LoadOptions::default(), &HashMap::new()).unwrap_err();
    assert!(matches!(e, SceneError::Invalid { .. }), "{e:?}");
    assert!(
        e.to_string().contains(&format!("cannot find \"{name}\"")) && e.to_string().contains("not one of them"),
        "{e}"
    );
    // The same with the files carried on disk (`import_carried`): only the mapped paths.
    let at = HashMap::from([(name.to_string(), paper::find_file(&path, name).unwrap())]);
    let on_disk = paper::import_carried(&path, &value, LoadOptions::default(), &at).unwrap();
    assert_same(&paper::import(&path, &value, LoadOptions::default()).unwrap(), &on_disk);
    let e = paper::import_carried(&path, &value, LoadOptions::default(), &HashMap::new()).unwrap_err();
    assert!(e.to_string().contains(&format!("cannot find \"{name}\"")), "{e}");
    // Carried under its name, a different mesh is what the scene gets (one tet, not the
    // bridge's 212 vertices), shown by the path it is carried under.
    let mut value = value;
    if let Some(mesh) = value["Meshes"][0].as_object_mut() {
        mesh.remove("Attach Verts");
    }
    let tet = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3\n";
    let carried = HashMap::from([(name.to_string(), CarriedFile::new("elsewhere/tet.obj", tet))]);
    let s = paper::import_carried_bytes(&path, &value, LoadOptions::default(), &carried).unwrap();
    assert_eq!((s.model.n(), s.model.tets().len()), (4, 1));
    assert_eq!(s.meshes[0].path, "elsewhere/tet.obj");
}

/// The bridge scene with its mesh carried as `bytes`, shown as `shown`.
fn bridge_with_mesh(shown: &str, bytes: Vec<u8>) -> Result<Scene, SceneError> {
    let path = paper_scene("bridgesus/bridgesus.json");
    let value = read_json(&path);
    let carried = HashMap::from([(
        "bridgesus/bridgesus200_tet_cen.obj".to_string(),
        CarriedFile::new(shown, bytes),
    )]);
    paper::import_carried_bytes(&path, &value, LoadOptions::default(), &carried)
}

#[test]
fn carried_files_that_are_not_text_or_not_meshes_are_refused_naming_them() {
    let shown = "/original/place/bridge.obj";
    // Not UTF-8: the mesh reader's error for a binary file, naming the shown path.
    let e = bridge_with_mesh(shown, vec![b'v', b' ', 0xff, 0xfe, b'\n']).unwrap_err();
    let SceneError::Mesh(m) = &e else { panic!("{e:?}") };
    assert_eq!(m.location.path, shown);
    assert!(matches!(m.kind, mesh::MeshErrorKind::UnsupportedFormat(_)), "{m:?}");
    assert!(e.to_string().contains("not UTF-8"), "{e}");
    // Malformed: the parser's error, at the shown path and line.
    let e = bridge_with_mesh(shown, b"v 0 0 0\nv nonsense\n".to_vec()).unwrap_err();
    let SceneError::Mesh(m) = &e else { panic!("{e:?}") };
    assert_eq!((m.location.path.as_str(), m.location.line), (shown, Some(2)));
    assert!(e.to_string().starts_with(&format!("{shown}:2")), "{e}");
    // A byte-order mark is dropped, as from disk.
    let mut bom = b"\xef\xbb\xbf".to_vec();
    bom.extend(std::fs::read(paper_scene("bridgesus/bridgesus200_tet_cen.obj")).unwrap());
    let s = bridge_with_mesh(shown, bom).unwrap();
    assert_eq!(s.model.n(), 212);
    assert_eq!(s.meshes[0].path, shown);
}

#[test]
fn carried_muscle_and_cloth_files_not_text_or_malformed_are_refused_naming_them() {
    for (scene, key_of, malformed, at) in [
        ("octopus/octopus.json", "Muscle filename", "0 0 x y\n", "line 1"),
        ("cloth_ball/cloth_ball.json", "Clothes", "v 0 0 0\nf 1 2 x\n", ":2"),
    ] {
        let path = paper_scene(scene);
        let value = read_json(&path);
        let mut carried = carried_from_disk(&path, &value);
        let name = if key_of == "Clothes" {
            value["Clothes"][0]["Obj filename"].as_str().unwrap()
        } else {
            value["Meshes"][0][key_of].as_str().unwrap()
        };
        let shown = format!("/shown/{name}");
        carried.insert(name.to_string(), CarriedFile::new(&shown, vec![0xc3, 0x28, b'\n']));
        let e = paper::import_carried_bytes(&path, &value, LoadOptions::default(), &carried).unwrap_err();
        let text = e.to_string();
        assert!(
            text.starts_with(&shown) && text.contains("not UTF-8"),
            "{scene}: {text}"
        );
        // Malformed text: the reader's error, naming the shown path.
        carried.insert(name.to_string(), CarriedFile::new(&shown, malformed));
        let e = paper::import_carried_bytes(&path, &value, LoadOptions::default(), &carried).unwrap_err();
        assert!(
            e.to_string().starts_with(&shown) && e.to_string().contains(at),
            "{scene}: {e}"
        );
    }
}

/// A scene in a scratch directory whose one mesh is `mesh_name`.
fn scene_with_mesh(dir: &Path, mesh_name: &str) -> (PathBuf, Value) {
    let value = json!({
        "Parameters": [{"Simulation HZ": 100}],
        "Meshes": [{"Obj filename": mesh_name, "Scale": 1.0}],
    });
    let path = write(dir, "scene.json", &value.to_string());
    (path, value)
}

#[test]
fn tetgen_pairs_and_gmsh_meshes_carried_in_memory_import_as_from_disk() {
    let dir = tmp_dir("paper-carried-formats");
    let tets = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1]).build().unwrap();
    let (node, ele) = mesh::write::tetgen(&tets, 1);
    write(&dir, "box.node", &node);
    write(&dir, "box.ele", &ele);
    write(&dir, "box.msh", &mesh::write::gmsh41(&tets));
    write(&dir, "box22.msh", &mesh::write::gmsh22(&tets));
    for name in ["box.node", "box.ele", "box.msh", "box22.msh"] {
        let (path, value) = scene_with_mesh(&dir, name);
        let carried = carried_from_disk(&path, &value);
        assert_eq!(carried.len(), if name.ends_with(".msh") { 1 } else { 2 }, "{name}");
        let disk = paper::import(&path, &value, LoadOptions::default()).unwrap();
        let memory = paper::import_carried_bytes(&path, &value, LoadOptions::default(), &carried).unwrap();
        assert_eq!(disk.model.n(), tets.num_vertices(), "{name}");
        assert_same(&disk, &memory);
    }
    // A TetGen half without its other half: refused, naming the missing one.
    let (path, value) = scene_with_mesh(&dir, "box.node");
    let mut carried = carried_from_disk(&path, &value);
    carried.remove("box.ele");
    let e = paper::import_carried_bytes(&path, &value, LoadOptions::default(), &carried).unwrap_err();
    assert!(
        e.to_string()
            .contains("cannot find \"box.ele\", the other half of the TetGen pair \"box.node\""),
        "{e}"
    );
    // A malformed .ele: the TetGen reader's error, naming the shown .ele.
    carried.insert("box.ele".into(), CarriedFile::new("/shown/box.ele", "1 4 0\n1 1 2 3\n"));
    let e = paper::import_carried_bytes(&path, &value, LoadOptions::default(), &carried).unwrap_err();
    assert!(e.to_string().starts_with("/shown/box.ele"), "{e}");
    // An extension no reader takes: refused naming the shown file and the extension.
    let (path, value) = scene_with_mesh(&dir, "box.stl");
    let carried = HashMap::from([("box.stl".to_string(), CarriedFile::new("/shown/box.stl", "solid"))]);
    let e = paper::import_carried_bytes(&path, &value, LoadOptions::default(), &carried).unwrap_err();
    assert!(
        e.to_string().starts_with("/shown/box.stl") && e.to_string().contains("extension '.stl'"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
