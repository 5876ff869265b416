//! The Newton direction by preconditioned conjugate gradients (docs/method.md Eq. S5), once
//! for every coordinate system Newton's method runs in: free vertices ([`super::newton`]) and
//! free vertices with joint increments ([`super::newton_skeletal`]). A method supplies its
//! vectors ([`CgVector`]) and its Hessian, preconditioner and residual measure
//! ([`NewtonOperator`]); the iteration, the inexact-Newton stopping rule and the handling of
//! non-positive curvature are here.

use nalgebra::Vector3;

use super::newton_rules::forcing;
use crate::solver::SolverError;

/// A vector of a Newton system's unknowns.
pub(crate) trait CgVector {
    /// `<self, o>`.
    fn dot(&self, o: &Self) -> f64;
    /// `self = 0`.
    fn set_zero(&mut self);
    /// `self = o`.
    fn copy_from(&mut self, o: &Self);
    /// `self += a o`.
    fn axpy(&mut self, a: f64, o: &Self);
    /// `self = z + beta self` (the search direction's update).
    fn xpby(&mut self, z: &Self, beta: f64);
}

impl CgVector for Vec<Vector3<f64>> {
    fn dot(&self, o: &Self) -> f64 {
        self.iter().zip(o).map(|(x, y)| x.dot(y)).sum()
    }

    fn set_zero(&mut self) {
        self.iter_mut().for_each(|d| *d = Vector3::zeros());
    }

    fn copy_from(&mut self, o: &Self) {
        self.copy_from_slice(o);
    }

    fn axpy(&mut self, a: f64, o: &Self) {
        for (x, y) in self.iter_mut().zip(o) {
            *x += y * a;
        }
    }

    fn xpby(&mut self, z: &Self, beta: f64) {
        for (p, z) in self.iter_mut().zip(z) {
            *p = z + *p * beta;
        }
    }
}

/// The Hessian, the preconditioner and the residual measure of one Newton system.
pub(crate) trait NewtonOperator {
    /// The unknowns.
    type V: CgVector;

    /// `z = P^-1 r`.
    fn precondition(&mut self, r: &Self::V, z: &mut Self::V) -> Result<(), SolverError>;

    /// The size of a preconditioned residual `z` (RMS in position space), which the stopping
    /// rule compares.
    fn measure(&mut self, z: &Self::V) -> f64;

    /// `hp = H p`; `false` where the Hessian is not defined (a projection that is not
    /// differentiable there).
    fn apply(&mut self, p: &Self::V, hp: &mut Self::V) -> bool;
}

/// Conjugate gradients' vectors: the direction, the residual, the preconditioned residual,
/// the search direction and its Hessian product.
#[derive(Debug, Clone)]
pub(crate) struct CgWork<V> {
    /// The Newton direction being built.
    pub dir: V,
    /// The residual `-grad E - H dir` (set to `-grad E` by the caller before a solve).
    pub r: V,
    /// `P^-1 r`.
    pub z: V,
    /// The search direction.
    pub p: V,
    /// `H p`.
    pub hp: V,
}

impl<V: Clone> CgWork<V> {
    /// Every vector a copy of `zero`.
    pub(crate) fn new(zero: V) -> Self {
        Self {
            dir: zero.clone(),
            r: zero.clone(),
            z: zero.clone(),
            p: zero.clone(),
            hp: zero,
        }
    }
}

/// What one direction solve did.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Direction {
    /// Conjugate-gradient iterations.
    pub iterations: usize,
    /// Whether the stopping rule was met before the cap.
    pub met: bool,
    /// The size of `P^-1 grad E` ([`NewtonOperator::measure`]): the length of the
    /// projective-dynamics step from this iterate.
    pub z0: f64,
    /// The Hessian showed non-positive curvature along a search direction (the unprojected
    /// Hessian is indefinite there).
    pub indefinite: bool,
}

impl Direction {
    /// No direction was computed: the Hessian could not be formed (try the projected one).
    pub(crate) fn undefined() -> Self {
        Self {
            iterations: 0,
            met: false,
            z0: f64::NAN,
            indefinite: true,
        }
    }
}

/// `H d = -grad E` by conjugate gradients preconditioned with `P` from `d = 0` (`w.r` holds
/// `-grad E` on entry, the direction ends in `w.dir`): stop when the preconditioned residual's
/// size is below `max(eta |P^-1 grad E|, floor)`, with the forcing term `eta` of [`forcing`]
/// (`z_first`: that size at the step's first iterate, `NaN` there). On non-positive curvature
/// keep what was found (the preconditioned gradient step if nothing was) and report it.
pub(crate) fn direction<O: NewtonOperator>(
    op: &mut O,
    w: &mut CgWork<O::V>,
    z_first: f64,
    floor: f64,
    max_iterations: usize,
) -> Result<Direction, SolverError> {
    w.dir.set_zero();
    op.precondition(&w.r, &mut w.z)?;
    let z0 = op.measure(&w.z);
    let eta = forcing(z0, z_first);
    let stop = (eta * z0).max(floor);
    if z0 <= floor {
        // Already within the floor: the preconditioned gradient step is the direction.
        w.dir.copy_from(&w.z);
        return Ok(Direction {
            iterations: 0,
            met: true,
            z0,
            indefinite: false,
        });
    }
    w.p.copy_from(&w.z);
    let mut rz = w.r.dot(&w.z);
    for it in 1..=max_iterations {
        let ok = op.apply(&w.p, &mut w.hp);
        let php = w.p.dot(&w.hp);
        if !ok || php.is_nan() || php <= 0.0 {
            // Only the unprojected Hessian can get here (the projected one is positive
            // definite up to round-off): keep what was found, or the projective-dynamics
            // step if nothing was, and tell the caller.
            if it == 1 {
                w.dir.copy_from(&w.z);
            }
            return Ok(Direction {
                iterations: it,
                met: false,
                z0,
                indefinite: true,
            });
        }
        let alpha = rz / php;
        w.dir.axpy(alpha, &w.p);
        w.r.axpy(-alpha, &w.hp);
        op.precondition(&w.r, &mut w.z)?;
        if op.measure(&w.z) <= stop {
            return Ok(Direction {
                iterations: it,
                met: true,
                z0,
                indefinite: false,
            });
        }
        let rz_new = w.r.dot(&w.z);
        let beta = rz_new / rz;
        rz = rz_new;
        w.p.xpby(&w.z, beta);
    }
    Ok(Direction {
        iterations: max_iterations,
        met: false,
        z0,
        indefinite: false,
    })
}
