//! Structured box and beam meshes (each cell split into tets), with optional jitter, for tests,
//! benchmarks and convergence studies.

use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{MeshError, MeshErrorKind, TetMesh};

/// How each hexahedral cell is split into tets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellSplit {
    /// Six tets around the cell diagonal (Kuhn / Freudenthal). Every tet is an orthoscheme, so
    /// no dihedral angle is obtuse: `L` is an M-matrix for any cell aspect ratio.
    Kuhn6,
    /// Five tets (four corners + a central tet), mirrored in alternate cells for conformity.
    Five,
}

/// A structured box of `cells[0] x cells[1] x cells[2]` hexahedral cells.
#[derive(Debug, Clone, Copy)]
pub struct BoxSpec {
    /// Cells per axis.
    pub cells: [usize; 3],
    /// Box edge lengths.
    pub size: [f64; 3],
    /// Position of the minimum corner.
    pub origin: [f64; 3],
    /// Cell split.
    pub split: CellSplit,
    /// Each vertex moves by a uniform random offset of up to `jitter` times the cell size per
    /// axis (0 for a regular grid; above ~0.3 tets may invert or degenerate).
    pub jitter: f64,
    /// Seed for the jitter.
    pub seed: u64,
}

impl BoxSpec {
    /// A regular Kuhn-split box with the minimum corner at the origin.
    ///
    /// ```
    /// use diffsoft::mesh::generate::{BoxSpec, CellSplit};
    ///
    /// let spec = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1]);
    /// assert_eq!(spec.split, CellSplit::Kuhn6);
    /// assert_eq!(spec.num_tets(), 12);
    /// let five = spec.split(CellSplit::Five).origin([0.0, 1.0, 0.0]).jitter(0.1, 7);
    /// assert_eq!(five.num_tets(), 10);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(cells: [usize; 3], size: [f64; 3]) -> Self {
        Self {
            cells,
            size,
            origin: [0.0; 3],
            split: CellSplit::Kuhn6,
            jitter: 0.0,
            seed: 0,
        }
    }

    /// The same box with another cell split.
    pub fn split(mut self, split: CellSplit) -> Self {
        self.split = split;
        self
    }

    /// The same box with vertex jitter (fraction of the cell size) from `seed`.
    pub fn jitter(mut self, jitter: f64, seed: u64) -> Self {
        self.jitter = jitter;
        self.seed = seed;
        self
    }

    /// The same box translated so its minimum corner is at `origin`.
    pub fn origin(mut self, origin: [f64; 3]) -> Self {
        self.origin = origin;
        self
    }

    /// Number of tets this spec produces (saturating at `usize::MAX`).
    pub fn num_tets(&self) -> usize {
        let per = match self.split {
            CellSplit::Kuhn6 => 6,
            CellSplit::Five => 5,
        };
        self.cells.iter().fold(per, |n, &c| n.saturating_mul(c))
    }

    /// Build the mesh (validated and oriented like a loaded one).
    ///
    /// ```
    /// use diffsoft::mesh::generate::BoxSpec;
    ///
    /// let mesh = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1]).origin([0.0, 1.0, 0.0]).build()?;
    /// assert_eq!((mesh.num_vertices(), mesh.num_tets()), (12, 12));
    /// let (lo, hi) = mesh.bounding_box();
    /// assert!((lo.y - 1.0).abs() < 1e-12 && (hi.x - 0.2).abs() < 1e-12);
    /// // A box needs a cell on every axis.
    /// assert!(BoxSpec::new([0, 1, 1], [1.0, 1.0, 1.0]).build().is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn build(&self) -> Result<TetMesh, MeshError> {
        box_mesh(self)
    }
}

/// A beam along x: `length x width x height` with `n` cells along and `m` across each side.
///
/// ```
/// use diffsoft::mesh::generate::beam;
///
/// let spec = beam(1.0, 0.1, 0.1, 4, 1);
/// assert_eq!(spec.cells, [4, 1, 1]);
/// let mesh = spec.build()?;
/// assert_eq!(mesh.num_tets(), 24);
/// assert!((mesh.bounding_box().1.x - 1.0).abs() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn beam(length: f64, width: f64, height: f64, n: usize, m: usize) -> BoxSpec {
    BoxSpec::new([n, m, m], [length, width, height])
}

/// A box whose Kuhn split has about `target_tets` tets with cubic cells on a `1 x 1 x aspect`
/// domain; used by benchmarks and scaling studies.
///
/// ```
/// use diffsoft::mesh::generate::box_with_about;
///
/// let spec = box_with_about(48, 1.0);
/// assert_eq!(spec.cells, [2, 2, 2]);
/// assert_eq!(spec.num_tets(), 48);
/// assert_eq!(spec.build()?.num_tets(), 48);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn box_with_about(target_tets: usize, aspect: f64) -> BoxSpec {
    let cells = target_tets as f64 / 6.0;
    let k = (cells / aspect).cbrt().max(1.0);
    let nz = (k * aspect).round().max(1.0) as usize;
    let k = k.round().max(1.0) as usize;
    BoxSpec::new([k, k, nz], [1.0, 1.0, nz as f64 / k as f64])
}

/// Vertex and tet counts of `spec`, checked against overflow and against the machine's memory
/// (the mesh and the model built on it need well over 200 bytes per tet; 256 are checked here).
fn checked_sizes(spec: &BoxSpec) -> Result<(usize, usize), MeshError> {
    let [nx, ny, nz] = spec.cells;
    let what = format!("a box of {nx} x {ny} x {nz} cells");
    let too_large = |m: String| MeshError::file("generated mesh", MeshErrorKind::TooLarge(m));
    let per = match spec.split {
        CellSplit::Kuhn6 => 6,
        CellSplit::Five => 5,
    };
    let vertices = [nx, ny, nz]
        .iter()
        .try_fold(1usize, |acc, &c| c.checked_add(1).and_then(|c| acc.checked_mul(c)));
    let tets = [nx, ny, nz, per].iter().try_fold(1usize, |acc, &c| acc.checked_mul(c));
    if spec.cells.contains(&0) {
        let m = format!("{what}: every axis needs at least one cell");
        return Err(MeshError::file("generated mesh", MeshErrorKind::Syntax(m)));
    }
    if let Some(bad) = spec.size.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
        let m = format!(
            "{what}: every edge length must be finite and positive, got {} in size [{}]",
            crate::base::number(*bad),
            spec.size.map(crate::base::number).join(", ")
        );
        return Err(MeshError::file("generated mesh", MeshErrorKind::Syntax(m)));
    }
    if let Some(bad) = spec.origin.iter().find(|o| !o.is_finite()) {
        let m = format!("{what}: its origin must be finite, got {}", crate::base::number(*bad));
        return Err(MeshError::file("generated mesh", MeshErrorKind::Syntax(m)));
    }
    let (Some(vertices), Some(tets)) = (vertices, tets) else {
        return Err(too_large(format!("{what}: the vertex or tet count overflows")));
    };
    crate::base::memory::check(&what, tets, 256).map_err(|e| too_large(e.message().to_string()))?;
    Ok((vertices, tets))
}

fn box_mesh(spec: &BoxSpec) -> Result<TetMesh, MeshError> {
    let [nx, ny, nz] = spec.cells;
    let h = [
        spec.size[0] / nx as f64,
        spec.size[1] / ny as f64,
        spec.size[2] / nz as f64,
    ];
    let (num_vertices, num_tets) = checked_sizes(spec)?;
    let id = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let mut vertices = Vec::with_capacity(num_vertices);
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                let mut p = Vector3::new(
                    spec.origin[0] + i as f64 * h[0],
                    spec.origin[1] + j as f64 * h[1],
                    spec.origin[2] + k as f64 * h[2],
                );
                if spec.jitter > 0.0 {
                    for a in 0..3 {
                        p[a] += spec.jitter * h[a] * rng.random_range(-1.0..=1.0);
                    }
                }
                vertices.push(p);
            }
        }
    }
    let mut tets = Vec::with_capacity(num_tets);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                // Cell corners c[b] with bit 0 = x, bit 1 = y, bit 2 = z.
                let c: [usize; 8] = std::array::from_fn(|b| id(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1)));
                match spec.split {
                    CellSplit::Kuhn6 => {
                        // Paths 0 -> 7 through the cube, one per permutation of the axes.
                        for perm in [[1, 2, 4], [1, 4, 2], [2, 1, 4], [2, 4, 1], [4, 1, 2], [4, 2, 1]] {
                            let a = perm[0];
                            let b = a + perm[1];
                            tets.push([c[0], c[a], c[b], c[7]]);
                        }
                    }
                    CellSplit::Five => {
                        if (i + j + k) % 2 == 0 {
                            tets.push([c[1], c[0], c[3], c[5]]);
                            tets.push([c[2], c[3], c[0], c[6]]);
                            tets.push([c[4], c[5], c[6], c[0]]);
                            tets.push([c[7], c[6], c[5], c[3]]);
                            tets.push([c[0], c[3], c[5], c[6]]);
                        } else {
                            tets.push([c[0], c[1], c[2], c[4]]);
                            tets.push([c[3], c[2], c[1], c[7]]);
                            tets.push([c[5], c[4], c[7], c[1]]);
                            tets.push([c[6], c[7], c[4], c[2]]);
                            tets.push([c[1], c[2], c[4], c[7]]);
                        }
                    }
                }
            }
        }
    }
    TetMesh::new(vertices, tets)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn absurd_cell_counts_are_errors_not_aborts() {
        assert!(BoxSpec::new([0, 1, 1], [1.0; 3]).build().is_err());
        for cells in [
            [usize::MAX, 2, 2],
            [1 << 22, 1 << 22, 1 << 22],
            [100_000, 100_000, 100_000],
        ] {
            let e = BoxSpec::new(cells, [1.0; 3]).build().unwrap_err();
            assert!(matches!(e.kind, MeshErrorKind::TooLarge(_)), "{cells:?}: {e}");
            assert!(e.to_string().contains(&format!("{} x", cells[0])), "{e}");
        }
    }

    #[test]
    fn kuhn_box_counts_and_volume() {
        let m = BoxSpec::new([2, 3, 4], [1.0, 2.0, 3.0]).build().unwrap();
        assert_eq!(m.num_vertices(), 3 * 4 * 5);
        assert_eq!(m.num_tets(), 6 * 24);
        let vol: f64 = (0..m.num_tets()).map(|t| m.signed_volume(t)).sum();
        assert!((vol - 6.0).abs() < 1e-12);
    }

    #[test]
    fn five_split_box_is_conforming_and_fills_volume() {
        let m = BoxSpec::new([3, 3, 3], [1.0, 1.0, 1.0])
            .split(CellSplit::Five)
            .build()
            .unwrap();
        assert_eq!(m.num_tets(), 5 * 27);
        let vol: f64 = (0..m.num_tets()).map(|t| m.signed_volume(t)).sum();
        assert!((vol - 1.0).abs() < 1e-12);
        // Conformity: every interior face is shared by exactly two tets.
        let mut faces = std::collections::HashMap::new();
        for t in &m.tets {
            for skip in 0..4 {
                let mut f: Vec<usize> = (0..4).filter(|&a| a != skip).map(|a| t[a]).collect();
                f.sort();
                *faces.entry(f).or_insert(0) += 1;
            }
        }
        assert!(faces.values().all(|&c| c == 1 || c == 2));
        let boundary = faces.values().filter(|&&c| c == 1).count();
        assert_eq!(boundary, 6 * 9 * 2);
    }
}
