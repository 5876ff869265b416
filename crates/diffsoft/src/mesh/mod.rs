//! Tetrahedral meshes: the [`TetMesh`] type, readers (OBJ with `t` lines, TetGen `.node`/`.ele`,
//! Gmsh `.msh` ASCII 2.2 and 4.1), writers, structured generators and quality measures.
//!
//! Every reader goes through one validation pass (shared with [`TetMesh::new`]): indices in range, no
//! repeated vertex in a tet, finite coordinates, no zero or near-zero volume. Inverted tets
//! (negative signed volume) are not errors: they are re-oriented (two vertices swapped) and
//! counted in [`MeshInfo`]. Vertices that no tet uses are dropped and counted; [`MeshInfo`] keeps
//! each kept vertex's id in the file so scene files can refer to vertices by their file index.
//!
//! This module knows nothing about physics.

mod error;
pub mod generate;
mod gmsh;
mod lines;
mod obj;
pub mod quality;
pub mod surface;
mod tetgen;
pub mod write;

pub use error::{Location, MeshError, MeshErrorKind};

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;
use std::path::Path;

/// A tetrahedral mesh: rest positions and positively oriented tets (0-based vertex indices).
#[derive(Debug, Clone, PartialEq)]
pub struct TetMesh {
    /// Vertex positions.
    pub vertices: Vec<Vector3<f64>>,
    /// Tets as four vertex indices, ordered so that the signed volume is positive.
    pub tets: Vec<[usize; 4]>,
}

/// The file format a mesh came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum MeshFormat {
    /// Wavefront OBJ with `v` vertex lines and `t` tet lines (0-based).
    Obj,
    /// TetGen `.node` + `.ele`.
    Tetgen,
    /// Gmsh ASCII 2.2.
    Gmsh22,
    /// Gmsh ASCII 4.1.
    Gmsh41,
    /// Built in memory (generator or API).
    Memory,
}

/// What loading a mesh did besides parsing: dropped nodes, re-oriented tets, file ids.
#[derive(Debug, Clone, PartialEq, Serialize, schemars::JsonSchema)]
pub struct MeshInfo {
    /// The path the mesh was read from.
    pub path: String,
    /// The file format.
    pub format: MeshFormat,
    /// Number of nodes in the file that no tet uses (dropped).
    pub dropped_nodes: usize,
    /// Number of tets whose vertex order was inverted in the file and was swapped.
    pub reoriented_tets: usize,
    /// Up to 10 indices of re-oriented tets, for the report.
    pub first_reoriented: Vec<usize>,
    /// Non-tet elements skipped (Gmsh: points, lines, triangles, ...).
    pub skipped_elements: usize,
    /// The quality threshold every tet passed ([`LoadOptions::min_quality`]).
    pub min_quality: f64,
    /// The factor the file's coordinates were multiplied by ([`LoadedMesh::scaled`]; 1 as
    /// read). A scene's bodies place their meshes by their own scale, rotation and translation,
    /// which the scene records.
    pub scale: f64,
    /// For each kept vertex, its id in the file's own numbering.
    #[serde(skip)]
    pub file_ids: Vec<i64>,
}

/// A mesh together with what loading it did.
#[derive(Debug, Clone)]
pub struct LoadedMesh {
    /// The validated mesh.
    pub mesh: TetMesh,
    /// Loading details.
    pub info: MeshInfo,
}

impl LoadedMesh {
    /// The mesh with its coordinates multiplied by `s` (the paper's "Scale"), the factor
    /// recorded in [`MeshInfo::scale`].
    ///
    /// ```
    /// use diffsoft::mesh;
    ///
    /// let dir = std::env::temp_dir().join(format!("diffsoft-doc-scaled-{}", std::process::id()));
    /// std::fs::create_dir_all(&dir)?;
    /// let path = dir.join("one.obj");
    /// std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3\n")?;
    /// let small = mesh::load(&path)?.scaled(0.05);
    /// assert_eq!(small.info.scale, 0.05);
    /// assert_eq!(small.mesh.vertices[1].x, 0.05);
    /// # std::fs::remove_dir_all(&dir)?;
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn scaled(self, s: f64) -> LoadedMesh {
        LoadedMesh {
            mesh: self.mesh.scaled(s),
            info: MeshInfo {
                scale: self.info.scale * s,
                ..self.info
            },
        }
    }
}

/// Options for reading and validating meshes.
#[derive(Debug, Clone, Copy)]
pub struct LoadOptions {
    /// Tets whose normalised volume `6 sqrt(2) |V| / l_rms^3` (1 for a regular tet) is below this
    /// are rejected as degenerate.
    pub min_quality: f64,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self { min_quality: 1e-9 }
    }
}

/// Parsed but unvalidated mesh data, in file order, shared by the readers.
#[derive(Debug, Default)]
pub(crate) struct RawMesh {
    pub nodes: Vec<[f64; 3]>,
    pub node_ids: Vec<i64>,
    /// Tets as indices into `nodes` (range already checked by the reader).
    pub tets: Vec<[usize; 4]>,
    /// 1-based line of each tet in the file.
    pub tet_lines: Vec<usize>,
    pub skipped_elements: usize,
}

impl TetMesh {
    /// Build a mesh from vertices and tets, validating and orienting as the readers do.
    ///
    /// ```
    /// use diffsoft::TetMesh;
    /// use nalgebra::Vector3;
    ///
    /// let v = vec![Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::z()];
    /// // Listed with negative volume: re-oriented, not refused.
    /// let mesh = TetMesh::new(v.clone(), vec![[0, 2, 1, 3]])?;
    /// assert_eq!((mesh.num_vertices(), mesh.num_tets()), (4, 1));
    /// assert!((mesh.signed_volume(0) - 1.0 / 6.0).abs() < 1e-15);
    /// // A tet that repeats a vertex is.
    /// assert!(TetMesh::new(v, vec![[0, 1, 1, 3]]).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(vertices: Vec<Vector3<f64>>, tets: Vec<[usize; 4]>) -> Result<TetMesh, MeshError> {
        Self::new_with(vertices, tets, LoadOptions::default()).map(|l| l.mesh)
    }

    /// As [`TetMesh::new`], returning the load details (dropped vertices, re-oriented tets).
    ///
    /// ```
    /// use diffsoft::mesh::{LoadOptions, MeshFormat};
    /// use diffsoft::TetMesh;
    /// use nalgebra::Vector3;
    ///
    /// // Vertex 4 is used by no tet: dropped and counted.
    /// let v = vec![Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::z(), Vector3::repeat(5.0)];
    /// let loaded = TetMesh::new_with(v, vec![[0, 2, 1, 3]], LoadOptions::default())?;
    /// assert_eq!(loaded.mesh.num_vertices(), 4);
    /// assert_eq!((loaded.info.dropped_nodes, loaded.info.reoriented_tets), (1, 1));
    /// assert_eq!(loaded.info.format, MeshFormat::Memory);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new_with(
        vertices: Vec<Vector3<f64>>,
        tets: Vec<[usize; 4]>,
        opts: LoadOptions,
    ) -> Result<LoadedMesh, MeshError> {
        let n = vertices.len();
        let path = "<memory>";
        for (i, v) in vertices.iter().enumerate() {
            if !v.iter().all(|c| c.is_finite()) {
                return Err(MeshError::file(
                    path,
                    MeshErrorKind::NonFinite(format!("vertex {i}: {v:?}")),
                ));
            }
        }
        for (t, tet) in tets.iter().enumerate() {
            for &i in tet {
                if i >= n {
                    return Err(MeshError::file(
                        path,
                        MeshErrorKind::IndexOutOfRange {
                            tet: t,
                            index: i as i128,
                            valid: format!("0..{n}"),
                        },
                    ));
                }
            }
        }
        let raw = RawMesh {
            nodes: vertices.iter().map(|v| [v.x, v.y, v.z]).collect(),
            node_ids: (0..n as i64).collect(),
            tet_lines: Vec::new(),
            tets,
            skipped_elements: 0,
        };
        Self::from_raw(path, MeshFormat::Memory, raw, opts)
    }

    /// Validate parsed data: repeated vertices, unused nodes, orientation, degenerate volume.
    pub(crate) fn from_raw(
        path: &str,
        format: MeshFormat,
        raw: RawMesh,
        opts: LoadOptions,
    ) -> Result<LoadedMesh, MeshError> {
        let err_at = |t: usize, kind: MeshErrorKind| match raw.tet_lines.get(t) {
            Some(&line) => MeshError::at(path, line, kind),
            None => MeshError::file(path, kind),
        };
        if raw.tets.is_empty() {
            return Err(MeshError::file(path, MeshErrorKind::NoTets));
        }
        for (t, tet) in raw.tets.iter().enumerate() {
            for a in 0..4 {
                for b in a + 1..4 {
                    if tet[a] == tet[b] {
                        return Err(err_at(
                            t,
                            MeshErrorKind::RepeatedVertex {
                                tet: t,
                                vertex: raw.node_ids[tet[a]],
                            },
                        ));
                    }
                }
            }
        }
        let mut seen = std::collections::HashMap::with_capacity(raw.tets.len());
        for (t, tet) in raw.tets.iter().enumerate() {
            let mut key = *tet;
            key.sort_unstable();
            if let Some(&first) = seen.get(&key) {
                return Err(err_at(t, MeshErrorKind::DuplicateTet { tet: t, first }));
            }
            seen.insert(key, t);
        }
        // The same check by position: corners at the same four places (bit for bit, -0 as 0).
        let place = |i: usize| raw.nodes[i].map(|c| (c + 0.0).to_bits());
        let mut seen = std::collections::HashMap::with_capacity(raw.tets.len());
        for (t, tet) in raw.tets.iter().enumerate() {
            let mut key = tet.map(place);
            key.sort_unstable();
            if let Some(&first) = seen.get(&key) {
                let vertices = tet.map(|i| raw.node_ids[i]);
                return Err(err_at(
                    t,
                    MeshErrorKind::CoincidentTet {
                        tet: t,
                        first,
                        vertices,
                    },
                ));
            }
            seen.insert(key, t);
        }
        // Drop nodes that no tet uses; keep file ids of the rest.
        const UNUSED: usize = usize::MAX;
        let mut new_index = vec![UNUSED; raw.nodes.len()];
        for tet in &raw.tets {
            for &i in tet {
                new_index[i] = 0;
            }
        }
        let mut vertices = Vec::new();
        let mut file_ids = Vec::new();
        for (i, slot) in new_index.iter_mut().enumerate() {
            if *slot != UNUSED {
                *slot = vertices.len();
                let p = raw.nodes[i];
                vertices.push(Vector3::new(p[0], p[1], p[2]));
                file_ids.push(raw.node_ids[i]);
            }
        }
        let dropped_nodes = raw.nodes.len() - vertices.len();
        let mut tets = Vec::with_capacity(raw.tets.len());
        let mut reoriented = 0usize;
        let mut first_reoriented = Vec::new();
        for (t, tet) in raw.tets.iter().enumerate() {
            let mut tet = tet.map(|i| new_index[i]);
            let (volume, quality) = volume_and_quality(&vertices, &tet);
            if !volume.is_finite() {
                // Coordinates near f64's range: the volume overflows, the tet is not degenerate.
                let reach = tet.iter().map(|&i| vertices[i].amax()).fold(0.0, f64::max);
                return Err(err_at(
                    t,
                    MeshErrorKind::TooLarge(format!(
                        "tet {t}: its volume overflows f64 (coordinates up to {reach:e}); scale the mesh down"
                    )),
                ));
            }
            if quality.is_nan() || quality < opts.min_quality {
                return Err(err_at(
                    t,
                    MeshErrorKind::DegenerateTet {
                        tet: t,
                        volume,
                        quality,
                        threshold: opts.min_quality,
                    },
                ));
            }
            if volume < 0.0 {
                tet.swap(1, 2);
                reoriented += 1;
                if first_reoriented.len() < 10 {
                    first_reoriented.push(t);
                }
            }
            tets.push(tet);
        }
        Ok(LoadedMesh {
            mesh: TetMesh { vertices, tets },
            info: MeshInfo {
                path: path.to_string(),
                format,
                dropped_nodes,
                reoriented_tets: reoriented,
                first_reoriented,
                skipped_elements: raw.skipped_elements,
                min_quality: opts.min_quality,
                scale: 1.0,
                file_ids,
            },
        })
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Number of tets.
    pub fn num_tets(&self) -> usize {
        self.tets.len()
    }

    /// Rest edge matrix `P = [q1-q0, q2-q0, q3-q0]` of tet `t` (Eq. 23).
    pub fn edge_matrix(&self, t: usize) -> Matrix3<f64> {
        edge_matrix(&self.vertices, &self.tets[t])
    }

    /// Signed volume `det P / 6` of tet `t` (positive after loading).
    pub fn signed_volume(&self, t: usize) -> f64 {
        self.edge_matrix(t).determinant() / 6.0
    }

    /// Axis-aligned bounding box (min, max).
    pub fn bounding_box(&self) -> (Vector3<f64>, Vector3<f64>) {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for v in &self.vertices {
            lo = lo.inf(v);
            hi = hi.sup(v);
        }
        (lo, hi)
    }

    /// A copy with every vertex mapped by `f` (scaling, rigid motion, ...). Orientation is kept
    /// only for maps with positive determinant.
    ///
    /// ```
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use nalgebra::Vector3;
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let moved = mesh.map_vertices(|v| v + Vector3::new(0.0, 1.0, 0.0));
    /// assert_eq!(moved.tets, mesh.tets);
    /// assert!((moved.bounding_box().0.y - 1.0).abs() < 1e-12);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn map_vertices(&self, f: impl Fn(&Vector3<f64>) -> Vector3<f64>) -> TetMesh {
        TetMesh {
            vertices: self.vertices.iter().map(f).collect(),
            tets: self.tets.clone(),
        }
    }

    /// A copy scaled by `s` about the origin (the paper's scene "Scale").
    ///
    /// ```
    /// use diffsoft::mesh::generate::BoxSpec;
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let big = mesh.scaled(10.0);
    /// assert!((big.signed_volume(0) / mesh.signed_volume(0) - 1000.0).abs() < 1e-9);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn scaled(&self, s: f64) -> TetMesh {
        self.map_vertices(|v| v * s)
    }
}

pub(crate) fn edge_matrix(vertices: &[Vector3<f64>], tet: &[usize; 4]) -> Matrix3<f64> {
    let q0 = vertices[tet[0]];
    Matrix3::from_columns(&[vertices[tet[1]] - q0, vertices[tet[2]] - q0, vertices[tet[3]] - q0])
}

/// Signed volume and normalised volume `6 sqrt(2) |V| / l_rms^3` (1 for a regular tet).
pub(crate) fn volume_and_quality(vertices: &[Vector3<f64>], tet: &[usize; 4]) -> (f64, f64) {
    let volume = edge_matrix(vertices, tet).determinant() / 6.0;
    let mut sum_sq = 0.0;
    for a in 0..4 {
        for b in a + 1..4 {
            sum_sq += (vertices[tet[a]] - vertices[tet[b]]).norm_squared();
        }
    }
    let l_rms = (sum_sq / 6.0).sqrt();
    let quality = if l_rms > 0.0 {
        6.0 * std::f64::consts::SQRT_2 * volume.abs() / (l_rms * l_rms * l_rms)
    } else {
        0.0
    };
    (volume, quality)
}

/// Read a mesh, choosing the reader by file extension: `.obj`, `.node`/`.ele` (TetGen), `.msh`.
///
/// ```
/// use diffsoft::mesh::{self, MeshFormat};
///
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../verification/paper/droneman/ball_tet.obj");
/// let loaded = mesh::load(path)?;
/// assert_eq!(loaded.info.format, MeshFormat::Obj);
/// assert!(loaded.mesh.num_tets() > 0);
/// assert!((0..loaded.mesh.num_tets()).all(|t| loaded.mesh.signed_volume(t) > 0.0));
/// // An unknown extension is an error that names the file.
/// let err = mesh::load("mesh.stl").unwrap_err();
/// assert_eq!(err.location.path, "mesh.stl");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn load(path: impl AsRef<Path>) -> Result<LoadedMesh, MeshError> {
    load_with(path, LoadOptions::default())
}

/// As [`load`], with explicit options.
///
/// ```
/// use diffsoft::mesh::{self, LoadOptions, MeshErrorKind};
///
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../verification/paper/droneman/ball_tet.obj");
/// let loaded = mesh::load_with(path, LoadOptions { min_quality: 1e-6 })?;
/// assert!(loaded.mesh.num_tets() > 0);
/// // No tet is as good as a regular one: a threshold above 1 refuses the mesh.
/// let err = mesh::load_with(path, LoadOptions { min_quality: 1.5 }).unwrap_err();
/// assert!(matches!(err.kind, MeshErrorKind::DegenerateTet { .. }));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn load_with(path: impl AsRef<Path>, opts: LoadOptions) -> Result<LoadedMesh, MeshError> {
    let path = path.as_ref();
    let shown = path.display().to_string();
    if path.as_os_str().is_empty() {
        return Err(MeshError::file(
            "<empty path>",
            MeshErrorKind::UnsupportedFormat("the mesh path is empty".into()),
        ));
    }
    if path.is_dir() {
        return Err(MeshError::file(
            &shown,
            MeshErrorKind::UnsupportedFormat("is a directory, expected a mesh file".into()),
        ));
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "obj" => parse_obj_text(&shown, &read_text(path)?, opts),
        "node" | "ele" => {
            let original = path.extension().and_then(|e| e.to_str()).unwrap_or_default();
            let (node_ext, ele_ext) = tetgen_extensions(original);
            let node_path = path.with_extension(node_ext);
            let ele_path = path.with_extension(ele_ext);
            let node_text = read_text(&node_path)?;
            let ele_text = read_text(&ele_path)?;
            let raw = tetgen::parse(
                &node_path.display().to_string(),
                &node_text,
                &ele_path.display().to_string(),
                &ele_text,
            )?;
            TetMesh::from_raw(&ele_path.display().to_string(), MeshFormat::Tetgen, raw, opts)
        }
        "msh" => parse_gmsh_text(&shown, &read_text(path)?, opts),
        _ => Err(unsupported_extension(&shown, &ext)),
    }
}

/// The extensions of a TetGen pair, in the case of `ext` (the extension one half was named
/// with: `T.NODE` goes with `T.ELE`, `t.node` and `t.Node` with `t.ele`): `(node, ele)`.
pub(crate) fn tetgen_extensions(ext: &str) -> (&'static str, &'static str) {
    let upper = !ext.is_empty() && ext.chars().all(|c| c.is_ascii_uppercase());
    if upper {
        ("NODE", "ELE")
    } else {
        ("node", "ele")
    }
}

/// The mesh in the text of OBJ file `shown` (named in messages), validated with `opts`.
pub(crate) fn parse_obj_text(shown: &str, text: &str, opts: LoadOptions) -> Result<LoadedMesh, MeshError> {
    let raw = obj::parse(shown, text)?;
    TetMesh::from_raw(shown, MeshFormat::Obj, raw, opts)
}

/// The mesh in the text of Gmsh file `shown` (named in messages), validated with `opts`.
pub(crate) fn parse_gmsh_text(shown: &str, text: &str, opts: LoadOptions) -> Result<LoadedMesh, MeshError> {
    let (raw, format) = gmsh::parse(shown, text)?;
    TetMesh::from_raw(shown, format, raw, opts)
}

/// The error for mesh file `shown`, whose lower-case extension `ext` (empty: none) no reader
/// takes.
pub(crate) fn unsupported_extension(shown: &str, ext: &str) -> MeshError {
    let what = if ext.is_empty() {
        "no file extension".to_string()
    } else {
        format!("extension '.{ext}'")
    };
    MeshError::file(
        shown,
        MeshErrorKind::UnsupportedFormat(format!(
            "{what} (expected .obj with t lines, TetGen .node/.ele, or Gmsh .msh)"
        )),
    )
}

/// Parse mesh text already in memory; `format_hint` is a file name used for the extension and
/// in messages (TetGen needs two texts and is not supported here).
///
/// ```
/// use diffsoft::mesh;
///
/// let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3\n";
/// let loaded = mesh::parse_str("tet.obj", text)?;
/// assert_eq!((loaded.mesh.num_vertices(), loaded.mesh.num_tets()), (4, 1));
/// // Errors name the file and the line.
/// let err = mesh::parse_str("bad.obj", "v 0 0 0\nt 0 1 2 x\n").unwrap_err();
/// assert_eq!((err.location.path.as_str(), err.location.line), ("bad.obj", Some(2)));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn parse_str(name: &str, text: &str) -> Result<LoadedMesh, MeshError> {
    let lower = name.to_ascii_lowercase();
    if lower.ends_with(".obj") {
        parse_obj_text(name, text, LoadOptions::default())
    } else if lower.ends_with(".msh") {
        parse_gmsh_text(name, text, LoadOptions::default())
    } else {
        Err(MeshError::file(
            name,
            MeshErrorKind::UnsupportedFormat("parse_str reads .obj and .msh text".into()),
        ))
    }
}

/// Parse a TetGen pair already in memory.
///
/// ```
/// use diffsoft::mesh::{self, MeshFormat};
///
/// // 1-based numbering, decided by the first node id.
/// let node = "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n";
/// let ele = "1 4 0\n1 1 2 3 4\n";
/// let loaded = mesh::parse_tetgen_str("tet.node", node, "tet.ele", ele)?;
/// assert_eq!(loaded.mesh.tets, vec![[0, 1, 2, 3]]);
/// assert_eq!(loaded.info.file_ids, vec![1, 2, 3, 4]);
/// assert_eq!(loaded.info.format, MeshFormat::Tetgen);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn parse_tetgen_str(
    node_name: &str,
    node_text: &str,
    ele_name: &str,
    ele_text: &str,
) -> Result<LoadedMesh, MeshError> {
    let raw = tetgen::parse(node_name, node_text, ele_name, ele_text)?;
    TetMesh::from_raw(ele_name, MeshFormat::Tetgen, raw, LoadOptions::default())
}

fn read_text(path: &Path) -> Result<String, MeshError> {
    crate::base::input_file::read_text(path).map_err(|e| text_error(&path.display().to_string(), &e))
}

/// A mesh file's text that could not be had (`e`, from [`crate::base::input_file`]) as the
/// error naming the file `shown`: bytes that are not text are an unsupported format.
pub(crate) fn text_error(shown: &str, e: &std::io::Error) -> MeshError {
    match e.kind() {
        std::io::ErrorKind::InvalidData => MeshError::file(shown, MeshErrorKind::UnsupportedFormat(e.to_string())),
        _ => MeshError::file(shown, MeshErrorKind::Io(e.to_string())),
    }
}
