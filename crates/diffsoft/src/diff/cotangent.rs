//! Vector-Jacobian products of a whole trajectory: a cotangent `C` on the positions (and
//! optionally the velocities) of every state `0..=N` is the loss `sum_k <C_k, q_k>` (+
//! `<D_k, v_k>`), whose gradient is the product of `C` with the trajectory's Jacobian. This is
//! how a loss written outside the crate (PyTorch, JAX) differentiates through a simulation.

use nalgebra::Vector3;

use super::loss::{Loss, LossGrad};
use super::{gradient, Controls, DiffError, Gradient, Options};
use crate::model::Model;
use crate::solver::Settings;

/// A cotangent on a trajectory of `steps` steps of `n` vertices, step-major like
/// [`Rollout`](super::Rollout): `q[k * n + i]` multiplies vertex `i`'s position in state `k`.
#[derive(Debug, Clone)]
pub struct Cotangent {
    n: usize,
    steps: usize,
    q: Vec<Vector3<f64>>,
    v: Option<Vec<Vector3<f64>>>,
}

impl Cotangent {
    /// A cotangent on the positions (`(steps + 1) * n` entries) and optionally the velocities
    /// (same length); an error if the lengths disagree or an entry is not finite.
    ///
    /// ```
    /// use diffsoft::{Cotangent, Loss};
    /// use nalgebra::Vector3;
    ///
    /// // Two steps of four vertices: states 0, 1, 2 (see [`vjp`] for its use).
    /// let c = Cotangent::new(4, 2, vec![Vector3::y(); 12], None)?;
    /// assert_eq!(c.name(), "cotangent");
    /// assert!(Cotangent::new(4, 2, vec![Vector3::y(); 8], None).is_err());
    /// assert!(Cotangent::new(4, 2, vec![Vector3::y(); 12], Some(vec![Vector3::repeat(f64::NAN); 12])).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(n: usize, steps: usize, q: Vec<Vector3<f64>>, v: Option<Vec<Vector3<f64>>>) -> Result<Self, DiffError> {
        let len = steps
            .checked_add(1)
            .and_then(|s| s.checked_mul(n))
            .ok_or_else(|| DiffError::Input(format!("cotangent of {steps} steps of {n} vertices is too large")))?;
        for (name, c) in [("positions", Some(&q)), ("velocities", v.as_ref())] {
            let Some(c) = c else { continue };
            if c.len() != len {
                return Err(DiffError::Input(format!(
                    "cotangent on the {name} has {} entries, expected (steps + 1) * n = ({steps} + 1) * {n} = {len}",
                    c.len()
                )));
            }
            if let Some(k) = c.iter().position(|x| !x.iter().all(|e| e.is_finite())) {
                return Err(DiffError::Input(format!(
                    "cotangent on the {name}: entry of state {}, vertex {} is not finite",
                    k / n.max(1),
                    k % n.max(1)
                )));
            }
        }
        Ok(Self { n, steps, q, v })
    }

    fn state(c: &[Vector3<f64>], n: usize, k: usize) -> &[Vector3<f64>] {
        &c[k * n..(k + 1) * n]
    }
}

impl Loss for Cotangent {
    fn term(
        &self,
        _model: &Model,
        n: usize,
        _steps: usize,
        q: &[Vector3<f64>],
        v: &[Vector3<f64>],
        g: LossGrad<'_>,
    ) -> f64 {
        let mut s = 0.0;
        for (i, c) in Self::state(&self.q, self.n, n).iter().enumerate() {
            s += c.dot(&q[i]);
            g.q[i] += c;
        }
        if let Some(cv) = &self.v {
            for (i, c) in Self::state(cv, self.n, n).iter().enumerate() {
                s += c.dot(&v[i]);
                g.v[i] += c;
            }
        }
        s
    }

    fn validate(&self, model: &Model) -> Result<(), DiffError> {
        if self.n != model.n() {
            return Err(DiffError::Input(format!(
                "cotangent is for {} vertices, the model has {}",
                self.n,
                model.n()
            )));
        }
        Ok(())
    }

    fn name(&self) -> String {
        "cotangent".into()
    }
}

/// `sum_k <C_k, q_k> + <D_k, v_k>` over the states `0..=steps` of a run and its gradient with
/// respect to everything [`gradient`] differentiates (the state-0 terms included).
///
/// ```
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
/// use diffsoft::{rollout, vjp, Controls, Cotangent, Options, Settings};
/// use nalgebra::Vector3;
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let model = ModelBuilder::new()
///     .gravity(Vector3::new(0.0, -9.81, 0.0))
///     .body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0)))
///     .build()?;
/// let (n, steps, settings) = (model.n(), 2, Settings::default());
/// // The mean height of the vertices after the last step.
/// let mut c = vec![Vector3::zeros(); (steps + 1) * n];
/// c[steps * n..].fill(Vector3::y() / n as f64);
/// let cotangent = Cotangent::new(n, steps, c, None)?;
/// let g = vjp(&model, &settings, steps, &Controls::default(), &cotangent, Options::default())?;
/// let run = rollout(&model, &settings, steps, &Controls::default())?;
/// let mean_y = run.positions[steps * n..].iter().map(|q| q.y).sum::<f64>() / n as f64;
/// assert!((g.loss - mean_y).abs() < 1e-12);
/// assert!((g.v0.iter().map(|d| d.y).sum::<f64>() - steps as f64 * settings.dt).abs() < 1e-9);
/// // The cotangent must cover the run's steps.
/// assert!(vjp(&model, &settings, 3, &Controls::default(), &cotangent, Options::default()).is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn vjp(
    model: &Model,
    settings: &Settings,
    steps: usize,
    controls: &Controls,
    cotangent: &Cotangent,
    opts: Options,
) -> Result<Gradient, DiffError> {
    if cotangent.steps != steps {
        return Err(DiffError::Input(format!(
            "cotangent covers {} steps, the run has {steps}",
            cotangent.steps
        )));
    }
    cotangent.validate(model)?;
    let mut g = gradient(model, settings, steps, controls, cotangent, opts)?;
    let (q0, v0) = match &controls.initial {
        Some((q, v)) => (q.as_slice(), v.as_slice()),
        None => (model.rest(), model.initial_velocity()),
    };
    for (i, c) in Cotangent::state(&cotangent.q, cotangent.n, 0).iter().enumerate() {
        g.loss += c.dot(&q0[i]);
        g.q0[i] += c;
    }
    if let Some(cv) = &cotangent.v {
        for (i, c) in Cotangent::state(cv, cotangent.n, 0).iter().enumerate() {
            g.loss += c.dot(&v0[i]);
            g.v0[i] += c;
        }
    }
    // The state-0 terms can overflow on their own (cotangents near the largest double).
    if let Some(what) = g.first_non_finite() {
        return Err(DiffError::NonFiniteGradient { what });
    }
    Ok(g)
}
