//! Failures of the local step and of its linearization.

use crate::kernel::actuator::ActuatorError;
use crate::kernel::ProjectionError;

/// A projection of the local step failed (never a silent NaN).
#[derive(Debug, Clone, thiserror::Error)]
#[non_exhaustive]
pub enum ConstraintError {
    /// A tet's corotated or volume projection failed.
    #[error("tet {tet}: {source}")]
    Projection {
        /// Tet index.
        tet: usize,
        /// Cause.
        source: ProjectionError,
    },
    /// An actuator projection failed.
    #[error("actuator '{group}', tet {tet}: {source}")]
    Actuator {
        /// Group name.
        group: String,
        /// Tet index.
        tet: usize,
        /// Cause.
        source: ActuatorError,
    },
    /// A NaN or infinity appeared (the message names the element).
    #[error("non-finite value: {0}")]
    NonFinite(String),
}

/// The local step has no derivative at this point (the message names the element and why).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct NotDifferentiable(pub String);
