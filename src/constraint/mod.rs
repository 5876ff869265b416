//! Transitional paths of the math kernels (now in [`crate::kernel`]).

#[doc(hidden)]
pub use crate::kernel::{actuator, svd, volume, ProjectionError};
