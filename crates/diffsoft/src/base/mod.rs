//! The bottom layer: plain data and the input-validation error that every other module builds
//! on. Nothing here imports the rest of the crate.
//!
//! * [`InputError`]: what every `validate()` and builder returns for physically meaningless or
//!   inconsistent input; the errors of higher layers wrap it (`#[from]`).
//! * [`Material`]: a body's elastic material and its constraint weights (docs/method.md
//!   section 2).
//! * [`Body`]: where one body lives in the assembled system.
//! * [`Schedule`]: a piecewise-linear time series (activations, torques).
//! * [`Choice`]: settings chosen from a fixed list of names, one spelling each.
//! * [`cancel`]: cooperative cancellation of long calls (a token polled before every step).
//! * [`unit_vector`]: directions from input (axes, normals, fibres) normalised without overflow.
//! * [`tasks`]: independent tasks on all cores, each single-threaded (the batches).
//! * `input_file`: input text files read one way (devices refused, a byte-order mark dropped).
//! * [`memory`]: sizes from files and flags checked against overflow and the machine's memory
//!   before anything is allocated for them.

mod body;
pub mod cancel;
mod choice;
mod error;
pub mod input_file;
mod material;
pub mod memory;
mod schedule;
pub mod tasks;
mod vector;

pub use body::Body;
pub use choice::Choice;
pub(crate) use error::check_name;
pub use error::number;
pub use error::InputError;
pub use material::{Material, MaterialModel};
pub use schedule::Schedule;
pub use vector::unit_vector;
