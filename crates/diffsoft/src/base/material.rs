//! A body's elastic material.

use serde::Serialize;

use super::InputError;

/// Elastic material of a body.
///
/// Weights follow the paper's reference implementation (docs/method.md section 2): per tet, a
/// corotated constraint with weight `E/(1+nu) V` and a volume constraint with weight
/// `nu E/(1+nu) V`, both on the deformation gradient. For small strains this is linear
/// elasticity with shear modulus `mu = E/(2(1+nu))` and an extra volumetric stiffness; with
/// `nu = 0` it is exactly linear elasticity with Young's modulus `E` and `lambda = 0`.
///
/// ```
/// use diffsoft::Material;
///
/// let rubber = Material { youngs_modulus: 1e6, poisson_ratio: 0.25 };
/// rubber.validate("rubber")?;
/// assert_eq!(rubber.rotation_stiffness(), 8e5); // E / (1 + nu)
/// assert_eq!(rubber.volume_stiffness(), 2e5); // nu E / (1 + nu)
/// let bad = Material { youngs_modulus: 1e6, poisson_ratio: 0.5 };
/// assert!(bad.validate("bad").is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, schemars::JsonSchema)]
pub struct Material {
    /// Young's modulus (Pa).
    pub youngs_modulus: f64,
    /// Poisson ratio (1), in `[0, 0.5)`.
    pub poisson_ratio: f64,
}

impl Material {
    /// Check the parameters are physically meaningful.
    pub fn validate(&self, body: &str) -> Result<(), InputError> {
        if !(self.youngs_modulus.is_finite() && self.youngs_modulus > 0.0) {
            return Err(InputError::new(format!(
                "body '{body}': Young's modulus must be finite and positive, got {}",
                self.youngs_modulus
            )));
        }
        if !(0.0..0.5).contains(&self.poisson_ratio) {
            return Err(InputError::new(format!(
                "body '{body}': Poisson ratio must be in [0, 0.5), got {}",
                self.poisson_ratio
            )));
        }
        Ok(())
    }

    /// Corotated weight per unit volume, `E / (1 + nu)`.
    pub fn rotation_stiffness(&self) -> f64 {
        self.youngs_modulus / (1.0 + self.poisson_ratio)
    }

    /// Volume weight per unit volume, `nu E / (1 + nu)`.
    pub fn volume_stiffness(&self) -> f64 {
        self.poisson_ratio * self.youngs_modulus / (1.0 + self.poisson_ratio)
    }
}
