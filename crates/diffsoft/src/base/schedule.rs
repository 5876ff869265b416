//! Piecewise-linear time series.

use serde::Serialize;

use super::InputError;

/// Piecewise-linear time series (constant before the first and after the last sample): the
/// activations of actuator groups and the torques of joints over time.
///
/// A ramp, as a struct literal:
///
/// ```
/// use diffsoft::Schedule;
///
/// let ramp = Schedule { times: vec![0.0, 1.0], values: vec![0.0, 2.0] };
/// ramp.validate("torque")?;
/// assert_eq!(ramp.at(0.25), 0.5);
/// assert_eq!(ramp.at(5.0), 2.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Schedule {
    /// Sample times, increasing.
    pub times: Vec<f64>,
    /// Values at those times.
    pub values: Vec<f64>,
}

impl Schedule {
    /// A constant value.
    ///
    /// ```
    /// use diffsoft::Schedule;
    ///
    /// let a = Schedule::constant(0.5);
    /// a.validate("activation")?;
    /// assert_eq!(a.at(-1.0), 0.5);
    /// assert_eq!(a.at(10.0), 0.5);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn constant(v: f64) -> Self {
        Self {
            times: vec![0.0],
            values: vec![v],
        }
    }

    /// Check lengths, order and finiteness.
    pub fn validate(&self, what: &str) -> Result<(), InputError> {
        let bad = |m: &str| Err(InputError::new(format!("{what}: {m}")));
        if self.times.is_empty() || self.times.len() != self.values.len() {
            return bad("needs as many values as times, at least one");
        }
        if !self.times.iter().chain(&self.values).all(|v| v.is_finite()) {
            return bad("times and values must be finite");
        }
        if self.times.windows(2).any(|w| w[1] <= w[0]) {
            return bad("times must increase");
        }
        Ok(())
    }

    /// Value at time `t`.
    pub fn at(&self, t: f64) -> f64 {
        let n = self.times.len();
        if t <= self.times[0] {
            return self.values[0];
        }
        if t >= self.times[n - 1] {
            return self.values[n - 1];
        }
        let k = self.times.partition_point(|&s| s <= t);
        let (t0, t1) = (self.times[k - 1], self.times[k]);
        let a = (t - t0) / (t1 - t0);
        self.values[k - 1] * (1.0 - a) + self.values[k] * a
    }
}
