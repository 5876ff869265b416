//! The time integrator's explicit phases around the local-global iterations (docs/method.md
//! section 2 and Eqs. T1-T3): the inertial target `s` (Eq. 2; BDF2: Eq. T1), the weight
//! `1/h_e^2` of the inertia term `M/h_e^2` in the step's objective and matrix (Eq. 5; BDF2 has
//! `h_e = 2h/3`, Eq. T2), and the velocity update (Eq. 4; BDF2: Eq. T3), with the adjoints of
//! each for the backward pass. The time step lives here and in [`Settings`](super::Settings)
//! only.
//!
//! Both schemes have one form, with coefficients `(a0, a1)` on the two latest states and an
//! effective step `h_e`:
//!
//! * `s = a0 q_n + a1 q_{n-1} + h_e (a0 v_n + a1 v_{n-1}) + h_e^2 a_ext`,
//! * `v_{n+1} = damping (q_{n+1} - a0 q_n - a1 q_{n-1}) / h_e`,
//!
//! implicit Euler `(1, 0, h)`, BDF2 `(4/3, -1/3, 2h/3)`. A step of either minimises
//! `|q - s|_M^2 / (2 h_e^2) + E(q)`, so projective dynamics keeps its constant matrix
//! `M/h_e^2 + L`; BDF2's first step (no earlier state) is implicit Euler.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::model::Model;

/// The time integrator (scene key `solver.integrator`, CLI `--integrator`).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default, Serialize, Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum Integrator {
    /// Implicit (backward) Euler: first order, damps numerically (docs/method.md Eqs. 2-5).
    #[default]
    ImplicitEuler,
    /// The two-step backward differentiation formula: second order, the same constant matrix
    /// with `h_e = 2h/3` (Eqs. T1-T3); its first step is implicit Euler.
    Bdf2,
}

/// One step's scheme: implicit Euler, or BDF2 once an earlier state exists.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Scheme {
    h: f64,
    damping: f64,
    /// Weight of the latest state `(q_n, v_n)`.
    a0: f64,
    /// Weight of the state before it `(q_{n-1}, v_{n-1})`.
    a1: f64,
    /// The effective step `h_e` of the inertia term.
    h_e: f64,
}

/// A state before the step's start: `(q_{n-1}, v_{n-1})`.
pub(crate) type Previous<'a> = Option<(&'a [Vector3<f64>], &'a [Vector3<f64>])>;

impl Scheme {
    /// Implicit Euler with step `h` and damping factor per step.
    pub(crate) fn implicit_euler(h: f64, damping: f64) -> Self {
        Self {
            h,
            damping,
            a0: 1.0,
            a1: 0.0,
            h_e: h,
        }
    }

    /// BDF2 with step `h` (Eqs. T1-T3).
    pub(crate) fn bdf2(h: f64, damping: f64) -> Self {
        Self {
            h,
            damping,
            a0: 4.0 / 3.0,
            a1: -1.0 / 3.0,
            h_e: 2.0 * h / 3.0,
        }
    }

    /// The scheme of a step of `integrator`: BDF2 needs the state before the step's start
    /// (`has_previous`), otherwise implicit Euler.
    pub(crate) fn for_step(integrator: Integrator, h: f64, damping: f64, has_previous: bool) -> Self {
        match integrator {
            Integrator::Bdf2 if has_previous => Self::bdf2(h, damping),
            _ => Self::implicit_euler(h, damping),
        }
    }

    /// Whether the step reads the state before its start.
    pub(crate) fn two_step(&self) -> bool {
        self.a1 != 0.0
    }

    /// The time step.
    pub(crate) fn h(&self) -> f64 {
        self.h
    }

    /// The effective step `h_e` whose `M/h_e^2` is the inertia term of the matrix.
    pub(crate) fn h_e(&self) -> f64 {
        self.h_e
    }

    /// `1/h_e^2`, the weight of the inertia term `M/h_e^2`.
    pub(crate) fn inv_h2(&self) -> f64 {
        1.0 / (self.h_e * self.h_e)
    }

    /// Eq. 2 / T1: the inertial target of every vertex (fixed vertices stay at rest).
    /// `previous` is read only by a two-step scheme, which needs it.
    pub(crate) fn inertial_target(
        &self,
        model: &Model,
        q: &[Vector3<f64>],
        v: &[Vector3<f64>],
        previous: Previous<'_>,
        s: &mut [Vector3<f64>],
    ) {
        let (h, a0, a1) = (self.h_e, self.a0, self.a1);
        match previous.filter(|_| self.two_step()) {
            Some((qp, vp)) => {
                for i in 0..model.n() {
                    s[i] = if model.fixed[i] {
                        model.rest[i]
                    } else {
                        q[i] * a0 + qp[i] * a1 + (v[i] * a0 + vp[i] * a1) * h + model.accel[i] * (h * h)
                    };
                }
            }
            None => {
                debug_assert!(!self.two_step(), "a two-step scheme needs the previous state");
                for i in 0..model.n() {
                    s[i] = if model.fixed[i] {
                        model.rest[i]
                    } else {
                        q[i] + v[i] * h + model.accel[i] * (h * h)
                    };
                }
            }
        }
    }

    /// The adjoint of Eq. 2 / T1 on a free vertex: given `s_bar`, add to the adjoints of the
    /// latest state, of the one before it (two-step schemes), and of the external acceleration.
    pub(crate) fn inertial_target_adjoint(
        &self,
        s_bar: Vector3<f64>,
        latest: (&mut Vector3<f64>, &mut Vector3<f64>),
        before: Option<(&mut Vector3<f64>, &mut Vector3<f64>)>,
        a_bar: &mut Vector3<f64>,
    ) {
        let h = self.h_e;
        *latest.0 += s_bar * self.a0;
        *latest.1 += s_bar * (self.a0 * h);
        if let Some((q, v)) = before {
            *q += s_bar * self.a1;
            *v += s_bar * (self.a1 * h);
        }
        *a_bar += s_bar * (h * h);
    }

    /// Eq. 4 / T3: the velocity after a step from `q_start` (and `q_before`, the position a
    /// step earlier, read by a two-step scheme) to `q`.
    #[inline]
    pub(crate) fn velocity(&self, q_start: &Vector3<f64>, q_before: &Vector3<f64>, q: &Vector3<f64>) -> Vector3<f64> {
        let base = if self.two_step() {
            q_start * self.a0 + q_before * self.a1
        } else {
            *q_start
        };
        (q - base) * (self.damping / self.h_e)
    }

    /// `dv_{n+1}/dq_{n+1} = damping / h_e` (the adjoint of Eq. 4 / T3); the derivatives with
    /// respect to `q_n` and `q_{n-1}` are this times `-a0` and `-a1` ([`Scheme::weights`]).
    pub(crate) fn velocity_coefficient(&self) -> f64 {
        self.damping / self.h_e
    }

    /// `(a0, a1)`: the weights of the latest state and of the one before it.
    pub(crate) fn weights(&self) -> (f64, f64) {
        (self.a0, self.a1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// BDF2 integrates `q'' = a` (a quadratic) exactly from exact history; implicit Euler does
    /// not.
    #[test]
    fn bdf2_is_exact_on_constant_acceleration() {
        let (h, a) = (0.1, -9.81);
        let exact_q = |t: f64| 1.0 + 2.0 * t + 0.5 * a * t * t;
        let exact_v = |t: f64| 2.0 + a * t;
        let s = Scheme::bdf2(h, 1.0);
        let t = 0.3;
        // With no internal forces the step's minimiser is q = s.
        let (a0, a1) = s.weights();
        let h_e = s.h_e();
        let q_new =
            a0 * exact_q(t) + a1 * exact_q(t - h) + h_e * (a0 * exact_v(t) + a1 * exact_v(t - h)) + h_e * h_e * a;
        assert!((q_new - exact_q(t + h)).abs() < 1e-12, "{q_new} vs {}", exact_q(t + h));
        let v_new = (q_new - a0 * exact_q(t) - a1 * exact_q(t - h)) / h_e;
        assert!((v_new - exact_v(t + h)).abs() < 1e-12);
        let e = Scheme::implicit_euler(h, 1.0);
        let q_ie = exact_q(t) + h * exact_v(t) + h * h * a;
        assert!((q_ie - exact_q(t + h)).abs() > 1e-3);
        assert!(e.inv_h2() < s.inv_h2());
    }
}

crate::choice!(Integrator {
    ImplicitEuler => "implicit_euler",
    Bdf2 => "bdf2",
});
