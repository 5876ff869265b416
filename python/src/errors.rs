//! Errors of the library as Python exceptions: the classes of `diffsoft._errors`
//! (`python/diffsoft/_errors.py`), each a subclass of `diffsoft.DiffsoftError` and of the
//! built-in that matches it, so `except ValueError` / `OSError` / `RuntimeError` catch them:
//!
//! * bad input is an `InputError` (`ValueError`), and an input too large for the process's
//!   memory an `OutOfMemoryError` (an `InputError` and a `MemoryError`); a feature that is not supported an
//!   `UnsupportedError` and a time step that certification refuses an `UncertifiedError`
//!   (both `InputError`s);
//! * a file that cannot be read is a `FileError` (`OSError`);
//! * a run that fails is a `SimulationError` (`RuntimeError`): a `DivergenceError` for
//!   divergence and non-finite states, a `ConvergenceError` for a gradient refused because the
//!   forward pass did not converge or its replay deviates;
//! * a `set`/`configure` of a scene that a call on another thread is reading is a
//!   `SceneBusyError` (`RuntimeError`).
//!
//! Each message is the library's, which names the file, line, element or parameter.
//!
//! The errors are built without the GIL (inside `Python::detach`), so the exception object is
//! made lazily: a `PyErr` of the built-in base whose argument, made when the error reaches
//! Python, is already an instance of the class. CPython raises such an instance as it is (an
//! exception value that is an instance of a subclass of the type raised is kept). Should
//! `diffsoft._errors` fail to import, the error is the built-in base with the same message.

use diffsoft::kernel::actuator::ActuatorError;
use diffsoft::kernel::ProjectionError;
use diffsoft::mesh::{MeshError, MeshErrorKind};
use diffsoft::scene::SceneError;
use diffsoft::solver::SolverError;
use diffsoft::DiffError;
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyString, PyType};
use pyo3::PyErrArguments;

/// The module that defines the classes.
const MODULE: &str = "diffsoft._errors";

/// An exception class of `diffsoft._errors`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    /// `InputError` (`ValueError`).
    Input,
    /// `UnsupportedError` (an `InputError`).
    Unsupported,
    /// `UncertifiedError` (an `InputError`).
    Uncertified,
    /// `OutOfMemoryError` (an `InputError` and a `MemoryError`).
    Memory,
    /// `FileError` (`OSError`).
    File,
    /// `SimulationError` (`RuntimeError`).
    Simulation,
    /// `DivergenceError` (a `SimulationError`).
    Divergence,
    /// `ConvergenceError` (a `SimulationError`).
    Convergence,
    /// `SceneBusyError` (`RuntimeError`).
    Busy,
}

/// The built-in exception a class derives from (the type of the lazy `PyErr`).
enum Builtin {
    Value,
    OS,
    Runtime,
}

impl Class {
    /// Every class, in declaration order (`self as usize` indexes the cache of classes).
    const ALL: [Class; 9] = [
        Class::Input,
        Class::Unsupported,
        Class::Uncertified,
        Class::Memory,
        Class::File,
        Class::Simulation,
        Class::Divergence,
        Class::Convergence,
        Class::Busy,
    ];

    /// The class's name in `diffsoft._errors`.
    fn name(self) -> &'static str {
        match self {
            Class::Input => "InputError",
            Class::Unsupported => "UnsupportedError",
            Class::Uncertified => "UncertifiedError",
            Class::Memory => "OutOfMemoryError",
            Class::File => "FileError",
            Class::Simulation => "SimulationError",
            Class::Divergence => "DivergenceError",
            Class::Convergence => "ConvergenceError",
            Class::Busy => "SceneBusyError",
        }
    }

    fn builtin(self) -> Builtin {
        match self {
            // An `OutOfMemoryError` is also a `ValueError` (its first base), so it is raised as is.
            Class::Input | Class::Unsupported | Class::Uncertified | Class::Memory => Builtin::Value,
            Class::File => Builtin::OS,
            Class::Simulation | Class::Divergence | Class::Convergence | Class::Busy => Builtin::Runtime,
        }
    }

    /// The Python class, imported once.
    fn class<'py>(self, py: Python<'py>) -> PyResult<&'py Bound<'py, PyType>> {
        static CLASSES: [PyOnceLock<Py<PyType>>; Class::ALL.len()] = [const { PyOnceLock::new() }; Class::ALL.len()];
        CLASSES[self as usize].import(py, MODULE, self.name())
    }

    /// An error of this class with `message`.
    pub fn err(self, message: impl Into<String>) -> PyErr {
        let args = Lazy {
            class: self,
            message: message.into(),
        };
        match self.builtin() {
            Builtin::Value => PyValueError::new_err(args),
            Builtin::OS => PyOSError::new_err(args),
            Builtin::Runtime => PyRuntimeError::new_err(args),
        }
    }
}

/// The argument of a lazy `PyErr`: an instance of the class, made when the error reaches
/// Python.
struct Lazy {
    class: Class,
    message: String,
}

impl PyErrArguments for Lazy {
    fn arguments(self, py: Python<'_>) -> Py<PyAny> {
        let instance = self.class.class(py).and_then(|c| c.call1((self.message.as_str(),)));
        match instance {
            Ok(e) => e.unbind(),
            // The built-in base with the message (see the module docs).
            Err(_) => PyString::new(py, &self.message).into_any().unbind(),
        }
    }
}

/// The class of a failed constraint or actuator projection: divergence when its input was
/// not finite, otherwise a simulation error.
fn projection(source: &ProjectionError) -> Class {
    match source {
        ProjectionError::NonFinite => Class::Divergence,
        _ => Class::Simulation,
    }
}

/// A solver error: input and certification refusals are the caller's (`InputError`,
/// `UncertifiedError`), non-finite states and divergence a `DivergenceError`, the rest
/// (factorization, the eigenvalues behind certification, projections) a `SimulationError`.
pub fn solver(e: SolverError) -> PyErr {
    let class = match &e {
        SolverError::Input(i) if i.is_out_of_memory() => Class::Memory,
        SolverError::Input(_) => Class::Input,
        SolverError::Uncertified(_) => Class::Uncertified,
        SolverError::NonFinite(_) | SolverError::Diverged(_) => Class::Divergence,
        // Never seen by a user: an interrupted call raises the signal handler's exception.
        SolverError::Interrupted => Class::Simulation,
        SolverError::Projection { source, .. } => projection(source),
        SolverError::Actuator { source, .. } => match source {
            ActuatorError::NonFinite => Class::Divergence,
            ActuatorError::Projection(p) => projection(p),
            _ => Class::Simulation,
        },
        _ => Class::Simulation,
    };
    class.err(e.to_string())
}

/// A differentiation error: bad input is an `InputError`, a feature the backward pass does not
/// differentiate an `UnsupportedError`, an unconverged forward or a replay that deviates a
/// `ConvergenceError`.
pub fn diff(e: DiffError) -> PyErr {
    let class = match e {
        DiffError::Solver(s) => return solver(s),
        DiffError::Input(_) | DiffError::NothingApplies { .. } => Class::Input,
        DiffError::Unsupported(_) => Class::Unsupported,
        DiffError::Unconverged { .. } | DiffError::CappedSolves { .. } => {
            // The library's advice ("allow unconverged steps explicitly"), as Python spells it.
            return Class::Convergence.err(format!(
                "{e} (allow_unconverged=True: Scene.grad/vjp, the batches, diffsoft.torch/jax.simulate)"
            ));
        }
        DiffError::NotReplayable { .. } => Class::Convergence,
        _ => Class::Simulation,
    };
    class.err(e.to_string())
}

/// A mesh error: unreadable files are a `FileError`, formats not read an `UnsupportedError`,
/// malformed files an `InputError`.
pub fn mesh(e: MeshError) -> PyErr {
    let class = match e.kind {
        MeshErrorKind::Io(_) => Class::File,
        MeshErrorKind::UnsupportedFormat(_) => Class::Unsupported,
        _ => Class::Input,
    };
    class.err(e.to_string())
}

/// A scene error: unreadable files are a `FileError`, features not simulated an
/// `UnsupportedError`, the rest an `InputError`.
pub fn scene(e: SceneError) -> PyErr {
    let class = match &e {
        SceneError::Mesh(m) => match m.kind {
            MeshErrorKind::Io(_) => Class::File,
            MeshErrorKind::UnsupportedFormat(_) => Class::Unsupported,
            _ => Class::Input,
        },
        SceneError::Io { .. } => Class::File,
        SceneError::Unsupported { .. } => Class::Unsupported,
        _ => Class::Input,
    };
    class.err(e.to_string())
}

/// Any other error (a report that could not be produced): a `SimulationError`.
pub fn other(e: impl std::fmt::Display) -> PyErr {
    Class::Simulation.err(e.to_string())
}

/// A panic inside the library (a bug): a `RuntimeError` naming it as internal, with its text.
pub fn panicked(message: impl std::fmt::Display) -> PyErr {
    pyo3::exceptions::PyRuntimeError::new_err(format!("internal error in diffsoft: {message}"))
}

/// Bad input found by the bindings themselves: an `InputError`.
pub fn value(msg: impl Into<String>) -> PyErr {
    Class::Input.err(msg)
}
