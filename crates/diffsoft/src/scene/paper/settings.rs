//! The scalar keys of a paper scene that take a checked value: the solver's `"Simulation HZ"`,
//! `"Max Iteration"` and `"Damping coefficient"` (and its stopping rule), and a body's
//! `"Scale"` and `"Mass"`. Each check is a plain function of the value (its message names the
//! key); the readers apply the reference's default where the key is absent.

use serde_json::Value;

use super::context::Ctx;
use crate::base::number;
use crate::scene::SceneError;
use crate::solver::Settings;

/// The largest "Max Iteration" a paper scene may give (local-global iterations per step).
pub(super) const MAX_ITERATION_CAP: f64 = 1e9;

/// Where the solver keys live, as the messages name it.
const PARAMETERS: &str = "Parameters[0]";

/// `"Simulation HZ"` of `params` (default 200): positive and finite.
pub(super) fn simulation_hz(cx: &Ctx<'_>, params: &Value) -> Result<f64, SceneError> {
    let hz = cx.number(params, "Simulation HZ", 200.0, PARAMETERS)?;
    check_hz(hz).map_err(|m| cx.invalid(m))
}

/// `"Scale"` of the mesh or cloth `obj` at `w` (`default` where absent): positive and finite.
pub(super) fn scale(cx: &Ctx<'_>, obj: &Value, default: f64, w: &str) -> Result<f64, SceneError> {
    let scale = cx.number(obj, "Scale", default, w)?;
    check_scale(w, scale).map_err(|m| cx.invalid(m))
}

/// `"Mass"` of the mesh `obj` at `w`, its total mass in kg (default 10): positive and finite.
pub(super) fn total_mass(cx: &Ctx<'_>, obj: &Value, w: &str) -> Result<f64, SceneError> {
    let total = cx.number(obj, "Mass", 10.0, w)?;
    check_mass(w, total).map_err(|m| cx.invalid(m))
}

/// The solver's settings for a model of `n` vertices and length scale `length_scale` at `hz`
/// steps a second: `"Max Iteration"` (default 30), `"Damping coefficient"` (default 0.9999) and
/// the reference's stopping rule as a relative RMS tolerance ([`tolerance`]); a note says which.
pub(super) fn solver(
    cx: &mut Ctx<'_>,
    params: &Value,
    hz: f64,
    n: usize,
    length_scale: f64,
) -> Result<Settings, SceneError> {
    let tolerance = tolerance(n, length_scale);
    let max_iterations = cx.number(params, "Max Iteration", 30.0, PARAMETERS)?;
    let max_iterations = check_max_iteration(max_iterations).map_err(|m| cx.invalid(m))?;
    let damping = cx.number(params, "Damping coefficient", 0.9999, PARAMETERS)?;
    let damping = check_damping(damping).map_err(|m| cx.invalid(m))?;
    let settings = Settings {
        dt: 1.0 / hz,
        max_iterations,
        damping,
        tolerance,
        ..Settings::default()
    };
    cx.notes.push(format!(
        "stopping rule of the reference (|dq|_2 / 3N < 5e-7) as relative RMS tolerance {tolerance:.3e}; damping {}; at most {} iterations",
        settings.damping, settings.max_iterations
    ));
    Ok(settings)
}

/// The reference's stopping rule `|dq|_2 / (3N) < 5e-7` as this solver's relative RMS change
/// `|dq|_2 / sqrt(N) / L`, for `n` vertices and length scale `length_scale` (`L`).
pub(super) fn tolerance(n: usize, length_scale: f64) -> f64 {
    let n = n as f64;
    5e-7 * 3.0 * n / n.sqrt() / length_scale
}

/// `"Simulation HZ"`: positive and finite.
fn check_hz(hz: f64) -> Result<f64, String> {
    if hz.is_finite() && hz > 0.0 {
        Ok(hz)
    } else {
        Err(format!("\"Simulation HZ\" must be positive, got {}", number(hz)))
    }
}

/// `"Scale"` at `w`: positive and finite.
fn check_scale(w: &str, scale: f64) -> Result<f64, String> {
    if scale.is_finite() && scale > 0.0 {
        Ok(scale)
    } else {
        Err(format!("{w}: \"Scale\" must be positive, got {}", number(scale)))
    }
}

/// `"Mass"` at `w`: positive and finite.
fn check_mass(w: &str, total: f64) -> Result<f64, String> {
    if total.is_finite() && total > 0.0 {
        Ok(total)
    } else {
        Err(format!(
            "{w}: \"Mass\" (the body's total mass, kg) must be finite and positive, got {}",
            number(total)
        ))
    }
}

/// `"Max Iteration"`: a whole number from 1 to [`MAX_ITERATION_CAP`].
fn check_max_iteration(max_iterations: f64) -> Result<usize, String> {
    if max_iterations.fract() == 0.0 && (1.0..=MAX_ITERATION_CAP).contains(&max_iterations) {
        Ok(max_iterations as usize)
    } else {
        Err(format!(
            "{PARAMETERS}: \"Max Iteration\" must be a whole number from 1 to {MAX_ITERATION_CAP:e}, got {}",
            number(max_iterations)
        ))
    }
}

/// `"Damping coefficient"`, the velocity kept per step: in (0, 1].
fn check_damping(damping: f64) -> Result<f64, String> {
    if damping > 0.0 && damping <= 1.0 {
        Ok(damping)
    } else {
        Err(format!(
            "{PARAMETERS}: \"Damping coefficient\" (velocity kept per step) must be in (0, 1], got {}",
            number(damping)
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn max_iteration_is_a_whole_number_from_1_to_the_cap() {
        assert_eq!(check_max_iteration(1.0), Ok(1));
        assert_eq!(check_max_iteration(30.0), Ok(30));
        assert_eq!(check_max_iteration(MAX_ITERATION_CAP), Ok(1_000_000_000));
        for bad in [0.0, -3.0, 2.5, MAX_ITERATION_CAP + 1.0, f64::INFINITY, f64::NAN] {
            let e = check_max_iteration(bad).unwrap_err();
            assert!(
                e.starts_with("Parameters[0]: \"Max Iteration\" must be a whole number from 1 to 1e9, got "),
                "{e}"
            );
        }
        assert!(check_max_iteration(2.5).unwrap_err().ends_with("got 2.5"));
    }

    #[test]
    fn damping_is_in_the_half_open_unit_interval() {
        assert_eq!(check_damping(1.0), Ok(1.0));
        assert_eq!(check_damping(0.9999), Ok(0.9999));
        for bad in [0.0, -0.5, 1.5, f64::NAN] {
            let e = check_damping(bad).unwrap_err();
            assert!(
                e.contains("\"Damping coefficient\" (velocity kept per step) must be in (0, 1]"),
                "{e}"
            );
        }
        assert!(check_damping(0.0).unwrap_err().ends_with("got 0"));
    }

    #[test]
    fn mass_scale_and_rate_are_finite_and_positive() {
        assert_eq!(check_mass("Meshes[0]", 10.0), Ok(10.0));
        assert_eq!(
            check_mass("Meshes[1]", -1.0).unwrap_err(),
            "Meshes[1]: \"Mass\" (the body's total mass, kg) must be finite and positive, got -1"
        );
        assert!(check_mass("Meshes[0]", 0.0).is_err() && check_mass("Meshes[0]", f64::INFINITY).is_err());
        assert_eq!(check_scale("Clothes[0]", 0.05), Ok(0.05));
        assert_eq!(
            check_scale("Clothes[0]", 0.0).unwrap_err(),
            "Clothes[0]: \"Scale\" must be positive, got 0"
        );
        assert_eq!(check_hz(200.0), Ok(200.0));
        assert_eq!(
            check_hz(-1.0).unwrap_err(),
            "\"Simulation HZ\" must be positive, got -1"
        );
    }

    #[test]
    fn the_reference_stopping_rule_scales_with_the_vertex_count_and_length() {
        // |dq|_2 / 3N < 5e-7  <=>  |dq|_2 / sqrt(N) / L < 5e-7 * 3 sqrt(N) / L.
        assert!((tolerance(100, 1.0) - 1.5e-5).abs() < 1e-18);
        assert!((tolerance(100, 2.0) - 7.5e-6).abs() < 1e-18);
    }
}
