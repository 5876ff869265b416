//! Count arguments of the Python API (`steps`, `iterations`), read so that a wrong value is
//! refused naming the argument and what it got: PyO3's own conversion to `usize` says only
//! "can't convert negative int to unsigned" or "'float' object cannot be interpreted as an
//! integer".

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyBool;

use crate::errors;

/// `v` as a count of at least `min`, named `name` in errors: an int or an object with
/// `__index__` (a NumPy integer), not a bool. Not an int: `TypeError`; below `min` or beyond a
/// machine word: `InputError` (a `ValueError`).
pub(crate) fn count(v: &Bound<'_, PyAny>, name: &str, min: usize) -> PyResult<usize> {
    let shown = || v.repr().map_or_else(|_| "?".to_string(), |r| r.to_string());
    let kind = || v.get_type().name().map_or_else(|_| "?".to_string(), |n| n.to_string());
    let not_int = || PyTypeError::new_err(format!("{name} must be an int, got {} {}", kind(), shown()));
    if v.is_instance_of::<PyBool>() {
        return Err(not_int());
    }
    let index = v.call_method0("__index__").map_err(|_| not_int())?;
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
