//! Where one body lives in the assembled system.

use std::ops::Range;

use serde::Serialize;

use super::{Material, MaterialModel};

/// One soft body of an assembled model: its name, its ranges in the global vertex and tet
/// numbering, and its material and mass.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct Body {
    /// Name.
    pub name: String,
    /// Its vertices in the global numbering.
    pub vertices: Range<usize>,
    /// Its tets in the global numbering.
    pub tets: Range<usize>,
    /// Material parameters.
    pub material: Material,
    /// The constitutive model they are used in.
    pub model: MaterialModel,
    /// Total mass (kg).
    pub mass: f64,
    /// Density (kg/m^3; for a total-mass body, mass / volume).
    pub density: f64,
    /// Whether gravity acts on it.
    pub gravity: bool,
    /// Whether its volume constraint is on.
    pub volume_constraint: bool,
}
