//! Command-line numbers checked as they are parsed: a flag whose value cannot mean anything
//! (a NaN, an infinite or negative time step, zero steps) is refused by clap, naming the flag
//! and the value, before any work starts, with exit status 1 as other bad input (`main`).

/// A finite number greater than zero (`value_parser = positive`): time steps, densities,
/// stiffnesses, sizes, tolerances that must stop somewhere.
pub(crate) fn positive(text: &str) -> Result<f64, String> {
    match finite(text) {
        Some(v) if v > 0.0 => Ok(v),
        _ => Err(format!("must be finite and positive, got {text}")),
    }
}

/// A finite number at least zero (`value_parser = non_negative`): tolerances where 0 means
/// "run the cap", quality thresholds, jitter, budgets.
pub(crate) fn non_negative(text: &str) -> Result<f64, String> {
    match finite(text) {
        Some(v) if v >= 0.0 => Ok(v),
        _ => Err(format!("must be finite and at least 0, got {text}")),
    }
}

/// A finite number, or `None`.
fn finite(text: &str) -> Option<f64> {
    text.trim().parse::<f64>().ok().filter(|v| v.is_finite())
}

/// A count of at least one (`value_parser = at_least_one`): steps to take.
pub(crate) fn at_least_one(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!("must be a whole number of at least 1, got {text}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meaningless_numbers_are_refused_with_the_value() {
        assert_eq!(positive("1e-3"), Ok(1e-3));
        for bad in ["nan", "NaN", "inf", "-inf", "0", "-5", "x"] {
            let e = positive(bad).unwrap_err();
            assert!(e.contains(bad), "{e}");
        }
        assert_eq!(non_negative("0"), Ok(0.0));
        assert!(non_negative("-1e-9").is_err() && non_negative("nan").is_err());
        assert_eq!(at_least_one("3"), Ok(3));
        assert!(at_least_one("0").is_err() && at_least_one("-1").is_err());
    }
}
