//! The native module of the `diffsoft` Python package (`diffsoft._diffsoft`): bindings of the
//! library's curated API. The Python layer (`python/diffsoft/`) adds the PyTorch and JAX
//! wrappers and the type stubs.

mod args;
mod arrays;
mod batch;
mod errors;
mod fork;
mod harness;
mod interrupt;
mod mesh_access;
mod params;
mod pyjson;
mod run;
mod scene;
mod scene_core;
mod scene_data;
mod scene_source;
mod vjp;
mod warn;

use pyo3::prelude::*;

/// Names and shapes of the array parameters, `[(name, shape, description (unit))]`, from the
/// library's parameter registry.
#[pyfunction]
fn array_parameters() -> Vec<(&'static str, &'static str, String)> {
    diffsoft::diff::params::arrays()
        .map(|p| (p.name, p.shape, p.summary()))
        .collect()
}

/// Names of the scalar parameters (those of the CLI's `--set` and `--param`), from the
/// library's parameter registry.
#[pyfunction]
fn scalar_parameters() -> Vec<&'static str> {
    diffsoft::diff::params::scalar_names()
}

/// A structured box mesh (the library's generator): `cells` hexahedral cells per axis of a box
/// of edge lengths `size` with its minimum corner at `origin` (the origin by default), each cell split into six tets
/// (`split="kuhn"`) or five (`split="five"`); `(vertices (n, 3) float64, tets (m, 4) int64)`.
#[pyfunction]
#[pyo3(signature = (cells, size, origin = None, split = "kuhn"))]
fn mesh_box<'py>(
    py: Python<'py>,
    cells: [usize; 3],
    size: [f64; 3],
    origin: Option<[f64; 3]>,
    split: &str,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    use diffsoft::mesh::generate::{BoxSpec, CellSplit};
    let origin = origin.unwrap_or([0.0; 3]);
    let split = match split {
        "kuhn" => CellSplit::Kuhn6,
        "five" => CellSplit::Five,
        _ => return Err(errors::value(format!("split '{split}': expected 'kuhn' or 'five'"))),
    };
    if cells.contains(&0) {
        return Err(errors::value(format!(
            "cells {cells:?}: every count must be at least 1"
        )));
    }
    if !size.iter().chain(&origin).all(|x| x.is_finite()) || size.iter().any(|&x| x <= 0.0) {
        return Err(errors::value(format!(
            "size {size:?} must be finite and positive, origin {origin:?} finite"
        )));
    }
    let m = BoxSpec::new(cells, size)
        .origin(origin)
        .split(split)
        .build()
        .map_err(errors::mesh)?;
    let tets = mesh_access::index_array(py, &m.tets)?;
    Ok((arrays::vectors(py, m.vertices)?, tets))
}

#[pymodule]
fn _diffsoft(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // numpy's C API is loaded now, at import: loaded lazily by the first array a call returns,
    // a Ctrl-C pending at that moment made the loader fail, and that failure is a panic.
    m.py().import("numpy")?;
    drop(numpy::PyArray1::<f64>::zeros(m.py(), 0, false));
    fork::init();
    m.add_class::<scene_core::Scene>()?;
    m.add_class::<run::Run>()?;
    m.add_function(wrap_pyfunction!(batch::grad_batch, m)?)?;
    m.add_function(wrap_pyfunction!(batch::simulate_batch, m)?)?;
    m.add_function(wrap_pyfunction!(vjp::vjp_batch, m)?)?;
    m.add_function(wrap_pyfunction!(harness::bounds, m)?)?;
    m.add_function(wrap_pyfunction!(harness::gradcheck, m)?)?;
    m.add_function(wrap_pyfunction!(harness::jacobians, m)?)?;
    m.add_function(wrap_pyfunction!(array_parameters, m)?)?;
    m.add_function(wrap_pyfunction!(scalar_parameters, m)?)?;
    m.add_function(wrap_pyfunction!(scene_data::_scene_from_state, m)?)?;
    m.add_function(wrap_pyfunction!(run::_run_from_state, m)?)?;
    m.add_function(wrap_pyfunction!(run::_trajectory_steps, m)?)?;
    m.add_function(wrap_pyfunction!(mesh_box, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
