//! The rules both Newton solvers share (docs/method.md section 6.5): the forcing term of the
//! inexact direction solve (Eq. S5), its absolute floor, and the line search's acceptance test
//! with its round-off allowances. [`super::newton`] applies them to the free vertices,
//! [`super::newton_skeletal`] to the reduced unknowns of a skeleton.

/// Armijo's sufficient-decrease constant.
const ARMIJO: f64 = 1e-4;
/// Step halvings of the line search before it gives up (then one projective-dynamics
/// iteration).
pub(super) const MAX_HALVINGS: usize = 30;
/// Largest forcing term of the direction solve (Eq. S5).
const FORCING_MAX: f64 = 0.1;
/// The direction solve also stops once the preconditioned residual is this fraction of the
/// convergence tolerance (the rest of the correction is below what the step resolves).
pub(super) const ABSOLUTE_FRACTION: f64 = 1e-2;
/// Relative round-off allowance on `E` in the line search: near the minimum, energy differences
/// fall below the precision of `E`'s sum and a Newton step that changes `E` by less than this is
/// accepted.
const ENERGY_ROUNDOFF: f64 = 1e-13;
/// Near the minimum, where the first-order decrease `-grad E . d` of a full Newton step is below
/// this fraction of `|E|`, the energy cannot rank the step against the iterate (its sum's
/// round-off is larger than the decrease): a full step that does not raise `E` by more than
/// this fraction is taken. Backtracking there would shorten correct steps at random and stop
/// the iteration short of the minimum by round-off-driven amounts (a loss that is noisy at
/// `1e-11` instead of `1e-14`).
const UNRESOLVED: f64 = 1e-10;

/// The forcing term `eta = min(FORCING_MAX, sqrt(z0 / z_first))` of the direction solve, with
/// `z0` the preconditioned gradient's size now and `z_first` at the step's first iteration
/// (`FORCING_MAX` before there is one).
pub(super) fn forcing(z0: f64, z_first: f64) -> f64 {
    if z_first > 0.0 {
        FORCING_MAX.min((z0 / z_first).sqrt())
    } else {
        FORCING_MAX
    }
}

/// Whether the line search takes the step of length `alpha` along a descent direction with
/// slope `gd = grad E . d < 0`, from energy `e` to `et`: Armijo's test with the round-off
/// allowance, or, for a full step where the energy cannot rank it, no rise beyond the
/// unresolved fraction.
pub(super) fn accepts(alpha: f64, gd: f64, e: f64, et: f64) -> bool {
    let unresolved = alpha == 1.0 && -gd <= UNRESOLVED * e.abs() && et <= e + UNRESOLVED * e.abs();
    unresolved || et <= e + ARMIJO * alpha * gd + ENERGY_ROUNDOFF * e.abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn armijo_and_round_off() {
        // A clear decrease passes, a rise fails.
        assert!(accepts(1.0, -1.0, 10.0, 9.0));
        assert!(!accepts(0.5, -1.0, 10.0, 10.5));
        // Near the minimum a full step that the energy cannot rank is taken, a halved one not.
        let e = 1.0;
        assert!(accepts(1.0, -1e-12, e, e + 1e-11));
        assert!(!accepts(0.5, -1e-12, e, e + 1e-11));
        // The forcing term: capped, then the square root of the relative gradient size.
        assert_eq!(forcing(1.0, 0.0), FORCING_MAX);
        assert_eq!(forcing(1.0, 1.0), FORCING_MAX);
        assert!((forcing(1e-4, 1.0) - 1e-2).abs() < 1e-15);
    }
}
