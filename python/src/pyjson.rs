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
    value(obj, "scene dict", at, 0)
}

/// A Python object given as the value of `what` (`configure(tolerance)`), as JSON: numpy
/// scalars and integers of any size read as [`to_json`] reads them in a scene dict.
pub(crate) fn to_json_for(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Json> {
    value(obj, what, "", 0)
}

/// How deep lists and dicts may nest: serde_json's own limit for a scene file, so a dict
/// reads as its JSON text would (and a list that holds itself is an error, not a stack overflow).
const MAX_DEPTH: usize = 128;

fn value(obj: &Bound<'_, PyAny>, context: &str, at: &str, depth: usize) -> PyResult<Json> {
    let here = |what: String| {
        let place = if at.is_empty() {
            String::new()
        } else {
            format!(": {at}")
        };
        errors::value(format!("{context}{place}{what}"))
    };
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
        if let Ok(v) = i.extract::<u64>() {
            return Ok(Json::from(v));
        }
        // Beyond 64 bits a number is a double, as the same digits in a scene file read.
        let v = i.extract::<f64>().ok().filter(|v| v.is_finite());
        return v
            .and_then(serde_json::Number::from_f64)
            .map(Json::Number)
            .ok_or_else(|| here(": integer too large for a double".into()));
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
    if depth >= MAX_DEPTH {
        return Err(here(format!(
            ": lists and dicts nest deeper than {MAX_DEPTH} levels (does a list or dict hold itself?)"
        )));
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
            m.insert(key, value(&v, context, &inner, depth + 1)?);
        }
        return Ok(Json::Object(m));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        return obj
            .try_iter()?
            .enumerate()
            .map(|(k, x)| value(&x?, context, &format!("{at}[{k}]"), depth + 1))
            .collect::<PyResult<Vec<_>>>()
            .map(Json::Array);
    }
    let py = obj.py();
    // numpy arrays and scalars (and anything else with `tolist`) as lists and numbers.
    let np = py.import("numpy")?;
    if obj.is_instance(&np.getattr("ndarray")?)? {
        return value(&obj.call_method0("tolist")?, context, at, depth);
    }
    if obj.is_instance(&np.getattr("generic")?)? {
        // A numpy scalar: `tolist` gives the Python number, except for the kinds Python has no
        // type for (`longdouble`, whose `tolist` is itself), read here as the double they round to.
        let plain = obj.call_method0("tolist")?;
        if !plain.is_instance(&np.getattr("generic")?)? {
            return value(&plain, context, at, depth);
        }
        if obj.is_instance(&np.getattr("floating")?)? {
            let v: f64 = obj.call_method0("__float__")?.extract()?;
            return serde_json::Number::from_f64(v)
                .map(Json::Number)
                .ok_or_else(|| here(format!(": {v} is not a finite number")));
        }
        return Err(here(format!(
            ": cannot be written in a scene (a numpy {})",
            obj.get_type().name().map_or("?".into(), |n| n.to_string())
        )));
    }
    let os = py.import("os")?;
    if obj.is_instance(&os.getattr("PathLike")?)? {
        return value(&os.call_method1("fspath", (obj,))?, context, at, depth);
    }
    Err(here(format!(
        ": cannot be written in a scene (a {})",
        obj.get_type().name().map_or("?".into(), |n| n.to_string())
    )))
}
