//! The time integrator's explicit phases around the local-global iterations (docs/method.md
//! section 2): implicit Euler's inertial target `s_n = q_n + h v_n + h^2 a_ext` (Eq. 2), the
//! weight `1/h^2` of the inertia term `M/h^2` in the step's objective and matrix (Eq. 5), and the
//! velocity update `v_{n+1} = damping (q_{n+1} - q_n) / h` (Eq. 4), with the adjoints of each for
//! the backward pass. The time step lives here and in [`Settings`](super::Settings) only.

use nalgebra::Vector3;

use crate::model::Model;

/// Implicit Euler with velocity damping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ImplicitEuler {
    h: f64,
    damping: f64,
}

impl ImplicitEuler {
    /// Time step `h` and damping factor per step.
    pub(crate) fn new(h: f64, damping: f64) -> Self {
        Self { h, damping }
    }

    /// The time step.
    pub(crate) fn h(&self) -> f64 {
        self.h
    }

    /// `1/h^2`, the weight of the inertia term `M/h^2`.
    pub(crate) fn inv_h2(&self) -> f64 {
        1.0 / (self.h * self.h)
    }

    /// Eq. 2: the inertial target of every vertex, `s = q + h v + h^2 a` (fixed vertices stay at
    /// rest).
    pub(crate) fn inertial_target(
        &self,
        model: &Model,
        q: &[Vector3<f64>],
        v: &[Vector3<f64>],
        s: &mut [Vector3<f64>],
    ) {
        let h = self.h;
        for i in 0..model.n() {
            s[i] = if model.fixed[i] {
                model.rest[i]
            } else {
                q[i] + v[i] * h + model.accel[i] * (h * h)
            };
        }
    }

    /// The adjoint of Eq. 2 on a free vertex: given `s_bar`, add to the adjoints of its start
    /// position, start velocity and external acceleration.
    pub(crate) fn inertial_target_adjoint(
        &self,
        s_bar: Vector3<f64>,
        q_bar: &mut Vector3<f64>,
        v_bar: &mut Vector3<f64>,
        a_bar: &mut Vector3<f64>,
    ) {
        *q_bar += s_bar;
        *v_bar += s_bar * self.h;
        *a_bar += s_bar * (self.h * self.h);
    }

    /// Eq. 4: the velocity after a step from `q_start` to `q`.
    #[inline]
    pub(crate) fn velocity(&self, q_start: &Vector3<f64>, q: &Vector3<f64>) -> Vector3<f64> {
        (q - q_start) * (self.damping / self.h)
    }

    /// `dv_{n+1}/dq_{n+1} = -dv_{n+1}/dq_n = damping / h` (the adjoint of Eq. 4).
    pub(crate) fn velocity_coefficient(&self) -> f64 {
        self.damping / self.h
    }
}
