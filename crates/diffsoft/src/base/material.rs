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
                super::number(self.youngs_modulus)
            )));
        }
        if !(0.0..0.5).contains(&self.poisson_ratio) {
            return Err(InputError::new(format!(
                "body '{body}': Poisson ratio must be in [0, 0.5), got {}",
                super::number(self.poisson_ratio)
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

    /// The small-strain response of the projective model with these parameters (docs/method.md
    /// Eq. H5): its volume term adds only a third of Lame's `lambda` (`2 mu nu / 3`), so it
    /// responds as `E_eff = E / (1 + 2 nu / 3)`, `nu_eff = nu / (3 + 2 nu)` (never above 0.125);
    /// exactly `(E, nu)` at `nu = 0`.
    ///
    /// ```
    /// use diffsoft::Material;
    ///
    /// let m = Material { youngs_modulus: 1e6, poisson_ratio: 0.3 };
    /// let r = m.projective_response();
    /// assert!((r.youngs_modulus - 1e6 / 1.2).abs() < 1e-6);
    /// assert!((r.poisson_ratio - 0.3 / 3.6).abs() < 1e-15);
    /// ```
    pub fn projective_response(&self) -> Material {
        let nu = self.poisson_ratio;
        Material {
            youngs_modulus: self.youngs_modulus / (1.0 + 2.0 * nu / 3.0),
            poisson_ratio: nu / (3.0 + 2.0 * nu),
        }
    }
}

/// The constitutive model of a body's material (scene key `material.model`; docs/method.md
/// section 2.4).
///
/// * `projective` (the default): the paper's corotated and volume constraints (Eq. 3); its
///   small-strain response is [`Material::projective_response`], not `(E, nu)` unless `nu = 0`.
///   Runs with every solver.
/// * `corotated`: the fixed-corotated energy (Stomakhin et al. 2012, Eq. H1) with the exact Lame
///   parameters of `(E, nu)`.
/// * `neo_hookean`: the stable Neo-Hookean energy (Smith et al. 2018, Eqs. H2-H3), re-parametrised
///   so that its small-strain response is exactly `(E, nu)`; defined for inverted elements.
///
/// The two true models are hyperelastic energies, not projective constraints: they run with
/// Newton's method (`solver: newton`, which `auto` picks for them).
///
/// ```
/// use diffsoft::base::{Choice, MaterialModel};
///
/// assert_eq!(MaterialModel::default(), MaterialModel::Projective);
/// assert_eq!(MaterialModel::from_name("neo_hookean"), Some(MaterialModel::NeoHookean));
/// assert!(MaterialModel::Corotated.is_hyperelastic());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum MaterialModel {
    /// The paper's projective constraints (corotated and volume).
    #[default]
    Projective,
    /// Fixed-corotated hyperelasticity with the exact Lame parameters.
    Corotated,
    /// Stable Neo-Hookean hyperelasticity, exact small-strain moduli.
    NeoHookean,
}

crate::choice!(MaterialModel {
    Projective => "projective",
    Corotated => "corotated",
    NeoHookean => "neo_hookean",
});

impl MaterialModel {
    /// Whether it is a hyperelastic energy (runs with Newton's method only).
    pub fn is_hyperelastic(self) -> bool {
        self != MaterialModel::Projective
    }

    /// The small-strain Young's modulus and Poisson ratio of a body of this model built with
    /// `material`: [`Material::projective_response`] for the projective model, `material` itself
    /// for the two true models (docs/method.md Eq. H5).
    ///
    /// ```
    /// use diffsoft::base::{Material, MaterialModel};
    ///
    /// let m = Material { youngs_modulus: 1e6, poisson_ratio: 0.45 };
    /// assert_eq!(MaterialModel::NeoHookean.small_strain_response(m), m);
    /// assert!(MaterialModel::Projective.small_strain_response(m).youngs_modulus < 0.8 * 1e6);
    /// ```
    pub fn small_strain_response(self, material: Material) -> Material {
        match self {
            MaterialModel::Projective => material.projective_response(),
            MaterialModel::Corotated | MaterialModel::NeoHookean => material,
        }
    }
}
