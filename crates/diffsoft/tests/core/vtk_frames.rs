//! VTK frames read back with a minimal parser of their own: positions and velocities bit for
//! bit, constraint flags, principal stretches against an independent SVD, activations, contact
//! impulses after landing on the ground, the time collection, atomic writes.

use std::collections::HashMap;
use std::path::Path;

use crate::common::tmp_dir;
use diffsoft::actuator::ActuatorSpec;
use diffsoft::cloth::{grid, ClothSpec};
use diffsoft::contact::Obstacle;
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::output::FrameWriter;
use diffsoft::{BodySpec, MassSpec, Material, Model, ModelBuilder, Schedule, Settings, Simulator, SolverKind};
use nalgebra::{Matrix3, Vector3};

// ---- a minimal reader of the frames ------------------------------------------------------------

/// One `DataArray`: its type, component count and little-endian values.
struct Array {
    ty: String,
    components: usize,
    bytes: Vec<u8>,
}

impl Array {
    fn f64s(&self) -> Vec<f64> {
        assert_eq!(self.ty, "Float64");
        self.bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
            .collect()
    }

    fn vectors(&self) -> Vec<Vector3<f64>> {
        assert_eq!(self.components, 3);
        self.f64s()
            .chunks_exact(3)
            .map(|c| Vector3::new(c[0], c[1], c[2]))
            .collect()
    }

    fn ints(&self) -> Vec<i64> {
        match self.ty.as_str() {
            "Int32" => self
                .bytes
                .chunks_exact(4)
                .map(|b| i32::from_le_bytes(b.try_into().unwrap()) as i64)
                .collect(),
            "Int64" => self
                .bytes
                .chunks_exact(8)
                .map(|b| i64::from_le_bytes(b.try_into().unwrap()))
                .collect(),
            "UInt8" => self.bytes.iter().map(|&b| b as i64).collect(),
            t => panic!("not an integer type: {t}"),
        }
    }
}

/// The value of attribute `name` in the tag text `tag`.
fn attribute<'a>(tag: &'a str, name: &str) -> Option<&'a str> {
    let key = format!(" {name}=\"");
    let start = tag.find(&key)? + key.len();
    Some(&tag[start..start + tag[start..].find('"')?])
}

fn base64_decode(text: &str) -> Vec<u8> {
    let value = |c: u8| -> u32 {
        match c {
            b'A'..=b'Z' => (c - b'A') as u32,
            b'a'..=b'z' => (c - b'a' + 26) as u32,
            b'0'..=b'9' => (c - b'0' + 52) as u32,
            b'+' => 62,
            b'/' => 63,
            _ => panic!("not base64: {c}"),
        }
    };
    let clean: Vec<u8> = text.bytes().filter(|c| !c.is_ascii_whitespace()).collect();
    assert_eq!(clean.len() % 4, 0, "base64 length");
    let mut out = Vec::with_capacity(clean.len() / 4 * 3);
    for q in clean.chunks_exact(4) {
        let pad = q.iter().filter(|&&c| c == b'=').count();
        let w = q.iter().take(4 - pad).fold(0u32, |w, &c| w << 6 | value(c)) << (6 * pad);
        out.extend_from_slice(&w.to_be_bytes()[1..4 - pad]);
    }
    out
}

/// Every `DataArray` of a frame by name, with the file's header checked: binary arrays carry
/// their byte count as UInt64 before the values; ascii arrays are parsed as numbers.
fn read_frame(path: &Path) -> (String, HashMap<String, Array>) {
    let xml = std::fs::read_to_string(path).unwrap();
    assert!(xml.contains("<VTKFile type=\"UnstructuredGrid\""), "{}", &xml[..200]);
    assert!(xml.contains("byte_order=\"LittleEndian\""));
    assert!(xml.contains("header_type=\"UInt64\""));
    let mut arrays = HashMap::new();
    let mut rest = xml.as_str();
    while let Some(start) = rest.find("<DataArray") {
        let tag_end = start + rest[start..].find('>').unwrap();
        let tag = &rest[start..tag_end];
        let body_end = tag_end + rest[tag_end..].find("</DataArray>").unwrap();
        let body = &rest[tag_end + 1..body_end];
        let name = attribute(tag, "Name").expect("every array is named").to_string();
        let ty = attribute(tag, "type").unwrap().to_string();
        let components = attribute(tag, "NumberOfComponents").map_or(1, |c| c.parse().unwrap());
        let bytes = match attribute(tag, "format") {
            Some("binary") => {
                let raw = base64_decode(body);
                let count = u64::from_le_bytes(raw[..8].try_into().unwrap()) as usize;
                assert_eq!(count, raw.len() - 8, "{name}: header byte count");
                raw[8..].to_vec()
            }
            Some("ascii") => body
                .split_ascii_whitespace()
                .flat_map(|w| match ty.as_str() {
                    "Float64" => w.parse::<f64>().unwrap().to_le_bytes().to_vec(),
                    "Int32" => w.parse::<i32>().unwrap().to_le_bytes().to_vec(),
                    "Int64" => w.parse::<i64>().unwrap().to_le_bytes().to_vec(),
                    "UInt8" => vec![w.parse::<u8>().unwrap()],
                    t => panic!("{t}"),
                })
                .collect(),
            f => panic!("{name}: format {f:?}"),
        };
        assert!(
            arrays.insert(name.clone(), Array { ty, components, bytes }).is_none(),
            "{name} twice"
        );
        rest = &rest[body_end..];
    }
    (xml, arrays)
}

/// `(time, file)` of every data set in the collection.
fn read_collection(path: &Path) -> Vec<(f64, String)> {
    let xml = std::fs::read_to_string(path).unwrap();
    assert!(xml.contains("<VTKFile type=\"Collection\""));
    xml.match_indices("<DataSet")
        .map(|(i, _)| {
            let tag = &xml[i..i + xml[i..].find("/>").unwrap()];
            (
                attribute(tag, "timestep").unwrap().parse().unwrap(),
                attribute(tag, "file").unwrap().to_string(),
            )
        })
        .collect()
}

/// The directory holds exactly `frames` frames and the collection: no temporary file is left.
fn assert_only_frames(dir: &Path, frames: usize) {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    let mut expected: Vec<String> = (0..frames).map(|k| format!("frame_{k:05}.vtu")).collect();
    expected.push("frames.pvd".into());
    assert_eq!(names, expected);
}

// ---- independent references --------------------------------------------------------------------

/// Singular values of `f`, largest first, the last negative when `det f < 0` (nalgebra's SVD).
fn signed_singular_values(f: &Matrix3<f64>) -> [f64; 3] {
    let mut s: Vec<f64> = f.singular_values().iter().copied().collect();
    s.sort_by(|a, b| b.total_cmp(a));
    if f.determinant() < 0.0 {
        s[2] = -s[2];
    }
    [s[0], s[1], s[2]]
}

/// A tet's `F = Ds Dm^-1` from the rest positions (inverted here, not the model's `Dm^-1`).
fn tet_deformation(rest: &[Vector3<f64>], q: &[Vector3<f64>], t: &[usize; 4]) -> Matrix3<f64> {
    let edges = |x: &[Vector3<f64>]| Matrix3::from_columns(&[x[t[1]] - x[t[0]], x[t[2]] - x[t[0]], x[t[3]] - x[t[0]]]);
    edges(q) * edges(rest).try_inverse().unwrap()
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * a.abs().max(b.abs()).max(1.0)
}

fn material(e: f64) -> Material {
    Material {
        youngs_modulus: e,
        poisson_ratio: 0.3,
    }
}

// ---- the tests ---------------------------------------------------------------------------------

/// A soft cantilever, 2 cm above a ground plane, fixed at x = 0 and attached at x = 0.1: its
/// free end sags onto the ground.
fn cantilever() -> (Model, Vec<usize>, Vec<usize>) {
    let mesh = BoxSpec::new([8, 2, 2], [0.8, 0.1, 0.1])
        .origin([0.0, 0.02, 0.0])
        .build()
        .unwrap();
    let fixed: Vec<usize> = (0..mesh.num_vertices())
        .filter(|&i| mesh.vertices[i].x < 1e-9)
        .collect();
    let attached: Vec<usize> = (0..mesh.num_vertices())
        .filter(|&i| (mesh.vertices[i].x - 0.1).abs() < 1e-9)
        .collect();
    let mut body = BodySpec::new("beam", mesh, material(1e4), MassSpec::Density(1000.0));
    body.fixed = fixed.clone();
    body.attachments = attached.iter().map(|&i| (i, 1e3)).collect();
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .obstacle(Obstacle::plane("ground", Vector3::zeros(), Vector3::y(), 0.5))
        .build()
        .unwrap();
    (model, fixed, attached)
}

#[test]
fn frames_hold_the_state_constraints_stretches_and_contact_impulses() {
    let dir = tmp_dir("vtk-frames-cantilever");
    let (model, fixed, attached) = cantilever();
    let rest = model.rest().to_vec();
    let settings = Settings {
        dt: 0.01,
        solver: SolverKind::Direct,
        ..Settings::default()
    };
    let mut sim = Simulator::new(model, settings).unwrap();
    let mut writer = FrameWriter::new(&dir, sim.model()).unwrap();
    let mut times = vec![sim.state().time];
    let first = writer.write_state(&sim).unwrap();
    assert_eq!(first, dir.join("frame_00000.vtu"));
    let mut contacts_seen = 0;
    for k in 1..=30 {
        contacts_seen += sim.step().unwrap().contacts;
        if k % 10 == 0 {
            writer.write_state(&sim).unwrap();
            times.push(sim.state().time);
        }
    }
    assert!(contacts_seen > 0, "the beam never reached the ground");
    assert_eq!(writer.count(), 4);

    let n = rest.len();
    let tets = sim.model().tets().to_vec();

    // At rest: the rest positions, zero velocity, no contact, every stretch 1.
    let (_, a) = read_frame(&first);
    assert_eq!(a["Points"].vectors(), rest);
    assert!(a["velocity"].f64s().iter().all(|&x| x == 0.0));
    assert!(a["contact_impulse"].f64s().iter().all(|&x| x == 0.0));
    let s = a["principal_stretches"].f64s();
    assert_eq!(s.len(), 3 * tets.len());
    assert!(s.iter().all(|x| (x - 1.0).abs() <= 1e-12), "stretches at rest");

    // After landing.
    let (xml, a) = read_frame(&dir.join("frame_00003.vtu"));
    assert!(xml.contains(&format!("NumberOfPoints=\"{n}\" NumberOfCells=\"{}\"", tets.len())));
    let st = sim.state();
    // Positions and velocities bit for bit.
    let points = a["Points"].vectors();
    assert!(points
        .iter()
        .zip(&st.q)
        .all(|(p, q)| p.iter().zip(q.iter()).all(|(x, y)| x.to_bits() == y.to_bits())));
    assert_eq!(points.len(), n);
    let velocity = a["velocity"].vectors();
    assert!(velocity
        .iter()
        .zip(&st.v)
        .all(|(p, q)| p.iter().zip(q.iter()).all(|(x, y)| x.to_bits() == y.to_bits())));
    assert_eq!(velocity.len(), n);

    // Constraint flags: the fixed set is 1, the attached set 2, the rest 0.
    let flags = a["constraint"].ints();
    assert_eq!(a["constraint"].ty, "Int32");
    for (i, &f) in flags.iter().enumerate() {
        let expected = if fixed.contains(&i) {
            1
        } else if attached.contains(&i) {
            2
        } else {
            0
        };
        assert_eq!(f, expected, "vertex {i}");
        assert_eq!(f == 1, sim.model().fixed()[i]);
    }

    // Cells: the tets in order, all of body 0, no actuators.
    let conn = a["connectivity"].ints();
    assert_eq!(conn.len(), 4 * tets.len());
    assert!(tets.iter().flatten().zip(&conn).all(|(&t, &c)| t as i64 == c));
    let offsets = a["offsets"].ints();
    assert!(offsets.iter().enumerate().all(|(k, &o)| o == 4 * (k as i64 + 1)));
    assert!(a["types"].ints().iter().all(|&t| t == 10));
    assert!(a["body"].ints().iter().all(|&b| b == 0));
    assert!(a["activation"].f64s().iter().all(|&x| x == 0.0));

    // Principal stretches against nalgebra's SVD of F = Ds Dm^-1; the beam is bent by now.
    let s = a["principal_stretches"].vectors();
    let mut largest: f64 = 0.0;
    for (t, (s, tet)) in s.iter().zip(&tets).enumerate() {
        let r = signed_singular_values(&tet_deformation(&rest, &st.q, tet));
        for k in 0..3 {
            assert!(close(s[k], r[k], 1e-10), "tet {t}: {s:?} vs {r:?}");
        }
        assert!(s[0] >= s[1] && s[1] >= s[2], "tet {t}: not sorted: {s:?}");
        largest = largest.max((s[0] - 1.0).abs()).max((s[2] - 1.0).abs());
    }
    assert!(largest > 1e-3, "the beam did not deform: {largest}");

    // Contact impulses: on vertices lying on the ground only, pushing up, and some there are.
    let impulse = a["contact_impulse"].vectors();
    let touched: Vec<usize> = (0..n).filter(|&i| impulse[i] != Vector3::zeros()).collect();
    assert!(!touched.is_empty(), "no contact impulse after landing");
    for &i in &touched {
        assert!(st.q[i].y.abs() < 1e-6, "vertex {i} at y = {} has an impulse", st.q[i].y);
        assert!(impulse[i].y > 0.0, "vertex {i}: {:?}", impulse[i]);
    }
    assert!((0..n).any(|i| st.q[i].y > 0.01 && impulse[i] == Vector3::zeros()));
    // The impulse is the momentum the ground gives in one step: at most a few times the beam's
    // weight times the step.
    let weight_h = sim.model().mass().iter().sum::<f64>() * 9.81 * 0.01;
    let total: f64 = touched.iter().map(|&i| impulse[i].y).sum();
    assert!(total > 0.0 && total < 10.0 * weight_h, "{total} vs {weight_h}");

    // The collection lists the frames in order with their times, exactly.
    let pvd = read_collection(&dir.join("frames.pvd"));
    let expected: Vec<(f64, String)> = times
        .iter()
        .enumerate()
        .map(|(k, &t)| (t, format!("frame_{k:05}.vtu")))
        .collect();
    assert_eq!(pvd, expected);
    assert_only_frames(&dir, 4);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn cloth_triangles_and_actuator_activations_are_cells() {
    let dir = tmp_dir("vtk-frames-cloth");
    let mesh = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1])
        .origin([1.0, 0.0, 0.0])
        .build()
        .unwrap();
    let mut body = BodySpec::new("cell", mesh, material(1e5), MassSpec::Density(1000.0));
    body.gravity = false;
    body.actuators = vec![ActuatorSpec::pneumatic(
        "lung",
        &[0, 2, 3],
        1e5,
        Schedule::constant(1.3),
    )];
    let mut sheet = ClothSpec::new("sheet", grid(3, 0.6), 50.0, 1e-4, 0.2);
    sheet.fixed = vec![0, 3];
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(body)
        .cloth(sheet)
        .build()
        .unwrap();
    let rest = model.rest().to_vec();
    let nt = model.tets().len();
    let cloth = model.cloth().unwrap().clone();
    let mut sim = Simulator::new(model, Settings::default()).unwrap();
    for _ in 0..5 {
        sim.step().unwrap();
    }
    let mut writer = FrameWriter::new(&dir, sim.model()).unwrap();
    let path = writer.write_state(&sim).unwrap();
    let (xml, a) = read_frame(&path);
    let cells = nt + cloth.triangles.len();
    assert!(xml.contains(&format!("NumberOfCells=\"{cells}\"")));

    // Tets then triangles, with their body ids.
    let types = a["types"].ints();
    assert_eq!(types.len(), cells);
    assert!(types[..nt].iter().all(|&t| t == 10) && types[nt..].iter().all(|&t| t == 5));
    let body = a["body"].ints();
    assert!(body[..nt].iter().all(|&b| b == 0) && body[nt..].iter().all(|&b| b == 1));
    let conn = a["connectivity"].ints();
    let tri_conn: Vec<i64> = cloth.triangles.iter().flatten().map(|&v| v as i64).collect();
    assert_eq!(&conn[4 * nt..], tri_conn.as_slice());
    assert_eq!(
        *a["offsets"].ints().last().unwrap(),
        (4 * nt + 3 * cloth.triangles.len()) as i64
    );

    // The group's activation on its tets, 0 elsewhere.
    let act = sim.activations().unwrap()[0];
    assert_eq!(act, 1.3);
    let activation = a["activation"].f64s();
    for (c, &x) in activation.iter().enumerate() {
        assert_eq!(x, if [0, 2, 3].contains(&c) { act } else { 0.0 }, "cell {c}");
    }

    // Cloth stretches: the in-plane singular values and 1, sorted; the in-plane ones from the
    // 3 x 3 map D (E^T E)^-1 E^T of the rest edges E onto the current edges D.
    let q = &sim.state().q;
    let s = a["principal_stretches"].vectors();
    let mut stretched = false;
    for (k, t) in cloth.triangles.iter().enumerate() {
        let edges = |x: &[Vector3<f64>]| nalgebra::Matrix3x2::from_columns(&[x[t[1]] - x[t[0]], x[t[2]] - x[t[0]]]);
        let (d, e) = (edges(q), edges(&rest));
        let f = d * (e.transpose() * e).try_inverse().unwrap() * e.transpose();
        let mut sv: Vec<f64> = f.singular_values().iter().copied().collect();
        sv.sort_by(|a, b| b.total_cmp(a));
        assert!(sv[2].abs() < 1e-9, "the map kills the normal: {sv:?}");
        let mut r = [sv[0], sv[1], 1.0];
        r.sort_by(|a, b| b.total_cmp(a));
        let got = s[nt + k];
        for i in 0..3 {
            assert!(close(got[i], r[i], 1e-10), "triangle {k}: {got:?} vs {r:?}");
        }
        stretched |= (sv[0] - 1.0).abs() > 1e-6;
    }
    assert!(stretched, "the cloth did not stretch");

    // The same state through `write`: stretches as before, no activation, no impulses.
    let st = sim.state().clone();
    let second = writer.write(st.time, &st.q, &st.v).unwrap();
    let (_, b) = read_frame(&second);
    assert_eq!(b["principal_stretches"].bytes, a["principal_stretches"].bytes);
    assert_eq!(b["Points"].bytes, a["Points"].bytes);
    assert!(b["activation"].f64s().iter().all(|&x| x == 0.0));
    assert!(b["contact_impulse"].f64s().iter().all(|&x| x == 0.0));
    assert_eq!(
        read_collection(&dir.join("frames.pvd")),
        vec![(st.time, "frame_00000.vtu".into()), (st.time, "frame_00001.vtu".into())]
    );
    assert_only_frames(&dir, 2);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn errors_name_the_path() {
    let dir = tmp_dir("vtk-frames-errors");
    let (model, _, _) = cantilever();
    // A directory that cannot be created (a file is in the way).
    std::fs::write(dir.join("file"), "x").unwrap();
    let bad = dir.join("file/frames");
    let e = FrameWriter::new(&bad, &model).unwrap_err().to_string();
    assert!(e.contains(&bad.display().to_string()), "{e}");
    // Positions of another model.
    let mut writer = FrameWriter::new(&dir.join("frames"), &model).unwrap();
    let q = vec![Vector3::zeros(); 3];
    let e = writer.write(0.0, &q, &q).unwrap_err().to_string();
    assert!(e.contains("frame_00000.vtu") && e.contains("3 positions"), "{e}");
    assert_eq!(writer.count(), 0);
    // A frame directory removed under the writer: the file's name is in the error, and no
    // temporary file is left.
    std::fs::remove_dir_all(dir.join("frames")).unwrap();
    let rest = model.rest().to_vec();
    let e = writer.write(0.0, &rest, &rest).unwrap_err().to_string();
    assert!(e.contains("frame_00000.vtu"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The base64 of the frames, against an independent encoding: Python's `base64` of the byte
/// count (UInt64) and two Float64 values `[1.0, -0.5]`, which is what a binary array holds.
#[test]
fn binary_arrays_decode_to_their_values() {
    let raw = base64_decode("EAAAAAAAAAAAAAAAAADwPwAAAAAAAOC/");
    assert_eq!(u64::from_le_bytes(raw[..8].try_into().unwrap()), 16);
    assert_eq!(f64::from_le_bytes(raw[8..16].try_into().unwrap()), 1.0);
    assert_eq!(f64::from_le_bytes(raw[16..].try_into().unwrap()), -0.5);
    assert_eq!(base64_decode("Zm9vYmE="), b"fooba");
    assert_eq!(base64_decode("Zm9vYg=="), b"foob");
}

/// The stationary solvers (the default `split` among them) keep their contact impulses for the
/// frames too: the landed cantilever's impulses are on ground vertices, push up, and carry about
/// the momentum the direct solver's do.
#[test]
fn stationary_solvers_write_contact_impulses_too() {
    let total = |solver: SolverKind| -> f64 {
        let dir = tmp_dir(&format!("vtk-frames-{solver:?}"));
        let (model, _, _) = cantilever();
        let settings = Settings {
            dt: 0.01,
            solver,
            ..Settings::default()
        };
        let mut sim = Simulator::new(model, settings).unwrap();
        assert_eq!(sim.certificate().used, solver, "{}", sim.certificate().message);
        let mut writer = FrameWriter::new(&dir, sim.model()).unwrap();
        for _ in 0..30 {
            sim.step().unwrap();
        }
        let path = writer.write_state(&sim).unwrap();
        let (_, a) = read_frame(&path);
        let impulse = a["contact_impulse"].vectors();
        let st = sim.state();
        let touched: Vec<usize> = (0..impulse.len()).filter(|&i| impulse[i] != Vector3::zeros()).collect();
        assert!(!touched.is_empty(), "{solver:?}: no contact impulse after landing");
        for &i in &touched {
            assert!(st.q[i].y.abs() < 1e-4, "{solver:?}: vertex {i} at y = {}", st.q[i].y);
            assert!(impulse[i].y > 0.0, "{solver:?}: vertex {i}: {:?}", impulse[i]);
        }
        std::fs::remove_dir_all(&dir).unwrap();
        touched.iter().map(|&i| impulse[i].y).sum()
    };
    let (direct, split) = (total(SolverKind::Direct), total(SolverKind::Split));
    assert!((split / direct - 1.0).abs() < 0.5, "split {split} vs direct {direct}");
}
