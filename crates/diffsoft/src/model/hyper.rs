//! The tets of bodies whose material is a hyperelastic energy (`corotated`, `neo_hookean`;
//! docs/method.md section 2.4): their energy and Lame parameters, and the weight each adds to
//! the constant matrix `L` as the preconditioner of Newton's method.

use crate::base::{Material, MaterialModel};
use crate::kernel::hyperelastic::{Energy, Lame};

/// The hyperelastic tets of a model (global tet numbering), in model order.
#[derive(Debug, Clone, PartialEq)]
pub struct HyperTets {
    /// Global index of each hyperelastic tet.
    pub tets: Vec<usize>,
    /// Its energy.
    pub energy: Vec<Energy>,
    /// Its Lame parameters (Pa).
    pub lame: Vec<Lame>,
    /// The weight `c_t = (2 mu + 3 lambda / 2) V` of its isotropic term `c_t A^T A` in `L`
    /// (Eq. 22). It cancels from the energy's gradient and Hessian (Eq. H6), so it is not a
    /// parameter; it makes `M/h^2 + L` the preconditioner of Newton's conjugate gradients, and
    /// the fixed point `x <- x - A^-1 grad E` of the skeleton's implicit adjoint contractive at
    /// small strain: the element Hessian's eigenvalues (`2 mu` in shear, `2 mu + 3 lambda` in
    /// dilation) lie within `(0, 2 c / V)`, and this `c` balances the two ends.
    pub weight: Vec<f64>,
}

/// The weight of a tet of volume `volume` in `L` (see [`HyperTets::weight`]).
pub(crate) fn weight(lame: Lame, volume: f64) -> f64 {
    (2.0 * lame.mu + 1.5 * lame.lambda) * volume
}

impl HyperTets {
    /// The energy of a model (`None` for the projective model).
    pub fn energy_of(model: MaterialModel) -> Option<Energy> {
        match model {
            MaterialModel::Projective => None,
            MaterialModel::Corotated => Some(Energy::FixedCorotated),
            MaterialModel::NeoHookean => Some(Energy::StableNeoHookean),
        }
    }

    /// Add tet `t` of volume `volume` with `material` under energy `energy`.
    pub(crate) fn push(&mut self, t: usize, energy: Energy, material: Material, volume: f64) {
        let lame = Lame::from_young(material.youngs_modulus, material.poisson_ratio);
        self.tets.push(t);
        self.energy.push(energy);
        self.lame.push(lame);
        self.weight.push(weight(lame, volume));
    }

    /// Position of global tet `t` among the hyperelastic tets.
    pub fn position(&self, t: usize) -> Option<usize> {
        self.tets.binary_search(&t).ok()
    }

    /// Number of hyperelastic tets.
    pub fn len(&self) -> usize {
        self.tets.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.tets.is_empty()
    }
}
