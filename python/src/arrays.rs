//! numpy arrays to and from the library's vectors. Outputs hand their buffer to numpy without
//! a copy; inputs are checked for shape, dtype and finiteness, naming the parameter.

use nalgebra::Vector3;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors;

const _: () = assert!(std::mem::size_of::<Vector3<f64>>() == 3 * std::mem::size_of::<f64>());
const _: () = assert!(std::mem::align_of::<Vector3<f64>>() == std::mem::align_of::<f64>());

/// The coordinates of `v`, without copying: a `Vector3<f64>` is three contiguous `f64`s
/// (nalgebra's column storage, `repr(C)`), checked above at compile time.
pub fn flatten(v: Vec<Vector3<f64>>) -> Vec<f64> {
    let mut v = std::mem::ManuallyDrop::new(v);
    let (ptr, len, cap) = (v.as_mut_ptr(), v.len(), v.capacity());
    // SAFETY: same alignment, and the allocation of `cap` vectors is exactly `3 * cap` f64s,
    // so the layout the allocator sees on drop is the one it handed out.
    unsafe { Vec::from_raw_parts(ptr.cast::<f64>(), 3 * len, 3 * cap) }
}

/// A float64 array of `shape` owning `data` (no copy).
pub fn array<'py>(py: Python<'py>, data: Vec<f64>, shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    let flat = PyArray1::from_vec(py, data);
    Ok(flat.reshape(shape)?.into_any())
}

/// `(rows, 3)` array of vectors.
pub fn vectors<'py>(py: Python<'py>, v: Vec<Vector3<f64>>) -> PyResult<Bound<'py, PyAny>> {
    let rows = v.len();
    array(py, flatten(v), &[rows, 3])
}

/// `(rows, cols)` array from rows of equal length.
pub fn matrix<'py>(py: Python<'py>, rows: &[Vec<f64>], cols: usize) -> PyResult<Bound<'py, PyAny>> {
    let data: Vec<f64> = rows.iter().flat_map(|r| r.iter().copied()).collect();
    array(py, data, &[rows.len(), cols])
}

/// An input array as float64 values with its shape (any numeric dtype or nested sequence is
/// converted by numpy first); every entry must be finite. A conversion that fails on the value
/// ([`conversion_failed`]) is an `InputError` naming `name`, the original its cause; any other
/// exception (a `KeyboardInterrupt`, a `MemoryError`, a user's error) propagates as raised.
pub fn read(name: &str, value: &Bound<'_, PyAny>) -> PyResult<(Vec<f64>, Vec<usize>)> {
    let py = value.py();
    let np = py.import("numpy")?;
    real_numbers(name, value)?;
    let arr = np.call_method1("ascontiguousarray", (value, "float64")).map_err(|e| {
        if !conversion_failed(py, &e) {
            return e;
        }
        let err = errors::value(format!("{name}: not an array of numbers ({e})"));
        err.set_cause(py, Some(e));
        err
    })?;
    let arr: PyReadonlyArrayDyn<'_, f64> = arr.extract()?;
    let shape = arr.shape().to_vec();
    let data = arr.as_slice()?.to_vec();
    if let Some(k) = data.iter().position(|x| !x.is_finite()) {
        return Err(errors::value(format!(
            "{name}: entry {k} (flat index) is {}, expected a finite number",
            data[k]
        )));
    }
    Ok((data, shape))
}

/// Whether `e`, raised while a value converted, says the value is not what was asked for (a
/// `TypeError`, `ValueError` or `OverflowError`): those become the package's message; any other
/// exception is the caller's own and propagates unchanged.
pub fn conversion_failed(py: Python<'_>, e: &PyErr) -> bool {
    use pyo3::exceptions::{PyOverflowError, PyTypeError, PyValueError};
    e.is_instance_of::<PyTypeError>(py)
        || e.is_instance_of::<PyValueError>(py)
        || e.is_instance_of::<PyOverflowError>(py)
}

/// Refuse what numpy would quietly turn into numbers that were never given: `None` (NaN),
/// bools (0 and 1), complex numbers (their real part), text (parsed), dates and times (their
/// ticks), and a masked array's masked entries (whatever lies under the mask).
pub fn real_numbers(name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
    let refuse = |what: &str| Err(errors::value(format!("{name}: got {what}, expected real numbers")));
    if value.is_none() {
        return refuse("None");
    }
    if value.is_instance_of::<pyo3::types::PyBool>() {
        return refuse("a bool");
    }
    let np = value.py().import("numpy")?;
    let ma = np.getattr("ma")?;
    if ma.call_method1("isMaskedArray", (value,))?.is_truthy()? {
        let masked: usize = ma.call_method1("count_masked", (value,))?.extract()?;
        if masked > 0 {
            return Err(errors::value(format!(
                "{name}: a masked array with {masked} masked entries (give the values to use: `.filled(x)`)"
            )));
        }
    }
    let arr = match np.call_method1("asarray", (value,)) {
        Ok(arr) => arr,
        // What numpy cannot read is reported by the conversion that follows.
        Err(e) if conversion_failed(value.py(), &e) => return Ok(()),
        Err(e) => return Err(e),
    };
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    match kind.as_str() {
        "f" | "i" | "u" => Ok(()),
        "b" => refuse("bools"),
        "c" => refuse("complex numbers"),
        "U" | "S" => refuse("text"),
        "M" | "m" => refuse("dates or times"),
        "O" => {
            // Objects (Decimals, mixed lists): numpy converts numbers; None would become NaN.
            let items = arr.call_method0("ravel")?.call_method0("tolist")?;
            for (k, item) in items.try_iter()?.enumerate() {
                let item = item?;
                if item.is_none() {
                    return Err(errors::value(format!(
                        "{name}: entry {k} (flat index) is None, expected a real number"
                    )));
                }
                if item.is_instance_of::<pyo3::types::PyBool>() {
                    return Err(errors::value(format!(
                        "{name}: entry {k} (flat index) is a bool, expected a real number"
                    )));
                }
            }
            Ok(())
        }
        other => refuse(&format!("numpy values of kind '{other}'")),
    }
}

/// A real number: a Python or numpy number, or a 0-d array; refused as [`real_numbers`] says. A
/// value that does not convert is an `InputError` naming `name` (the original its cause) when the
/// conversion raised what [`conversion_failed`] admits; any other exception propagates.
pub fn read_scalar(name: &str, value: &Bound<'_, PyAny>) -> PyResult<f64> {
    real_numbers(name, value)?;
    let py = value.py();
    value.extract::<f64>().map_err(|e| {
        if !conversion_failed(py, &e) {
            return e;
        }
        let err = errors::value(format!("{name}: expected a number"));
        err.set_cause(py, Some(e));
        err
    })
}

/// An `(rows, 3)` array of vectors, from what [`read`] returned.
pub fn vectors_of(name: &str, (data, shape): (Vec<f64>, Vec<usize>), rows: usize) -> PyResult<Vec<Vector3<f64>>> {
    if shape != [rows, 3] {
        return Err(errors::value(format!("{name}: shape {shape:?}, expected ({rows}, 3)")));
    }
    Ok(data.chunks_exact(3).map(|c| Vector3::new(c[0], c[1], c[2])).collect())
}

/// A `(rows, cols)` array as rows (`rows` free when `None`), from what [`read`] returned.
pub fn matrix_of(
    name: &str,
    (data, shape): (Vec<f64>, Vec<usize>),
    rows: Option<usize>,
    cols: usize,
) -> PyResult<Vec<Vec<f64>>> {
    let ok = shape.len() == 2 && shape[1] == cols && rows.is_none_or(|r| shape[0] == r);
    if !ok {
        let want = rows.map_or("steps".to_string(), |r| r.to_string());
        return Err(errors::value(format!(
            "{name}: shape {shape:?}, expected ({want}, {cols})"
        )));
    }
    if cols == 0 {
        return Ok(vec![Vec::new(); shape[0]]);
    }
    Ok(data.chunks_exact(cols).map(<[f64]>::to_vec).collect())
}

/// A `(len,)` array, from what [`read`] returned.
pub fn vector_of(name: &str, (data, shape): (Vec<f64>, Vec<usize>), len: usize) -> PyResult<Vec<f64>> {
    if shape != [len] {
        return Err(errors::value(format!("{name}: shape {shape:?}, expected ({len},)")));
    }
    Ok(data)
}

/// A JSON value as Python objects (dicts, lists, floats, ints, strings, None).
pub fn json<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    use pyo3::types::{PyDict, PyList};
    use serde_json::Value;
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any(),
        Value::Number(n) => match (n.as_i64(), n.as_u64()) {
            (Some(i), _) => i.into_pyobject(py)?.into_any(),
            (None, Some(u)) => u.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(a) => {
            let items = a.iter().map(|x| json(py, x)).collect::<PyResult<Vec<_>>>()?;
            PyList::new(py, items)?.into_any()
        }
        Value::Object(o) => {
            let d = PyDict::new(py);
            for (k, x) in o {
                d.set_item(k, json(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// A serializable report as Python objects.
pub fn report<'py>(py: Python<'py>, r: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let v = serde_json::to_value(r).map_err(errors::other)?;
    json(py, &v)
}
