//! Scalar losses of a trajectory, composable: every loss is a sum of per-step terms of the
//! state after each step `n = 1..=N`, with their gradients.

use nalgebra::Vector3;

use crate::model::Model;

use super::DiffError;

/// Gradients a loss term writes (added to, never overwritten).
#[derive(Debug)]
pub struct LossGrad<'a> {
    /// `dL/dq` per vertex.
    pub q: &'a mut [Vector3<f64>],
    /// `dL/dv` per vertex.
    pub v: &'a mut [Vector3<f64>],
    /// `dL/dm` per vertex (losses weighted by mass, such as the centre of mass).
    pub mass: &'a mut [f64],
}

/// A scalar loss of a trajectory.
pub trait Loss: Send + Sync {
    /// The term of step `n` of `steps` (state `q`, `v` after the step) with its gradient added
    /// to `grad`.
    fn term(
        &self,
        model: &Model,
        n: usize,
        steps: usize,
        q: &[Vector3<f64>],
        v: &[Vector3<f64>],
        grad: LossGrad<'_>,
    ) -> f64;

    /// The term of step `n` that depends on the joints: `joints` holds the one-DoF joints'
    /// coordinates per reduced coordinate (angles or extensions; 0 elsewhere, empty without a
    /// skeleton); the gradient is added to `grad` (same layout). Zero by default.
    fn joint_term(&self, _model: &Model, _n: usize, _steps: usize, _joints: &[f64], _grad: &mut [f64]) -> f64 {
        0.0
    }

    /// Check the loss against the model (vertex indices, bone names) before a run.
    fn validate(&self, _model: &Model) -> Result<(), DiffError> {
        Ok(())
    }

    /// A short name for reports.
    fn name(&self) -> String;
}

/// Centre of mass: of the final state, or averaged over steps `1..=N`.
///
/// ```
/// use diffsoft::diff::loss::{CenterOfMass, LossGrad};
/// use diffsoft::Loss;
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
/// use nalgebra::Vector3;
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let model = ModelBuilder::new().body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0))).build()?;
/// let com_x = CenterOfMass { direction: Vector3::x(), time_average: false, vertices: None };
/// com_x.validate(&model)?;
/// assert_eq!(com_x.name(), "final_com.x");
/// // The term of the last step at the rest state, with its gradient.
/// let n = model.n();
/// let (mut gq, mut gv, mut gm) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n], vec![0.0; n]);
/// let grad = LossGrad { q: &mut gq, v: &mut gv, mass: &mut gm };
/// let x = com_x.term(&model, 1, 1, model.rest(), &vec![Vector3::zeros(); n], grad);
/// assert!((x - 0.05).abs() < 1e-12);
/// assert!((gq.iter().map(|g| g.x).sum::<f64>() - 1.0).abs() < 1e-12);
/// // Vertex sets are checked against the model.
/// let outside = CenterOfMass { direction: Vector3::x(), time_average: true, vertices: Some(vec![99]) };
/// assert!(outside.validate(&model).is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone)]
pub struct CenterOfMass {
    /// Component (0, 1, 2) or `None` for the weighted sum `direction . com`.
    pub direction: Vector3<f64>,
    /// Average over all steps instead of the final state.
    pub time_average: bool,
    /// Restrict to these vertices (`None`: all).
    pub vertices: Option<Vec<usize>>,
}

impl CenterOfMass {
    /// `weight direction . com` over `verts` (without allocating), with its gradient.
    fn com_term(
        &self,
        model: &Model,
        verts: impl Iterator<Item = usize> + Clone,
        weight: f64,
        q: &[Vector3<f64>],
        g: LossGrad<'_>,
    ) -> f64 {
        let total: f64 = verts.clone().map(|i| model.mass[i]).sum();
        let com: Vector3<f64> = verts.clone().map(|i| q[i] * model.mass[i]).sum::<Vector3<f64>>() / total;
        let value = self.direction.dot(&com);
        for i in verts {
            g.q[i] += self.direction * (weight * model.mass[i] / total);
            g.mass[i] += weight * self.direction.dot(&(q[i] - com)) / total;
        }
        weight * value
    }
}

impl Loss for CenterOfMass {
    fn term(
        &self,
        model: &Model,
        n: usize,
        steps: usize,
        q: &[Vector3<f64>],
        _v: &[Vector3<f64>],
        g: LossGrad<'_>,
    ) -> f64 {
        let Some(weight) = step_weight(self.time_average, n, steps) else {
            return 0.0;
        };
        match &self.vertices {
            Some(v) => self.com_term(model, v.iter().copied(), weight, q, g),
            None => self.com_term(model, 0..q.len(), weight, q, g),
        }
    }

    fn validate(&self, model: &Model) -> Result<(), DiffError> {
        if !self.direction.iter().all(|x| x.is_finite()) {
            return Err(DiffError::Input(format!(
                "loss {}: direction must be finite",
                self.name()
            )));
        }
        if let Some(v) = &self.vertices {
            if v.is_empty() {
                return Err(DiffError::Input(format!("loss {}: empty vertex set", self.name())));
            }
            check_vertices(&self.name(), model, v.iter().copied())?;
        }
        Ok(())
    }

    fn name(&self) -> String {
        format!(
            "{}_com{}",
            if self.time_average { "mean" } else { "final" },
            axis_suffix(&self.direction)
        )
    }
}

/// The weight of step `n` of `steps` in a loss over the final state (1 at the last step, none
/// before it) or averaged over the steps (`1/steps` at each).
fn step_weight(time_average: bool, n: usize, steps: usize) -> Option<f64> {
    if time_average {
        Some(1.0 / steps as f64)
    } else {
        (n == steps).then_some(1.0)
    }
}

/// `sum_k value(q_{i_k}, t_k)` over `(vertex, datum)` pairs at the final step, each adding its
/// gradient to `g.q`: the body of the per-vertex losses.
fn final_vertex_terms<T>(
    pairs: &[(usize, T)],
    n: usize,
    steps: usize,
    q: &[Vector3<f64>],
    g: LossGrad<'_>,
    value: impl Fn(&Vector3<f64>, &T) -> (f64, Vector3<f64>),
) -> f64 {
    if step_weight(false, n, steps).is_none() {
        return 0.0;
    }
    let mut s = 0.0;
    for (i, t) in pairs {
        let (v, d) = value(&q[*i], t);
        s += v;
        g.q[*i] += d;
    }
    s
}

fn check_vertices(name: &str, model: &Model, verts: impl Iterator<Item = usize>) -> Result<(), DiffError> {
    for i in verts {
        if i >= model.n() {
            return Err(DiffError::Input(format!(
                "loss {name}: vertex {i} out of range ({} vertices)",
                model.n()
            )));
        }
    }
    Ok(())
}

fn axis_suffix(d: &Vector3<f64>) -> String {
    for (k, s) in [".x", ".y", ".z"].iter().enumerate() {
        if *d == Vector3::ith(k, 1.0) {
            return s.to_string();
        }
    }
    format!("[{},{},{}]", d.x, d.y, d.z)
}

/// `sum_i c_i . q_i` over chosen vertices of the final state (positions of chosen vertices).
///
/// ```
/// use diffsoft::diff::loss::{LossGrad, VertexPositions};
/// use diffsoft::Loss;
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
/// use nalgebra::Vector3;
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let model = ModelBuilder::new().body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0))).build()?;
/// let top = model.rest().iter().position(|q| *q == Vector3::repeat(0.1)).ok_or("no corner")?;
/// let loss = VertexPositions { terms: vec![(top, Vector3::new(1.0, 2.0, 0.0))] };
/// loss.validate(&model)?;
/// // The term of the last step at the rest state, with its gradient.
/// let n = model.n();
/// let (mut gq, mut gv, mut gm) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n], vec![0.0; n]);
/// let grad = LossGrad { q: &mut gq, v: &mut gv, mass: &mut gm };
/// let value = loss.term(&model, 1, 1, model.rest(), &vec![Vector3::zeros(); n], grad);
/// assert!((value - 0.3).abs() < 1e-12); // 1 x 0.1 + 2 x 0.1
/// assert_eq!(gq[top], Vector3::new(1.0, 2.0, 0.0));
/// // Only the final state counts.
/// let (mut gq, mut gv, mut gm) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n], vec![0.0; n]);
/// let grad = LossGrad { q: &mut gq, v: &mut gv, mass: &mut gm };
/// assert_eq!(loss.term(&model, 1, 2, model.rest(), &vec![Vector3::zeros(); n], grad), 0.0);
/// assert!(VertexPositions { terms: vec![(n, Vector3::x())] }.validate(&model).is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone)]
pub struct VertexPositions {
    /// `(vertex, weight vector)` pairs.
    pub terms: Vec<(usize, Vector3<f64>)>,
}

impl Loss for VertexPositions {
    fn term(
        &self,
        _m: &Model,
        n: usize,
        steps: usize,
        q: &[Vector3<f64>],
        _v: &[Vector3<f64>],
        g: LossGrad<'_>,
    ) -> f64 {
        final_vertex_terms(&self.terms, n, steps, q, g, |x, c| (c.dot(x), *c))
    }

    fn validate(&self, model: &Model) -> Result<(), DiffError> {
        check_vertices(&self.name(), model, self.terms.iter().map(|t| t.0))
    }

    fn name(&self) -> String {
        "vertex_positions".into()
    }
}

/// `1/2 sum_i |q_i - target_i|^2` over chosen vertices of the final state.
///
/// ```
/// use diffsoft::diff::loss::{LossGrad, TargetDistance};
/// use diffsoft::Loss;
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
/// use nalgebra::Vector3;
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let model = ModelBuilder::new().body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0))).build()?;
/// // Vertex 0 should be 0.1 m higher.
/// let loss = TargetDistance { targets: vec![(0, model.rest()[0] + Vector3::new(0.0, 0.1, 0.0))] };
/// loss.validate(&model)?;
/// // The term of the last step at the rest state, with its gradient.
/// let n = model.n();
/// let (mut gq, mut gv, mut gm) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n], vec![0.0; n]);
/// let grad = LossGrad { q: &mut gq, v: &mut gv, mass: &mut gm };
/// let value = loss.term(&model, 1, 1, model.rest(), &vec![Vector3::zeros(); n], grad);
/// assert!((value - 0.005).abs() < 1e-12); // 1/2 x 0.1^2
/// assert!((gq[0] - Vector3::new(0.0, -0.1, 0.0)).norm() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone)]
pub struct TargetDistance {
    /// `(vertex, target)` pairs.
    pub targets: Vec<(usize, Vector3<f64>)>,
}

impl Loss for TargetDistance {
    fn term(
        &self,
        _m: &Model,
        n: usize,
        steps: usize,
        q: &[Vector3<f64>],
        _v: &[Vector3<f64>],
        g: LossGrad<'_>,
    ) -> f64 {
        final_vertex_terms(&self.targets, n, steps, q, g, |x, t| {
            let d = x - t;
            (0.5 * d.norm_squared(), d)
        })
    }

    fn validate(&self, model: &Model) -> Result<(), DiffError> {
        check_vertices(&self.name(), model, self.targets.iter().map(|t| t.0))
    }

    fn name(&self) -> String {
        "target_distance".into()
    }
}

/// A weighted sum of losses; start from [`Sum::default`] and [`Sum::add`] terms.
///
/// ```
/// use diffsoft::diff::loss::{CenterOfMass, LossGrad, Sum, TargetDistance};
/// use diffsoft::Loss;
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
/// use nalgebra::Vector3;
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let model = ModelBuilder::new().body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0))).build()?;
/// let com_y = CenterOfMass { direction: Vector3::y(), time_average: false, vertices: None };
/// let pull = TargetDistance { targets: vec![(0, model.rest()[0] + Vector3::new(0.0, 0.1, 0.0))] };
/// let loss = Sum::default().add(2.0, com_y).add(10.0, pull);
/// assert_eq!(loss.terms.len(), 2);
/// loss.validate(&model)?;
/// // The term of the last step at the rest state, with its gradient.
/// let n = model.n();
/// let (mut gq, mut gv, mut gm) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n], vec![0.0; n]);
/// let grad = LossGrad { q: &mut gq, v: &mut gv, mass: &mut gm };
/// let value = loss.term(&model, 1, 1, model.rest(), &vec![Vector3::zeros(); n], grad);
/// assert!((value - (2.0 * 0.05 + 10.0 * 0.005)).abs() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Default)]
pub struct Sum {
    /// `(weight, loss)` pairs.
    pub terms: Vec<(f64, Box<dyn Loss>)>,
}

impl Sum {
    /// Add `weight x loss`.
    ///
    /// ```
    /// use diffsoft::diff::loss::{CenterOfMass, Sum};
    /// use diffsoft::Loss;
    /// use nalgebra::Vector3;
    ///
    /// let com = |d: Vector3<f64>| CenterOfMass { direction: d, time_average: false, vertices: None };
    /// let loss = Sum::default().add(1.0, com(Vector3::x())).add(-0.5, com(Vector3::y()));
    /// assert_eq!(loss.name(), "1*final_com.x+-0.5*final_com.y");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn add(mut self, weight: f64, loss: impl Loss + 'static) -> Self {
        self.terms.push((weight, Box::new(loss)));
        self
    }
}

/// A joint's coordinate (angle or extension) of a one-DoF joint: its final value, its average
/// over the steps, or half its squared distance to a target at the final step.
///
/// ```
/// use diffsoft::diff::loss::JointAngle;
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::skeleton::{rotational::Rotational, BoneSpec};
/// use diffsoft::{BodySpec, Loss, MassSpec, Material, ModelBuilder};
/// use nalgebra::Vector3;
///
/// let mesh = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1]).build()?;
/// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let hinge = Rotational::new(Vector3::zeros(), Vector3::z());
/// let mut body = BodySpec::new("arm", mesh, material, MassSpec::Density(1000.0));
/// let bone = BoneSpec { name: "elbow".into(), parent: None, joint: Box::new(hinge), vertices: vec![0], torque: None };
/// body.bones.push(bone);
/// let model = ModelBuilder::new().body(body).build()?;
///
/// let angle = JointAngle { bone: "elbow".into(), target: Some(0.5), time_average: false };
/// angle.validate(&model)?;
/// // 1/2 (theta - target)^2 at theta = 0, with its derivative.
/// let mut grad = vec![0.0; 1];
/// assert!((angle.joint_term(&model, 1, 1, &[0.0], &mut grad) - 0.125).abs() < 1e-12);
/// assert!((grad[0] + 0.5).abs() < 1e-12);
/// // A bone the model does not have.
/// assert!(JointAngle { bone: "knee".into(), target: None, time_average: false }.validate(&model).is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone)]
pub struct JointAngle {
    /// Bone whose joint is measured.
    pub bone: String,
    /// `Some(target)`: `1/2 (theta - target)^2`; `None`: `theta` itself.
    pub target: Option<f64>,
    /// Average over all steps instead of the final state.
    pub time_average: bool,
}

impl JointAngle {
    fn dof(&self, model: &Model) -> Result<usize, DiffError> {
        let sk = model
            .skeleton
            .as_ref()
            .ok_or_else(|| DiffError::Input(format!("loss joint_angle.{}: the model has no skeleton", self.bone)))?;
        sk.scalar_dof(&self.bone)
            .map_err(|e| DiffError::Input(format!("loss joint_angle.{}: {e}", self.bone)))
    }
}

impl Loss for JointAngle {
    fn term(
        &self,
        _m: &Model,
        _n: usize,
        _steps: usize,
        _q: &[Vector3<f64>],
        _v: &[Vector3<f64>],
        _g: LossGrad<'_>,
    ) -> f64 {
        0.0
    }

    fn joint_term(&self, model: &Model, n: usize, steps: usize, joints: &[f64], grad: &mut [f64]) -> f64 {
        let Some(weight) = step_weight(self.time_average, n, steps) else {
            return 0.0;
        };
        let Ok(k) = self.dof(model) else {
            return f64::NAN;
        };
        match self.target {
            Some(t) => {
                let d = joints[k] - t;
                grad[k] += weight * d;
                weight * 0.5 * d * d
            }
            None => {
                grad[k] += weight;
                weight * joints[k]
            }
        }
    }

    fn validate(&self, model: &Model) -> Result<(), DiffError> {
        if self.target.is_some_and(|t| !t.is_finite()) {
            return Err(DiffError::Input(format!(
                "loss joint_angle.{}: target must be finite",
                self.bone
            )));
        }
        self.dof(model).map(|_| ())
    }

    fn name(&self) -> String {
        format!(
            "{}joint_angle.{}",
            if self.time_average { "mean_" } else { "" },
            self.bone
        )
    }
}

impl Loss for Sum {
    fn term(
        &self,
        model: &Model,
        n: usize,
        steps: usize,
        q: &[Vector3<f64>],
        v: &[Vector3<f64>],
        g: LossGrad<'_>,
    ) -> f64 {
        let mut total = 0.0;
        let (mut gq, mut gv, mut gm) = (
            vec![Vector3::zeros(); q.len()],
            vec![Vector3::zeros(); q.len()],
            vec![0.0; q.len()],
        );
        for (w, l) in &self.terms {
            gq.iter_mut().for_each(|x| *x = Vector3::zeros());
            gv.iter_mut().for_each(|x| *x = Vector3::zeros());
            gm.iter_mut().for_each(|x| *x = 0.0);
            total += w * l.term(
                model,
                n,
                steps,
                q,
                v,
                LossGrad {
                    q: &mut gq,
                    v: &mut gv,
                    mass: &mut gm,
                },
            );
            for i in 0..q.len() {
                g.q[i] += gq[i] * *w;
                g.v[i] += gv[i] * *w;
                g.mass[i] += gm[i] * *w;
            }
        }
        total
    }

    fn joint_term(&self, model: &Model, n: usize, steps: usize, joints: &[f64], grad: &mut [f64]) -> f64 {
        let mut total = 0.0;
        let mut g = vec![0.0; grad.len()];
        for (w, l) in &self.terms {
            g.iter_mut().for_each(|x| *x = 0.0);
            total += w * l.joint_term(model, n, steps, joints, &mut g);
            for (a, b) in grad.iter_mut().zip(&g) {
                *a += w * b;
            }
        }
        total
    }

    fn validate(&self, model: &Model) -> Result<(), DiffError> {
        self.terms.iter().try_for_each(|(w, l)| {
            if !w.is_finite() {
                return Err(DiffError::Input(format!("loss {}: weight must be finite", l.name())));
            }
            l.validate(model)
        })
    }

    fn name(&self) -> String {
        self.terms
            .iter()
            .map(|(w, l)| format!("{w}*{}", l.name()))
            .collect::<Vec<_>>()
            .join("+")
    }
}

/// A loss by name: `final_com.x|y|z`, `mean_com.x|y|z`, `joint_angle.BONE`,
/// `mean_joint_angle.BONE`.
///
/// ```
/// use diffsoft::diff::loss::by_name;
///
/// assert_eq!(by_name("final_com.y")?.name(), "final_com.y");
/// assert_eq!(by_name("mean_com.x")?.name(), "mean_com.x");
/// assert!(by_name("final_com.w").is_err());
/// assert!(by_name("energy").is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn by_name(name: &str) -> Result<Box<dyn Loss>, DiffError> {
    let (kind, axis) = name.split_once('.').ok_or_else(|| {
        DiffError::Input(format!(
            "unknown loss '{name}' (expected final_com.x|y|z, mean_com.x|y|z, joint_angle.BONE or mean_joint_angle.BONE)"
        ))
    })?;
    if kind == "joint_angle" || kind == "mean_joint_angle" {
        return Ok(Box::new(JointAngle {
            bone: axis.to_string(),
            target: None,
            time_average: kind == "mean_joint_angle",
        }));
    }
    let k = match axis {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        _ => return Err(DiffError::Input(format!("loss '{name}': axis must be x, y or z"))),
    };
    let time_average = match kind {
        "final_com" => false,
        "mean_com" => true,
        _ => {
            return Err(DiffError::Input(format!(
                "unknown loss '{name}' (expected final_com.x|y|z or mean_com.x|y|z)"
            )))
        }
    };
    Ok(Box::new(CenterOfMass {
        direction: Vector3::ith(k, 1.0),
        time_average,
        vertices: None,
    }))
}
