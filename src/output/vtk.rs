//! VTK XML unstructured-grid frames (`frame_00000.vtu`) of all bodies (tets, and triangles for
//! cloth), with velocity and body id as data, and a ParaView collection `frames.pvd` that orders them in time.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataSet, IOBuffer, UnstructuredGridPiece, Version,
    VertexNumbers, Vtk,
};

use crate::model::Model;

/// Writes numbered frames into a directory and keeps the time collection up to date.
#[derive(Debug)]
pub struct FrameWriter {
    dir: PathBuf,
    cells: Vec<u32>,
    types: Vec<CellType>,
    body: Vec<i32>,
    frames: Vec<(f64, String)>,
}

impl FrameWriter {
    /// Prepare `dir` (created if needed) for the frames of `model`.
    pub fn new(dir: &Path, model: &Model) -> std::io::Result<Self> {
        std::fs::create_dir_all(dir)?;
        let mut cells = Vec::with_capacity(model.tets.len() * 5);
        for t in &model.tets {
            cells.push(4);
            cells.extend(t.iter().map(|&i| i as u32));
        }
        let mut body = vec![0i32; model.tets.len()];
        for (k, b) in model.bodies.iter().enumerate() {
            for t in b.tets.clone() {
                body[t] = k as i32;
            }
        }
        let mut types = vec![CellType::Tetra; model.tets.len()];
        if let Some(cl) = &model.cloth {
            // Cloth triangles follow the tets; their body ids continue the soft bodies'.
            for (k, b) in cl.bodies.iter().enumerate() {
                for t in b.triangles.clone() {
                    cells.push(3);
                    cells.extend(cl.triangles[t].iter().map(|&i| i as u32));
                    types.push(CellType::Triangle);
                    body.push((model.bodies.len() + k) as i32);
                }
            }
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            cells,
            types,
            body,
            frames: Vec::new(),
        })
    }

    /// Write one frame of positions `q` and velocities `v` at `time`; returns its path.
    pub fn write(&mut self, time: f64, q: &[Vector3<f64>], v: &[Vector3<f64>]) -> std::io::Result<PathBuf> {
        let name = format!("frame_{:05}.vtu", self.frames.len());
        let path = self.dir.join(&name);
        let points: Vec<f64> = q.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
        let vel: Vec<f64> = v.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
        let vtk = Vtk {
            version: Version::new((1, 0)),
            byte_order: ByteOrder::LittleEndian,
            title: format!("diffsoft t = {time}"),
            file_path: None,
            data: DataSet::inline(UnstructuredGridPiece {
                points: IOBuffer::F64(points),
                cells: Cells {
                    cell_verts: VertexNumbers::Legacy {
                        num_cells: self.types.len() as u32,
                        vertices: self.cells.clone(),
                    },
                    types: self.types.clone(),
                },
                data: Attributes {
                    point: vec![Attribute::generic("velocity", 3).with_data(IOBuffer::F64(vel))],
                    cell: vec![Attribute::generic("body", 1).with_data(IOBuffer::I32(self.body.clone()))],
                },
            }),
        };
        vtk.export(&path)
            .map_err(|e| std::io::Error::other(format!("{}: {e}", path.display())))?;
        self.frames.push((time, name));
        self.write_collection()?;
        Ok(path)
    }

    fn write_collection(&self) -> std::io::Result<()> {
        let mut s =
            String::from("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n");
        for (t, f) in &self.frames {
            let _ = writeln!(s, "    <DataSet timestep=\"{t:.9e}\" part=\"0\" file=\"{f}\"/>");
        }
        s.push_str("  </Collection>\n</VTKFile>\n");
        std::fs::write(self.dir.join("frames.pvd"), s)
    }

    /// Frames written so far.
    pub fn count(&self) -> usize {
        self.frames.len()
    }
}
