//! Coulomb friction: a capstan, a cloth strip over a fixed cylinder that sticks below the
//! Euler-Eytelwein ratio `T2 / T1 = e^(mu theta)` and slides above it.
//!
//! Reported as not run: the scene (a strip wrapped half-way round a cylinder obstacle, loaded at
//! both ends by attached masses, run to rest) is not built yet; see [`NOT_BUILT`].

use super::case::{Case, Spec};

/// Why the capstan cases are reported as not run.
pub const NOT_BUILT: &str = "the capstan scene is not built yet: it needs cloth loaded by end masses over a     cylinder obstacle run to rest for each tension ratio; the engine's Coulomb friction is checked today     against implicit Euler's stopping distance of a sliding box (reports/physics.json)";

/// The capstan cases: the strip sticks at `T2 / T1 = 0.9 e^(mu pi)` and slides at
/// `1.1 e^(mu pi)` (`mu = 0.3`, half a turn).
pub fn cases(_fast: bool) -> Vec<Case> {
    [("sticks", 0.9), ("slides", 1.1)]
        .into_iter()
        .map(|(variant, ratio)| {
            let mut spec = Spec::new("capstan", variant, "cloth", "E, nu");
            spec.setup = format!(
                "cloth strip over a fixed cylinder (half a turn, mu = 0.3), end loads with T2 / T1 = {ratio} e^(mu pi)"
            );
            spec.quantity = "slip of the strip after it comes to rest (m)".into();
            spec.formula = format!(
                "{variant} when T2 / T1 {} e^(mu theta)",
                if ratio < 1.0 { "<" } else { ">" }
            );
            spec.source = "Euler 1762, Eytelwein 1808: the capstan equation".into();
            spec.tolerance = 0.0;
            spec.tolerance_basis = "a stick/slip verdict".into();
            spec.not_run(NOT_BUILT)
        })
        .collect()
}
