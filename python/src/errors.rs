//! Errors of the library as Python exceptions: bad input is a `ValueError`, a file that cannot
//! be read an `OSError`, a simulation that fails (divergence, non-finite state, factorization)
//! a `RuntimeError`. Each message is the library's, which names the file, line, element or
//! parameter.

use diffsoft::mesh::{MeshError, MeshErrorKind};
use diffsoft::scene::SceneError;
use diffsoft::solver::SolverError;
use diffsoft::DiffError;
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::PyErr;

/// A solver error: input and certification problems are the caller's (`ValueError`), the rest
/// are failures of the run (`RuntimeError`).
pub fn solver(e: SolverError) -> PyErr {
    match e {
        SolverError::Input(_) | SolverError::Uncertified(_) => PyValueError::new_err(e.to_string()),
        _ => PyRuntimeError::new_err(e.to_string()),
    }
}

/// A differentiation error.
pub fn diff(e: DiffError) -> PyErr {
    match e {
        DiffError::Input(_) | DiffError::Unsupported(_) => PyValueError::new_err(e.to_string()),
        DiffError::Solver(s) => solver(s),
        _ => PyRuntimeError::new_err(e.to_string()),
    }
}

/// A mesh error: unreadable files are `OSError`, malformed ones `ValueError`.
pub fn mesh(e: MeshError) -> PyErr {
    match e.kind {
        MeshErrorKind::Io(_) => PyOSError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// A scene error.
pub fn scene(e: SceneError) -> PyErr {
    match e {
        SceneError::Io { .. } => PyOSError::new_err(e.to_string()),
        SceneError::Mesh(m) => mesh(m),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// Any other error of the harness (reports that could not be produced).
pub fn other(e: impl std::fmt::Display) -> PyErr {
    PyRuntimeError::new_err(e.to_string())
}

/// Bad input found by the bindings themselves.
pub fn value(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}
