//! Errors of the forward simulation.

use crate::base::InputError;
use crate::kernel::actuator::ActuatorError;
use crate::kernel::ProjectionError;

/// Errors of the solver: bad input, a time step the certification rejects, divergence.
#[derive(Debug, Clone, thiserror::Error)]
#[non_exhaustive]
pub enum SolverError {
    /// Physically meaningless or inconsistent input.
    #[error("invalid input: {0}")]
    Input(InputError),
    /// The chosen iteration diverges at this time step (certified check).
    #[error("time step rejected by certification: {0}")]
    Uncertified(String),
    /// The eigenvalue computation behind certification failed.
    #[error("certification failed: {0}")]
    Certification(String),
    /// The sparse factorization failed.
    #[error("factorization failed: {0}")]
    Factorization(String),
    /// A constraint projection failed.
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
    /// A NaN or infinity appeared.
    #[error("non-finite value: {0}")]
    NonFinite(String),
    /// The simulation or an iteration diverged.
    #[error("diverged: {0}")]
    Diverged(String),
    /// The caller cancelled the run ([`crate::base::cancel`]); nothing it returns is complete.
    #[error("interrupted")]
    Interrupted,
}

impl From<crate::constraint::ConstraintError> for SolverError {
    fn from(e: crate::constraint::ConstraintError) -> Self {
        use crate::constraint::ConstraintError as C;
        match e {
            C::Projection { tet, source } => SolverError::Projection { tet, source },
            C::Actuator { group, tet, source } => SolverError::Actuator { group, tet, source },
            C::NonFinite(m) => SolverError::NonFinite(m),
        }
    }
}

impl SolverError {
    /// An input error with this message.
    pub(crate) fn input(message: impl Into<String>) -> Self {
        Self::Input(InputError::new(message))
    }
}

/// Not `#[from]`: the message already holds the input error's text, and a `source()` would make
/// error chains (`{:#}`) print it twice.
impl From<InputError> for SolverError {
    fn from(e: InputError) -> Self {
        Self::Input(e)
    }
}
