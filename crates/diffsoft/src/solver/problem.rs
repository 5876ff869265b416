//! The problem one step solves (docs/method.md Eq. S3): its energy, gradient and Hessian
//! product, the single place their terms are written. Projective dynamics' local-global
//! iteration descends the energy with the fixed Hessian `A = M/h^2 + L` (its Anderson safeguard
//! reads [`step_objective`]); Newton's method (free vertices and skeleton coordinates alike)
//! reads [`StepProblem`].
//!
//! The terms: inertia `1/(2h^2) |q - s|_M^2`, every constraint set's energy (elasticity,
//! actuators, cloth, with their weights from the materials; `constraint`), attachments, the
//! joint torques' work. The gradient is `A q - b - J p` (the constant part `b` holds inertia,
//! the Dirichlet vertices' pull and the attachments' targets), the Hessian
//! `A - J K~ J^T` with every constraint kind's declared term ([`ConstraintHessian`]). A new
//! energy term enters here and in the constraint set that owns it; the test at the end of this
//! file checks energy, gradient and Hessian against each other with every term present.

use nalgebra::Vector3;

use super::assembled::GlobalSystem;
use super::hessian::ConstraintHessian;
use super::SolverError;
use crate::constraint::{Constraints, TetSvd};
use crate::model::Model;
use crate::skeleton::Skeleton;

/// One step's problem at fixed contacts: what the energy, gradient and Hessian read.
pub(crate) struct StepProblem<'a> {
    /// The model.
    pub model: &'a Model,
    /// The global system (free and bone vertices, `A`).
    pub sys: &'a GlobalSystem,
    /// The step's activation per actuator group.
    pub activations: &'a [f64],
    /// The inertial target `s_n` (every vertex).
    pub s: &'a [Vector3<f64>],
    /// `1/h_e^2`.
    pub ih2: f64,
    /// The right-hand side's constant part `M s / h^2 + fixed pull + attachments` (free).
    pub base: &'a [Vector3<f64>],
    /// Joint scalars at the start of the step (skeleton DoF layout; empty without bones).
    pub coords0: &'a [f64],
    /// The step's joint torques (skeleton DoF layout; empty without bones).
    pub torque: &'a [f64],
}

impl StepProblem<'_> {
    /// The local step at the positions `full` (every vertex; decompositions into `record`) and
    /// the step energy there (the skeleton, if any, in the state that placed its vertices).
    /// Returns `(E, constraint energy)`.
    pub(crate) fn energy(
        &self,
        constraints: &mut Constraints,
        full: &[Vector3<f64>],
        skeleton: Option<&Skeleton>,
        record: &mut [TetSvd],
    ) -> Result<(f64, f64), SolverError> {
        let elastic = constraints.project(self.model, full, self.activations, Some(record))?;
        let e = step_objective(
            self.model,
            full,
            self.s,
            self.ih2,
            elastic,
            skeleton,
            self.coords0,
            self.torque,
        );
        Ok((e, elastic))
    }

    /// `grad_q E = A q - b - J p` on the free vertices `x` and the bone vertices `q_r` (empty
    /// without bones; `base_r` its constant part) from the last local step, whose `J p` is
    /// gathered into `gathered` (every vertex).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn gradient(
        &self,
        constraints: &mut Constraints,
        x: &[Vector3<f64>],
        q_r: &[Vector3<f64>],
        base_r: &[Vector3<f64>],
        gathered: &mut [Vector3<f64>],
        g_f: &mut [Vector3<f64>],
        g_r: &mut [Vector3<f64>],
    ) {
        constraints.gather(self.model, gathered);
        apply_a(self.sys, x, q_r, g_f, g_r);
        for (k, &v) in self.sys.free.iter().enumerate() {
            g_f[k] -= self.base[k] + gathered[v];
        }
        for (r, &v) in self.sys.rigid.iter().enumerate() {
            g_r[r] -= base_r[r] + gathered[v];
        }
    }

    /// `y = H u = (A - J K~ J^T) u` for `u = (u_f, u_r)` on the free and bone vertices, at the
    /// iterate `q` (every vertex) with the Hessian `hessian` prepared there; `u_full`,
    /// `out_full`: scratch on every vertex (zero at fixed vertices). `false` where an
    /// actuator's projection is not differentiable.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn hessian_product(
        &self,
        hessian: &mut ConstraintHessian,
        q: &[Vector3<f64>],
        u_f: &[Vector3<f64>],
        u_r: &[Vector3<f64>],
        y_f: &mut [Vector3<f64>],
        y_r: &mut [Vector3<f64>],
        u_full: &mut [Vector3<f64>],
        out_full: &mut [Vector3<f64>],
    ) -> bool {
        let sys = self.sys;
        apply_a(sys, u_f, u_r, y_f, y_r);
        for (k, &v) in sys.free.iter().enumerate() {
            u_full[v] = u_f[k];
        }
        for (r, &v) in sys.rigid.iter().enumerate() {
            u_full[v] = u_r[r];
        }
        if !hessian.apply(self.model, q, self.activations, u_full, out_full) {
            return false;
        }
        for (k, &v) in sys.free.iter().enumerate() {
            y_f[k] -= out_full[v];
        }
        for (r, &v) in sys.rigid.iter().enumerate() {
            y_r[r] -= out_full[v];
        }
        true
    }
}

/// The constant part of the global step's right-hand side on the free vertices (Eq. 5):
/// `M s / h^2`, the Dirichlet vertices' pull and every projection that does not depend on the
/// positions (attachments' targets).
pub(crate) fn constant_rhs(
    model: &Model,
    sys: &GlobalSystem,
    constraints: &Constraints,
    s: &[Vector3<f64>],
    ih2: f64,
    base: &mut [Vector3<f64>],
) {
    for (k, &v) in sys.free.iter().enumerate() {
        base[k] = s[v] * (model.mass[v] * ih2) + sys.coupling[k];
    }
    constraints.constant_rhs(model, &mut |v, b| {
        let k = sys.index[v];
        if k != usize::MAX {
            base[k] += b;
        }
    });
}

/// `y = A u` on the free and bone vertices for `u = (u_f, u_r)` (`u_r` empty without bones).
pub(crate) fn apply_a(
    sys: &GlobalSystem,
    u_f: &[Vector3<f64>],
    u_r: &[Vector3<f64>],
    y_f: &mut [Vector3<f64>],
    y_r: &mut [Vector3<f64>],
) {
    sys.apply(u_f, y_f);
    let nr = u_r.len();
    for (r, list) in sys.l_rf.iter().enumerate() {
        let mut acc = u_r[r] * sys.mass_rigid_h2[r];
        for &(f, v) in list {
            y_f[f] += u_r[r] * v;
            acc += u_f[f] * v;
        }
        let row = &sys.l_rr[r * nr..(r + 1) * nr];
        for (c, &v) in row.iter().enumerate() {
            if v != 0.0 {
                acc += u_r[c] * v;
            }
        }
        y_r[r] = acc;
    }
}

/// The objective the local-global iteration of one step minimises:
/// `1/(2h^2) |q - s|_M^2 + E_constraints(q) + attachments - tau . (z - z_start)`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn step_objective(
    model: &Model,
    q: &[Vector3<f64>],
    s: &[Vector3<f64>],
    ih2: f64,
    elastic: f64,
    skeleton: Option<&Skeleton>,
    coords0: &[f64],
    torque: &[f64],
) -> f64 {
    let mut e = elastic;
    for ((qi, si), m) in q.iter().zip(s).zip(&model.mass) {
        e += 0.5 * ih2 * m * (qi - si).norm_squared();
    }
    for a in &model.attachments {
        e += a.energy(&q[a.vertex]);
    }
    if let Some(sk) = skeleton {
        for b in &sk.bones {
            let (Some(c), k) = (b.joint.scalar(), b.dof_offset) else {
                continue;
            };
            if torque[k] != 0.0 {
                // Angles wrap: take the difference on the circle.
                let mut d = c - coords0[k];
                if d > std::f64::consts::PI {
                    d -= 2.0 * std::f64::consts::PI;
                } else if d < -std::f64::consts::PI {
                    d += 2.0 * std::f64::consts::PI;
                }
                e -= torque[k] * d;
            }
        }
    }
    e
}

#[cfg(all(test, feature = "testing"))]
mod tests {
    use super::*;
    use crate::base::MaterialModel;
    use crate::model::fixtures::{actuated_beam, ground_box};

    /// A deterministic pseudo-random number in `[-1, 1)`.
    fn noise(k: usize) -> f64 {
        let x = (k as f64 * 12.9898).sin() * 43_758.545_3;
        2.0 * (x - x.floor()) - 1.0
    }

    /// Energy, gradient and Hessian of the step problem agree with each other (central
    /// differences) on a model with every term Newton's method takes: inertia, corotated
    /// elasticity with its volume term, pneumatic and muscle actuators, attachments, a Dirichlet
    /// vertex and gravity. A term added to the energy but not to the gradient or the Hessian
    /// (or a constraint kind whose Hessian term is wrong) fails here.
    #[test]
    fn every_term_is_in_the_gradient_and_the_hessian() {
        let beam = actuated_beam().unwrap();
        let mut model = beam.model;
        // One Dirichlet vertex besides the springs.
        model.fixed[beam.tip] = true;
        check_terms(&model, &["elasticity", "pneumatic", "muscle", "attachment"]);
        // The hyperelastic materials: with actuators (every kind's exact K) and without (their
        // own K~ beside the elastic one).
        for m in [MaterialModel::Corotated, MaterialModel::NeoHookean] {
            let mut hyper = model.clone();
            let name = hyper.bodies[0].name.clone();
            hyper.set_material_model(&name, m).unwrap();
            check_terms(&hyper, &["hyperelastic", "pneumatic", "muscle", "attachment"]);
            let mut plain = ground_box(0.5).unwrap();
            let name = plain.bodies[0].name.clone();
            plain.set_material_model(&name, m).unwrap();
            check_terms(&plain, &["hyperelastic"]);
        }
    }

    fn check_terms(model: &crate::model::Model, expected: &[&str]) {
        let model = model.clone();
        let h = 1e-2;
        let sys = GlobalSystem::new(&model, h).unwrap();
        let mut constraints = Constraints::new(&model);
        let kinds: Vec<_> = constraints.hessian_terms().map(|(k, _)| k).collect();
        for k in expected {
            assert!(kinds.contains(k), "{k} missing from {kinds:?}");
        }
        let n = model.n();
        let scale = model.length_scale;
        let s: Vec<Vector3<f64>> = (0..n)
            .map(|i| model.rest[i] + Vector3::new(noise(3 * i), noise(3 * i + 1), noise(3 * i + 2)) * 0.01 * scale)
            .collect();
        let ih2 = 1.0 / (h * h);
        let mut base = vec![Vector3::zeros(); sys.n()];
        constant_rhs(&model, &sys, &constraints, &s, ih2, &mut base);
        let activations = [0.8, 0.3];
        let activations = &activations[..model.actuators.as_ref().map_or(0, |a| a.groups.len())];
        let p = StepProblem {
            model: &model,
            sys: &sys,
            activations,
            s: &s,
            ih2,
            base: &base,
            coords0: &[],
            torque: &[],
        };
        let nf = sys.n();
        let x: Vec<Vector3<f64>> = (0..nf)
            .map(|k| {
                let v = sys.free[k];
                model.rest[v] + Vector3::new(noise(7 * k + 5), noise(7 * k + 6), noise(7 * k + 9)) * 0.05 * scale
            })
            .collect();
        let d: Vec<Vector3<f64>> = (0..nf)
            .map(|k| Vector3::new(noise(11 * k + 1), noise(11 * k + 2), noise(11 * k + 3)))
            .collect();
        let mut record = vec![TetSvd::default(); model.tets.len()];
        let mut full = model.rest.clone();
        let mut gathered = vec![Vector3::zeros(); n];
        let mut at = |t: f64, constraints: &mut Constraints, record: &mut [TetSvd]| {
            for (k, &v) in sys.free.iter().enumerate() {
                full[v] = x[k] + d[k] * t;
            }
            let (e, _) = p.energy(constraints, &full, None, record).unwrap();
            let mut g = vec![Vector3::zeros(); nf];
            p.gradient(constraints, &x_at(&x, &d, t), &[], &[], &mut gathered, &mut g, &mut []);
            (e, g, full.clone())
        };
        let (_, g0, q0) = at(0.0, &mut constraints, &mut record);
        let dot = |a: &[Vector3<f64>], b: &[Vector3<f64>]| a.iter().zip(b).map(|(x, y)| x.dot(y)).sum::<f64>();
        // Gradient against the energy's central difference.
        let eps = 1e-6 * scale;
        let (ep, gp, _) = at(eps, &mut constraints, &mut record);
        let (em, gm, _) = at(-eps, &mut constraints, &mut record);
        let fd = (ep - em) / (2.0 * eps);
        let an = dot(&g0, &d);
        assert!(
            (fd - an).abs() <= 1e-6 * an.abs().max(1e-12),
            "gradient {an:e} vs {fd:e}"
        );
        // The exact Hessian against the gradient's central difference.
        at(0.0, &mut constraints, &mut record);
        let mut hessian = ConstraintHessian::new(&model);
        assert!(hessian.prepare(&model, &record, &q0, true));
        let (mut hd, mut u_full, mut out_full) = (
            vec![Vector3::zeros(); nf],
            vec![Vector3::zeros(); n],
            vec![Vector3::zeros(); n],
        );
        assert!(p.hessian_product(&mut hessian, &q0, &d, &[], &mut hd, &mut [], &mut u_full, &mut out_full));
        let fd_h: Vec<Vector3<f64>> = gp.iter().zip(&gm).map(|(a, b)| (a - b) / (2.0 * eps)).collect();
        let err = fd_h.iter().zip(&hd).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        let size = hd.iter().map(|v| v.norm()).fold(0.0, f64::max);
        assert!(err <= 1e-5 * size, "Hessian product off by {err:e} (size {size:e})");
    }

    fn x_at(x: &[Vector3<f64>], d: &[Vector3<f64>], t: f64) -> Vec<Vector3<f64>> {
        x.iter().zip(d).map(|(a, b)| a + b * t).collect()
    }
}
