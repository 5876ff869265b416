//! VTK XML unstructured-grid frames (`frame_00000.vtu`, ...) of all bodies and a ParaView
//! collection `frames.pvd` that orders them in time. Both are written by this module (no VTK
//! library) and atomically ([`write_atomic`]): a reader never sees a half-written file.
//!
//! # Format
//!
//! Each frame is one `<Piece>` of a `VTKFile type="UnstructuredGrid" version="1.0"`,
//! `byte_order="LittleEndian"`, `header_type="UInt64"`. Every `DataArray` is
//! `format="binary"`: inline base64 of one stream holding the array's byte count (UInt64,
//! little-endian) followed by its little-endian values, uncompressed, so `Float64` values are
//! stored bit for bit. Cells are the model's tets (`VTK_TETRA`, 10) in the model's order,
//! then the cloth triangles (`VTK_TRIANGLE`, 5) body by body; `connectivity` and `offsets` are
//! `Int32` (`Int64` for meshes past 2^31 entries).
//!
//! # Fields
//!
//! | field | where | type, components | unit | meaning |
//! |---|---|---|---|---|
//! | `Points` | points | Float64, 3 | m | positions `q` |
//! | `velocity` | point data | Float64, 3 | m/s | velocities `v` |
//! | `contact_impulse` | point data | Float64, 3 | N s | impulse the contacts gave the vertex in the last step: `h lambda` from obstacle contacts and, as `c_k h lambda` on each vertex of the stencil, from contacts between bodies (docs/method.md Eqs. C1, C3, C4); zero where no contact acted, on bone vertices of a skeleton (their contacts are solved in joint coordinates and not exposed), and everywhere in frames written by [`FrameWriter::write`] |
//! | `constraint` | point data | Int32, 1 | - | 0 free, 1 fixed (Dirichlet), 2 attached (penalty attachment); a vertex both fixed and attached is 1 |
//! | `body` | cell data | Int32, 1 | - | body index: soft bodies in model order, then the cloth bodies |
//! | `principal_stretches` | cell data | Float64, 3 | 1 | singular values of the deformation gradient, largest first; for a tet `F = Ds Dm^-1` (signed: the last is negative for an inverted tet); for a cloth triangle the two in-plane stretches and 1 (the cloth model has no stretch across the sheet), sorted together |
//! | `activation` | cell data | Float64, 1 | group's (pneumatic: target volume ratio; muscle: contraction in `[0, 1]`) | activation of the tet's actuator group in the last step (the last group listing the tet, if several do); 0 for cells in no group and in frames written by [`FrameWriter::write`] |
//!
//! The collection lists each frame with its time (s) in Rust's shortest round-trip notation.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Vector3};

use super::{write_atomic, COLLECTION};
use crate::cloth::TriangleGeometry;
use crate::model::Model;
use crate::solver::Simulator;

/// VTK cell type of a tet.
const VTK_TETRA: u8 = 10;
/// VTK cell type of a triangle.
const VTK_TRIANGLE: u8 = 5;

/// Writes numbered frames into a directory and keeps the time collection up to date.
///
/// Everything constant for a model (cells, body ids, constraint flags, the rest shapes the
/// stretches need) is prepared in [`FrameWriter::new`]; a frame reuses the writer's buffers.
pub struct FrameWriter {
    dir: PathBuf,
    /// Number of points.
    n: usize,
    /// Tets and their inverse rest edge matrices `Dm^-1`.
    tets: Vec<([usize; 4], Matrix3<f64>)>,
    /// Cloth triangles in cell order with their rest geometry.
    triangles: Vec<([usize; 3], TriangleGeometry)>,
    /// Per cell: actuator group + 1 (0: none).
    cell_group: Vec<u32>,
    /// `<?xml ...` up to and including `<PointData>`.
    head: String,
    /// The `constraint` point array, encoded.
    constraint_xml: String,
    /// The `body` cell array, encoded.
    body_xml: String,
    /// `<Points>` is per frame; `</Points>` then the whole `<Cells>` element and the tail.
    tail: String,
    stretches: Vec<Vector3<f64>>,
    activation: Vec<f64>,
    impulse: Vec<Vector3<f64>>,
    /// Raw bytes of the array being encoded.
    scratch: Vec<u8>,
    /// The frame's file content.
    out: Vec<u8>,
    frames: Vec<(f64, String)>,
}

impl std::fmt::Debug for FrameWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrameWriter")
            .field("dir", &self.dir)
            .field("points", &self.n)
            .field("cells", &self.cell_group.len())
            .field("frames", &self.frames.len())
            .finish()
    }
}

impl FrameWriter {
    /// Prepare `dir` (created if needed) for the frames of `model`. Errors name the directory.
    ///
    /// ```
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::output::FrameWriter;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Settings, Simulator};
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
    /// let model = ModelBuilder::new().body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0))).build()?;
    /// let dir = std::env::temp_dir().join(format!("diffsoft-doc-frames-{}", std::process::id()));
    /// let mut frames = FrameWriter::new(&dir, &model)?;
    /// let mut sim = Simulator::new(model, Settings::default())?;
    /// sim.step()?;
    /// let path = frames.write_state(&sim)?;
    /// assert_eq!(path, dir.join("frame_00000.vtu"));
    /// assert_eq!(frames.count(), 1);
    /// assert!(String::from_utf8_lossy(&std::fs::read(&path)?).contains("<UnstructuredGrid>"));
    /// std::fs::remove_dir_all(&dir)?;
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(dir: &Path, model: &Model) -> std::io::Result<Self> {
        super::output_dir(dir, "the frames' path")?;
        let n = model.n();
        let tets: Vec<_> = model
            .tets
            .iter()
            .zip(&model.fem.geometry)
            .map(|(t, g)| (*t, g.p_inv))
            .collect();
        let mut body = vec![0i32; tets.len()];
        for (k, b) in model.bodies.iter().enumerate() {
            for t in b.tets.clone() {
                body[t] = k as i32;
            }
        }
        let mut triangles = Vec::new();
        if let Some(cl) = &model.cloth {
            // Cloth triangles follow the tets; their body ids continue the soft bodies'.
            for (k, b) in cl.bodies.iter().enumerate() {
                for t in b.triangles.clone() {
                    triangles.push((cl.triangles[t], cl.geometry[t]));
                    body.push((model.bodies.len() + k) as i32);
                }
            }
        }
        let cells = tets.len() + triangles.len();
        let mut cell_group = vec![0u32; cells];
        if let Some(act) = &model.actuators {
            for c in &act.cells {
                cell_group[c.tet] = c.group as u32 + 1;
            }
        }
        let mut constraint = vec![0i32; n];
        for a in &model.attachments {
            constraint[a.vertex] = 2;
        }
        for (c, &f) in constraint.iter_mut().zip(&model.fixed) {
            if f {
                *c = 1;
            }
        }

        let mut scratch = Vec::new();
        let mut buf = Vec::new();
        let mut head = String::new();
        let _ = write!(
            head,
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" \
             byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n\
             <Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{cells}\">\n<PointData>\n"
        );
        data_array(&mut buf, &mut scratch, "Int32", "constraint", 1, |s| {
            constraint.iter().for_each(|c| s.extend_from_slice(&c.to_le_bytes()))
        });
        let constraint_xml = String::from_utf8(std::mem::take(&mut buf)).expect("ascii");
        data_array(&mut buf, &mut scratch, "Int32", "body", 1, |s| {
            body.iter().for_each(|b| s.extend_from_slice(&b.to_le_bytes()))
        });
        let body_xml = String::from_utf8(std::mem::take(&mut buf)).expect("ascii");

        // Cells: connectivity, end offsets, types.
        let corners = 4 * tets.len() + 3 * triangles.len();
        let narrow = n <= i32::MAX as usize && corners <= i32::MAX as usize;
        let (ty, width) = if narrow { ("Int32", 4) } else { ("Int64", 8) };
        let push = move |s: &mut Vec<u8>, x: usize| {
            if width == 4 {
                s.extend_from_slice(&(x as i32).to_le_bytes());
            } else {
                s.extend_from_slice(&(x as i64).to_le_bytes());
            }
        };
        buf.extend_from_slice(b"</Points>\n<Cells>\n");
        data_array(&mut buf, &mut scratch, ty, "connectivity", 1, |s| {
            for (t, _) in &tets {
                t.iter().for_each(|&i| push(s, i));
            }
            for (t, _) in &triangles {
                t.iter().for_each(|&i| push(s, i));
            }
        });
        data_array(&mut buf, &mut scratch, ty, "offsets", 1, |s| {
            (1..=tets.len()).for_each(|k| push(s, 4 * k));
            (1..=triangles.len()).for_each(|k| push(s, 4 * tets.len() + 3 * k));
        });
        data_array(&mut buf, &mut scratch, "UInt8", "types", 1, |s| {
            s.resize(s.len() + tets.len(), VTK_TETRA);
            s.resize(s.len() + triangles.len(), VTK_TRIANGLE);
        });
        buf.extend_from_slice(b"</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
        let tail = String::from_utf8(buf).expect("ascii");

        Ok(Self {
            dir: dir.to_path_buf(),
            n,
            tets,
            triangles,
            cell_group,
            head,
            constraint_xml,
            body_xml,
            tail,
            stretches: vec![Vector3::zeros(); cells],
            activation: vec![0.0; cells],
            impulse: vec![Vector3::zeros(); n],
            scratch,
            out: Vec::new(),
            frames: Vec::new(),
        })
    }

    /// Write one frame of positions `q` (m) and velocities `v` (m/s) at `time` (s); returns its
    /// path. The principal stretches follow from `q`; `activation` and `contact_impulse` are
    /// written as zeros (use [`FrameWriter::write_state`] for them). Errors name the file.
    pub fn write(&mut self, time: f64, q: &[Vector3<f64>], v: &[Vector3<f64>]) -> std::io::Result<PathBuf> {
        self.activation.fill(0.0);
        self.impulse.fill(Vector3::zeros());
        self.write_frame(time, q, v)
    }

    /// Write one frame of the simulator's current state: its time, positions and velocities,
    /// the activations of its last step and the contact impulses of its last step (see the
    /// module documentation); returns the frame's path. `sim` must simulate the model the
    /// writer was made for. Errors name the file.
    pub fn write_state(&mut self, sim: &Simulator) -> std::io::Result<PathBuf> {
        let model = sim.model();
        if model.tets.len() != self.tets.len() || model.num_cloth_triangles() != self.triangles.len() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!(
                    "{}: the simulator's model has {} tets and {} cloth triangles, the frames' {} and {}",
                    self.next_path().display(),
                    model.tets.len(),
                    model.num_cloth_triangles(),
                    self.tets.len(),
                    self.triangles.len()
                ),
            ));
        }
        let acts = sim.activations().unwrap_or(&[]);
        for (a, &g) in self.activation.iter_mut().zip(&self.cell_group) {
            *a = match g {
                0 => 0.0,
                g => acts.get(g as usize - 1).copied().unwrap_or(0.0),
            };
        }
        contact_impulses(sim, &mut self.impulse);
        let st = sim.state();
        self.write_frame(st.time, &st.q, &st.v)
    }

    /// Frames written so far.
    pub fn count(&self) -> usize {
        self.frames.len()
    }

    fn next_path(&self) -> PathBuf {
        self.dir.join(format!("frame_{:05}.vtu", self.frames.len()))
    }

    /// Assemble and write a frame from `q`, `v` and the activation and impulse buffers.
    fn write_frame(&mut self, time: f64, q: &[Vector3<f64>], v: &[Vector3<f64>]) -> std::io::Result<PathBuf> {
        let name = format!("frame_{:05}.vtu", self.frames.len());
        let path = super::own_file(&self.dir, &name)?;
        if q.len() != self.n || v.len() != self.n {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!(
                    "{}: {} positions and {} velocities for a model of {} vertices",
                    path.display(),
                    q.len(),
                    v.len(),
                    self.n
                ),
            ));
        }
        self.principal_stretches(q);
        let (out, s) = (&mut self.out, &mut self.scratch);
        out.clear();
        out.extend_from_slice(self.head.as_bytes());
        data_array(out, s, "Float64", "velocity", 3, |s| push_vectors(s, v));
        data_array(out, s, "Float64", "contact_impulse", 3, |s| {
            push_vectors(s, &self.impulse)
        });
        out.extend_from_slice(self.constraint_xml.as_bytes());
        out.extend_from_slice(b"</PointData>\n<CellData>\n");
        out.extend_from_slice(self.body_xml.as_bytes());
        data_array(out, s, "Float64", "principal_stretches", 3, |s| {
            push_vectors(s, &self.stretches)
        });
        data_array(out, s, "Float64", "activation", 1, |s| {
            self.activation
                .iter()
                .for_each(|a| s.extend_from_slice(&a.to_le_bytes()))
        });
        out.extend_from_slice(b"</CellData>\n<Points>\n");
        data_array(out, s, "Float64", "Points", 3, |s| push_vectors(s, q));
        out.extend_from_slice(self.tail.as_bytes());
        write_atomic(&path, &self.out)?;
        self.frames.push((time, name));
        self.write_collection()?;
        Ok(path)
    }

    /// Singular values of every cell's deformation gradient at `q`, largest first.
    fn principal_stretches(&mut self, q: &[Vector3<f64>]) {
        use crate::kernel::svd::{svd3, svd3_warm_batch, LANES};
        let deformation = |(t, p_inv): &([usize; 4], Matrix3<f64>)| {
            let x0 = q[t[0]];
            Matrix3::from_columns(&[q[t[1]] - x0, q[t[2]] - x0, q[t[3]] - x0]) * p_inv
        };
        let (tet_part, tri_part) = self.stretches.split_at_mut(self.tets.len());
        // The batched kernel decomposes LANES tets at once (2.5x faster than one by one).
        let mut out = tet_part.chunks_exact_mut(LANES);
        let mut tets = self.tets.chunks_exact(LANES);
        let v0 = [Matrix3::identity(); LANES];
        for (s, t) in (&mut out).zip(&mut tets) {
            let f: [Matrix3<f64>; LANES] = std::array::from_fn(|k| deformation(&t[k]));
            for (s, d) in s.iter_mut().zip(svd3_warm_batch(&f, &v0)) {
                *s = d.sigma;
            }
        }
        for (s, t) in out.into_remainder().iter_mut().zip(tets.remainder()) {
            *s = svd3(&deformation(t)).sigma;
        }
        for (s, (t, g)) in tri_part.iter_mut().zip(&self.triangles) {
            let f = crate::cloth::deformation_gradient(q, t, g);
            let (s1, s2) = crate::kernel::polar32::singular_values(&f);
            let mut v = [s1, s2, 1.0];
            v.sort_by(|a, b| b.total_cmp(a));
            *s = Vector3::from(v);
        }
    }

    /// Rewrite the collection (`frames.pvd`) with every frame so far.
    fn write_collection(&self) -> std::io::Result<()> {
        let mut s = String::from(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n",
        );
        for (t, f) in &self.frames {
            let _ = writeln!(s, "    <DataSet timestep=\"{t:?}\" part=\"0\" file=\"{f}\"/>");
        }
        s.push_str("  </Collection>\n</VTKFile>\n");
        write_atomic(&super::own_file(&self.dir, COLLECTION)?, s.as_bytes())
    }
}

/// The contact impulses (N s) of the simulator's last step per vertex into `out`: `h lambda`
/// of every contact of the last solve (every global solver keeps them for output), spread over
/// the contact's stencil. Zero for contacts on bone vertices, which the simulator does not
/// expose.
fn contact_impulses(sim: &Simulator, out: &mut [Vector3<f64>]) {
    out.fill(Vector3::zeros());
    let h = sim.integrator.h();
    let free = &sim.system.free;
    if let Some(lambda) = sim.iteration.contact_impulses() {
        // The last solve's impulses belong to the first contacts of the list (a final contact
        // round may have appended contacts that were not solved: they get none).
        for (c, l) in sim.contacts.free.iter().zip(lambda) {
            for (k, coef) in c.stencil.entries() {
                out[free[k]] += l * (coef * h);
            }
        }
    }
}

/// Little-endian bytes of `v`'s components, vector by vector.
fn push_vectors(s: &mut Vec<u8>, v: &[Vector3<f64>]) {
    s.reserve(24 * v.len());
    for x in v {
        s.extend_from_slice(&x.x.to_le_bytes());
        s.extend_from_slice(&x.y.to_le_bytes());
        s.extend_from_slice(&x.z.to_le_bytes());
    }
}

/// Append a `format="binary"` `DataArray` element to `out`: `fill` appends the array's
/// little-endian bytes to the (cleared) `scratch`, which is then base64-encoded after its
/// UInt64 byte count, as one stream.
fn data_array(
    out: &mut Vec<u8>,
    scratch: &mut Vec<u8>,
    ty: &str,
    name: &str,
    components: usize,
    fill: impl FnOnce(&mut Vec<u8>),
) {
    scratch.clear();
    scratch.extend_from_slice(&[0; 8]);
    fill(scratch);
    let bytes = (scratch.len() - 8) as u64;
    scratch[..8].copy_from_slice(&bytes.to_le_bytes());
    let _ = write!(
        VecWriter(out),
        "<DataArray type=\"{ty}\" Name=\"{name}\" NumberOfComponents=\"{components}\" format=\"binary\">"
    );
    base64_encode(scratch, out);
    out.extend_from_slice(b"</DataArray>\n");
}

/// `fmt::Write` into a byte buffer.
struct VecWriter<'a>(&'a mut Vec<u8>);

impl std::fmt::Write for VecWriter<'_> {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.0.extend_from_slice(s.as_bytes());
        Ok(())
    }
}

const BASE64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Append the standard base64 encoding (RFC 4648, with padding) of `input` to `out`.
pub(crate) fn base64_encode(input: &[u8], out: &mut Vec<u8>) {
    let start = out.len();
    out.resize(start + input.len().div_ceil(3) * 4, 0);
    let dst = &mut out[start..];
    let chunks = input.chunks_exact(3);
    let rest = chunks.remainder();
    let mut d = dst.chunks_exact_mut(4);
    for (c, o) in chunks.zip(&mut d) {
        let w = (c[0] as u32) << 16 | (c[1] as u32) << 8 | c[2] as u32;
        o[0] = BASE64[(w >> 18) as usize & 63];
        o[1] = BASE64[(w >> 12) as usize & 63];
        o[2] = BASE64[(w >> 6) as usize & 63];
        o[3] = BASE64[w as usize & 63];
    }
    if let Some(o) = d.next() {
        let w = (rest[0] as u32) << 16 | rest.get(1).map_or(0, |&b| (b as u32) << 8);
        o[0] = BASE64[(w >> 18) as usize & 63];
        o[1] = BASE64[(w >> 12) as usize & 63];
        o[2] = if rest.len() == 2 {
            BASE64[(w >> 6) as usize & 63]
        } else {
            b'='
        };
        o[3] = b'=';
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encode(s: &[u8]) -> String {
        let mut out = b"x".to_vec();
        base64_encode(s, &mut out);
        String::from_utf8(out[1..].to_vec()).unwrap()
    }

    /// A frame or the collection whose name is taken by a link (to an input, say) or a FIFO is
    /// refused, naming it, and the link's target is left as it was.
    #[test]
    fn frames_are_never_written_through_a_link_or_into_a_fifo() {
        use crate::mesh::generate::BoxSpec;
        use crate::{BodySpec, MassSpec, Material, ModelBuilder, Settings};
        let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build().unwrap();
        let material = Material {
            youngs_modulus: 1e5,
            poisson_ratio: 0.3,
        };
        let model = ModelBuilder::new()
            .body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0)))
            .build()
            .unwrap();
        let dir = std::env::temp_dir().join(format!("diffsoft-frames-links-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let input = dir.join("input.json");
        std::fs::write(&input, "an input").unwrap();
        std::os::unix::fs::symlink(&input, dir.join("frame_00000.vtu")).unwrap();
        let mut frames = FrameWriter::new(&dir, &model).unwrap();
        let mut sim = Simulator::new(model.clone(), Settings::default()).unwrap();
        sim.step().unwrap();
        let e = frames.write_state(&sim).unwrap_err().to_string();
        assert!(e.contains("frame_00000.vtu: is a symbolic link to"), "{e}");
        assert_eq!(std::fs::read_to_string(&input).unwrap(), "an input");
        // A FIFO under the frame's name: refused at once (writing would block).
        std::fs::remove_file(dir.join("frame_00000.vtu")).unwrap();
        let made = std::process::Command::new("mkfifo")
            .arg(dir.join("frame_00000.vtu"))
            .status()
            .unwrap();
        assert!(made.success());
        let e = frames.write_state(&sim).unwrap_err().to_string();
        assert!(e.contains("frame_00000.vtu: is a named pipe (FIFO)"), "{e}");
        // The collection's name taken by a link: the frame is written, the collection refused.
        std::fs::remove_file(dir.join("frame_00000.vtu")).unwrap();
        std::os::unix::fs::symlink(&input, dir.join(COLLECTION)).unwrap();
        let mut frames = FrameWriter::new(&dir, &model).unwrap();
        let e = frames.write_state(&sim).unwrap_err().to_string();
        assert!(e.contains(COLLECTION) && e.contains("symbolic link"), "{e}");
        assert_eq!(std::fs::read_to_string(&input).unwrap(), "an input");
        // A regular file where the directory should be is named as such.
        let e = FrameWriter::new(&input, &model).unwrap_err().to_string();
        assert!(e.contains("must name a directory, and this is a regular file"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn base64_matches_the_rfc_4648_vectors() {
        for (plain, coded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(encode(plain.as_bytes()), coded, "{plain:?}");
        }
        // The last two letters of the alphabet and all-ones / all-zeros groups.
        assert_eq!(encode(&[0xfb, 0xff]), "+/8=");
        assert_eq!(encode(&[0xff, 0xff, 0xff]), "////");
        assert_eq!(encode(&[0, 0, 0]), "AAAA");
    }

    #[test]
    fn data_array_puts_the_byte_count_before_the_values() {
        let (mut out, mut scratch) = (Vec::new(), Vec::new());
        data_array(&mut out, &mut scratch, "Int32", "a", 1, |s| {
            s.extend_from_slice(&7i32.to_le_bytes())
        });
        let text = String::from_utf8(out).unwrap();
        // 4u64 then 7i32, little-endian: 04 00 00 00 00 00 00 00 07 00 00 00.
        let mut expected =
            String::from("<DataArray type=\"Int32\" Name=\"a\" NumberOfComponents=\"1\" format=\"binary\">");
        expected += &encode(&[4, 0, 0, 0, 0, 0, 0, 0, 7, 0, 0, 0]);
        expected += "</DataArray>\n";
        assert_eq!(text, expected);
        assert_eq!(encode(&[4, 0, 0, 0, 0, 0, 0, 0, 7, 0, 0, 0]), "BAAAAAAAAAAHAAAA");
    }
}
