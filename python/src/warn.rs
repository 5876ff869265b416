//! Python warnings raised at the caller's own line: frames of diffsoft's Python package and of
//! the frameworks it wraps (PyTorch, JAX) are skipped, so a warning of
//! `diffsoft.torch.simulate` or of a `backward()` points at the user's line, and Python's
//! default filter shows it once per call site (the bindings' own messages carry no counts,
//! which would make every call's text new; the library's accuracy notes, `DiffStats::warnings`,
//! do, and show again when their figures change).

use pyo3::prelude::*;

/// Packages whose frames a warning skips (diffsoft's wrappers and the frameworks that call them).
const SKIPPED: [&str; 4] = ["diffsoft", "torch", "jax", "jaxlib"];

/// The directories of the loaded packages of [`SKIPPED`], each ending in a separator.
fn skipped_dirs(py: Python<'_>) -> PyResult<Vec<String>> {
    let modules = py.import("sys")?.getattr("modules")?;
    let mut dirs = Vec::new();
    for name in SKIPPED {
        let Ok(module) = modules.get_item(name) else { continue };
        let Ok(paths) = module.getattr("__path__") else {
            continue;
        };
        for p in paths.try_iter()? {
            let mut dir: String = p?.extract()?;
            dir.push(std::path::MAIN_SEPARATOR);
            dirs.push(dir);
        }
    }
    Ok(dirs)
}

/// The `stacklevel` of `warnings.warn`, called from native code, that names the first frame
/// outside [`SKIPPED`] (1, the innermost Python frame, when every frame is inside them).
fn user_stacklevel(py: Python<'_>) -> PyResult<usize> {
    let dirs = skipped_dirs(py)?;
    // The innermost Python frame: the caller of the native function.
    let mut frame = py.import("sys")?.call_method1("_getframe", (0,))?;
    let mut level = 1;
    loop {
        let file: String = frame.getattr("f_code")?.getattr("co_filename")?.extract()?;
        if !dirs.iter().any(|d| file.starts_with(d.as_str())) {
            return Ok(level);
        }
        let back = frame.getattr("f_back")?;
        if back.is_none() {
            return Ok(1);
        }
        frame = back;
        level += 1;
    }
}

/// A warning category: a class of `diffsoft._errors` (`ConvergenceWarning`), or `UserWarning`
/// should it not import.
pub(crate) fn category<'py>(py: Python<'py>, name: &str) -> Bound<'py, PyAny> {
    py.import("diffsoft._errors")
        .and_then(|m| m.getattr(name))
        .unwrap_or_else(|_| py.get_type::<pyo3::exceptions::PyUserWarning>().into_any())
}

/// Warn with `message` of `category` at the caller's line (see the module docs). A filter
/// that turns the warning into an error makes this an `Err`.
pub(crate) fn at_caller(py: Python<'_>, category: &Bound<'_, PyAny>, message: &str) -> PyResult<()> {
    let level = user_stacklevel(py).unwrap_or(1);
    py.import("warnings")?
        .call_method1("warn", (message, category, level))?;
    Ok(())
}

/// A `UserWarning` at the caller's line.
pub(crate) fn user(py: Python<'_>, message: &str) -> PyResult<()> {
    at_caller(py, py.get_type::<pyo3::exceptions::PyUserWarning>().as_any(), message)
}

/// The `ConvergenceWarning` of a run with steps that stopped at the iteration cap before
/// meeting the solver's tolerance (`Scene.simulate`, the wrappers' forward passes).
pub(crate) fn unconverged(py: Python<'_>) -> PyResult<()> {
    at_caller(
        py,
        &category(py, "ConvergenceWarning"),
        "diffsoft: steps of this simulation stopped at max_iterations before meeting the solver's tolerance (Run.stats['unconverged_steps'] counts them; raise max_iterations or the tolerance with Scene.configure); a gradient through such a run raises ConvergenceError unless allow_unconverged=True",
    )
}

/// The `ConvergenceWarning` of a run with an unconverged step that raised the total energy of
/// a scene without an energy source (`diffsoft::output::solver_energy_gain`): energy the
/// solver made, not the physics. `item` names the run of a batch it came from (the first
/// such run of `simulate_batch`), `None` for `Scene.simulate`.
pub(crate) fn energy_gain(py: Python<'_>, g: &diffsoft::output::EnergyGain, item: Option<usize>) -> PyResult<()> {
    let run = item.map_or(String::new(), |k| format!("run {k} of the batch (values[{k}]): "));
    at_caller(
        py,
        &category(py, "ConvergenceWarning"),
        &format!(
            "diffsoft: {run}step {} stopped at max_iterations and raised the total energy from {:.4e} J to {:.4e} J in a scene with no energy source (no actuators or joint torques): that energy is the solver's, not the physics'; lower dt or raise max_iterations (Scene.configure) until no step gains energy",
            g.step, g.before, g.after
        ),
    )
}

/// The warning of a run whose steps ended with bodies passing through each other
/// (`Scene.simulate`, `simulate_batch`): a `UserWarning`, since more iterations do not mend it.
/// No count in the text, as for the other warnings: Python's filter shows it once per call site.
pub(crate) fn interpenetration(py: Python<'_>) -> PyResult<()> {
    user(
        py,
        "diffsoft: steps of this simulation ended with bodies passing through each other (contacts the run missed; Run.stats['summary']['steps_with_pair_crossings'] counts them, each step's 'pair_crossings' its crossing surface edges): lower the time step or the speed, or raise contact_rounds; a gradient through such a run raises SimulationError",
    )
}

/// The warning of a run that folded a body through itself (`Scene.simulate`,
/// `simulate_batch`; `diffsoft::output::folded`: a tenth of the tets inverted at the end of
/// some step): a `UserWarning`, since more iterations do not mend it. `soft` names the bodies
/// noted as too soft to carry their own weight ([`soft_bodies`]), the usual culprits; the step
/// log counts inverted tets per model, not per body.
pub(crate) fn inversion(py: Python<'_>, soft: &[String]) -> PyResult<()> {
    let culprits = match soft {
        [] => String::new(),
        names => format!(
            " ({} too soft to carry {} own weight: Scene.notes)",
            names
                .iter()
                .map(|n| format!("body '{n}'"))
                .collect::<Vec<_>>()
                .join(", "),
            if names.len() == 1 { "its" } else { "their" }
        ),
    };
    user(
        py,
        &format!("diffsoft: steps of this simulation ended with a tenth or more of the tets inverted, a body folded through itself{culprits} (Run.stats['summary']['steps_with_inverted_tets'] counts the steps with any, each step's 'inverted_tets' its inverted tets): its material is too soft for its load or the time step too long, and its contacts cannot keep it apart from other bodies"),
    )
}

/// The names of the bodies of `model` too soft to carry their own weight
/// (`diffsoft::output::BodyLog::weight_note`), for [`inversion`].
pub(crate) fn soft_bodies(model: &diffsoft::Model) -> Vec<String> {
    model
        .bodies()
        .iter()
        .filter(|b| diffsoft::output::BodyLog::weight_note(model, b).is_some())
        .map(|b| b.name.clone())
        .collect()
}
