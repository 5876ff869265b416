//! Arguments of the Python API read so that a wrong value is refused naming the argument and
//! what it got: counts (`steps`, `iterations`), lists of names (`params`) and lists of dicts
//! (`values`). PyO3's own conversions say only "can't convert negative int to unsigned",
//! "Can't extract `str` to `Vec`" or "'NoneType' object is not iterable".

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PySequence, PyString};

use crate::errors;

/// `type value` of `v` for messages (`float 1.5`, `str 'density'`).
fn described(v: &Bound<'_, PyAny>) -> String {
    let kind = v.get_type().name().map_or_else(|_| "?".to_string(), |n| n.to_string());
    let shown = v.repr().map_or_else(|_| "?".to_string(), |r| r.to_string());
    format!("{kind} {shown}")
}

/// The items of `v`, a sequence (a list or tuple; not a str), named `name` in errors.
fn items<'py>(v: &Bound<'py, PyAny>, name: &str, what: &str) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let seq = match v.cast::<PySequence>() {
        Ok(s) if !v.is_instance_of::<PyString>() => s,
        _ => {
            return Err(PyTypeError::new_err(format!(
                "{name} must be {what}, got {}",
                described(v)
            )))
        }
    };
    seq.try_iter()?.collect()
}

/// `v` as a list of names (`params`), named `name` in errors: a list or tuple of str, each
/// once. A bare str is refused with the list it likely meant.
pub(crate) fn names(v: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<String>> {
    if v.is_instance_of::<PyString>() {
        let shown = v.repr().map_or_else(|_| "?".to_string(), |r| r.to_string());
        return Err(PyTypeError::new_err(format!(
            "{name} must be a list of names, got str {shown} (for one name, write [{shown}])"
        )));
    }
    let names: Vec<String> = items(v, name, "a list of names")?
        .iter()
        .enumerate()
        .map(|(k, x)| {
            x.extract::<String>()
                .map_err(|_| PyTypeError::new_err(format!("{name}[{k}] must be a str, got {}", described(x))))
        })
        .collect::<PyResult<_>>()?;
    // A repeat would come back as one entry of the result: refused, as the CLI refuses a
    // repeated `--param`.
    for (k, n) in names.iter().enumerate() {
        if let Some(first) = names[..k].iter().position(|m| m == n) {
            return Err(crate::errors::value(format!(
                "{name}[{k}]: '{n}' is already {name}[{first}]; give each name once"
            )));
        }
    }
    Ok(names)
}

/// `v` as a list of dicts (`values` of the batches), named `name` in errors.
pub(crate) fn dicts<'py>(v: &Bound<'py, PyAny>, name: &str) -> PyResult<Vec<Bound<'py, PyDict>>> {
    items(v, name, "a list of dicts")?
        .into_iter()
        .enumerate()
        .map(|(k, x)| {
            let shown = described(&x);
            x.cast_into::<PyDict>()
                .map_err(|_| PyTypeError::new_err(format!("{name}[{k}] must be a dict, got {shown}")))
        })
        .collect()
}

/// `v` as a count of at least `min`, named `name` in errors: an int or an object with
/// `__index__` (a NumPy integer), not a bool. Not an int: `TypeError`; below `min` or beyond a
/// machine word: `InputError` (a `ValueError`).
pub(crate) fn count(v: &Bound<'_, PyAny>, name: &str, min: usize) -> PyResult<usize> {
    let shown = || v.repr().map_or_else(|_| "?".to_string(), |r| r.to_string());
    let not_int = || PyTypeError::new_err(format!("{name} must be an int, got {}", described(v)));
    if v.is_instance_of::<PyBool>() {
        return Err(not_int());
    }
    // Only the failures that say "not an int" become the message (the original its cause); an
    // exception of the value's own `__index__` (a `KeyboardInterrupt`, a `MemoryError`, a
    // user's error) propagates unchanged.
    let index = v.call_method0("__index__").map_err(|e| {
        let py = v.py();
        let not_an_int = e.is_instance_of::<pyo3::exceptions::PyAttributeError>(py)
            || e.is_instance_of::<PyTypeError>(py)
            || e.is_instance_of::<pyo3::exceptions::PyValueError>(py);
        if !not_an_int {
            return e;
        }
        let err = not_int();
        err.set_cause(py, Some(e));
        err
    })?;
    let n: i128 = match index.extract() {
        Ok(n) => n,
        // An int beyond 128 bits: far past any count.
        Err(_) => {
            return Err(errors::value(format!(
                "{name} must be at most {}, got {}",
                usize::MAX,
                shown()
            )))
        }
    };
    if n < min as i128 {
        return Err(errors::value(format!("{name} must be at least {min}, got {n}")));
    }
    usize::try_from(n).map_err(|_| errors::value(format!("{name} must be at most {}, got {n}", usize::MAX)))
}

/// `v` as a file path, named `name` in errors: a str or an `os.PathLike` whose `__fspath__`
/// gives a str (a `pathlib.Path`). Anything else (bytes included) is a `TypeError` saying what
/// it got.
pub(crate) fn path(v: &Bound<'_, PyAny>, name: &str) -> PyResult<std::path::PathBuf> {
    let wrong = || {
        PyTypeError::new_err(format!(
            "{name} must be a str or an os.PathLike (such as pathlib.Path), got {}",
            described(v)
        ))
    };
    let fspath = if v.is_instance_of::<PyString>() {
        v.clone()
    } else if v.is_instance_of::<pyo3::types::PyBytes>() || !v.hasattr("__fspath__")? {
        return Err(wrong());
    } else {
        v.py().import("os")?.call_method1("fspath", (v,))?
    };
    if !fspath.is_instance_of::<PyString>() {
        return Err(wrong());
    }
    // pyo3's conversion, which keeps the bytes of a name Python decoded with `surrogateescape`.
    fspath.extract::<std::path::PathBuf>()
}
