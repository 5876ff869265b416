//! The native module of the `diffsoft` Python package (`diffsoft._diffsoft`): bindings of the
//! library's curated API. The Python layer (`python/diffsoft/`) adds the PyTorch and JAX
//! wrappers and the type stubs.

mod arrays;
mod batch;
mod errors;
mod harness;
mod interrupt;
mod params;
mod run;
mod scene;
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

#[pymodule]
fn _diffsoft(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // numpy's C API is loaded now, at import: loaded lazily by the first array a call returns,
    // a Ctrl-C pending at that moment made the loader fail, and that failure is a panic.
    m.py().import("numpy")?;
    drop(numpy::PyArray1::<f64>::zeros(m.py(), 0, false));
    m.add_class::<scene::Scene>()?;
    m.add_class::<run::Run>()?;
    m.add_function(wrap_pyfunction!(batch::grad_batch, m)?)?;
    m.add_function(wrap_pyfunction!(batch::simulate_batch, m)?)?;
    m.add_function(wrap_pyfunction!(vjp::vjp_batch, m)?)?;
    m.add_function(wrap_pyfunction!(harness::bounds, m)?)?;
    m.add_function(wrap_pyfunction!(harness::gradcheck, m)?)?;
    m.add_function(wrap_pyfunction!(harness::jacobians, m)?)?;
    m.add_function(wrap_pyfunction!(array_parameters, m)?)?;
    m.add_function(wrap_pyfunction!(scalar_parameters, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
