//! The skeleton's backward buffers (`SkeletalAdjoint`), sized once: the reduced step's `W`
//! and `Sigma`, a working copy of the skeleton, `B` at two iterates and the adjoints carried
//! across steps. The algorithms that use them are in `skeletal.rs`.

use nalgebra::{DMatrix, Vector3};

use super::{DiffError, Gradient};
use crate::model::Model;
use crate::skeleton::Skeleton;
use crate::solver::assembled::GlobalSystem;
use crate::solver::direct::Direct;
use crate::solver::skeletal::Skeletal;

/// Per-step scratch of the skeleton's backward pass, sized on first use and reused.
#[derive(Debug, Clone, Default)]
pub(super) struct Scratch {
    /// Implicit mode: accumulators whose parameter adjoints are discarded (a gradient of the
    /// run's shape, the state adjoint, activations, torques).
    pub(super) g: Option<Box<Gradient>>,
    pub(super) q: Vec<Vector3<f64>>,
    pub(super) act: Vec<f64>,
    pub(super) torque: Vec<f64>,
    /// Implicit mode: the fixed point's right-hand side and previous iterate.
    pub(super) x_in: Vec<Vector3<f64>>,
    pub(super) z_in: Vec<f64>,
    pub(super) prev_x: Vec<Vector3<f64>>,
    pub(super) prev_z: Vec<f64>,
    /// The adjoint of a solve's impulses, carried to the iteration before it.
    pub(super) impulse_bar: Vec<Vector3<f64>>,
    /// Torque adjoints of a step.
    pub(super) torque_acc: Vec<f64>,
}

impl Scratch {
    /// Size for a gradient like `g`, `n` vertices, `groups` actuator groups and `dofs` joint
    /// coordinates; start a step (no impulse adjoint yet).
    pub(super) fn prepare(&mut self, g: &Gradient, n: usize, groups: usize, dofs: usize) {
        if self.g.is_none() {
            self.g = Some(Box::new(g.clone()));
        }
        self.q.resize(n, Vector3::zeros());
        self.act.resize(groups, 0.0);
        self.torque.resize(dofs, 0.0);
        self.torque_acc.resize(dofs, 0.0);
        self.impulse_bar.clear();
    }
}

/// `dst = src` (resizing `dst` once).
pub(super) fn copy_into<T: Clone>(dst: &mut Vec<T>, src: &[T]) {
    dst.clear();
    dst.extend_from_slice(src);
}

/// Buffers of the skeleton's backward pass.
#[derive(Debug, Clone)]
pub(crate) struct SkeletalAdjoint {
    /// `W` and `Sigma`.
    pub(super) skeletal: Skeletal,
    /// A copy of the skeleton whose state is loaded per iterate.
    pub(super) work: Skeleton,
    /// `B` at `z_k` and at `z_{k+1}` (`3 n_R x dofs`).
    pub(super) b: DMatrix<f64>,
    pub(super) b_next: DMatrix<f64>,
    /// `(Sigma (x) I3) B`.
    pub(super) sb: DMatrix<f64>,
    pub(super) b_bar: DMatrix<f64>,
    pub(super) q_r: Vec<Vector3<f64>>,
    pub(super) q_r_next: Vec<Vector3<f64>>,
    pub(super) beta: Vec<Vector3<f64>>,
    pub(super) tmp_r: Vec<Vector3<f64>>,
    /// The adjoint of the joint state (chart at the current iterate), carried across steps.
    pub(super) z_bar: Vec<f64>,
    pub(super) z_after: Vec<f64>,
    pub(super) dz_bar: Vec<f64>,
    /// Adjoint of the bone vertices' positions after the step (set by the caller).
    pub(super) q_r_bar_in: Vec<Vector3<f64>>,
    /// Right-hand side adjoint accumulated on bone vertices over a step.
    pub(super) base_acc: Vec<Vector3<f64>>,
    /// Free-numbered scratch: `W beta`, `W (q_R' - c)`.
    pub(super) w_beta: Vec<Vector3<f64>>,
    pub(super) w_shift: Vec<Vector3<f64>>,
    /// Per-step scratch (sized on first use, then reused).
    pub(super) scratch: Scratch,
    /// Full-numbered vectors of the matrix terms.
    pub(super) alpha: Vec<Vector3<f64>>,
    pub(super) gamma: Vec<Vector3<f64>>,
    pub(super) y_tilde: Vec<Vector3<f64>>,
    pub(super) q_prime: Vec<Vector3<f64>>,
    /// Unrolled mode: the share of the step's joint-state adjoint that reached the joint state
    /// the iterations started from (`|z_0 bar| / |z_N bar|`), the joints' part of
    /// [`DiffStats::unrolled_leftover`](super::DiffStats::unrolled_leftover); 0 until measured.
    pub(super) joint_leftover: f64,
}

impl SkeletalAdjoint {
    /// Buffers for `model` (which has a skeleton), with `W` and `Sigma` from the factored system.
    pub(super) fn new(model: &Model, sys: &GlobalSystem, direct: &Direct) -> Option<Self> {
        let sk = model.skeleton.as_ref()?;
        let (nr, nf, n, dofs) = (sys.rigid.len(), sys.n(), model.n(), sk.dofs);
        Some(Self {
            skeletal: Skeletal::new(sys, direct, sk),
            work: sk.clone(),
            b: DMatrix::zeros(3 * nr, dofs),
            b_next: DMatrix::zeros(3 * nr, dofs),
            sb: DMatrix::zeros(3 * nr, dofs),
            b_bar: DMatrix::zeros(3 * nr, dofs),
            q_r: vec![Vector3::zeros(); nr],
            q_r_next: vec![Vector3::zeros(); nr],
            beta: vec![Vector3::zeros(); nr],
            tmp_r: vec![Vector3::zeros(); nr],
            joint_leftover: 0.0,
            z_bar: vec![0.0; dofs],
            z_after: vec![0.0; dofs],
            dz_bar: vec![0.0; dofs],
            q_r_bar_in: vec![Vector3::zeros(); nr],
            base_acc: vec![Vector3::zeros(); nr],
            w_beta: vec![Vector3::zeros(); nf],
            w_shift: vec![Vector3::zeros(); nf],
            scratch: Scratch::default(),
            alpha: vec![Vector3::zeros(); n],
            gamma: vec![Vector3::zeros(); n],
            y_tilde: vec![Vector3::zeros(); n],
            q_prime: vec![Vector3::zeros(); n],
        })
    }

    /// Load joint state `s`; bone-vertex positions into `q` and `B` into `b`.
    pub(super) fn load(
        work: &mut Skeleton,
        s: &[f64],
        q: &mut [Vector3<f64>],
        b: &mut DMatrix<f64>,
    ) -> Result<(), DiffError> {
        work.load_state(s)?;
        work.positions(q);
        work.jacobian(b);
        Ok(())
    }

    /// `z_bar += B^T v` (per bone vertex `v`).
    pub(super) fn add_bt(b: &DMatrix<f64>, v: &[Vector3<f64>], z_bar: &mut [f64]) {
        for (k, zb) in z_bar.iter_mut().enumerate() {
            let col = b.column(k);
            let mut s = 0.0;
            for (r, x) in v.iter().enumerate() {
                s += col[3 * r] * x.x + col[3 * r + 1] * x.y + col[3 * r + 2] * x.z;
            }
            *zb += s;
        }
    }

    /// `out = W v` (free numbering), `W` column-major `n_F x n_R`.
    pub(super) fn w_times(w: &DMatrix<f64>, v: &[Vector3<f64>], out: &mut [Vector3<f64>]) {
        out.iter_mut().for_each(|o| *o = Vector3::zeros());
        let nf = out.len();
        for (r, col) in w.as_slice().chunks_exact(nf.max(1)).enumerate() {
            let x = v[r];
            for (o, &wv) in out.iter_mut().zip(col) {
                *o += x * wv;
            }
        }
    }
}
