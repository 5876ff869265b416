//! Python objects of a scene dict as JSON (`Scene.from_dict`), numbers kept exactly (a float is
//! its f64; no text in between) and every error naming its place in the dict.

use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde_json::Value as Json;

use crate::errors;

/// A Python object of a scene dict as JSON: dicts with string keys, lists, tuples, numpy arrays
/// and scalars, numbers (finite), strings, paths, bools and `None`. `at` names the place in
/// messages (`bodies[0].mesh.vertices[3][1]`).
pub(crate) fn to_json(obj: &Bound<'_, PyAny>, at: &str) -> PyResult<Json> {
    let here = |what: String| errors::value(format!("scene dict: {}{what}", if at.is_empty() { "" } else { at }));
    if obj.is_none() {
        return Ok(Json::Null);
    }
    if let Ok(b) = obj.cast::<PyBool>() {
        return Ok(Json::Bool(b.is_true()));
    }
    if let Ok(i) = obj.cast::<PyInt>() {
        if let Ok(v) = i.extract::<i64>() {
            return Ok(Json::from(v));
        }
        return Ok(Json::from(
            i.extract::<u64>().map_err(|_| here(": integer out of range".into()))?,
        ));
    }
    if let Ok(f) = obj.cast::<PyFloat>() {
        let v = f.value();
        return serde_json::Number::from_f64(v)
            .map(Json::Number)
            .ok_or_else(|| here(format!(": {v} is not a finite number")));
    }
    if let Ok(s) = obj.cast::<PyString>() {
        return Ok(Json::String(s.extract::<String>()?));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        let mut m = serde_json::Map::new();
        for (k, v) in d.iter() {
            let key: String = k.extract().map_err(|_| {
                here(format!(
                    ": keys must be strings, got {}",
                    k.repr().map_or("?".into(), |r| r.to_string())
                ))
            })?;
            let inner = if at.is_empty() {
                key.clone()
            } else {
                format!("{at}.{key}")
            };
            m.insert(key, to_json(&v, &inner)?);
        }
        return Ok(Json::Object(m));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        return obj
            .try_iter()?
            .enumerate()
            .map(|(k, x)| to_json(&x?, &format!("{at}[{k}]")))
            .collect::<PyResult<Vec<_>>>()
            .map(Json::Array);
    }
    let py = obj.py();
    // numpy arrays and scalars (and anything else with `tolist`) as lists and numbers.
    let np = py.import("numpy")?;
    if obj.is_instance(&np.getattr("ndarray")?)? || obj.is_instance(&np.getattr("generic")?)? {
        return to_json(&obj.call_method0("tolist")?, at);
    }
    let os = py.import("os")?;
    if obj.is_instance(&os.getattr("PathLike")?)? {
        return to_json(&os.call_method1("fspath", (obj,))?, at);
    }
    Err(here(format!(
        ": cannot be written in a scene (a {})",
        obj.get_type().name().map_or("?".into(), |n| n.to_string())
    )))
}
