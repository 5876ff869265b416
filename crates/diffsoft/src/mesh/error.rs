//! Mesh errors: every error names the file, and the line or element it is about.

use std::fmt;

/// Where in an input a mesh error was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    /// File path as given by the caller (or `<generated>` / `<memory>`).
    pub path: String,
    /// 1-based line number, when the error belongs to one line.
    pub line: Option<usize>,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}", self.path, line),
            None => write!(f, "{}", self.path),
        }
    }
}

/// What went wrong while reading or validating a mesh.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MeshErrorKind {
    /// The file could not be read.
    #[error("cannot read file: {0}")]
    Io(String),
    /// The file type or format version is not supported.
    #[error("unsupported mesh format: {0}")]
    UnsupportedFormat(String),
    /// The file ends before the data its headers announce.
    #[error("unexpected end of file: {0}")]
    Truncated(String),
    /// A token is not a number of the expected kind.
    #[error("expected {expected}, found '{found}'")]
    BadNumber {
        /// What kind of number was expected.
        expected: &'static str,
        /// The offending token.
        found: String,
    },
    /// A coordinate is NaN or infinite.
    #[error("non-finite coordinate '{0}'")]
    NonFinite(String),
    /// A vertex (node) index does not refer to an existing vertex.
    #[error("tet {tet}: vertex index {index} out of range ({valid})")]
    IndexOutOfRange {
        /// 0-based tet number in file order.
        tet: usize,
        /// The index as written in the file (wide enough for any `i64` or `u64` one).
        index: i128,
        /// The valid range, in the file's numbering.
        valid: String,
    },
    /// A tet uses the same vertex twice.
    #[error("tet {tet}: vertex {vertex} appears more than once")]
    RepeatedVertex {
        /// 0-based tet number in file order.
        tet: usize,
        /// The repeated vertex, in the file's numbering.
        vertex: i64,
    },
    /// Two tets have the same four vertices (in any order): the element would count twice.
    #[error("tet {tet} repeats tet {first} (the same four vertices)")]
    DuplicateTet {
        /// 0-based tet number in file order.
        tet: usize,
        /// The earlier tet it repeats.
        first: usize,
    },
    /// Two tets have their corners at the same four positions through different vertices (the
    /// mesh repeats vertices there): the same solid would count twice.
    #[error("tet {tet} lies on tet {first}: their corners are at the same four positions (vertices {vertices:?} of tet {tet} repeat those of tet {first} at the same places; merge the repeated vertices)")]
    CoincidentTet {
        /// 0-based tet number in file order.
        tet: usize,
        /// The earlier tet it lies on.
        first: usize,
        /// The later tet's vertices, in the file's numbering.
        vertices: [i64; 4],
    },
    /// A tet has zero or near-zero volume.
    #[error("tet {tet}: degenerate (volume {volume:e}; 6*sqrt(2)*|V|/l_rms^3 = {quality:e} is below {threshold:e})")]
    DegenerateTet {
        /// 0-based tet number in file order.
        tet: usize,
        /// Signed volume.
        volume: f64,
        /// Normalised volume (1 for a regular tet).
        quality: f64,
        /// The rejection threshold on the normalised volume.
        threshold: f64,
    },
    /// A structural problem: wrong token count, missing section, inconsistent header.
    #[error("{0}")]
    Syntax(String),
    /// The mesh has no tetrahedra.
    #[error("mesh has no tetrahedra")]
    NoTets,
    /// Declared or requested sizes overflow or do not fit in memory.
    #[error("{0}")]
    TooLarge(String),
}

/// A mesh error with its location.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{location}: {kind}")]
pub struct MeshError {
    /// File and line.
    pub location: Location,
    /// What went wrong.
    pub kind: MeshErrorKind,
}

impl MeshError {
    /// An error about one line of a file.
    ///
    /// ```
    /// use diffsoft::mesh::{MeshError, MeshErrorKind};
    ///
    /// let e = MeshError::at("cube.msh", 12, MeshErrorKind::NoTets);
    /// assert_eq!(e.location.line, Some(12));
    /// assert_eq!(e.to_string(), "cube.msh:12: mesh has no tetrahedra");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn at(path: &str, line: usize, kind: MeshErrorKind) -> Self {
        Self {
            location: Location {
                path: path.to_string(),
                line: Some(line),
            },
            kind,
        }
    }

    /// An error about a whole file.
    ///
    /// ```
    /// use diffsoft::mesh::{MeshError, MeshErrorKind};
    ///
    /// let e = MeshError::file("cube.msh", MeshErrorKind::Io("permission denied".into()));
    /// assert_eq!(e.location.line, None);
    /// assert_eq!(e.to_string(), "cube.msh: cannot read file: permission denied");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn file(path: &str, kind: MeshErrorKind) -> Self {
        Self {
            location: Location {
                path: path.to_string(),
                line: None,
            },
            kind,
        }
    }
}
