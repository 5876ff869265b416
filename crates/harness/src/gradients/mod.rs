//! Gradient checks of whole simulations (`diffsoft gradcheck`, `reports/gradients.json`),
//! following docs/method.md section 7: for each scene and parameter group, the analytic derivative
//! (reverse mode, [`diffsoft::diff`]) against central differences over a sweep of relative steps
//! (the V-curve, its minimum, the truncation slope and a Richardson estimate); random directions
//! `u` for large parameter vectors (comparing `g . u` with the difference quotient along `u`,
//! as PyTorch's fast gradcheck and JAX's `check_grads` do); and a dual-number check of the local
//! step's linearization on the states of a step. Pass/fail under `|a - n| <= atol + rtol |n|`
//! with `n` the central difference at the best step or, where it is closer, the Richardson
//! extrapolation of two neighbouring steps at or above it; the worst entry is named with both
//! values.

mod check;
mod cost;
mod memory;
mod report;
mod sysid;

pub use check::*;
pub use cost::*;
pub use memory::*;
pub use report::*;
pub use sysid::*;

/// Schema of `gradients.json`.
pub const GRADIENTS_SCHEMA: &str = "diffsoft.gradients/1";
/// Schema of `diffsoft gradcheck --json`.
pub const GRADCHECK_SCHEMA: &str = "diffsoft.gradcheck/1";

/// The store budget of the memory study's second unrolled run (bytes).
pub const STORE_BUDGET: usize = 64_000_000;

/// Relative tolerance of the checks.
pub const RTOL: f64 = 1e-6;
/// Absolute tolerance of the checks.
pub const ATOL: f64 = 1e-12;
